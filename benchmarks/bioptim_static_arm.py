"""bioptim's muscle fatigue example (studies/bioptim_static_arm_xia.toml) against bioptim's measured
solve: 17.28882458 in 67 iterations, 8.8 s on a quiet machine (14 s loaded), collocation on 50
intervals (docs/porting.md, "The static arm").

Usage::

    python benchmarks/bioptim_static_arm.py [--repeats 3] [--grids 50x2 100x2] [--hessians exact gauss-newton]

One row per grid (intervals x RK4 substeps) and ``solver.hessian``: the build time of the OCP and
the compile time of its library with a cold cache (a fresh folder per Hessian; a grid whose library
is there already says ``cached``; the library depends on the interval length), then ``--repeats`` solves with the warm cache,
each in a new OCP of the same process (build time, IPOPT wall time: their medians), the
iterations, the objective, its difference from bioptim's, and bioptim's 8.8 s over the median
solve time. Run it alone on the machine: it compiles one library per substeps and Hessian.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
STUDY = ROOT / "studies" / "bioptim_static_arm_xia.toml"
#: bioptim's measured optimum, iterations and quiet solve time (s)
BIOPTIM_OBJECTIVE, BIOPTIM_ITERATIONS, BIOPTIM_SOLVE_S = 17.28882458, 67, 8.8


def solve(study, cache: Path):
    """(build s with the compile, compile s, IPOPT wall s, iterations, objective, status) of one solve."""
    from fatigue_pin.drivers.full import solve_full

    ocp, sol = solve_full(study.problem(), 1, study.transcription(), study.solver(cache), guess=study.horizon["guess"])
    return ocp.build_time_s, ocp.compile_time_s, sol.wall_time_s, sol.iterations, sol.objective, sol.status


def main() -> None:
    from fatigue_pin.io.study import Study

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--grids", nargs="+", default=["50x2", "100x2"], help="intervals x substeps")
    parser.add_argument("--hessians", nargs="+", default=["exact", "gauss-newton"])
    args = parser.parse_args()
    base = Study.from_file(STUDY)
    print(f"{STUDY.relative_to(ROOT)}; bioptim: objective {BIOPTIM_OBJECTIVE}, {BIOPTIM_ITERATIONS} iterations, "
          f"{BIOPTIM_SOLVE_S} s (quiet); medians of {args.repeats} warm solves")
    print(f"{'grid':>7} {'hessian':>13} {'build s':>8} {'compile s':>10} {'warm build s':>13} {'solve s':>8} {'iter':>5} "
          f"{'objective':>12} {'vs bioptim':>11} {'speed-up':>9}")
    for hessian in args.hessians:
        with tempfile.TemporaryDirectory(prefix="fatigue_pin_bench_") as folder:
            cache = Path(folder)  # cold for the first grid
            for k, grid in enumerate(args.grids):
                n, substeps = (int(x) for x in grid.split("x"))
                study = base.replace({"task.intervals_per_cycle": n, "transcription.substeps": substeps, "solver.hessian": hessian,
                                      "solver.first_compile": "wait"})
                first = solve(study, cache)
                runs = [solve(study, cache) for _ in range(args.repeats)]
                builds = statistics.median(r[0] for r in runs)
                wall = statistics.median(r[2] for r in runs)
                its, obj = runs[-1][3], runs[-1][4]
                failed = [r[5] for r in (first, *runs) if r[5] != "Solve_Succeeded"]
                rel = (obj - BIOPTIM_OBJECTIVE) / BIOPTIM_OBJECTIVE
                compile_s = f"{first[1]:>10.1f}" if first[1] else f"{'cached':>10}"
                print(f"{grid:>7} {hessian:>13} {first[0] - first[1]:>8.2f} {compile_s} {builds:>13.2f} {wall:>8.2f} {its:>5d} "
                      f"{obj:>12.6f} {rel:>+10.3%} {BIOPTIM_SOLVE_S / wall:>8.1f}x" + (f"  NOT CONVERGED: {failed}" if failed else ""),
                      flush=True)

if __name__ == "__main__":
    main()
