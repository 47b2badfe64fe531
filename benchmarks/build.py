"""Build cost of the compiled NLP: the per-model library against the whole-NLP compile per horizon.

Usage::

    python benchmarks/build.py [--cycles 1 2 4 8 16 32] [--modes library nlp]
        [--solve 4 16 32] [--repeats 3] [--max-iter 40] [--baseline] [--search] [--jobs 2]

Tables (every build uses a fresh temporary cache, so the first horizon pays the library compile):

1. builds: for each compile mode (``SolverOptions.compile_mode``), the build time of each horizon
   in ``--cycles`` order; the first row includes the library compile (empty cache), the next ones
   only what each new horizon costs (``library``: nothing is compiled; ``nlp``: the whole NLP).
2. per-iteration solve time at ``--solve`` cycles for each mode, from rest, medians of
   ``--repeats`` solves capped at ``--max-iter`` iterations (same iterates in every mode: the
   derivatives are exact, so only the evaluation cost differs); with ``--baseline`` also the
   whole-NLP compile (``nlp``, about a minute of compile per horizon) and the ratios.
3. ``--search``: the cold maximum-repetitions search (authors-code, fatigue-torque, S = 10, up to
   33 cycles) end to end with an empty cache, per mode.
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from pathlib import Path

from fatigue_pin.drivers.full import OcpBuilder
from fatigue_pin.drivers.search import max_repetitions
from fatigue_pin.paper.curl import curl_study
from fatigue_pin.ocp.problem import Problem
from fatigue_pin.ocp.solver import SolverOptions

STUDY = curl_study("full", "fatigue-torque", "authors-code", 10.0)


def builder(mode: str, cache: Path, jobs: int | None, max_iter: int = 3000, progress=None) -> OcpBuilder:
    """Ocps of the benchmark problem (authors-code, fatigue-torque, S = 10) for any horizon."""
    solver = SolverOptions(cache_dir=cache, compile_mode=mode, compile_jobs=jobs, max_iter=max_iter)
    return OcpBuilder(STUDY.problem(), STUDY.transcription(), solver, progress=progress)


def builds(model: Problem, modes: list[str], cycles: list[int], jobs: int | None) -> None:
    """Table 1: build time per horizon with an empty cache at the start."""
    print("\n## builds (empty cache at the first row)")
    print(f"{'mode':<8} {'cycles':>6} {'build s':>8} {'library compile s':>18} {'NLP compile s':>14}")
    for mode in modes:
        with tempfile.TemporaryDirectory(prefix="fatigue_pin_bench.") as tmp:
            for n in cycles:
                t0 = time.perf_counter()
                ocp = builder(mode, Path(tmp), jobs, progress=lambda line: print("   ", line, flush=True))(n)
                total = time.perf_counter() - t0
                lib = ocp.compile_time_s - ocp.nlp.compile_time_s
                print(f"{mode:<8} {n:>6} {total:>8.1f} {lib:>18.1f} {ocp.nlp.compile_time_s:>14.1f}", flush=True)


def per_iteration(model: Problem, modes: list[str], cycles: list[int], repeats: int, max_iter: int,
                  jobs: int | None, cache: Path) -> None:
    """Table 2: ms per IPOPT iteration per mode (medians), ratio to the first mode."""
    print(f"\n## per-iteration solve time (from rest, max_iter {max_iter}, median of {repeats})")
    print(f"{'cycles':>6} {'mode':<8} {'iter':>5} {'ms/iter':>8} {'ratio':>6} {'cpu ms/iter':>11} {'ratio':>6} {'build s':>8}  status")
    for n in cycles:
        reference = None
        for mode in modes:
            t0 = time.perf_counter()
            ocp = builder(mode, cache, jobs, max_iter)(n)
            build = time.perf_counter() - t0
            per_it, cpu_it, iters, status = [], [], [], ""
            for _ in range(repeats):
                c0 = time.process_time()
                sol = ocp.solve()
                it = max(1, sol.iterations)
                per_it.append(1000 * sol.wall_time_s / it)
                cpu_it.append(1000 * (time.process_time() - c0) / it)
                iters.append(sol.iterations)
                status = sol.status
            ms, cpu = statistics.median(per_it), statistics.median(cpu_it)
            reference = reference or (ms, cpu)
            print(f"{n:>6} {mode:<8} {statistics.median(iters):>5.0f} {ms:>8.1f} {ms / reference[0]:>6.2f} {cpu:>11.1f} "
                  f"{cpu / reference[1]:>6.2f} {build:>8.1f}  {status}", flush=True)


def search(model: Problem, modes: list[str], jobs: int | None) -> None:
    """Table 3: cold maximum-repetitions search, end to end."""
    print("\n## cold max-repetitions search (authors-code, fatigue-torque, S = 10, n_max 33), empty cache")
    print(f"{'mode':<8} {'max cycles':>10} {'elapsed s':>10} {'builds s':>9} {'solves s':>9}  tried")
    for mode in modes:
        with tempfile.TemporaryDirectory(prefix="fatigue_pin_bench.") as tmp:
            t0 = time.perf_counter()
            b0 = builder(mode, Path(tmp), jobs)
            result = max_repetitions(STUDY.problem(), b0.transcription, b0.solver, n_max=33,
                                     progress=lambda line: print("   ", line, flush=True))
            elapsed = time.perf_counter() - t0
            b = sum(float(r["build_time_s"]) for r in result.tried)
            s = sum(float(r["wall_time_s"]) for r in result.tried)
            tried = ", ".join(f"{r['n_cycles']}{'' if r['converged'] else 'x'}" for r in result.tried)
            print(f"{mode:<8} {result.max_cycles:>10} {elapsed:>10.1f} {b:>9.1f} {s:>9.1f}  {tried}", flush=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cycles", type=int, nargs="+", default=[1, 2, 4, 8, 16, 32])
    parser.add_argument("--modes", nargs="+", default=["library"], choices=["library", "nlp"])
    parser.add_argument("--solve", type=int, nargs="*", default=[4, 16, 32])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--max-iter", type=int, default=3000)
    parser.add_argument("--baseline", action="store_true", help="also the whole-NLP compile (slow: a compile per horizon)")
    parser.add_argument("--search", action="store_true", help="cold max-repetitions search per mode")
    parser.add_argument("--no-builds", action="store_true", help="skip table 1")
    parser.add_argument("--jobs", type=int, default=None, help="parallel compiler processes (default: every core)")
    args = parser.parse_args(argv)

    model = STUDY.problem()
    print(f"{os.cpu_count()} cores, OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', 'unset')}, jobs {args.jobs or 'all'}")
    if not args.no_builds:
        builds(model, args.modes, args.cycles, args.jobs)
    if args.solve:
        modes = (["nlp"] if args.baseline else []) + [m for m in args.modes if m != "nlp"]
        with tempfile.TemporaryDirectory(prefix="fatigue_pin_bench.") as tmp:
            per_iteration(model, modes, args.solve, args.repeats, args.max_iter, args.jobs, Path(tmp))
    if args.search:
        search(model, args.modes, args.jobs)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
