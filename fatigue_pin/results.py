"""OCP results in HDF5: one group per run, written atomically, read back as :class:`RunResult`.

Layout (``docs/results.md``)::

    /<run name>/                     attributes: horizon, cost, preset, S, F, R, LD, LR, n_cycles,
                                     converged, status, wall_time_s, build_time_s, iterations,
                                     solver, model, weights (JSON), fatigue_params (JSON),
                                     study (the study's TOML text, when run from a study),
                                     urdf (the model's URDF text)
        t            (nodes,)              s
        q, qdot      (nodes, nq)           rad, rad/s          attribute joints
        tau_plus     (intervals, nv)       N m                 attribute joints
        tau_minus    (intervals, nv)       N m
        <state>      (nodes, halves)       1, one dataset per fatigue state the models declare
                                           (Xia: ma, mr, mf; group attribute fatigue_states lists
                                           them; NaN in the columns of halves without the state)
        cycle_costs  (cycles, terms)       weighted cost       attribute terms
        torque_limits (cycles, halves)     N m, (1 - mf) * tau_limit at the end of each cycle
        cycle_wall_time_s (cycles,)        s, solve time attributed to each kept cycle
        windows      (windows,) table      sliding horizon only: index, first_cycle, status,
                                           converged, iterations, wall_time_s, objective
    /search                          max-cycles searches: n_cycles, converged, iterations, wall_time_s

Every write builds the whole new file next to the old one and renames it over the old one
(``os.replace``), so a crash or a kill at any moment leaves either the old or the new file,
both complete and readable.
"""

from __future__ import annotations

import json
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from fatigue_pin.errors import FatiguePinError

#: Attributes every run group carries.
RUN_ATTRIBUTES = (
    "horizon", "n_cycles", "converged", "status", "wall_time_s", "build_time_s", "iterations", "solver", "model",
    "weights", "fatigue_params",
)
#: Fatigue states of files written before the layout named them (Xia's model).
LEGACY_FATIGUE_STATES = ("ma", "mr", "mf")

WINDOW_DTYPE = np.dtype([
    ("index", "i4"), ("first_cycle", "i4"), ("status", "S40"), ("converged", "?"),
    ("iterations", "i4"), ("wall_time_s", "f8"), ("objective", "f8"),
])

SEARCH_DTYPE = np.dtype([("n_cycles", "i4"), ("converged", "?"), ("status", "S40"), ("iterations", "i4"), ("wall_time_s", "f8")])


class ResultFileError(FatiguePinError, ValueError):
    """A result file or run that cannot be read."""


