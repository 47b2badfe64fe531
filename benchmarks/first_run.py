"""A user's first run on a machine: ``fatigue-pin run`` end to end with an empty compiled-code
cache, for each ``solver.first_compile``, then the next run (the library cached).

Usage::

    python benchmarks/first_run.py [--repeats 3] [--cases pendulum arm26-1 arm26-2]

One table row per case and mode: the median wall time of ``--repeats`` runs of the CLI (each in
a fresh process with a fresh ``FATIGUE_PIN_CACHE``, the way a user meets it; ``background``
waits for its detached compile to finish before the next repeat so that runs do not overlap),
the IPOPT iterations and the objective. ``next`` is the second run on the cache that the
``background`` run filled. ``uncompiled`` is ``solver.compile = false``.
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CASES = {
    "pendulum": ["studies/bioptim_pendulum_xia.toml"],
    "arm26-1": ["studies/curl_full_authors-variant.toml", "--set", "horizon.cycles=1"],
    "arm26-2": ["studies/curl_full_authors-variant.toml", "--set", "horizon.cycles=2"],
}
MODES = {"wait": ["--set", "solver.first_compile=wait"], "background": ["--set", "solver.first_compile=background"],
         "uncompiled": ["--set", "solver.compile=false"]}


def cli(args: list[str], cache: Path, out: Path) -> tuple[float, str]:
    """Wall time (s) and output of one ``fatigue-pin run``."""
    env = {**os.environ, "FATIGUE_PIN_CACHE": str(cache)}
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "fatigue_pin.cli.main", "run", *args, "--out", str(out)],
                          cwd=ROOT, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"run failed ({proc.returncode}): {' '.join(args)}\n{proc.stderr[-2000:]}")
    return wall, proc.stdout + proc.stderr


def wait_compiled(cache: Path, timeout_s: float = 600.0) -> None:
    """Until the detached compile has written its checksum (the last step)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline and not list(cache.glob("*.so.sha256")):
        time.sleep(0.2)


def solved(output: str) -> str:
    match = re.search(r"(\d+) iterations, [0-9.]+ s, objective (\S+)", output)
    return f"{match.group(1):>5} {match.group(2):>12}" if match else f"{'?':>5} {'?':>12}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    args = parser.parse_args()
    print(f"{'case':<10} {'mode':<11} {'median s':>9} {'runs s':<24} {'iter':>5} {'objective':>12}")
    for case in args.cases:
        for mode in (*MODES, "next"):
            walls, last = [], ""
            for _ in range(args.repeats):
                with tempfile.TemporaryDirectory(prefix="fatigue_pin_first.") as tmp:
                    cache, out = Path(tmp) / "cache", Path(tmp) / "run.h5"
                    if mode == "next":
                        cli(CASES[case] + MODES["background"], cache, Path(tmp) / "first.h5")
                        wait_compiled(cache)
                    wall, last = cli(CASES[case] + MODES.get(mode, []), cache, out)
                    if mode == "background":
                        wait_compiled(cache)
                    walls.append(wall)
            runs = " ".join(f"{w:.1f}" for w in walls)
            print(f"{case:<10} {mode:<11} {statistics.median(walls):>9.1f} {runs:<24} {solved(last)}", flush=True)


if __name__ == "__main__":
    main()
