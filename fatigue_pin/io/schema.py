"""The tables of a study file, taken from the classes they build.

Each table of a study is read by the class it configures, and its keys are that class's fields:

======================  =====================================================================
``[model]``             :class:`~fatigue_pin.robot.model.ModelSource` (``payload``: :class:`~fatigue_pin.robot.model.Payload`)
``[actuators]``         :class:`~fatigue_pin.ocp.actuators.Actuation`
``[task]``              :class:`~fatigue_pin.ocp.task.Task` but ``items``, and the arrays of
                        :data:`TASK_ARRAYS` (task items of :mod:`fatigue_pin.ocp.task`)
``[transcription]``     :class:`~fatigue_pin.ocp.transcription.Transcription`
``[horizon]``           :class:`~fatigue_pin.drivers.horizon.Horizon` (with the fields of
                        :class:`~fatigue_pin.drivers.sliding.SlidingSettings`)
``[solver]``            :class:`~fatigue_pin.ocp.solver.SolverOptions` (but ``cache_dir``)
======================  =====================================================================

A key's type is its field's annotation, its default the field's default (none: required), and
its check the class's validator (``__post_init__``): :func:`read_table` fills the defaults, builds
the class, and restates the class's error (``SolverOptions.tol = -1.0: expected ...``) with the
key's path in the study (``solver.tol = -1.0: expected ...``). A field added to one of these
classes is therefore a study key, with its default, type and checks, with no edit here
(docs/studies.md, "Where keys come from"). ``[fatigue]`` and ``[costs]`` are checked against the
fatigue models and cost kinds in :mod:`fatigue_pin.io.tables`.
"""

from __future__ import annotations

import collections.abc
import copy
import dataclasses
import functools
import math
import re
import types
import typing
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from fatigue_pin.core.errors import FatiguePinError, StudyError
from fatigue_pin.core.settings import REQUIRED, default_value, expected_of, is_bool, is_int, is_str
from fatigue_pin.core.text import shown


# -- keys of a table, from the fields of its class ---------------------------------------------------


@dataclass(frozen=True)
class Key:
    """One key of a study table.

    Attributes:
        name: the key in the study.
        owner: the class whose field it sets.
        field: that field's name (``name`` unless renamed).
        group: the field of the table's class that gathers it (``keys_of``), or "" (its own field).
        annotation: the field's type.
        default: the default in TOML form (lists for tuples), or :data:`REQUIRED`.
        expected: what a valid value is (the field's ``expected``), or "" (the field has none).
    """

    name: str
    owner: type
    field: str
    group: str
    annotation: Any
    default: Any
    expected: str

    @property
    def phrase(self) -> str:
        """What a valid value is: ``expected``, else the type in words."""
        return self.expected or type_phrase(self.annotation)

    @property
    def required(self) -> bool:
        return self.default is REQUIRED

    @property
    def nested(self) -> type | None:
        """The settings class of a key whose value is a table of its own (``model.payload``)."""
        return next((t for t in _members(self.annotation) if dataclasses.is_dataclass(t)), None)


def _members(annotation: Any) -> tuple[Any, ...]:
    """The types of a union (``float | None`` -> (float,)), or the annotation itself."""
    if typing.get_origin(annotation) in (typing.Union, types.UnionType):
        return tuple(a for a in typing.get_args(annotation) if a is not type(None))
    return (annotation,)


def toml_form(value: Any) -> Any:
    """``value`` as a study file holds it: tuples as lists, paths as strings (deep)."""
    if isinstance(value, (list, tuple)):
        return [toml_form(v) for v in value]
    if isinstance(value, dict):
        return {k: toml_form(v) for k, v in value.items()}
    if isinstance(value, Path):
        return str(value)
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: toml_form(getattr(value, f.name)) for f in dataclasses.fields(value)}
    return value


def table_keys(cls: type, skip: tuple[str, ...] = (), renames: dict[str, str] | None = None) -> dict[str, Key]:
    """The keys of a table that builds ``cls``, in field order: its fields (but ``skip`` and those
    declared ``study=False``), a field declared with ``keys_of`` replaced by the fields of that
    class; ``renames`` maps a field to its key."""
    return dict(_table_keys(cls, tuple(skip), tuple(sorted((renames or {}).items()))))


