"""OCP results in HDF5: one group per run, written atomically, read back as :class:`RunResult`.

Layout (``docs/results.md``)::

    /<run name>/                     attributes: horizon, cost, preset, S, F, R, LD, LR, n_cycles,
                                     converged, status, wall_time_s, build_time_s, iterations,
                                     solver, model, weights (JSON), fatigue_params (JSON),
                                     study (the study's TOML text, when run from a study),
                                     urdf (the model's URDF text)
        t            (nodes,)              s
        q, qdot      (nodes, nq)           rad, rad/s or m, m/s attributes joints, units (one per
                                           joint), and on q joint_kinds (revolute, prismatic)
        tau_halves   (intervals, halves)   N m or N, every actuator half's (none for a passive joint),
                                           attributes actuators, units (layouts 1-2: tau_plus, tau_minus)
        unit_controls (intervals, units)   a muscle run's, instead of tau_halves: every unit's control
                                           (a muscle's activation, 1; a residual half's torque, N m);
                                           group attributes actuation = "muscles", muscle_names (JSON),
                                           muscles (the muscle file's text); extras/muscle_force,
                                           extras/joint_torque
        <state>      (nodes, halves)       1, one dataset per fatigue state the models declare
                                           (Xia: ma, mr, mf; group attribute fatigue_states lists
                                           them; NaN in the columns of halves without the state)
        cycle_costs  (cycles, terms)       weighted cost       attribute terms
        torque_limits (cycles, halves)     N m or N (attribute units), (1 - mf) * tau_limit at the
                                           end of each cycle
        cycle_wall_time_s (cycles,)        s, solve time attributed to each kept cycle
        windows      (windows,) table      sliding horizon only: index, first_cycle, status,
                                           converged, iterations, wall_time_s, objective
        extras/<name>                      further arrays of a driver (closed loop: docs/mpc.md)
    /search/<table>                  max-cycles searches (fatigue_pin.drivers.search), one row per solve:
                                     n_cycles, converged, status, iterations, wall_time_s, kind
                                     (how it ended), guess (what started it), constraint_violation;
                                     attributes: run (the best run's name), max_cycles, the labels
    /searched/<table>/N<n>           the converged solution of every N the search tried

The root attribute ``format`` is ``fatigue_pin.results/<layout>`` (:data:`LAYOUT`, now 3: the
torques of the halves that exist, ``tau_halves``; 2: every run names its fatigue states in
``fatigue_states``); readers refuse a newer layout and still read layouts 1 and 2.

Every write takes the file's lock (``flock`` of ``.<name>.lock`` beside it, so concurrent
writers take turns and none loses another's update), copies the current file's bytes beside it,
edits only the changed group in the copy, fsyncs it and renames it over the old one
(``os.replace``), so a crash, a kill or a full disk at any moment leaves either the old or the
new file, both complete and readable, and a write costs about the same whatever the file holds.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from fatigue_pin.core.errors import FatiguePinError, ResultFileError
from fatigue_pin.core.files import atomic_write, check_folder, check_output_dir, check_space, clone, locked, through_links
from fatigue_pin.drivers.run import (
    FAILED_WINDOW_SUFFIX,
    IN_PROGRESS_SUFFIX,
    RUN_ATTRIBUTES,
    RUN_NAME_GRAMMAR,
    SEARCH_DTYPE,
    WINDOW_DTYPE,
    RunResult,
    check_run_name,
    torque_limits_at_cycle_ends,
)
from fatigue_pin.io.run_group import LEGACY_FATIGUE_STATES, as_attr, attr_value, read_run_group, text_of, write_run_group

__all__ = [
    "FAILED_WINDOW_SUFFIX", "RUN_ATTRIBUTES", "SEARCH_DTYPE", "WINDOW_DTYPE", "ResultFile", "ResultFileError", "RunResult",
    "check_output", "check_output_dir", "check_run_slot", "delete_run", "list_runs", "read_run", "read_search", "read_search_attrs", "torque_limits_at_cycle_ends",
    "write_run", "write_search",
]

LAYOUT = 3
#: The ``format`` attribute of files this version writes.
FORMAT = f"fatigue_pin.results/{LAYOUT}"
_FORMAT_PREFIX = "fatigue_pin.results/"
#: File-creation settings: free space is tracked across sessions, so replacing a run reuses the
#: space of the old one instead of growing the file.
_CREATE = {"fs_strategy": "fsm", "fs_persist": True, "fs_threshold": 1}
#: A file is compacted once it is larger than twice its size after its last compaction plus this.
_COMPACT_SLACK = 1 << 20


def _layout_of(h5: h5py.File, path: Path) -> int | None:
    """The layout version of an open file (None: no ``format`` attribute, e.g. forward studies);
    refuses a newer layout or a foreign format."""
    if "format" not in h5.attrs:
        return None
    fmt = text_of(h5.attrs["format"])
    number = fmt[len(_FORMAT_PREFIX):] if fmt.startswith(_FORMAT_PREFIX) else ""
    if not number.isdigit():
        raise ResultFileError(f"{str(path)!r} has format {fmt!r}; expected a fatigue_pin result file ({FORMAT!r})")
    if int(number) > LAYOUT:
        raise ResultFileError(f"{str(path)!r} was written by a newer fatigue_pin (layout {int(number)}); "
                              f"this version reads layouts up to {LAYOUT}")
    return int(number)


def _io_error(path: Path, exc: OSError) -> ResultFileError:
    """A one-line error for an OSError while writing ``path`` (the previous file is unchanged)."""
    if exc.errno in (errno.ENOSPC, errno.EDQUOT) or "No space left" in str(exc):
        return ResultFileError(f"cannot write {str(path)!r}: the disk is full (no space left on device); "
                               "the previous file is unchanged")
    reason = exc.strerror or str(exc).splitlines()[0]
    return ResultFileError(f"cannot write {str(path)!r}: {reason}; the previous file is unchanged")


def _compact(src: Path, dst: Path) -> None:
    """Rewrite ``src`` object by object into a new file at ``dst`` created with :data:`_CREATE`
    (files of layout 1, or written without persistent free-space tracking; once per file),
    naming the fatigue states of runs that predate ``fatigue_states``."""
    with h5py.File(src, "r") as old, h5py.File(dst, "w", **_CREATE) as new:
        for key, value in old.attrs.items():
            new.attrs[key] = value
        for key in old:
            old.copy(old[key], new, name=key)
        runs: list[str] = []
        new.visititems(lambda key, obj: runs.append(key) if isinstance(obj, h5py.Group) and "t" in obj and "q" in obj else None)
        for key in runs:
            if "fatigue_states" not in new[key].attrs:
                new[key].attrs["fatigue_states"] = [s for s in LEGACY_FATIGUE_STATES if s in new[key]]


def _prepare(path: Path, tmp: Path) -> int | None:
    """Put at ``tmp`` a copy of ``path`` (an empty new file if there is none) to be edited.

    The copy is a byte copy, unless the file is of an older layout, lacks persistent free-space
    tracking, or has more than doubled (plus 1 MiB) since it was last compacted (HDF5 does not
    reuse all the space of deleted groups): then it is rewritten object by object, once in a
    while, so a file's size stays within about twice its contents. Returns the size of a new or
    compacted file (None for a byte copy).
    """
    if not path.exists():
        h5py.File(tmp, "w", **_CREATE).close()
        return 0
    with _open(path) as old:  # refuses a damaged file, a foreign one or a newer layout
        layout = _layout_of(old, path)
        persistent = bool(old.id.get_create_plist().get_file_space_strategy()[1])
        compacted = int(old.attrs.get("compacted_bytes", 0))
    if layout == LAYOUT and persistent and path.stat().st_size <= 2 * compacted + _COMPACT_SLACK:
        clone(path, tmp)
        return None
    _compact(path, tmp)
    return tmp.stat().st_size


def _check_room(path: Path, new_bytes: int) -> None:
    """Refuse a write that cannot fit before HDF5 starts it: a copy of the file plus the new data
    (with a margin for HDF5's metadata). HDF5 failing to write in the middle of an edit leaves its
    library state in this process damaged (later calls may crash), so a full disk is detected
    here whenever it can be."""
    old = path.stat().st_size if path.exists() else 0
    need = old + 2 * new_bytes + (64 << 10)
    try:
        st = os.statvfs(path.parent)
    except OSError:
        return
    free = st.f_bavail * st.f_frsize
    if free < need:
        raise ResultFileError(
            f"cannot write {str(path)!r}: the disk is full ({free} bytes free, about {need} needed); "
            "the previous file is unchanged"
        )


def _atomic_rewrite(path: Path, skip: set[str], fill: Any, new_bytes: int = 0) -> None:
    """Change ``path``: delete the groups in ``skip``, then ``fill(h5file)``.

    Under the file's lock, the current file is copied byte for byte beside it (``FILE.tmp``), the
    copy is edited with h5py, flushed and fsynced, and renamed over the original
    (``os.replace``). A write costs a copy of the file's bytes plus the new data, whatever the
    file holds; a kill, a crash or a full disk at any moment leaves the previous file unchanged.

    Raises:
        ResultFileError: the existing file cannot be read (damaged, not HDF5, newer layout), or
            the write fails (full disk, permissions), naming the path.
    """
    path = through_links(path)  # a symbolic link is written through: the link stays, its target changes

    def write(tmp: Path) -> None:
        compacted = _prepare(path, tmp)
        with h5py.File(tmp, "a") as h5:
            if compacted is not None:
                h5.attrs["compacted_bytes"] = compacted
            for key in skip:  # run names may be paths such as "sliding/torque_S10"
                if key in h5:
                    del h5[key]
            fill(h5)
            h5.attrs["format"] = FORMAT

    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with locked(path.with_name(f".{path.name}.lock")):
            _check_room(path, new_bytes)
            atomic_write(path, write, tmp=path.with_name(path.name + ".tmp"))
    except OSError as exc:
        raise _io_error(path, exc) from exc


def _is_run(obj: Any) -> bool:
    return isinstance(obj, h5py.Group) and "t" in obj and "q" in obj


def _check_slot(h5: h5py.File, name: str, path: Path) -> bool:
    """Whether ``name`` can take a run in the open file ``h5`` (True: it holds a run, which the
    new one replaces). A run never lands on anything but a run of the same name: not on the
    group of other runs, a search table or any other object, and not inside another run.

    Raises:
        ResultFileError: naming what is there.
    """
    segments = name.split("/")
    for k in range(1, len(segments)):
        parent = "/".join(segments[:k])
        if parent in h5 and (not isinstance(h5[parent], h5py.Group) or _is_run(h5[parent])):
            raise ResultFileError(f"run name {name!r} lies inside {'run' if _is_run(h5[parent]) else 'dataset'} {parent!r} of "
                                  f"{str(path)!r}; expected a name that is not inside another run")
    if name not in h5:
        return False
    obj = h5[name]
    if _is_run(obj):
        return True
    inside = sorted(f"{name}/{k}" for k, v in obj.items() if isinstance(v, h5py.Group)) if isinstance(obj, h5py.Group) else []
    what = f"the group of {inside}" if inside else ("a dataset" if isinstance(obj, h5py.Dataset) else "a group that is no run")
    raise ResultFileError(f"run name {name!r} is {what} in {str(path)!r}; a run replaces only a run of the same name: "
                          "expected a new name or the name of a run")


def check_run_slot(path: str | Path, name: str, internal: bool = False) -> str:
    """Check, before any work, that run ``name`` follows the grammar
    (:func:`~fatigue_pin.drivers.run.check_run_name`) and can be written to ``path`` without
    replacing anything but a run of the same name (a missing file: any valid name)."""
    check_run_name(name, internal)
    path = Path(path)
    if path.exists():
        with _open(path) as h5:
            _check_slot(h5, name, path)
    return name


def write_run(path: str | Path, run: RunResult) -> Path:
    """Add run ``run.name`` to the HDF5 file ``path``, or replace the run of that name (atomic,
    crash-safe); a name that collides with anything else in the file is refused (:func:`check_run_slot`)."""
    path = Path(path)
    check_run_name(run.name, internal=True)

    def fill(h5: h5py.File) -> None:
        if _check_slot(h5, run.name, path):  # on the copy: the file is unchanged if this raises
            del h5[run.name]
        write_run_group(h5.create_group(run.name), run)

    arrays = [run.t, run.q, run.qdot, run.half_torques(), run.cycle_costs, run.torque_limits, *run.fatigue.values(),
              *run.extras.values()]
    size = sum(np.asarray(a).nbytes for a in arrays) + len(run.urdf) + len(run.study)
    _atomic_rewrite(path, set(), fill, new_bytes=size)
    return path


def delete_run(path: str | Path, name: str) -> None:
    """Remove run ``name`` from the file ``path`` (atomic); only a run is ever removed, and a
    missing file or run leaves everything as it is."""
    path = Path(path)
    check_run_name(name, internal=True)
    if not path.exists() or name not in list_runs(path, failed_windows=True):
        return

    def fill(h5: h5py.File) -> None:
        if _check_slot(h5, name, path):
            del h5[name]

    _atomic_rewrite(path, set(), fill)


def write_search(path: str | Path, name: str, rows: list[dict[str, Any]], attrs: dict[str, Any] | None = None) -> None:
    """Write the table of a max-cycles search as ``/search/<name>`` (atomic), one row per solve:
    n_cycles, converged, IPOPT status, iterations, wall_time_s, kind (how it ended,
    :func:`fatigue_pin.ocp.solver.failure_kind`), guess (what started it: ``warm N=<n>`` or the guess
    name) and constraint_violation (IPOPT's inf_pr at the last iterate)."""

    table = np.array([(r["n_cycles"], r["converged"], r["status"].encode()[:40], r["iterations"], r["wall_time_s"],
                       str(r.get("kind", "")).encode()[:24], str(r.get("guess", "")).encode()[:24],
                       float(r.get("constraint_violation", np.nan))) for r in rows], dtype=SEARCH_DTYPE)

    check_run_name(name, internal=True)
    if "/" in name:
        raise ResultFileError(f"search table name {name!r}: expected one segment ({RUN_NAME_GRAMMAR})")

    def fill(h5: h5py.File) -> None:
        if "search" in h5 and not isinstance(h5["search"], h5py.Group) or "search" in h5 and _is_run(h5["search"]):
            raise ResultFileError(f"'search' in {str(path)!r} is not the group of search tables; expected a result file "
                                  "written by fatigue_pin")
        grp = h5.require_group("search")
        if name in grp:
            del grp[name]
        ds = grp.create_dataset(name, data=table)
        for key, value in (attrs or {}).items():
            ds.attrs[key] = as_attr(value)

    _atomic_rewrite(Path(path), set(), fill)


def check_output(path: str | Path) -> Path:
    """Check, before any work, that ``path`` can receive a result file.

    Its folder must exist (or be creatable) and be writable, ``path`` must not be a folder, an
    existing file must be a result file this version can read and extend (HDF5, complete, not
    of a newer layout), and the disk must have room for a copy of it (every write copies the
    file beside it before renaming it over the old one).

    Raises:
        ResultFileError: naming the path and what is wrong.
    """
    path = through_links(path)  # a symbolic link: its target is what is written
    if path.is_dir():
        raise ResultFileError(f"output {str(path)!r} is a folder; expected the path of an HDF5 result file")
    size = 0
    if path.exists():
        if not path.is_file():
            raise ResultFileError(f"output {str(path)!r} is not a regular file; expected the path of an HDF5 result file")
        if not os.access(path, os.R_OK):
            raise ResultFileError(f"output {str(path)!r} is not readable (permission denied); runs are added to an existing file")
        if not h5py.is_hdf5(path):
            raise ResultFileError(f"output {str(path)!r} exists and is not an HDF5 file; expected a new path or a result file")
        with _open(path):  # damaged or of a newer layout: refused now, not after the solve
            pass
        if not os.access(path, os.W_OK):
            raise ResultFileError(f"output {str(path)!r} is not writable")
        size = path.stat().st_size
    folder = path.parent
    check_folder(folder, f"output folder {str(folder)!r}")
    check_space(folder, size + (64 << 10), f"adding a run to {str(path)!r}")
    return path


def _open(path: str | Path) -> h5py.File:
    """Open a result file for reading; every way it can be unusable is a one-line ResultFileError."""
    path = Path(path)
    if path.is_dir():
        raise ResultFileError(f"{str(path)!r} is a folder; expected an HDF5 result file")
    if not path.exists():
        raise ResultFileError(f"result file not found: {str(path)!r}; expected an HDF5 file written by fatigue_pin")
    if not os.access(path, os.R_OK):
        raise ResultFileError(f"result file {str(path)!r} is not readable (permission denied)")
    if not h5py.is_hdf5(path):
        raise ResultFileError(f"{str(path)!r} is not a readable HDF5 file: it lacks the HDF5 signature; "
                              "expected a result file written by fatigue_pin")
    try:
        h5 = h5py.File(path, "r")
    except OSError as exc:
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise ResultFileError(f"{str(path)!r} is not a readable HDF5 file: it is truncated or damaged ({reason}); "
                              "expected a complete result file") from None
    try:
        with _reading(f"the layout of {str(path)!r}"):  # a damaged root object raises KeyError, RuntimeError, ...
            _layout_of(h5, path)
    except BaseException:
        h5.close()
        raise
    return h5


def _run_names(h5: h5py.File) -> list[str]:
    names: list[str] = []
    h5.visititems(lambda key, obj: names.append(key) if isinstance(obj, h5py.Group) and "t" in obj and "q" in obj else None)
    return sorted(names)


def _main_runs(names: list[str]) -> list[str]:
    """``names`` without the failed windows of sliding runs and the runs in progress."""
    return [n for n in names if not n.endswith(FAILED_WINDOW_SUFFIX) and not n.endswith(IN_PROGRESS_SUFFIX)]


@contextlib.contextmanager
def _reading(what: str):
    """Any failure of h5py or numpy while reading ``what`` of an open file (a damaged file can
    raise RuntimeError, KeyError, IndexError, TypeError, UnicodeDecodeError, ...) becomes one
    ResultFileError naming it; the project's own errors pass as they are."""
    try:
        yield
    except FatiguePinError:
        raise
    except Exception as exc:  # noqa: BLE001 - whatever a damaged file makes h5py raise
        reason = str(exc).splitlines()[0] if str(exc) else ""
        raise ResultFileError(f"{what} cannot be read ({type(exc).__name__}: {reason}); the file is damaged") from None


def list_runs(path: str | Path, failed_windows: bool = False) -> list[str]:
    """Names of the OCP runs in a result file (groups holding a ``t`` dataset), sorted; the
    failed windows of sliding runs (``*_failed_window``) only with ``failed_windows=True``."""
    with _open(path) as h5, _reading(f"the groups of {str(path)!r}"):
        names = _run_names(h5)
    return names if failed_windows else _main_runs(names)


def read_run(path: str | Path, name: str | None = None) -> RunResult:
    """Read one run; ``name`` may be omitted when the file holds exactly one run (a sliding
    run's failed window, ``*_failed_window``, does not count)."""
    with _open(path) as h5:
        with _reading(f"the groups of {str(path)!r}"):
            runs = _run_names(h5)
        if name is None:
            main = _main_runs(runs)
            if not main:
                raise ResultFileError(f"{str(path)!r} holds no run; expected a result file with a run (it may hold "
                                      f"only search tables or failed windows: {runs})")
            if len(main) != 1:
                raise ResultFileError(f"{str(path)!r} holds {len(main)} runs {main}; choose one by name (--run NAME)")
            name = main[0]
        if name not in runs:
            shown = runs if len(runs) <= 12 else runs[:12] + [f"... {len(runs) - 12} more"]
            raise ResultFileError(f"run {name!r} is not in {str(path)!r}; it holds {shown}")
        with _reading(f"run {name!r} in {str(path)!r}"):
            return read_run_group(h5[name], name)


def read_search(path: str | Path) -> dict[str, np.ndarray]:
    """All max-cycles search tables of a file, by name."""
    with _open(path) as h5, _reading(f"the search tables of {str(path)!r}"):
        if "search" not in h5:
            return {}
        return {k: h5["search"][k][()] for k in h5["search"]}


def read_search_attrs(path: str | Path) -> dict[str, dict[str, Any]]:
    """The attributes of every search table of a file, by name: ``run`` (the best run's name),
    ``max_cycles`` (the largest N converged so far), the labels, and ``interrupted`` (``SIGINT``,
    ``SIGTERM``) while a search stopped by a signal has not been resumed to its end."""
    with _open(path) as h5, _reading(f"the search tables of {str(path)!r}"):
        if "search" not in h5:
            return {}
        return {k: {a: attr_value(v) for a, v in h5["search"][k].attrs.items()} for k in h5["search"]}


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


class ResultFile:
    """An HDF5 result file as the :class:`~fatigue_pin.drivers.run.RunStore` of a driver: every
    write is atomic (see :func:`write_run`)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)

    def runs(self) -> list[str]:
        return list_runs(self.path, failed_windows=True) if self.path.exists() else []

    def read(self, name: str) -> RunResult:
        return read_run(self.path, name)

    def write(self, run: RunResult) -> None:
        write_run(self.path, run)

    def tables(self) -> dict[str, np.ndarray]:
        return read_search(self.path) if self.path.exists() else {}

    def write_table(self, name: str, rows: list[dict[str, Any]], attrs: dict[str, Any]) -> None:
        write_search(self.path, name, rows, attrs)

    def delete(self, name: str) -> None:
        delete_run(self.path, name)

    def __repr__(self) -> str:
        return f"ResultFile({str(self.path)!r})"
