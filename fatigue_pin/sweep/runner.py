"""Running a sweep: check the output folder, find the jobs already done, run the others on a Dask
client and write the summary as jobs finish (:func:`run_sweep`); ``fatigue-pin sweep``
(:func:`sweep_command`)."""

from __future__ import annotations

import math
import sys
import time
import uuid
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from fatigue_pin.sweep import cluster as clusters
from fatigue_pin.sweep.jobs import _one_line, _remove_leftovers, read_job_file, run_job
from fatigue_pin.sweep.plan import Job, Sweep, SweepError, _show
from fatigue_pin.sweep.summary import STATUSES, write_summary

Progress = Callable[[str], None]

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
    slurm_settings = clusters.SlurmSettings(**{k.lstrip("-"): v for k, v in slurm_options.items() if v is not None})
    if scheduler:
        clusters.scheduler_address(scheduler)  # its form, before any work (it is reached only if a job is to run)
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
            client = clusters.connect_scheduler(scheduler)
        elif slurm:
            cluster = clusters.slurm_cluster(slurm_settings)
            cluster.scale(n=min(len(pending), workers or len(pending)))
            client = Client(cluster)
        else:
            cluster = clusters.local_cluster(workers)
            client = Client(cluster)
        try:
            progress(clusters.dashboard(client))
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