@dataclass
class RunResult:
    """One OCP run (full horizon, or sliding horizon stitched from its windows).

    Shapes: nodes = n_cycles * intervals_per_cycle + 1, intervals = nodes - 1, halves = 2 nv.

    Attributes:
        name: group name in the file.
        attrs: run attributes (see :data:`RUN_ATTRIBUTES`; more may be present).
        t: node times (s), (nodes,).
        q, qdot: joint positions (rad) and velocities (rad/s), (nodes, nq).
        tau_plus, tau_minus: actuator half torques (N m), (intervals, nv).
        fatigue: fatigue states by name (Xia: ``ma``, ``mr``, ``mf``), each (nodes, halves); NaN in
            the columns of halves whose model has no such state.
        cycle_costs: weighted cost terms per cycle, (cycles, len(cost_terms)).
        torque_limits: available torque (1 - mf) * tau_limit of every half at the end of each
            cycle (N m, signed like the half), (cycles, halves).
        joint_names, actuator_names, cost_terms: labels of the columns.
        cycle_wall_time_s: solve time attributed to each cycle (s), (cycles,).
        windows: sliding-horizon window table (structured, :data:`WINDOW_DTYPE`), or None.
        urdf: the model's URDF text (so the file reproduces itself), or "".
        study: the TOML text of the study that produced the run, or "" (built in Python).
        fatigued: the fatigued fraction of every half (each model's fatigued state), (nodes, halves).
    """

    name: str
    attrs: dict[str, Any]
    t: np.ndarray
    q: np.ndarray
    qdot: np.ndarray
    tau_plus: np.ndarray
    tau_minus: np.ndarray
    fatigue: dict[str, np.ndarray]
    cycle_costs: np.ndarray
    torque_limits: np.ndarray
    joint_names: tuple[str, ...]
    actuator_names: tuple[str, ...]
    cost_terms: tuple[str, ...]
    cycle_wall_time_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    windows: np.ndarray | None = None
    urdf: str = ""
    study: str = ""
    fatigued: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.fatigued is None:
            self.fatigued = self.fatigue.get("mf")

    @property
    def fatigue_states(self) -> tuple[str, ...]:
        return tuple(self.fatigue)

    def state(self, name: str) -> np.ndarray:
        """Fatigue state ``name`` of every half, (nodes, halves)."""
        if name not in self.fatigue:
            raise ResultFileError(f"run {self.name!r} has no fatigue state {name!r}; its states are {list(self.fatigue)}")
        return self.fatigue[name]

    @property
    def ma(self) -> np.ndarray:
        return self.state("ma")

    @property
    def mr(self) -> np.ndarray:
        return self.state("mr")

    @property
    def mf(self) -> np.ndarray:
        return self.state("mf")

    @property
    def n_cycles(self) -> int:
        return int(self.cycle_costs.shape[0])

    @property
    def converged(self) -> bool:
        return bool(self.attrs.get("converged", False))

    @property
    def intervals_per_cycle(self) -> int:
        return (self.t.size - 1) // max(self.n_cycles, 1)

    def invariant_error(self) -> np.ndarray:
        """|1 - (sum of the fatigue states)| of every half at every node, (nodes, halves) (for
        Xia's model |1 - (ma + mr + mf)|; states a half lacks count as 0)."""
        total = sum(np.nan_to_num(v) for v in self.fatigue.values())
        return np.abs(1.0 - total)

    def cycle_slice(self, cycle: int) -> slice:
        """Node slice of cycle ``cycle`` (0-based), both ends included."""
        n = self.intervals_per_cycle
        if not 0 <= cycle < self.n_cycles:
            raise ResultFileError(f"cycle {cycle} is out of range: run {self.name!r} has cycles 0..{self.n_cycles - 1}")
        return slice(cycle * n, (cycle + 1) * n + 1)


def torque_limits_at_cycle_ends(mf: np.ndarray, signed_limits: np.ndarray, intervals_per_cycle: int) -> np.ndarray:
    """(1 - mf) * limit at nodes n, 2n, ..., shape (cycles, halves); ``signed_limits`` (halves,)."""
    ends = np.arange(intervals_per_cycle, mf.shape[0], intervals_per_cycle)
    return (1.0 - mf[ends]) * np.asarray(signed_limits)[None, :]


def _as_attr(value: Any) -> Any:
    if value is None:
        return "none"
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, Path):
        return str(value)
    return value


def _write_run(group: h5py.Group, run: RunResult) -> None:
    for key, value in run.attrs.items():
        group.attrs[key] = _as_attr(value)
    group.attrs["urdf"] = run.urdf
    group.attrs["study"] = run.study
    group.attrs["fatigue_states"] = list(run.fatigue)
    units = {"t": "s", "q": "rad", "qdot": "rad/s", "tau_plus": "N m", "tau_minus": "N m",
             "cycle_costs": "cost", "torque_limits": "N m", "cycle_wall_time_s": "s"}
    arrays = {name: getattr(run, name) for name in units} | dict(run.fatigue) | {"fatigued": run.fatigued}
    units |= {name: "1" for name in run.fatigue} | {"fatigued": "1"}
    for name, unit in units.items():
        data = np.asarray(arrays[name], dtype=float)
        ds = group.create_dataset(name, data=data, compression="gzip" if data.size > 1000 else None)
        ds.attrs["unit"] = unit
    for name in ("q", "qdot", "tau_plus", "tau_minus"):
        group[name].attrs["joints"] = list(run.joint_names)
    for name in (*run.fatigue, "fatigued", "torque_limits"):
        group[name].attrs["actuators"] = list(run.actuator_names)
    group["cycle_costs"].attrs["terms"] = list(run.cost_terms)
    if run.windows is not None:
        group.create_dataset("windows", data=np.asarray(run.windows, dtype=WINDOW_DTYPE))


