"""The compile of a muscle problem's library: how the muscle paths (exact or polynomial), the
compiler's optimisation level and the Hessian option trade the compile (which a user waits for
once per model) against the solve.

Usage::

    python benchmarks/muscle_compile.py [--paths exact polynomial] [--flags "-O3 -march=native" -O1]
        [--hessians exact gauss-newton] [--cycles 1]

The problem: the paper's curl (its task and the fatigue-torque costs' fatigue and posture terms)
on the bundled arm26's six muscles with +-50 N m residual torques that do not tire, 10 intervals
per cycle, 2 RK4 substeps. One row per paths, compiler flags and Hessian: the compile time of the
library with an empty cache (s), the first solve's wall time (s), IPOPT iterations and the
objective; the first row is the uncompiled solve. One run each (a compile is minutes): the
machine's load shows in the solve times, not in the ratios between compiles of one run.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from fatigue_pin.drivers.full import OcpBuilder
from fatigue_pin.io.study import Study

ROOT = Path(__file__).resolve().parents[1]


def study(cycles: int, changes: dict) -> Study:
    base = Study.from_file(ROOT / "studies/curl_full_fatigue-torque_paper.toml")
    return base.replace({
        "model.muscles": "arm26", "actuators.kind": "muscles", "actuators.residuals": 50.0, "horizon.cycles": cycles,
        "task.intervals_per_cycle": 10, "transcription.substeps": 2,
        "costs": {"fatigue": 1e3, "activation": 1.0, "residual": 1.0, "posture": {"weight": 1e5, "joints": ["shoulder"]}},
        **changes})


def one(s: Study, cycles: int, cache: Path | None) -> tuple[float, float, int, float]:
    """(compile s, solve s, iterations, objective)."""
    ocp = OcpBuilder(s.problem(), s.transcription(), s.solver(cache))(cycles)
    t0 = time.perf_counter()
    sol = ocp.solve()
    return ocp.compile_time_s, time.perf_counter() - t0, sol.iterations, sol.objective


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--paths", nargs="+", default=["exact", "polynomial"])
    ap.add_argument("--flags", nargs="+", default=["-O3 -march=native", " -O1"],
                    help="each a quoted set of flags; start a set with a space (\" -O1\") so that it is not read as an option")
    ap.add_argument("--hessians", nargs="+", default=["exact", "gauss-newton"])
    ap.add_argument("--cycles", type=int, default=1)
    args = ap.parse_args()
    print("| paths | flags | hessian | compile (s) | solve (s) | iterations | objective |\n|---|---|---|---|---|---|---|", flush=True)
    for paths in args.paths:
        c, w, it, obj = one(study(args.cycles, {"solver.compile": False, "actuators.paths": paths}), args.cycles, None)
        print(f"| {paths} | uncompiled | exact | - | {w:.1f} | {it} | {obj:.8f} |", flush=True)
        for flags in args.flags:
            for hessian in args.hessians:
                with tempfile.TemporaryDirectory(prefix="fatigue_pin_muscle_cache_") as tmp:
                    s = study(args.cycles, {"solver.compile": True, "solver.first_compile": "wait", "solver.hessian": hessian,
                                            "solver.compiler_flags": flags.split(), "actuators.paths": paths})
                    c, w, it, obj = one(s, args.cycles, Path(tmp))
                print(f"| {paths} | {flags} | {hessian} | {c:.1f} | {w:.2f} | {it} | {obj:.8f} |", flush=True)


if __name__ == "__main__":
    main()
