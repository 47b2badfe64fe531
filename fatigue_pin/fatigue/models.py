"""Xia's three-compartment fatigue model with an invariant stabiliser (3CC / 3CC-S / 3CC-r).

This module is the one place where Xia's equations are written. Per actuator, the states are
the active, resting and fatigued fractions ``m = (ma, mr, mf)`` of the actuator's capacity
(dimensionless, each in [0, 1]) and the control is the target load ``TL`` in [0, 1]:

    C(ma, mr, TL) = LD * (TL - ma)   if ma <  TL and mr >= TL - ma
                  = LD * mr          if ma <  TL and mr <  TL - ma
                  = LR * (TL - ma)   if ma >= TL
    dma/dt = C - F * ma
    dmr/dt = -C + R' * mf
    dmf/dt = F * ma - R' * mf + S * (1 - ma - mr - mf)

with ``R' = r * R`` while ``ma >= TL`` and ``TL <= rest_load``, and ``R' = R`` otherwise
(``r = 1`` is Xia's model; ``r != 1`` is the rest-recovery variant 3CC-r of Looft et al. 2018).
``rest_load`` is an option of the model, not a parameter of the vector ``p``: its default 1
applies ``r`` on the whole relaxation branch ``ma >= TL`` (as this package always did);
``rest_load = 0`` applies it only at rest, ``TL = 0``, as Rakshit et al. (2021, Eq. 7) do
(MyoSuite counts ``TL <= 0.01`` as rest). ``S = 0`` is Xia's 3CC; ``S > 0`` is the stabilised
3CC-S. The exact model satisfies ``d(ma + mr + mf)/dt = S * (1 - ma - mr - mf)``, so an error in
the sum decays like ``exp(-S t)``; the rest multiplier is applied to both ``dmr`` and ``dmf`` so
that 3CC-r keeps this property (the paper writes ``r`` in ``dmr`` only, which would break the
invariant for ``r != 1``).

The right-hand side exists once, as the SX ``casadi.Function`` returned by :func:`fatigue_rhs`
(exact branches with ``casadi.if_else``, no smoothing). The numeric helpers of
:mod:`fatigue_pin.fatigue.simulation` evaluate that same function. Michaud's model is in
:mod:`fatigue_pin.fatigue.michaud`; the interface both implement in
:mod:`fatigue_pin.fatigue.interface`.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass
from numbers import Real
from typing import ClassVar

import casadi as ca
import numpy as np

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.fatigue.interface import FatigueModel, check_stabiliser
from fatigue_pin.fatigue.michaud import MichaudFatigue
from fatigue_pin.core.text import shown

__all__ = [
    "XiaFatigue",
    "FatigueParams",
    "FATIGUE_MODELS",
    "fatigue_model",
    "model_of_class",
    "STATE_NAMES",
    "PARAM_NAMES",
    "PARAM_UNITS",
    "fatigue_rhs",
]

#: Names of the three fatigue states of one actuator, in state-vector order.
STATE_NAMES: tuple[str, str, str] = ("ma", "mr", "mf")
#: Names of the entries of the parameter vector ``p`` of :func:`fatigue_rhs`, in order.
PARAM_NAMES: tuple[str, ...] = ("LD", "LR", "F", "R", "S", "r")
#: Units of the entries of ``p`` (``r`` is a dimensionless multiplier).
PARAM_UNITS: tuple[str, ...] = ("1/s", "1/s", "1/s", "1/s", "1/s", "1")


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
            ``r`` while ``ma >= TL`` and ``TL <= rest_load``. 1 gives Xia's model.
        rest_load: option (not in the parameter vector): the largest target load at which ``r``
            acts (dimensionless, in [0, 1]). 1 (default): on the whole relaxation branch
            ``ma >= TL``; 0: only at rest, ``TL = 0`` (Rakshit et al. 2021, Eq. 7).

    All parameters must be finite and >= 0 (``LD = 0`` or ``LR = 0`` is accepted: a degenerate
    but well-defined controller that never develops or never relaxes).
    """

    kind: ClassVar[str] = "xia"
    state_names: ClassVar[tuple[str, ...]] = STATE_NAMES
    state_total: ClassVar[float | None] = 1.0
    param_names: ClassVar[tuple[str, ...]] = PARAM_NAMES
    param_units: ClassVar[tuple[str, ...]] = PARAM_UNITS
    option_names: ClassVar[tuple[str, ...]] = ("rest_load",)
    fatigued_state: ClassVar[str] = "mf"

    LD: float
    LR: float
    F: float
    R: float
    S: float = 0.0
    r: float = 1.0
    rest_load: float = 1.0

    def __post_init__(self) -> None:
        super().__post_init__()
        x = self.rest_load
        if isinstance(x, bool) or not isinstance(x, Real) or not math.isfinite(float(x)) or not 0.0 <= float(x) <= 1.0:
            raise ParameterError(f"XiaFatigue.rest_load = {shown(x)}: expected a target load in [0, 1] "
                                 "(1: r acts whenever ma >= TL; 0: only at rest, TL = 0)")
        object.__setattr__(self, "rest_load", float(x))

    def rhs(self) -> ca.Function:
        return fatigue_rhs(self.rest_load)

    @classmethod
    def rest_state(cls) -> np.ndarray:
        return np.array([0.0, 1.0, 0.0])

    def check_step(self, dt: float, method: str = "rk4") -> None:
        check_stabiliser(self, dt, method)


