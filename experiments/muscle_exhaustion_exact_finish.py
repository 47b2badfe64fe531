"""Is the muscle exhaustion study's count exhaustion, or a Gauss-Newton stall? Run
``studies/curl_muscles_exhaustion.toml`` as shipped, except that a window whose Gauss-Newton solve
stops at its iteration limit without a verdict of infeasibility (``failure_kind`` =
``not-converged``) is solved again with the exact Hessian, warm-started from its last iterate
(primal and dual), within ``--exact-iterations``. The run then ends only where the exact Hessian
fails too.

An experiment, not an option of the package: it replaces the sliding driver's window solve
(``fatigue_pin.ocp.window_budget.solve_within``, which the driver calls through its module) for
this process only. The exact Hessian's library is compiled once (about 37 s) into ``--cache``.

Usage::

    python experiments/muscle_exhaustion_exact_finish.py OUT.h5 [--cache DIR] [--exact-iterations 150]

Printed: the run's window lines, and for every finished window the Gauss-Newton stall (its
iterations, last constraint violation and objective) beside the exact finish (status,
iterations, seconds, objective). Results: ``muscle_exhaustion_exact_finish_results.txt``.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

from fatigue_pin.drivers.full import OcpBuilder
from fatigue_pin.io.study import Study, run_study
from fatigue_pin.ocp import window_budget

STUDY = Path(__file__).resolve().parents[1] / "studies/curl_muscles_exhaustion.toml"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out", help="HDF5 result file to write")
    ap.add_argument("--cache", default=None, help="folder of compiled code (default: the package's)")
    ap.add_argument("--exact-iterations", type=int, default=150, help="IPOPT iteration limit of an exact finish")
    args = ap.parse_args()

    exact_study = Study.from_file(STUDY).replace({"solver.hessian": "exact"})
    builder = OcpBuilder(exact_study.problem(), exact_study.transcription(), exact_study.solver(cache_dir=args.cache))
    exact: dict = {}
    gauss_newton = window_budget.solve_within

    def solve_within(ocp, budget, **solve):
        sol, within = gauss_newton(ocp, budget, **solve)
        if sol.success or sol.nlp.kind != "not-converged":
            return sol, within
        if "ocp" not in exact:
            t0 = time.perf_counter()
            exact["ocp"] = builder(ocp.n_cycles)
            print(f"the exact Hessian's OCP built in {time.perf_counter() - t0:.1f} s", flush=True)
        again = exact["ocp"].solve(x_init=solve["x_init"], guess=(sol.x, sol.u), x_end=solve.get("x_end"), warm=sol.nlp,
                                   warm_start=True, max_iter=args.exact_iterations)
        print(f"  Gauss-Newton stalled at {sol.iterations} it (constraint violation {sol.nlp.constraint_violation:.1e}, "
              f"objective {sol.objective:.6f}); exact finish: {again.status} in {again.iterations} it, "
              f"{again.wall_time_s:.1f} s, objective {again.objective:.6f}, constraint violation "
              f"{again.nlp.constraint_violation:.1e}", flush=True)
        return dataclasses.replace(again, iterations=sol.iterations + again.iterations,
                                   wall_time_s=sol.wall_time_s + again.wall_time_s), within

    window_budget.solve_within = solve_within
    result = run_study(Study.from_file(STUDY), out=args.out, progress=print, cache_dir=args.cache)
    print(f"{result.run.attrs.get('repetitions')} repetitions, {result.run.n_cycles} cycles kept")


if __name__ == "__main__":
    main()
