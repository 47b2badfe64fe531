"""Fresh install of fatigue_pin: wall time and peak memory per phase, and the symbolic builds at first solve.

Usage::

    python benchmarks/install.py [--repeats 2] [--phases] [--skip-full] [--symbolic-only PYTHON]

Every run starts from a new virtual environment and an empty pip cache (``PIP_CACHE_DIR`` in a
temporary folder), as on a fresh machine. Tables:

1. ``--phases``: the install split in three: (a) the build dependencies (``build-system.requires``)
   into a new venv, (b) ``pip wheel . --no-build-isolation`` with that venv (CMake configure and
   the compile of src/), (c) the wheel with the run-time and test dependencies into another new
   venv (the cache of (a) is warm by then, as it is for pip's own isolated build).
2. the real command, ``python -m venv .venv && .venv/bin/pip install '.[test]'``, ``--repeats``
   times, each with an empty cache (skipped with ``--skip-full``).
3. the extension's symbolic builds, what the user waits for at the first solve of a model:
   ``casadi_dynamics`` (ABA and RNEA), ``casadi_aba_derivatives`` and the end-effector's frame
   functions, for arm26 and the UR5, in the venv of table 2 (or 1), or in ``--symbolic-only``'s
   Python.

Peak RSS is the largest resident set of one process of the phase (the compiler of the heaviest
translation unit during a build). The load average (1 min) is printed beside each time: the
machine may be shared.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

# Runs in the venv under test: one line per (model, function) with its build time in seconds.
SYMBOLIC = r"""
import time
t0 = time.perf_counter()
from fatigue_pin.robot import dynamics, kinematics
from fatigue_pin.robot.model import resolve_model
print(f"import\t-\t{time.perf_counter() - t0:.2f}", flush=True)
for name, frame in (("arm26", None), ("ur5", "tool0")):
    model = resolve_model(name).pin_model
    frame = frame or model.frames[-1].name
    for label, build in (("dynamics (aba, rnea)", lambda: dynamics.casadi_dynamics(model)),
                         ("aba_derivatives", lambda: dynamics.casadi_aba_derivatives(model)),
                         ("frame kinematics", lambda: kinematics.frame_functions(model, frame))):
        t0 = time.perf_counter()
        build()
        print(f"{name}\t{label}\t{time.perf_counter() - t0:.3f}", flush=True)
"""

# Runs a command and prints the largest ru_maxrss (kB) of its process tree on the last line.
MEASURE = ("import resource, subprocess, sys; rc = subprocess.run(sys.argv[1:]).returncode; "
           "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss); sys.exit(rc)")


def load() -> str:
    """1-minute load average."""
    return f"{os.getloadavg()[0]:.2f}"


def run(cmd: list[str], log: Path, env: dict[str, str] | None = None, cwd: Path | None = None) -> tuple[float, float]:
    """Runs ``cmd`` (output to ``log``); returns (wall s, peak RSS MB of one of its processes)."""
    t0 = time.perf_counter()
    with open(log, "w") as out:
        proc = subprocess.run([sys.executable, "-c", MEASURE, *cmd], stdout=subprocess.PIPE, stderr=out,
                              env=env, cwd=cwd, text=True)
    wall = time.perf_counter() - t0
    lines = proc.stdout.splitlines()
    log.write_text(log.read_text() + "\n".join(lines[:-1]))
    if proc.returncode:
        raise SystemExit(f"{' '.join(cmd)} failed (exit {proc.returncode}), see {log}")
    return wall, int(lines[-1]) / 1024


def fresh_env(cache: Path) -> dict[str, str]:
    """The environment with an empty pip cache and no PYTHONPATH."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["PIP_CACHE_DIR"] = str(cache)
    return env


def row(phase: str, wall: float, rss: float, start_load: str) -> None:
    print(f"{phase:<44} {wall:>8.1f} {rss:>10.0f} {start_load:>6}/{load():<6}", flush=True)