def _str_list(values: Any) -> tuple[str, ...]:
    return tuple(v.decode() if isinstance(v, bytes) else str(v) for v in values)


def _read_run(group: h5py.Group, name: str) -> RunResult:
    states = _str_list(group.attrs["fatigue_states"]) if "fatigue_states" in group.attrs else LEGACY_FATIGUE_STATES
    missing = [k for k in ("t", "q", "qdot", "tau_plus", "tau_minus", *states, "cycle_costs", "torque_limits") if k not in group]
    if missing:
        raise ResultFileError(f"run {name!r} lacks datasets {missing}; is it an OCP run written by fatigue_pin?")
    attrs = {k: (v.decode() if isinstance(v, bytes) else v) for k, v in group.attrs.items() if k not in ("urdf", "study", "fatigue_states")}
    attrs = {k: (v.item() if isinstance(v, np.generic) else v) for k, v in attrs.items()}
    return RunResult(
        name=name,
        attrs=attrs,
        t=group["t"][()],
        q=group["q"][()],
        qdot=group["qdot"][()],
        tau_plus=group["tau_plus"][()],
        tau_minus=group["tau_minus"][()],
        fatigue={s: group[s][()] for s in states},
        cycle_costs=group["cycle_costs"][()],
        torque_limits=group["torque_limits"][()],
        joint_names=_str_list(group["q"].attrs["joints"]),
        actuator_names=_str_list(group[states[0]].attrs["actuators"]),
        cost_terms=_str_list(group["cycle_costs"].attrs["terms"]),
        cycle_wall_time_s=group["cycle_wall_time_s"][()] if "cycle_wall_time_s" in group else np.zeros(0),
        windows=group["windows"][()] if "windows" in group else None,
        urdf=str(group.attrs.get("urdf", "")),
        study=_text(group.attrs.get("study", "")),
        fatigued=group["fatigued"][()] if "fatigued" in group else None,
    )


def _text(value: Any) -> str:
    return value.decode() if isinstance(value, bytes) else str(value)


def _copy_except(src: Path, dst: h5py.File, skip: set[str]) -> None:
    if not src.exists():
        return
    with h5py.File(src, "r") as old:
        for key, value in old.attrs.items():
            dst.attrs[key] = value
        for key in old:
            old.copy(old[key], dst, name=key)
    for key in skip:  # run names may be paths such as "sliding/torque_S10"
        if key in dst:
            del dst[key]


