"""Each named study run whole with MUMPS and with the stage-wise KKT solver (``riccati``, stated
explicitly), one after the other: repetitions, objective, IPOPT iterations, wall time and
``fatigue-pin verify``. The check behind a study's ``solver.linear_solver = "riccati"``: the same
optimum and repetitions, verify passing.

Usage::

    python benchmarks/linear_solver_studies.py ur5_carry ur5_lift_swing [--cache DIR] [--out DIR]

A name is a file of studies/ or benchmarks/studies/. The MUMPS run goes first and compiles the
study's library into the cache, so its wall time includes the compile unless the cache already
holds it: compare the iterations here, the speed with benchmarks/kkt_solvers.py.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("studies", nargs="+")
    ap.add_argument("--cache", default=None, help="compiled-code cache (default ~/.cache/fatigue_pin)")
    ap.add_argument("--out", default=None, help="folder of the result files (default: a temporary one)")
    args = ap.parse_args()
    from fatigue_pin.io.study import Study, run_study

    folder = Path(args.out or tempfile.mkdtemp(prefix="linear_solver_studies_"))
    folder.mkdir(parents=True, exist_ok=True)
    for name in args.studies:
        path = next((p for p in (ROOT / "studies" / f"{name}.toml", ROOT / "benchmarks" / "studies" / f"{name}.toml") if p.is_file()), None)
        if path is None:
            sys.exit(f"study {name!r}: no file studies/{name}.toml or benchmarks/studies/{name}.toml")
        for solver in ("mumps", "riccati"):
            out = folder / f"{name}_{solver}.h5"
            out.unlink(missing_ok=True)
            study = Study.from_file(path).replace({"solver.linear_solver": solver})
            t0 = time.perf_counter()
            r = run_study(study, out=out, cache_dir=args.cache)
            wall = time.perf_counter() - t0
            v = subprocess.run([sys.executable, "-m", "fatigue_pin.cli.main", "verify", str(out)], capture_output=True, text=True)
            said = (v.stdout.strip().splitlines() or [""])[-1].strip()
            print(f"{name:20} {solver:8} {r.kind:8} repetitions {r.repetitions:3d} objective {r.objective:.12e} iterations {r.iterations:5d} "
                  f"wall {wall:6.1f} s  verify: {said} (exit {v.returncode})", flush=True)


if __name__ == "__main__":
    main()
