"""Full-horizon OCP speed: build, solve, iterations and time per cycle for several horizons.

Usage: python benchmarks/full_horizon.py [--cycles 4 8 16 32] [--repeats 3] [--cost fatigue-torque]
       [--stabilization 10] [--preset authors-code] [--guess rest|physical|resample]
       [--parallel auto|serial|openmp] [--no-compile] [--compile-mode library|nlp]
       [--derivative-blocks auto|on|off] [--solver NAME=VALUE ...]

Each horizon is built once (the compiled NLP is cached; the first build on a machine includes
the compile time, shown apart) and solved ``--repeats`` times from the same initial guess; the
table shows medians. ``--guess resample`` starts every horizon from the previous row's solution
stretched in time (``fatigue_pin.ocp.guesses.resample_guess``, as the maximum-repetitions search does);
the first row starts from rest. The default preset is ``authors-code``, the values behind the
paper's 32 repetitions (with the text's R = 0.00094 the arm cannot do 32). The last columns are
IPOPT's wall time per call of the Lagrangian's Hessian and of the constraint Jacobian.

Reference (issue 4): the paper's own code on this kind of machine took 3.96 s for 1 cycle
and 13.6 s for 3 cycles (~4.5 s per cycle, 0.27 s per iteration at 3 cycles).
"""

from __future__ import annotations

import argparse
import ast
import dataclasses
import os
import statistics

from fatigue_pin.drivers.full import OcpBuilder
from fatigue_pin.ocp.guesses import resample_guess
from fatigue_pin.paper.curl import curl_study

PAPER_CODE_S_PER_CYCLE = 13.6 / 3


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cycles", type=int, nargs="+", default=[4, 8, 16, 32])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--cost", default="fatigue-torque")
    parser.add_argument("--stabilization", type=float, default=10.0)
    parser.add_argument("--preset", default="authors-code")
    parser.add_argument("--guess", choices=("rest", "physical", "resample"), default="rest")
    parser.add_argument("--parallel", choices=("auto", "serial", "openmp"), default="auto")
    parser.add_argument("--no-compile", action="store_true")
    parser.add_argument("--compile-mode", choices=("library", "nlp"), default="library")
    parser.add_argument("--derivative-blocks", choices=("auto", "on", "off"), default="auto")
    parser.add_argument("--solver", nargs="*", default=[], metavar="NAME=VALUE",
                        help="SolverOptions fields, e.g. blas_threads=0 dynamics_jacobian='automatic' (the defaults before issue 23)")
    args = parser.parse_args()

    study = curl_study("full", args.cost, args.preset, args.stabilization,
                       guess="physical" if args.guess == "physical" else "rest",
                       solver={"compile": not args.no_compile}, transcription={"parallel": args.parallel})
    blocks = {"auto": None, "on": True, "off": False}[args.derivative_blocks]
    changes = {k: ast.literal_eval(v) for k, v in (item.split("=", 1) for item in args.solver)}
    solver = dataclasses.replace(study.solver(), compile_mode=args.compile_mode, derivative_blocks=blocks, **changes)
    build = OcpBuilder(study.problem(), study.transcription(), solver, study.horizon["guess"])
    print(f"preset {args.preset}, cost {args.cost}, S = {args.stabilization:g}, guess {args.guess}, "
          f"map {args.parallel}, compile mode {args.compile_mode}, derivative blocks {args.derivative_blocks}, "
          f"OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', 'unset')}, {os.cpu_count()} cores, solver changes {changes}")
    header = (f"{'N':>4} {'build s':>8} {'compile s':>9} {'solve s':>8} {'iter':>5} {'ms/iter':>8} {'ms/iter/cycle':>13} "
              f"{'s/cycle':>8} {'vs paper code':>13} {'hess ms':>8} {'jac ms':>7}  status")
    print(header, flush=True)
    previous = None
    for n in sorted(args.cycles):
        ocp = build(n)
        guess = resample_guess(ocp, previous) if args.guess == "resample" and previous is not None else None
        walls, iters, hess, jac, sol = [], [], [], [], None
        for _ in range(args.repeats):
            sol = ocp.solve(guess=guess)
            walls.append(sol.wall_time_s)
            iters.append(sol.iterations)
            hess.append(_ms_per_call(ocp.nlp.stats(), "nlp_hess_l"))
            jac.append(_ms_per_call(ocp.nlp.stats(), "nlp_jac_g"))
        if sol is not None and sol.success:
            previous = sol
        wall = statistics.median(walls)
        it = int(statistics.median(iters))
        per_it = 1000 * wall / max(it, 1)
        print(f"{n:>4} {ocp.build_time_s:>8.1f} {ocp.compile_time_s:>9.1f} {wall:>8.2f} {it:>5} {per_it:>8.1f} "
              f"{per_it / n:>13.2f} {wall / n:>8.3f} {PAPER_CODE_S_PER_CYCLE / (wall / n):>12.1f}x "
              f"{statistics.median(hess):>8.1f} {statistics.median(jac):>7.1f}  {sol.status}", flush=True)


def _ms_per_call(stats: dict, name: str) -> float:
    """IPOPT's wall time per call of the NLP function ``name`` (ms), NaN if never called."""
    calls = stats.get(f"n_call_{name}", 0)
    return 1000 * stats.get(f"t_wall_{name}", 0.0) / calls if calls else float("nan")


if __name__ == "__main__":
    main()
