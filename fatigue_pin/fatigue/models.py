"""Xia's three-compartment fatigue model with an invariant stabiliser (3CC / 3CC-S / 3CC-r).

This module is the one place where the fatigue equations are written. Per actuator, the states are
the active, resting and fatigued fractions ``m = (ma, mr, mf)`` of the actuator's capacity
(dimensionless, each in [0, 1]) and the control is the target load ``TL`` in [0, 1]:

    C(ma, mr, TL) = LD * (TL - ma)   if ma <  TL and mr >= TL - ma
                  = LD * mr          if ma <  TL and mr <  TL - ma
                  = LR * (TL - ma)   if ma >= TL
    dma/dt = C - F * ma
    dmr/dt = -C + R' * mf
    dmf/dt = F * ma - R' * mf + S * (1 - ma - mr - mf)

with ``R' = r * R`` while ``ma >= TL`` and ``R' = R`` otherwise (``r = 1`` is Xia's model; ``r != 1``
is Looft's rest-recovery variant 3CC-r). ``S = 0`` is Xia's 3CC; ``S > 0`` is the stabilised 3CC-S.
The exact model satisfies ``d(ma + mr + mf)/dt = S * (1 - ma - mr - mf)``, so an error in the sum
decays like ``exp(-S t)``; the rest multiplier is applied to both ``dmr`` and ``dmf`` so that 3CC-r
keeps this property (the paper writes ``r`` in ``dmr`` only, which would break the invariant for
``r != 1``).

The right-hand side exists once, as the SX ``casadi.Function`` returned by :func:`fatigue_rhs`
(exact branches with ``casadi.if_else``, no smoothing). The numeric helpers (:func:`rhs_numeric`,
:func:`simulate`) evaluate that same function.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable
from dataclasses import dataclass
from numbers import Real
from typing import ClassVar

import casadi as ca
import numpy as np
from scipy.integrate import solve_ivp

from fatigue_pin.core.errors import DimensionError, ParameterError

__all__ = [
    "FatigueModel",
    "XiaFatigue",
    "FATIGUE_MODELS",
    "fatigue_model",
    "STATE_NAMES",
    "PARAM_NAMES",
    "PARAM_UNITS",
    "STABILITY_LIMITS",
    "FatigueParams",
    "FatigueTrajectory",
    "check_stabiliser",
    "fatigue_rhs",
    "rhs_numeric",
    "simulate",
    "invariant_error",
]

#: Names of the three fatigue states of one actuator, in state-vector order.
STATE_NAMES: tuple[str, str, str] = ("ma", "mr", "mf")
#: Names of the entries of the parameter vector ``p`` of :func:`fatigue_rhs`, in order.
PARAM_NAMES: tuple[str, ...] = ("LD", "LR", "F", "R", "S", "r")
#: Units of the entries of ``p`` (``r`` is a dimensionless multiplier).
PARAM_UNITS: tuple[str, ...] = ("1/s", "1/s", "1/s", "1/s", "1/s", "1")

#: Stability interval of explicit one-step methods on the negative real axis: the method damps
#: ``y' = -S y`` iff ``0 <= S * dt < limit``. RK4's limit is the real root of
#: ``|1 - x + x^2/2 - x^3/6 + x^4/24| = 1``; adaptive methods (``None``) choose their own steps.
STABILITY_LIMITS: dict[str, float | None] = {
    "euler": 2.0,
    "rk2": 2.0,
    "rk3": 2.5127453266183286,
    "rk4": 2.785293563405282,
    "rk45": None,
    "rk23": None,
    "dop853": None,
    "radau": None,
    "bdf": None,
    "lsoda": None,
}

# Stability polynomials R(z) of the fixed-step methods (amplification of y' = lambda y per step).
_STABILITY_POLYNOMIALS: dict[str, tuple[float, ...]] = {
    "euler": (1.0, 1.0),
    "rk2": (1.0, 1.0, 1.0 / 2.0),
    "rk3": (1.0, 1.0, 1.0 / 2.0, 1.0 / 6.0),
    "rk4": (1.0, 1.0, 1.0 / 2.0, 1.0 / 6.0, 1.0 / 24.0),
}


def _check_rate(owner: str, name: str, value: object, unit: str) -> float:
    """Return ``value`` as a float, or raise ParameterError if it is not a finite number >= 0."""
    what = "a finite rate >= 0 (1/s)" if unit == "1/s" else "a finite multiplier >= 0 (dimensionless)"
    if isinstance(value, bool) or not isinstance(value, Real):
        raise ParameterError(f"{owner}.{name} = {value!r}: expected {what}")
    x = float(value)
    if not math.isfinite(x) or x < 0.0:
        raise ParameterError(f"{owner}.{name} = {x!r}: expected {what}")
    return x


class FatigueModel:
    """Interface of a fatigue model of one actuator half, holding its parameter values.

    A fatigue model is a frozen dataclass whose fields are its parameters (in
    :attr:`param_names` order). The class declares:

    * ``kind``: the name used in study files (``[fatigue] model = "xia"``);
    * ``state_names``: its states, in state-vector order (dimensionless fractions);
    * ``param_names`` and ``param_units``: its parameters, in the order of :meth:`as_vector`;
    * ``fatigued_state``: the state that is the fatigued fraction, bounded with the target load
      by the coupling constraint ``0 <= TL + m_fatigued <= 1`` of the OCPs;
    * :meth:`rhs`: the right-hand side as an SX ``casadi.Function``
      ``(m[n_states], TL, p[n_params]) -> dm[n_states]`` (1/s), built once per class;
    * :meth:`rest_state`: the state of a rested actuator, shape (n_states,).

    Nothing outside a model assumes a number of states or parameters: OCP state layouts, result
    files and plots take the names declared here. See ``docs/fatigue.md`` for how to add one.
    """

    kind: ClassVar[str] = ""
    state_names: ClassVar[tuple[str, ...]] = ()
    param_names: ClassVar[tuple[str, ...]] = ()
    param_units: ClassVar[tuple[str, ...]] = ()
    fatigued_state: ClassVar[str] = "mf"
    #: What the states of a valid state sum to (Xia: ma + mr + mf = 1), or None if nothing.
    state_total: ClassVar[float | None] = None

    # -- structure (class level) -----------------------------------------------------------------

    @classmethod
    def rhs(cls) -> ca.Function:
        """The right-hand side ``(m, TL, p) -> dm`` as an SX ``casadi.Function``."""
        raise NotImplementedError(f"{cls.__name__}.rhs")

    @classmethod
    def rest_state(cls) -> np.ndarray:
        """State of a rested actuator, shape (n_states,)."""
        raise NotImplementedError(f"{cls.__name__}.rest_state")

    @classmethod
    def n_states(cls) -> int:
        return len(cls.state_names)

    @classmethod
    def n_params(cls) -> int:
        return len(cls.param_names)

    @classmethod
    def state_index(cls, name: str) -> int:
        """Position of state ``name`` in this model's state vector."""
        if name not in cls.state_names:
            raise ParameterError(f"fatigue model {cls.kind!r} has no state {name!r}; its states are {list(cls.state_names)}")
        return cls.state_names.index(name)

    @classmethod
    def structure_key(cls) -> str:
        """Text that identifies the model's equations (the serialized right-hand side), for
        caches of compiled code that depend on it."""
        return f"{cls.kind}:{cls.rhs().serialize()}"

    # -- values (instance level) -----------------------------------------------------------------

    def __post_init__(self) -> None:
        owner = type(self).__name__
        for name, unit in zip(self.param_names, self.param_units):
            object.__setattr__(self, name, _check_rate(owner, name, getattr(self, name), unit))

    def with_(self, **changes: float) -> "FatigueModel":
        """A copy with some parameters changed (validated again), e.g. ``params.with_(S=0)``."""
        unknown = sorted(set(changes) - set(self.param_names))
        if unknown:
            raise ParameterError(f"{type(self).__name__}.with_: unknown field(s) {unknown}; expected some of {list(self.param_names)}")
        return dataclasses.replace(self, **changes)

    def as_vector(self) -> np.ndarray:
        """The parameter vector ``p`` of :meth:`rhs`, shape (n_params,), in :attr:`param_names` order."""
        return np.array([getattr(self, name) for name in self.param_names], dtype=float)

    def as_dict(self) -> dict[str, float]:
        """The parameters as a plain dict (for HDF5 attributes, logs and study files)."""
        return {name: getattr(self, name) for name in self.param_names}

    def check_step(self, dt: float, method: str = "rk4") -> None:
        """Raise ParameterError if an explicit integrator with step ``dt`` (s) is unstable for
        these parameters. The default accepts every step; models with a stiff term override it."""
        del dt, method

    def check_state(self, m: np.ndarray, owner: str = "fatigue state", tol: float = 1e-4) -> np.ndarray:
        """Return ``m`` as a float array (n_states,) if it is a valid state: every state a finite
        fraction in [0, 1] and, when the model declares :attr:`state_total`, their sum equal to it
        within ``tol``; otherwise raise ParameterError naming ``owner`` and the states."""
        m = np.asarray(m, dtype=float).reshape(-1)
        if m.shape != (self.n_states(),):
            raise DimensionError(f"{owner} has {m.size} entries; expected {self.n_states()} {list(self.state_names)}")
        named = ", ".join(f"{n} = {v:g}" for n, v in zip(self.state_names, m))
        if not np.all(np.isfinite(m)) or np.any(m < -tol) or np.any(m > 1.0 + tol):
            raise ParameterError(f"{owner}: {named}; expected fractions in [0, 1]")
        if self.state_total is not None and abs(float(m.sum()) - self.state_total) > tol:
            raise ParameterError(f"{owner}: {named}; {' + '.join(self.state_names)} = {float(m.sum()):g}, "
                                 f"expected {self.state_total:g}")
        return m

    def rates(self, m: np.ndarray, TL: float) -> np.ndarray:
        """``dm/dt`` on numbers (1/s), shape (n_states,)."""
        m = np.asarray(m, dtype=float).reshape(-1)
        if m.shape != (self.n_states(),):
            raise DimensionError(f"fatigue state of shape {m.shape}: expected {self.n_states()} entries {list(self.state_names)}")
        return np.asarray(self.rhs()(m, float(TL), self.as_vector())).reshape(-1)


