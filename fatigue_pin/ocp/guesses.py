"""Initial guesses of an OCP: the one place that makes them.

* ``rest``: every node at the initial state, zero torque (:func:`rest_guess`);
* ``physical``: the joints on a smooth motion through their targets
  (:meth:`Task.reference_trajectory`), the inverse-dynamics torques split into the actuator
  halves and the fatigue states integrated from those torques (:func:`physical_guess`);
* ``ik``: the same through the inverse-kinematics postures of the frame targets
  (:func:`ik_guess`; :func:`fatigue_pin.robot.ik.solve_ik` at every phase with a frame target,
  joints with a joint target at that phase held at its value);
* from another solution: stretched over another number of cycles (:func:`resample_guess`, the
  maximum-repetitions search), or shifted by the advance of a sliding window
  (:func:`shifted_window_guess`), or shifted exactly, a closed loop's plan
  (:func:`shifted_plan_guess`).

Shapes: states (N+1, nx), controls (N, nu).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin

from fatigue_pin.core.errors import ParameterError, TaskError
from fatigue_pin.ocp.task import FrameOrientation, FrameTarget, JointTarget, Task, phase_label, phase_value
from fatigue_pin.robot.ik import solve_ik
from fatigue_pin.core.text import shown

if TYPE_CHECKING:
    from fatigue_pin.ocp.transcription import Ocp

#: the named initial guesses (``guess`` of an Ocp, ``[horizon] guess`` of a study)
GUESSES = ("rest", "physical", "ik")

Guess = tuple[np.ndarray, np.ndarray]


def rollout_fatigue(ocp: Ocp, x_init: np.ndarray, q: np.ndarray, qdot: np.ndarray, u: np.ndarray,
                    fatigue: np.ndarray | None = None) -> np.ndarray:
    """States (N+1, nx) from given q, qdot and controls, with the fatigue states integrated
    forward from ``x_init``'s through the interval function, so that they are continuous
    (``fatigue``: the fatigue parameters (n_params,); default the actuators')."""
    N, L = u.shape[0], ocp.layout
    x = np.zeros((N + 1, L.nx))
    x[:, L.q], x[:, L.v] = q, qdot
    x[0, L.m] = x_init[L.m]
    if N == 0:
        return x
    p = ocp.actuators.param_vector() if fatigue is None else np.asarray(fatigue, dtype=float)
    rollout = ocp.functions.fatigue_rollout(N)
    x[1:, L.m] = np.asarray(rollout(x[0, L.m], np.asarray(u, dtype=float).T, np.tile(p.reshape(-1, 1), (1, N)))).T
    return x


def _inverse_dynamics_guess(ocp: Ocp, x_init: np.ndarray, q: np.ndarray, qdot: np.ndarray, qddot: np.ndarray) -> Guess:
    """The torques of a motion (RNEA) as the actuators' controls (``controls_for_torques``: the
    halves' torques clipped to their limits, or the muscles' activations), and the fatigue states
    integrated from them."""
    N = ocp.n_intervals
    tau = np.array([np.asarray(ocp.model.rnea(q[k], qdot[k], qddot[k])).reshape(-1) for k in range(N)])
    u = ocp.actuators.controls_for_torques(tau, q[:N], qdot[:N])
    return rollout_fatigue(ocp, x_init, q, qdot, u), u


def rest_guess(ocp: Ocp, x_init: np.ndarray | None = None) -> Guess:
    """Every node at the initial state, zero torque."""
    x_init = ocp.start_state(x_init)
    return np.tile(x_init, (ocp.n_intervals + 1, 1)), np.zeros((ocp.n_intervals, ocp.layout.nu))


def physical_guess(ocp: Ocp, x_init: np.ndarray | None = None) -> Guess:
    """The joints on :meth:`Task.reference_trajectory`, with their inverse-dynamics torques."""
    x_init = ocp.start_state(x_init)
    q, qdot, qddot = ocp.task.reference_trajectory(ocp.model, ocp.t, x_init[ocp.layout.q])
    return _inverse_dynamics_guess(ocp, x_init, q, qdot, qddot)


def ik_guess(ocp: Ocp, x_init: np.ndarray | None = None) -> Guess:
    """The joints through the inverse-kinematics postures of the frame targets (:func:`ik_reference`),
    with their inverse-dynamics torques. Without frame targets, the physical guess."""
    if not any(isinstance(i, (FrameTarget, FrameOrientation)) for i in ocp.task.items):
        return physical_guess(ocp, x_init)
    x_init = ocp.start_state(x_init)
    q, qdot, qddot = ik_reference(ocp.task, ocp.model, ocp.t, x_init[ocp.layout.q])
    return _inverse_dynamics_guess(ocp, x_init, q, qdot, qddot)


_NAMED = {"rest": rest_guess, "physical": physical_guess, "ik": ik_guess}


def initial_guess(ocp: Ocp, kind: str, x_init: np.ndarray | None = None) -> Guess:
    """The guess named ``kind`` (one of :data:`GUESSES`)."""
    if kind not in _NAMED:
        raise ParameterError(f"guess = {kind!r}: expected one of {list(GUESSES)}")
    return _NAMED[kind](ocp, x_init)


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
    phases = sorted({i.at for i in frame_items}, key=phase_value)
    out: dict[float, np.ndarray] = {}
    q = np.asarray(q_start, dtype=float)
    for at in phases:
        positions = [i for i in frame_items if isinstance(i, FrameTarget) and i.at == at]
        orientations = [i for i in frame_items if isinstance(i, FrameOrientation) and i.at == at]
        fixed = {t.joint: t.value for t in task.joint_targets if t.at == at and t.value is not None}
        res = solve_ik(model, positions, orientations, q0=q, fixed=fixed, q_ref=q_start)
        if not res.success:
            pm = model.pin_model
            data = pm.createData()
            pin.framesForwardKinematics(pm, data, res.q)
            worst = max(positions, key=lambda t: t.distance(data.oMf[pm.getFrameId(t.frame)].translation), default=None)
            what = (f"frame {worst.frame!r} at {shown(worst.position)} m" if worst is not None and res.position_error > 1e-6
                    else f"the orientation of {[o.frame for o in orientations]}")
            raise TaskError(
                f"task targets at phase {phase_label(at)}: inverse kinematics cannot place {what} (best: {max(res.position_error, 0):.4f} m "
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
    targeted = {(t.joint, t.at) for t in items if t.value is not None}
    for at, q in postures.items():
        for j, name in enumerate(model.joint_names):
            if (name, at) not in targeted:
                items.append(JointTarget(name, float(np.clip(q[j], model.q_lower[j], model.q_upper[j])), at))
    reference = Task(task.cycle_duration, task.intervals_per_cycle, tuple(items), None, task.final_node_offset, cyclic=task.cyclic)
    return reference.reference_trajectory(model, t, q0)


def resample_guess(ocp: Ocp, previous: Any) -> Guess:
    """Initial guess for ``ocp`` from a solution with another number of cycles, stretched in time.

    Cycle c of the new horizon (N_new cycles) copies cycle floor(c * N_prev / N_new) of the
    previous solution, states and controls alike, and the last node copies the last node. The
    fatigue trajectory is thus stretched over the new horizon (its gaps are not closed), so the
    guess keeps the previous solution's pacing: exhausted at the end, not half way. Measured on
    arm26 (authors-code, fatigue-torque, S = 10) with the default solver options: 32 cycles from
    the 16-cycle solution take 113 IPOPT iterations against 212 from the rest guess (16 from 8:
    104 against 101).

    Args:
        previous: anything with states ``x`` (nodes, nx) and controls ``u`` (intervals, nu) (an
            :class:`~fatigue_pin.ocp.transcription.OcpSolution`), or the tuple ``(x, u)``.
    """
    x_prev, u_prev = previous if isinstance(previous, tuple) else (previous.x, previous.u)
    n = ocp.task.intervals_per_cycle
    n_new = ocp.n_cycles
    n_prev = u_prev.shape[0] // n
    src_cycle = (np.arange(n_new) * n_prev) // n_new
    idx_u = (src_cycle[:, None] * n + np.arange(n)[None, :]).reshape(-1)
    idx_x = np.append(idx_u, u_prev.shape[0])
    return x_prev[idx_x].copy(), u_prev[idx_u].copy()


def shifted_window_guess(ocp: Ocp, x_init: np.ndarray, x_prev: np.ndarray, u_prev: np.ndarray, advance: int,
                         copy_fatigue: bool = False, intervals: int | None = None,
                         fatigue: np.ndarray | None = None) -> Guess:
    """Guess of a sliding window of K cycles from the previous window's states (K n + 1, nx) and
    controls (K n, nu): its cycle ``advance`` (the first cycle after the advance point; the last
    cycle when the window advances by K) copied into every cycle, the fatigue states integrated
    from ``x_init`` (or, with ``copy_fatigue``, copied too, as the authors' code does).

    ``intervals``: the window advances by this many intervals instead of ``advance`` cycles (a
    closed loop re-planning mid-cycle): the n intervals starting there (or whole cycles earlier,
    when fewer than n remain) are copied, so the guess has the new window's phase. A window of one
    cycle has no whole cycle earlier: the intervals past its end are taken one cycle earlier, from
    its start (the cycle's same phase).
    ``fatigue``: the fatigue parameters of the integration (default the actuators')."""
    n, K = ocp.task.intervals_per_cycle, ocp.n_cycles
    shift = advance * n if intervals is None else int(intervals)
    start = shift - n * max(0, -(-(shift - (K - 1) * n) // n))  # at most (K - 1) n, same phase
    if start >= 0:
        rows = np.arange(start, start + n)
    else:  # K = 1, re-planned mid-cycle: the intervals shift..n-1, then 0..shift-1
        rows = (np.arange(n) + shift) % n
    u = np.tile(u_prev[rows], (K, 1))
    xs = np.vstack([np.tile(x_prev[rows], (K, 1)), x_prev[rows[-1] + 1][None, :]])
    if copy_fatigue:
        return xs, u
    L = ocp.layout
    return rollout_fatigue(ocp, x_init, xs[:, L.q], xs[:, L.v], u, fatigue), u


def shifted_plan_guess(ocp: Ocp, x_init: np.ndarray, x_prev: np.ndarray, u_prev: np.ndarray, intervals: int,
                       fatigue: np.ndarray | None = None) -> Guess:
    """Guess of a window re-planned ``intervals`` intervals after the plan (x_prev (H+1, nx),
    u_prev (H, nu)) of a window of the same length H: that plan shifted, node j taking the plan's
    node j + ``intervals``. A window ends within its end box around its own start, whole cycles
    later, so the plan continues past its end as it began: the last ``intervals`` intervals
    take the plan's first ones (the same phases, whole cycles earlier). Node 0 is ``x_init``'s q and
    qdot; the fatigue states are integrated from ``x_init``'s with the shifted controls
    (``fatigue``: the parameters, default the actuators'). Unlike :func:`shifted_window_guess`,
    which repeats one cycle, every node keeps the plan's own timing: the start of the closed
    loop's real-time iterations (:class:`~fatigue_pin.drivers.mpc.MpcSettings`), which improve one
    plan over the re-plans."""
    H, r = u_prev.shape[0], int(intervals)
    if not 0 < r < H or x_prev.shape[0] != H + 1:
        raise ParameterError(f"shifted_plan_guess: a shift of {intervals!r} intervals of a plan of {H} intervals; "
                             f"expected 0 < shift < {H}")
    rows = np.r_[np.arange(r, H), np.arange(r)]
    xs = x_prev[np.r_[np.arange(r, H + 1), np.arange(1, r + 1)]].copy()
    L = ocp.layout
    xs[0, L.q], xs[0, L.v] = x_init[L.q], x_init[L.v]
    u = u_prev[rows].copy()
    return rollout_fatigue(ocp, x_init, xs[:, L.q], xs[:, L.v], u, fatigue), u
