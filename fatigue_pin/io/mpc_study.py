"""Closed-loop studies: a study file with a plant and an ``[mpc]`` table (docs/mpc.md).

Besides the tables of a study (:mod:`fatigue_pin.io.study`), which describe the *model* and the
controller's window (``[horizon]``: ``cycles`` = K, ``max_cycles``, ``end_tolerance``, ...), a
closed-loop study has::

    seed = 0                       the seed of every random draw of the plant
    [plant]                        integrator ("rk4" | "rk45"), substeps (RK4 steps per interval)
    [plant.fatigue]                overrides of the study's [fatigue] for the plant, same keys
    [plant.model]                  overrides of the study's [model] for the plant, same keys
                                   (e.g. [plant.model.payload] mass = 5.0)
    [plant.noise]                  q (rad), qdot (rad/s), capacity: standard deviations
    [plant.disturbance]            constant, std: N m, one value or one per joint
    [mpc]                          replan_every, estimator, probe_every, target_tolerance,
                                   capacity_margin, end
    [mpc.mhe]                      cycles, params, probe_std, saturation_std, state_std,
                                   param_std, max_iter

With no ``[plant]`` table the plant equals the model. Every key is checked: an unknown key, a
plant override of a key the study does not have, a negative standard deviation or
``replan_every < 1`` is one error naming the key.
"""

from __future__ import annotations

import copy
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fatigue_pin.core.progress import Progress, as_reporter
from fatigue_pin.drivers.mpc import ClosedLoop, MpcSettings
from fatigue_pin.drivers.plant import PlantSettings
from fatigue_pin.drivers.run import RunResult
from fatigue_pin.drivers.sliding import SlidingSettings
from fatigue_pin.core.errors import StudyError
from fatigue_pin.io.schema import read_table
from fatigue_pin.io.study import Study
from fatigue_pin.io.tables import _toml_key, _toml_value
from fatigue_pin.core.text import plain, shown

#: Tables of the study a [plant] table may override.
PLANT_OVERRIDES = ("model", "fatigue", "motors")
#: Keys of [plant] that are the plant's own settings (not overrides).
PLANT_OWN = ("noise", "disturbance", "integrator", "substeps", "rtol", "atol")  # fields of PlantSettings but seed
#: Top-level keys a closed-loop study adds.
MPC_KEYS = ("plant", "mpc", "seed")


def is_closed_loop(path: str | Path) -> bool:
    """Whether the TOML study file ``path`` is a closed-loop study (has a ``[plant]`` or ``[mpc]``
    table or a ``seed``). False for anything else, including files that are not TOML (their
    reader says what is wrong)."""
    path = Path(path)
    if path.suffix.lower() != ".toml" or not path.is_file():
        return False
    try:
        data = tomllib.loads(path.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError, OSError):
        return False
    return is_closed_loop_table(data)


def is_closed_loop_table(data: dict[str, Any]) -> bool:
    """Whether the parsed study ``data`` is a closed-loop study: it has a ``[plant]`` or
    ``[mpc]`` table or a ``seed`` (:data:`MPC_KEYS`)."""
    return any(key in data for key in MPC_KEYS)


def _merge(base: dict[str, Any], changes: dict[str, Any]) -> dict[str, Any]:
    out = copy.deepcopy(base)
    for key, value in changes.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = _merge(out[key], value)
        else:
            out[key] = copy.deepcopy(value)
    return out


def _plant_data(data: dict[str, Any], plant: dict[str, Any]) -> dict[str, Any]:
    """The study data of the plant: the model's with the [plant] overrides merged in."""
    overrides = {k: v for k, v in plant.items() if k not in PLANT_OWN}
    for key, value in overrides.items():
        if key not in PLANT_OVERRIDES:
            raise StudyError(f"unknown key plant.{key}; a plant overrides {list(PLANT_OVERRIDES)} of the study, "
                             f"or sets {list(PLANT_OWN)}")
        if not isinstance(value, dict):
            raise StudyError(f"plant.{key} = {shown(value)}: expected a table of the study's [{key}] keys")
    return _merge(data, overrides)


def _plant_study(data: dict[str, Any], plant: dict[str, Any]) -> Study:
    """The plant's study; its errors name the key as the [plant] table does (``plant.fatigue.G``)."""
    merged = _plant_data(data, plant)
    try:
        return Study.from_dict(merged)
    except StudyError as exc:
        text = str(exc)
        for prefix in ("unknown key ", "missing key "):
            if text.startswith(prefix):
                raise StudyError(prefix + "plant." + text[len(prefix):]) from None
        raise StudyError(("plant." if text.startswith(PLANT_OVERRIDES) else "plant: ") + text) from None


