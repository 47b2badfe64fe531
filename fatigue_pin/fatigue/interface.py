"""The interface every fatigue model implements, and the stability check of its stabiliser.

A fatigue model of one actuator half is a frozen dataclass deriving from :class:`FatigueModel`:
its fields are its parameters, its class declares its states and its right-hand side (a CasADi
function). Xia's model is in :mod:`fatigue_pin.fatigue.models`, Michaud's in
:mod:`fatigue_pin.fatigue.michaud`; ``docs/extending.md`` shows how to add one.
"""

from __future__ import annotations

import dataclasses
import math
from numbers import Real
from typing import ClassVar

import casadi as ca
import numpy as np

from fatigue_pin.core.errors import DimensionError, ParameterError
from fatigue_pin.core.text import shown

__all__ = ["FatigueModel", "STABILITY_LIMITS", "check_stabiliser", "check_rate"]

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


def check_rate(owner: str, name: str, value: object, unit: str) -> float:
    """Return ``value`` as a float, or raise ParameterError if it is not a finite number >= 0.

    Args:
        owner: what holds the value, for the message (e.g. ``"XiaFatigue"``).
        name: the value's name, for the message (e.g. ``"F"``).
        value: the value to check.
        unit: ``"1/s"`` for a rate, anything else for a dimensionless multiplier.
    """
    what = "a finite rate >= 0 (1/s)" if unit == "1/s" else "a finite multiplier >= 0 (dimensionless)"
    if isinstance(value, bool) or not isinstance(value, Real):
        raise ParameterError(f"{owner}.{name} = {shown(value)}: expected {what}")
    x = float(value)
    if not math.isfinite(x) or x < 0.0:
        raise ParameterError(f"{owner}.{name} = {shown(x)}: expected {what}")
    return x


class FatigueModel:
    """Interface of a fatigue model of one actuator half, holding its parameter values.

    A fatigue model is a frozen dataclass whose fields are its parameters (in
    :attr:`param_names` order) and, optionally, options that change its equations. The class
    declares:

    * ``kind``: the name used in study files (``[fatigue] model = "xia"``);
    * ``state_names``: its states, in state-vector order (dimensionless fractions);
    * ``param_names`` and ``param_units``: its parameters, in the order of :meth:`as_vector`;
    * ``option_names``: fields that are not parameters of the vector ``p`` but select the
      equations (Xia's ``rest_load``); they are part of :meth:`structure_key` and of
      :meth:`as_dict` when they differ from their default;
    * ``fatigued_state``: the state that is the fatigued fraction, bounded with the target load
      by the coupling constraint ``0 <= TL + m_fatigued <= 1`` of the OCPs;
    * ``active_state``: the state that is the active fraction, whose product with the torque
      limit is the half's torque under the ``active`` coupling (docs/model.md), or None if the
      model has none;
    * :meth:`rhs`: the right-hand side as an SX ``casadi.Function``
      ``(m[n_states], TL, p[n_params]) -> dm[n_states]`` (1/s);
    * :meth:`rest_state`: the state of a rested actuator, shape (n_states,).

    Nothing outside a model assumes a number of states or parameters: OCP state layouts, result
    files and plots take the names declared here. See ``docs/extending.md`` for how to add one.
    """

    kind: ClassVar[str] = ""
    state_names: ClassVar[tuple[str, ...]] = ()
    param_names: ClassVar[tuple[str, ...]] = ()
    param_units: ClassVar[tuple[str, ...]] = ()
    option_names: ClassVar[tuple[str, ...]] = ()
    fatigued_state: ClassVar[str] = "mf"
    active_state: ClassVar[str | None] = "ma"
    #: What the states of a valid state sum to (Xia: ma + mr + mf = 1), or None if nothing.
    state_total: ClassVar[float | None] = None

    # -- structure ---------------------------------------------------------------------------------

    def rhs(self) -> ca.Function:
        """The right-hand side ``(m, TL, p) -> dm`` as an SX ``casadi.Function``."""
        raise NotImplementedError(f"{type(self).__name__}.rhs")

    @classmethod
    def rest_state(cls) -> np.ndarray:
        """State of a rested actuator, shape (n_states,)."""
        raise NotImplementedError(f"{cls.__name__}.rest_state")

    @classmethod
    def n_states(cls) -> int:
        """Number of states."""
        return len(cls.state_names)

    @classmethod
    def n_params(cls) -> int:
        """Number of entries of the parameter vector ``p``."""
        return len(cls.param_names)

    @classmethod
    def total_states(cls) -> tuple[str, ...]:
        """The states whose sum is :attr:`state_total` (all of them, unless a model says otherwise)."""
        return cls.state_names

    @classmethod
    def state_index(cls, name: str) -> int:
        """Position of state ``name`` in this model's state vector."""
        if name not in cls.state_names:
            raise ParameterError(f"fatigue model {cls.kind!r} has no state {name!r}; its states are {list(cls.state_names)}")
        return cls.state_names.index(name)

    def structure_key(self) -> str:
        """Text that identifies the model's equations (the serialized right-hand side), for
        caches of compiled code that depend on it."""
        return f"{self.kind}:{self.rhs().serialize()}"

    # -- values ------------------------------------------------------------------------------------

    def __post_init__(self) -> None:
        owner = type(self).__name__
        for name, unit in zip(self.param_names, self.param_units):
            object.__setattr__(self, name, check_rate(owner, name, getattr(self, name), unit))

    def with_(self, **changes: float) -> "FatigueModel":
        """A copy with some parameters (or options) changed, validated again, e.g. ``params.with_(S=0)``."""
        unknown = sorted(set(changes) - set(self.param_names) - set(self.option_names))
        if unknown:
            raise ParameterError(f"{type(self).__name__}.with_: unknown field(s) {unknown}; "
                                 f"expected some of {list(self.param_names + self.option_names)}")
        return dataclasses.replace(self, **changes)

    def as_vector(self) -> np.ndarray:
        """The parameter vector ``p`` of :meth:`rhs`, shape (n_params,), in :attr:`param_names` order."""
        return np.array([getattr(self, name) for name in self.param_names], dtype=float)

    def as_dict(self) -> dict[str, float]:
        """The parameters as a plain dict (for HDF5 attributes, logs and study files), followed
        by the options that differ from their default."""
        out = {name: getattr(self, name) for name in self.param_names}
        defaults = {f.name: f.default for f in dataclasses.fields(self)} if dataclasses.is_dataclass(self) else {}
        for name in self.option_names:
            if getattr(self, name) != defaults.get(name, dataclasses.MISSING):
                out[name] = getattr(self, name)
        return out

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


