"""Settings as validated dataclasses: one definition per setting.

A settings class (:class:`~fatigue_pin.ocp.transcription.Transcription`,
:class:`~fatigue_pin.ocp.solver.SolverOptions`, :class:`~fatigue_pin.drivers.sliding.SlidingSettings`,
:class:`~fatigue_pin.drivers.horizon.Horizon`, :class:`~fatigue_pin.robot.model.ModelSource`, ...)
is a frozen dataclass whose fields are its settings. A field says everything about its setting,
once: its name, its type (the annotation), its default (none: the setting is required) and, when
declared with :func:`setting`, what a valid value is: ``expected``, the phrase that error messages
and docs/studies.md show, and ``check``, a test of the value alone.

``__post_init__`` is the validator: it calls :func:`check_fields` (every field's own check, with
the message ``Class.field = value: expected ...``), then checks the relations between fields
itself, with messages of the same form. The study files take their tables from these classes
(:mod:`fatigue_pin.io.schema`): a field added to a settings class is a study key, with its default
and its checks, with no other edit.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from typing import Any, Callable, Mapping

import numpy as np

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.core.text import shown

#: The default of a field that has none (the setting is required).
REQUIRED = dataclasses.MISSING


def setting(default: Any = dataclasses.MISSING, expected: str = "", check: Callable[[Any], bool] | None = None, *,
            default_factory: Any = dataclasses.MISSING, study: bool = True,
            keys_of: tuple[type, dict[str, str]] | None = None) -> Any:
    """A dataclass field for one setting.

    Args:
        default: the default value (none: required); mutable defaults through ``default_factory``.
        expected: what a valid value is, as a phrase after "expected" (``"an integer >= 1"``).
        check: ``check(value) -> bool`` of the value alone (an exception counts as False);
            ``None`` passes when the default is ``None``.
        study: False for a setting of the machine rather than of the study (``cache_dir``): not a
            study key.
        keys_of: ``(SettingsClass, renames)``: the field holds the values of that class's fields
            by name, and a study table lists them as keys of its own; ``renames`` maps a field of
            that class to the key of this class that stands for it (e.g. ``{"window": "cycles"}``).
    """
    metadata = {"expected": expected, "check": check, "study": study, "keys_of": keys_of}
    return dataclasses.field(default=default, default_factory=default_factory, metadata=metadata)


def is_int(v: Any) -> bool:
    """An integer (Python or NumPy), not a bool."""
    return isinstance(v, numbers.Integral) and not isinstance(v, bool)


def is_number(v: Any) -> bool:
    """A finite real number (Python or NumPy), not a bool."""
    return isinstance(v, numbers.Real) and not isinstance(v, bool) and math.isfinite(float(v))


def is_bool(v: Any) -> bool:
    """True or False (Python or NumPy)."""
    return isinstance(v, (bool, np.bool_))


def is_str(v: Any) -> bool:
    return isinstance(v, str)


def is_strs(v: Any) -> bool:
    """A list or tuple of strings."""
    return isinstance(v, (list, tuple)) and all(isinstance(x, str) for x in v)


def default_value(f: dataclasses.Field) -> Any:
    """The default of field ``f`` (a fresh one for a ``default_factory``), or :data:`REQUIRED`."""
    if f.default is not dataclasses.MISSING:
        return f.default
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    return REQUIRED


def default_of(cls: type, name: str) -> Any:
    """The default of setting ``name`` of settings class ``cls``."""
    return default_value(field_of(cls, name))


def replaced(cls: type, settings: Any, changes: Mapping[str, Any], error: type[Exception] = ParameterError) -> Any:
    """``settings`` (an instance of ``cls``; None: its defaults) with ``changes`` (field name ->
    value), validated; a name that is not a field of ``cls`` is ``error``."""
    names = [f.name for f in dataclasses.fields(cls)]
    unknown = [k for k in changes if k not in names]
    if unknown:
        raise error(f"{cls.__name__}: unknown setting {unknown[0]!r}; expected one of {names}")
    return dataclasses.replace(settings if settings is not None else cls(), **changes)


def field_of(cls: type, name: str) -> dataclasses.Field:
    for f in dataclasses.fields(cls):
        if f.name == name:
            return f
    raise KeyError(f"{cls.__name__} has no setting {name!r}")


def expected_of(f: dataclasses.Field) -> str:
    """The ``expected`` phrase of field ``f`` ("" when it was declared without :func:`setting`)."""
    return f.metadata.get("expected", "") or ""


def check_message(cls: type, f: dataclasses.Field, value: Any) -> str | None:
    """The error message of ``value`` for field ``f`` of ``cls`` by the field's own check, or None
    when it passes (or the field has no check)."""
    check = f.metadata.get("check")
    if check is None or (value is None and default_value(f) is None):
        return None
    try:
        ok = bool(check(value))
    except (TypeError, ValueError, ArithmeticError):
        ok = False
    return None if ok else f"{cls.__name__}.{f.name} = {shown(value)}: expected {expected_of(f)}"


def check_values(cls: type, values: Mapping[str, Any], error: type[Exception] = ParameterError) -> None:
    """Check each of ``values`` (field name -> value) by its field's own check, without building
    ``cls`` (relations between fields are not checked); unknown names are errors."""
    fields = {f.name: f for f in dataclasses.fields(cls)}
    for name, value in values.items():
        if name not in fields:
            raise error(f"{cls.__name__}: unknown setting {name!r}; expected one of {sorted(fields)}")
        message = check_message(cls, fields[name], value)
        if message:
            raise error(message)


def check_fields(obj: Any, error: type[Exception] = ParameterError) -> None:
    """Check every field of the settings object ``obj`` by its own check (call it first in
    ``__post_init__``)."""
    cls = type(obj)
    for f in dataclasses.fields(cls):
        message = check_message(cls, f, getattr(obj, f.name))
        if message:
            raise error(message)
