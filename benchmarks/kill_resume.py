"""Kill long runs with SIGKILL at random moments, resume them, and check that nothing is lost.

    PYTHONPATH=. python benchmarks/kill_resume.py [--kills 20] [--seed 0]

For the small curl (10 intervals per cycle, 2 RK4 substeps, uncompiled), a sliding-horizon run
(``--windows``), a maximum-repetitions search (``--n-max``) and a closed loop (``--mpc-cycles``) are each started with
``resume=True`` in a child process and killed with SIGKILL, ``--kills`` times in all, then resumed
until they finish. Half the kills land at a random point of a write of the result file (the child
announces every step of a write: the byte copy, the HDF5 edit, the fsync, the rename, and pauses
briefly there), the others after a random delay (mostly during a solve). After every kill:

* the result file must open and its run / search table must read (else: an unreadable file);
* every window / N the child reported as written must be in it, and what it holds must be the
  beginning of the uninterrupted run's table (else: lost items);

and every resumed run must end equal to the uninterrupted one: the same windows (first cycles,
statuses) or the same N tried in the same order, and the same trajectories to 1e-9.

Prints the figures: kills (and how many during a write), resumes, unreadable files, lost items,
runs equal to the uninterrupted one. ``tests/test_kill_resume.py`` runs a short version.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import subprocess
import sys
import textwrap
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

CHILD = textwrap.dedent(
    """
    import os, sys, time
    import fatigue_pin.core.files as FS
    import fatigue_pin.io.results as R
    from fatigue_pin.paper.curl import curl_study
    from fatigue_pin.io.study import run_study

    def say(line):
        sys.stdout.write(line + "\\n")
        sys.stdout.flush()

    PAUSE = float(os.environ.get("KILL_PAUSE", "0.02"))
    LOCKSTEP = os.environ.get("KILL_LOCKSTEP") == "1"

    def announce(tag, prefix="IO "):  # a step: the parent may signal here
        say(prefix + tag)
        if LOCKSTEP:  # wait for the parent's go: a signal it sent first has arrived by then
            sys.stdin.readline()
        else:
            time.sleep(PAUSE)

    real_clone, real_compact, real_fsync, real_replace, real_group = R.clone, R._compact, FS.fsync, os.replace, R.write_run_group

    def clone(src, dst):
        announce("copy")
        real_clone(src, dst)

    def compact(src, dst):
        announce("compact")
        real_compact(src, dst)

    def group(g, run):
        announce("h5")
        real_group(g, run)
        announce("h5-written")

    def fsync(path, directory=False):
        if not directory:
            announce("fsync")
        real_fsync(path, directory)

    def replace(a, b):
        announce("rename")
        real_replace(a, b)

    R.clone, R._compact, R.write_run_group, FS.fsync, os.replace = clone, compact, group, fsync, replace

    import contextlib
    import fatigue_pin.ocp.solver as SOLVER
    real_watch = SOLVER.watch

    @contextlib.contextmanager
    def watch_solve():  # the solve has started (IPOPT's own watch is entered next)
        announce("solve", "AT ")
        with real_watch():
            yield

    SOLVER.watch = watch_solve

    def progress(line):  # a window's or re-plan's line: between two solves, after its write
        announce(line.split()[0], "AT ")

    def wrote(module, name, tag, counts=lambda *args: True):
        real = getattr(module, name)

        def call(*args, **kwargs):
            out = real(*args, **kwargs)
            if counts(*args):
                say("WROTE " + tag)
            return out

        setattr(module, name, call)

    kind, out, n = sys.argv[1], sys.argv[2], int(sys.argv[3])
    # every write of a driver goes through its store: a sliding run's windows, a closed loop's
    # re-plans, a search's table
    if kind == "max-cycles":
        wrote(R.ResultFile, "write_table", "search", lambda store, name, rows, attrs: not attrs.get("interrupted"))
    else:
        # a window's write; the run stored again as interrupted (SIGINT, SIGTERM) adds no window
        wrote(R.ResultFile, "write", "window", lambda store, run: not run.attrs.get("interrupted"))
    study = curl_study("sliding" if kind == "mpc" else kind, max_cycles=n, intervals_per_cycle=10, substeps=2,
                       solver={"compile": False})
    from fatigue_pin.core.signals import Interrupted, watch
    try:
        with watch():  # SIGINT, SIGTERM: Interrupted, exit code 130, 143 (as fatigue-pin does)
            say("START")
            if kind == "mpc":
                from fatigue_pin.drivers.mpc_run import run_closed_loop
                from fatigue_pin.io.mpc_study import MpcStudy
                loop = MpcStudy.from_toml(study.to_toml() + MPC_TABLES).closed_loop()
                run_closed_loop(loop, R.ResultFile(out), "run", resume=True, progress=progress)
            else:
                run_study(study, out, name="run", resume=True, progress=progress)
    except Interrupted as exc:
        say("INTERRUPTED")
        sys.exit(exc.exit_code)
    say("FINISHED")
    """
)

#: The closed loop of the harness: the small curl against a plant that tires faster, re-planned
#: every cycle (10 intervals), with noise-free measurements and MHE.
MPC_TABLES = """
[plant.fatigue]
F = 0.912

