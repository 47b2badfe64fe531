"""The UR5 carry study (studies/ur5_carry.toml): figures and numbers for docs/robot-study.md.

Usage: python experiments/robot_study.py RESULT.h5 [--run sliding/ur5_carry] [--out docs/figures]

Reads a run of the study and writes (PNG, small):

* ``robot_fatigue.png``: the fatigued fraction mf at the end of each cycle, every half that tires;
* ``robot_joints.png``: the joint angles over an early, a middle and the last cycle;
* ``robot_torque_share.png``: each joint's RMS torque per cycle, as a fraction of its limit;
* ``robot_tool_path.png``: the tool path (x-z and x-y) of those cycles, with the targets.

and prints per cycle: the largest mf (which half), each joint's RMS torque / limit, the distance of
the tool to its targets at their phases (numeric Pinocchio from the stored q), and the lowest
tool height.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from fatigue_pin.robot.kinematics import frame_placement  # noqa: E402
from fatigue_pin.robot.model import resolve_model  # noqa: E402
from fatigue_pin.io.results import read_run  # noqa: E402
from fatigue_pin.io.study import Study  # noqa: E402


def cycle_table(run, study: Study) -> list[dict]:
    model = resolve_model(study.data["model"]["urdf"])
    pm = model.pin_model
    n = study.data["task"]["intervals_per_cycle"]
    limits = model.tau_upper
    tau = run.tau_plus + run.tau_minus
    mf = run.fatigue["mf"]
    rows = []
    for c in range(run.n_cycles):
        s = slice(c * n, (c + 1) * n)
        rms = np.sqrt(np.mean(tau[s] ** 2, axis=0)) / limits
        end = mf[(c + 1) * n]
        errors = []
        for t in study.data["task"]["targets"]:
            k = c * n + int(round(t["at"] * n))
            errors.append(float(np.linalg.norm(frame_placement(pm, t["frame"], run.q[k]).translation - np.array(t["position"]))))
        heights = [frame_placement(pm, "tool0", q).translation[2] for q in run.q[c * n:(c + 1) * n + 1]]
        rows.append({"cycle": c + 1, "mf_max": float(end.max()), "mf_half": run.actuator_names[int(end.argmax())],
                     "rms_share": rms, "target_errors": errors, "min_height": float(min(heights))})
    return rows


def _save(fig, path: Path) -> None:
    """Lay the figure out, write it as PNG and free it."""
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("result", type=Path)
    parser.add_argument("--run", default=None)
    parser.add_argument("--out", type=Path, default=Path("docs/figures"))
    args = parser.parse_args()
    run = read_run(args.result, args.run)
    study = Study.from_toml(run.study)
    model = resolve_model(study.data["model"]["urdf"])
    n = study.data["task"]["intervals_per_cycle"]
    rows = cycle_table(run, study)
    joints = [j.replace("_joint", "") for j in run.joint_names]
    print(f"run {run.name}: {run.n_cycles} cycles, attrs repetitions={run.attrs.get('repetitions')}, converged={run.attrs.get('converged')}")
    print("cycle  max mf (half)                      RMS torque / limit: " + " ".join(f"{j[:9]:>9}" for j in joints)
          + "   target errors (mm)   min height (m)")
    for r in rows:
        print(f"{r['cycle']:>5}  {r['mf_max']:.3f} ({r['mf_half']:<26})" + " " * 20
              + " ".join(f"{x:>9.3f}" for x in r["rms_share"]) + "   "
              + ", ".join(f"{1e3 * e:.2f}" for e in r["target_errors"]) + f"   {r['min_height']:.3f}")
    args.out.mkdir(parents=True, exist_ok=True)
    cycles = np.arange(1, run.n_cycles + 1)
    mf_end = run.fatigue["mf"][n::n]

    fig, ax = plt.subplots(figsize=(6.4, 3.6))
    for h, name in enumerate(run.actuator_names):
        if mf_end[:, h].max() > 0.05:
            ax.plot(cycles, mf_end[:, h], marker=".", label=name.replace("_joint", ""))
    ax.set(xlabel="cycle", ylabel="mf at the end of the cycle", title="UR5 carrying 4 kg: fatigued fraction of the halves that tire")
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    _save(fig, args.out / "robot_fatigue.png")

    shown = sorted({0, run.n_cycles // 2, run.n_cycles - 1})
    tt = np.linspace(0, study.data["task"]["cycle_duration"], n + 1)
    fig, axes = plt.subplots(2, 3, figsize=(9, 4.8), sharex=True)
    for j, ax in enumerate(axes.ravel()):
        for c in shown:
            ax.plot(tt, run.q[c * n:(c + 1) * n + 1, j], label=f"cycle {c + 1}")
        ax.set_title(joints[j], fontsize=9)
        ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=7)
    for ax in axes[1]:
        ax.set_xlabel("t in the cycle (s)")
    axes[0, 0].set_ylabel("q (rad)")
    axes[1, 0].set_ylabel("q (rad)")
    _save(fig, args.out / "robot_joints.png")

    share = np.array([r["rms_share"] for r in rows])
    fig, ax = plt.subplots(figsize=(6.4, 3.6))
    for j, name in enumerate(joints):
        ax.plot(cycles, share[:, j], marker=".", label=name)
    ax.set(xlabel="cycle", ylabel="RMS torque / limit", title="Load carried by each joint, per cycle")
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    _save(fig, args.out / "robot_torque_share.png")

    fig, (a1, a2) = plt.subplots(1, 2, figsize=(9, 3.8))
    pm = model.pin_model
    for c in shown:
        p = np.array([frame_placement(pm, "tool0", q).translation for q in run.q[c * n:(c + 1) * n + 1]])
        a1.plot(p[:, 1], p[:, 2], label=f"cycle {c + 1}")
        a2.plot(p[:, 0], p[:, 1], label=f"cycle {c + 1}")
    for t in study.data["task"]["targets"]:
        a1.plot(t["position"][1], t["position"][2], "kx")
        a2.plot(t["position"][0], t["position"][1], "kx")
    for plane in study.data["task"].get("planes", []):
        a1.axhline(plane["offset"], color="0.5", lw=0.8, ls="--")
    a1.set(xlabel="y (m)", ylabel="z (m)", title="tool path, side view")
    a2.set(xlabel="x (m)", ylabel="y (m)", title="tool path, from above")
    for a in (a1, a2):
        a.set_aspect("equal", adjustable="datalim")
        a.grid(alpha=0.3)
    a1.legend(fontsize=7)
    _save(fig, args.out / "robot_tool_path.png")


if __name__ == "__main__":
    main()
