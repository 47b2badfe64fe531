"""Anticipation against reaction on the UR5 lift with motors (issue 35; docs/motors.md,
"Anticipation against reaction"): figures of the three runs.

The runs (each passes ``fatigue-pin verify``), the windings held below 50 deg C::

    fatigue-pin run studies/ur5_motors_lift.toml --out plain.h5 --set motors.T_max=60.0 --set horizon.max_cycles=21
    fatigue-pin run studies/ur5_motors_lift.toml --out budget.h5 --set motors.T_max=60.0 --set horizon.max_cycles=21 \\
        --set horizon.heat_budget=true
    fatigue-pin run studies/ur5_motors_lift.toml --out full.h5 --set motors.T_max=60.0 --set horizon.kind=full \\
        --set horizon.cycles=21

Then::

    python experiments/motors_anticipation.py plain.h5 budget.h5 full.h5 --out docs/figures/motors

writes ``anticipation.png`` (each horizon's shoulder-lift and wrist-1 windings against their
limit, and each joint's RMS torque per cycle) and each run's own figure
(:func:`fatigue_pin.viz.plots.plot_motors`) in ``plain/``, ``budget/`` and ``full/``, and prints a table of the lifts and the hottest
windings.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib
import numpy as np

from fatigue_pin.io.results import list_runs, read_run
from fatigue_pin.viz.plots import _figure, _save, cycle_rms_torques, motor_limits, plot_motors

LABELS = ("sliding windows", "sliding within the heat budget", "full horizon")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("files", nargs=3, type=Path, help="the plain, heat-budget and full-horizon result files")
    parser.add_argument("--out", type=Path, default=Path("docs/figures/motors"))
    args = parser.parse_args()
    runs = []
    for path in args.files:
        names = [n for n in list_runs(path) if not n.endswith(("failed_window", "in_progress"))]
        runs.append(read_run(path, names[0]))
    fig = _figure(figsize=(12, 8))
    ax_T, ax_tau = fig.subplots(2, 1)
    colors = matplotlib.colormaps["tab10"]
    styles = ("-", "--", ":")
    print(f"{'horizon':32s} lifts  hottest winding (deg C) per joint")
    for k, (label, run) in enumerate(zip(LABELS, runs)):
        T_w, limits, joints = run.extras["winding_C"], motor_limits(run), run.actuator_names
        print(f"{label:32s} {run.n_cycles:5d}  " + ", ".join(f"{j} {T_w[:, i].max():.1f}" for i, j in enumerate(joints)))
        for i, joint in enumerate(joints):
            if joint in ("shoulder_lift_joint", "wrist_1_joint"):
                ax_T.plot(run.t[:-1], T_w[:, i], ls=styles[k], color=colors(i), lw=1.3, label=f"{label}: {joint}")
        rms = cycle_rms_torques(run)
        for i, joint in enumerate(joints):
            ax_tau.plot(np.arange(1, run.n_cycles + 1), rms[:, i], ls=styles[k], marker="o", ms=2, color=colors(i),
                        label=joint if k == 0 else None)
        plot_motors(run, args.out / ("plain", "budget", "full")[k])
    ax_T.axhline(limits.max(), color="k", lw=0.8, label=f"limit {limits.max():.0f} C")
    ax_T.set_ylabel("winding (deg C)")
    ax_T.set_xlabel("time (s)")
    ax_tau.set_ylabel("RMS torque in the cycle (N m)")
    ax_tau.set_xlabel(f"cycle ({', '.join(f'{s} {label}' for s, label in zip(('solid', 'dashed', 'dotted'), LABELS))})")
    for ax in (ax_T, ax_tau):
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, ncol=3)
    fig.suptitle("UR5 lift, windings held below 50 deg C: reaction against anticipation", fontsize=10)
    fig.tight_layout()
    print("wrote", *_save(fig, args.out, "anticipation"))


if __name__ == "__main__":
    main()