@functools.lru_cache(maxsize=None)
def _table_keys(cls: type, skip: tuple[str, ...], rename_items: tuple[tuple[str, str], ...]) -> dict[str, Key]:
    renames = dict(rename_items)
    hints = typing.get_type_hints(cls)
    keys: dict[str, Key] = {}
    for f in dataclasses.fields(cls):
        if f.name in skip or not f.init or not f.metadata.get("study", True):
            continue
        keys_of = f.metadata.get("keys_of")
        if keys_of:
            inner, inner_renames = keys_of
            for k in table_keys(inner, skip=tuple(inner_renames)).values():
                keys[k.name] = dataclasses.replace(k, group=f.name)
            continue
        name = renames.get(f.name, f.name)
        default = default_value(f)
        keys[name] = Key(name, cls, f.name, "", hints[f.name], REQUIRED if default is REQUIRED else toml_form(default),
                         expected_of(f))
    return keys


# -- types of values ---------------------------------------------------------------------------------


def is_toml_number(v: Any) -> bool:
    """An integer or a float (finite or not) of a TOML file, not a bool."""
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def type_check(annotation: Any) -> Callable[[Any], bool]:
    """A test that a TOML value has the type ``annotation`` (a list for a tuple or sequence, a
    table for a dict or a settings class); anything passes for a type TOML cannot hold."""
    checks = [_type_check(t) for t in _members(annotation)]
    return lambda v: any(c(v) for c in checks)


def _type_check(tp: Any) -> Callable[[Any], bool]:
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    simple = {bool: is_bool, int: is_int, float: is_toml_number, str: is_str, dict: lambda v: isinstance(v, dict)}
    if tp in simple:
        return simple[tp]
    if origin in (tuple, list, collections.abc.Sequence):
        item = type_check(args[0]) if args else (lambda v: True)
        return lambda v: isinstance(v, list) and all(item(x) for x in v)
    if origin in (dict, collections.abc.Mapping) or (isinstance(tp, type) and dataclasses.is_dataclass(tp)):
        return lambda v: isinstance(v, dict)
    return lambda v: True


def type_phrase(annotation: Any) -> str:
    """What a value of type ``annotation`` is, in words ("a list of numbers")."""
    return " or ".join(_phrase(t) for t in _members(annotation))


def _phrase(tp: Any, plural: bool = False) -> str:
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    words = {bool: ("true or false", "booleans"), int: ("an integer", "integers"), float: ("a number", "numbers"),
             str: ("a string", "strings"), dict: ("a table", "tables")}
    if tp in words:
        return words[tp][plural]
    if origin in (tuple, list, collections.abc.Sequence):
        return "a list of " + (_phrase(args[0], plural=True) if args else "values")
    if origin in (dict, collections.abc.Mapping) or (isinstance(tp, type) and dataclasses.is_dataclass(tp)):
        return "tables" if plural else "a table"
    return "values" if plural else "a value"


# -- reading a table --------------------------------------------------------------------------------


def fill(cls: type, table: Any, path: str, *, skip: tuple[str, ...] = (), renames: dict[str, str] | None = None,
         optional: tuple[str, ...] = (), drop_none: bool = False) -> dict[str, Any]:
    """``table`` with every default of ``cls``'s keys filled in, in key order (the normalised
    table); unknown keys, missing required keys (but ``optional`` ones) and non-finite numbers are
    errors naming ``path``. Nested tables (``model.payload``) are filled too, without None values."""
    keys = table_keys(cls, skip, renames)
    if not isinstance(table, dict):
        raise StudyError(f"{path} = {shown(table)}: expected a table")
    unknown = sorted(set(table) - set(keys))
    if unknown:
        raise StudyError(f"unknown key {path}.{unknown[0]}; expected one of {sorted(keys)}")
    out: dict[str, Any] = {}
    for name, key in keys.items():
        if name in table and not (drop_none and table[name] is None):  # None given: not given (TOML has no None)
            value = table[name]
            if is_toml_number(value) and not math.isfinite(float(value)):
                raise StudyError(f"{path}.{name} = {shown(value)}: expected a finite number" + (f" ({key.expected})" if key.expected else ""))
        elif key.required and name not in optional:
            raise StudyError(f"missing key {path}.{name}: expected {key.phrase}")
        else:
            value = None if key.required else copy.deepcopy(key.default)
        if key.nested is not None and isinstance(value, dict):
            value = fill(key.nested, value, f"{path}.{name}", drop_none=True)
        if value is not None or not drop_none:
            out[name] = value
    return out


