"""Node-wise checks of ``fatigue-pin verify`` that need no integration: the stored numbers are
finite, the coupling ``0 <= TL + m_fatigued <= 1``, the bounds (q, qdot, torques, fatigue states),
the invariant ``|1 - sum of each half's states|``, and the numpy fatigue right-hand sides against
the models' own ``rates`` (docs/verify.md gives the equations)."""

from __future__ import annotations

import math

import numpy as np

from fatigue_pin.drivers.run import unit_joint
from fatigue_pin.verify.fatigue_rhs import numpy_rhs
from fatigue_pin.verify.report import VerifyCheck, VerifyTolerances, worst
from fatigue_pin.verify.stored import Stored

__all__ = ["finite_check", "coupling_check", "bound_checks", "invariant_checks", "rhs_check", "DEFAULT_VELOCITY_LIMIT"]

#: Velocity bound where the URDF gives none (as :func:`fatigue_pin.robot.model.load_model`).
DEFAULT_VELOCITY_LIMIT = 10 * math.pi


def finite_check(s: Stored) -> VerifyCheck:
    """How many stored numbers (q, qdot, torques, each half's fatigue states and fatigued
    fraction) are NaN or infinite; any fails (tolerance 0), with the first one named."""
    joints = s.joints
    parts = [
        ("node", s.Y, [f"q {j}" for j in joints] + [f"qdot {j}" for j in joints]),
        ("node", s.M, s.state_labels),
        ("node", np.asarray(s.run.fatigued, dtype=float), [f"fatigued {h.name}" for h in s.halves]),
        ("interval", s.run.half_torques(), [_control_label(s, name) for name in s.run.actuator_names]),
    ]
    count, where = 0, ""
    for what, values, labels in parts:
        bad = ~np.isfinite(np.asarray(values, dtype=float))
        if bad.any() and not where:
            k, j = np.argwhere(bad)[0]
            where = f"{what} {k}, {labels[j] if j < len(labels) else ''}".rstrip(", ")
        count += int(bad.sum())
    return VerifyCheck("finite stored values", float(count), "count", 0.0, where or "every node and interval")


def coupling_check(s: Stored, tol: VerifyTolerances) -> tuple[VerifyCheck, float]:
    """``TL + m_fatigued`` in [0, 1] at every node, with ``u_N := u_{N-1}`` and m_fatigued the
    stored fatigued fraction of every half (:attr:`RunResult.fatigued`); derated motors (the
    coupling ``derated``): ``TL^2 + x_w`` in [0, 1], each torque within ``limit sqrt(1 - x_w)``.

    A closed-loop run's plant delivers, at the start of every interval, at most its capacity
    ``1 - mf`` and holds that torque while mf rises, so ``u_{N-1}`` with ``mf_N`` may exceed 1 (the
    open-loop estimator's tired plant: 0.026): there ``u_N`` is the torque the plant delivered next
    (``extras["tail_u"]``), and node N is left out when the plant did nothing after it."""
    TL_nodes = np.vstack([s.TL, s.TL[-1:]])
    mf = np.asarray(s.run.fatigued, dtype=float)
    if s.horizon == "mpc":
        tail = np.asarray(s.run.extras.get("tail_u", np.zeros((0, 0))), dtype=float)
        na = len(s.halves) // 2
        if tail.ndim == 2 and tail.shape[0] > 0 and tail.shape[1] == 2 * na:
            # controls (tau_plus of the actuated joints, then tau_minus) in half order
            halves = np.ravel(np.column_stack([tail[0, :na], tail[0, na:]]))
            TL_nodes[-1] = halves / s.limits
        else:
            TL_nodes, mf = TL_nodes[:-1], mf[:-1]
    coupling = str(s.run.attrs.get("coupling", "tl+mf<=1"))
    derated = coupling == "derated"  # motors: |tau| <= limit sqrt(1 - x_w)
    c = (TL_nodes * TL_nodes if derated else TL_nodes) + mf
    value, where = worst(np.maximum(-c, c - 1.0), [h.name for h in s.halves], "node")
    if derated:
        return VerifyCheck("derated torque TL^2 + x_w in [0, 1]", value, "1", tol.coupling, where), value
    if coupling != "tl+mf<=1":  # not a constraint of the run: reported only
        return VerifyCheck(f"coupling TL + m_f ({coupling})", value, "1", None, where), 0.0
    return VerifyCheck("coupling TL + m_fatigued in [0, 1]", value, "1", tol.coupling, where), value


