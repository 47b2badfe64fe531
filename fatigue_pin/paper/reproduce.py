"""The demo and the reproduction of the paper's study, as plain functions over the API.

``demo(out)`` solves the sliding-horizon curl to exhaustion on defaults and writes its HDF5 file,
figures and replay HTML. ``reproduce(out)`` runs the whole study: forward studies, full-horizon
maximum repetitions and sliding horizon for the three costs with S = 10 and S = 0, on several
processes, then writes figures, replays and ``report.md`` (each table of the paper beside ours).
"""

from __future__ import annotations

import os
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fatigue_pin.paper.curl import COSTS, PAPER_MINUTES_S0, PAPER_REPETITIONS

from fatigue_pin.core.cores import usable_cores
from fatigue_pin.core.progress import Progress, as_reporter

@dataclass(frozen=True)
class Job:
    """One run of the study."""

    horizon: str  # "full" (max repetitions) or "sliding"
    cost: str
    S: float
    preset: str
    out: Path
    n_max: int = 33
    max_cycles: int | None = None

    @property
    def label(self) -> str:
        return f"{self.horizon}/{self.cost}_S{self.S:g}"

    def study(self):
        """The job as a study of the paper's curl."""
        from fatigue_pin.paper.curl import curl_study

        horizon = "max-cycles" if self.horizon == "full" else "sliding"
        bound = self.n_max if horizon == "max-cycles" else self.max_cycles
        return curl_study(horizon, self.cost, self.preset, self.S, max_cycles=bound)

def _one_thread_per_worker() -> None:
    """Worker-process initialiser: one OpenMP thread per worker (the parent is left unchanged)."""
    os.environ["OMP_NUM_THREADS"] = "1"

def _run_job(job: Job) -> dict[str, object]:
    """Run one job in a worker process (no progress output; results go to the job's file)."""
    from fatigue_pin.io.study import run_study

    t0 = time.perf_counter()
    result = run_study(job.study(), job.out)
    return {"label": job.label, "horizon": job.horizon, "cost": job.cost, "S": job.S, "repetitions": result.repetitions,
            "solve_time_s": result.solve_time_s, "elapsed_s": time.perf_counter() - t0, "file": str(job.out)}

def _figures_and_replays(files: list[Path], out: Path, progress: Progress) -> list[Path]:
    from fatigue_pin.paper.forward_file import is_forward_file, plot_forward_file
    from fatigue_pin.viz.plots import plot_file
    from fatigue_pin.viz.replay import export_html
    from fatigue_pin.io.results import list_runs, read_run

    written: list[Path] = []
    for path in files:
        if not path.exists():
            continue
        if is_forward_file(path):
            written += plot_forward_file(path, out / "figures")
            continue
        written += plot_file(path, out / "figures")
        for name in list_runs(path):
            html = out / "replay" / f"{name.replace('/', '_')}.html"
            export_html(read_run(path, name), html)
            written.append(html)
            progress(f"replay: {html}")
    return written

def demo(out: str | Path = "results/demo", progress: Progress = print, max_cycles: int | None = None) -> dict[str, Path]:
    """Solve the sliding-horizon curl to exhaustion (paper defaults) and write everything.

    Returns the paths written: ``h5``, ``figures`` (folder) and ``replay`` (HTML).
    """
    from fatigue_pin.paper.curl import curl_study
    from fatigue_pin.viz.plots import plot_file
    from fatigue_pin.viz.replay import export_html
    from fatigue_pin.io.results import check_output
    from fatigue_pin.io.study import run_study

    out = Path(out)
    h5 = out / "sliding.h5"
    check_output(h5)
    study = curl_study("sliding", max_cycles=max_cycles)
    model = study.model()
    progress(model.summary())
    progress("building the 3-cycle window OCP (compiled once per machine, then cached) ...")
    result = run_study(study, h5, progress=progress)
    figures = out / "figures"
    for path in plot_file(h5, figures):
        progress(f"figure: {path}")
    html = export_html(result.run, out / "replay.html")
    progress(f"replay (open in a browser): {html}")
    progress(f"results: {h5}")
    for line in demo_summary(result, study):
        progress(line)
    return {"h5": h5, "figures": figures, "replay": html}


