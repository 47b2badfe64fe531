"""Reference table of arm26's muscle-tendon lengths and moment arms, computed by OpenSim 4.6.

The table is an independent check of our own muscle geometry (``tests/muscles``): it is made
with OpenSim itself, not with ``fatigue_pin``, and is not imported by the package or its tests'
runtime (the tests only read the CSV it writes).

What it computes. It loads ``arm26.osim`` (``Models/Arm26/arm26.osim`` of the GitHub repository
opensim-org/opensim-models; the file is third-party and is not kept in this repository) and, for
two wrapping configurations,

* ``wraps = "TRI"``: only the wrap cylinder ``TRI`` (on ``r_humerus``) active; ``TRIlonghh``,
  ``TRIlongglen`` and ``BIClonghh`` set inactive;
* ``wraps = "none"``: all four wrap objects inactive;

on the grid ``r_shoulder_elev`` = 0, 15, ..., 90 deg times ``r_elbow_flex`` = 0, 10, ..., 130 deg
(7 x 14 poses), it records for each of the six muscles (TRIlong, TRIlat, TRImed, BIClong,
BICshort, BRA) the muscle-tendon length ``muscle.getLength(state)`` and the moment arms
``muscle.computeMomentArm(state, coord)`` about both coordinates (OpenSim's sign: positive =
the muscle tends to increase the coordinate, i.e. flexion at the elbow). Every pose starts from
a fresh state (``model.initSystem()``), since OpenSim's wrap solutions depend on the state's
history. Every muscle's ``minimum_activation`` is raised to 0.01 where it is lower, as
OpenSim 4.6's ``initSystem`` rejects smaller values.

Output: a CSV with header
``wraps,shoulder_deg,elbow_deg,muscle,length_m,moment_arm_shoulder_m,moment_arm_elbow_m``
(numbers as ``repr(float)``, full precision), preceded by one ``#`` comment line naming the
OpenSim version, the source file and the opensim-models commit. It also prints, per muscle and
configuration, the range of the elbow moment arm.

Requirements: OpenSim's Python bindings in a separate environment, not the project's::

    python3 -m venv /tmp/osim_venv && /tmp/osim_venv/bin/pip install opensim==4.6 numpy

Usage (from the repository root)::

    /tmp/osim_venv/bin/python experiments/opensim_arm26_geometry.py \\
        --osim /path/to/arm26.osim --out tests/data/arm26_opensim_geometry.csv \\
        [--models-commit <opensim-models commit the file came from>]
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import opensim as osim

MUSCLES = ("TRIlong", "TRIlat", "TRImed", "BIClong", "BICshort", "BRA")
WRAP_OBJECTS = ("TRIlongglen", "TRIlonghh", "BIClonghh", "TRI")
CONFIGS = {"TRI": ("TRI",), "none": ()}
SHOULDER = "r_shoulder_elev"
ELBOW = "r_elbow_flex"
SHOULDER_DEG = tuple(range(0, 91, 15))
ELBOW_DEG = tuple(range(0, 131, 10))
HEADER = "wraps,shoulder_deg,elbow_deg,muscle,length_m,moment_arm_shoulder_m,moment_arm_elbow_m"
MIN_ACTIVATION = 0.01


def load_model(osim_path: Path, active_wraps: tuple[str, ...]) -> osim.Model:
    """The model with only ``active_wraps`` of the four wrap objects active."""
    model = osim.Model(str(osim_path))
    muscles = model.updMuscles()
    for i in range(muscles.getSize()):
        muscle = muscles.get(i)
        if not muscle.hasProperty("minimum_activation"):
            continue
        prop = muscle.updPropertyByName("minimum_activation")
        if osim.PropertyHelper.getValueDouble(prop) < MIN_ACTIVATION:
            osim.PropertyHelper.setValueDouble(MIN_ACTIVATION, prop)
    found = set()
    bodies = model.updBodySet()
    frames = [model.updGround()] + [bodies.get(i) for i in range(bodies.getSize())]
    for frame in frames:
        wraps = frame.upd_WrapObjectSet()
        for i in range(wraps.getSize()):
            wrap = wraps.get(i)
            name = wrap.getName()
            if name in WRAP_OBJECTS:
                wrap.set_active(name in active_wraps)
                found.add(name)
    missing = set(WRAP_OBJECTS) - found
    if missing:
        raise SystemExit(f"wrap objects not found in {osim_path}: {sorted(missing)}")
    model.finalizeFromProperties()
    model.initSystem()
    return model


def pose_rows(model: osim.Model, wraps: str, shoulder_deg: float, elbow_deg: float) -> list[tuple]:
    """One row per muscle at one pose, from a fresh state."""
    state = model.initSystem()
    coords = model.getCoordinateSet()
    shoulder, elbow = coords.get(SHOULDER), coords.get(ELBOW)
    shoulder.setValue(state, math.radians(shoulder_deg), False)
    elbow.setValue(state, math.radians(elbow_deg), False)
    model.realizePosition(state)
    for i in range(coords.getSize()):
        coords.get(i).setSpeedValue(state, 0.0)
    model.realizeVelocity(state)
    rows = []
    for name in MUSCLES:
        muscle = model.getMuscles().get(name)
        rows.append((
            wraps, shoulder_deg, elbow_deg, name,
            float(muscle.getLength(state)),
            float(muscle.computeMomentArm(state, shoulder)),
            float(muscle.computeMomentArm(state, elbow)),
        ))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--osim", type=Path, required=True, help="path to arm26.osim")
    parser.add_argument("--out", type=Path, required=True, help="CSV to write")
    parser.add_argument("--models-commit", default="unknown",
                        help="opensim-models commit the .osim file came from (for the header)")
    args = parser.parse_args()

    start = time.perf_counter()
    rows: list[tuple] = []
    for wraps, active in CONFIGS.items():
        model = load_model(args.osim, active)
        for s in SHOULDER_DEG:
            for e in ELBOW_DEG:
                rows.extend(pose_rows(model, wraps, s, e))
    elapsed = time.perf_counter() - start

    args.out.parent.mkdir(parents=True, exist_ok=True)
    comment = (f"# OpenSim {osim.GetVersionAndDate()}; source Models/Arm26/{args.osim.name} "
               f"of opensim-org/opensim-models at commit {args.models_commit}; "
               f"made by experiments/opensim_arm26_geometry.py")
    with args.out.open("w") as f:
        f.write(comment + "\n" + HEADER + "\n")
        for w, s, e, m, length, ma_s, ma_e in rows:
            f.write(f"{w},{s},{e},{m},{length!r},{ma_s!r},{ma_e!r}\n")

    bad = [r for r in rows if not all(math.isfinite(v) for v in r[4:])]
    print(f"{len(rows)} rows -> {args.out} in {elapsed:.2f} s ({len(bad)} with non-finite values)")
    print("elbow moment arm range [mm] over the grid:")
    print(f"{'muscle':10s}" + "".join(f"{w:>22s}" for w in CONFIGS))
    for name in MUSCLES:
        cells = []
        for wraps in CONFIGS:
            mas = [r[6] * 1e3 for r in rows if r[0] == wraps and r[3] == name]
            cells.append(f"{min(mas):9.2f} .. {max(mas):7.2f}")
        print(f"{name:10s}" + "".join(f"{c:>22s}" for c in cells))


if __name__ == "__main__":
    main()
