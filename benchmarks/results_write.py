"""Time to write one run, or one sliding-horizon window, into result files that already hold
0, 10 and 50 runs (medians of several writes).

    PYTHONPATH=. python benchmarks/results_write.py [--repeats 7] [--cycles 20]

Every run has the size of a paper run (50 intervals per cycle, ``--cycles`` cycles, two joints,
Xia's three states on four halves, the arm26 URDF text). "one run" adds a new run to the file;
"one window" replaces a sliding run by the same run with one more window (what a sliding
horizon does after every window). Each timed write starts from a fresh copy of the prepared
file, so every sample sees the same file.
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import tempfile
import time
from pathlib import Path

from fatigue_pin.robot.model import bundled_urdf
from fatigue_pin.drivers.synthetic import synthetic_run
from fatigue_pin.io.results import RunResult, write_run

N_PER_CYCLE = 50


def make_run(name: str, cycles: int, windows: int | None = None, seed: int = 0) -> RunResult:
    """A run of the paper's size (:func:`fatigue_pin.drivers.synthetic.synthetic_run`)."""
    return synthetic_run(name, cycles, N_PER_CYCLE, windows=windows, seed=seed, mf_end=0.5, urdf=bundled_urdf().read_text(),
                         attrs={"status": "Solve_Succeeded", "wall_time_s": 1.0})


def timed(base: Path, work: Path, run: RunResult, repeats: int) -> float:
    samples = []
    for _ in range(repeats):
        shutil.copyfile(base, work)
        t0 = time.perf_counter()
        write_run(work, run)
        samples.append(time.perf_counter() - t0)
    return statistics.median(samples)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--cycles", type=int, default=20, help="cycles of every stored run")
    args = parser.parse_args()
    print(f"runs of {args.cycles} cycles x {N_PER_CYCLE} intervals; median of {args.repeats} writes")
    print(f"{'runs in file':>12} {'file size':>11} {'one run (ms)':>13} {'one window (ms)':>16}")
    with tempfile.TemporaryDirectory() as tmp:
        tmp_path = Path(tmp)
        for held in (0, 10, 50):
            base = tmp_path / f"base{held}.h5"
            for i in range(held):
                write_run(base, make_run(f"full/run{i}", args.cycles, seed=i))
            write_run(base, make_run("sliding/run", args.cycles, windows=args.cycles - 2))
            size = base.stat().st_size
            work = tmp_path / "work.h5"
            one_run = timed(base, work, make_run("full/new", args.cycles, seed=999), args.repeats)
            one_window = timed(base, work, make_run("sliding/run", args.cycles + 1, windows=args.cycles - 1), args.repeats)
            print(f"{held:>12} {size / 1e6:>9.2f}MB {one_run * 1e3:>13.1f} {one_window * 1e3:>16.1f}")


if __name__ == "__main__":
    main()