def demo_summary(result, study) -> list[str]:
    """The demo's closing lines for a sliding-horizon ``result`` (a
    :class:`~fatigue_pin.io.study.StudyResult`) of the curl ``study``: how its count compares with
    the paper's, then the count and why the run ended (:func:`fatigue_pin.drivers.sliding.ending`),
    last."""
    from fatigue_pin.drivers.sliding import ending
    from fatigue_pin.paper.curl import VARIANTS

    labels = study.data.get("labels", {})
    cost, preset = labels.get("cost"), labels.get("preset")
    published = PAPER_REPETITIONS.get(("sliding", float(study.data["fatigue"]["S"])), {}).get(cost)
    lines = []
    if published is not None and preset == "paper":
        text, code = VARIANTS["paper"], VARIANTS["authors-code"]
        lines.append(
            f"the paper reports {published} repetitions for this curl: its published counts come from its authors' code, whose "
            f"values differ from its text (the ones used here): recovery R = {code.R:g} 1/s (text: {text.R:g}, ten times "
            f"slower, so the arm tires sooner), shoulder weight {code.posture_weight:g} (text: {text.posture_weight:g}) and "
            "the last low target one node before the end; the solver settings are the same. "
            f"studies/curl_sliding_{cost}_authors-code.toml has the code's values (docs/reproduction.md)")
    lines.append(f"{result.repetitions} repetitions: {ending(result.run)}; {result.solve_time_s:.1f} s of solving")
    return lines

def reproduce(
    out: str | Path = "results/reproduce",
    preset: str = "paper",
    quick: bool = False,
    jobs: int | None = None,
    progress: Progress = None,
) -> Path:
    """Run the paper's study and write HDF5 files, figures, replays and ``report.md``.

    Args:
        out: output folder.
        preset: ``paper`` or ``authors-code``.
        quick: a subset that finishes in a few minutes: the forward studies, the sliding
            horizon of every cost with S = 10 capped at 6 cycles, the full horizon capped at 4.
        jobs: worker processes (default: the number of cores).
        progress: a Reporter (lines and a bar over the runs) or a line callback; default quiet.

    Returns:
        The path of ``report.md``.
    """
    from fatigue_pin.paper.forward import format_table, run_forward_studies

    progress = as_reporter(progress)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    progress("forward studies (paper section 2) ...")
    forward = run_forward_studies(out)
    stabilisers = (10.0,) if quick else (10.0, 0.0)
    job_list = [
        Job(h, c, S, preset, out / f"{h}_{c}_S{S:g}.h5", n_max=4 if quick else 33,
            max_cycles=6 if quick else None)
        for h in ("sliding", "full") for S in stabilisers for c in COSTS
    ]
    workers = max(1, min(jobs or usable_cores(), len(job_list)))
    progress(f"{len(job_list)} OCP runs on {workers} processes ...")
    rows: list[dict[str, object]] = []
    init = _one_thread_per_worker if workers > 1 else None
    bar = progress.bar(len(job_list), "OCP runs", "run")
    with ProcessPoolExecutor(max_workers=workers, initializer=init) as pool:
        futures = {pool.submit(_run_job, job): job for job in job_list}
        for fut in as_completed(futures):
            job = futures[fut]
            try:
                row = fut.result()
            except Exception as exc:  # keep the other runs; report the failure
                row = {"label": job.label, "horizon": job.horizon, "cost": job.cost, "S": job.S, "repetitions": -1,
                       "solve_time_s": float("nan"), "elapsed_s": float("nan"), "file": str(job.out), "error": repr(exc)}
            rows.append(row)
            progress(f"done {row['label']}: {row['repetitions']} repetitions, {row['solve_time_s']:.1f} s solving")
            bar.update(1, last=row["label"])
    bar.close()
    files = [out / "forward_studies.h5"] + [job.out for job in job_list]
    _figures_and_replays(files, out, progress)
    report = out / "report.md"
    report.write_text(_report(rows, format_table(forward), preset, quick, time.perf_counter() - t0, files))
    progress(f"report: {report}")
    return report

