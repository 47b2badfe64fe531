"""IPOPT's KKT solve by the stage-wise solver (``solver.linear_solver = "riccati"``, issue 33)
against MUMPS, on a sliding study's first window, in one run.

Usage::

    python benchmarks/kkt_solvers.py [--cases arm26,ur5] [--repeats 5] [--iterations 10]

Cases: ``arm26`` the paper's sliding study (studies/curl_sliding_fatigue_paper.toml), ``ur5``
benchmarks/studies/ur5_scale.toml, ``panda`` benchmarks/studies/panda_scale.toml and ``muscles``
studies/curl_muscles_sliding.toml, first window each (the compiled library from the cache).

Per case, the first window is solved ``--repeats`` times with each solver, alternating. Printed:

* iterate agreement over the first ``--iterations`` iterations (objective, inf_pr: the largest
  relative difference), iterations and final objective of each;
* per solver, medians over the repeats of: IPOPT's timing statistics of the linear system
  (LinearSystemFactorization + LinearSystemBackSolve per iteration; NB: with MUMPS, IPOPT's
  factorisation timer reads 0 and the back-solve timer does not hold MUMPS's whole work, so only
  the next column compares the two), IPOPT's own time per iteration (IPOPT's OverallAlgorithm wall
  time minus the NLP function evaluations: the KKT solves and IPOPT's vector work), the window's wall
  time, IPOPT's symbolic analysis of the pattern per solve (LinearSystemSymbolicFactorization: with
  ``riccati`` the first solve analyses, later solves of the same pattern copy that analysis), and
  the stage-wise solver's blocks (count, largest).
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
CASES = {
    "arm26": ROOT / "studies" / "curl_sliding_fatigue_paper.toml",
    "ur5": ROOT / "benchmarks" / "studies" / "ur5_scale.toml",
    "panda": ROOT / "benchmarks" / "studies" / "panda_scale.toml",
    "muscles": ROOT / "studies" / "curl_muscles_sliding.toml",
}
SOLVERS = ("riccati", "mumps")
# "riccati-block": the stage-wise library with its pair step off (FATIGUE_PIN_RICCATI_PAIR=0 while it
# solves: the library reads it at each analysis), i.e. the block LDL^T alone, for the A/B.
PAIR_ENV = "FATIGUE_PIN_RICCATI_PAIR"


def linear_solver_of(name: str) -> str:
    return "riccati" if name.startswith("riccati") else name


def pair_counts() -> tuple[int, int] | None:
    """(pair-step, block LDL^T) factorisations of the stage-wise library's last analysed solver."""
    import ctypes

    from fatigue_pin.ocp.riccati import riccati_library

    path = riccati_library()
    if path is None:
        return None
    lib = ctypes.CDLL(str(path))
    if not hasattr(lib, "riccati_pair_counts"):
        return None
    p, b = ctypes.c_long(0), ctypes.c_long(0)
    lib.riccati_pair_counts(ctypes.byref(p), ctypes.byref(b))
    return p.value, b.value
TIMING = {"factor": "LinearSystemFactorization", "backsolve": "LinearSystemBackSolve",
          "symbolic": "LinearSystemSymbolicFactorization"}


def first_window(path: Path, linear_solver: str):
    """The sliding runner's NLP solver and the arguments of its first window's solve."""
    from fatigue_pin.drivers.sliding import SlidingHorizon, SlidingSettings
    from fatigue_pin.io.study import Study

    study = Study.from_file(path).replace({"solver.linear_solver": linear_solver, "solver.ipopt": {"print_timing_statistics": "yes"},
                                           "solver.print_level": 3})
    h = study.horizon
    settings = SlidingSettings(window=h["cycles"], advance=h["advance"], max_cycles=h["cycles"], end_tolerance=h["end_tolerance"],
                               failure_iterations=h["failure_iterations"], min_iterations=h["min_iterations"], warmup=h["warmup"],
                               guess_fatigue=h["guess_fatigue"], warm_start=h["warm_start"])
    runner = SlidingHorizon(study.problem(), settings, study.transcription(), study.solver(), guess=h["guess"])
    calls = []
    solve = runner.ocp.solve

    def recorded(*a, **k):
        calls.append((a, k))
        return solve(*a, **k)

    runner.ocp.solve = recorded
    from fatigue_pin.core.streams import captured
    with captured(1):
        runner.run(None)
    runner.ocp.solve = solve
    return runner.ocp, calls[0]