@dataclass(frozen=True)
class XiaFatigue(FatigueModel):
    """Xia's three-compartment model 3CC, with the stabiliser S (3CC-S) and the rest-recovery
    multiplier r (3CC-r) of Looft, Herkert & Frey-Law (2018).

    States ``(ma, mr, mf)``: active, resting and fatigued fractions of the motor units.

    Attributes:
        LD: development factor of the controller C (1/s).
        LR: relaxation factor of the controller C (1/s).
        F: fatigue rate (1/s).
        R: recovery rate (1/s).
        S: invariant stabiliser (1/s); 0 gives Xia's original model.
        r: rest-recovery multiplier of the 3CC-r variant (dimensionless); ``R`` is multiplied by
            ``r`` while ``ma >= TL``. 1 gives Xia's model.

    All fields must be finite and >= 0 (``LD = 0`` or ``LR = 0`` is accepted: a degenerate but
    well-defined controller that never develops or never relaxes).
    """

    kind: ClassVar[str] = "xia"
    state_names: ClassVar[tuple[str, ...]] = ("ma", "mr", "mf")
    state_total: ClassVar[float | None] = 1.0
    param_names: ClassVar[tuple[str, ...]] = ("LD", "LR", "F", "R", "S", "r")
    param_units: ClassVar[tuple[str, ...]] = ("1/s", "1/s", "1/s", "1/s", "1/s", "1")
    fatigued_state: ClassVar[str] = "mf"

    LD: float
    LR: float
    F: float
    R: float
    S: float = 0.0
    r: float = 1.0

    @classmethod
    def rhs(cls) -> ca.Function:
        return fatigue_rhs()

    @classmethod
    def rest_state(cls) -> np.ndarray:
        return np.array([0.0, 1.0, 0.0])

    def check_step(self, dt: float, method: str = "rk4") -> None:
        check_stabiliser(self, dt, method)


