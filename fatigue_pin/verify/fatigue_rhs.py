"""The fatigue models' right-hand sides written again in numpy, for the reference integration of
``fatigue-pin verify`` (independent of the CasADi expressions of :mod:`fatigue_pin.fatigue.models`,
against which they are cross-checked on every stored node).

Each is ``(m, TL, params by name) -> dm/dt``: ``m`` the states of one actuator half in its model's
order (Xia: ma, mr, mf; Michaud: ma, mr, mf, E), ``TL`` the target load (dimensionless), rates in 1/s.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

__all__ = ["numpy_rhs", "NumpyRhs"]

NumpyRhs = Callable[[np.ndarray, float, dict[str, float]], np.ndarray]


def _xia(m: np.ndarray, TL: float, p: dict[str, float]) -> np.ndarray:
    """Xia's 3CC with stabiliser S and rest multiplier r (docs/fatigue.md); r acts while
    ma >= TL and TL <= rest_load (default 1: on the whole relaxation branch)."""
    ma, mr, mf = m
    if ma < TL:
        C = p["LD"] * (TL - ma) if mr >= TL - ma else p["LD"] * mr
        R = p["R"]
    else:
        C = p["LR"] * (TL - ma)
        R = p["r"] * p["R"] if TL <= p.get("rest_load", 1.0) else p["R"]
    return np.array([
        C - p["F"] * ma,
        -C + R * mf,
        p["F"] * ma - R * mf + p["S"] * (1.0 - ma - mr - mf),
    ])


def _michaud(m: np.ndarray, TL: float, p: dict[str, float]) -> np.ndarray:
    """Michaud's model as bioptim writes it (fatigue_pin.fatigue.michaud.michaud_rhs docstring)."""
    ma, mr, mf, E = m
    th, k, S = p["effort_threshold"], p["effort_factor"], p["stabilization_factor"]
    if ma < TL:
        C = p["LD"] * (TL - ma) if mr > TL - ma else p["LD"] * mr
    else:
        C = p["LR"] * (TL - ma)
    above, below = TL > th, TL < th
    e = k * (TL - th) * ((1.0 - E) / (1.0 - th) if above else E / th)
    return np.array([
        C - p["F"] * ma - (e if above else 0.0),
        -C + p["R"] * mf - (e if below else 0.0),
        p["F"] * ma - p["R"] * mf,
        e + S * (1.0 - ma - mr - mf - E),
    ])


_NUMPY_RHS: dict[str, NumpyRhs] = {"xia": _xia, "michaud": _michaud}


def numpy_rhs(kind: str) -> NumpyRhs | None:
    """The numpy right-hand side ``(m, TL, params by name) -> dm/dt`` of a fatigue model kind, or
    None when there is no numpy transcription of it."""
    return _NUMPY_RHS.get(kind)
