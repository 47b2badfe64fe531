"""A joint motor through a gear: current, losses and the temperatures of its winding and housing.

Per joint, with the joint torque ``tau`` (N m) and velocity ``qd`` (rad/s):

* motor torque ``tau_m = tau / (N eta) + f tanh(N qd / omega_f)`` (N m): the gear of ratio ``N``
  and efficiency ``eta`` (applied in both directions, so a back-driven joint's current is
  over-estimated: conservative for heat, and smooth), plus a smooth Coulomb friction ``f`` at
  the motor shaft;
* current ``i = tau_m / k_t`` (A);
* copper loss at the winding ``P_w = R25 (1 + alpha (T_w - 25)) i^2`` (W);
* no-load (iron, bearing) loss at the housing ``P_h = P_nl`` (W), constant while powered;
* the thermal network of :mod:`fatigue_pin.motors.thermal` with the ambient temperature ``T_a``:
  ``C_w dT_w/dt = P_w - (T_w - T_h) / R_wh`` and ``C_h dT_h/dt = P_h + (T_w - T_h) / R_wh - (T_h - T_a) / R_ha``.

The limit is ``T_w <= T_max - margin`` (deg C). Temperatures are in deg C throughout.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca
import numpy as np

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.core.settings import check_fields, is_number, setting
from fatigue_pin.motors.thermal import ThermalNetwork

__all__ = ["MotorParameters", "REFERENCE_C"]

#: Temperature (deg C) at which datasheets give the terminal resistance R25.
REFERENCE_C = 25.0


def _positive(v: object) -> bool:
    return is_number(v) and v > 0


def _nonneg(v: object) -> bool:
    return is_number(v) and v >= 0


@dataclass(frozen=True)
class MotorParameters:
    """One joint's motor, gear and thermal network.

    Attributes:
        R25: terminal resistance at 25 deg C (ohm), > 0.
        k_t: torque constant (N m/A), > 0.
        gear_ratio: gear ratio N (motor turns per joint turn), > 0.
        R_wh: thermal resistance winding-housing (K/W), > 0.
        R_ha: thermal resistance housing-ambient (K/W), > 0.
        tau_w: thermal time constant of the winding, ``C_w R_wh`` (s), > 0.
        tau_m: thermal time constant of the motor, ``C_h R_ha`` (s), > 0.
        T_max: the winding's maximum temperature (deg C).
        alpha: temperature coefficient of the resistance (1/K, referred to 25 deg C), >= 0.
        efficiency: gear efficiency eta, in (0, 1].
        friction: Coulomb friction torque at the motor shaft (N m), >= 0.
        friction_speed: motor speed of the friction's tanh smoothing (rad/s), > 0.
        no_load_loss: no-load (iron, bearing) loss at the housing (W), >= 0.
        margin: distance kept below T_max (K), >= 0.
        T_ambient: ambient temperature (deg C), below ``T_max - margin``.
    """

    R25: float = setting(expected="a resistance > 0 (ohm)", check=_positive)
    k_t: float = setting(expected="a torque constant > 0 (N m/A)", check=_positive)
    gear_ratio: float = setting(expected="a gear ratio > 0", check=_positive)
    R_wh: float = setting(expected="a thermal resistance > 0 (K/W)", check=_positive)
    R_ha: float = setting(expected="a thermal resistance > 0 (K/W)", check=_positive)
    tau_w: float = setting(expected="a time constant > 0 (s)", check=_positive)
    tau_m: float = setting(expected="a time constant > 0 (s)", check=_positive)
    T_max: float = setting(expected="a temperature (deg C)", check=is_number)
    alpha: float = setting(0.0039, "a coefficient >= 0 (1/K)", _nonneg)
    efficiency: float = setting(1.0, "an efficiency in (0, 1]", lambda v: is_number(v) and 0 < v <= 1)
    friction: float = setting(0.0, "a torque >= 0 (N m, motor side)", _nonneg)
    friction_speed: float = setting(1.0, "a speed > 0 (rad/s, motor side)", _positive)
    no_load_loss: float = setting(0.0, "a power >= 0 (W)", _nonneg)
    margin: float = setting(10.0, "a temperature difference >= 0 (K)", _nonneg)
    T_ambient: float = setting(25.0, "a temperature (deg C)", is_number)

    def __post_init__(self) -> None:
        check_fields(self)
        if self.T_ambient >= self.T_max - self.margin:
            raise ParameterError(
                f"MotorParameters.T_max = {self.T_max!r}: expected above T_ambient + margin "
                f"= {self.T_ambient!r} + {self.margin!r} (deg C)")

    @property
    def network(self) -> ThermalNetwork:
        """The thermal network (resistances and time constants)."""
        return ThermalNetwork(self.R_wh, self.R_ha, self.tau_w, self.tau_m)

    @property
    def T_limit(self) -> float:
        """The winding temperature the constraint allows, ``T_max - margin`` (deg C)."""
        return self.T_max - self.margin

    def resistance(self, T_w):
        """Winding resistance at ``T_w`` (deg C; number or CasADi), ohm."""
        return self.R25 * (1.0 + self.alpha * (T_w - REFERENCE_C))

    def current(self, tau, qd):
        """Motor current (A) for the joint torque ``tau`` (N m) at joint velocity ``qd`` (rad/s);
        numbers, arrays or CasADi expressions."""
        tanh = ca.tanh if isinstance(tau, (ca.SX, ca.MX)) or isinstance(qd, (ca.SX, ca.MX)) else np.tanh
        tau_m = tau / (self.gear_ratio * self.efficiency) + self.friction * tanh(self.gear_ratio * qd / self.friction_speed)
        return tau_m / self.k_t

    def derivative(self, T_w, T_h, i):
        """``(dT_w/dt, dT_h/dt)`` (K/s) at temperatures ``T_w``, ``T_h`` (deg C) and current ``i`` (A)."""
        flow = (T_w - T_h) / self.R_wh
        dT_w = (self.resistance(T_w) * i * i - flow) / self.network.C_w
        dT_h = (self.no_load_loss + flow - (T_h - self.T_ambient) / self.R_ha) / self.network.C_h
        return dT_w, dT_h

    def rhs(self) -> ca.Function:
        """SX function ``thermal(T[2], i) -> dT[2]``: the temperatures' derivative (K/s) at
        ``T = (T_w, T_h)`` (deg C) and current ``i`` (A)."""
        T, i = ca.SX.sym("T", 2), ca.SX.sym("i")
        dT_w, dT_h = self.derivative(T[0], T[1], i)
        return ca.Function("thermal", [T, i], [ca.vertcat(dT_w, dT_h)], ["T", "i"], ["dT"])

    def steady_state(self, i: float) -> tuple[float, float]:
        """``(T_w, T_h)`` (deg C) in steady state at the constant current ``i`` (A), with ``R(T_w)``:
        ``theta_w = (R_th P_25 + R_ha P_nl) / (1 - alpha R_th R25 i^2)`` where ``P_25 =
        R25 (1 + alpha (T_a - 25)) i^2`` and ``R_th = R_wh + R_ha``.

        Raises:
            ParameterError: the current runs away (no steady state: ``alpha R_th R25 i^2 >= 1``).
        """
        R_th = self.R_wh + self.R_ha
        k = self.alpha * R_th * self.R25 * i * i
        if k >= 1.0:
            raise ParameterError(f"current {i!r} A: expected below the runaway current "
                                 f"{math.sqrt(1.0 / (self.alpha * R_th * self.R25)):.6g} A (no steady state)")
        theta_w = (R_th * self.resistance(self.T_ambient) * i * i + self.R_ha * self.no_load_loss) / (1.0 - k)
        P_w = self.resistance(self.T_ambient + theta_w) * i * i
        return self.T_ambient + theta_w, self.T_ambient + self.R_ha * (P_w + self.no_load_loss)

    def continuous_current(self, T_ambient: float | None = None) -> float:
        """The current (A) that holds the winding at ``T_max - margin`` in steady state at the
        ambient ``T_ambient`` (deg C; default the motor's), with the no-load loss at the housing."""
        return math.sqrt(self.heat_budget(T_ambient) / self.resistance(self.T_limit))

    def heat_budget(self, T_ambient: float | None = None) -> float:
        """The largest mean copper loss (W) that holds the winding at ``T_max - margin`` in steady
        state at the ambient ``T_ambient`` (deg C; default the motor's), with the no-load loss at
        the housing: ``(T_limit - T_a - R_ha P_nl) / (R_wh + R_ha)``, 0 when the no-load loss alone
        reaches the limit."""
        T_a = self.T_ambient if T_ambient is None else T_ambient
        return max(0.0, (self.T_limit - T_a - self.R_ha * self.no_load_loss) / (self.R_wh + self.R_ha))

    def continuous_torque(self, T_ambient: float | None = None) -> float:
        """The joint torque (N m) at :meth:`continuous_current`, without friction:
        ``N eta k_t I_c``."""
        return self.gear_ratio * self.efficiency * self.k_t * self.continuous_current(T_ambient)

    def derating(self, T_w):
        """Factor in [0, 1] on a joint torque limit at the winding temperature ``T_w`` (deg C):
        ``sqrt((T_limit - T_w) / (T_limit - T_a))`` clipped (heat goes with the square of the
        torque), 1 at ambient, 0 at the limit. Numbers or arrays."""
        s = np.clip((self.T_limit - np.asarray(T_w, dtype=float)) / (self.T_limit - self.T_ambient), 0.0, 1.0)
        return np.sqrt(s)
