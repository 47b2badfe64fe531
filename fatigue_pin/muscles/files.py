"""Muscle files: a model's muscles and wrap cylinders in TOML, beside its URDF.

A muscle file has ``[[wraps]]`` tables (``name``, ``frame``, ``translation``, ``rotation``,
``radius``: the fields of :class:`~fatigue_pin.muscles.wraps.CylinderWrap`) and ``[[muscles]]``
tables (the fields of :class:`~fatigue_pin.muscles.muscle.Muscle`, with ``points`` a list of
``{ frame = "...", location = [x, y, z] }``). The bundled ones: ``urdf/arm26.muscles.toml``
(:func:`load_muscles` ``("arm26")``) and ``urdf/arm26_idealized.muscles.toml`` (the same muscles
idealised on their via-point paths, ``"arm26_idealized"``).
"""

from __future__ import annotations

import dataclasses
import tomllib
from pathlib import Path

from fatigue_pin.core.errors import ModelError, ParameterError
from fatigue_pin.muscles.muscle import Muscle, PathPoint
from fatigue_pin.muscles.muscle_set import MuscleSet
from fatigue_pin.muscles.wraps import CylinderWrap
from fatigue_pin.robot.model import bundled_file

__all__ = ["bundled_muscles", "load_muscles", "read_muscles"]

_SUFFIX = ".muscles.toml"


def bundled_muscles(name: str) -> Path:
    """Path of a muscle file shipped with fatigue_pin (``arm26``, ``arm26_idealized``), beside the bundled URDFs."""
    path = bundled_file(f"{name}{_SUFFIX}")
    if path is None:
        raise ModelError(f"bundled muscle file {name!r} not found; the bundled ones are: arm26, arm26_idealized")
    return path


def _fields(cls: type, table: dict, where: str) -> dict:
    names = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(table) - names)
    if unknown:
        raise ParameterError(f"{where}: unknown key {unknown[0]!r}; expected some of {sorted(names)}")
    required = [f.name for f in dataclasses.fields(cls)
                if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING]
    missing = [k for k in required if k not in table]
    if missing:
        raise ParameterError(f"{where}: missing key {missing[0]!r}")
    return dict(table)


def read_muscles(text: str, source: str = "") -> MuscleSet:
    """The muscle set of a muscle file's text (see the module docstring); ``source`` names the
    file in messages. Raises ParameterError with one line naming the bad entry."""
    where = source or "muscle file"
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ParameterError(f"{where} is not valid TOML ({exc})") from None
    unknown = sorted(set(data) - {"muscles", "wraps"})
    if unknown:
        raise ParameterError(f"{where}: unknown table {unknown[0]!r}; expected [[muscles]] and [[wraps]]")
    wraps = []
    for k, table in enumerate(data.get("wraps", [])):
        at = f"{where}: wraps[{k}]" + (f" ({table['name']!r})" if isinstance(table, dict) and "name" in table else "")
        if not isinstance(table, dict):
            raise ParameterError(f"{at}: expected a table")
        wraps.append(_with_source(lambda: CylinderWrap(**_fields(CylinderWrap, table, at)), where))
    muscles = []
    for k, table in enumerate(data.get("muscles", [])):
        at = f"{where}: muscles[{k}]" + (f" ({table['name']!r})" if isinstance(table, dict) and "name" in table else "")
        if not isinstance(table, dict):
            raise ParameterError(f"{at}: expected a table")
        fields = _fields(Muscle, table, at)
        points = fields.get("points")
        if not isinstance(points, list) or not all(isinstance(p, dict) for p in points):
            raise ParameterError(f"{at}: points = {points!r}: expected a list of {{ frame = ..., location = [x, y, z] }}")
        fields["points"] = tuple(_with_source(lambda p=p: PathPoint(**_fields(PathPoint, p, f"{at}.points")), where) for p in points)
        muscles.append(_with_source(lambda: Muscle(**fields), where))
    return MuscleSet(tuple(muscles), tuple(wraps), source, text)


def _with_source(build, where: str):
    """``build()``, its ParameterError or TypeError prefixed with the file."""
    try:
        return build()
    except ParameterError as exc:
        raise ParameterError(f"{where}: {exc}") from None
    except TypeError as exc:
        raise ParameterError(f"{where}: {exc}") from None


def load_muscles(name_or_path: str | Path) -> MuscleSet:
    """The muscle set of a bundled model name (``arm26``) or of a muscle file path."""
    text = str(name_or_path)
    path = Path(text)
    if not path.is_file():
        if "/" in text or text.endswith(".toml"):
            raise ModelError(f"muscle file {text!r} does not exist; expected a bundled model name (arm26) or a muscle file")
        path = bundled_muscles(text)
    return read_muscles(path.read_text(), str(path))