[mpc]
replan_every = 10
estimator = "mhe"
end = "receding"
"""
CHILD = CHILD.replace("MPC_TABLES", repr(MPC_TABLES))


@dataclass
class Figures:
    kind: str
    kills: int = 0
    kills_in_write: int = 0
    where: dict[str, int] = field(default_factory=dict)
    resumes: int = 0
    unreadable: int = 0
    lost: int = 0
    runs: int = 0
    equal: int = 0
    problems: list[str] = field(default_factory=list)


def _env() -> dict[str, str]:
    """Children import the fatigue_pin this process imported (installed, or the tree on PYTHONPATH)."""
    import fatigue_pin

    home = str(Path(fatigue_pin.__file__).resolve().parents[1])
    return {**os.environ, "PYTHONPATH": home + os.pathsep + os.environ.get("PYTHONPATH", ""), "OMP_NUM_THREADS": "1"}


#: Exit codes of a child stopped by each signal: SIGKILL kills it; SIGINT and SIGTERM it handles.
EXIT_CODES = {signal.SIGKILL: -signal.SIGKILL, signal.SIGINT: 130, signal.SIGTERM: 143}


def segment(kind: str, out: Path, n: int, kill: tuple | None) -> tuple[int, bool, str | None, float]:
    """Run the child once, in lockstep: at every step it announces it waits for the parent's go,
    so a signal sent at a step arrives there. ``kill``: None (to the end), ("io", k): SIGKILL at
    its k-th write step, ("at", step[, signal[, k]]): at the k-th (default first) announcement of
    a step: a write step (``copy``, ``compact``, ``h5``, ``h5-written``, ``fsync``, ``rename``),
    ``solve`` (a solve has started), or a progress line's first word (``window``, ``re-plan``,
    ``N``: between two solves, once the last one is stored), ("time", s): s seconds after it has
    started working, ("after-write", s): s seconds after its first write (during the next
    solve); a signal other than SIGKILL (SIGINT, SIGTERM) must make the child exit with 130, 143.
    Returns (items it reported written, killed, the last write step it announced before dying or
    None, seconds of work)."""
    sig = kill[2] if kill is not None and len(kill) > 2 else signal.SIGKILL
    nth = kill[3] if kill is not None and len(kill) > 3 else 1
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-c", CHILD, kind, str(out), str(n)], stdout=subprocess.PIPE,
                            stdin=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
                            env={**_env(), "KILL_LOCKSTEP": "1"}, cwd=out.parent)
    timer = None
    written, steps, last, finished, sent = 0, 0, None, False, False
    seen: dict[str, int] = {}
    assert proc.stdout is not None and proc.stdin is not None

    def send() -> None:
        nonlocal sent
        if proc.poll() is None and not sent:
            os.kill(proc.pid, sig)
            sent = True

    for line in proc.stdout:
        if line.startswith("START"):
            t0 = time.perf_counter()
            if kill is not None and kill[0] == "time":
                timer = threading.Timer(kill[1], send)
                timer.start()
        elif line.startswith("WROTE window") or line.startswith("WROTE search"):
            written += 1
            last = None
            if kill is not None and kill[0] == "after-write" and written == 1:  # during the next solve
                timer = threading.Timer(kill[1], send)
                timer.start()
        elif line.startswith("IO ") or line.startswith("AT "):
            tag = line.split()[1]
            seen[tag] = seen.get(tag, 0) + 1
            if line.startswith("IO "):
                steps += 1
                last = tag
            if kill is not None and ((kill[0] == "io" and steps == int(kill[1]) and line.startswith("IO "))
                                     or (kill[0] == "at" and tag == kill[1] and seen[tag] == nth)):
                send()
                if sig == signal.SIGKILL:
                    break
            try:  # go on (a signal sent above has arrived: the child was waiting for this line)
                proc.stdin.write("go\n")
                proc.stdin.flush()
            except OSError:
                pass
        elif line.startswith("FINISHED"):
            finished = True
    proc.wait()
    with contextlib.suppress(OSError):
        proc.stdin.close()
    if timer is not None:
        timer.cancel()
    killed = proc.returncode == EXIT_CODES[sig] and not finished
    if not killed and (proc.returncode != 0 or not finished):
        raise RuntimeError(f"the {kind} child failed with exit code {proc.returncode}")
    return written, killed, last if killed else None, time.perf_counter() - t0


def stored(kind: str, out: Path) -> list[tuple]:
    """The items a file holds: windows (index, first cycle, status, converged), a closed loop's
    re-plans (index, node, status, converged) or search rows
    (N, converged, status); every converged N's run is read too. Raises if anything is unreadable."""
    from fatigue_pin.drivers.search import step_run_name
    from fatigue_pin.io.results import list_runs, read_run, read_search

    if not out.exists():
        return []
    runs = list_runs(out)
    if kind == "sliding":
        if "run" not in runs:
            return []
        w = read_run(out, "run").windows
        return [(int(r["index"]), int(r["first_cycle"]), bytes(r["status"]), bool(r["converged"])) for r in w]
    if kind == "mpc":
        if "run" not in runs:
            return []
        w = read_run(out, "run").extras["replans"]
        return [(int(r["index"]), int(r["node"]), bytes(r["status"]), bool(r["converged"])) for r in w]
    table = read_search(out).get("run")
    if table is None:
        return []
    items = [(int(r["n_cycles"]), bool(r["converged"]), bytes(r["status"])) for r in table]
    for n, converged, _ in items:
        if converged:
            read_run(out, step_run_name("run", n))
    return items