def header(title: str) -> None:
    print(f"\n## {title}")
    print(f"{'phase':<44} {'wall s':>8} {'peak MB':>10} {'load start/end':>14}")


def phases(tmp: Path) -> Path:
    """Table 1; returns the Python of the venv with the wheel installed."""
    header("phases (empty pip cache at (a))")
    env = fresh_env(tmp / "cache")
    requires = tomllib.loads((ROOT / "pyproject.toml").read_text())["build-system"]["requires"]
    l0 = load()
    wall, rss = run([sys.executable, "-m", "venv", str(tmp / "build")], tmp / "a0.log", env)
    w, r = run([str(tmp / "build/bin/pip"), "install", *requires], tmp / "a.log", env)
    row("(a) build dependencies", wall + w, max(rss, r), l0)
    l0 = load()
    wall, rss = run([str(tmp / "build/bin/pip"), "wheel", str(ROOT), "--no-build-isolation", "--no-deps", "-w",
                     str(tmp / "wheel")], tmp / "b.log", env)
    row("(b) configure + compile (pip wheel)", wall, rss, l0)
    l0 = load()
    wheel = next((tmp / "wheel").glob("fatigue_pin-*.whl"))
    wall, rss = run([sys.executable, "-m", "venv", str(tmp / "run")], tmp / "c0.log", env)
    w, r = run([str(tmp / "run/bin/pip"), "install", f"{wheel}[test]"], tmp / "c.log", env)
    row("(c) run-time and test dependencies", wall + w, max(rss, r), l0)
    return tmp / "run/bin/python"


def full(tmp: Path, repeats: int) -> Path:
    """Table 2; returns the Python of the last venv."""
    header("python -m venv .venv && .venv/bin/pip install '.[test]' (empty pip cache each time)")
    walls = []
    for i in range(repeats):
        venv = tmp / f"full{i}"
        env = fresh_env(tmp / f"cache_full{i}")
        l0 = load()
        wall, rss = run([sys.executable, "-m", "venv", str(venv)], tmp / f"full{i}_venv.log", env)
        w, r = run([str(venv / "bin/pip"), "install", f"{ROOT}[test]"], tmp / f"full{i}.log", env, cwd=tmp)
        walls.append(wall + w)
        row(f"run {i + 1}", wall + w, max(rss, r), l0)
    print(f"{'median':<44} {statistics.median(walls):>8.1f}")
    return venv / "bin/python"


def symbolic(python: Path) -> None:
    """Table 3: the extension's symbolic builds in ``python``'s environment (run from a neutral folder)."""
    print(f"\n## symbolic builds at first solve ({python})")
    print(f"{'model':<8} {'function':<24} {'s':>8}")
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    proc = subprocess.run([str(python), "-c", SYMBOLIC], capture_output=True, text=True, env=env,
                          cwd=tempfile.gettempdir())
    if proc.returncode:
        raise SystemExit(f"the symbolic builds failed:\n{proc.stderr}")
    for line in proc.stdout.splitlines():
        model, function, seconds = line.split("\t")
        print(f"{model:<8} {function:<24} {float(seconds):>8.3f}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=2, help="runs of the real command")
    parser.add_argument("--phases", action="store_true", help="also the install split in three phases")
    parser.add_argument("--skip-full", action="store_true", help="skip the real command")
    parser.add_argument("--symbolic-only", type=Path, default=None, metavar="PYTHON",
                        help="only table 3, in this Python's environment")
    args = parser.parse_args(argv)
    if args.symbolic_only:
        symbolic(args.symbolic_only)
        return 0
    print(f"{os.cpu_count()} cores, load {load()}")
    python = None
    with tempfile.TemporaryDirectory(prefix="fatigue_pin_install.") as tmp:
        if args.phases:
            python = phases(Path(tmp))
        if not args.skip_full:
            python = full(Path(tmp), args.repeats)
        if python is not None:
            symbolic(python)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
