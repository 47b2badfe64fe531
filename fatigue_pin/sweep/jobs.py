"""Parameter sweeps: many studies from one base study, run on Dask (``docs/sweeps.md``).

A sweep file (TOML) names a base study (``base = "studies/x.toml"``, relative to the sweep file,
or an inline ``[base]`` table) and the changes to make to it: a ``[grid]`` of dotted keys to
lists of values (every combination is a job) and/or ``[[cases]]`` (each a table of dotted keys to
values; with a grid too, every case is combined with every grid point)::

    base = "curl.toml"

    [grid]
    "fatigue.S" = [10.0, 0.0]
    "horizon.kind" = ["sliding", "max-cycles"]

    [[cases]]
    "labels.cost" = "fatigue-torque"

    [[cases]]
    "labels.cost" = "torque"
    "costs.fatigue.weight" = 0.0

:meth:`Sweep.jobs` resolves every job to a validated :class:`~fatigue_pin.io.study.Study` whose id is
a hash of its TOML text. :func:`run_sweep` runs the jobs that have no complete result file in the
output folder on a Dask client, one file ``<id>.h5`` per job written atomically by the worker, and
writes ``summary.csv`` and ``summary.h5`` (one row per job). :func:`sweep_command` is the
``fatigue-pin sweep`` command: a local cluster (one single-threaded worker process per core), an
existing scheduler, or SLURM through dask-jobqueue.
"""

from __future__ import annotations

import copy
import csv
import hashlib
import itertools
import json
import math
import os
import socket
import sys
import time
import tomllib
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable

from fatigue_pin.core.errors import FatiguePinError
from fatigue_pin.io.study import Study, StudyError, StudyResult

Progress = Callable[[str], None]

#: Keys a sweep file may hold at its top level.
SWEEP_KEYS = ("base", "grid", "cases", "description")
#: Columns of the summary after the swept keys (``docs/sweeps.md``).
SUMMARY_COLUMNS = ("case", "job", "status", "repetitions", "objective", "iterations", "wall_time_s", "worker", "file", "run",
                   "reused", "error")
STATUSES = ("converged", "not converged", "error")
SUMMARY_FORMAT = "fatigue_pin.sweep/1"


class SweepError(FatiguePinError, ValueError):
    """A sweep file that cannot be used, or a sweep output folder that cannot receive results."""


# -- sweep files -----------------------------------------------------------------------------------