#: The model that the rest of the package calls ``FatigueParams`` (Xia's 3CC / 3CC-S / 3CC-r).
FatigueParams = XiaFatigue

#: Fatigue models by ``kind`` (the ``model`` key of a study file's ``[fatigue]`` table).
FATIGUE_MODELS: dict[str, type[FatigueModel]] = {"xia": XiaFatigue}


def fatigue_model(kind: str, **params: float) -> FatigueModel:
    """A fatigue model by kind with its parameter values, e.g. ``fatigue_model("xia", LD=10, ...)``.

    Raises:
        ParameterError: unknown kind, unknown or missing parameter names, or bad values.
    """
    if kind not in FATIGUE_MODELS:
        raise ParameterError(f"fatigue model {kind!r} is unknown; expected one of {sorted(FATIGUE_MODELS)}")
    cls = FATIGUE_MODELS[kind]
    unknown = sorted(set(params) - set(cls.param_names))
    if unknown:
        raise ParameterError(f"fatigue model {kind!r} has no parameter(s) {unknown}; its parameters are {list(cls.param_names)}")
    try:
        return cls(**params)
    except TypeError as exc:
        fields = [f.name for f in dataclasses.fields(cls) if f.default is dataclasses.MISSING]
        missing = [n for n in fields if n not in params]
        raise ParameterError(f"fatigue model {kind!r} needs parameter(s) {missing}") from exc


