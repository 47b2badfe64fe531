"""The muscle curves of De Groote, Kinney, Rao and Fregly (2016), with OpenSim Moco's constants
(``DeGrooteFregly2016Muscle``), and their first-order activation dynamics.

Notation (docs/muscles.md, "Curves"): ``l`` the normalised fibre length ``l_M / l_opt``, ``v`` the
normalised fibre velocity ``v_M / (v_max l_opt)`` (shortening is ``v < 0``), ``lt`` the normalised
tendon length ``l_T / l_slack``. Every curve is dimensionless and accepts a float, a numpy array or
a CasADi SX/MX/DM expression (elementwise), and returns the same kind.

Moco's constants differ from the paper's rounded supplement so that ``f_L(1) = 1``,
``f_V(0) = 1``, ``f_V(-1) = 0`` and ``f_T(1) = 0`` hold exactly; Moco also shifts the passive curve
so that it is 0 at ``l = 0.2`` rather than at 1.
"""

from __future__ import annotations

import math
from typing import Any

import casadi as ca
import numpy as np

__all__ = ["ACTIVE_FORCE_LENGTH", "FORCE_VELOCITY", "active_force_length", "passive_force_length", "force_velocity",
           "force_velocity_inverse", "tendon_force_length", "tendon_length", "activation_rate"]

#: ``(b1i, b2i, b3i, b4i)`` of the three terms of the active force-length curve (Moco).
ACTIVE_FORCE_LENGTH = (
    (0.8150671134243542, 1.055033428970575, 0.162384573599574, 0.063303448465465),
    (0.433004984392647, 0.716775413397760, -0.029947116970696, 0.200356847296188),
    (0.1, 1.0, 0.5 * math.sqrt(0.5), 0.0),
)
#: ``(d1, d2, d3, d4)`` of the force-velocity curve (Moco's d1 and d4).
FORCE_VELOCITY = (-0.3211346127989808, -8.149, -0.374, 0.8825327733249912)
#: passive force-length: exponential shape ``kPE`` and the normalised length where it is 0
PASSIVE_SHAPE, PASSIVE_MIN_LENGTH = 4.0, 0.2
#: tendon force-length: ``(c1, c2, c3)``
TENDON = (0.2, 1.0, 0.2)


def _ops(x: Any):
    """The module whose ``exp``, ``log``, ``sqrt``, ``sinh``, ``tanh`` apply to ``x``."""
    return ca if isinstance(x, (ca.SX, ca.MX, ca.DM)) else np


def active_force_length(l: Any, width_scale: float = 1.0) -> Any:
    """Active force-length ``f_L(l)``: the sum of three Gaussian-like terms
    ``b1 exp(-(x - b2)^2 / (2 (b3 + b4 x)^2))`` of ``x = (l - 1) / width_scale + 1``; 1 at l = 1."""
    ops = _ops(l)
    x = (l - 1.0) / width_scale + 1.0
    return sum(b1 * ops.exp(-0.5 * (x - b2) ** 2 / (b3 + b4 * x) ** 2) for b1, b2, b3, b4 in ACTIVE_FORCE_LENGTH)


def passive_force_length(l: Any, strain: float = 0.6) -> Any:
    """Passive force-length ``f_PE(l)``, 0 at l = 0.2 and 1 at ``l = 1 + strain`` (``strain``:
    Moco's ``passive_fiber_strain_at_one_norm_force``)."""
    ops = _ops(l)
    k = PASSIVE_SHAPE
    offset = math.exp(k * (PASSIVE_MIN_LENGTH - 1.0) / strain)
    return (ops.exp(k * (l - 1.0) / strain) - offset) / (math.exp(k) - offset)


def force_velocity(v: Any) -> Any:
    """Force-velocity ``f_V(v) = d1 asinh(d2 v + d3) + d4``: 1 at v = 0, 0 at v = -1 (maximal
    shortening), about 1.79 at v = 1."""
    ops = _ops(v)
    d1, d2, d3, d4 = FORCE_VELOCITY
    w = d2 * v + d3
    return d1 * ops.log(w + ops.sqrt(w * w + 1.0)) + d4


def force_velocity_inverse(f: Any) -> Any:
    """The normalised velocity at which ``f_V`` equals ``f``: ``(sinh((f - d4) / d1) - d3) / d2``."""
    ops = _ops(f)
    d1, d2, d3, d4 = FORCE_VELOCITY
    return (ops.sinh((f - d4) / d1) - d3) / d2


def _tendon_shape(strain: float) -> float:
    c1, c2, c3 = TENDON
    return math.log((1.0 + c3) / c1) / (1.0 + strain - c2)


def tendon_force_length(lt: Any, strain: float = 0.049) -> Any:
    """Tendon force-length ``f_T(lt) = c1 exp(kT (lt - c2)) - c3``, with ``kT`` such that
    ``f_T(1 + strain) = 1`` (``strain``: Moco's ``tendon_strain_at_one_norm_force``)."""
    ops = _ops(lt)
    c1, c2, c3 = TENDON
    return c1 * ops.exp(_tendon_shape(strain) * (lt - c2)) - c3


def tendon_length(f: Any, strain: float = 0.049) -> Any:
    """The inverse of :func:`tendon_force_length`: the normalised tendon length at force ``f``."""
    ops = _ops(f)
    c1, c2, c3 = TENDON
    return ops.log((f + c3) / c1) / _tendon_shape(strain) + c2


def activation_rate(e: Any, a: Any, tau_act: float, tau_deact: float, smoothing: float) -> Any:
    """``da/dt`` (1/s) of the activation ``a`` under the excitation ``e`` (Moco's
    ``DeGrooteFregly2016Muscle``): with ``f = tanh(b (e - a)) / 2`` and ``z = 0.5 + 1.5 a``,
    ``((f + 1/2) / (tau_act z) + (1/2 - f) z / tau_deact) (e - a)``; time constants in s, ``b`` the
    smoothing (Moco's default 0.1, 10 recommended)."""
    ops = _ops(a)
    f = 0.5 * ops.tanh(smoothing * (e - a))
    z = 0.5 + 1.5 * a
    return ((f + 0.5) / (tau_act * z) + (0.5 - f) * z / tau_deact) * (e - a)