def _report(rows: list[dict[str, object]], forward_table: str, preset: str, quick: bool, elapsed: float, files: list[Path]) -> str:
    from fatigue_pin.io.results import list_runs, read_run

    lines = [
        "# Reproduction report",
        "",
        f"Preset `{preset}`{' (quick subset: capped runs, repetitions are lower bounds)' if quick else ''}; "
        f"total wall time {elapsed / 60:.1f} min. Paper values: docs/reproduction.md.",
        "",
        "## Forward studies (paper section 2)",
        "",
        "```",
        forward_table,
        "```",
        "",
        "## Repetitions",
        "",
        "| horizon | cost | S | ours | paper | solve time ours (min) | paper, S = 0 (min) |",
        "|---|---|---|---|---|---|---|",
    ]
    for row in sorted(rows, key=lambda r: (r["horizon"], -float(r["S"]), list(COSTS).index(str(r["cost"])))):
        key = (str(row["horizon"]), float(row["S"]))
        paper = PAPER_REPETITIONS.get(key, {}).get(str(row["cost"]), "")
        paper_min = PAPER_MINUTES_S0.get((str(row["horizon"]), str(row["cost"])), "") if float(row["S"]) == 0 else ""
        reps = row["repetitions"] if "error" not in row else f"error: {row['error']}"
        lines.append(f"| {row['horizon']} | {row['cost']} | {float(row['S']):g} | {reps} | {paper} | "
                     f"{float(row['solve_time_s']) / 60:.2f} | {paper_min} |")
    lines += ["", "## Invariant |1 - (ma + mr + mf)| at the final time", "",
              "Paper: 1e-14..1e-11 (full horizon, S = 10), 1e-9..1e-3 (without stabiliser).", "",
              "| run | max over halves |", "|---|---|"]
    for path in files[1:]:
        if path.exists():
            for name in list_runs(path):
                run = read_run(path, name)
                lines.append(f"| {name} | {run.invariant_error()[-1].max():.2e} |")
    lines += ["", "## Independent verification (`fatigue-pin verify`)", "",
              "Each interval re-integrated from its stored node with scipy DOP853 and numeric pinocchio.aba "
              "(docs/verify.md); worst values over the run, default tolerances.", "",
              "| run | gap q, qdot | gap fatigue | coupling violation | invariant | verdict |", "|---|---|---|---|---|---|"]
    lines += _verify_rows(files[1:])
    lines += ["", "## Figures and replays", "", "Figures: [figures/](figures/). Replays (open in a browser): [replay/](replay/).", ""]
    return "\n".join(lines)

def _verify_rows(files: list[Path]) -> list[str]:
    """One table row of :func:`fatigue_pin.verify.verifier.verify_run` figures per run of the files."""
    from fatigue_pin.io.results import list_runs, read_run
    from fatigue_pin.verify import verify_run

    rows = []
    for path in files:
        if not path.exists():
            continue
        for name in list_runs(path):
            try:
                r = verify_run(read_run(path, name))
            except Exception as exc:  # one unverifiable run must not lose the report
                rows.append(f"| {name} | | | | | error: {exc} |")
                continue
            verdict = "passed" if r.passed else "FAILED: " + ", ".join(c.name for c in r.failures)
            rows.append(f"| {name} | {r.gap:.1e} | {r.gap_fatigue:.1e} | {r.coupling:.1e} | {r.invariant:.1e} | {verdict} |")
    return rows

def final_invariant_errors(path: Path) -> dict[str, float]:
    """max |1 - (ma + mr + mf)| at the final node of every run in a file."""
    from fatigue_pin.io.results import list_runs, read_run

    return {name: float(np.max(read_run(path, name).invariant_error()[-1])) for name in list_runs(path)}
