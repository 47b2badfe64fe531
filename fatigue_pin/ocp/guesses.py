"""Inverse kinematics of a task's frame targets, and the initial guess built from it.

:func:`solve_ik` finds a configuration that puts frames at points (and, optionally, orientations)
by damped least squares on Pinocchio's frame Jacobians (``LOCAL_WORLD_ALIGNED``), with joint
limits enforced by clipping and a pull towards a reference posture in the Jacobian's null space;
it restarts from the middle of the joint ranges and from seeded random postures when it stalls.

:func:`ik_guess` (``guess = "ik"`` of :class:`~fatigue_pin.ocp.transcription.Ocp`, ``[horizon] guess =
"ik"`` in a study) solves it at every phase of the cycle that has a frame target, holds the
joints with a joint target at that phase at their value, then moves every joint on the same
half-cosine path between those postures as :meth:`Task.reference_trajectory`, with the
inverse-dynamics torques (RNEA: gravity compensation plus the inertial part) split into the
actuator halves and the fatigue states integrated from them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np
import pinocchio as pin

from fatigue_pin.core.errors import TaskError
from fatigue_pin.ocp.task import FrameOrientation, FrameTarget, JointTarget, Task


@dataclass(frozen=True)
class IkResult:
    """A configuration q (nq,), the largest distance (m) of a frame target outside its tolerance
    (<= 0: every target met), the largest orientation error beyond its tolerance (rad), and the
    iterations taken."""

    q: np.ndarray
    position_error: float
    orientation_error: float
    iterations: int

    @property
    def success(self) -> bool:
        return self.position_error <= 1e-6 and self.orientation_error <= 1e-6


def _errors(model: pin.Model, data: pin.Data, q: np.ndarray, positions, orientations, fixed: Sequence[int]):
    """Stacked error vector and Jacobian (world-aligned) of the targets at q; free columns only."""
    pin.computeJointJacobians(model, data, q)
    pin.framesForwardKinematics(model, data, q)
    rows, jac = [], []
    for fid, p in positions:
        rows.append(p - data.oMf[fid].translation)
        jac.append(pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)[:3])
    for fid, R in orientations:
        rows.append(pin.log3(R @ data.oMf[fid].rotation.T))
        jac.append(pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)[3:])
    e = np.concatenate(rows) if rows else np.zeros(0)
    J = np.vstack(jac) if jac else np.zeros((0, model.nv))
    J[:, list(fixed)] = 0.0
    return e, J


def solve_ik(
    model,
    positions: Sequence[FrameTarget] = (),
    orientations: Sequence[FrameOrientation] = (),
    q0: np.ndarray | None = None,
    fixed: Mapping[str, float] | None = None,
    q_ref: np.ndarray | None = None,
    max_iter: int = 300,
    damping: float = 1e-4,
    restarts: int = 8,
    seed: int = 0,
) -> IkResult:
    """Configuration of ``model`` (a :class:`~fatigue_pin.robot.model.RobotModel`) meeting frame targets.

    Args:
        positions: frame position targets (each within its tolerance counts as met; the
            iteration aims at the target point itself).
        orientations: frame orientation targets.
        q0: start (default: ``q_ref``, else the middle of the joint ranges).
        fixed: joints held at given values (rad or m), by name.
        q_ref: posture pulled towards in the null space of the targets (default ``q0``).
        max_iter: iterations per start; restarts: further starts (middle of the ranges, then
            seeded random postures) when a start ends outside a tolerance.

    Returns:
        The best :class:`IkResult` over the starts (check ``success``).
    """
    pm = model.pin_model
    data = pm.createData()
    lo, hi = np.asarray(model.q_lower, dtype=float), np.asarray(model.q_upper, dtype=float)
    lo_f, hi_f = np.where(np.isfinite(lo), lo, -np.pi), np.where(np.isfinite(hi), hi, np.pi)
    mid = 0.5 * (lo_f + hi_f)
    fixed_idx = {model.joint_index(j): float(v) for j, v in (fixed or {}).items()}
    pos = [(pm.getFrameId(t.frame), np.asarray(t.position)) for t in positions]
    ori = [(pm.getFrameId(t.frame), t.matrix) for t in orientations]
    q_ref = np.asarray(q_ref if q_ref is not None else (q0 if q0 is not None else mid), dtype=float)
    rng = np.random.default_rng(seed)
    starts = [np.asarray(q0, dtype=float) if q0 is not None else q_ref, mid]
    starts += [rng.uniform(lo_f, hi_f) for _ in range(max(0, restarts - 1))]

    def outside(q: np.ndarray) -> tuple[float, float]:
        pin.framesForwardKinematics(pm, data, q)
        pe = max((t.distance(data.oMf[fid].translation) for t, (fid, _) in zip(positions, pos)), default=-np.inf)
        oe = max((float(np.linalg.norm(pin.log3(R @ data.oMf[fid].rotation.T))) - t.tolerance
                  for t, (fid, R) in zip(orientations, ori)), default=-np.inf)
        return pe, oe

    best: IkResult | None = None
    for start in starts:
        q = np.clip(start.copy(), lo_f, hi_f)
        for j, v in fixed_idx.items():
            q[j] = v
        it = 0
        for it in range(1, max_iter + 1):
            e, J = _errors(pm, data, q, pos, ori, fixed_idx)
            if e.size == 0 or np.linalg.norm(e) < 1e-9:
                break
            JJt = J @ J.T + damping * np.eye(J.shape[0])
            Jp = J.T @ np.linalg.solve(JJt, np.eye(J.shape[0]))
            # the posture pull only while far from the targets: the damped projector leaks it
            # into the task space, which would stall the last millimetres
            pull = 0.1 if np.linalg.norm(e) > 1e-3 else 0.0
            dq = Jp @ e + (np.eye(pm.nv) - Jp @ J) @ (pull * (q_ref - q))
            dq[list(fixed_idx)] = 0.0
            step = np.linalg.norm(dq)
            if step > 0.5:  # rad: keep the linearisation valid
                dq *= 0.5 / step
            q = np.clip(pin.integrate(pm, q, dq), lo_f, hi_f)
        pe, oe = outside(q)
        result = IkResult(q, pe, oe, it)
        if best is None or max(pe, oe) < max(best.position_error, best.orientation_error):
            best = result
        if best.success:
            break
    assert best is not None
    return best


def phase_postures(task: Task, model, q_start: np.ndarray) -> dict[float, np.ndarray]:
    """Inverse kinematics at every phase of ``task`` with a frame target: phase -> q (nq,).

    Phases are solved in order, each starting from the previous posture (the first from
    ``q_start``) and pulled towards ``q_start``; joints with a joint target at that phase are held
    at its value.

    Raises:
        TaskError: a phase whose targets no start reaches (out of reach, or blocked by the joint
            limits or by other targets), naming the frame, the point and the distance left.
    """
    frame_items = [i for i in task.items if isinstance(i, (FrameTarget, FrameOrientation))]
    phases = sorted({i.at for i in frame_items})
    out: dict[float, np.ndarray] = {}
    q = np.asarray(q_start, dtype=float)
    for at in phases:
        positions = [i for i in frame_items if isinstance(i, FrameTarget) and i.at == at]
        orientations = [i for i in frame_items if isinstance(i, FrameOrientation) and i.at == at]
        fixed = {t.joint: t.value for t in task.joint_targets if t.at == at}
        res = solve_ik(model, positions, orientations, q0=q, fixed=fixed, q_ref=q_start)
        if not res.success:
            pm = model.pin_model
            data = pm.createData()
            pin.framesForwardKinematics(pm, data, res.q)
            worst = max(positions, key=lambda t: t.distance(data.oMf[pm.getFrameId(t.frame)].translation), default=None)
            what = (f"frame {worst.frame!r} at {list(worst.position)} m" if worst is not None and res.position_error > 1e-6
                    else f"the orientation of {[o.frame for o in orientations]}")
            raise TaskError(
                f"task targets at phase {at:g}: inverse kinematics cannot place {what} (best: {max(res.position_error, 0):.4f} m "
                f"outside the tolerance, {max(res.orientation_error, 0):.4f} rad); the point is out of reach or the joint "
                "limits / other targets block it"
            )
        out[at] = res.q
        q = res.q
    return out


def ik_reference(task: Task, model, t: np.ndarray, q0: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A smooth motion through the inverse-kinematics postures of the frame targets (and the joint
    targets): q (len(t), nq), qdot, qddot, as :meth:`Task.reference_trajectory`."""
    postures = phase_postures(task, model, q0)
    items = list(task.joint_targets)
    targeted = {(t.joint, t.at) for t in items}
    for at, q in postures.items():
        for j, name in enumerate(model.joint_names):
            if (name, at) not in targeted:
                items.append(JointTarget(name, float(np.clip(q[j], model.q_lower[j], model.q_upper[j])), at))
    reference = Task(task.cycle_duration, task.intervals_per_cycle, tuple(items), None, task.final_node_offset)
    return reference.reference_trajectory(model, t, q0)


def ik_guess(ocp, x_init: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Initial guess of an :class:`~fatigue_pin.ocp.transcription.Ocp` from the inverse kinematics of
    its task's frame targets (the module docstring). Without frame targets, the physical guess.
    Shapes (N+1, nx), (N, nu)."""
    task = ocp.task
    if not any(isinstance(i, (FrameTarget, FrameOrientation)) for i in task.items):
        return ocp.physical_guess(x_init)
    x_init = ocp._x_init(x_init)
    L, N = ocp.layout, ocp.n_intervals
    q, qdot, qddot = ik_reference(task, ocp.model, ocp.t, x_init[L.q])
    tau = np.array([np.asarray(ocp.model.rnea(q[k], qdot[k], qddot[k])).reshape(-1) for k in range(N)])
    tau = np.clip(tau, ocp.actuators.tau_minus_limits, ocp.actuators.tau_plus_limits)
    u = np.hstack([np.maximum(tau, 0.0), np.minimum(tau, 0.0)])
    return ocp.rollout_fatigue(x_init, q, qdot, u), u
