"""Sweep speed on this machine: a 12-job sweep on 1 and on 2 local workers, and the scheduler's
overhead per job.

Usage: PYTHONPATH=. python benchmarks/sweep.py [--workers 1 2] [--cycles 2 3 4]

Jobs: the paper's curl at test size (10 intervals per cycle, 2 RK4 substeps, no compile), full
horizon, ``horizon.cycles`` x ``fatigue.S`` in {10, 0} x ``costs.torque.weight`` in {1, 2}
(12 jobs with the default three horizons). Every row starts a fresh ``LocalCluster`` (one
single-threaded worker process per worker) and a fresh output folder; the cluster start and a
warm-up (imports and model load on every worker) are timed apart from the sweep itself.

Overhead: ``direct`` runs each job with :func:`fatigue_pin.sweep.jobs.run_job` in this process one after
the other; the same jobs through one Dask worker cost that plus the scheduler's overhead. Jobs of
trivial size (``solver.max_iter = 0``) make the difference visible; ``no-op task`` is the round
trip of an empty Dask task.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))


def _warm() -> None:
    """Imports and the model load, once per worker (what the first job would pay)."""
    from fatigue_pin.robot.model import load_model
    from fatigue_pin.io.study import run_study  # noqa: F401

    load_model()


def _noop() -> None:
    return None


def _jobs(cycles: list[int], trivial: bool = False):
    from conftest import small_curl

    from fatigue_pin.sweep.plan import Sweep

    base = small_curl("full")
    grid = {"horizon.cycles": cycles, "fatigue.S": [10.0, 0.0], "costs.torque.weight": [1.0, 2.0]}
    if trivial:
        grid = {"horizon.cycles": [1], "fatigue.S": [10.0, 0.0], "costs.torque.weight": [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]}
        base = base.replace({"solver.max_iter": 0})
    return Sweep.from_dict({"base": base.data, "grid": grid}).jobs()


def _sweep(jobs, workers: int) -> dict[str, float]:
    from distributed import Client

    from fatigue_pin.sweep.cluster import local_cluster
    from fatigue_pin.sweep.runner import run_sweep

    t0 = time.perf_counter()
    with local_cluster(workers) as cluster, Client(cluster) as client:
        client.wait_for_workers(workers)
        t_start = time.perf_counter() - t0
        t0 = time.perf_counter()
        client.run(_warm)
        t_warm = time.perf_counter() - t0
        with tempfile.TemporaryDirectory() as out:
            t0 = time.perf_counter()
            outcome = run_sweep(jobs, out, client)
            wall = time.perf_counter() - t0
        t0 = time.perf_counter()
        n = 50
        for _ in range(n):
            client.submit(_noop, pure=False).result()
        noop = (time.perf_counter() - t0) / n
    solve = sum(r["wall_time_s"] for r in outcome.rows.values())
    assert outcome.errors == 0, outcome.rows
    return {"start": t_start, "warm": t_warm, "wall": wall, "job_sum": solve, "noop": noop}


def _direct(jobs) -> float:
    from fatigue_pin.sweep.jobs import run_job

    _warm()
    with tempfile.TemporaryDirectory() as out:
        t0 = time.perf_counter()
        for job in jobs:
            run_job(job.text, job.id, out)
        return time.perf_counter() - t0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--cycles", type=int, nargs="+", default=[2, 3, 4])
    args = parser.parse_args()

    jobs = _jobs(args.cycles)
    print(f"{len(jobs)} jobs on {os.cpu_count()} cores; load average before: {os.getloadavg()[0]:.2f}")
    direct = _direct(jobs)
    rows = [(w, _sweep(jobs, w)) for w in args.workers]
    print()
    print("| workers | cluster start (s) | warm-up (s) | sweep wall (s) | sum of job times (s) | speed-up vs 1 worker | vs direct |")
    print("|---|---|---|---|---|---|---|")
    print(f"| direct (this process) | - | - | {direct:.1f} | - | - | 1.00 |")
    one = next((r["wall"] for w, r in rows if w == 1), None)
    for w, r in rows:
        speed = f"{one / r['wall']:.2f}" if one else "-"
        print(f"| {w} | {r['start']:.1f} | {r['warm']:.1f} | {r['wall']:.1f} | {r['job_sum']:.1f} | {speed} | {direct / r['wall']:.2f} |")

    trivial = _jobs([1], trivial=True)
    t_direct = _direct(trivial)
    r = _sweep(trivial, 1)
    n = len(trivial)
    print()
    print("| overhead, 1 worker | per job (ms) |")
    print("|---|---|")
    print(f"| trivial job, direct call | {1e3 * t_direct / n:.0f} |")
    print(f"| trivial job through Dask | {1e3 * r['wall'] / n:.0f} |")
    print(f"| scheduler overhead (difference) | {1e3 * (r['wall'] - t_direct) / n:.0f} |")
    print(f"| no-op task round trip | {1e3 * r['noop']:.1f} |")
    print(f"\nload average after: {os.getloadavg()[0]:.2f} (other work on the machine slows every row alike only roughly)")


if __name__ == "__main__":
    main()
