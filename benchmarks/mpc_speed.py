"""Closed-loop speed (issue 24): re-planning every 0.1 s on arm26, real-time factor per re-plan.

Usage::

    python benchmarks/mpc_speed.py [--replans 20] [--repeats 2] [--configs before,now] [--cache DIR]
    python benchmarks/mpc_speed.py --to-exhaustion [--repeats 2] [--configs now,rti-3,rti-4,rti-5]

The paper's sliding study, authors-code, cost fatigue, S = 10
(studies/curl_sliding_fatigue_authors-code.toml: 50 intervals of 0.02 s per cycle, windows of 3
cycles) as a closed loop with the plant equal to the model, no noise, the open-loop estimator and
a re-plan every 5 intervals (0.1 s). Configurations (changes of the study, as ``--set``):

* ``before``: the solver's defaults before issue 23's options (CasADi's automatic Jacobian of
  ABA, OpenBLAS threads as the environment sets them);
* ``now``: today's defaults (analytical ABA derivatives, one BLAS thread);
* ``mu_init-1e-2``, ``mu_init-1e-3``: IPOPT's first barrier parameter lowered from 1 (the
  re-plans start from the previous plan shifted, a guess close to the optimum);
* ``warm``: ``horizon.warm_start``: every re-plan starts from the last plan's primal and dual
  solution moved by the intervals between them (IPOPT's warm start);
* ``mumps``, ``riccati``: IPOPT's linear solver (``now`` is the study's, ``auto``: ``riccati``
  on arm26).
* ``rti-3``, ``rti-4``, ``rti-5``: real-time iterations (``mpc.iterations_per_replan`` = 3, 4,
  5): every re-plan after the first makes at most that many IPOPT iterations from the plan in
  force, and its last iterate is the plan.
* ``rti-K-HESSIAN`` (K = 2..6; HESSIAN ``gauss-newton``, ``one-step`` or ``euler-step``): the
  same with ``solver.hessian`` = HESSIAN, a cheaper Hessian per iteration (the first plan too).
* ``rti-K-riccati``: the same on the stage-wise KKT solver (the study states MUMPS);
  ``rti-K-HESSIAN-riccati``: both.

``--to-exhaustion``: each run goes on until the plant misses a cycle or a re-plan fails
(``mpc.end = "receding"``, at most 25 cycles), and the table gives the plant's repetitions
beside the real-time factors: a faster scheme must keep the repetitions of the converged
re-plans (within one).

Every run is a child process; the configurations alternate within each repeat; the compile
cache is built first (not timed). Printed: per configuration the medians over the repeats of the
median and largest real-time factor (s of solving per s of motion advanced) of the re-plans, and
of IPOPT's iterations per re-plan.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
STUDY = ROOT / "studies" / "curl_sliding_fatigue_authors-code.toml"
CONFIGS: dict[str, dict] = {
    "before": {"solver.dynamics_jacobian": "automatic", "solver.blas_threads": 0},
    "now": {},
    "mu_init-1e-2": {"solver.mu_init": 1e-2},
    "mu_init-1e-3": {"solver.mu_init": 1e-3},
    "warm": {"horizon.warm_start": True},
    "mumps": {"solver.linear_solver": "mumps"},
    "riccati": {"solver.linear_solver": "riccati"},
    **{f"rti-{k}": {"mpc.iterations_per_replan": k} for k in (2, 3, 4, 5, 6)},
    **{f"rti-{k}-{h}": {"mpc.iterations_per_replan": k, "solver.hessian": h}
       for k in (2, 3, 4, 5, 6) for h in ("gauss-newton", "one-step", "euler-step")},
    **{f"rti-{k}-riccati": {"mpc.iterations_per_replan": k, "solver.linear_solver": "riccati"} for k in (2, 3, 4, 5, 6)},
    **{f"rti-{k}-{h}-riccati": {"mpc.iterations_per_replan": k, "solver.hessian": h, "solver.linear_solver": "riccati"}
       for k in (2, 3, 4, 5, 6) for h in ("gauss-newton", "one-step", "euler-step")},
}
#: ``--to-exhaustion``: the run ends when the plant is spent, not after ``--replans``
EXHAUSTION = {"mpc.end": "receding", "horizon.max_cycles": 25}
LOOP = {"mpc.replan_every": 5, "mpc.estimator": "open-loop", "horizon.max_cycles": 6}


def child(config: str, replans: int, cache: str, out: str) -> None:
    """One closed-loop run of ``replans`` re-plans (0: to exhaustion); writes their records and
    the plant's repetitions as JSON to ``out``."""
    import numpy as np

    from fatigue_pin.io.mpc_study import MpcStudy, run_mpc

    study = MpcStudy.from_file(STUDY, {**LOOP, **(EXHAUSTION if replans == 0 else {}), **CONFIGS[config]})
    run = run_mpc(study, None, cache_dir=cache, stop_after=replans or None)
    rec = run.extras["replans"]
    record = {name: np.asarray(rec[name]).tolist() for name in ("real_time_factor", "iterations", "converged", "wall_time_s")}
    record["statuses"] = [s.decode() for s in rec["status"]]
    record |= {"repetitions": int(run.attrs["repetitions"]), "task_error": np.asarray(run.extras["task_error"]).tolist()}
    Path(out).write_text(json.dumps(record))


