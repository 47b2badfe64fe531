"""One job of a sweep on a Dask worker (:func:`run_job`): the run is built in a hidden partial
file, marked complete with its study and summary row, and renamed into place. A closed-loop
study (:mod:`fatigue_pin.io.mpc_study`) runs its closed loop, as ``fatigue-pin mpc`` does."""

from __future__ import annotations

import json
import math
import os
import socket
import time
from pathlib import Path
from typing import Any

from fatigue_pin.io.mpc_study import MpcStudy, is_closed_loop_table, run_mpc
from fatigue_pin.io.study import Study, StudyResult
from fatigue_pin.sweep.summary import SUMMARY_FORMAT

# -- one job on a worker -----------------------------------------------------------------------------


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _summarise(result: StudyResult) -> dict[str, Any]:
    """Status, repetitions, objective, iterations and run name of a finished run_study."""
    return {"status": "converged" if result.converged else "not converged", "repetitions": result.repetitions,
            "objective": result.objective, "iterations": result.iterations, "run": result.run.name if result.run is not None else ""}


def _summarise_closed_loop(run) -> dict[str, Any]:
    """The same of a closed loop's run (:func:`fatigue_pin.io.mpc_study.run_mpc`): its re-plans'
    status, the plant's repetitions, the cost of its cycles, the re-plans' iterations."""
    a = run.attrs
    return {"status": "converged" if a["converged"] else "not converged", "repetitions": int(a["repetitions"]),
            "objective": float(run.cycle_costs.sum()) if run.cycle_costs.size else math.nan,
            "iterations": int(a["iterations"]), "run": run.name}


def _job_study(text: str, job_id: str) -> Study | MpcStudy:
    """The study of a job's TOML text: a closed-loop study when it has [plant], [mpc] or a seed."""
    import tomllib

    if is_closed_loop_table(tomllib.loads(text)):
        return MpcStudy.from_toml(text, f"job {job_id}")
    return Study.from_toml(text, f"job {job_id}")


def _run(study: Study | MpcStudy, part: Path, resume: bool, cache_dir: str | None) -> dict[str, Any]:
    """Run a job's study into ``part`` (``resume``: continue the run stored there); its summary."""
    from fatigue_pin.io.study import run_study

    if isinstance(study, MpcStudy):
        return _summarise_closed_loop(run_mpc(study, part, resume=resume, cache_dir=cache_dir))
    return _summarise(run_study(study, part, resume=resume, cache_dir=cache_dir))


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
        study = _job_study(text, job_id)
        resume = part.exists() and h5py.is_hdf5(part)
        if not resume:
            _remove_leftovers(out, job_id)
        try:
            summary = _run(study, part, resume, cache_dir)
        except (ResultFileError, OSError):
            if not resume:
                raise
            _remove_leftovers(out, job_id)  # a partial file that cannot be resumed: start again
            summary = _run(study, part, False, cache_dir)
        row.update(summary)
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
