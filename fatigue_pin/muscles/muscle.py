"""One muscle-tendon unit: its parameters, its path on the links, and its force.

A :class:`Muscle` is a Hill-type unit with a rigid tendon (docs/muscles.md, "Force"):

* ``kind = "degroote"``: the De Groote-Fregly 2016 curves (:mod:`fatigue_pin.muscles.curves`).
  With the fibre width ``w = l_opt sin(alpha_0)`` kept constant, the fibre length is
  ``l_M = sqrt((L - l_slack)^2 + w^2)``, ``cos(alpha) = (L - l_slack) / l_M``, the fibre velocity
  ``v_M = Ldot cos(alpha)``, and the force along the tendon
  ``F = F_max (a f_L(l_M / l_opt) f_V(v_M / (v_max l_opt)) + f_PE(l_M / l_opt) + beta v) cos(alpha)``;
* ``kind = "idealized"``: ``F = a F_max`` (no force-length, force-velocity or passive force).

``L`` is the muscle-tendon length (m) and ``Ldot`` its lengthening speed (m/s), from
:class:`~fatigue_pin.muscles.paths.MuscleGeometry`; ``a`` the activation in [0, 1].
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import casadi as ca
import numpy as np

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.core.text import shown
from fatigue_pin.muscles import curves
from fatigue_pin.muscles.wraps import WrapUse, triple

__all__ = ["MUSCLE_KINDS", "PathPoint", "Muscle"]

#: The force models of a muscle (module docstring).
MUSCLE_KINDS = ("degroote", "idealized")


@dataclass(frozen=True)
class PathPoint:
    """A point of a muscle's path, fixed on a link.

    Attributes:
        frame: the link (a frame of the model).
        location: the point in the link's frame (m), shape (3,).
    """

    frame: str
    location: tuple[float, float, float]

    def __post_init__(self) -> None:
        object.__setattr__(self, "location", triple(self.location, f"path point on {self.frame!r}: location", " (m)"))


def _positive(muscle: str, name: str, value: Any, unit: str, what: str, allow_zero: bool = False) -> float:
    ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool) and math.isfinite(value)
    if not ok or value < 0 or (value == 0 and not allow_zero):
        bound = ">= 0" if allow_zero else "> 0"
        raise ParameterError(f"muscle {muscle!r}: {name} = {shown(value)}: expected {what} {bound} ({unit})")
    return float(value)


@dataclass(frozen=True)
class Muscle:
    """A muscle-tendon unit (see the module docstring).

    Attributes:
        name: its name (letters, digits, ``_``, ``-``).
        points: its path, origin first, insertion last (at least two points).
        max_force: maximal isometric force F_max (N), > 0.
        optimal_length: optimal fibre length l_opt (m), > 0.
        tendon_slack_length: l_slack (m), >= 0.
        pennation: pennation angle at the optimal length alpha_0 (rad), in [0, pi/2).
        max_velocity: maximal contraction velocity v_max (optimal lengths per second), > 0.
        kind: one of :data:`MUSCLE_KINDS`.
        wraps: the wrap cylinders the path may go round (:class:`~fatigue_pin.muscles.wraps.WrapUse`,
            or a name: either side); every segment is tested against each.
        group: a group name for shared fatigue parameters (default: none).
        passive_strain: fibre strain at which the passive force is F_max (Moco's 0.6).
        damping: fibre damping beta (dimensionless, of F_max per normalised velocity), >= 0.
        activation_time, deactivation_time: time constants of the activation dynamics (s), > 0
            (Moco's 0.015 and 0.060).
        activation_smoothing: ``b`` of the activation dynamics (Moco's 0.1).
    """

    name: str
    points: tuple[PathPoint, ...]
    max_force: float
    optimal_length: float
    tendon_slack_length: float
    pennation: float = 0.0
    max_velocity: float = 10.0
    kind: str = "degroote"
    wraps: tuple[WrapUse, ...] = ()
    group: str = ""
    passive_strain: float = 0.6
    damping: float = 0.0
    activation_time: float = 0.015
    deactivation_time: float = 0.060
    activation_smoothing: float = field(default=0.1)

    def __post_init__(self) -> None:
        n = self.name
        if not isinstance(n, str) or not n or not all(c.isalnum() or c in "_-" for c in n):
            raise ParameterError(f"muscle name {shown(n)}: expected letters, digits, '_' or '-'")
        points = tuple(self.points)
        if len(points) < 2 or not all(isinstance(p, PathPoint) for p in points):
            raise ParameterError(f"muscle {n!r}: {len(points)} path points: expected an origin and an insertion at least")
        object.__setattr__(self, "points", points)
        object.__setattr__(self, "max_force", _positive(n, "max_force", self.max_force, "N", "a force"))
        object.__setattr__(self, "optimal_length", _positive(n, "optimal_length", self.optimal_length, "m", "a fibre length"))
        object.__setattr__(self, "tendon_slack_length",
                           _positive(n, "tendon_slack_length", self.tendon_slack_length, "m", "a length", allow_zero=True))
        object.__setattr__(self, "max_velocity", _positive(n, "max_velocity", self.max_velocity, "optimal lengths/s", "a velocity"))
        pen = _positive(n, "pennation", self.pennation, "rad", "an angle", allow_zero=True)
        if pen >= math.pi / 2:
            raise ParameterError(f"muscle {n!r}: pennation = {shown(self.pennation)}: expected an angle in [0, pi/2) (rad)")
        object.__setattr__(self, "pennation", pen)
        if self.kind not in MUSCLE_KINDS:
            raise ParameterError(f"muscle {n!r}: kind = {shown(self.kind)}: expected one of {list(MUSCLE_KINDS)}")
        uses = tuple(WrapUse(w) if isinstance(w, str) else WrapUse(**w) if isinstance(w, dict) else w for w in self.wraps)
        if not all(isinstance(w, WrapUse) for w in uses):
            raise ParameterError(f"muscle {n!r}: wraps = {shown(self.wraps)}: expected wrap names or {{ name = ..., turn = ... }} tables")
        object.__setattr__(self, "wraps", uses)
        object.__setattr__(self, "passive_strain", _positive(n, "passive_strain", self.passive_strain, "-", "a strain"))
        object.__setattr__(self, "damping", _positive(n, "damping", self.damping, "-", "a damping", allow_zero=True))
        for key in ("activation_time", "deactivation_time"):
            object.__setattr__(self, key, _positive(n, key, getattr(self, key), "s", "a time constant"))
        object.__setattr__(self, "activation_smoothing",
                           _positive(n, "activation_smoothing", self.activation_smoothing, "-", "a smoothing"))

    @property
    def frames(self) -> tuple[str, ...]:
        """The links its points are on, in path order, without repeats."""
        return tuple(dict.fromkeys(p.frame for p in self.points))

    def fibre(self, L: Any, Ldot: Any) -> tuple[Any, Any, Any]:
        """``(normalised fibre length, normalised fibre velocity, cos(alpha))`` at muscle-tendon
        length ``L`` (m) and lengthening speed ``Ldot`` (m/s) (rigid tendon)."""
        sqrt = ca.sqrt if isinstance(L, (ca.SX, ca.MX, ca.DM)) else np.sqrt
        along = L - self.tendon_slack_length
        width = self.optimal_length * math.sin(self.pennation)
        l_m = sqrt(along * along + width * width)
        cos = along / l_m
        return l_m / self.optimal_length, Ldot * cos / (self.max_velocity * self.optimal_length), cos

    def force(self, a: Any, L: Any, Ldot: Any) -> Any:
        """Tendon force (N) at activation ``a``, length ``L`` (m) and lengthening speed ``Ldot``
        (m/s); floats, numpy arrays or CasADi expressions (elementwise)."""
        if self.kind == "idealized":
            return a * self.max_force
        l, v, cos = self.fibre(L, Ldot)
        active = a * curves.active_force_length(l) * curves.force_velocity(v)
        return self.max_force * (active + curves.passive_force_length(l, self.passive_strain) + self.damping * v) * cos

    def activation_rate(self, e: Any, a: Any) -> Any:
        """``da/dt`` (1/s) under excitation ``e`` (:func:`~fatigue_pin.muscles.curves.activation_rate`)."""
        return curves.activation_rate(e, a, self.activation_time, self.deactivation_time, self.activation_smoothing)
