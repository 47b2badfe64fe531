"""The two-node (winding, housing) lumped thermal network of a motor, as numbers.

With the rises over ambient ``theta_w = T_w - T_a`` and ``theta_h = T_h - T_a`` (K), the losses
``P_w`` at the winding and ``P_h`` at the housing (W):

    C_w dtheta_w/dt = P_w - (theta_w - theta_h) / R_wh
    C_h dtheta_h/dt = P_h + (theta_w - theta_h) / R_wh - theta_h / R_ha

with the datasheet (maxon) conventions ``C_w = tau_w / R_wh`` and ``C_h = tau_m / R_ha``:
``tau_w`` and ``tau_m`` are products of a capacity and a resistance, not the eigen time constants
of the coupled network (:meth:`ThermalNetwork.eigen_time_constants`). In matrix form
``dtheta/dt = A theta + B P`` with ``A = [[-a, a], [b, -(b + c)]]``, ``a = 1 / (C_w R_wh)``,
``b = 1 / (C_h R_wh)``, ``c = 1 / (C_h R_ha)``, ``B = diag(1 / C_w, 1 / C_h)``.

For constant losses the response is the steady state plus two exponentials
(:meth:`ThermalNetwork.response`), exact; the copper loss's rise with the winding temperature
(``R(T_w)``) is in :mod:`fatigue_pin.motors.motor`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.core.settings import check_fields, is_number, setting

__all__ = ["ThermalNetwork"]


def _positive(v: object) -> bool:
    return is_number(v) and v > 0


@dataclass(frozen=True)
class ThermalNetwork:
    """The thermal resistances and time constants of one motor (datasheet conventions).

    Attributes:
        R_wh: thermal resistance winding-housing (K/W), > 0.
        R_ha: thermal resistance housing-ambient (K/W), > 0.
        tau_w: thermal time constant of the winding, ``C_w R_wh`` (s), > 0.
        tau_m: thermal time constant of the motor, ``C_h R_ha`` (s), > 0.
    """

    R_wh: float = setting(expected="a thermal resistance > 0 (K/W)", check=_positive)
    R_ha: float = setting(expected="a thermal resistance > 0 (K/W)", check=_positive)
    tau_w: float = setting(expected="a time constant > 0 (s)", check=_positive)
    tau_m: float = setting(expected="a time constant > 0 (s)", check=_positive)

    def __post_init__(self) -> None:
        check_fields(self)

    @property
    def C_w(self) -> float:
        """Heat capacity of the winding (J/K)."""
        return self.tau_w / self.R_wh

    @property
    def C_h(self) -> float:
        """Heat capacity of the housing (J/K)."""
        return self.tau_m / self.R_ha

    @property
    def rates(self) -> tuple[float, float, float]:
        """``(a, b, c)`` (1/s): ``1 / (C_w R_wh)``, ``1 / (C_h R_wh)``, ``1 / (C_h R_ha)``."""
        return 1.0 / self.tau_w, 1.0 / (self.C_h * self.R_wh), 1.0 / self.tau_m

    @property
    def A(self) -> np.ndarray:
        """The system matrix (1/s), shape (2, 2), on ``(theta_w, theta_h)``."""
        a, b, c = self.rates
        return np.array([[-a, a], [b, -(b + c)]])

    @property
    def B(self) -> np.ndarray:
        """The input matrix (K/J), shape (2, 2), on ``(P_w, P_h)``."""
        return np.diag([1.0 / self.C_w, 1.0 / self.C_h])

    def eigenvalues(self) -> tuple[float, float]:
        """``(lambda_slow, lambda_fast)`` (1/s), real, negative and distinct."""
        a, b, c = self.rates
        s = a + b + c
        root = math.sqrt(s * s - 4.0 * a * c)
        # the slow root as 2 a c / (-s - root): no cancellation when a c << s^2
        return -2.0 * a * c / (s + root), -(s + root) / 2.0

    def eigen_time_constants(self) -> tuple[float, float]:
        """``(tau_fast, tau_slow)`` (s), the network's own time constants; their product is
        ``tau_w tau_m`` and their sum ``tau_w + tau_m + C_w R_ha``."""
        slow, fast = self.eigenvalues()
        return -1.0 / fast, -1.0 / slow

    def steady_state(self, P_w: float, P_h: float = 0.0) -> np.ndarray:
        """Rises ``(theta_w, theta_h)`` (K) in steady state under constant losses (W):
        ``theta_h = R_ha (P_w + P_h)``, ``theta_w = theta_h + R_wh P_w``."""
        theta_h = self.R_ha * (P_w + P_h)
        return np.array([theta_h + self.R_wh * P_w, theta_h])

    def response(self, t: np.ndarray | float, P_w: float, P_h: float = 0.0,
                 theta0: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
        """Rises (K), shape ``(len(t), 2)`` (``(theta_w, theta_h)`` per time), at times ``t`` (s,
        >= 0) from the rises ``theta0`` under constant losses ``P_w``, ``P_h`` (W): the steady state
        plus two exponentials, ``theta(t) = theta_inf + sum_k v_k (u_k . (theta0 - theta_inf)) e^(lambda_k t)``
        with the eigenvectors ``v_k`` of ``A`` and the rows ``u_k`` of their inverse."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        a, b, c = self.rates
        inf = self.steady_state(P_w, P_h)
        d = np.asarray(theta0, dtype=float) - inf
        out = np.tile(inf, (t.size, 1))
        lams = self.eigenvalues()
        # eigenvector of A for lambda: (a, lambda + a); the two columns V, their inverse by rows
        V = np.array([[a, a], [lams[0] + a, lams[1] + a]])
        coef = np.linalg.solve(V, d)
        for k, lam in enumerate(lams):
            out += np.outer(np.exp(lam * t), V[:, k] * coef[k])
        return out

    def propagator(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """``(Phi, Gamma)`` of the exact zero-order-hold step of length ``dt`` (s):
        ``theta(t + dt) = Phi theta(t) + Gamma (P_w, P_h)`` for losses constant over the step."""
        if not (is_number(dt) and dt > 0):
            raise ParameterError(f"ThermalNetwork.propagator dt = {dt!r}: expected a step > 0 (s)")
        Phi = np.column_stack([self.response(dt, 0.0, 0.0, e)[0] for e in ((1.0, 0.0), (0.0, 1.0))])
        Gamma = np.column_stack([self.response(dt, *p)[0] for p in ((1.0, 0.0), (0.0, 1.0))])
        return Phi, Gamma