def same_result(kind: str, a: Path, b: Path, atol: float = 1e-9) -> str | None:
    """None if the runs stored in ``a`` and ``b`` are equal (tables, trajectories to ``atol``),
    else what differs."""
    from fatigue_pin.drivers.search import step_run_name
    from fatigue_pin.io.results import list_runs, read_run

    if stored(kind, a) != stored(kind, b):
        return f"tables differ: {stored(kind, a)} != {stored(kind, b)}"
    names = ["run"] if kind in ("sliding", "mpc") else [step_run_name("run", n) for n, ok, _ in stored(kind, a) if ok] + ["run"]
    if sorted(list_runs(a)) != sorted(list_runs(b)):
        return f"runs differ: {list_runs(a)} != {list_runs(b)}"
    for name in names:
        ra, rb = read_run(a, name), read_run(b, name)
        for key in ("q", "qdot", "tau_plus", "tau_minus", "cycle_costs"):
            if getattr(ra, key).shape != getattr(rb, key).shape or not np.allclose(getattr(ra, key), getattr(rb, key), atol=atol, rtol=0):
                return f"{name}: {key} differs"
        for s in ra.fatigue:
            if not np.allclose(ra.fatigue[s], rb.fatigue[s], atol=atol, rtol=0, equal_nan=True):
                return f"{name}: {s} differs"
    return None