def build(cls: type, values: dict[str, Any], path: str, *, skip: tuple[str, ...] = (), renames: dict[str, str] | None = None,
          **extra: Any) -> Any:
    """An instance of ``cls`` from a filled table (key -> value, :func:`fill`) and ``extra`` fields.

    The class's validator speaks first: its error is restated with the key's path. A value it
    accepts that is not of its key's type (a float for an integer, ...) is refused next."""
    keys = table_keys(cls, skip, renames)
    kwargs: dict[str, Any] = dict(extra)
    for name, value in values.items():
        key = keys[name]
        if key.nested is not None and isinstance(value, dict):
            value = build(key.nested, value, f"{path}.{name}")
        elif isinstance(value, list) and any(typing.get_origin(t) is tuple for t in _members(key.annotation)):
            value = tuple(value)
        if key.group:
            kwargs.setdefault(key.group, {})[key.field] = value
        else:
            kwargs[key.field] = value
    failure: Exception | None = None
    try:
        obj = cls(**kwargs)
    except FatiguePinError as exc:
        raise StudyError(restate(str(exc), path, _owners(cls, keys, renames), values)) from None
    except (TypeError, ValueError, ArithmeticError) as exc:  # a value of a type the validator did not expect
        failure = exc
    for name, value in values.items():
        key = keys[name]
        if value is not None and not type_check(key.annotation)(value):
            raise StudyError(f"{path}.{name} = {shown(value)}: expected {key.phrase}")
    if failure is not None:
        raise StudyError(f"{path}: {failure}")
    return obj


def read_table(cls: type, table: Any, path: str, **options: Any) -> tuple[dict[str, Any], Any]:
    """The normalised table (:func:`fill`) and the instance of ``cls`` it builds (:func:`build`)."""
    values = fill(cls, table, path, **options)
    return values, build(cls, values, path, skip=options.get("skip", ()), renames=options.get("renames"))


def _owners(cls: type, keys: dict[str, Key], renames: dict[str, str] | None) -> dict[str, dict[str, str]]:
    """The classes whose messages a table's errors may carry, each with its field -> key renames."""
    owners = {cls.__name__.lower(): dict(renames or {})}
    for f in dataclasses.fields(cls):
        if f.metadata.get("keys_of"):
            inner, inner_renames = f.metadata["keys_of"]
            owners[inner.__name__.lower()] = dict(inner_renames)
    for key in keys.values():
        if key.nested is not None:
            owners.setdefault(key.nested.__name__.lower(), {})
    return owners


_OWNER = re.compile(r"(\w+)(\([^)]*\))?(?:\.(\w+)| (\w+)(?= = ))?")


def restate(message: str, path: str, owners: dict[str, dict[str, str]], values: dict[str, Any] | None = None) -> str:
    """A validator's message with its owner (``SolverOptions.tol``, ``JointTarget('elbow').at``,
    ``payload mass``) replaced by the study path (``solver.tol``, ``task.targets[1].at``,
    ``model.payload.mass``), fields named by their keys, and the value as the study wrote it
    (``values``: key -> value) rather than as the class converted it."""
    m = _OWNER.match(message)
    if m and m.group(1).lower() in owners:
        renames = owners[m.group(1).lower()]
        key = m.group(3) or m.group(4)
        rest = message[m.end():]
        for name, new in renames.items():
            rest = re.sub(rf"\b{name} = ", f"{new} = ", rest)
        if key is None:
            return f"{path}{rest}"
        key = renames.get(key, key)
        if values is not None and key in values and rest.startswith(" = ") and ": expected" in rest:
            rest = f" = {shown(values[key])}" + rest[rest.index(": expected"):]
        return f"{path}.{key}{rest}"
    if message.startswith(path.split(".")[0].split("[")[0]):
        return message
    return f"{path}: {message}"
