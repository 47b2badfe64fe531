"""Signed torque actuators, each half carrying its own fatigue model (any :class:`FatigueModel`).

Every *actuated* joint ``j`` of a model is driven by two halves whose torques add up to the joint
torque:

* the flexion half ``j_plus`` with torque ``tau_plus`` in [0, tau_upper] (N m or N), and
* the extension half ``j_minus`` with torque ``tau_minus`` in [tau_lower, 0].

A *passive* joint has no actuator: no halves, no fatigue states, and a joint torque of 0
(:class:`Actuation` ``passive``, or a zero effort limit in the URDF).

Each half has a target load ``TL = tau / tau_limit`` in [0, 1] (``tau_plus / tau_upper`` or
``tau_minus / tau_lower``) and the fatigue states its model declares (Xia's 3CC: ``(ma, mr, mf)``),
driven by the model's right-hand side. How the torque and the fatigue are coupled is the
actuators' :attr:`~SignedTorqueActuators.coupling_kind` (:data:`COUPLINGS`, docs/model.md).

Orderings (used by every vector of this module), with na actuated joints of nv:

* halves: for each actuated joint in model order, the plus half then the minus half, i.e.
  ``(j0_plus, j0_minus, j1_plus, j1_minus, ...)`` (``n_halves = 2 * na``);
* controls ``u = (tau_plus, tau_minus)`` (shape (nu,) = (2 na,)): the plus halves' torques of the
  actuated joints in model order, then the minus halves' (:meth:`SignedTorqueActuators.control_rows`);
  the joint torque (nv,) is :meth:`SignedTorqueActuators.joint_torque` (0 on passive joints);
* fatigue states: the states of each half consecutively, halves in the order above; where a
  half's states start is :meth:`SignedTorqueActuators.state_offsets`, and a state is addressed by
  name with :meth:`SignedTorqueActuators.state_rows` (``n_states`` = the sum of the halves' states).

The symbolic methods accept CasADi SX, MX or DM and numpy arrays, and return CasADi expressions.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Protocol, Union

import casadi as ca
import numpy as np

from fatigue_pin.core.errors import DimensionError, ParameterError
from fatigue_pin.fatigue.interface import FatigueModel
from fatigue_pin.ocp.actuation import COUPLINGS, Actuation
from fatigue_pin.ocp.actuation_layer import ActuationLayer, column
from fatigue_pin.ocp.halves import ActuatorHalf, FatigueGroup
from fatigue_pin.fatigue.models import FatigueParams
from fatigue_pin.core.text import shown

__all__ = ["COUPLINGS", "Actuation", "ActuatorHalf", "FatigueGroup", "SignedTorqueActuators", "ParamsSpec"]

Expr = Union[ca.SX, ca.MX, ca.DM, np.ndarray]
#: Fatigue parameters for :meth:`SignedTorqueActuators.from_model`: one set for every half, or a
#: dict joint name -> one set for both halves or a ``(plus, minus)`` pair.
ParamsSpec = Union[FatigueModel, Mapping[str, Union[FatigueModel, tuple[FatigueModel, FatigueModel]]]]


class _HasTorqueLimits(Protocol):
    joint_names: tuple[str, ...]
    tau_lower: np.ndarray
    tau_upper: np.ndarray


class SignedTorqueActuators(ActuationLayer):
    """Signed torque actuators of a model: a plus and a minus half per actuated joint, each with
    its fatigue model; passive joints have none.

    Build with :meth:`from_model` or :meth:`from_limits`. See the module docstring for the ordering
    of halves, controls and states.
    """

    def __init__(self, halves: Sequence[ActuatorHalf], joints: Sequence[str] | None = None,
                 coupling: str = "tl+mf<=1") -> None:
        """Args:
        halves: ``(j0 plus, j0 minus, j1 plus, j1 minus, ...)``; each actuated joint exactly once,
            in the order of ``joints``.
        joints: every joint of the model in model order (length nv); those without halves are
            passive. Default: the halves' joints (no passive joint).
        coupling: one of :data:`COUPLINGS`.
        """
        halves = tuple(halves)
        if not halves or len(halves) % 2:
            raise DimensionError(f"{len(halves)} actuator halves: expected a plus and a minus half per actuated joint "
                                 "(an even number > 0: at least one joint must be actuated)")
        actuated: list[str] = []
        for k in range(0, len(halves), 2):
            plus, minus = halves[k], halves[k + 1]
            if plus.joint != minus.joint or plus.sign != 1 or minus.sign != -1:
                raise ParameterError(
                    f"actuator halves {k} and {k + 1} are {plus.name!r}, {minus.name!r}: expected the plus then the minus half of one joint"
                )
            if plus.joint in actuated:
                raise ParameterError(f"joint {plus.joint!r} has more than one pair of actuator halves")
            actuated.append(plus.joint)
        names = tuple(actuated) if joints is None else tuple(str(j) for j in joints)
        unknown = [j for j in actuated if j not in names]
        if unknown:
            raise ParameterError(f"actuator halves drive joint(s) {unknown}, which are not among the joints {list(names)}")
        if [j for j in names if j in actuated] != actuated:
            raise ParameterError(f"actuator halves drive joints {actuated}: expected them in the order of the joints {list(names)}")
        self._set_units(halves, names, coupling, ("half", "halves"))
        self._actuated = tuple(actuated)

    # -- construction --------------------------------------------------------------------------

    @classmethod
    def from_limits(
        cls,
        joint_names: Sequence[str],
        tau_lower: Sequence[float] | np.ndarray,
        tau_upper: Sequence[float] | np.ndarray,
        params: ParamsSpec,
        actuation: Actuation | None = None,
    ) -> SignedTorqueActuators:
        """Build from joint names and torque bounds.

        Args:
            joint_names: joint names in model order (length nv).
            tau_lower: lower torque bounds (N m), shape (nv,), each < 0 (limit of the minus half),
                or 0 together with ``tau_upper`` (a passive joint: zero effort limit).
            tau_upper: upper torque bounds (N m), shape (nv,), each > 0 (limit of the plus half),
                or 0 (passive).
            params: one :class:`FatigueParams` for every half, or a dict joint name -> FatigueParams
                (both halves) or -> ``(plus, minus)`` pair; the dict must name every actuated joint
                and may name passive ones (ignored).
            actuation: passive joints and coupling (default: none passive, ``tl+mf<=1``).

        Raises:
            ParameterError: unknown or missing joint names in ``params`` or ``actuation.passive``,
                a bound of the wrong sign, or no actuated joint.
            DimensionError: bounds whose length is not the number of joints.
        """
        actuation = actuation or Actuation()
        names = tuple(str(n) for n in joint_names)
        nv = len(names)
        lo = np.asarray(tau_lower, dtype=float).reshape(-1)
        up = np.asarray(tau_upper, dtype=float).reshape(-1)
        if lo.shape != (nv,) or up.shape != (nv,):
            raise DimensionError(f"tau_lower {lo.shape}, tau_upper {up.shape}: expected ({nv},) for joints {list(names)}")
        unknown = [j for j in actuation.passive if j not in names]
        if unknown:
            raise ParameterError(f"actuators.passive names joint {unknown[0]!r}, which is not in the model; its joints are {list(names)}")
        passive = set(actuation.passive) | {names[j] for j in range(nv) if lo[j] == 0.0 and up[j] == 0.0}
        for j, name in enumerate(names):
            if name in passive:
                continue
            if not (lo[j] < 0.0):
                raise ParameterError(f"tau_lower of joint {name!r} = {shown(lo[j])} N m: expected < 0 (limit of the extension half), "
                                     "or 0 with tau_upper 0 (a passive joint)")
            if not (up[j] > 0.0):
                raise ParameterError(f"tau_upper of joint {name!r} = {shown(up[j])} N m: expected > 0 (limit of the flexion half), "
                                     "or 0 with tau_lower 0 (a passive joint)")
        actuated = tuple(n for n in names if n not in passive)
        if not actuated:
            raise ParameterError(f"every joint of {list(names)} is passive: expected at least one actuated joint")
        per_joint = cls._resolve_params(actuated, params, tuple(passive))
        halves: list[ActuatorHalf] = []
        for j, name in enumerate(names):
            if name in passive:
                continue
            p_plus, p_minus = per_joint[name]
            halves.append(ActuatorHalf(name, 1, float(up[j]), p_plus))
            halves.append(ActuatorHalf(name, -1, float(-lo[j]), p_minus))
        return cls(halves, names, actuation.coupling)

    @classmethod
    def from_model(cls, model: _HasTorqueLimits, params: ParamsSpec, actuation: Actuation | None = None) -> SignedTorqueActuators:
        """Build from a model with ``joint_names``, ``tau_lower`` and ``tau_upper`` (N m), e.g. a
        :class:`fatigue_pin.robot.model.RobotModel`. See :meth:`from_limits` for ``params`` and
        ``actuation``."""
        return cls.from_limits(model.joint_names, model.tau_lower, model.tau_upper, params, actuation)

    @staticmethod
    def _resolve_params(names: tuple[str, ...], params: ParamsSpec,
                        passive: tuple[str, ...] = ()) -> dict[str, tuple[FatigueParams, FatigueParams]]:
        if isinstance(params, FatigueModel):
            return {n: (params, params) for n in names}
        if not isinstance(params, Mapping):
            raise ParameterError(
                f"actuator params of type {type(params).__name__}: expected a FatigueParams or a dict joint name -> "
                "FatigueParams or (plus, minus) pair"
            )
        unknown = sorted(set(params) - set(names) - set(passive))
        if unknown:
            raise ParameterError(f"fatigue params given for unknown joint(s) {unknown}; the actuated joints are {list(names)}")
        missing = [n for n in names if n not in params]
        if missing:
            raise ParameterError(f"no fatigue params for joint(s) {missing}; the dict must name every actuated joint of {list(names)}")
        out: dict[str, tuple[FatigueParams, FatigueParams]] = {}
        for n in names:
            v = params[n]
            if isinstance(v, FatigueModel):
                out[n] = (v, v)
            elif isinstance(v, tuple) and len(v) == 2 and all(isinstance(x, FatigueModel) for x in v):
                out[n] = (v[0], v[1])
            else:
                raise ParameterError(f"fatigue params of joint {shown(n)} = {shown(v)}: expected a FatigueParams or a (plus, minus) pair")
        return out

    # -- sizes and names -----------------------------------------------------------------------

    @property
    def actuated_joints(self) -> tuple[str, ...]:
        """The joints with halves, in model order (length na)."""
        return self._actuated

    @property
    def passive_joints(self) -> tuple[str, ...]:
        """The joints without an actuator, in model order."""
        return tuple(j for j in self._joint_names if j not in self._actuated)

    @property
    def n_actuated(self) -> int:
        """Number of actuated joints (na)."""
        return len(self._actuated)

    @property
    def nu(self) -> int:
        """Number of controls (``2 * na``: the plus halves' torques, then the minus halves')."""
        return 2 * self.n_actuated

    def structure_key(self) -> str:
        """Text identifying what compiled code depends on: joints, limits, fatigue equations and,
        when not the default, the passive joints and the coupling."""
        key = ";".join(f"{h.name}:{h.tau_limit!r}:{h.params.structure_key()}" for h in self._halves)
        if self.passive_joints or self._coupling != "tl+mf<=1":  # the default's key is as before (caches)
            key += f";passive={list(self.passive_joints)};coupling={self._coupling}"
        return key

    @property
    def tau_plus_limits(self) -> np.ndarray:
        """Upper bounds of ``tau_plus`` (N m), shape (na,): the plus halves' limits."""
        return np.array([h.tau_limit for h in self._halves[0::2]])

    @property
    def tau_minus_limits(self) -> np.ndarray:
        """Lower bounds of ``tau_minus`` (N m, negative), shape (na,): the minus halves' limits."""
        return np.array([-h.tau_limit for h in self._halves[1::2]])

    @property
    def signed_limits(self) -> np.ndarray:
        """Torque of each half at TL = 1 (N m), shape (n_halves,): ``+tau_upper``, ``tau_lower``, ..."""
        return np.array([h.signed_limit for h in self._halves])

    def control_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounds of the controls (N m), each shape (nu,): ``[0, tau_upper]`` for the plus halves,
        ``[tau_lower, 0]`` for the minus halves."""
        na = self.n_actuated
        return (np.concatenate([np.zeros(na), self.tau_minus_limits]),
                np.concatenate([self.tau_plus_limits, np.zeros(na)]))

    def control_scales(self, magnitude: np.ndarray) -> np.ndarray:
        """Scales of the controls, shape (nu,), from a per-joint magnitude (nv,) (e.g. the larger
        torque limit of each joint): each half takes its joint's."""
        m = np.asarray(magnitude, dtype=float).reshape(-1)[self.actuated_index]
        return np.concatenate([m, m])

    @property
    def actuated_index(self) -> list[int]:
        """Index in the model's joints of each actuated joint, length na."""
        return [self._joint_names.index(j) for j in self._actuated]

    # -- controls, halves and joint torques ------------------------------------------------------

    def control_rows(self) -> list[int]:
        """Row of each half's torque in the controls ``u = (tau_plus, tau_minus)`` (shape (nu,)),
        length n_halves: ``a`` for the plus half of the a-th actuated joint, ``na + a`` for its
        minus half."""
        na = self.n_actuated
        return [k // 2 + (0 if h.sign > 0 else na) for k, h in enumerate(self._halves)]

    def torque_matrix(self) -> np.ndarray:
        """``B`` (nv, nu) with joint torque = ``B u``: a 1 where a control acts on its joint, rows of
        passive joints zero."""
        B = np.zeros((self.nv, self.nu))
        for a, j in enumerate(self.actuated_index):
            B[j, a] = B[j, self.n_actuated + a] = 1.0
        return B

    def half_torque_matrix(self) -> np.ndarray:
        """``H`` (nv, n_halves) with joint torque = ``H tau_halves`` (halves in half order)."""
        H = np.zeros((self.nv, self.n_halves))
        for k, h in enumerate(self._halves):
            H[self._joint_names.index(h.joint), k] = 1.0
        return H

    def joint_torque(self, u: Expr, m: Expr | None = None, y: Expr | None = None) -> Expr:
        """Joint torques (N m or N), 0 on passive joints, from controls ``u`` (the rigid-body
        state ``y`` is not needed: the torque of a half does not depend on it).

        CasADi ``u`` of shape (nu, K) gives (nv, K); a numpy ``u`` of shape (..., nu) (a row per
        interval) gives (..., nv). Under the ``active`` coupling the torque is the halves'
        ``m_active * limit`` and ``m`` (the fatigue states: (n_states, K), or (..., n_states) for
        numpy) is required; otherwise it is the sum of the halves' controls and ``m`` is ignored.
        """
        if self._coupling == "active":
            if m is None:
                raise ParameterError("coupling 'active': the joint torque is m_active * limit; expected the fatigue states m")
            return self._map_halves(self.half_torques_from_states(m))
        if isinstance(u, (ca.SX, ca.MX, ca.DM)):
            if u.size1() != self.nu:
                raise DimensionError(f"controls u of shape {u.shape}: expected {self.nu} rows (tau_plus, tau_minus)")
            if not self.passive_joints:  # the expression of the NLPs before passive joints (their caches)
                return u[: self.n_actuated, :] + u[self.n_actuated :, :]
            return ca.mtimes(ca.DM(self.torque_matrix()), u)
        a = np.asarray(u, dtype=float)
        if a.shape[-1] != self.nu:
            raise DimensionError(f"controls u of shape {a.shape}: expected {self.nu} columns (tau_plus, tau_minus)")
        return a @ self.torque_matrix().T

    def controls_for_torques(self, tau: np.ndarray, q: np.ndarray | None = None, qdot: np.ndarray | None = None) -> np.ndarray:
        """Controls (N, nu) that give joint torques ``tau`` (N, nv) as nearly as the limits allow:
        each actuated joint's torque clipped to its limits and given to the half of its sign
        (passive joints have none); ``q``, ``qdot`` are not needed."""
        tau = np.clip(np.asarray(tau, dtype=float)[:, self.actuated_index], self.tau_minus_limits, self.tau_plus_limits)
        return np.hstack([np.maximum(tau, 0.0), np.minimum(tau, 0.0)])

    def _map_halves(self, tau_halves: Expr) -> Expr:
        """Joint torques from half torques: (n_halves, K) -> (nv, K), or numpy (..., n_halves) -> (..., nv)."""
        if isinstance(tau_halves, (ca.SX, ca.MX, ca.DM)):
            return ca.mtimes(ca.DM(self.half_torque_matrix()), tau_halves)
        return np.asarray(tau_halves, dtype=float) @ self.half_torque_matrix().T

    def half_torques_from_states(self, m: Expr) -> Expr:
        """``m_active * signed limit`` of every half (N m): CasADi (n_states, K) -> (n_halves, K),
        numpy (..., n_states) -> (..., n_halves)."""
        rows = self.active_rows()
        if isinstance(m, (ca.SX, ca.MX, ca.DM)):
            return m[rows, :] * ca.repmat(ca.DM(self.signed_limits), 1, m.size2())
        return np.asarray(m, dtype=float)[..., rows] * self.signed_limits

    def half_torques(self, u: np.ndarray) -> np.ndarray:
        """The controls (..., nu) as torques of the halves (..., n_halves), in half order."""
        return np.asarray(u, dtype=float)[..., self.control_rows()]

    def per_joint(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The controls (..., nu) as ``(tau_plus, tau_minus)``, each (..., nv) with a column per
        joint of the model (0 on passive joints), N m."""
        u = np.asarray(u, dtype=float)
        na, idx = self.n_actuated, self.actuated_index
        plus, minus = np.zeros(u.shape[:-1] + (self.nv,)), np.zeros(u.shape[:-1] + (self.nv,))
        plus[..., idx], minus[..., idx] = u[..., :na], u[..., na:]
        return plus, minus

    def controls(self, tau_halves: np.ndarray) -> np.ndarray:
        """The inverse of :meth:`half_torques`: controls (..., nu) from half torques (..., n_halves)."""
        t = np.asarray(tau_halves, dtype=float)
        u = np.zeros(t.shape[:-1] + (self.nu,))
        u[..., self.control_rows()] = t
        return u

    # -- expressions ---------------------------------------------------------------------------

    def target_loads(self, u: Expr) -> Expr:
        """Target loads ``TL`` (dimensionless) of every half, shape (n_halves, K), from controls
        ``u = (tau_plus; tau_minus)`` of shape (nu, K) (N m): ``tau_plus / tau_upper`` and
        ``tau_minus / tau_lower`` in half order; a row selection divided by the signed limits, so
        affine in ``u`` (the one place that divides a torque by its limit)."""
        u = u if isinstance(u, (ca.SX, ca.MX, ca.DM)) else column(u, self.nu, "controls u")
        if u.size1() != self.nu:
            raise DimensionError(f"controls u of shape {u.shape}: expected {self.nu} rows (tau_plus, tau_minus)")
        return u[self.control_rows(), :] / ca.repmat(ca.DM(self.signed_limits), 1, u.size2())

    def available_torque(self, mf: Expr) -> Expr:
        """Signed torque each half can still produce, ``(1 - mf) * limit`` (N m), shape (n_halves,):
        ``(1 - mf) * tau_upper`` for a plus half (>= 0), ``(1 - mf) * tau_lower`` for a minus half (<= 0).

        Args:
            mf: fatigued fraction of each half, shape (n_halves,) (see :meth:`split_states`).
        """
        mf = column(mf, self.n_halves, "mf")
        return (1 - mf) * ca.DM(self.signed_limits)

    def __repr__(self) -> str:
        parts = ", ".join(f"{h.name}: {h.tau_limit:g} N m" for h in self._halves)
        extra = "".join([f", passive {list(self.passive_joints)}" if self.passive_joints else "",
                         f", coupling {self._coupling!r}" if self._coupling != "tl+mf<=1" else ""])
        return f"SignedTorqueActuators({parts}{extra})"
