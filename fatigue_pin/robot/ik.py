"""Inverse kinematics: a configuration that puts frames at points (and, optionally, at
orientations).

:func:`solve_ik` works by damped least squares on Pinocchio's frame Jacobians
(``LOCAL_WORLD_ALIGNED``), with joint limits enforced by clipping and a pull towards a reference
posture in the Jacobian's null space; it restarts from the middle of the joint ranges and from
seeded random postures when it stalls. A target is anything with ``frame`` and ``position`` (m,
(3,)) and a ``distance(p)`` beyond its tolerance (and optionally ``rows``, the world axes it holds,
as indices), or ``frame``, ``matrix`` (3, 3) and
``tolerance`` (rad) for an orientation, such as the task items of :mod:`fatigue_pin.ocp.task`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np
import pinocchio as pin


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
    for fid, p, held in positions:
        rows.append((p - data.oMf[fid].translation)[held])
        jac.append(pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)[:3][held])
    for fid, R in orientations:
        rows.append(pin.log3(R @ data.oMf[fid].rotation.T))
        jac.append(pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)[3:])
    e = np.concatenate(rows) if rows else np.zeros(0)
    J = np.vstack(jac) if jac else np.zeros((0, model.nv))
    J[:, list(fixed)] = 0.0
    return e, J


def solve_ik(
    model,
    positions: Sequence[Any] = (),
    orientations: Sequence[Any] = (),
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
    pos = [(pm.getFrameId(t.frame), np.asarray(t.position), list(getattr(t, "rows", (0, 1, 2)))) for t in positions]  # the held axes
    ori = [(pm.getFrameId(t.frame), t.matrix) for t in orientations]
    q_ref = np.asarray(q_ref if q_ref is not None else (q0 if q0 is not None else mid), dtype=float)
    rng = np.random.default_rng(seed)
    starts = [np.asarray(q0, dtype=float) if q0 is not None else q_ref, mid]
    starts += [rng.uniform(lo_f, hi_f) for _ in range(max(0, restarts - 1))]

    def outside(q: np.ndarray) -> tuple[float, float]:
        pin.framesForwardKinematics(pm, data, q)
        pe = max((t.distance(data.oMf[fid].translation) for t, (fid, *_) in zip(positions, pos)), default=-np.inf)
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