#: The model that the rest of the package calls ``FatigueParams`` (Xia's 3CC / 3CC-S / 3CC-r).
FatigueParams = XiaFatigue

#: Fatigue models by ``kind`` (the ``model`` key of a study file's ``[fatigue]`` table).
FATIGUE_MODELS: dict[str, type[FatigueModel]] = {"xia": XiaFatigue, "michaud": MichaudFatigue}


def fatigue_model(kind: str, **params: float) -> FatigueModel:
    """A fatigue model by kind with its parameter values, e.g. ``fatigue_model("xia", LD=10, ...)``.

    Options of the model (Xia's ``rest_load``) are accepted as well.

    Raises:
        ParameterError: unknown kind, unknown or missing parameter names, or bad values.
    """
    if kind not in FATIGUE_MODELS:
        raise ParameterError(f"fatigue model {kind!r} is unknown; expected one of {sorted(FATIGUE_MODELS)}")
    return model_of_class(FATIGUE_MODELS[kind], **params)


def model_of_class(cls: type[FatigueModel], **params: float) -> FatigueModel:
    """A model of class ``cls`` with its parameter values (and options) by name.

    Raises:
        ParameterError: unknown or missing parameter names, or bad values (named by ``cls.kind``).
    """
    kind = cls.kind
    unknown = sorted(set(params) - set(cls.param_names) - set(cls.option_names))
    if unknown:
        raise ParameterError(f"fatigue model {kind!r} has no parameter(s) {unknown}; its parameters are {list(cls.param_names)}")
    try:
        return cls(**params)
    except TypeError as exc:
        fields = [f.name for f in dataclasses.fields(cls) if f.default is dataclasses.MISSING]
        missing = [n for n in fields if n not in params]
        raise ParameterError(f"fatigue model {kind!r} needs parameter(s) {missing}") from exc


@functools.cache
def fatigue_rhs(rest_load: float = 1.0) -> ca.Function:
    """The 3CC-S right-hand side as an SX ``casadi.Function`` (built once per ``rest_load``, then cached).

    Args:
        rest_load: the largest target load at which the rest multiplier ``r`` acts
            (dimensionless, in [0, 1]); ``r`` acts while ``ma >= TL`` and ``TL <= rest_load``.
            For ``rest_load >= 1`` the second condition always holds and is left out, so the
            function is the one of Xia's 3CC-r as this package always wrote it.

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
    if float(rest_load) >= 1.0:
        R_eff = ca.if_else(developing, R, r * R)
    else:
        R_eff = ca.if_else(ca.logic_and(ma >= TL, TL <= float(rest_load)), r * R, R)
    dma = C - F * ma
    dmr = -C + R_eff * mf
    dmf = F * ma - R_eff * mf + S * (1 - ma - mr - mf)
    return ca.Function("fatigue_rhs", [m, TL, p], [ca.vertcat(dma, dmr, dmf)], ["m", "TL", "p"], ["dm"])
