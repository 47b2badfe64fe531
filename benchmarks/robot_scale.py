"""Robot-scale speed (issue 23): sliding windows of arm26, a UR5 and a Panda, for today's default
and each speed option, side by side in one run.

Usage::

    python benchmarks/robot_scale.py [--cases arm26,ur5,panda] [--configs exact,gauss-newton]
                                     [--windows 4] [--repeats 3] [--cache DIR]

Cases (studies):

* ``arm26``: the paper's sliding study, authors-code, cost fatigue, S = 10
  (studies/curl_sliding_fatigue_authors-code.toml), the whole run (until a window fails);
* ``ur5``: benchmarks/studies/ur5_scale.toml (3 kg at tool0, two frame targets per 1 s cycle,
  3CC-S on every half, windows of 3 cycles x 50 intervals, 5 RK4 substeps), ``--windows`` windows;
* ``panda``: benchmarks/studies/panda_scale.toml (fingers locked, 2 kg at the hand), the same.

Configurations (:data:`CONFIGS`): changes of the study (``--set`` syntax) per option; ``exact`` is
today's default (the study's own linear solver); ``X-riccati`` and ``X-mumps`` are option ``X``
on the stage-wise KKT solver or on MUMPS; ``O1`` and ``O2`` compile the library at -O1 or -O2 (with ``-march=native``)
instead of the default -O3.

Every run is a child process (its own peak memory, ``ru_maxrss``). First every (case,
configuration) is built once against the compile cache ``--cache`` (default: a fresh temporary
folder, so that the compile a user waits for is measured); then the runs are repeated
``--repeats`` times, the configurations alternating within each repeat, so that a busy machine
slows all of them alike. Printed per (case, configuration): compile time, the medians over the
repeats of the median window time, iterations per window, time per iteration and real-time
factor (s of solving per s of motion advanced), whole-run time, windows converged, peak memory,
and the optimum's difference from ``exact`` on the first window (same problem: relative
objective, largest state difference) and over all windows both solved.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CASES = {
    "arm26": (ROOT / "studies" / "curl_sliding_fatigue_authors-code.toml", None),
    "ur5": (ROOT / "benchmarks" / "studies" / "ur5_scale.toml", "windows"),
    "panda": (ROOT / "benchmarks" / "studies" / "panda_scale.toml", "windows"),
}
#: configuration name -> study changes (dotted key -> value)
CONFIGS: dict[str, dict] = {
    "before": {"solver.dynamics_jacobian": "automatic", "solver.blas_threads": 0},  # the default before issue 23's options
    "exact": {},
    "one-step": {"solver.hessian": "one-step"},
    "gauss-newton": {"solver.hessian": "gauss-newton"},
    "substeps2": {"transcription.substeps": 2},
    "one-step-substeps2": {"solver.hessian": "one-step", "transcription.substeps": 2},
    "warm": {"horizon.warm_start": True},
    "analytical": {"solver.dynamics_jacobian": "analytical"},
    "O1": {"solver.compiler_flags": ["-O1", "-march=native"]},
    "O2": {"solver.compiler_flags": ["-O2", "-march=native"]},
    "euler-step": {"solver.hessian": "euler-step"},
    "analytical-one-step": {"solver.dynamics_jacobian": "analytical", "solver.hessian": "one-step"},
    "analytical-euler-step": {"solver.dynamics_jacobian": "analytical", "solver.hessian": "euler-step"},
    "blas0": {"solver.blas_threads": 0},
    "automatic": {"solver.dynamics_jacobian": "automatic"},
    "one-step-warm": {"solver.hessian": "one-step", "horizon.warm_start": True},
    "mumps": {"solver.linear_solver": "mumps"},
}
# every option again on each linear solver: ``X-riccati`` (the stage-wise KKT solver) and
# ``X-mumps``, whatever the study states
CONFIGS.update({f"{name}-{ls}": {**changes, "solver.linear_solver": ls}
                for name, changes in list(CONFIGS.items()) if name not in ("before", "mumps") for ls in ("riccati", "mumps")})


def child(case: str, config: str, windows: int, cache: str, out: str) -> None:
    """One run in this process; writes a JSON summary to ``out`` and the windows' states beside it."""
    import resource

    from fatigue_pin.drivers.sliding import SlidingHorizon, SlidingSettings
    from fatigue_pin.io.study import Study

    path, limit = CASES[case]
    study = Study.from_file(path)
    changes = dict(CONFIGS[config])
    if changes:
        study = study.replace(changes)
    h = study.horizon
    max_cycles = h["cycles"] + windows - 1 if (limit and windows > 0) else (h["max_cycles"] if windows > 0 else h["cycles"])
    t0 = time.perf_counter()
    problem = study.problem()
    settings = SlidingSettings(window=h["cycles"], advance=h["advance"], max_cycles=max_cycles, end_tolerance=h["end_tolerance"],
                               failure_iterations=h["failure_iterations"], min_iterations=h["min_iterations"], warmup=h["warmup"],
                               guess_fatigue=h["guess_fatigue"], warm_start=h["warm_start"])
    runner = SlidingHorizon(problem, settings, study.transcription(), study.solver(cache), guess=h["guess"])
    build = time.perf_counter() - t0
    result: dict = {"case": case, "config": config, "build_s": build, "compile_s": float(runner.ocp.compile_time_s),
                    "nv": problem.layout.nv, "nx": problem.layout.nx, "intervals": runner.ocp.n_intervals}
    xs, objs = [], []
    if windows > 0:
        t1, c1 = time.perf_counter(), time.process_time()
        sols = []
        solve = runner.ocp.solve

        def recorded(*a, **k):  # every window's solution, for the optimum's difference
            sols.append(solve(*a, **k))
            return sols[-1]

        runner.ocp.solve = recorded
        run = runner.run(None)
        result["run_s"] = time.perf_counter() - t1
        result["run_cpu_s"] = time.process_time() - c1  # every thread's CPU time: less sensitive to other processes
        w = run.windows
        result.update(wall=w["wall_time_s"].tolist(), iterations=w["iterations"].tolist(), converged=w["converged"].tolist(),
                      objective=w["objective"].tolist(), advance_s=h["advance"] * problem.task.cycle_duration)
        xs = [s.x for s in sols]
        objs = [s.objective for s in sols]
    result["peak_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    np.savez(out + ".npz", *xs, objective=np.array(objs))
    Path(out).write_text(json.dumps(result))


def spawn(case: str, config: str, windows: int, cache: str, tmp: Path, tag: str) -> dict:
    out = str(tmp / f"{case}_{config}_{tag}.json")
    env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    cmd = [sys.executable, __file__, "--child", case, config, str(windows), cache, out]
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
    if proc.returncode != 0:
        print(f"  {case} {config}: child failed:\n{proc.stderr[-2000:]}", flush=True)
        return {}
    r = json.loads(Path(out).read_text())
    with np.load(out + ".npz") as z:
        r["x"] = [z[f"arr_{i}"] for i in range(len(z.files) - 1)]
    return r


def differences(a: dict, b: dict) -> tuple[float, float, float, float]:
    """(relative objective, largest state difference) on the first window, then the largest of
    each over the windows both converged."""
    n = min(len(a.get("x", [])), len(b.get("x", [])))
    rel, dx = [], []
    for i in range(n):
        if not (a["converged"][i] and b["converged"][i]):
            break
        rel.append(abs(a["objective"][i] - b["objective"][i]) / max(abs(a["objective"][i]), 1e-300))
        dx.append(float(np.abs(a["x"][i] - b["x"][i]).max()) if a["x"][i].shape == b["x"][i].shape else float("nan"))
    if not rel:
        return (float("nan"),) * 4
    return rel[0], dx[0], max(rel), max(dx)


def main() -> None:
    if len(sys.argv) > 1 and sys.argv[1] == "--child":
        child(sys.argv[2], sys.argv[3], int(sys.argv[4]), sys.argv[5], sys.argv[6])
        return
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cases", default="arm26,ur5,panda")
    parser.add_argument("--configs", default="exact,gauss-newton")
    parser.add_argument("--windows", type=int, default=4, help="windows per robot run (arm26: the whole run)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--cache", default=None, help="compile cache (default: a fresh temporary folder: compiles are timed)")
    args = parser.parse_args()
    cases, configs = args.cases.split(","), args.configs.split(",")
    for name in cases + configs:
        if name not in CASES and name not in CONFIGS:
            raise SystemExit(f"unknown case or configuration {name!r}; expected {sorted(CASES)} / {sorted(CONFIGS)}")
    with tempfile.TemporaryDirectory() as tmpname:
        tmp = Path(tmpname)
        cache = args.cache or str(tmp / "cache")
        print(f"load {os.getloadavg()}, cache {cache}", flush=True)
        compile_s: dict = {}
        for case in cases:
            for config in configs:
                r = spawn(case, config, 0, cache, tmp, "build")
                compile_s[case, config] = r.get("compile_s", float("nan"))
                print(f"  build {case} {config}: compile {compile_s[case, config]:.1f} s, build {r.get('build_s', float('nan')):.1f} s",
                      flush=True)
        runs: dict = {(c, k): [] for c in cases for k in configs}
        for rep in range(args.repeats):
            for case in cases:
                for config in configs:
                    r = spawn(case, config, args.windows, cache, tmp, f"r{rep}")
                    if not r:
                        continue
                    runs[case, config].append(r)
                    ok = np.array(r["converged"], dtype=bool)
                    wall = np.array(r["wall"])
                    print(f"  repeat {rep} {case} {config}: {int(ok.sum())}/{len(ok)} windows, median window "
                          f"{np.median(wall[ok]) if ok.any() else float('nan'):.3f} s, run {r['run_s']:.2f} s "
                          f"(CPU {r['run_cpu_s']:.2f} s), "
                          f"iterations {r['iterations']}, load {os.getloadavg()[0]:.2f}", flush=True)
        print()
        print("| robot (nv) | option | compile (s) | median window (s) | iterations / window | ms / iteration | real-time factor "
              "| whole run (s) | run CPU (s) | windows converged | peak memory (MB) | first window: objective rel. / states | all windows |")
        print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
        for case in cases:
            base = runs[case, configs[0]]
            for config in configs:
                rs = runs[case, config]
                if not rs:
                    continue
                med = lambda f: statistics.median(f(r) for r in rs)  # noqa: E731
                ok = lambda r: np.array(r["converged"], dtype=bool)  # noqa: E731
                window = med(lambda r: float(np.median(np.array(r["wall"])[ok(r)])) if ok(r).any() else float("nan"))
                iters = med(lambda r: float(np.median(np.array(r["iterations"])[ok(r)])) if ok(r).any() else float("nan"))
                per_it = med(lambda r: 1e3 * float(np.sum(np.array(r["wall"])[ok(r)]) / max(1, np.sum(np.array(r["iterations"])[ok(r)]))))
                rtf = window / rs[0]["advance_s"]
                d = differences(base[0], rs[0]) if base else (float("nan"),) * 4
                print(f"| {case} ({rs[0]['nv']}) | {config} | {compile_s[case, config]:.1f} | {window:.3f} | {iters:.0f} | {per_it:.1f} | "
                      f"{rtf:.2f} | {med(lambda r: r['run_s']):.2f} | {med(lambda r: r['run_cpu_s']):.2f} | {int(ok(rs[0]).sum())}/{len(rs[0]['converged'])} | "
                      f"{med(lambda r: r['peak_rss_mb']):.0f} | {d[0]:.1e} / {d[1]:.1e} | {d[2]:.1e} / {d[3]:.1e} |", flush=True)


if __name__ == "__main__":
    main()
