"""Motors as an actuation kind: one motor per actuated joint, its signed torque the control, its
winding and housing temperatures the capacity states (docs/motors.md).

With na actuated joints of nv:

* controls ``u = tau`` (na,), the joint torques (N m), in ``[-limit, limit]`` (the joint's torque
  limit, the smaller of the model's two);
* target loads ``TL = tau / limit`` (signed; heat goes with ``TL^2``);
* the joint torque is ``u`` on the actuated joints, 0 on passive ones;
* capacity states: each motor's :class:`~fatigue_pin.motors.thermal_states.MotorThermal`
  ``(xw, xh)``, the rises over ambient over the rise the limit allows, so that the [0, 1] bounds
  of the OCPs' fatigue states are ``T_w <= T_max - margin``. The coupling is ``observed`` (the
  ``tl+mf<=1`` rows have no meaning for heat; the limit is the state bound), or, with ``derate``,
  ``derated``: each torque within its derated limit, ``|tau| <= limit sqrt(1 - x_w)``
  (:meth:`~fatigue_pin.motors.motor.MotorParameters.derating`), the rows ``0 <= TL^2 + x_w <= 1``.

Friction and the no-load loss's speed dependence are not in the states (the states see the torque
only); the no-load loss is constant (:mod:`fatigue_pin.motors.motor`).
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping
from dataclasses import dataclass

import casadi as ca
import numpy as np

from fatigue_pin.core.errors import DimensionError, ParameterError
from fatigue_pin.motors.duty import repeated_cycle_winding
from fatigue_pin.motors.motor import MotorParameters
from fatigue_pin.motors.thermal_states import MotorThermal
from fatigue_pin.ocp.actuation_layer import ActuationLayer, Expr, RunRecord

__all__ = ["MotorUnit", "MotorActuators"]


@dataclass(frozen=True)
class MotorUnit:
    """One joint's motor as a unit of the actuation layer.

    Attributes:
        name: the joint's name.
        params: its temperature states' model.
        motor: the motor.
        limit: the joint's torque limit (N m), > 0: the controls' bound and TL = 1.
    """

    name: str
    params: MotorThermal
    motor: MotorParameters
    limit: float


class MotorActuators(ActuationLayer):
    """A motor on every actuated joint (module docstring).

    Args:
        joint_names: every joint of the model in model order (nv).
        motors: joint name -> its motor, one per actuated joint (model order is kept).
        limits: joint name -> its torque limit (N m, > 0), for every joint of ``motors``.
        derate: bound each torque by its derated limit ``limit sqrt(1 - x_w)`` (the coupling
            ``derated``): a warm motor gives less torque, none at its limit.
    """

    units_per_joint = False
    kind = "motors"
    torque_follows_state = False
    #: a motor delivers its command while its winding is below the limit (a closed loop's plant
    #: trips it to 0 at the limit)
    capacity_limits_load = False
    #: a window ends within the heat budget of the task's remaining cycles (:meth:`window_budget`)
    has_window_budget = True

    def __init__(self, joint_names: tuple[str, ...], motors: Mapping[str, MotorParameters], limits: Mapping[str, float],
                 derate: bool = False) -> None:
        unknown = [j for j in motors if j not in joint_names]
        if unknown:
            raise ParameterError(f"motor on joint {unknown[0]!r}: expected a joint of the model {list(joint_names)}")
        if not motors:
            raise ParameterError("motors: none given; expected a motor on at least one joint")
        units = []
        for j in (j for j in joint_names if j in motors):
            limit = float(limits.get(j, 0.0))
            if not limit > 0:
                raise ParameterError(f"joint {j!r}: torque limit {limit!r}: expected > 0 (N m) for a motor")
            units.append(MotorUnit(j, MotorThermal.from_motor(motors[j], limit), motors[j], limit))
        self._set_units(tuple(units), tuple(joint_names), "observed", ("motor", "motors"))
        if derate:  # a motor's own coupling (not one of a study's [actuators] couplings)
            self._coupling = "derated"

    @classmethod
    def from_model(cls, model, motors: Mapping[str, MotorParameters], derate: bool = False) -> "MotorActuators":
        """The motors on ``model`` (a :class:`~fatigue_pin.robot.model.RobotModel`): each joint's
        limit is the smaller magnitude of its torque bounds."""
        limits = {j: float(min(-lo, hi)) for j, lo, hi in zip(model.joint_names, model.tau_lower, model.tau_upper)}
        return cls(tuple(model.joint_names), motors, limits, derate)

    @property
    def derated(self) -> bool:
        """Whether each torque is bounded by its derated limit (the coupling ``derated``)."""
        return self._coupling == "derated"

    @property
    def coupling_rows(self) -> bool:
        """Whether the OCPs hold ``0 <= TL^2 + x_w <= 1`` (:attr:`derated`)."""
        return self.derated

    def coupling(self, m, u):
        """``TL^2 + x_w`` of every motor, (na,): ``<= 1`` is ``|tau| <= limit sqrt(1 - x_w)``."""
        TL = self.target_loads(u)
        return TL * TL + self.fatigued(m)

    def delivered_loads(self, TL: np.ndarray, capacity: np.ndarray) -> np.ndarray:
        """A motor delivers its command while its winding is below the limit (capacity
        ``1 - x_w > 0``) and trips to 0 at it; derated, within ``+- sqrt(capacity)``."""
        TL, cap = np.asarray(TL, dtype=float), np.maximum(np.asarray(capacity, dtype=float), 0.0)
        if self.derated:
            return np.clip(TL, -np.sqrt(cap), np.sqrt(cap))
        return np.where(cap > 0.0, TL, 0.0)

    # -- sizes, bounds, names ----------------------------------------------------------------------

    @property
    def actuated_index(self) -> list[int]:
        """Index in the model's joints of each motor's joint, length na."""
        return [self._joint_names.index(u.name) for u in self._halves]

    @property
    def n_actuated(self) -> int:
        """Number of motors (na)."""
        return len(self._halves)

    @property
    def nu(self) -> int:
        """Number of controls: one signed torque per motor."""
        return self.n_actuated

    @property
    def limits(self) -> np.ndarray:
        """Torque limits (N m), (na,)."""
        return np.array([u.limit for u in self._halves])

    @property
    def signed_limits(self) -> np.ndarray:
        """Each unit's control at TL = 1 (N m), (na,): its limit."""
        return self.limits

    def control_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """``[-limit, limit]`` per motor (N m), each (nu,)."""
        return -self.limits, self.limits

    def control_scales(self, magnitude: np.ndarray) -> np.ndarray:
        """Scales of the controls (nu,) from a per-joint magnitude (nv,): each motor its joint's."""
        return np.asarray(magnitude, dtype=float).reshape(-1)[self.actuated_index]

    def structure_key(self) -> str:
        """What compiled code depends on: joints, limits, the states' equations."""
        return "motors;" + ("derated;" if self.derated else "") + ";".join(
            f"{u.name}:{u.limit!r}:{u.params.structure_key()}" for u in self._halves)

    # -- controls and joint torques ------------------------------------------------------------------

    def half_torques(self, u: np.ndarray) -> np.ndarray:
        """The controls (..., nu) as the units' controls (..., na): the same torques (N m)."""
        return np.asarray(u, dtype=float).copy()

    def controls(self, unit_controls: np.ndarray) -> np.ndarray:
        """The inverse of :meth:`half_torques`."""
        return np.asarray(unit_controls, dtype=float).copy()

    def torque_matrix(self) -> np.ndarray:
        """``B`` (nv, nu) with joint torque = ``B u``."""
        B = np.zeros((self.nv, self.nu))
        B[self.actuated_index, range(self.nu)] = 1.0
        return B

    def per_joint(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The torques (..., nu) as ``(tau_plus, tau_minus)`` (..., nv): their positive and
        negative parts on their joints (N m)."""
        tau = np.asarray(u, dtype=float) @ self.torque_matrix().T
        return np.maximum(tau, 0.0), np.minimum(tau, 0.0)

    def joint_torque(self, u: Expr, m: Expr | None = None, y: Expr | None = None) -> Expr:
        """Joint torques (N m): CasADi ``u`` (nu, K) -> (nv, K); numpy (..., nu) -> (..., nv)."""
        if isinstance(u, (ca.SX, ca.MX, ca.DM)):
            if u.size1() != self.nu:
                raise DimensionError(f"controls u of shape {u.shape}: expected {self.nu} rows (one torque per motor)")
            return ca.mtimes(ca.DM(self.torque_matrix()), u)
        a = np.asarray(u, dtype=float)
        if a.shape[-1] != self.nu:
            raise DimensionError(f"controls u of shape {a.shape}: expected {self.nu} columns (one torque per motor)")
        return a @ self.torque_matrix().T

    def target_loads(self, u: Expr) -> Expr:
        """``tau / limit`` of every motor, (na, K) (signed)."""
        u = u if isinstance(u, (ca.SX, ca.MX, ca.DM)) else ca.DM(np.asarray(u, dtype=float).reshape(-1, self.nu).T)
        return u / ca.repmat(ca.DM(self.limits), 1, u.size2())

    def controls_for_torques(self, tau: np.ndarray, q: np.ndarray | None = None, qdot: np.ndarray | None = None) -> np.ndarray:
        """Controls (N, nu) for joint torques (N, nv): the motors' joints' torques, clipped to the limits."""
        return np.clip(np.asarray(tau, dtype=float)[:, self.actuated_index], -self.limits, self.limits)

    def measured_rows(self) -> list[int]:
        """The housing's state ``x_h`` of every motor: what a sensor on the motor (a UR's joint
        temperature) measures; a probe gives ``1 - x_h``."""
        return self.state_rows("xh")

    @property
    def n_window_budget(self) -> int:
        """Rows of a window's heat budget: one per motor (its winding)."""
        return self.n_actuated

    def window_budget(self, cycle_s: float, after: int) -> tuple[np.ndarray, np.ndarray]:
        """Each motor's winding after ``after`` more cycles like a window's last
        (:func:`~fatigue_pin.motors.duty.repeated_cycle_winding`), as rows
        ``(E_last, E_before)`` (na, n_states) on the states at that cycle's end and start."""
        E_last, E_before = np.zeros((self.n_actuated, self.n_states)), np.zeros((self.n_actuated, self.n_states))
        for k, (unit, w, h) in enumerate(zip(self._halves, self.state_rows("xw"), self.state_rows("xh"))):
            E_last[k, [w, h]], E_before[k, [w, h]] = repeated_cycle_winding(unit.params, cycle_s, after)
        return E_last, E_before

    # -- temperatures and records ----------------------------------------------------------------------

    def temperatures(self, m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Winding and housing temperatures (deg C), each (..., na), from the states (..., n_states)."""
        m = np.asarray(m, dtype=float)
        T_a = np.array([u.motor.T_ambient for u in self._halves])
        D = np.array([u.motor.T_limit for u in self._halves]) - T_a
        return T_a + D * m[..., self.state_rows("xw")], T_a + D * m[..., self.state_rows("xh")]

    def run_record(self, q: np.ndarray, qdot: np.ndarray, u: np.ndarray, m: np.ndarray) -> RunRecord:
        """The motors' torques, and their winding and housing temperatures at the start of every
        interval (``winding_C``, ``housing_C``, (N, na))."""
        T_w, T_h = self.temperatures(m)
        return RunRecord(self.half_torques(u), "", {"winding_C": T_w, "housing_C": T_h})

    def run_record_attributes(self) -> dict[str, object]:
        """``actuation = "motors"`` and ``motors``: JSON of joint -> the motor's fields and limit."""
        table = {u.name: {**dataclasses.asdict(u.motor), "limit": u.limit} for u in self._halves}
        return {"actuation": self.kind, "motors": json.dumps(table)}

    def __repr__(self) -> str:
        return "MotorActuators(" + ", ".join(f"{u.name}: {u.limit:g} N m" for u in self._halves) + ")"
