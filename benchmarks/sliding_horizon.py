"""Sliding-horizon speed: wall time and iterations per window for a run to exhaustion.

Usage: python benchmarks/sliding_horizon.py [--cost fatigue-torque] [--stabilization 10]
       [--max-cycles N] [--runs 1] [--compile-mode library|nlp] [--derivative-blocks auto|on|off]

Prints one line per window, then the median wall time and iterations of the normal windows,
the terminal windows apart (the failing window, and windows that needed more than three times
the median iterations), and the total. Reference (issue 5): the paper's own code on this kind
of machine took ~5 s per fresh window, 15-25 s once fatigued, ~18 min for its failing window and
~25 min for 20 repetitions in all.
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from fatigue_pin.paper.curl import curl_study
from fatigue_pin.io.results import ResultFile
from fatigue_pin.drivers.sliding import SlidingHorizon


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cost", default="fatigue-torque")
    parser.add_argument("--stabilization", type=float, default=10.0)
    parser.add_argument("--preset", default="paper")
    parser.add_argument("--max-cycles", type=int, default=None)
    parser.add_argument("--runs", type=int, default=1, help="repeat the whole run; medians over runs")
    parser.add_argument("--compile-mode", choices=("library", "nlp"), default="library")
    parser.add_argument("--derivative-blocks", choices=("auto", "on", "off"), default="auto")
    args = parser.parse_args()

    study = curl_study("sliding", args.cost, args.preset, args.stabilization)
    blocks = {"auto": None, "on": True, "off": False}[args.derivative_blocks]
    solver = dataclasses.replace(study.solver(), compile_mode=args.compile_mode, derivative_blocks=blocks)
    print(f"compile mode {args.compile_mode}, derivative blocks {args.derivative_blocks}")
    t0 = time.perf_counter()
    runner = SlidingHorizon(study.problem(), dataclasses.replace(study.horizon_settings().sliding_settings(), max_cycles=args.max_cycles), study.transcription(), solver)
    print(f"build {runner.ocp.build_time_s:.1f} s (compile {runner.ocp.compile_time_s:.1f} s) in {time.perf_counter() - t0:.1f} s")
    totals, normals, terminals, reps = [], [], [], []
    for r in range(args.runs):
        with tempfile.TemporaryDirectory() as tmp:
            t1 = time.perf_counter()
            run = runner.run(ResultFile(Path(tmp) / "bench.h5"), progress=print if r == 0 else (lambda _: None))
            totals.append(time.perf_counter() - t1)
        w = run.windows
        med_it = float(np.median(w["iterations"][w["converged"]])) if w["converged"].any() else 0.0
        terminal = (~w["converged"]) | (w["iterations"] > 3 * med_it)
        normals.append(w["wall_time_s"][~terminal])
        terminals.append(w["wall_time_s"][terminal])
        reps.append(int(run.attrs["repetitions"]))
        its = w["iterations"]
    normal = np.concatenate(normals)
    print(f"\nrepetitions: {reps}")
    print(f"windows: {len(w)} ({int(w['converged'].sum())} converged)")
    print(f"normal windows: median {statistics.median(normal):.2f} s, min {normal.min():.2f}, max {normal.max():.2f} s; "
          f"median iterations {np.median(its[~terminal]):.0f}")
    term = np.concatenate(terminals)
    if term.size:
        print(f"terminal windows: {', '.join(f'{x:.2f}' for x in term)} s "
              f"({term.max() / statistics.median(normal):.1f}x the median window)")
    print(f"whole run to exhaustion: median {statistics.median(totals):.1f} s over {args.runs} run(s) "
          f"(solve time {float(w['wall_time_s'].sum()):.1f} s)")


if __name__ == "__main__":
    main()
