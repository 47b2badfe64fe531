"""Full-horizon maximum repetitions for the three costs with S = 10 and S = 0 (paper table 2).

Runs ``fatigue_pin.drivers.search.max_repetitions`` for every (cost, S), one after the other (each solve
uses every core), writes one HDF5 file per search into ``--out`` (the search table and the best
run; written after every N, so an interrupted study resumes where it stopped) and prints every N
tried and the summary beside the paper's. Usage::

    python experiments/max_repetitions.py --out results/max_repetitions [--preset authors-code]
        [--n-max N] [--costs fatigue-torque torque fatigue] [--stabilization 10 0]
        [--max-wall-time 900] [--max-iter 500]

The default preset is ``authors-code``: the paper's counts come from those values. There is no
cap by default: the search gallops (N = 1, 2, 4, ...) until a failure, then bisects; a failed
warm start is solved again from rest before it counts. ``--max-wall-time`` bounds one solve; a
solve stopped by it counts as a failure, reported with IPOPT's status and its kind
(``fatigue_pin.ocp.solver.failure_kind``). ``--max-iter`` bounds it by IPOPT iterations instead,
which, unlike a wall time, gives the same limit on a loaded machine.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from fatigue_pin.paper.curl import COSTS, PAPER_REPETITIONS, Q_INIT, VARIANTS, curl_study
from fatigue_pin.viz.plots import plot_capacity
from fatigue_pin.io.study import run_study


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("results/max_repetitions"), help="output directory")
    parser.add_argument("--preset", default="authors-code", choices=list(VARIANTS))
    parser.add_argument("--n-max", type=int, default=None, help="largest N tried (default: no cap)")
    parser.add_argument("--costs", nargs="+", default=list(COSTS), choices=list(COSTS))
    parser.add_argument("--stabilization", type=float, nargs="+", default=[10.0, 0.0])
    parser.add_argument("--max-wall-time", type=float, default=None, help="wall-time limit of one solve (s)")
    parser.add_argument("--max-iter", type=int, default=None, help="IPOPT iteration limit of one solve (default: the solver's)")
    parser.add_argument("--compile-mode", default="library", choices=["library", "nlp"],
                        help="nlp: compile each horizon's whole NLP once (~75 s, shared by every cost and S), "
                             "then iterate about twice as fast: the better choice for long solves")
    args = parser.parse_args(argv)

    args.out.mkdir(parents=True, exist_ok=True)
    summary = []
    for S in args.stabilization:
        for cost in args.costs:
            solver = {"max_wall_time": args.max_wall_time, "compile_mode": args.compile_mode}
            if args.max_iter is not None:
                solver["max_iter"] = args.max_iter
            study = curl_study("max-cycles", cost, args.preset, S, max_cycles=args.n_max, solver=solver)
            print(f"== {cost}, S = {S:g}, preset {args.preset}", flush=True)
            t0 = time.perf_counter()
            out = args.out / f"full_{cost}_S{S:g}.h5"
            result = run_study(study, out, progress=lambda s: print(s, flush=True), resume=True).search
            solve = sum(float(r["wall_time_s"]) for r in result.tried)
            if result.run is not None:  # why it cannot do one more: capacities against the holding torques
                model = study.problem().model
                holding = dict(zip(model.joint_names, np.abs(model.gravity_torque(np.asarray(Q_INIT)))))
                plot_capacity(result.run, args.out / "figures", holding=holding, stem="limit_capacity")
            limit = result.max_cycles + 1
            how = "; ".join(f"{r['guess']}: {r['status']} ({r['kind']}, {r['iterations']} it, {float(r['wall_time_s']):.0f} s)"
                            for r in result.tried if r["n_cycles"] == limit) or "-"
            summary.append((cost, S, result.max_cycles, how, solve, time.perf_counter() - t0))
    cap = f"N <= {args.n_max}" if args.n_max else "no cap"
    print(f"\nmaximum repetitions, full horizon, preset {args.preset}, {cap}")
    print(f"{'cost':<15} {'S':>4} {'ours':>5} {'paper':>6} {'solve s (all N)':>16} {'elapsed s':>10}  how N+1 failed")
    for cost, S, reps, how, solve, elapsed in summary:
        paper = PAPER_REPETITIONS[("full", S)][cost] if ("full", S) in PAPER_REPETITIONS else "-"
        print(f"{cost:<15} {S:>4g} {reps:>5} {paper:>6} {solve:>16.1f} {elapsed:>10.1f}  {how}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
