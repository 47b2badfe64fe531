"""The paper's curl driven by arm26's six muscles with residual torques: the first cycles, full horizon.

Usage::

    python experiments/muscle_curl_first_cycles.py [--cycles 1 2] [--intervals 10]

The paper's curl study (``studies/curl_full_fatigue-torque_paper.toml``, its costs and task) with
its actuators replaced by :class:`~fatigue_pin.ocp.muscle_actuators.MuscleActuators`: the bundled
arm26 muscles (``urdf/arm26.muscles.toml``, rigid tendons, De Groote-Fregly curves), each with the
study's Xia model, and residual torque halves of +-50 N m at both joints with the same model. The
torque cost sums the squares of the activations and of the residual torques (N m): the residuals
cost about 2,500 times as much per unit of torque as the muscles. Uncompiled (no muscle study key
yet, so no compiled library). Prints, per number of cycles: success, wall time, objective, IPOPT
iterations, each muscle's largest activation, the residuals' largest torques and every unit's
fatigued fraction at the end.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from fatigue_pin.io.study import Study
from fatigue_pin.muscles.files import load_muscles
from fatigue_pin.muscles.geometry import MuscleGeometry
from fatigue_pin.ocp.actuators import SignedTorqueActuators
from fatigue_pin.ocp.muscle_actuators import MuscleActuators
from fatigue_pin.ocp.problem import Problem
from fatigue_pin.ocp.solver import SolverOptions
from fatigue_pin.ocp.transcription import Ocp, Transcription

STUDY = Path(__file__).resolve().parents[1] / "studies" / "curl_full_fatigue-torque_paper.toml"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cycles", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--intervals", type=int, default=10, help="intervals per cycle")
    args = parser.parse_args()
    study = Study.from_file(STUDY).replace({"task.intervals_per_cycle": args.intervals, "transcription.substeps": 2})
    base = study.problem()
    model = base.model
    xia = base.actuators.halves[0].params
    muscles = load_muscles("arm26")
    actuators = MuscleActuators(model.joint_names, muscles, MuscleGeometry(model.pin_model, muscles), xia,
                                residuals=SignedTorqueActuators.from_model(model, xia))
    problem = Problem(model, actuators, base.task, base.costs, None)
    nm = actuators.n_muscles
    for n in args.cycles:
        t0 = time.perf_counter()
        sol = Ocp(problem, n, Transcription(substeps=2), SolverOptions(compile=False)).solve()
        wall = time.perf_counter() - t0
        mf = sol.x[-1, problem.layout.fatigued_rows()]
        print(f"{n} cycle(s), {args.intervals} intervals each: success {sol.success}, {wall:.1f} s, objective {sol.objective:.6g}, "
              f"{sol.iterations} iterations")
        print("  largest activation  " + "  ".join(f"{m} {a:.3f}" for m, a in zip(muscles.names, sol.u[:, :nm].max(0))))
        print("  largest residual    " + "  ".join(f"{h} {t:.2f} N m" for h, t in zip(actuators.half_names[nm:], np.abs(sol.u[:, nm:]).max(0))))
        print("  mf at the end       " + "  ".join(f"{h} {f:.4f}" for h, f in zip(actuators.half_names, mf)))


if __name__ == "__main__":
    main()
