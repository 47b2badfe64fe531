"""A motor's temperatures as the capacity states of an actuator: :class:`MotorThermal`, a
:class:`~fatigue_pin.fatigue.interface.FatigueModel`.

The states are the rises over ambient, normalised by the rise the limit allows,
``D = T_max - margin - T_a``:

    x_w = (T_w - T_a) / D,    x_h = (T_h - T_a) / D

so that ``x_w = 0`` is a cold motor and ``x_w = 1`` the winding at its limit: the OCPs' bounds of a
fatigue state, [0, 1], are then the constraint ``T_w <= T_max - margin`` (and ``x_h <= x_w``
follows). The "target load" is the signed joint torque over a reference torque (the joint's torque
limit), ``TL = tau / tau_ref``; the current is ``i = TL I_ref`` with ``I_ref = tau_ref / (N eta k_t)``
(no friction: the state equations see the torque only). With ``R(T_w) = R_a (1 + beta x_w)``,
``R_a = R(T_a)``:

    dx_w/dt = q_w (1 + beta x_w) TL^2 - a (x_w - x_h)
    dx_h/dt = q_h + b (x_w - x_h) - c x_h

with ``q_w = R_a I_ref^2 / (C_w D)``, ``beta = R25 alpha D / R_a``, ``a = 1 / tau_w``,
``q_h = P_nl / (C_h D)``, ``b = 1 / (C_h R_wh)``, ``c = 1 / tau_m`` (1/s, beta dimensionless):
every motor has the same equations, its numbers are in the parameter vector.

Heat goes with the square of the torque, so one motor (one unit) per joint carries the signed
torque; it is not a model for a torque half.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import casadi as ca
import numpy as np

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.fatigue.interface import FatigueModel
from fatigue_pin.motors.motor import MotorParameters

__all__ = ["MotorThermal"]


@dataclass(frozen=True)
class MotorThermal(FatigueModel):
    """Normalised winding and housing temperature rises of one joint's motor (module docstring).

    Attributes:
        q_w: heating rate of the winding at ``TL = 1`` and ambient temperature (1/s).
        beta: rise of the resistance over the allowed rise (dimensionless).
        a: ``1 / tau_w`` (1/s).
        q_h: heating rate of the housing by the no-load loss (1/s).
        b: ``1 / (C_h R_wh)`` (1/s).
        c: ``1 / tau_m`` (1/s).
    """

    q_w: float
    beta: float
    a: float
    q_h: float
    b: float
    c: float

    kind: ClassVar[str] = "motor-thermal"
    state_names: ClassVar[tuple[str, ...]] = ("xw", "xh")
    param_names: ClassVar[tuple[str, ...]] = ("q_w", "beta", "a", "q_h", "b", "c")
    param_units: ClassVar[tuple[str, ...]] = ("1/s", "", "1/s", "1/s", "1/s", "1/s")
    fatigued_state: ClassVar[str] = "xw"
    active_state: ClassVar[str | None] = None

    @classmethod
    def from_motor(cls, motor: MotorParameters, torque_ref: float) -> "MotorThermal":
        """The states of ``motor`` with the target load ``tau / torque_ref`` (N m, > 0)."""
        if not torque_ref > 0:
            raise ParameterError(f"MotorThermal torque_ref = {torque_ref!r}: expected a joint torque > 0 (N m)")
        net = motor.network
        D = motor.T_limit - motor.T_ambient
        R_a = motor.resistance(motor.T_ambient)
        I_ref = torque_ref / (motor.gear_ratio * motor.efficiency * motor.k_t)
        a, b, c = net.rates
        return cls(q_w=R_a * I_ref ** 2 / (net.C_w * D), beta=motor.R25 * motor.alpha * D / R_a, a=a,
                   q_h=motor.no_load_loss / (net.C_h * D), b=b, c=c)

    def rhs(self) -> ca.Function:
        """``(m[2], TL, p[6]) -> dm[2]`` (1/s), SX."""
        m, TL, p = ca.SX.sym("m", 2), ca.SX.sym("TL"), ca.SX.sym("p", 6)
        q_w, beta, a, q_h, b, c = (p[k] for k in range(6))
        flow = m[0] - m[1]
        dm = ca.vertcat(q_w * (1 + beta * m[0]) * TL * TL - a * flow, q_h + b * flow - c * m[1])
        return ca.Function("motor_thermal", [m, TL, p], [dm], ["m", "TL", "p"], ["dm"])

    @classmethod
    def rest_state(cls) -> np.ndarray:
        """A cold motor: both nodes at ambient, ``(0, 0)``."""
        return np.zeros(2)
