"""Michaud's fatigue model: Xia's three compartments plus an effort-perception state, as bioptim
implements it (:class:`MichaudFatigue`, equations in :func:`michaud_rhs`)."""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import ClassVar

import casadi as ca
import numpy as np

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.fatigue.interface import FatigueModel, check_stabiliser
from fatigue_pin.core.text import shown

__all__ = ["MichaudFatigue", "michaud_rhs", "MICHAUD_SOURCE"]

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
                f"MichaudFatigue.effort_threshold = {shown(th)}: expected a target load strictly between 0 and 1 "
                "(the effort rate divides by th and by 1 - th)"
            )

    def rhs(self) -> ca.Function:
        return michaud_rhs()

    @classmethod
    def rest_state(cls) -> np.ndarray:
        return np.array([0.0, 1.0, 0.0, 0.0])

    def check_step(self, dt: float, method: str = "rk4") -> None:
        """The sum error decays like ``exp(-S t)`` (``S = stabilization_factor``); checked as Xia's S."""
        check_stabiliser(self.stabilization_factor, dt, method)