@dataclass(frozen=True)
class MpcStudy:
    """A closed-loop study: the model's study, the plant's study and the loop's settings.

    Attributes:
        study: the model's study (controller and window).
        plant_study: the plant's study (``study`` with the [plant] overrides).
        plant: noise, disturbance, seed and integrator of the plant.
        mpc: re-planning, estimator and probes.
        tables: the raw ``plant``, ``mpc`` and ``seed`` entries (written back with the study).
    """

    study: Study
    plant_study: Study
    plant: PlantSettings
    mpc: MpcSettings
    tables: dict[str, Any]

    @classmethod
    def from_dict(cls, data: dict[str, Any], changes: dict[str, Any] | None = None) -> MpcStudy:
        """From parsed TOML; ``changes``: dotted keys (``--set``), e.g. ``mpc.replan_every``.
        Numpy scalars and arrays, in ``data`` or ``changes``, enter as plain Python values."""
        if not isinstance(data, dict):
            raise StudyError(f"study = {shown(data)}: expected a table")
        data = plain(data)  # a copy
        base_changes = {}
        for dotted, value in plain(changes or {}).items():
            parts = dotted.split(".")
            if parts[0] not in MPC_KEYS:
                base_changes[dotted] = value
                continue
            node = data
            for p in parts[:-1]:
                node = node.setdefault(p, {})
                if not isinstance(node, dict):
                    raise StudyError(f"study key {dotted!r}: {p!r} is not a table")
            node[parts[-1]] = value
        tables = {k: data.pop(k) for k in MPC_KEYS if k in data}
        study = Study.from_dict(data)
        if base_changes:
            study = study.replace(base_changes)
        plant_table = tables.get("plant", {})
        if not isinstance(plant_table, dict):
            raise StudyError(f"plant = {shown(plant_table)}: expected a table")
        plant_study = _plant_study(study.data, plant_table) if plant_table else study
        own = {k: v for k, v in plant_table.items() if k in PLANT_OWN}
        seed = tables.get("seed", 0)
        if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
            raise StudyError(f"seed = {shown(seed)}: expected an integer >= 0")
        _, plant = read_table(PlantSettings, {**own, "seed": seed}, "plant")  # keys from the settings classes
        mpc_table = tables.get("mpc", {})
        _, mpc = read_table(MpcSettings, mpc_table, "mpc")
        return cls(study, plant_study, plant, mpc, tables)

    @classmethod
    def from_toml(cls, text: str, source: str = "study", changes: dict[str, Any] | None = None) -> MpcStudy:
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise StudyError(f"{source} is not valid TOML: {exc}") from None
        return cls.from_dict(data, changes)

    @classmethod
    def from_file(cls, path: str | Path, changes: dict[str, Any] | None = None) -> MpcStudy:
        path = Path(path)
        if not path.is_file():
            raise StudyError(f"study file not found: {str(path)!r}; expected a .toml study file")
        return cls.from_toml(path.read_text(), repr(str(path)), changes)

    def to_toml(self) -> str:
        """The study's TOML text, the closed-loop tables included."""
        lines = [self.study.to_toml().rstrip(), ""]
        if "seed" in self.tables:
            lines = [f"seed = {_toml_value(self.tables['seed'])}", ""] + lines

        def table(header: str, values: dict[str, Any]) -> None:
            plain = {k: v for k, v in values.items() if not isinstance(v, dict)}
            if plain or not values:
                lines.append(f"[{header}]")
                lines.extend(f"{_toml_key(k)} = {_toml_value(v)}" for k, v in plain.items())
                lines.append("")
            for k, v in values.items():
                if isinstance(v, dict):
                    table(f"{header}.{_toml_key(k)}", v)

        for key in ("plant", "mpc"):
            if key in self.tables:
                table(key, self.tables[key])
        return "\n".join(lines)

    @property
    def data(self) -> dict[str, Any]:
        """The study's tables, the closed-loop ones (``plant``, ``mpc``, ``seed``) included: what
        :meth:`from_dict` reads and dotted keys change (a sweep's base)."""
        return {**copy.deepcopy(self.study.data), **copy.deepcopy(self.tables)}

    def replace(self, changes: dict[str, Any]) -> MpcStudy:
        """A copy with dotted keys changed, e.g. ``{"plant.fatigue.F": 0.9, "mpc.replan_every": 5}``
        (as ``--set``; the model's keys as :meth:`Study.replace`)."""
        return MpcStudy.from_dict(self.data, changes)

    def sliding(self) -> SlidingSettings:
        """The controller's window from the study's [horizon] table."""
        return self.study.horizon_settings().sliding_settings()

    def run_name(self) -> str:
        return f"mpc/{self.study.name}"

    def closed_loop(self, cache_dir: str | Path | None = None, progress=None) -> ClosedLoop:
        """The :class:`ClosedLoop` of this study (builds the window OCP)."""
        return ClosedLoop(self.study.problem(), self.plant_study.problem(), self.sliding(), self.mpc, self.plant,
                          self.study.transcription(), self.study.solver(cache_dir), self.study.horizon_settings().guess, progress)


def run_mpc(study: MpcStudy | str | Path, out: str | Path | None = None, name: str | None = None, resume: bool = False,
            progress: Progress = None, cache_dir: str | Path | None = None, changes: dict[str, Any] | None = None,
            stop_after: int | None = None) -> RunResult:
    """Run a closed-loop study and store its run in ``out`` (HDF5) after every re-plan.

    Args:
        study: an :class:`MpcStudy` or the path of its TOML file.
        out: the result file (checked before any work); None: memory only.
        name: run name (default ``mpc/<study name>``).
        resume: continue the run stored under ``name`` in ``out``.
        progress: a Reporter or a line callback.
        cache_dir: folder of compiled code.
        changes: dotted keys to change (``--set``), when ``study`` is a path.
        stop_after: re-plan at most this many times in this call.

    Returns:
        The run (:mod:`fatigue_pin.drivers.mpc_run`): the plant, with the prediction and the
        estimate in its extras; attribute ``repetitions``.
    """
    from fatigue_pin.drivers.mpc_run import run_closed_loop
    from fatigue_pin.io.results import ResultFile, check_output

    if out is not None:
        check_output(out)
    if not isinstance(study, MpcStudy):
        study = MpcStudy.from_file(study, changes)
    rep = as_reporter(progress)
    loop = study.closed_loop(cache_dir, rep)
    store = ResultFile(out) if out is not None else None
    return run_closed_loop(loop, store, name or study.run_name(), resume, study.to_toml(), study.study.labels, rep, stop_after)
