"""Muscles as an actuation kind: each muscle's activation is a control, its force acts on the
joints through its moment arms, and its fatigue model carries its capacity states.

With nm muscles on a model of nv joints (docs/muscles.md):

* controls ``u = a`` (nm,), the activations, in [0, 1];
* target loads ``TL = a`` (the muscle's share of its maximal activation);
* the force of muscle i is ``F_i(a_i^eff, L_i(q), Ldot_i(q, qdot))``
  (:meth:`~fatigue_pin.muscles.muscle.Muscle.force`), with the effective activation ``a^eff = a``
  under the ``tl+mf<=1`` and ``observed`` couplings (the paper's: ``TL + mf <= 1`` bounds the
  activation by what is not fatigued) and ``a^eff = m_active`` under ``active`` (bioptim's: the
  force follows Xia's active fraction, which tracks TL while enough is rested);
* the joint torque is ``r(q)^T F`` (nv,), so it depends on the rigid-body state: the interval
  functions integrate the rigid body with it (:attr:`torque_needs_state`);
* fatigue states: each muscle's model's states, muscle after muscle (:class:`ActuationLayer`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Union

import casadi as ca
import numpy as np

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.core.text import shown
from fatigue_pin.fatigue.interface import FatigueModel
from fatigue_pin.muscles.muscle import Muscle
from fatigue_pin.muscles.muscle_set import MuscleSet
from fatigue_pin.ocp.actuation import COUPLINGS
from fatigue_pin.ocp.actuation_layer import ActuationLayer, Expr

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
        coupling: one of :data:`~fatigue_pin.ocp.actuation.COUPLINGS`.
    """

    torque_needs_state = True

    def __init__(self, joint_names: tuple[str, ...], muscles: MuscleSet, geometry: Any, params: MuscleParams,
                 coupling: str = "tl+mf<=1") -> None:
        if coupling not in COUPLINGS:
            raise ParameterError(f"coupling = {shown(coupling)}: expected one of {list(COUPLINGS)}")
        self._joint_names = tuple(joint_names)
        self._coupling = coupling
        self._halves = tuple(MuscleUnit(m.name, self._params_of(m, params), m) for m in muscles.muscles)
        if coupling == "active":
            lacking = [u.name for u in self._halves if u.params.active_state not in u.params.state_names]
            if lacking:
                raise ParameterError(f"coupling 'active' needs an active state in every muscle's fatigue model; {lacking} have none")
        self.muscles = muscles
        self.geometry = geometry
        nq = nv = len(self._joint_names)
        q, v = ca.SX.sym("q", nq), ca.SX.sym("v", nv)
        a = ca.SX.sym("a", self.nu)
        L, Ldot = geometry.lengths(q), geometry.speeds(q, v)
        F = ca.vertcat(*[m.force(a[i], L[i], Ldot[i]) for i, m in enumerate(muscles.muscles)])
        #: ``muscle_forces(q, v, a) -> F (nm,)`` (N): tendon forces at effective activations a
        self.forces = ca.Function("muscle_forces", [q, v, a], [F], ["q", "v", "a"], ["F"])
        #: ``muscle_torque(q, v, a) -> tau (nv,)`` (N m): ``r(q)^T F``
        self.torque = ca.Function("muscle_torque", [q, v, a], [ca.mtimes(geometry.moment_arms(q).T, F)], ["q", "v", "a"], ["tau"])

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
        """Number of controls: one activation per muscle."""
        return len(self._halves)

    @property
    def n_actuated(self) -> int:
        """Number of muscles (the units that take a control)."""
        return len(self._halves)

    def control_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Activations in [0, 1], each shape (nu,)."""
        return np.zeros(self.nu), np.ones(self.nu)

    def control_scales(self, magnitude: np.ndarray) -> np.ndarray:
        """Scales of the controls, (nu,): 1 (activations are of order 1)."""
        return np.ones(self.nu)

    def structure_key(self) -> str:
        """What compiled code depends on: every muscle's parameters and path, its fatigue equations,
        the geometry's functions and the coupling."""
        parts = [f"{u.muscle!r}:{u.params.structure_key()}" for u in self._halves]
        return "muscles;" + ";".join(parts) + f";wraps={self.muscles.wraps!r};geometry={self.geometry.lengths.serialize()};coupling={self._coupling}"

    # -- expressions ---------------------------------------------------------------------------------

    def target_loads(self, u: Expr) -> Expr:
        """Target loads of the muscles, (nm, K): their activations."""
        return u if isinstance(u, (ca.SX, ca.MX, ca.DM)) else ca.DM(np.asarray(u, dtype=float).reshape(-1, self.nu).T)

    def effective_activation(self, u: Expr, m: Expr | None) -> Expr:
        """The activation the force uses (module docstring): ``u``, or the active fractions under
        the ``active`` coupling (rows of ``m``)."""
        if self._coupling != "active":
            return u
        if m is None:
            raise ParameterError("coupling 'active': the muscle force follows m_active; expected the fatigue states m")
        return m[self.active_rows(), :] if isinstance(m, (ca.SX, ca.MX, ca.DM)) else np.asarray(m)[..., self.active_rows()]

    def joint_torque(self, u: Expr, m: Expr | None = None, y: Expr | None = None) -> Expr:
        """Joint torques (N m), ``r(q)^T F``: CasADi ``u`` (nu, K), ``y = (q, qdot)`` (2 nv, K) ->
        (nv, K); numpy ``u`` (..., nu), ``y`` (..., 2 nv) -> (..., nv)."""
        if y is None:
            raise ParameterError("muscle actuators: the joint torque depends on q and qdot; expected the rigid-body state y")
        a = self.effective_activation(u, m)
        nv = self.nv
        if isinstance(u, (ca.SX, ca.MX, ca.DM)):
            K = u.size2()
            return (self.torque if K == 1 else self.torque.map(K))(y[:nv, :], y[nv:, :], a)
        lead = np.shape(u)[:-1]
        a = np.asarray(a, dtype=float).reshape(-1, self.nu)
        y = np.asarray(y, dtype=float).reshape(-1, 2 * nv)
        out = np.array(self.torque.map(y.shape[0])(y[:, :nv].T, y[:, nv:].T, a.T)).T
        return out.reshape(lead + (nv,))

    def controls_for_torques(self, tau: np.ndarray, q: np.ndarray, qdot: np.ndarray) -> np.ndarray:
        """Activations (N, nu) that give joint torques ``tau`` (N, nv) at (q, qdot) as nearly as
        the bounds allow: bounded least squares of ``r^T F(a)`` (affine in a), per node (scipy)."""
        from scipy.optimize import lsq_linear

        out = np.zeros((tau.shape[0], self.nu))
        zero, one = np.zeros(self.nu), np.ones(self.nu)
        for k in range(tau.shape[0]):
            base = np.asarray(self.torque(q[k], qdot[k], zero)).reshape(-1)
            B = np.array([np.asarray(self.torque(q[k], qdot[k], e)).reshape(-1) - base for e in np.eye(self.nu)]).T
            out[k] = lsq_linear(B, tau[k] - base, bounds=(zero, one)).x
        return out
