"""The authors' full-horizon variant (issue 16, item 3): does it fail at the paper's counts + 1?

Solves ``studies/curl_full_authors-variant.toml`` (the authors-code values with their end box,
the task targets as constraint rows, no joint-torque variable, a solve from rest per N, IPOPT's
mu_init 0.1 and perturb_dec_fact 1/3, no scaling, acceptable level accepted;
``fatigue_pin.paper.curl.authors_variant_dict``; ``--set transcription.target_rows=false`` and the
like undo one of them) for each cost and stabiliser at the
paper's count and one more: S = 10 at 32 and 33 cycles, S = 0 at 20/21 (fatigue-torque), 18/19
(fatigue) and 14/15 (torque). For each solve it prints IPOPT's status, how it ended
(``fatigue_pin.ocp.solver.failure_kind``), iterations, time, the worst |1 - (ma + mr + mf)| on the
nodes, the elbow flexion capacity at the end, and IPOPT's inertia correction: how many iterations
needed a Hessian regularisation and its largest size. Converged runs are written to
``--out/variant.h5``; the table also goes to ``--out/variant.json`` (solves already in it are
not repeated). Usage::

    python experiments/authors_variant.py --out results/authors_variant [--max-wall-time 600]
        [--only fatigue-torque:10:33 torque:0:15 ...] [--set transcription.target_rows=false ...]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from fatigue_pin.drivers.full import solve_full
from fatigue_pin.drivers.run import solution_to_run
from fatigue_pin.paper.curl import PAPER_REPETITIONS, authors_variant_dict
from fatigue_pin.io.results import write_run
from fatigue_pin.io.study import Study, parse_changes


def cases() -> list[tuple[str, float, int]]:
    out = []
    for S in (10.0, 0.0):
        for cost, n in PAPER_REPETITIONS[("full", S)].items():
            out += [(cost, S, n), (cost, S, n + 1)]
    return out


def solve_case(cost: str, S: float, n: int, max_wall_time: float | None, out: Path,
               changes: dict | None = None) -> dict:
    solver = {"max_wall_time": max_wall_time} if max_wall_time else {}
    study = Study.from_dict(authors_variant_dict(cost, S, n, solver=solver)).replace(changes or {})
    h = study.horizon
    ocp, sol = solve_full(study.problem(), n, study.transcription(), study.solver(), guess=h["guess"],
                          end_tolerance=h["end_tolerance"])
    it = ocp.nlp.stats().get("iterations", {})
    reg = np.asarray(it.get("regularization_size", []), dtype=float)
    total = sum(sol.fatigue(s) for s in ("ma", "mr", "mf"))
    elbow = list(ocp.actuators.half_names).index("elbow_plus")
    row = {
        "cost": cost, "S": S, "n_cycles": n, "status": sol.status, "kind": sol.kind, "converged": sol.success,
        "iterations": sol.iterations, "wall_time_s": round(sol.wall_time_s, 1), "objective": sol.objective,
        "invariant_max": float(np.nanmax(np.abs(1.0 - total))),
        "elbow_capacity_end": float(50.0 * (1.0 - sol.fatigue("mf")[-1, elbow])),
        "regularised_iterations": int((reg > 0).sum()), "regularisation_max": float(reg.max()) if reg.size else 0.0,
        "constraint_violation": sol.nlp.constraint_violation,
    }
    if sol.success:
        write_run(out / "variant.h5", solution_to_run(ocp, sol, f"full/variant_{cost}_S{S:g}_N{n}", study.to_toml(), study.labels))
    return row


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("results/authors_variant"), help="output folder")
    parser.add_argument("--max-wall-time", type=float, default=600.0, help="wall-time limit of one solve (s)")
    parser.add_argument("--only", nargs="*", default=None, help="cases cost:S:N (default: all)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="change a key of the variant, e.g. transcription.target_rows=false (TOML value)")
    args = parser.parse_args(argv)
    changes = parse_changes(args.set)
    args.out.mkdir(parents=True, exist_ok=True)
    table_path = args.out / "variant.json"
    rows = json.loads(table_path.read_text()) if table_path.exists() else []
    done = {(r["cost"], r["S"], r["n_cycles"]) for r in rows}
    todo = cases() if args.only is None else [(c, float(s), int(n)) for c, s, n in (x.split(":") for x in args.only)]
    for cost, S, n in todo:
        if (cost, S, n) in done:
            continue
        print(f"== {cost}, S = {S:g}, N = {n}", flush=True)
        row = solve_case(cost, S, n, args.max_wall_time, args.out, changes)
        print(row, flush=True)
        rows.append(row)
        tmp = table_path.with_suffix(".tmp")
        tmp.write_text(json.dumps(rows, indent=1))
        tmp.replace(table_path)
    print(f"\n{'cost':<15} {'S':>3} {'N':>3} {'status':<32} {'kind':<18} {'it':>5} {'s':>6} {'|1-sum|':>9} "
          f"{'elbow cap':>9} {'reg. it':>7} {'reg. max':>9}")
    for r in rows:
        print(f"{r['cost']:<15} {r['S']:>3g} {r['n_cycles']:>3} {r['status']:<32} {r['kind']:<18} {r['iterations']:>5} "
              f"{r['wall_time_s']:>6.0f} {r['invariant_max']:>9.1e} {r['elbow_capacity_end']:>9.2f} "
              f"{r['regularised_iterations']:>7} {r['regularisation_max']:>9.1e}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
