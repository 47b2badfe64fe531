"""Muscles as an actuation kind: each muscle's activation is a control, its force acts on the
joints through its moment arms, and its fatigue model carries its capacity states.

With nm muscles on a model of nv joints (docs/muscles.md):

* controls ``u = a`` (nm,), the activations, in [0, 1]; with activation dynamics
  (``activation_dynamics``, :mod:`fatigue_pin.muscles.activation`) the excitations ``e``, and the
  activation ``a`` is the first state of each muscle's unit;
* target loads ``TL = a`` (the muscle's share of its maximal activation), or ``TL = e``;
* the force of muscle i is ``F_i(a_i^eff, L_i(q), Ldot_i(q, qdot))``
  (:meth:`~fatigue_pin.muscles.muscle.Muscle.force`), with the effective activation ``a^eff = a``
  under the ``tl+mf<=1`` and ``observed`` couplings (the paper's: ``TL + mf <= 1`` bounds the
  activation by what is not fatigued) and ``a^eff = m_active`` under ``active`` (bioptim's: the
  force follows Xia's active fraction, which tracks TL while enough is rested); with activation
  dynamics ``a^eff`` is the activation state ``a``;
* the joint torque is ``r(q)^T F`` (nv,), so it depends on the rigid-body state: the interval
  functions integrate the rigid body with it (:attr:`torque_follows_state`);
* fatigue states: each muscle's model's states, muscle after muscle (:class:`ActuationLayer`).

Residual torques (optional): signed torque actuators on the joints beside the muscles
(:class:`~fatigue_pin.ocp.actuators.SignedTorqueActuators`, bounded by their limits, each half with
its fatigue model: one that does not tire, e.g. Xia's with F = 0, makes them non-fatigable). Their
controls follow the activations, ``u = (a, tau_plus, tau_minus)``, their halves follow the muscles
as units (states, target loads ``tau / limit``), and their torque adds to the muscles'.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Union

import casadi as ca
import numpy as np

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.fatigue.interface import FatigueModel
from fatigue_pin.muscles.activation import ACTIVATION, with_activation
from fatigue_pin.muscles.muscle import Muscle
from fatigue_pin.muscles.muscle_set import MuscleSet
from fatigue_pin.muscles.polynomial_paths import PolynomialPaths
from fatigue_pin.ocp.actuation_layer import ActuationLayer, Expr, RunRecord
from fatigue_pin.ocp.actuators import SignedTorqueActuators

__all__ = ["MuscleUnit", "MuscleActuators"]

#: Fatigue parameters of the muscles: one model for all, or a dict muscle name or group -> model.
MuscleParams = Union[FatigueModel, Mapping[str, FatigueModel]]


@dataclass(frozen=True)
class MuscleUnit:
    """One muscle as a unit of the actuation layer: its name, its fatigue model, the muscle."""

    name: str
    params: FatigueModel
    muscle: Muscle


class MuscleActuators(ActuationLayer):
    """The muscles of a model as its actuators (module docstring).

    Args:
        joint_names: every joint of the model in model order (nv).
        muscles: the muscle set.
        geometry: its paths on the model: an object with CasADi functions ``lengths(q) -> (nm,)``,
            ``moment_arms(q) -> (nm, nv)`` and ``speeds(q, v) -> (nm,)``
            (:class:`~fatigue_pin.muscles.geometry.MuscleGeometry`).
        params: one fatigue model for every muscle, or a dict muscle name or group -> model
            (a muscle's own name wins over its group) that covers every muscle.
        coupling: one of :data:`~fatigue_pin.ocp.actuation.COUPLINGS`, for the muscles and the
            residual torques.
        residuals: residual torque actuators on the same joints, or None (module docstring), with the
            muscles' coupling; beside muscles of the ``active`` coupling they may have the
            ``observed`` one: their torque is then their control (bioptim's residual torques).
        activation_dynamics: the controls are excitations and each muscle's activation is a state
            (:mod:`fatigue_pin.muscles.activation`), with the muscle's own time constants; not
            with the ``active`` coupling (whose force follows m_active).
    """

    units_per_joint = False
    kind = "muscles"
    #: the muscles' torque depends on q and qdot (moment arms, lengths, speeds)
    torque_follows_state = True

    def __init__(self, joint_names: tuple[str, ...], muscles: MuscleSet, geometry: Any, params: MuscleParams,
                 coupling: str = "tl+mf<=1", residuals: SignedTorqueActuators | None = None,
                 activation_dynamics: bool = False) -> None:
        if activation_dynamics and coupling == "active":
            raise ParameterError("activation_dynamics = true with coupling 'active': the force would follow m_active, not the "
                                 "activation; expected coupling 'tl+mf<=1' or 'observed', or activation_dynamics = false")
        #: whether each muscle's activation is a state driven by its excitation, the control
        self.activation_dynamics = bool(activation_dynamics)
        units = tuple(MuscleUnit(m.name, self._unit_params(m, params, self.activation_dynamics), m) for m in muscles.muscles)
        self.n_muscles = len(units)
        self._set_units(units + (residuals.halves if residuals is not None else ()), joint_names, coupling, ("unit", "units"))
        direct = coupling == "active" and residuals is not None and residuals.coupling_kind == "observed"
        if residuals is not None and ((residuals.coupling_kind != coupling and not direct) or residuals.joint_names != self._joint_names):
            raise ParameterError(f"residual torques with coupling {residuals.coupling_kind!r} on joints {list(residuals.joint_names)}: "
                                 f"expected the muscles' coupling {coupling!r} (or 'observed' beside 'active' muscles) on joints "
                                 f"{list(self._joint_names)}")
        self.residuals = residuals
        self.muscles = muscles
        self.geometry = geometry
        nq = nv = len(self._joint_names)
        q, v = ca.SX.sym("q", nq), ca.SX.sym("v", nv)
        a = ca.SX.sym("a", self.n_muscles)
        L, Ldot = geometry.lengths(q), geometry.speeds(q, v)
        F = ca.vertcat(*[m.force(a[i], L[i], Ldot[i]) for i, m in enumerate(muscles.muscles)])
        #: ``muscle_forces(q, v, a) -> F (nm,)`` (N): tendon forces at effective activations a
        self.forces = ca.Function("muscle_forces", [q, v, a], [F], ["q", "v", "a"], ["F"])
        #: ``muscle_torque(q, v, a) -> tau (nv,)`` (N m): ``r(q)^T F``
        self.torque = ca.Function("muscle_torque", [q, v, a], [ca.mtimes(geometry.moment_arms(q).T, F)], ["q", "v", "a"], ["tau"])

    @classmethod
    def _unit_params(cls, muscle: Muscle, params: MuscleParams, dynamics: bool) -> FatigueModel:
        """The model of a muscle's unit: its fatigue model, with its activation dynamics in front."""
        model = cls._params_of(muscle, params)
        if not dynamics:
            return model
        return with_activation(model, muscle.activation_time, muscle.deactivation_time, muscle.activation_smoothing)

    @staticmethod
    def _params_of(muscle: Muscle, params: MuscleParams) -> FatigueModel:
        if isinstance(params, FatigueModel):
            return params
        if isinstance(params, Mapping):
            for key in (muscle.name, muscle.group):
                if key and key in params and isinstance(params[key], FatigueModel):
                    return params[key]
        raise ParameterError(f"no fatigue model for muscle {muscle.name!r} (group {muscle.group!r}): expected one model, "
                             "or a dict muscle name or group -> fatigue model that covers every muscle")

    # -- sizes, bounds, names ----------------------------------------------------------------------

    @property
    def nu(self) -> int:
        """Number of controls: one activation per muscle, then the residual halves' torques."""
        return self.n_muscles + (self.residuals.nu if self.residuals is not None else 0)

    def control_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Activations in [0, 1], then the residual halves' torque bounds (N m); each (nu,)."""
        lo, hi = np.zeros(self.n_muscles), np.ones(self.n_muscles)
        if self.residuals is None:
            return lo, hi
        rlo, rhi = self.residuals.control_bounds()
        return np.concatenate([lo, rlo]), np.concatenate([hi, rhi])

    @property
    def signed_limits(self) -> np.ndarray:
        """Each unit's control at TL = 1, (n_units,): 1 for a muscle (its activation), the
        residual halves' signed torque limits (N m)."""
        ones = np.ones(self.n_muscles)
        return ones if self.residuals is None else np.concatenate([ones, self.residuals.signed_limits])

    def half_torques(self, u: np.ndarray) -> np.ndarray:
        """The controls (..., nu) as the controls of the units (..., n_units), in unit order:
        the activations, then the residual halves' torques (N m) in half order."""
        u = np.asarray(u, dtype=float)
        nm = self.n_muscles
        if self.residuals is None:
            return u[..., :nm]
        return np.concatenate([u[..., :nm], self.residuals.half_torques(u[..., nm:])], axis=-1)

    def controls(self, unit_controls: np.ndarray) -> np.ndarray:
        """The inverse of :meth:`half_torques`: controls (..., nu) from the units' (..., n_units)."""
        c = np.asarray(unit_controls, dtype=float)
        nm = self.n_muscles
        if self.residuals is None:
            return c[..., :nm].copy()
        return np.concatenate([c[..., :nm], self.residuals.controls(c[..., nm:])], axis=-1)

    def per_joint(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The residual torques of the controls (..., nu) as ``(tau_plus, tau_minus)``, each
        (..., nv) (N m), zeros without residual torques."""
        u = np.asarray(u, dtype=float)
        if self.residuals is None:
            zero = np.zeros(u.shape[:-1] + (self.nv,))
            return zero, zero.copy()
        return self.residuals.per_joint(u[..., self.n_muscles:])

    def activation_rows(self) -> list[int]:
        """The activations (the excitations, with activation dynamics): the first nm controls."""
        return list(range(self.n_muscles))

    def residual_rows(self) -> list[int]:
        """The residual halves' torques, after the activations (none without residual torques)."""
        return list(range(self.n_muscles, self.nu))

    def run_record(self, q: np.ndarray, qdot: np.ndarray, u: np.ndarray, m: np.ndarray) -> RunRecord:
        """The units' controls (activations, residual torques), the muscle file's text, and at the
        start of every interval each muscle's force (N) and the joint torque (N m), (N, nm) and
        (N, nv) (``muscle_force``, ``joint_torque``)."""
        q, qdot, u = (np.asarray(a, dtype=float) for a in (q, qdot, u))
        N = u.shape[0]
        a = np.asarray(self.effective_activation(u, np.asarray(m, dtype=float)), dtype=float).reshape(N, self.n_muscles)
        forces = np.array(self.forces.map(N)(q.T, qdot.T, a.T)).T.reshape(N, self.n_muscles) if N else np.zeros((0, self.n_muscles))
        tau = self.joint_torque(u, m, np.hstack([q, qdot])) if N else np.zeros((0, self.nv))
        return RunRecord(self.half_torques(u), self.muscles.text,
                         {"muscle_force": forces, "joint_torque": np.asarray(tau, dtype=float).reshape(N, self.nv)})

    def run_record_attributes(self) -> dict[str, object]:
        """``actuation = "muscles"`` and ``muscle_names`` (JSON): the first units of the run; with
        residual torques, their ``residual_coupling``; on polynomial paths, ``muscle_paths``: the
        polynomials (JSON), which verify checks the run on."""
        out: dict[str, object] = {"actuation": self.kind, "muscle_names": json.dumps(list(self.muscles.names))}
        if self.activation_dynamics:
            out["activation_dynamics"] = True
        if self.residuals is not None:
            out["residual_coupling"] = self.residuals.coupling_kind
        if isinstance(self.geometry, PolynomialPaths):
            out["muscle_paths"] = self.geometry.to_json()
        return out

    def control_scales(self, magnitude: np.ndarray) -> np.ndarray:
        """Scales of the controls, (nu,): 1 for the activations (of order 1), the residual
        halves' as :meth:`SignedTorqueActuators.control_scales`."""
        ones = np.ones(self.n_muscles)
        return ones if self.residuals is None else np.concatenate([ones, self.residuals.control_scales(magnitude)])

    def structure_key(self) -> str:
        """What compiled code depends on: every muscle's parameters and path, its fatigue equations,
        the geometry's functions and the coupling."""
        parts = [f"{u.muscle!r}:{u.params.structure_key()}" for u in self._halves[: self.n_muscles]]
        residual = f";residuals={self.residuals.structure_key()}" if self.residuals is not None else ""
        return ("muscles;" + ";".join(parts) + f";wraps={self.muscles.wraps!r};geometry={self.geometry.lengths.serialize()}"
                f";coupling={self._coupling}{residual}")

    # -- expressions ---------------------------------------------------------------------------------

    def target_loads(self, u: Expr) -> Expr:
        """Target loads of the units, (n_units, K): the muscles' activations, then the residual
        halves' ``tau / limit``."""
        u = u if isinstance(u, (ca.SX, ca.MX, ca.DM)) else ca.DM(np.asarray(u, dtype=float).reshape(-1, self.nu).T)
        if self.residuals is None:
            return u
        return ca.vertcat(u[: self.n_muscles, :], self.residuals.target_loads(u[self.n_muscles :, :]))

    def effective_activation(self, u: Expr, m: Expr | None) -> Expr:
        """The activation the force uses (module docstring): the activations in ``u``, the
        muscles' active fractions under the ``active`` coupling, or their activation states with
        activation dynamics (rows of ``m``)."""
        nm = self.n_muscles
        if self._coupling != "active" and not self.activation_dynamics:
            return u[:nm, :] if isinstance(u, (ca.SX, ca.MX, ca.DM)) else np.asarray(u)[..., :nm]
        if m is None:
            raise ParameterError("the muscle force follows a state (m_active, or the activation); expected the fatigue states m")
        rows = self.force_state_rows()
        return m[rows, :] if isinstance(m, (ca.SX, ca.MX, ca.DM)) else np.asarray(m)[..., rows]

    def force_state_rows(self) -> list[int]:
        """Rows of the states the muscles' forces follow, (nm,): each muscle's activation state
        with activation dynamics, its active fraction under the ``active`` coupling; empty
        otherwise (the force follows the control)."""
        if self.activation_dynamics:
            return [int(r) for r in self.state_rows(ACTIVATION)[: self.n_muscles]]
        if self._coupling == "active":
            return self.active_rows()[: self.n_muscles]
        return []

    def _residual_torque(self, u: Expr, m: Expr | None, y: Expr) -> Expr | None:
        """The residual torques' joint torque (nv, K) or (..., nv), or None without them."""
        if self.residuals is None:
            return None
        symbolic = isinstance(u, (ca.SX, ca.MX, ca.DM))
        ur = u[self.n_muscles :, :] if symbolic else np.asarray(u)[..., self.n_muscles :]
        mr = None
        if m is not None:
            k = self.state_offsets()[self.n_muscles]
            mr = m[k:, :] if symbolic else np.asarray(m)[..., k:]
        return self.residuals.joint_torque(ur, mr, y)

    def joint_torque(self, u: Expr, m: Expr | None = None, y: Expr | None = None) -> Expr:
        """Joint torques (N m), ``r(q)^T F``: CasADi ``u`` (nu, K), ``y = (q, qdot)`` (2 nv, K) ->
        (nv, K); numpy ``u`` (..., nu), ``y`` (..., 2 nv) -> (..., nv)."""
        if y is None:
            raise ParameterError("muscle actuators: the joint torque depends on q and qdot; expected the rigid-body state y")
        a = self.effective_activation(u, m)
        nv = self.nv
        residual = self._residual_torque(u, m, y)
        if isinstance(u, (ca.SX, ca.MX, ca.DM)):
            K = u.size2()
            tau = (self.torque if K == 1 else self.torque.map(K))(y[:nv, :], y[nv:, :], a)
            return tau if residual is None else tau + residual
        lead = np.shape(u)[:-1]
        a = np.asarray(a, dtype=float).reshape(-1, self.n_muscles)
        yy = np.asarray(y, dtype=float).reshape(-1, 2 * nv)
        tau = np.array(self.torque.map(yy.shape[0])(yy[:, :nv].T, yy[:, nv:].T, a.T)).T.reshape(lead + (nv,))
        return tau if residual is None else tau + residual

    def controls_for_torques(self, tau: np.ndarray, q: np.ndarray, qdot: np.ndarray) -> np.ndarray:
        """Controls (N, nu) that give joint torques ``tau`` (N, nv) at (q, qdot) as nearly as the
        bounds allow: the activations by bounded least squares of ``r^T F(a)`` (affine in a), per
        node (scipy), then the residual torques take what the muscles leave."""
        from scipy.optimize import lsq_linear

        nm = self.n_muscles
        a = np.zeros((tau.shape[0], nm))
        left = np.array(tau, dtype=float)
        zero, one = np.zeros(nm), np.ones(nm)
        for k in range(tau.shape[0]):
            base = np.asarray(self.torque(q[k], qdot[k], zero)).reshape(-1)
            B = np.array([np.asarray(self.torque(q[k], qdot[k], e)).reshape(-1) - base for e in np.eye(nm)]).T
            a[k] = lsq_linear(B, tau[k] - base, bounds=(zero, one)).x
            left[k] -= base + B @ a[k]
        if self.residuals is None:
            return a
        return np.hstack([a, self.residuals.controls_for_torques(left)])