def check_stabiliser(params: FatigueParams | float, dt: float, method: str = "rk4") -> float | None:
    """Check that an explicit integrator with step ``dt`` damps the error of the sum of states.

    The exact model gives ``e' = -S e`` for ``e = 1 - (ma + mr + mf)``, a linear invariant every
    Runge-Kutta method reproduces exactly: after one step ``e <- R(-S dt) e`` with ``R`` the
    method's stability polynomial. The stabiliser only helps if ``|R(-S dt)| < 1``, i.e. if
    ``S * dt`` lies inside the method's stability interval on the real axis (see
    :data:`STABILITY_LIMITS`: RK4 < 2.785, explicit Euler < 2).

    Args:
        params: the fatigue parameters, or the stabiliser ``S`` itself (1/s).
        dt: the integrator step (s), e.g. the RK4 substep ``0.02 / 5`` of the OCPs.
        method: ``"euler"``, ``"rk2"``, ``"rk3"``, ``"rk4"``; adaptive methods (``"rk45"``,
            ``"rk23"``, ``"dop853"``, ``"radau"``, ``"bdf"``, ``"lsoda"``) choose their own steps and
            are not checked.

    Returns:
        The amplification factor ``R(-S dt)`` of the sum error per step (dimensionless), or
        ``None`` for adaptive methods.

    Raises:
        ParameterError: ``dt`` not finite and > 0, unknown method, or ``S * dt`` outside the
            stability interval.
    """
    S = params.S if isinstance(params, XiaFatigue) else _check_rate("check_stabiliser", "S", params, "1/s")
    key = method.lower()
    if key not in STABILITY_LIMITS:
        raise ParameterError(f"check_stabiliser: method = {method!r}: expected one of {sorted(STABILITY_LIMITS)}")
    if isinstance(dt, bool) or not isinstance(dt, Real) or not math.isfinite(float(dt)) or float(dt) <= 0.0:
        raise ParameterError(f"check_stabiliser: dt = {dt!r}: expected a finite step > 0 (s)")
    limit = STABILITY_LIMITS[key]
    if limit is None:
        return None
    z = S * float(dt)
    if z >= limit:
        raise ParameterError(
            f"stabiliser S = {S!r} 1/s with {method} step dt = {float(dt)!r} s: S*dt = {z:.6g} is outside the "
            f"method's stability interval on the real axis (S*dt must be < {limit:.6g}, i.e. S < {limit / float(dt):.6g} 1/s "
            f"or dt < {limit / S:.6g} s); the error of ma + mr + mf would grow instead of decay"
        )
    coeffs = _STABILITY_POLYNOMIALS[key]
    return float(sum(c * (-z) ** k for k, c in enumerate(coeffs)))


