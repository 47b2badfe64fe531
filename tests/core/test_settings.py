"""Settings fields: one definition (default, expected, check) that the validator, the study
tables and the command line all read."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.core.settings import REQUIRED, check_fields, check_values, default_of, is_bool, is_int, is_number, setting


@dataclass(frozen=True)
class Window:
    size: int = setting(3, "an integer >= 1", lambda v: is_int(v) and v >= 1)
    step: int = setting(1, "an integer >= 1", lambda v: is_int(v) and v >= 1)
    limit: float | None = setting(None, "seconds > 0", lambda v: is_number(v) and v > 0)
    flags: tuple[str, ...] = setting(default_factory=tuple, expected="strings")
    label: str = "w"  # a plain field: no check of its own

    def __post_init__(self) -> None:
        check_fields(self)
        if self.step > self.size:
            raise ParameterError(f"Window.step = {self.step!r}: expected at most size = {self.size}")


def test_a_field_check_names_the_class_field_value_and_expectation():
    with pytest.raises(ParameterError, match=r"^Window.size = 0: expected an integer >= 1$"):
        Window(size=0)
    with pytest.raises(ParameterError, match=r"Window.size = 2.0: expected an integer >= 1"):
        Window(size=2.0)
    with pytest.raises(ParameterError, match=r"Window.step = 4: expected at most size = 3"):
        Window(step=4)
    with pytest.raises(ParameterError, match=r"Window.limit = 'x': expected seconds > 0"):  # a TypeError in the check is a failure
        Window(limit="x")
    assert Window(size=np.int64(4), limit=None).size == 4  # NumPy integers are integers; None passes where it is the default


def test_values_are_checked_alone_without_the_relations():
    check_values(Window, {"step": 9})  # step > size is a relation: not checked alone
    with pytest.raises(ParameterError, match=r"Window.step = 0"):
        check_values(Window, {"step": 0})
    with pytest.raises(ParameterError, match=r"unknown setting 'stride'"):
        check_values(Window, {"stride": 1})


def test_defaults_come_from_the_field():
    assert default_of(Window, "size") == 3 and default_of(Window, "limit") is None and default_of(Window, "flags") == ()
    assert default_of(Window, "label") == "w"

    @dataclass
    class Needs:
        x: int = setting(expected="an integer")

    assert default_of(Needs, "x") is REQUIRED
    with pytest.raises(KeyError):
        default_of(Window, "nope")


def test_predicates():
    assert is_int(3) and is_int(np.int32(3)) and not is_int(True) and not is_int(3.0)
    assert is_number(2.5) and is_number(np.float64(1)) and not is_number(float("nan")) and not is_number(True)
    assert is_bool(False) and is_bool(np.bool_(True)) and not is_bool(0)
