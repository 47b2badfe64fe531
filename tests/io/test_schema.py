"""Study tables from the fields of the classes they build: keys, defaults, types, the class's own
validation restated with the study path, and fields added later flowing in with no other edit."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import pytest

from conftest import small_curl
from fatigue_pin.core.errors import ParameterError
from fatigue_pin.core.settings import default_of, is_int, setting
from fatigue_pin.drivers.horizon import Horizon
from fatigue_pin.drivers.sliding import SlidingSettings
from fatigue_pin.io.schema import StudyError, read_table, restate, table_keys, type_phrase
from fatigue_pin.io.study import Study
from fatigue_pin.ocp.solver import SolverOptions
from fatigue_pin.ocp.transcription import Transcription


def test_solver_keys_are_the_fields_of_solver_options():
    keys = table_keys(SolverOptions)
    fields = [f.name for f in dataclasses.fields(SolverOptions) if f.name != "cache_dir"]
    assert list(keys) == fields  # in field order; cache_dir is the machine's (study=False)
    assert keys["compiler_flags"].default == ["-O3", "-march=native"]  # the tuple default, as TOML holds it
    assert keys["tol"].default == default_of(SolverOptions, "tol") == 1e-6


def test_horizon_keys_are_its_fields_and_the_sliding_settings_but_the_window():
    keys = table_keys(Horizon)
    sliding = [f.name for f in dataclasses.fields(SlidingSettings) if f.name != "window"]
    assert list(keys) == ["kind", "cycles", "cyclic_end", "guess", *sliding]
    assert all(keys[k].owner is SlidingSettings and keys[k].group == "sliding" for k in sliding)
    assert keys["warmup"].default == default_of(SlidingSettings, "warmup")


@dataclass(frozen=True)
class Faster(Transcription):
    """Transcription with two settings added later: one declared with setting(), one plain field
    checked by __post_init__ (what another module adds must flow into the study with no edit)."""

    threads: int = setting(2, "an integer >= 1", lambda v: is_int(v) and v >= 1)
    warm: bool = False
    ratio: float = 0.5

    def __post_init__(self) -> None:
        super().__post_init__()
        if not 0 < self.ratio < 1:
            raise ParameterError(f"Faster.ratio = {self.ratio!r}: expected a ratio in (0, 1)")


def test_a_field_added_to_a_settings_class_is_a_study_key_with_its_default_and_checks():
    values, built = read_table(Faster, {"substeps": 3}, "transcription")
    assert values == {**Study.from_dict(small_curl().data).data["transcription"], "substeps": 3, "threads": 2, "warm": False,
                      "ratio": 0.5}
    assert built == Faster(substeps=3)
    with pytest.raises(StudyError, match=r"^transcription.threads = 0: expected an integer >= 1$"):
        read_table(Faster, {"threads": 0}, "transcription")
    with pytest.raises(StudyError, match=r"^transcription.ratio = 2.0: expected a ratio in \(0, 1\)$"):
        read_table(Faster, {"ratio": 2.0}, "transcription")
    with pytest.raises(StudyError, match=r"^transcription.warm = 'yes': expected true or false$"):  # its type, from the annotation
        read_table(Faster, {"warm": "yes"}, "transcription")
    with pytest.raises(StudyError, match=r"^transcription.threads = 2.0: expected an integer >= 1$"):
        read_table(Faster, {"threads": 2.0}, "transcription")
    with pytest.raises(StudyError, match=r"unknown key transcription.thread; expected one of \[.*'threads'.*\]"):
        read_table(Faster, {"thread": 2}, "transcription")


def test_messages_carry_the_study_path_and_the_study_value():
    base = small_curl("sliding").data
    cases = [
        ("solver", "tol", -1.0, "solver.tol = -1.0: expected a tolerance > 0"),
        ("solver", "max_iter", 3000.0, "solver.max_iter = 3000.0: expected an integer >= 0"),
        ("horizon", "advance", 4, "horizon.advance = 4: expected an integer in [1, cycles = 3]"),
        ("horizon", "max_cycles", 2, "horizon.max_cycles = 2: expected at least the window, cycles = 3"),
        ("horizon", "warmup", -1, "horizon.warmup = -1: expected an integer >= 0"),
        ("model", "gravity", [0, 0], "model.gravity = [0, 0]: expected 3 finite numbers (m/s^2, world frame)"),
        ("model", "payload", {"frame": "hand", "mass": -1.0}, "model.payload.mass = -1.0: expected a finite mass >= 0 (kg)"),
        ("task", "cycle_duration", float("inf"), "task.cycle_duration = inf: expected a finite number"),
    ]
    for table, key, value, message in cases:
        with pytest.raises(StudyError) as info:
            Study.from_dict({**base, table: {**base[table], key: value}})
        assert str(info.value) == message


def test_sliding_keys_are_checked_alone_for_every_kind_and_against_the_window_for_sliding():
    full = small_curl("full").data
    with pytest.raises(StudyError, match=r"^horizon.warmup = -1: expected an integer >= 0$"):
        Study.from_dict({**full, "horizon": {**full["horizon"], "warmup": -1}})
    search = Study.from_dict({**full, "horizon": {"kind": "max-cycles", "cycles": 3, "max_cycles": 2}})  # no window to meet
    assert search.horizon_settings().max_cycles == 2


def test_restate_names_keys_of_renamed_fields():
    owners = {"frameorientation": {"rotation": "rpy", "tolerance": "angle_tolerance"}}
    assert restate("FrameOrientation('tool0').tolerance = 4.0: expected an angle in (0, pi] (rad)", "task.targets[2]", owners,
                   {"angle_tolerance": 4}) == "task.targets[2].angle_tolerance = 4: expected an angle in (0, pi] (rad)"
    assert restate("JointRange('elbow'): lower = 2 > upper = 1; expected lower <= upper", "task.ranges[0]", {"jointrange": {}}) \
        == "task.ranges[0]: lower = 2 > upper = 1; expected lower <= upper"
    assert restate("task phase at = 0.33 is not a node", "task", {"task": {}}) == "task phase at = 0.33 is not a node"
    assert restate("something broke", "solver", {"solveroptions": {}}) == "solver: something broke"


def test_type_phrases():
    assert type_phrase(int) == "an integer" and type_phrase(float | None) == "a number"
    assert type_phrase(tuple[str, ...]) == "a list of strings" and type_phrase(bool) == "true or false"