def spawn(config: str, replans: int, cache: str, out: str) -> dict:
    env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    proc = subprocess.run([sys.executable, __file__, "--child", config, str(replans), cache, out], env=env,
                          capture_output=True, text=True)
    if proc.returncode != 0:
        print(f"  {config}: child failed:\n{proc.stderr[-2000:]}", flush=True)
        return {}
    return json.loads(Path(out).read_text())


def main() -> None:
    if len(sys.argv) > 1 and sys.argv[1] == "--child":
        child(sys.argv[2], int(sys.argv[3]), sys.argv[4], sys.argv[5])
        return
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--replans", type=int, default=20)
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--configs", default="before,now")
    parser.add_argument("--cache", default=None, help="compile cache (default: a temporary folder)")
    parser.add_argument("--to-exhaustion", action="store_true", help="run every loop until the plant is spent")
    args = parser.parse_args()
    replans = 0 if args.to_exhaustion else args.replans
    configs = args.configs.split(",")
    with tempfile.TemporaryDirectory() as tmpname:
        cache = args.cache or str(Path(tmpname) / "cache")
        print(f"load {os.getloadavg()}, cache {cache}", flush=True)
        for config in configs:  # build the caches (one re-plan), untimed
            spawn(config, 1, cache, str(Path(tmpname) / "build.json"))
        runs: dict[str, list[dict]] = {c: [] for c in configs}
        for rep in range(args.repeats):
            for config in configs:
                r = spawn(config, replans, cache, str(Path(tmpname) / f"{config}_{rep}.json"))
                if r and len(r["iterations"]) < 2:
                    print(f"  repeat {rep} {config}: no re-plan after the first (statuses {r.get('statuses')}, "
                          f"iterations {r['iterations']})", flush=True)
                elif r:
                    runs[config].append(r)
                    print(f"  repeat {rep} {config}: RTF median {statistics.median(r['real_time_factor'][1:]):.2f}, max "
                          f"{max(r['real_time_factor'][1:]):.2f}, repetitions {r['repetitions']}, task errors "
                          f"{[round(e, 4) for e in r['task_error']]}, iterations {r['iterations']}, load {os.getloadavg()[0]:.2f}", flush=True)
        print()
        print("Real-time factors and iterations of the re-plans after the first (the first plan is made before the motion).")
        print("| configuration | re-plans | converged | real-time factor median | real-time factor max | iterations median | repetitions |")
        print("|---|---|---|---|---|---|---|")
        for config, rs in runs.items():
            if not rs:
                continue
            med = lambda f: statistics.median(f(r) for r in rs)  # noqa: E731
            print(f"| {config} | {len(rs[0]['iterations'])} | {sum(map(bool, rs[0]['converged']))} | "
                  f"{med(lambda r: statistics.median(r['real_time_factor'][1:])):.2f} | {med(lambda r: max(r['real_time_factor'][1:])):.2f} | "
                  f"{med(lambda r: statistics.median(r['iterations'][1:])):.0f} | {', '.join(str(r['repetitions']) for r in rs)} |", flush=True)


if __name__ == "__main__":
    main()