def check_stabiliser(params: FatigueModel | float, dt: float, method: str = "rk4") -> float | None:
    """Check that an explicit integrator with step ``dt`` damps the error of the sum of states.

    The exact model gives ``e' = -S e`` for ``e = 1 - (ma + mr + mf)``, a linear invariant every
    Runge-Kutta method reproduces exactly: after one step ``e <- R(-S dt) e`` with ``R`` the
    method's stability polynomial. The stabiliser only helps if ``|R(-S dt)| < 1``, i.e. if
    ``S * dt`` lies inside the method's stability interval on the real axis (see
    :data:`STABILITY_LIMITS`: RK4 < 2.785, explicit Euler < 2).

    Args:
        params: a fatigue model with a stabiliser field ``S`` (Xia's), or the stabiliser ``S``
            itself (1/s).
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
    if isinstance(params, FatigueModel):
        if not hasattr(params, "S"):
            raise ParameterError(f"check_stabiliser: {type(params).__name__} has no stabiliser S; pass S (1/s) itself")
        S = float(params.S)  # type: ignore[attr-defined]
    else:
        S = check_rate("check_stabiliser", "S", params, "1/s")
    key = method.lower()
    if key not in STABILITY_LIMITS:
        raise ParameterError(f"check_stabiliser: method = {method!r}: expected one of {sorted(STABILITY_LIMITS)}")
    if isinstance(dt, bool) or not isinstance(dt, Real) or not math.isfinite(float(dt)) or float(dt) <= 0.0:
        raise ParameterError(f"check_stabiliser: dt = {shown(dt)}: expected a finite step > 0 (s)")
    limit = STABILITY_LIMITS[key]
    if limit is None:
        return None
    z = S * float(dt)
    if z >= limit:
        raise ParameterError(
            f"stabiliser S = {shown(S)} 1/s with {method} step dt = {float(dt)!r} s: S*dt = {z:.6g} is outside the "
            f"method's stability interval on the real axis (S*dt must be < {limit:.6g}, i.e. S < {limit / float(dt):.6g} 1/s "
            f"or dt < {limit / S:.6g} s); the error of ma + mr + mf would grow instead of decay"
        )
    coeffs = _STABILITY_POLYNOMIALS[key]
    return float(sum(c * (-z) ** k for k, c in enumerate(coeffs)))