def _control_label(s: Stored, unit: str) -> str:
    """``tau_plus elbow`` for a half, ``activation BRA`` for a muscle, ``tau elbow`` for a motor."""
    if unit in s.run.muscle_names:
        return f"activation {unit}"
    joint, side = unit_joint(unit, s.run.joint_names)
    return f"tau_{side} {joint}" if side else f"tau {joint}"


def bound_checks(s: Stored, tol: VerifyTolerances) -> tuple[list[VerifyCheck], float]:
    """q within the URDF limits, |qdot| within the velocity limits, each torque half within
    [0, limit] (plus) or [limit, 0] (minus), each muscle's activation in [0, 1] (its limit is 1),
    fatigue states in [0, 1] (a motor's signed torque within [-limit, limit], its normalised
    temperatures in [0, 1]: T_w <= T_max - margin)."""
    run, model, joints = s.run, s.robot.pin_model, s.joints
    q_lo, q_hi = np.array(model.lowerPositionLimit, dtype=float), np.array(model.upperPositionLimit, dtype=float)
    v_max = np.array(model.velocityLimit, dtype=float)
    v_max = np.where(np.isfinite(v_max) & (v_max > 0), v_max, DEFAULT_VELOCITY_LIMIT)
    with np.errstate(invalid="ignore"):
        b_q, at_bq = worst(np.maximum(q_lo - run.q, run.q - q_hi), joints, "node")
        b_v, at_bv = worst(np.abs(run.qdot) - v_max, joints, "node")
        sign, tau = np.sign(s.limits), run.half_torques()  # plus halves in [0, limit], minus halves in [limit, 0]
        beyond = np.abs(tau) - s.limits if run.actuation == "motors" else np.maximum(-sign * tau, sign * tau - np.abs(s.limits))
        b_t, at_bt = worst(beyond, [h.name for h in s.halves], "interval")  # a motor's signed torque in [-limit, limit]
        b_m, at_bm = worst(np.maximum(-s.M, s.M - 1.0), s.state_labels, "node")
    checks = [
        VerifyCheck("bound q", b_q, s.units("position"), tol.bound, at_bq),
        VerifyCheck("bound qdot", b_v, s.units("velocity"), tol.bound, at_bv),
        VerifyCheck("bound torques", b_t, s.units("effort"), tol.bound, at_bt),
        VerifyCheck("bound fatigue states in [0, 1]", b_m, "1", tol.bound, at_bm),
    ]
    return checks, max(b_q, b_v, b_t, b_m)


def invariant_checks(s: Stored) -> tuple[list[VerifyCheck], float, float, str]:
    """``|1 - sum of each half's states|`` at every node and at the last (reported only).

    Returns:
        the two lines, the worst value, the value at the last node and the sums per model kind.
    """
    inv = s.invariant(s.M)
    invariant, at_inv = worst(inv, [h.name for h in s.halves], "node")
    last = inv[-1][np.isfinite(inv[-1])]
    inv_final = float(last.max()) if last.size else 0.0
    kinds = {h.kind: " + ".join(h.model.total_states()) if h.model.state_total is not None else "none" for h in s.halves}
    invariant_sum = "; ".join(f"{k}: {v}" for k, v in kinds.items())
    name_sum = next(iter(kinds.values())) if len(kinds) == 1 else "sum of each half's states"
    checks = [
        VerifyCheck(f"invariant |1 - ({name_sum})|" if name_sum != "none" else "invariant (none: the states have no sum)",
                    invariant, "1", None, at_inv),
        VerifyCheck("invariant at the last node", inv_final, "1", None, f"node {s.N}"),
    ]
    return checks, invariant, inv_final, invariant_sum


def rhs_check(s: Stored, notes: list[str]) -> tuple[VerifyCheck, float]:
    """The numpy fatigue right-hand sides against the models' ``rates`` on every stored node
    (finite nodes only), with the node's target load (``u_N := u_{N-1}``)."""
    TL_nodes = np.vstack([s.TL, s.TL[-1:]])
    off = s.offsets
    err = float("nan")
    if any(numpy_rhs(h.kind) for h in s.halves):
        err = 0.0
        for k in range(s.N + 1):
            for i, h in enumerate(s.halves):
                m, TL = s.M[k, off[i]:off[i + 1]], TL_nodes[k, i]
                if numpy_rhs(h.kind) is None or not (np.all(np.isfinite(m)) and np.isfinite(TL)):
                    continue
                err = max(err, float(np.max(np.abs(h.rhs(m, TL) - h.model.rates(m, TL)))))
    without = sorted({h.kind for h in s.halves if numpy_rhs(h.kind) is None})
    if without:
        notes.append(f"no numpy transcription of fatigue model(s) {without}: integrated with the model's rates")
    return VerifyCheck("rhs: numpy vs model rates", err, "1/s", None, "every node"), err
