"""Cylinder wrap objects: the shortest path of a muscle segment around a cylinder, analytic.

A :class:`CylinderWrap` is fixed on a link: its centre ``translation`` (m) and its orientation
(body-fixed X-Y-Z Euler angles, rad, as OpenSim's ``xyz_body_rotation``; the cylinder's axis is
its local z) in the link's frame, and its ``radius`` (m). It is infinite along its axis.

:func:`wrapped_length` gives the length of one straight segment ``P -> S`` of a path, with both end
points in the cylinder's frame (docs/muscles.md, "Wrapping"). Projected on the cross-section, if
the straight segment passes closer than the radius to the axis (and both ends are outside the
circle), the path leaves ``P`` along the tangent to the circle on the side the segment passes,
follows the arc, and leaves along the tangent to ``S``; its length in the plane is
``sqrt(|p|^2 - r^2) + r * arc + sqrt(|s|^2 - r^2)``, and unrolled (a helix on the cylinder) the 3-D
length is ``sqrt(L_plane^2 + (S_z - P_z)^2)``. Otherwise it is ``|S - P|``. The length is C1 at the
onset of wrapping (the tangent points meet), so one ``if_else`` per segment switches the cases.

Which side: by default (``turn = "either"``, OpenSim's quadrant ``all``) the side the straight
segment passes. When the segment sweeps through the axis as the joint turns, that side flips and
the moment arm jumps (arm26's triceps over the elbow cylinder does so at 147 deg of flexion). A
muscle's :class:`WrapUse` can fix the side instead: ``positive``, the path goes round
counter-clockwise about the cylinder's +z axis from its earlier point to its later one, or
``negative``; the path then wraps whenever the straight segment would pass the axis on the other
side or closer than the radius, and its length stays C1 through the axis.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca
import numpy as np

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.core.text import shown

__all__ = ["TURNS", "CylinderWrap", "WrapUse", "wrapped_length", "euler_xyz", "triple"]

#: Which way a path goes round a cylinder (:class:`WrapUse`).
TURNS = ("either", "positive", "negative")


def euler_xyz(angles: tuple[float, float, float]) -> np.ndarray:
    """Rotation matrix (3, 3) of body-fixed X-Y-Z Euler angles (rad): ``Rx(a) Ry(b) Rz(c)``."""
    a, b, c = (float(x) for x in angles)
    rx = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
    ry = np.array([[math.cos(b), 0, math.sin(b)], [0, 1, 0], [-math.sin(b), 0, math.cos(b)]])
    rz = np.array([[math.cos(c), -math.sin(c), 0], [math.sin(c), math.cos(c), 0], [0, 0, 1]])
    return rx @ ry @ rz


def triple(value: object, what: str, unit: str = "") -> tuple[float, float, float]:
    """``value`` as three floats; ParameterError ``<what> = <value>: expected three finite
    numbers<unit>`` otherwise (``unit`` e.g. ``" (m)"``)."""
    try:
        a = np.asarray(value, dtype=float).reshape(-1) if not isinstance(value, str) else np.array([])
    except (TypeError, ValueError):
        a = np.array([])
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ParameterError(f"{what} = {shown(value)}: expected three finite numbers{unit}")
    return (float(a[0]), float(a[1]), float(a[2]))


@dataclass(frozen=True)
class CylinderWrap:
    """A wrap cylinder on a link (see the module docstring).

    Attributes:
        name: its name, as muscles refer to it.
        frame: the link (a frame of the model) it is fixed on.
        translation: its centre in the link's frame (m), shape (3,).
        rotation: body-fixed X-Y-Z Euler angles of its frame in the link's frame (rad), shape (3,).
        radius: m, > 0.
    """

    name: str
    frame: str
    translation: tuple[float, float, float]
    rotation: tuple[float, float, float]
    radius: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "translation", triple(self.translation, f"wrap {self.name!r} translation"))
        object.__setattr__(self, "rotation", triple(self.rotation, f"wrap {self.name!r} rotation"))
        r = self.radius
        if isinstance(r, bool) or not isinstance(r, (int, float, np.floating, np.integer)) or not math.isfinite(r) or r <= 0:
            raise ParameterError(f"wrap {self.name!r} radius = {shown(r)}: expected a cylinder radius > 0 (m)")
        object.__setattr__(self, "radius", float(r))

    def matrix(self) -> np.ndarray:
        """Orientation of the cylinder's frame in the link's frame, (3, 3) (columns: its axes)."""
        return euler_xyz(self.rotation)

    def to_cylinder(self, point_in_link: ca.SX | np.ndarray) -> ca.SX | np.ndarray:
        """A point given in the link's frame (3,) expressed in the cylinder's frame (m)."""
        R, c = self.matrix(), np.asarray(self.translation)
        if isinstance(point_in_link, (ca.SX, ca.MX, ca.DM)):
            return ca.mtimes(ca.DM(R.T), point_in_link - ca.DM(c))
        return R.T @ (np.asarray(point_in_link, dtype=float) - c)


@dataclass(frozen=True)
class WrapUse:
    """A muscle's use of a wrap cylinder.

    Attributes:
        name: the cylinder's name.
        turn: one of :data:`TURNS` (module docstring).
    """

    name: str
    turn: str = "either"

    def __post_init__(self) -> None:
        if self.turn not in TURNS:
            raise ParameterError(f"wrap {self.name!r} turn = {shown(self.turn)}: expected one of {list(TURNS)}")


class _NUMPY:
    """The operations of :func:`wrapped_length` on numpy numbers (verify evaluates paths on numbers)."""

    fmax, sqrt, atan2, floor, acos = np.fmax, np.sqrt, np.arctan2, np.floor, np.arccos
    logic_and = np.logical_and

    @staticmethod
    def if_else(c, a, b):
        return float(np.where(c, a, b))


def wrapped_length(P: ca.SX, S: ca.SX, radius: float, turn: str = "either") -> ca.SX:
    """Length (m) of the shortest path from ``P`` to ``S`` (each (3,), in the cylinder's frame, axis
    z) that does not enter the cylinder of ``radius``, going round it as ``turn`` says (see the
    module docstring). CasADi SX, MX or DM in, the same kind out; numpy arrays in, a float out."""
    x = ca if isinstance(P, (ca.SX, ca.MX, ca.DM)) or isinstance(S, (ca.SX, ca.MX, ca.DM)) else _NUMPY
    r = float(radius)
    px, py, pz, sx, sy, sz = P[0], P[1], P[2], S[0], S[1], S[2]
    dx, dy = sx - px, sy - py
    d2 = dx * dx + dy * dy
    cross = px * sy - py * sx
    t = -(px * dx + py * dy) / x.fmax(d2, 1e-30)  # where the closest point of the line is
    dp2, ds2 = px * px + py * py, sx * sx + sy * sy
    if turn == "either":
        sigma = x.if_else(cross >= 0, 1, -1)  # the side the segment passes (either way through the axis)
        near = cross * cross < r * r * d2
    else:
        sigma = 1 if turn == "positive" else -1
        near = sigma * cross < r * x.sqrt(d2)  # on the other side, or closer than r on this one
    wraps = x.logic_and(x.logic_and(t > 0, t < 1), x.logic_and(near, x.logic_and(dp2 > r * r, ds2 > r * r)))
    # the wrapped length, with guarded arguments (its branch is evaluated either way)
    dp, ds = x.sqrt(x.fmax(dp2, r * r * (1 + 1e-12))), x.sqrt(x.fmax(ds2, r * r * (1 + 1e-12)))
    tangents = x.sqrt(dp * dp - r * r) + x.sqrt(ds * ds - r * r)
    swept = sigma * (x.atan2(sy, sx) - x.atan2(py, px))
    swept = swept - 2 * math.pi * x.floor(swept / (2 * math.pi))  # in [0, 2 pi)
    arc = swept - x.acos(r / dp) - x.acos(r / ds)
    plane = tangents + r * arc
    dz = sz - pz
    wrapped = x.sqrt(plane * plane + dz * dz)
    straight = x.sqrt(d2 + dz * dz)
    return x.if_else(wraps, wrapped, straight)