def _flatten(table: dict[str, Any], base: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """Dotted keys of a (nested) table: ``{"fatigue": {"S": 1}}`` -> ``{"fatigue.S": 1}``.

    TOML reads a bare dotted key ``fatigue.S = 1`` as nested tables and a quoted one
    ``"fatigue.S" = 1`` as one key; both end up as ``"fatigue.S"``. A table is split into its
    keys (merged into the base's table) where the base study has a table at that key; elsewhere
    it is one value (e.g. ``"fatigue.joints" = { elbow = { S = 0.0 } }`` adds a table).
    """
    out: dict[str, Any] = {}
    for key, value in table.items():
        dotted = f"{prefix}.{key}" if prefix else str(key)
        node: Any = base
        for part in dotted.split("."):
            node = node.get(part) if isinstance(node, dict) else None
        if isinstance(value, dict) and value and isinstance(node, dict):
            out.update(_flatten(value, base, dotted))
        else:
            out[dotted] = value
    return out


def study_id(text: str) -> str:
    """The id of a resolved study: the first 16 hex digits of the SHA-256 of its TOML text."""
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _show(values: dict[str, Any]) -> str:
    return ", ".join(f"{k} = {v!r}" for k, v in values.items()) or "the base study"


@dataclass(frozen=True)
class Job:
    """One study of a sweep.

    Attributes:
        index: position in the sweep (0-based; the order of :meth:`Sweep.jobs`).
        study: the resolved, validated study.
        values: the swept keys and their values for this job (case keys, then grid keys).
        case: index of the job's ``[[cases]]`` table (None in a sweep without cases).
        text: the study's TOML text (what the result file stores).
        id: :func:`study_id` of ``text``; the result file is ``<id>.h5``.
    """

    index: int
    study: Study
    values: dict[str, Any]
    text: str
    id: str
    case: int | None = None

    @property
    def file(self) -> str:
        return f"{self.id}.h5"


@dataclass
class Sweep:
    """A base study and the changes that make its jobs."""

    base: Study
    grid: dict[str, list[Any]] = field(default_factory=dict)
    cases: list[dict[str, Any]] = field(default_factory=list)
    source: str = "sweep"
    description: str = ""

    @classmethod
    def from_file(cls, path: str | Path) -> Sweep:
        """Read a sweep file; a relative ``base`` path is taken from the sweep file's folder."""
        path = Path(path)
        if not path.is_file():
            raise SweepError(f"sweep file not found: {str(path)!r}")
        try:
            data = tomllib.loads(path.read_text())
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
            raise SweepError(f"{path}: not valid TOML: {exc}") from None
        return cls.from_dict(data, root=path.parent, source=str(path))

    @classmethod
    def from_toml(cls, text: str, root: str | Path = ".", source: str = "sweep") -> Sweep:
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise SweepError(f"{source}: not valid TOML: {exc}") from None
        return cls.from_dict(data, root=root, source=source)

    @classmethod
    def from_dict(cls, data: dict[str, Any], root: str | Path = ".", source: str = "sweep") -> Sweep:
        """A sweep from its parsed table; errors are :class:`SweepError` naming the file and key."""
        if not isinstance(data, dict):
            raise SweepError(f"{source}: expected a table")
        unknown = sorted(set(data) - set(SWEEP_KEYS))
        if unknown:
            raise SweepError(f"{source}: unknown key {unknown[0]!r}; a sweep file has {list(SWEEP_KEYS)}")
        base = cls._base(data.get("base"), Path(root), source)
        grid_table = data.get("grid", {})
        if not isinstance(grid_table, dict):
            raise SweepError(f"{source}: grid = {grid_table!r}: expected a table of dotted keys to lists of values")
        grid = _flatten(grid_table, base.data)
        for key, values in grid.items():
            if not isinstance(values, list):
                raise SweepError(f"{source}: [grid] {key} = {values!r}: expected a list of values")
            if not values:
                raise SweepError(f"{source}: [grid] {key} is an empty list; expected at least one value")
            for value in values:  # each value alone, so the message names it
                try:
                    base.replace({key: value})
                except StudyError as exc:
                    raise SweepError(f"{source}: [grid] {key} = {value!r}: {exc}") from None
        raw_cases = data.get("cases", None)
        cases: list[dict[str, Any]] = []
        if raw_cases is not None:
            if not isinstance(raw_cases, list) or not all(isinstance(c, dict) for c in raw_cases):
                raise SweepError(f"{source}: cases must be an array of tables [[cases]]")
            if not raw_cases:
                raise SweepError(f"{source}: cases is an empty list; expected at least one [[cases]] table")
            for i, case in enumerate(raw_cases):
                flat = _flatten(case, base.data)
                if not flat:
                    raise SweepError(f"{source}: cases[{i}] is empty; expected dotted keys and values")
                both = sorted(set(flat) & set(grid))
                if both:
                    raise SweepError(f"{source}: cases[{i}] and [grid] both set {both[0]!r}")
                try:
                    base.replace(flat)
                except StudyError as exc:
                    raise SweepError(f"{source}: cases[{i}]: {exc}") from None
                cases.append(flat)
        description = data.get("description", "")
        if not isinstance(description, str):
            raise SweepError(f"{source}: description = {description!r}: expected a string")
        sweep = cls(base, grid, cases, source, description)
        sweep.jobs()  # every combination must be a valid study, and no two the same
        return sweep

    @staticmethod
    def _base(base: Any, root: Path, source: str) -> Study:
        if base is None:
            raise SweepError(f"{source}: missing key 'base': expected a study file path or a [base] table")
        if isinstance(base, str):
            path = Path(base) if Path(base).is_absolute() else root / base
            if not path.is_file():
                raise SweepError(f"{source}: base study not found: {base!r} (looked for {str(path)!r})")
            try:
                return Study.from_file(path)
            except FatiguePinError as exc:
                raise SweepError(f"{source}: base study {base!r}: {exc}") from None
        if isinstance(base, dict):
            try:
                return Study.from_dict(base)
            except StudyError as exc:
                raise SweepError(f"{source}: [base]: {exc}") from None
        raise SweepError(f"{source}: base = {base!r}: expected a study file path or a [base] table")

    @property
    def keys(self) -> list[str]:
        """Every swept key: the cases' (in order of appearance), then the grid's."""
        keys: list[str] = []
        for case in self.cases:
            keys += [k for k in case if k not in keys]
        return keys + [k for k in self.grid if k not in keys]

    def jobs(self) -> list[Job]:
        """Every job: each case combined with each grid point (cases outer, grid in file order)."""
        points = [dict(zip(self.grid, combo)) for combo in itertools.product(*self.grid.values())]
        jobs: list[Job] = []
        seen: dict[str, Job] = {}
        for c, case in enumerate(self.cases or [{}]):
            for point in points:
                values = {**copy.deepcopy(case), **copy.deepcopy(point)}
                try:
                    study = self.base.replace(values) if values else self.base
                except StudyError as exc:
                    raise SweepError(f"{self.source}: job {_show(values)}: {exc}") from None
                text = study.to_toml()
                job = Job(len(jobs), study, values, text, study_id(text), c if self.cases else None)
                if job.id in seen:
                    raise SweepError(f"{self.source}: jobs {_show(seen[job.id].values)} and {_show(values)} are the same study")
                seen[job.id] = job
                jobs.append(job)
        return jobs


# -- one job on a worker -----------------------------------------------------------------------------


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _summarise(result: StudyResult) -> dict[str, Any]:
    """Status, repetitions, objective, iterations and run name of a finished run_study."""
    return {"status": "converged" if result.converged else "not converged", "repetitions": result.repetitions,
            "objective": result.objective, "iterations": result.iterations, "run": result.run.name if result.run is not None else ""}


def partial_path(out_dir: Path, job_id: str) -> Path:
    """Where a worker builds the file of job ``job_id`` (hidden; renamed once complete)."""
    return Path(out_dir) / f".{job_id}.part.h5"


def read_job_file(path: str | Path, text: str) -> dict[str, Any]:
    """The summary row stored in a job's result file, once the file is checked complete and valid:
    readable, written by a sweep, holding the study ``text`` and its run.

    Raises:
        ResultFileError: naming what is missing.
    """
    import h5py

    from fatigue_pin.io.results import ResultFileError, list_runs, read_run

    path = Path(path)
    if not path.is_file():
        raise ResultFileError(f"{str(path)!r} does not exist")
    try:
        with h5py.File(path, "r") as h5:
            marked = "sweep" in h5
            if marked:
                stored = h5["sweep"].attrs.get("study", "")
                stored = stored.decode() if isinstance(stored, bytes) else str(stored)
                row = json.loads(h5["sweep"].attrs["row"])
            searches = "search" in h5
    except (OSError, KeyError, ValueError) as exc:
        raise ResultFileError(f"{str(path)!r} is not a readable sweep result: {exc}") from None
    if not marked:
        raise ResultFileError(f"{str(path)!r} was not completed by a sweep")
    if stored != text:
        raise ResultFileError(f"{str(path)!r} holds another study")
    name = row.get("run", "")
    if name:
        run = read_run(path, name)
        if run.study != text:
            raise ResultFileError(f"run {name!r} of {str(path)!r} holds another study")
    elif row.get("status") == "converged" or not searches or list_runs(path):
        raise ResultFileError(f"{str(path)!r} lacks its run")
    return row


def _finish(part: Path, final: Path, text: str, row: dict[str, Any]) -> None:
    """Mark the job file complete (``/sweep``: the study and the row) and rename it into place."""
    import h5py

    with h5py.File(part, "a") as h5:
        if "sweep" in h5:
            del h5["sweep"]
        g = h5.create_group("sweep")
        g.attrs["study"] = text
        g.attrs["row"] = json.dumps(row)
        g.attrs["format"] = SUMMARY_FORMAT
    with open(part, "rb+") as fh:
        os.fsync(fh.fileno())
    os.replace(part, final)
    _remove_leftovers(part.parent, final.stem)


def _remove_leftovers(out: Path, job_id: str) -> None:
    """Delete the hidden files of a job's attempts (partial file, its temporary copy and lock)."""
    for leftover in out.glob(f".*{job_id}.part.h5*"):
        leftover.unlink(missing_ok=True)


def run_job(text: str, job_id: str, out_dir: str, cache_dir: str | None = None) -> dict[str, Any]:
    """Run one job (on a Dask worker) and return its summary row.

    The run is written to the hidden ``.<id>.part.h5`` (a run started by a worker that died is
    resumed from it) and renamed to ``<id>.h5`` once complete. A job that raises gives a row with
    status ``error`` and no file; a file system error (``OSError``) is raised so Dask retries.
    """
    import h5py

    from fatigue_pin.io.results import ResultFileError
    from fatigue_pin.io.study import run_study

    out = Path(out_dir)
    final = out / f"{job_id}.h5"
    host = socket.gethostname()
    try:  # an earlier attempt finished after all (its worker died after the rename)
        return {**read_job_file(final, text), "reused": True}
    except ResultFileError:
        pass
    part = partial_path(out, job_id)
    t0 = time.perf_counter()
    row: dict[str, Any] = {"job": job_id, "file": final.name, "worker": host, "reused": False, "error": ""}
    try:
        study = Study.from_toml(text, f"job {job_id}")
        resume = part.exists() and h5py.is_hdf5(part)
        if not resume:
            _remove_leftovers(out, job_id)
        try:
            result = run_study(study, part, resume=resume, cache_dir=cache_dir)
        except (ResultFileError, OSError):
            if not resume:
                raise
            _remove_leftovers(out, job_id)  # a partial file that cannot be resumed: start again
            result = run_study(study, part, cache_dir=cache_dir)
        row.update(_summarise(result))
        row["wall_time_s"] = time.perf_counter() - t0
        if not part.exists():
            h5py.File(part, "w").close()
        _finish(part, final, text, row)
    except OSError:
        raise
    except Exception as exc:  # reported in the summary; the sweep goes on
        _remove_leftovers(out, job_id)
        row.update(status="error", repetitions=-1, objective=math.nan, iterations=-1, run="",
                   wall_time_s=time.perf_counter() - t0, error=_one_line(exc))
    return row


# -- the summary -----------------------------------------------------------------------------------


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return "" if math.isnan(value) else repr(value)
    if isinstance(value, (list, dict)):
        return json.dumps(value)
    return str(value)


def summary_rows(jobs: Iterable[Job], rows: dict[str, dict[str, Any]]) -> tuple[list[str], list[dict[str, Any]]]:
    """Columns and rows of the summary (a job without a row yet has status ``pending``)."""
    jobs = list(jobs)
    keys: list[str] = []
    for job in jobs:
        keys += [k for k in job.values if k not in keys]
    table = []
    for job in jobs:
        row = {**rows.get(job.id, {"job": job.id, "status": "pending", "file": job.file}), "case": job.case}
        table.append({**{k: job.values.get(k) for k in keys}, **{c: row.get(c) for c in SUMMARY_COLUMNS}})
    return keys + list(SUMMARY_COLUMNS), table


def write_summary(out: str | Path, jobs: Iterable[Job], rows: dict[str, dict[str, Any]]) -> tuple[Path, Path]:
    """Write ``summary.csv`` and ``summary.h5`` (the same table; each written atomically)."""
    import h5py
    import numpy as np

    out = Path(out)
    columns, table = summary_rows(jobs, rows)
    csv_path, h5_path = out / "summary.csv", out / "summary.h5"
    tmp = out / ".summary.csv.tmp"
    with open(tmp, "w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(columns)
        for row in table:
            writer.writerow([_cell(row[c]) for c in columns])
    os.replace(tmp, csv_path)

    fields, data = [], []
    for c in columns:
        values = [row[c] for row in table]
        present = [v for v in values if v is not None]
        if present and all(isinstance(v, bool) for v in present) and len(present) == len(values):
            fields.append((c, "?"))
            data.append(values)
        elif present and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in present):
            fields.append((c, "f8"))
            data.append([math.nan if v is None else float(v) for v in values])
        else:
            fields.append((c, h5py.string_dtype()))
            data.append([_cell(v) for v in values])
    array = np.empty(len(table), dtype=np.dtype(fields))
    for (name, _), values in zip(fields, data):
        array[name] = values
    tmp = out / ".summary.h5.tmp"
    with h5py.File(tmp, "w") as h5:
        ds = h5.create_dataset("summary", data=array)
        ds.attrs["columns"] = columns
        ds.attrs["swept"] = columns[: len(columns) - len(SUMMARY_COLUMNS)]
        h5.attrs["format"] = SUMMARY_FORMAT
    os.replace(tmp, h5_path)
    return csv_path, h5_path


def _parse(text: str) -> Any:
    if text == "":
        return None
    if text in ("true", "false"):
        return text == "true"
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    if text[:1] in "[{":
        try:
            return json.loads(text)
        except ValueError:
            pass
    return text


def read_summary(out: str | Path) -> tuple[list[str], list[str], list[dict[str, Any]]]:
    """``(swept keys, columns, rows)`` of ``out/summary.csv`` (values typed back)."""
    path = Path(out) / "summary.csv"
    if not path.is_file():
        raise SweepError(f"{str(out)!r} holds no sweep summary (summary.csv)")
    with open(path, newline="") as fh:
        reader = csv.reader(fh)
        columns = next(reader, [])
        rows = [dict(zip(columns, (_parse(v) for v in line))) for line in reader]
    if SUMMARY_COLUMNS[0] not in columns:
        raise SweepError(f"{str(path)!r} is not a sweep summary: it has no {SUMMARY_COLUMNS[0]!r} column")
    return columns[: columns.index(SUMMARY_COLUMNS[0])], columns, rows


# -- running a sweep -------------------------------------------------------------------------------


def check_folder(out: str | Path) -> Path:
    """Check, before any work, that ``out`` is (or can become) a writable folder."""
    from fatigue_pin.io.results import check_output

    out = Path(out)
    if out.exists() and not out.is_dir():
        raise SweepError(f"output {str(out)!r} is a file; expected a folder (one result file per job, summary.csv)")
    check_output(out / ".fatigue_pin_sweep_check.h5")  # the folder: creatable, writable (nothing is written there)
    return out.resolve()


@dataclass
class SweepOutcome:
    """What :func:`run_sweep` did: every job, its row, how many were solved now, the summary files."""

    jobs: list[Job]
    rows: dict[str, dict[str, Any]]
    ran: int
    summary: tuple[Path, Path]

    @property
    def errors(self) -> int:
        return sum(1 for r in self.rows.values() if r.get("status") == "error")


def plan(jobs: list[Job], out: Path) -> tuple[dict[str, dict[str, Any]], list[Job]]:
    """Rows of the jobs whose files are complete and valid (``reused``) and the jobs to run."""
    from fatigue_pin.io.results import ResultFileError

    done: dict[str, dict[str, Any]] = {}
    pending: list[Job] = []
    for job in jobs:
        try:
            done[job.id] = {**read_job_file(out / job.file, job.text), "reused": True}
        except ResultFileError:
            pending.append(job)
    return done, pending


def _line(job: Job, row: dict[str, Any]) -> str:
    what = row.get("status", "?")
    if what == "error":
        what = f"ERROR {row.get('error', '')}"
    else:
        what += f", {row.get('repetitions')} repetitions, {row.get('iterations')} iterations"
    return f"{job.id} ({_show(job.values)}): {what}, {float(row.get('wall_time_s') or 0.0):.1f} s on {row.get('worker', '?')}"


def run_sweep(jobs: list[Job], out: str | Path, client: Any = None, cache_dir: str | Path | None = None, retries: int = 2,
              progress: Progress | None = None, bar: bool = False, pending: list[Job] | None = None,
              done: dict[str, dict[str, Any]] | None = None) -> SweepOutcome:
    """Run every job without a complete file in ``out`` on the Dask ``client``; write the summary.

    Args:
        jobs: the sweep's jobs (:meth:`Sweep.jobs`).
        out: output folder (must be visible to the workers at the same path).
        client: a ``distributed.Client`` (needed only when some job is not done).
        cache_dir: compiled-code cache folder passed to every job.
        retries: Dask retries of a job whose worker raised a file system error.
        progress: called with one line per finished job.
        bar: show a tqdm progress bar on stderr.
        pending: the jobs still to run, from :func:`plan`, when already computed.
        done: the jobs already done, from :func:`plan`, when already computed.
    """
    from distributed import as_completed

    say = progress or (lambda _: None)
    out = Path(out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    if pending is None or done is None:
        done, pending = plan(jobs, out)
    rows = dict(done)
    summary = write_summary(out, jobs, rows)
    if not pending:
        return SweepOutcome(jobs, rows, 0, summary)
    if client is None:
        raise SweepError("run_sweep: a Dask client is needed to run the jobs that are not done")
    cache = str(Path(cache_dir).resolve()) if cache_dir else None
    futures = {client.submit(run_job, job.text, job.id, str(out), cache, key=f"fatigue-pin-job-{job.id}-{uuid.uuid4().hex[:8]}",
                             retries=retries, pure=False): job for job in pending}
    ticker = None
    if bar:
        from tqdm import tqdm

        ticker = tqdm(total=len(pending), unit="job", file=sys.stderr, dynamic_ncols=True)
    last = time.monotonic()
    try:
        for fut in as_completed(futures):
            job = futures[fut]
            try:
                row = fut.result()
            except Exception as exc:  # the worker died too often, or kept raising: report and go on
                row = {"job": job.id, "status": "error", "repetitions": -1, "objective": math.nan, "iterations": -1,
                       "wall_time_s": math.nan, "worker": "", "file": "", "run": "", "reused": False, "error": _one_line(exc)}
            if row.get("status") == "error":
                row["file"] = ""
            rows[job.id] = row
            (ticker.write if ticker is not None else say)(_line(job, row))
            if ticker is not None:
                ticker.update()
            if time.monotonic() - last > 2.0:
                summary = write_summary(out, jobs, rows)
                last = time.monotonic()
    finally:
        if ticker is not None:
            ticker.close()
        for fut in futures:
            fut.release()
        summary = write_summary(out, jobs, rows)
    for job in pending:  # leftovers of attempts whose workers died
        if (out / job.file).exists():
            _remove_leftovers(out, job.id)
    return SweepOutcome(jobs, rows, len(pending), summary)


# -- clusters ----------------------------------------------------------------------------------------


def local_cluster(workers: int | None = None):
    """One single-threaded worker process per core, everything on 127.0.0.1."""
    from distributed import LocalCluster

    n = workers or os.cpu_count() or 1
    return LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                        dashboard_address="127.0.0.1:0", scheduler_port=0)


def slurm_cluster(queue: str | None = None, walltime: str = "01:00:00", cores: int = 1, memory: str = "4GB",
                  interface: str | None = None, host: str | None = None, **kwargs: Any):
    """A dask-jobqueue ``SLURMCluster``: each SLURM job runs ``cores`` single-threaded workers.

    The workers run this Python (``sys.executable``) with this ``PYTHONPATH`` and one OpenMP
    thread. ``interface`` (e.g. ``ib0``) or ``host`` says where the scheduler listens (it must be
    reachable from the compute nodes); the dashboard listens on 127.0.0.1 (reach it over ssh).
    """
    try:
        from dask_jobqueue import SLURMCluster
    except ImportError:
        raise SweepError("--slurm needs dask-jobqueue: pip install 'fatigue_pin[slurm]' (or dask-jobqueue)") from None
    prologue = ["export OMP_NUM_THREADS=1"]
    if os.environ.get("PYTHONPATH"):
        prologue.append(f"export PYTHONPATH={os.environ['PYTHONPATH']}")
    scheduler_options = {"dashboard_address": "127.0.0.1:0", **kwargs.pop("scheduler_options", {})}
    if host is not None:
        scheduler_options["host"] = host
    return SLURMCluster(queue=queue, walltime=walltime, cores=cores, processes=cores, memory=memory,
                        interface=interface, python=sys.executable, job_script_prologue=prologue,
                        scheduler_options=scheduler_options, **kwargs)


def _dashboard(client: Any) -> str:
    """The line saying where the Dask dashboard is, or that it is off: it needs bokeh (the
    ``dashboard`` extra, ``pip install 'fatigue_pin[dashboard]'``)."""
    try:
        if "dashboard" in client.scheduler_info().get("services", {}):
            return f"dashboard: {client.dashboard_link}"
    except Exception:  # noqa: BLE001 - no dashboard is not an error
        pass
    import importlib.util

    if importlib.util.find_spec("bokeh") is None:
        return "dashboard: off (it needs bokeh: pip install 'fatigue_pin[dashboard]')"
    return "dashboard: off (the scheduler serves none)"


def sweep_command(sweep_file: str | Path, out: str | Path, scheduler: str | None = None, slurm: bool = False,
                  workers: int | None = None, queue: str | None = None, walltime: str | None = None,
                  cores: int | None = None, memory: str | None = None, interface: str | None = None,
                  cache_dir: str | Path | None = None, retries: int = 2, progress: Progress = print,
                  bar: bool | None = None) -> int:
    """``fatigue-pin sweep``: read the sweep, check ``out``, run what is not done, print the outcome.

    Returns the exit code: 0, or 1 when some job ended in an error.
    """
    slurm_options = {"--queue": queue, "--walltime": walltime, "--cores": cores, "--memory": memory, "--interface": interface}
    given = [k for k, v in slurm_options.items() if v is not None]
    if given and not slurm:
        raise SweepError(f"{given[0]} applies to --slurm only")
    if workers is not None and workers < 1:
        raise SweepError(f"--workers {workers}: expected an integer >= 1")
    if workers is not None and scheduler:
        raise SweepError("--workers applies to the local cluster and --slurm, not to --scheduler")
    if cores is not None and cores < 1:
        raise SweepError(f"--cores {cores}: expected an integer >= 1")
    sweep = Sweep.from_file(sweep_file)
    jobs = sweep.jobs()
    out = check_folder(out)
    done, pending = plan(jobs, out)
    progress(f"{len(jobs)} jobs: {len(done)} already done, {len(pending)} to run; results in {out}")
    if bar is None:
        bar = sys.stderr.isatty()
    if not pending:
        outcome = run_sweep(jobs, out, None, pending=pending, done=done)
    else:
        from distributed import Client

        cluster = None
        if scheduler:
            client = Client(scheduler, timeout="30s")
        elif slurm:
            cluster = slurm_cluster(queue, walltime or "01:00:00", cores or 1, memory or "4GB", interface)
            cluster.scale(n=min(len(pending), workers or len(pending)))
            client = Client(cluster)
        else:
            cluster = local_cluster(workers)
            client = Client(cluster)
        try:
            progress(_dashboard(client))
            outcome = run_sweep(jobs, out, client, cache_dir=cache_dir, retries=retries, progress=progress, bar=bar,
                                pending=pending, done=done)
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
    counts = {s: sum(1 for r in outcome.rows.values() if r.get("status") == s) for s in STATUSES}
    progress(f"{counts['converged']} converged, {counts['not converged']} not converged, {counts['error']} errors "
             f"({outcome.ran} run now); wrote {outcome.summary[0]} and {outcome.summary[1].name}")
    return 1 if outcome.errors else 0
