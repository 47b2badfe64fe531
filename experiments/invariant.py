"""The invariant |1 - (ma + mr + mf)| as the paper measured it (issue 16, item 4).

For the sliding horizon (three costs, S = 10 and S = 0, ``authors-code``) it runs each study to
exhaustion (or reuses ``--out/sliding_<cost>_S<S>.h5``) and reports the final and worst
|1 - sum| of every actuator half:

* on the converged nodes (the kept run: our export);
* on the last, failed window (IPOPT's last iterate, stored as ``<run>_failed_window``): the paper's
  code exports its cycles 2-3 last, so the paper's "final" value is this window's last node;
* after single shooting of the kept run's controls from its initial state (``verify_run``), with
  RK45 at the paper's rtol 1e-3 / atol 1e-6 and with DOP853 at rtol 1e-10 / atol 1e-12.

With ``--full DIR`` it adds the limit solutions of the maximum-repetitions searches in DIR
(``full_<cost>_S<S>.h5`` of ``experiments/max_repetitions.py``). Usage::

    python experiments/invariant.py --out results/invariant [--full results/max_repetitions]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from fatigue_pin.paper.curl import COSTS, curl_study
from fatigue_pin.io.results import list_runs, read_run
from fatigue_pin.drivers.run import failed_window_name
from fatigue_pin.io.study import run_study
from fatigue_pin.verify import verify_run


def invariant(run) -> np.ndarray:
    """|1 - sum of the states| of every half on every node, (nodes, halves)."""
    total = sum(np.nan_to_num(run.fatigue[s]) for s in ("ma", "mr", "mf"))
    return np.abs(1.0 - total)


def measure(run, failed=None) -> dict:
    inv = invariant(run)
    row = {"run": run.name, "cycles": run.n_cycles, "final": float(inv[-1].max()), "worst": float(inv.max())}
    if failed is not None:
        fi = invariant(failed)
        row.update(failed_status=str(failed.attrs.get("status", "")), failed_final=float(fi[-1].max()), failed_worst=float(fi.max()))
    for label, method, rtol, atol in (("rk45_paper", "RK45", 1e-3, 1e-6), ("dop853_tight", "DOP853", 1e-10, 1e-12)):
        rep = verify_run(run, single_shooting=True, rtol=rtol, atol=atol, method=method)
        row[f"ss_{label}_final"] = rep.single_shooting_invariant_final
        row[f"ss_{label}_worst"] = rep.single_shooting_invariant
    return row


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("results/invariant"), help="output folder")
    parser.add_argument("--full", type=Path, default=None, help="folder of max_repetitions.py's search files")
    parser.add_argument("--preset", default="authors-code")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    rows = []
    for S in (10.0, 0.0):
        for cost in COSTS:
            study = curl_study("sliding", cost, args.preset, S)
            path = args.out / f"sliding_{cost}_S{S:g}.h5"
            name = study.run_name()
            if not (path.exists() and name in list_runs(path) and read_run(path, name).attrs.get("finished")):
                print(f"== sliding {cost}, S = {S:g}", flush=True)
                run_study(study, path, resume=True)
            run = read_run(path, name)
            fname = failed_window_name(name)
            failed = read_run(path, fname) if fname in list_runs(path, failed_windows=True) else None
            row = {"horizon": "sliding", "cost": cost, "S": S, **measure(run, failed)}
            print(row, flush=True)
            rows.append(row)
    if args.full is not None:
        for S in (10.0, 0.0):
            for cost in COSTS:
                path = args.full / f"full_{cost}_S{S:g}.h5"
                if not path.exists():
                    continue
                run = read_run(path, f"full/{cost}_S{S:g}")
                row = {"horizon": "full", "cost": cost, "S": S, **measure(run)}
                print(row, flush=True)
                rows.append(row)
    (args.out / "invariant.json").write_text(json.dumps(rows, indent=1))
    print(f"\n{'horizon':<8} {'cost':<15} {'S':>3} {'cycles':>6} {'final':>9} {'worst':>9} {'failed win. final':>17} "
          f"{'SS RK45 1e-3':>12} {'SS DOP853':>10}")
    for r in rows:
        fw = f"{r['failed_final']:.1e}" if "failed_final" in r else "-"
        print(f"{r['horizon']:<8} {r['cost']:<15} {r['S']:>3g} {r['cycles']:>6} {r['final']:>9.1e} {r['worst']:>9.1e} {fw:>17} "
              f"{r['ss_rk45_paper_final']:>12.1e} {r['ss_dop853_tight_final']:>10.1e}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