@functools.cache
def fatigue_rhs() -> ca.Function:
    """The 3CC-S right-hand side as an SX ``casadi.Function`` (built once, then cached).

    Inputs:
        ``m`` (3): states ``(ma, mr, mf)`` (dimensionless);
        ``TL`` (1): target load (dimensionless, in [0, 1]);
        ``p`` (6): parameters ``[LD, LR, F, R, S, r]`` (1/s, except ``r`` dimensionless).

    Output:
        ``dm`` (3): ``(dma/dt, dmr/dt, dmf/dt)`` (1/s).

    The controller C uses exact ``casadi.if_else`` branches. Call it on SX to inline it, on MX to
    get a call node, or on numbers (returns a ``casadi.DM``).
    """
    m = ca.SX.sym("m", 3)
    TL = ca.SX.sym("TL")
    p = ca.SX.sym("p", 6)
    ma, mr, mf = m[0], m[1], m[2]
    LD, LR, F, R, S, r = (p[i] for i in range(6))

    developing = ma < TL
    C = ca.if_else(
        developing,
        ca.if_else(mr >= TL - ma, LD * (TL - ma), LD * mr),
        LR * (TL - ma),
    )
    R_eff = ca.if_else(developing, R, r * R)
    dma = C - F * ma
    dmr = -C + R_eff * mf
    dmf = F * ma - R_eff * mf + S * (1 - ma - mr - mf)
    return ca.Function("fatigue_rhs", [m, TL, p], [ca.vertcat(dma, dmr, dmf)], ["m", "TL", "p"], ["dm"])


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
        params: a :class:`FatigueParams` or the vector ``[LD, LR, F, R, S, r]``.

    Returns:
        ``dm/dt``, shape (3,) (1/s).
    """
    del t
    m = np.asarray(m, dtype=float).reshape(-1)
    if m.shape != (3,):
        raise DimensionError(f"fatigue state of shape {m.shape}: expected 3 entries (ma, mr, mf)")
    return fatigue_rhs()(m, float(TL), _param_vector(params)).full().reshape(3)


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
        method, rtol, atol: integrator and tolerances (scipy's defaults are RK45, 1e-3, 1e-6).
        **solve_ivp_options: passed on to ``solve_ivp`` (e.g. ``max_step``, ``first_step``).

    Returns:
        A :class:`FatigueTrajectory`; check ``success`` before using it.
    """
    y0 = np.asarray(m0, dtype=float).reshape(-1)
    if y0.shape != (3,):
        raise DimensionError(f"m0 of shape {np.shape(m0)}: expected 3 entries (ma, mr, mf)")
    if not math.isfinite(float(t_end)) or float(t_end) <= 0.0:
        raise ParameterError(f"simulate: t_end = {t_end!r}: expected a finite time > 0 (s)")
    f = fatigue_rhs()
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


# -- Michaud's model (appended) ------------------------------------------------------------------

#: Where :class:`MichaudFatigue`'s equations come from (bioptim's implementation).
MICHAUD_SOURCE = (
    "pyomeca/bioptim, bioptim/dynamics/fatigue/michaud_fatigue.py, class MichaudFatigue.apply_dynamics "
    "(read at commit e8fbc72971387be3c193364f712fbc55a225f32f; file last changed in dc335a18a6b59b8f1a6774f3693714fdfddcfe20)"
)


@functools.cache
def michaud_rhs() -> ca.Function:
    """Michaud's model as an SX ``casadi.Function`` (built once, then cached), as bioptim writes it.

    Inputs:
        ``m`` (4): states ``(ma, mr, mf, E)`` (dimensionless; bioptim names them ``ma, mr, mf_xia, mf``);
        ``TL`` (1): target load (dimensionless, in [0, 1]);
        ``p`` (7): ``[LD, LR, F, R, effort_threshold, effort_factor, stabilization_factor]``
        (1/s, except ``effort_threshold`` dimensionless).

    Output:
        ``dm`` (4): ``(dma/dt, dmr/dt, dmf/dt, dE/dt)`` (1/s).

    With ``th = effort_threshold``, ``k = effort_factor`` and ``S = stabilization_factor``::

        C  = LD (TL - ma)  if ma < TL and mr > TL - ma
           = LD mr         if ma < TL and mr <= TL - ma
           = LR (TL - ma)  if ma >= TL
        e  = k (TL - th) (1 - E) / (1 - th)   if TL > th
           = k (TL - th) E / th               otherwise
        dma/dt = C - F ma - (e if TL > th else 0)
        dmr/dt = -C + R mf - (e if TL < th else 0)
        dmf/dt = F ma - R mf
        dE/dt  = e + S (1 - ma - mr - mf - E)

    The stabiliser acts on the effort state ``E`` only, and the sum it restores is the sum of all
    four states: ``d(ma + mr + mf + E)/dt = S (1 - ma - mr - mf - E)`` on every branch (at
    ``TL = th``, ``e = 0``).
    """
    m = ca.SX.sym("m", 4)
    TL = ca.SX.sym("TL")
    p = ca.SX.sym("p", 7)
    ma, mr, mf, E = m[0], m[1], m[2], m[3]
    LD, LR, F, R, th, k, S = (p[i] for i in range(7))

    # Branch for branch as bioptim: ca.lt / ca.gt, strict comparisons.
    C = ca.if_else(ma < TL, ca.if_else(mr > TL - ma, LD * (TL - ma), LD * mr), LR * (TL - ma))
    above = TL > th
    below = TL < th
    e = k * (TL - th) * ca.if_else(above, (1 - E) / (1 - th), E / th)
    dma = C - F * ma - ca.if_else(above, e, 0)
    dmr = -C + R * mf - ca.if_else(below, e, 0)
    dmf = F * ma - R * mf
    dE = e + S * (1 - ma - mr - mf - E)
    return ca.Function("michaud_rhs", [m, TL, p], [ca.vertcat(dma, dmr, dmf, dE)], ["m", "TL", "p"], ["dm"])


