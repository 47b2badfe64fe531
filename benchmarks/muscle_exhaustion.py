"""The muscle curl to exhaustion (studies/curl_muscles_exhaustion.toml): its speed against issue
34's targets (median window <= 1.0 s, whole run to exhaustion <= 90 s, per-model compile <= 30 s)
and its repetitions, for the study as shipped and for variants given as ``--set`` groups.

Usage::

    python benchmarks/muscle_exhaustion.py [--runs 2] [--fresh-cache]
        [--variant "substeps 8" transcription.substeps=8] [--verify]

Each run is ``fatigue-pin run`` in a subprocess (its wall time includes Python's start, the study's
build and, with ``--fresh-cache``, the compile of the interval library into an empty
``FATIGUE_PIN_CACHE``). One row per variant: medians over its runs of the compile (s, the run's
``compile_time_s``; "cached" when the library was on disk), the median window (s of solve per
converged window), the converged windows' total solve, the failing window's solve, the whole run's
wall time, the IPOPT iterations, the repetitions and how the run ended; with ``--verify``,
``fatigue-pin verify`` of the last run (its largest gaps and verdict). The load average is
printed beside every run: the machine is shared.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from fatigue_pin.io.results import read_run

ROOT = Path(__file__).resolve().parents[1]
STUDY = ROOT / "studies/curl_muscles_exhaustion.toml"
CLI = [sys.executable, "-c", "import sys; from fatigue_pin.cli.main import main; sys.exit(main())"]


def load() -> str:
    return " ".join(Path("/proc/loadavg").read_text().split()[:3]) if Path("/proc/loadavg").exists() else "?"


def one_run(sets: list[str], out: Path, env: dict) -> dict:
    args = [*CLI, "run", str(STUDY), "--out", str(out)]
    for s in sets:
        args += ["--set", s]
    before = load()
    t0 = time.perf_counter()
    proc = subprocess.run(args, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if not out.exists():
        raise SystemExit(f"the run wrote no file (exit {proc.returncode}):\n{proc.stderr[-2000:]}")
    run = read_run(out)
    w = run.windows
    ok = w["converged"]
    times = np.asarray(w["wall_time_s"], dtype=float)
    compile_s = float(run.attrs.get("compile_time_s", 0.0) or 0.0)
    last = proc.stdout.strip().splitlines()[-1] if proc.stdout.strip() else ""
    return {"wall": wall, "compile": compile_s, "median": float(np.median(times[ok])) if ok.any() else float("nan"),
            "solve": float(times[ok].sum()), "failed": float(times[~ok].sum()), "iterations": int(np.sum(w["iterations"])),
            "windows": int(ok.sum()), "repetitions": int(run.attrs.get("repetitions", 0)),
            "ended": "max_cycles" if bool(ok.all()) else str(w["status"][~ok][0].decode()),
            "load": f"{before} -> {load()}", "last": last}


def verify(out: Path, env: dict) -> str:
    t0 = time.perf_counter()
    proc = subprocess.run([*CLI, "verify", str(out)], env=env, capture_output=True, text=True)
    lines = [l.strip() for l in proc.stdout.splitlines() if l.strip().startswith(("gap", "PASSED", "FAILED"))]
    return f"{'; '.join(' '.join(l.split()[:4]) for l in lines)} ({time.perf_counter() - t0:.0f} s, exit {proc.returncode})"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=1)
    ap.add_argument("--fresh-cache", action="store_true", help="compile into an empty cache for every run")
    ap.add_argument("--variant", nargs="+", action="append", default=None, metavar=("LABEL", "KEY=VALUE"),
                    help="a label and its --set changes; default: the study as shipped")
    ap.add_argument("--verify", action="store_true")
    args = ap.parse_args()
    variants = args.variant or [["as shipped"]]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for label, *sets in variants:
            runs = []
            for k in range(args.runs):
                env = dict(os.environ)
                if args.fresh_cache:
                    env["FATIGUE_PIN_CACHE"] = str(Path(tmp) / f"cache_{len(rows)}_{k}")
                out = Path(tmp) / f"run_{len(rows)}_{k}.h5"
                r = one_run(sets, out, env)
                print(f"# {label}, run {k + 1}: {r['last']}  [wall {r['wall']:.1f} s, load {r['load']}]", flush=True)
                runs.append(r)
            med = {key: statistics.median(r[key] for r in runs) for key in ("wall", "compile", "median", "solve", "failed", "iterations")}
            row = {"label": label, **med, "repetitions": "/".join(str(r["repetitions"]) for r in runs),
                   "ended": runs[-1]["ended"], "compiled": any(r["compile"] > 0 for r in runs),
                   "verify": verify(out, env) if args.verify else "-"}
            rows.append(row)
    print("\n| variant | runs | compile (s) | median window (s) | converged windows' solve (s) | failing window (s) | whole run wall (s) "
          "| iterations | repetitions | ended | verify |\n|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        comp = f"{r['compile']:.1f}" if r["compiled"] else "cached"
        print(f"| {r['label']} | {args.runs} | {comp} | {r['median']:.2f} | {r['solve']:.1f} | {r['failed']:.1f} | {r['wall']:.1f} "
              f"| {r['iterations']:.0f} | {r['repetitions']} | {r['ended']} | {r['verify']} |")


if __name__ == "__main__":
    main()
