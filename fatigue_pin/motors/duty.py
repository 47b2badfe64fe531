"""Repeated duty: the periodic temperatures of a cycle of losses, and the heat budget of a cycle.

For losses that repeat with period ``T_c`` the linear network (``alpha = 0``) converges to a periodic
orbit; over one period ``int dtheta/dt = 0``, so the orbit's time mean is the steady state at the
cycle-mean losses (the "RMS rule"):

    mean theta_w = (R_wh + R_ha) mean P_w + R_ha mean P_h

:func:`periodic_orbit` computes the orbit exactly for piecewise-constant losses (the fixed point of
the cycle's zero-order-hold steps); :func:`cycle_heat_budget` is the largest cycle-mean copper loss
that keeps that mean at the motor's limit, the budget a window can leave the cycles after it.

:func:`repeated_cycle_winding` is the heat budget of a sliding window (``[horizon] heat_budget``):
the winding after the task's remaining cycles, each heating as the window's last cycle does, as a
linear function of the states at that cycle's ends; the window keeps it below the limit
(docs/motors.md).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.linalg import expm

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.motors.motor import MotorParameters
from fatigue_pin.motors.thermal import ThermalNetwork
from fatigue_pin.motors.thermal_states import MotorThermal

__all__ = ["periodic_orbit", "cycle_mean_rise", "cycle_heat_budget", "cycle_propagator", "repeated_cycle_winding"]


def periodic_orbit(network: ThermalNetwork, durations: Sequence[float], P_w: Sequence[float],
                   P_h: Sequence[float] | None = None) -> np.ndarray:
    """Rises ``(theta_w, theta_h)`` (K) at the start of each segment of the periodic orbit, shape
    (len(durations), 2), for a cycle of segments of ``durations`` (s, > 0) with constant losses
    ``P_w`` at the winding and ``P_h`` at the housing (W; default 0), repeated forever.

    Raises:
        ParameterError: segments of unequal lengths, or a duration not > 0.
    """
    d = np.asarray(durations, dtype=float).reshape(-1)
    pw = np.asarray(P_w, dtype=float).reshape(-1)
    ph = np.zeros_like(pw) if P_h is None else np.asarray(P_h, dtype=float).reshape(-1)
    if not (d.size > 0 and d.shape == pw.shape == ph.shape):
        raise ParameterError(f"periodic_orbit: {d.size} durations, {pw.size} P_w, {ph.size} P_h: expected one of each per segment")
    if np.any(~np.isfinite(d) | (d <= 0)):
        raise ParameterError(f"periodic_orbit durations = {d.tolist()}: expected segment lengths > 0 (s)")
    steps = [network.propagator(float(dk)) for dk in d]
    # theta after the cycle = Phi_c theta_0 + g_c; the orbit's start is the fixed point
    Phi_c, g_c = np.eye(2), np.zeros(2)
    for (Phi, Gamma), p in zip(steps, np.column_stack([pw, ph])):
        Phi_c, g_c = Phi @ Phi_c, Phi @ g_c + Gamma @ p
    x = np.linalg.solve(np.eye(2) - Phi_c, g_c)
    out = np.empty((d.size, 2))
    for k, ((Phi, Gamma), p) in enumerate(zip(steps, np.column_stack([pw, ph]))):
        out[k] = x
        x = Phi @ x + Gamma @ p
    return out


def cycle_mean_rise(network: ThermalNetwork, durations: Sequence[float], P_w: Sequence[float],
                    P_h: Sequence[float] | None = None) -> np.ndarray:
    """Time mean of the periodic orbit's rises ``(theta_w, theta_h)`` (K): the steady state at the
    cycle-mean losses."""
    d = np.asarray(durations, dtype=float)
    mean_w = float(np.dot(d, P_w) / d.sum())
    mean_h = 0.0 if P_h is None else float(np.dot(d, P_h) / d.sum())
    return network.steady_state(mean_w, mean_h)


def cycle_heat_budget(motor: MotorParameters) -> float:
    """The largest cycle-mean copper loss (W) whose periodic orbit has its mean winding temperature
    at ``T_max - margin`` with the no-load loss at the housing, the resistance taken at the limit:
    ``(T_limit - T_a - R_ha P_nl) / (R_wh + R_ha)`` (0 when the no-load loss alone reaches the limit).
    With ``P_w = R i^2`` it is the RMS current ``motor.continuous_current()``."""
    return motor.heat_budget()


def cycle_propagator(thermal: MotorThermal, cycle_s: float) -> np.ndarray:
    """``Phi`` (2, 2): the normalised states ``(x_w, x_h)`` after ``cycle_s`` seconds (> 0) without
    losses, ``expm(A cycle_s)`` with ``A = [[-a, a], [b, -(b + c)]]`` (:class:`MotorThermal`; the
    resistance's rise with temperature is a loss, not part of ``A``)."""
    if not (np.isfinite(cycle_s) and cycle_s > 0):
        raise ParameterError(f"cycle_propagator cycle_s = {cycle_s!r}: expected a cycle duration > 0 (s)")
    A = np.array([[-thermal.a, thermal.a], [thermal.b, -(thermal.b + thermal.c)]])
    return expm(A * float(cycle_s))


def repeated_cycle_winding(thermal: MotorThermal, cycle_s: float, after: int) -> tuple[np.ndarray, np.ndarray]:
    """The winding after ``after`` more cycles like the last, linear in the states at that cycle's
    two ends: ``x_w(T + after cycle_s) = c_last . x(T) + c_before . x(T - cycle_s)``.

    Over a cycle the normalised states ``x = (x_w, x_h)`` obey ``x' = Phi x + g``
    (:func:`cycle_propagator`), where the forced response ``g`` is the cycle's demand: its copper
    loss (with the resistance at its temperature) and the housing's no-load loss. The last cycle
    took ``x(T - cycle_s)`` to ``x(T)``, so ``g = x(T) - Phi x(T - cycle_s)``, and ``after = R``
    more cycles demanding ``g`` end at ``Phi^R x(T) + (I + Phi + ... + Phi^(R-1)) g``. Its winding
    row gives ``c_last = [Phi^R + S_R]_w`` and ``c_before = -[S_R Phi]_w``, ``S_R`` the sum. The
    heat budget of a sliding window (``[horizon] heat_budget``) bounds it by 1, the limit.

    It ignores the ripple within a cycle (small where ``tau_w`` spans many cycles), and it bounds
    the winding at the end of the ``R`` cycles, its maximum while they heat it.

    Returns:
        ``(c_last, c_before)``, each (2,), on ``(x_w, x_h)``; ``after = 0`` gives ``x_w(T)``.
    """
    if not (isinstance(after, (int, np.integer)) and after >= 0):
        raise ParameterError(f"repeated_cycle_winding after = {after!r}: expected an integer number of cycles >= 0")
    Phi = cycle_propagator(thermal, cycle_s)
    power, total = np.eye(2), np.zeros((2, 2))
    for _ in range(int(after)):
        total = total + power  # S_r = I + ... + Phi^(r-1)
        power = Phi @ power    # Phi^r
    return (power + total)[0].copy(), -(total @ Phi)[0].copy()
