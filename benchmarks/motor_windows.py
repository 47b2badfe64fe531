"""Motor studies' sliding windows: compile, window times and the real-time factor (issue 35's
target: median window <= 1.0 s on the thermal UR5 study).

Usage: python benchmarks/motor_windows.py [--studies ur5_motors_lift ur5_motors_paced] [--runs 3]
       [--max-cycles N]

For each study (``studies/<name>.toml`` as shipped, or capped at ``--max-cycles``), builds the
sliding horizon once (the library compile counted once per machine: it is cached), then runs it
``--runs`` times, alternating the studies run by run so that a noisy machine affects them alike.
Prints a table: the first window (a cold start), the median of the other windows over all runs,
its real-time factor (s of solving per s of motion advanced), the median iterations, the
windows that needed a second solve without their heat budget, and the cycles reached.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numpy as np

from fatigue_pin.drivers.sliding import SlidingHorizon
from fatigue_pin.io.study import Study

STUDIES = Path(__file__).resolve().parents[1] / "studies"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--studies", nargs="+", default=["ur5_motors_lift", "ur5_motors_paced"])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--max-cycles", type=int, default=None)
    args = parser.parse_args()

    runners, builds = {}, {}
    for name in args.studies:
        study = Study.from_file(STUDIES / f"{name}.toml")
        if args.max_cycles is not None:
            study = study.replace({"horizon.max_cycles": args.max_cycles})
        h = study.horizon_settings()
        t0 = time.perf_counter()
        runners[name] = SlidingHorizon(study.problem(), h.sliding_settings(), study.transcription(), study.solver(), guess=h.guess)
        builds[name] = (time.perf_counter() - t0, runners[name].ocp.compile_time_s)
    first: dict[str, list[float]] = {n: [] for n in args.studies}
    rest: dict[str, list[float]] = {n: [] for n in args.studies}
    its: dict[str, list[int]] = {n: [] for n in args.studies}
    resolved: dict[str, list[int]] = {n: [] for n in args.studies}
    cycles: dict[str, list[int]] = {n: [] for n in args.studies}
    for r in range(args.runs):
        for name in args.studies:  # alternate: run r of every study, then run r + 1
            lines: list[str] = []
            run = runners[name].run(progress=lines.append)
            w = run.windows
            first[name].append(float(w["wall_time_s"][0]))
            rest[name] += [float(x) for x in w["wall_time_s"][1:]]
            its[name] += [int(x) for x in w["iterations"][1:]]
            resolved[name].append(sum("solved without" in line for line in lines))
            cycles[name].append(run.n_cycles)
            print(f"run {r + 1}/{args.runs} {name}: {run.n_cycles} cycles, {len(w)} windows, "
                  f"{float(w['wall_time_s'].sum()):.1f} s solving", flush=True)
    print()
    print("| study | build (compile) s | first window s | median window s (others) | real-time factor | median iterations | "
          "windows solved again without the budget | cycles |")
    print("|---|---|---|---|---|---|---|---|")
    for name in args.studies:
        advanced = runners[name].sliding.advance * runners[name].ocp.task.cycle_duration
        med = statistics.median(rest[name]) if rest[name] else float("nan")
        print(f"| {name} | {builds[name][0]:.1f} ({builds[name][1]:.1f}) | {statistics.median(first[name]):.2f} | "
              f"{med:.2f} | {med / advanced:.2f} | {np.median(its[name]) if its[name] else float('nan'):.0f} | "
              f"{resolved[name]} | {cycles[name]} |")


if __name__ == "__main__":
    main()
