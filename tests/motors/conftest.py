"""Shared builders of the motor tests: the reference's closed form and an independent integrator."""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp


def network_ode(R_wh: float, R_ha: float, tau_w: float, tau_m: float, P_w: float, P_h: float = 0.0):
    """The two-node network's right-hand side on the rises (K), written from the equations."""
    C_w, C_h = tau_w / R_wh, tau_m / R_ha

    def f(t, th):
        flow = (th[0] - th[1]) / R_wh
        return [(P_w - flow) / C_w, (P_h + flow - th[1] / R_ha) / C_h]

    return f


def integrate(f, t: np.ndarray, y0) -> np.ndarray:
    """``solve_ivp`` (DOP853, tight tolerances) at the times ``t``; shape (len(t), n)."""
    sol = solve_ivp(f, (0.0, float(t[-1])), list(y0), method="DOP853", t_eval=t, rtol=1e-13, atol=1e-12)
    assert sol.success
    return sol.y.T


def step_from_ambient(R_wh: float, R_ha: float, tau_w: float, tau_m: float, P: float, t: np.ndarray):
    """The winding's and housing's rise (K) after a step of loss ``P`` (W) at the winding from
    ambient, as the reference's section 5.3 writes it (K_f, K_s with the eigen time constants)."""
    C_w, C_h = tau_w / R_wh, tau_m / R_ha
    a, b, c = 1 / (C_w * R_wh), 1 / (C_h * R_wh), 1 / (C_h * R_ha)
    s = a + b + c
    lam = np.roots([1.0, s, a * c])
    tf, ts = sorted(-1 / lam)
    w_inf, h_inf = (R_wh + R_ha) * P, R_ha * P
    Kf = tf * (P * ts / C_w - w_inf) / (ts - tf)
    Ks = ts * (w_inf - P * tf / C_w) / (ts - tf)
    w = w_inf - Kf * np.exp(-t / tf) - Ks * np.exp(-t / ts)
    h = h_inf * (1 - (ts * np.exp(-t / ts) - tf * np.exp(-t / tf)) / (ts - tf))
    return np.column_stack([w, h])