def _atomic_rewrite(path: Path, skip: set[str], fill: Any) -> None:
    """Write ``path`` anew: everything from the old file except the groups in ``skip``, then
    ``fill(h5file)``; the new file replaces the old one only once it is complete."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    try:
        with h5py.File(tmp, "w") as h5:
            _copy_except(path, h5, skip)
            fill(h5)
            h5.attrs["format"] = "fatigue_pin.results/1"
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def write_run(path: str | Path, run: RunResult) -> Path:
    """Add or replace run ``run.name`` in the HDF5 file ``path`` (atomic, crash-safe)."""

    def fill(h5: h5py.File) -> None:
        _write_run(h5.create_group(run.name), run)

    _atomic_rewrite(Path(path), {run.name}, fill)
    return Path(path)


def write_search(path: str | Path, name: str, rows: list[dict[str, Any]], attrs: dict[str, Any] | None = None) -> None:
    """Write the table of a max-cycles search as ``/search/<name>`` (atomic)."""

    table = np.array([(r["n_cycles"], r["converged"], r["status"].encode()[:40], r["iterations"], r["wall_time_s"]) for r in rows],
                     dtype=SEARCH_DTYPE)

    def fill(h5: h5py.File) -> None:
        grp = h5.require_group("search")
        if name in grp:
            del grp[name]
        ds = grp.create_dataset(name, data=table)
        for key, value in (attrs or {}).items():
            ds.attrs[key] = _as_attr(value)

    _atomic_rewrite(Path(path), set(), fill)


def check_output(path: str | Path) -> Path:
    """Check, before any work, that ``path`` can receive a result file.

    Its folder must exist (or be creatable) and be writable, ``path`` must not be a folder, and
    an existing file must be an HDF5 file (runs are added to it).

    Raises:
        ResultFileError: naming the path and what is wrong.
    """
    path = Path(path)
    if path.is_dir():
        raise ResultFileError(f"output {str(path)!r} is a folder; expected the path of an HDF5 result file")
    if path.exists():
        if not h5py.is_hdf5(path):
            raise ResultFileError(f"output {str(path)!r} exists and is not an HDF5 file; expected a new path or a result file")
        if not os.access(path, os.W_OK):
            raise ResultFileError(f"output {str(path)!r} is not writable")
    folder = path.parent
    existing = folder
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        raise ResultFileError(f"output folder {str(folder)!r} cannot be created: {str(existing)!r} is not a folder")
    probe = existing if existing != folder else folder
    if not os.access(probe, os.W_OK | os.X_OK):
        raise ResultFileError(f"output folder {str(probe)!r} is not writable; expected a folder you can write to")
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=folder, prefix=".fatigue_pin_probe_"):
            pass
    except OSError as exc:
        raise ResultFileError(f"output folder {str(folder)!r} is not writable ({exc.strerror or exc})") from None
    return path


def _open(path: str | Path) -> h5py.File:
    path = Path(path)
    if not path.is_file():
        raise ResultFileError(f"result file not found: {str(path)!r}")
    try:
        return h5py.File(path, "r")
    except OSError as exc:
        raise ResultFileError(f"{str(path)!r} is not a readable HDF5 file: {exc}") from exc


def list_runs(path: str | Path) -> list[str]:
    """Names of the OCP runs in a result file (groups holding a ``t`` dataset), sorted."""
    with _open(path) as h5:
        names: list[str] = []
        h5.visititems(lambda key, obj: names.append(key) if isinstance(obj, h5py.Group) and "t" in obj and "q" in obj else None)
    return sorted(names)


def read_run(path: str | Path, name: str | None = None) -> RunResult:
    """Read one run; ``name`` may be omitted when the file holds exactly one run."""
    runs = list_runs(path)
    if name is None:
        if len(runs) != 1:
            raise ResultFileError(f"{str(path)!r} holds {len(runs)} runs {runs}; choose one by name")
        name = runs[0]
    if name not in runs:
        raise ResultFileError(f"run {name!r} is not in {str(path)!r}; it holds {runs}")
    with _open(path) as h5:
        return _read_run(h5[name], name)


def read_search(path: str | Path) -> dict[str, np.ndarray]:
    """All max-cycles search tables of a file, by name."""
    with _open(path) as h5:
        if "search" not in h5:
            return {}
        return {k: h5["search"][k][()] for k in h5["search"]}


def config_json(obj: Any) -> str:
    """JSON text of a (nested) dataclass configuration, for the ``config`` attribute."""
    import dataclasses

    def default(o: Any) -> Any:
        if dataclasses.is_dataclass(o):
            return {f.name: getattr(o, f.name) for f in dataclasses.fields(o)}
        if isinstance(o, (np.ndarray, np.generic)):
            return o.tolist()
        if isinstance(o, Path):
            return str(o)
        return repr(o)

    return json.dumps(obj, default=default, sort_keys=True)