@dataclass(frozen=True)
class MichaudFatigue(FatigueModel):
    """Michaud's model: Xia's three compartments plus an effort-perception state ``E``, as bioptim
    implements it (see :data:`MICHAUD_SOURCE` and :func:`michaud_rhs` for the equations).

    States ``(ma, mr, mf, E)``: active, resting and fatigued fractions (Xia's compartments) and the
    perceived effort. Above the threshold (``TL > effort_threshold``) effort builds up at the
    expense of ``ma``; below it, effort relaxes back into ``mr``. The four states sum to 1 and the
    stabiliser ``stabilization_factor`` (on ``E``) pulls a perturbed sum back.

    bioptim names the states ``ma, mr, mf_xia, mf``: its "mf" (the ``fatigue_suffix`` it scales muscle
    activations with) is the effort state, here ``E``. Here ``fatigued_state`` is Xia's fatigued
    fraction ``mf`` (bioptim's ``mf_xia``), the analogue of the paper's coupling ``TL + mf <= 1``;
    note that the capacity left is ``ma + mr = 1 - mf - E``, so an OCP that should stop ``TL`` from
    exceeding it would bound ``TL + mf + E <= 1`` instead. bioptim bounds all four states in [0, 1]
    and starts them at ``(0, 1, 0, 0)``.

    Attributes:
        LD, LR: development and relaxation factors of Xia's controller C (1/s).
        F: fatigue rate (1/s) (bioptim's docstring calls it the "recovery rate", but its equations
            use it as Xia's F, the flow ma -> mf).
        R: recovery rate (1/s), the flow mf -> mr.
        effort_threshold: target load above which effort builds up (dimensionless, 0 < th < 1).
        effort_factor: rate of effort build-up and relaxation (1/s).
        stabilization_factor: stabiliser (1/s) on ``E``; bioptim's default is 1.
    """

    kind: ClassVar[str] = "michaud"
    state_names: ClassVar[tuple[str, ...]] = ("ma", "mr", "mf", "E")
    state_total: ClassVar[float | None] = 1.0
    param_names: ClassVar[tuple[str, ...]] = (
        "LD", "LR", "F", "R", "effort_threshold", "effort_factor", "stabilization_factor"
    )
    param_units: ClassVar[tuple[str, ...]] = ("1/s", "1/s", "1/s", "1/s", "1", "1/s", "1/s")
    fatigued_state: ClassVar[str] = "mf"

    LD: float
    LR: float
    F: float
    R: float
    effort_threshold: float
    effort_factor: float
    stabilization_factor: float = 1.0

    def __post_init__(self) -> None:
        super().__post_init__()
        th = self.effort_threshold
        if not 0.0 < th < 1.0:
            raise ParameterError(
                f"MichaudFatigue.effort_threshold = {th!r}: expected a target load strictly between 0 and 1 "
                "(the effort rate divides by th and by 1 - th)"
            )

    @classmethod
    def rhs(cls) -> ca.Function:
        return michaud_rhs()

    @classmethod
    def rest_state(cls) -> np.ndarray:
        return np.array([0.0, 1.0, 0.0, 0.0])

    def check_step(self, dt: float, method: str = "rk4") -> None:
        """The sum error decays like ``exp(-S t)`` (``S = stabilization_factor``); checked as Xia's S."""
        check_stabiliser(self.stabilization_factor, dt, method)


FATIGUE_MODELS["michaud"] = MichaudFatigue
__all__ += ["MichaudFatigue", "michaud_rhs", "MICHAUD_SOURCE"]
