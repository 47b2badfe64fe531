"""The shipped cyclic studies give the same results before and after a change: run each one,
shortened where it is long, and print one JSON line per study (objective, IPOPT iterations,
repetitions, status), to compare two versions of the package line by line.

Usage (the same command under each version; e.g. an installed release and the source tree)::

    python experiments/cycles_untouched.py > before.jsonl
    PYTHONPATH=. python experiments/cycles_untouched.py > after.jsonl
    python experiments/cycles_untouched.py --compare before.jsonl after.jsonl

``STUDIES_DIR`` names the folder of study files (default: this checkout's ``studies/``), so that an
older checkout runs its own studies: ``STUDIES_DIR=old/studies PYTHONPATH=old python ...``.

Shortened: full horizons and searches as a full horizon of 2 cycles (``horizon.kind = "full"``),
the UR5 studies 1 cycle; the sliding studies run to exhaustion as shipped (the paper's counts).
Closed-loop studies (``seed``, ``[plant]``) are not run. Each run uses a fresh cache folder so the
two versions compile their own code.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
import time
import tomllib
from pathlib import Path

STUDIES = Path(os.environ.get("STUDIES_DIR", Path(__file__).resolve().parents[1] / "studies"))


def shortened(path: Path) -> dict[str, object] | None:
    """The ``--set`` changes that make a study short, or None for a study that is not run here."""
    data = tomllib.loads(path.read_text())
    if {"seed", "plant", "mpc"} & set(data) or path.name == "paper_reproduce.toml":
        return None
    kind = data.get("horizon", {}).get("kind", "full")
    if kind == "sliding":
        return {}
    return {"horizon.kind": "full", "horizon.cycles": 1 if data["model"]["urdf"] != "arm26" else 2}


def run_all() -> int:
    import fatigue_pin
    from fatigue_pin.io.study import Study, run_study

    for path in sorted(STUDIES.glob("*.toml")):
        changes = shortened(path)
        if changes is None:
            continue
        study = Study.from_file(path).replace(changes) if changes else Study.from_file(path)
        t0 = time.perf_counter()
        with tempfile.TemporaryDirectory() as cache:
            result = run_study(study, cache_dir=cache)
        print(json.dumps({"study": path.name, "changes": changes, "objective": result.objective, "iterations": result.iterations,
                          "repetitions": result.repetitions, "outcome": result.outcome.split(" (")[0],
                          "package": str(Path(fatigue_pin.__file__).parent), "wall_s": round(time.perf_counter() - t0, 1)}),
              flush=True)
    return 0


def compare(before: Path, after: Path) -> int:
    """A table of the two runs; exit 1 where an objective differs by more than 1e-6 relative, or
    the iterations or repetitions differ."""
    a = {r["study"]: r for r in map(json.loads, before.read_text().splitlines())}
    b = {r["study"]: r for r in map(json.loads, after.read_text().splitlines())}
    print(f"{'study':52s} {'objective before':>18s} {'after':>18s} {'iter':>11s} {'reps':>7s}")
    bad = 0
    for name in sorted(a.keys() | b.keys()):
        if name not in a or name not in b:
            print(f"{name:52s} missing in {'after' if name in a else 'before'}")
            bad += 1
            continue
        x, y = a[name], b[name]
        same = (math.isclose(x["objective"], y["objective"], rel_tol=1e-6) or (math.isnan(x["objective"]) and math.isnan(y["objective"]))) \
            and x["iterations"] == y["iterations"] and x["repetitions"] == y["repetitions"]
        bad += not same
        print(f"{name:52s} {x['objective']:18.10g} {y['objective']:18.10g} {x['iterations']:>5d}/{y['iterations']:<5d} "
              f"{x['repetitions']:>3d}/{y['repetitions']:<3d} {'same' if same else 'DIFFERS'}")
    return 1 if bad else 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--compare", nargs=2, type=Path, metavar=("BEFORE", "AFTER"))
    args = parser.parse_args(argv)
    return compare(*args.compare) if args.compare else run_all()


if __name__ == "__main__":
    sys.exit(main())
