"""Which formulation choice of the authors' code breaks its S = 0 runs (issue 16, item 3).

Runs the sliding horizon of ``studies/curl_sliding_<cost>_authors-code.toml`` with the authors'
solver settings and window guess (``mu_init = 0.1``, ``perturb_dec_fact = 1/3``, no scaling,
``Solved_To_Acceptable_Level`` accepted, 3000 iterations per window, fatigue states copied;
docs/authors-code.md D9-D13) in each formulation:

- ``ours``: targets as fixed variables, the joint torque T as a variable;
- ``no-T``: ``transcription.torque_variable = false`` (D4);
- ``rows``: ``transcription.target_rows = true`` (D3), node 0's row duplicating the fixed state;
- ``both``: D3 and D4, as the authors' code;
- ``rows-ours``: D3 with our own solver settings and guess;
- ``node0-row``, ``rows-after-node0``: D3 split in two (the node-0 row alone, the other rows
  alone), by narrowing, for the duration of the run, the target list the transcription turns
  into rows.

Prints, for each run, the converged windows, the paper's count (+ 3) and how the last window
ended; the runs go to ``--out/<cost>.h5``. Usage::

    python experiments/target_rows.py --out results/target_rows [--costs torque fatigue-torque]
        [--stabilization 0 10] [--variants rows both ...]
"""

from __future__ import annotations

import argparse
import contextlib
from pathlib import Path

import fatigue_pin.ocp.transcription as transcription
from fatigue_pin.io.study import Study, run_study

THEIR_SETTINGS = {
    "solver.mu_init": 0.1, "solver.perturb_dec_fact": 1.0 / 3.0, "transcription.scaling": False,
    "solver.accept_acceptable": True, "horizon.failure_iterations": 1e9, "horizon.guess_fatigue": "copy",
}
VARIANTS = {
    "ours": ({}, True, None),
    "no-T": ({"transcription.torque_variable": False}, True, None),
    "rows": ({"transcription.target_rows": True}, True, None),
    "both": ({"transcription.target_rows": True, "transcription.torque_variable": False}, True, None),
    "rows-ours": ({"transcription.target_rows": True}, False, None),
    "node0-row": ({"transcription.target_rows": True}, True, "node0"),
    "rows-after-node0": ({"transcription.target_rows": True}, True, "after"),
}


@contextlib.contextmanager
def target_subset(which: str | None):
    """Within the block, the transcription makes rows of the node-0 targets only (``node0``; the
    other targets stay fixed variables) or of the others only (``after``)."""
    if which is None:
        yield
        return
    pairs, bounds = transcription.joint_target_pairs, transcription.Ocp.state_bounds
    keep = (lambda node: node == 0) if which == "node0" else (lambda node: node != 0)

    def rows(task, model, n):
        return [r for r in pairs(task, model, n) if keep(r[0])]

    def state_bounds(self, x_init, x_end=None):
        lb, ub = bounds(self, x_init, x_end)
        for node, j, a, b in pairs(self.task, self.model, self.n_intervals):
            if not keep(node):
                lb[j, node], ub[j, node] = a, b
        return lb, ub

    transcription.joint_target_pairs, transcription.Ocp.state_bounds = rows, state_bounds
    try:
        yield
    finally:
        transcription.joint_target_pairs, transcription.Ocp.state_bounds = pairs, bounds


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("results/target_rows"), help="output folder")
    parser.add_argument("--costs", nargs="+", default=["torque"])
    parser.add_argument("--stabilization", type=float, nargs="+", default=[0.0, 10.0])
    parser.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=list(VARIANTS))
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    rows = []
    for cost in args.costs:
        for S in args.stabilization:
            for variant in args.variants:
                changes, theirs, subset = VARIANTS[variant]
                study = Study.from_file(Path(__file__).parents[1] / f"studies/curl_sliding_{cost}_authors-code.toml")
                study = study.replace({"fatigue.S": S, **(THEIR_SETTINGS if theirs else {}), **changes})
                out, name = args.out / f"{cost}.h5", f"{variant}_S{S:g}"
                print(f"== {cost}, S = {S:g}, {variant}", flush=True)
                with target_subset(subset):
                    run = run_study(study, out, name=name, progress=lambda s: print(s, flush=True)).run
                windows = run.windows
                converged = int(windows["converged"].sum())
                failed = windows[~windows["converged"]]
                last = (f"window {int(failed['index'][0]) + 1}: {failed['status'][0].decode()} after "
                        f"{int(failed['iterations'][0])} it") if len(failed) else "-"
                rows.append((cost, S, variant, converged, last))
    print(f"\n{'cost':<15} {'S':>3} {'variant':<17} {'converged':>9} {'paper count':>11}  last window")
    for cost, S, variant, converged, last in rows:
        print(f"{cost:<15} {S:>3g} {variant:<17} {converged:>9} {converged + 3:>11}  {last}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
