"""Where the load goes in a muscle run of the curl: read a run written by
``fatigue-pin run studies/curl_muscles_exhaustion.toml --out FILE`` (or any muscle curl) and print

- each unit's fatigued fraction mf at the start of every ``--every``-th cycle, and the cycle in
  which each muscle first reaches mf 0.5 and 0.9 (which muscle tires first);
- per cycle, the elbow flexion impulse (the time integral of the positive part of each source's
  elbow torque, N m s) of the biceps (both heads), the brachialis and the residual torque, with
  their shares, and the largest residual torque at each joint.

A muscle's elbow torque at the start of every interval is ``r_elbow(q) F`` with the run's stored
tendon force F (``extras["muscle_force"]``) and the moment arm ``r = -dL/dq`` of the run's own
paths (its polynomials, evaluated on numbers as verify does); each interval's torque is held over
the interval (its controls are).

Usage::

    python experiments/muscle_curl_exhaustion.py FILE.h5 [--every 2]
"""

from __future__ import annotations

import argparse

import numpy as np

from fatigue_pin.io.results import read_run
from fatigue_pin.muscles.files import read_muscles
from fatigue_pin.muscles.polynomial_paths import PolynomialPaths
from fatigue_pin.robot.model import load_model
from fatigue_pin.verify.muscle_torque import NumericMuscles


def elbow_moments(run) -> np.ndarray:
    """Each muscle's elbow torque (N m) at the start of every interval, (intervals, muscles)."""
    robot = load_model(text=run.urdf) if run.urdf else load_model()
    muscles = read_muscles(run.muscles, "the run's muscle file")
    paths = run.attrs.get("muscle_paths")
    numeric = NumericMuscles(robot.pin_model, muscles, PolynomialPaths.polynomials_from_json(str(paths)) if paths else None)
    elbow = run.joint_names.index("elbow")
    forces = np.asarray(run.extras["muscle_force"], dtype=float)
    out = np.zeros_like(forces)
    for k in range(forces.shape[0]):
        _, J = numeric.length_gradient(np.asarray(run.q[k], dtype=float))
        out[k] = -J[:, elbow] * forces[k]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("file")
    ap.add_argument("--run", default=None)
    ap.add_argument("--every", type=int, default=2)
    args = ap.parse_args()
    run = read_run(args.file, args.run)
    names = list(run.actuator_names)
    muscles = list(run.muscle_names)
    n = run.n_cycles
    print(f"# {args.file}: {n} cycles, repetitions {run.attrs.get('repetitions')}, stop: {run.attrs.get('stop_reason', '')}")
    print("# mf at the start of cycle k (k = 0: rest)")
    print("cycle " + " ".join(f"{u:>14s}" for u in names))
    starts = [run.cycle_slice(c).start for c in range(n)] + [run.cycle_slice(n - 1).stop - 1]
    for c in sorted(set(range(0, n + 1, args.every)) | {n}):
        print(f"{c:5d} " + " ".join(f"{run.fatigued[starts[c], h]:14.3f}" for h in range(len(names))))
    print("# the cycle in which each muscle's mf first reaches 0.5 and 0.9 (- : never)")
    for m in muscles:
        h = names.index(m)
        marks = []
        for level in (0.5, 0.9):
            hit = np.nonzero(run.fatigued[:, h] >= level)[0]
            marks.append("-" if hit.size == 0 else str(int(np.searchsorted(starts[1:], hit[0], side="left")) + 1))
        print(f"  {m:9s} 0.5 in cycle {marks[0]:>3s}   0.9 in cycle {marks[1]:>3s}")
    moments = elbow_moments(run)
    dt = np.diff(run.t)
    groups = {"biceps": [muscles.index(m) for m in muscles if m.startswith("BIC")],
              "brachialis": [muscles.index(m) for m in muscles if m == "BRA"]}
    elbow = run.joint_names.index("elbow")
    residual = np.asarray(run.tau_plus + run.tau_minus, dtype=float)
    print("# per cycle: elbow flexion impulse (N m s, positive parts) by source, shares, and the largest residual torque per joint (N m)")
    print("cycle   biceps  brachialis  residual   shares (bic/bra/res)   max |residual| " + " ".join(run.joint_names))
    for c in range(n):
        s = run.cycle_slice(c)
        k = slice(s.start, s.stop - 1)
        flex = {g: float(np.sum(np.clip(moments[k][:, idx].sum(axis=1), 0, None) * dt[k])) for g, idx in groups.items()}
        flex["residual"] = float(np.sum(np.clip(residual[k, elbow], 0, None) * dt[k]))
        total = sum(flex.values()) or 1.0
        shares = "/".join(f"{flex[g] / total:.2f}" for g in ("biceps", "brachialis", "residual"))
        peaks = " ".join(f"{np.max(np.abs(residual[k, j])):6.2f}" for j in range(len(run.joint_names)))
        print(f"{c + 1:5d} {flex['biceps']:8.3f} {flex['brachialis']:11.3f} {flex['residual']:9.3f}   {shares:>20s}   {peaks}")


if __name__ == "__main__":
    main()