def timed(ocp, call, solver: str = "") -> dict:
    from fatigue_pin.core.streams import captured

    a, k = call
    old = os.environ.pop(PAIR_ENV, None)
    if solver == "riccati-block":
        os.environ[PAIR_ENV] = "0"
    try:
        with captured(1) as said:
            t0 = time.perf_counter()
            ocp.solve(*a, **k)
            wall = time.perf_counter() - t0
    finally:
        os.environ.pop(PAIR_ENV, None)
        if old is not None:
            os.environ[PAIR_ENV] = old
    stats = ocp.nlp.stats() if hasattr(ocp, "nlp") else None
    text = "\n".join(said)
    out = {"wall": wall}
    for key, label in TIMING.items():
        m = re.search(label + r"\.*:\s*[0-9.eE+-]+\s*\(sys:\s*[0-9.eE+-]+\s*wall:\s*([0-9.eE+-]+)\)", text)
        out[key] = float(m.group(1)) if m else float("nan")
    m = re.search(r"Number of Iterations\.+:\s*(\d+)", text)
    out["iterations"] = int(m.group(1)) if m else -1
    out["factorizations"] = len(re.findall(r"^\s*\d+r?\s", text, flags=re.M))  # iteration lines (lower bound)
    out["said"] = text
    out["counts"] = pair_counts() if solver.startswith("riccati") else None
    st = ocp.nlp.stats()
    evals = sum(v for k, v in st.items() if k.startswith("t_wall_nlp_"))
    m = re.search(r"OverallAlgorithm\.*:\s*[0-9.eE+-]+\s*\(sys:\s*[0-9.eE+-]+\s*wall:\s*([0-9.eE+-]+)\)", text)
    # IPOPT's own time: its whole algorithm's wall time minus the NLP function evaluations
    out["ipopt"] = (float(m.group(1)) if m else wall) - evals
    out["stats"] = stats
    return out


def blocks(ocp) -> str:
    """The stage-wise solver's blocks on this NLP (largest, count)."""
    from fatigue_pin.ocp.riccati import riccati_blocks

    solver = next(iter(ocp.nlp._solvers.values()))
    biggest, count = riccati_blocks(solver.get_function("nlp_hess_l").sparsity_out(0), solver.get_function("nlp_jac_g").sparsity_out(1))
    return f"{count} of <= {biggest}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cases", default="arm26,ur5")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--iterations", type=int, default=10)
    ap.add_argument("--solvers", default=",".join(SOLVERS), help="riccati, riccati-block (pair step off), mumps")
    args = ap.parse_args()
    solvers = args.solvers.split(",")
    print(f"{'case':6} {'solver':13} {'iters':>5} {'objective':>22} {'KKT ms/iter':>11} {'factor ms':>9} {'solves ms':>9} "
          f"{'IPOPT ms/iter':>13} {'analysis ms':>11} {'window s':>8}  blocks")
    for case in args.cases.split(","):
        built = {s: first_window(CASES[case], linear_solver_of(s)) for s in solvers}
        runs: dict[str, list[dict]] = {s: [] for s in solvers}
        for _ in range(args.repeats):
            for s in solvers:
                ocp, call = built[s]
                r = timed(ocp, call, s)
                r["record"] = ocp.nlp.stats()["iterations"] if hasattr(ocp, "nlp") else None
                runs[s].append(r)
        last = {s: runs[s][-1] for s in solvers}
        for s in solvers:
            it = last[s]["iterations"]
            per = [(r["factor"] + r["backsolve"]) / max(1, r["iterations"] + 1) * 1e3 for r in runs[s]]
            fac = [r["factor"] / max(1, r["iterations"] + 1) * 1e3 for r in runs[s]]
            sol = [r["backsolve"] / max(1, r["iterations"] + 1) * 1e3 for r in runs[s]]
            wall = [r["wall"] for r in runs[s]]
            inner = [r["ipopt"] / max(1, r["iterations"]) * 1e3 for r in runs[s]]
            symbolic = [r["symbolic"] * 1e3 for r in runs[s]]
            obj = last[s]["record"]["obj"][-1] if last[s]["record"] else float("nan")
            print(f"{case:6} {s:13} {it:5d} {obj:22.15e} {statistics.median(per):11.3f} {statistics.median(fac):9.3f} "
                  f"{statistics.median(sol):9.3f} {statistics.median(inner):13.2f} {statistics.median(symbolic):11.2f} {statistics.median(wall):8.3f}  {blocks(built[s][0])}"
                  + (f"; pair/block factorisations {last[s]['counts']}" if last[s].get("counts") else ""))
        pairs = [(x, y) for i, x in enumerate(solvers) for y in solvers[i + 1:]]
        for sa, sb in pairs:
            ra, rb = last[sa]["record"], last[sb]["record"]
            if not (ra and rb):
                continue
            n = min(args.iterations + 1, len(ra["obj"]), len(rb["obj"]))
            rel = lambda a, b: float(np.max(np.abs(np.subtract(a, b)) / np.maximum(np.abs(b), 1e-300)))  # noqa: E731
            print(f"{case:6} {sa} vs {sb}, iterates 0..{n - 1}: objective rel. diff {rel(ra['obj'][:n], rb['obj'][:n]):.2e}, "
                  f"inf_pr rel. diff {rel(ra['inf_pr'][:n], rb['inf_pr'][:n]):.2e}; iterations {last[sa]['iterations']} / "
                  f"{last[sb]['iterations']}; final objective rel. diff {abs(ra['obj'][-1] - rb['obj'][-1]) / abs(rb['obj'][-1]):.2e}")
        sys.stdout.flush()


if __name__ == "__main__":
    main()