def reference(kind: str, n: int, folder: Path) -> tuple[Path, float]:
    """The uninterrupted run, and its duration (s)."""
    out = folder / f"{kind}_reference.h5"
    if out.exists():
        out.unlink()
    _, _, _, elapsed = segment(kind, out, n, None)
    return out, elapsed


def campaign(kind: str, n: int, kills: int, folder: Path, seed: int = 0, say=print,
             plan: list[tuple] | None = None, ref: tuple[Path, float] | None = None) -> Figures:
    """``kills`` SIGKILLs of ``kind`` runs (``sliding`` or ``max-cycles``), resumed until they end;
    as many runs from scratch as the kills need. Kills are drawn at random, half at a step of a
    write, half after a random time; ``plan`` gives them instead, in order. ``ref``: the
    uninterrupted run and its duration, if already made (:func:`reference`)."""
    rng = np.random.default_rng(seed)
    plan = list(plan or [])
    ref, duration = ref or reference(kind, n, folder)
    ref_items = stored(kind, ref)
    fig = Figures(kind)
    while fig.kills < kills:
        fig.runs += 1
        out = folder / f"{kind}_{fig.runs}.h5"
        if out.exists():
            out.unlink()
        have: list[tuple] = []
        while True:
            kill: tuple[str, float] | None = None
            if plan and fig.kills < kills:
                kill = plan[fig.kills]
            elif fig.kills < kills:
                kill = ("io", int(rng.integers(1, 12))) if rng.random() < 0.5 else ("time", float(rng.uniform(0.0, duration)))
            if have or fig.kills:
                fig.resumes += out.exists()
            written, killed, last, _ = segment(kind, out, n, kill)
            try:
                now = stored(kind, out)
            except Exception as exc:  # noqa: BLE001 - any failure to read counts
                fig.unreadable += 1
                fig.problems.append(f"run {fig.runs}: unreadable after a kill ({last}): {exc}")
                break
            if killed:
                fig.kills += 1
                fig.kills_in_write += last is not None
                key = last or "between writes"
                fig.where[key] = fig.where.get(key, 0) + 1
            expected = len(have) + written
            if len(now) < expected or now != ref_items[: len(now)]:
                fig.lost += max(expected - len(now), 0) or 1
                fig.problems.append(f"run {fig.runs}: held {len(have)} items + {written} written, now {len(now)}: {now}")
            have = now
            if not killed:
                break
        if fig.unreadable:
            break
        diff = same_result(kind, out, ref)
        if diff is None:
            fig.equal += 1
        else:
            fig.problems.append(f"run {fig.runs}: differs from the uninterrupted run: {diff}")
        say(f"{kind}: run {fig.runs} done; {fig.kills} kills so far")
    return fig


def report(figs: list[Figures]) -> str:
    lines = [f"{'':<12}{'kills':>6}{'in a write':>11}{'resumes':>9}{'unreadable':>11}{'lost':>6}{'runs':>6}{'equal':>7}"]
    for f in figs:
        lines.append(f"{f.kind:<12}{f.kills:>6}{f.kills_in_write:>11}{f.resumes:>9}{f.unreadable:>11}{f.lost:>6}{f.runs:>6}{f.equal:>7}")
    for f in figs:
        lines.append(f"{f.kind} kills by step: " + ", ".join(f"{k} {v}" for k, v in sorted(f.where.items())))
        lines += [f"  {p}" for p in f.problems]
    return "\n".join(lines)


def main() -> None:
    import tempfile

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kills", type=int, default=20, help="kills of each kind of run")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--windows", type=int, default=8, help="sliding: stop after this many cycles")
    parser.add_argument("--n-max", type=int, default=6, help="search: largest N")
    parser.add_argument("--mpc-cycles", type=int, default=4, help="closed loop: stop after this many cycles")
    parser.add_argument("--keep", type=Path, default=None, help="keep the files in this folder")
    args = parser.parse_args()
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.keep or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        figs = [campaign("sliding", args.windows, args.kills, folder, args.seed),
                campaign("max-cycles", args.n_max, args.kills, folder, args.seed + 1),
                campaign("mpc", args.mpc_cycles, args.kills, folder, args.seed + 2)]
    print(report(figs))
    print(f"{time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
