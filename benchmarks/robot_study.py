"""The robot study's speed beside arm26's: build time (symbolic assembly + compile) and the
median sliding window, for the UR5 carry study (studies/ur5_carry.toml) and the paper's curl
(studies/curl_sliding_fatigue_paper.toml).

Usage: python benchmarks/robot_study.py [--windows 6] [--fresh | --cache-dir DIR] [--only ur5_carry]

Each study runs in sliding horizon for ``--windows`` windows (``horizon.max_cycles`` = window +
windows - 1). The build (symbolic assembly, C generation and, when the library is not cached yet,
its compile) is timed with the solver's compile cache (default ``~/.cache/fatigue_pin``; ``--fresh``:
an empty temporary cache, so that the first compile is measured), then every window's wall time
and iterations are read from the run's window table. Prints one line per study and a table for
docs/robot-study.md.
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from fatigue_pin.io.results import ResultFile
from fatigue_pin.drivers.sliding import SlidingHorizon
from fatigue_pin.io.study import Study

STUDIES = Path(__file__).resolve().parents[1] / "studies"
CASES = {"ur5_carry": STUDIES / "ur5_carry.toml", "arm26_curl": STUDIES / "curl_sliding_fatigue_paper.toml"}


def measure(path: Path, windows: int, cache_dir: Path) -> dict:
    study = Study.from_file(path)
    horizon = study.horizon_settings()
    t0 = time.perf_counter()
    problem = study.problem()
    settings = dataclasses.replace(horizon.sliding_settings(), max_cycles=horizon.cycles + windows - 1)
    runner = SlidingHorizon(problem, settings, study.transcription(), study.solver(cache_dir), guess=horizon.guess)
    build = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as tmp:
        run = runner.run(ResultFile(Path(tmp) / "bench.h5"))
    w = run.windows
    ok = w["converged"]
    return {
        "study": study.name, "nx": problem.layout.nx, "nu": problem.layout.nu, "nodes": runner.ocp.n_intervals + 1,
        "build_s": build, "compile_s": float(getattr(runner.ocp, "compile_time_s", runner.ocp.nlp.compile_time_s)),
        "windows": len(w), "converged": int(ok.sum()),
        "median_window_s": float(statistics.median(w["wall_time_s"][ok])) if ok.any() else float("nan"),
        "median_iterations": float(np.median(w["iterations"][ok])) if ok.any() else float("nan"),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--windows", type=int, default=6)
    parser.add_argument("--cache-dir", type=Path, default=None, help="compile cache (default: the solver's)")
    parser.add_argument("--fresh", action="store_true", help="an empty temporary compile cache (measures the first compile)")
    parser.add_argument("--only", choices=sorted(CASES), default=None)
    args = parser.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        cache = Path(tmp) if args.fresh else args.cache_dir
        for name, path in CASES.items():
            if args.only and name != args.only:
                continue
            r = measure(path, args.windows, cache)
            rows.append(r)
            print(f"{name}: nx {r['nx']}, nodes per window {r['nodes']}, build {r['build_s']:.1f} s (compile {r['compile_s']:.1f} s), "
                  f"{r['converged']}/{r['windows']} windows converged, median window {r['median_window_s']:.2f} s, "
                  f"{r['median_iterations']:.0f} iterations", flush=True)
    print("\n| study | nx | nodes / window | build (s) | of which compile (s) | median window (s) | median iterations |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['study']} | {r['nx']} | {r['nodes']} | {r['build_s']:.1f} | {r['compile_s']:.1f} | "
              f"{r['median_window_s']:.2f} | {r['median_iterations']:.0f} |")


if __name__ == "__main__":
    main()
