"""Forward simulation of one actuator's Xia fatigue model with scipy (:func:`simulate`), the
right-hand side on numbers (:func:`rhs_numeric`) and the error of the sum of states
(:func:`invariant_error`). All of them evaluate the model's own CasADi right-hand side
(:func:`fatigue_pin.fatigue.models.fatigue_rhs`)."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from fatigue_pin.core.errors import DimensionError, ParameterError
from fatigue_pin.fatigue.models import FatigueParams, PARAM_NAMES, fatigue_rhs
from fatigue_pin.core.text import shown

__all__ = ["FatigueTrajectory", "simulate", "rhs_numeric", "invariant_error"]


def _param_vector(params: FatigueParams | np.ndarray) -> np.ndarray:
    if isinstance(params, FatigueParams):
        return params.as_vector()
    p = np.asarray(params, dtype=float).reshape(-1)
    if p.shape != (6,):
        raise DimensionError(f"fatigue parameter vector of shape {np.shape(params)}: expected 6 entries {list(PARAM_NAMES)}")
    return p


def rhs_numeric(t: float, m: np.ndarray, TL: float, params: FatigueParams | np.ndarray) -> np.ndarray:
    """Evaluate :func:`fatigue_rhs` on numbers, with the ``(t, y)`` signature of scipy.

    Args:
        t: time (s); unused (the model is autonomous), kept for ``solve_ivp``.
        m: states ``(ma, mr, mf)``, shape (3,).
        TL: target load (dimensionless).
        params: a :class:`FatigueParams` (its ``rest_load`` option included) or the vector
            ``[LD, LR, F, R, S, r]`` (then ``rest_load = 1``).

    Returns:
        ``dm/dt``, shape (3,) (1/s).
    """
    del t
    m = np.asarray(m, dtype=float).reshape(-1)
    if m.shape != (3,):
        raise DimensionError(f"fatigue state of shape {m.shape}: expected 3 entries (ma, mr, mf)")
    f = params.rhs() if isinstance(params, FatigueParams) else fatigue_rhs()
    return f(m, float(TL), _param_vector(params)).full().reshape(3)


@dataclass(frozen=True)
class FatigueTrajectory:
    """A simulated fatigue trajectory of one actuator.

    Attributes:
        t: times (s), shape (n,).
        ma, mr, mf: states at ``t`` (dimensionless), shape (n,) each.
        params: the parameters used.
        method, rtol, atol: the scipy integrator settings.
        success, message: as reported by ``solve_ivp``.
        nfev: number of right-hand-side evaluations.
    """

    t: np.ndarray
    ma: np.ndarray
    mr: np.ndarray
    mf: np.ndarray
    params: FatigueParams
    method: str
    rtol: float
    atol: float
    success: bool
    message: str
    nfev: int

    @property
    def m(self) -> np.ndarray:
        """States stacked as rows ``(ma, mr, mf)``, shape (3, n)."""
        return np.vstack([self.ma, self.mr, self.mf])

    @property
    def total(self) -> np.ndarray:
        """``ma + mr + mf``, shape (n,)."""
        return self.ma + self.mr + self.mf

    @property
    def invariant_error(self) -> np.ndarray:
        """``|1 - (ma + mr + mf)|``, shape (n,)."""
        return invariant_error(self.m)


def simulate(
    params: FatigueParams,
    TL: float | Callable[[float], float],
    m0: tuple[float, float, float] | np.ndarray,
    t_end: float,
    t_eval: np.ndarray | None = None,
    method: str = "RK45",
    rtol: float = 1e-3,
    atol: float = 1e-6,
    **solve_ivp_options: object,
) -> FatigueTrajectory:
    """Integrate one fatigue model with ``scipy.integrate.solve_ivp``.

    Args:
        params: the fatigue parameters.
        TL: target load (dimensionless), a constant or a function of time ``TL(t)``.
        m0: initial states ``(ma, mr, mf)``, shape (3,).
        t_end: final time (s), > 0; the simulation starts at t = 0.
        t_eval: output times (s); ``None`` returns the integrator's own steps.
        method: scipy integrator (scipy's default RK45).
        rtol: relative tolerance (scipy's default 1e-3).
        atol: absolute tolerance (scipy's default 1e-6).
        **solve_ivp_options: passed on to ``solve_ivp`` (e.g. ``max_step``, ``first_step``).

    Returns:
        A :class:`FatigueTrajectory`; check ``success`` before using it.
    """
    y0 = np.asarray(m0, dtype=float).reshape(-1)
    if y0.shape != (3,):
        raise DimensionError(f"m0 of shape {np.shape(m0)}: expected 3 entries (ma, mr, mf)")
    if not math.isfinite(float(t_end)) or float(t_end) <= 0.0:
        raise ParameterError(f"simulate: t_end = {shown(t_end)}: expected a finite time > 0 (s)")
    f = params.rhs()
    p = params.as_vector()
    if callable(TL):
        load = TL

        def rhs(t: float, y: np.ndarray) -> np.ndarray:
            return f(y, float(load(t)), p).full().reshape(3)

    else:
        tl = float(TL)

        def rhs(t: float, y: np.ndarray) -> np.ndarray:
            return f(y, tl, p).full().reshape(3)

    out = solve_ivp(
        rhs, (0.0, float(t_end)), y0, method=method, t_eval=t_eval, rtol=rtol, atol=atol, **solve_ivp_options
    )
    return FatigueTrajectory(
        t=out.t,
        ma=out.y[0],
        mr=out.y[1],
        mf=out.y[2],
        params=params,
        method=method,
        rtol=float(rtol),
        atol=float(atol),
        success=bool(out.success),
        message=str(out.message),
        nfev=int(out.nfev),
    )


def invariant_error(m: np.ndarray) -> np.ndarray | float:
    """``|1 - (ma + mr + mf)|`` of states stacked along the first axis.

    Args:
        m: states ``(ma, mr, mf)``, shape (3,) or (3, n).

    Returns:
        The invariant error (dimensionless): a float for shape (3,), shape (n,) otherwise.
    """
    a = np.asarray(m, dtype=float)
    if a.ndim == 0 or a.shape[0] != 3:
        raise DimensionError(f"states of shape {a.shape}: expected (3,) or (3, n) with rows (ma, mr, mf)")
    err = np.abs(1.0 - a.sum(axis=0))
    return float(err) if err.ndim == 0 else err
