"""OpenSim models in: an ``.osim`` file read as a URDF text and a muscle file text.

:func:`read_osim` parses the XML of an OpenSim model (format 4.x, ``OpenSimDocument Version``
>= 40000 with ``<ground>``, sockets and ``PhysicalOffsetFrame``; or 3.x, below) with the standard library and
writes the model in the project's two forms, which everything downstream already reads:

* a URDF text (:func:`~fatigue_pin.robot.model.load_model`): the root link ``world`` (z up), a
  fixed joint that turns OpenSim's y-up ``ground`` by Rx(+pi/2) (the bundled arm26's convention),
  one link per body with its mass, centre of mass and inertia, and for every OpenSim joint a chain
  of URDF joints: the parent offset frame as the origin of the first, one revolute (rotation) or
  prismatic (translation) URDF joint per coordinate, named as the coordinate, with the
  coordinate's range as position limits, and a fixed joint to the body when the child offset frame
  is not the body's frame. The model's ``<gravity>``, turned into the world frame, is written as a
  top-level ``<gravity xyz="..."/>`` element that :func:`~fatigue_pin.robot.model.load_model` reads;
* a muscle file text (docs/muscles.md): every ``Thelen2003Muscle``,
  ``Millard2012EquilibriumMuscle`` and ``DeGrooteFregly2016Muscle`` with its maximal isometric
  force, optimal fibre length, tendon slack length, pennation at the optimal length, maximal
  contraction velocity, activation time constants and passive strain (onto the De Groote-Fregly
  curves with a rigid tendon, ``kind = "degroote"``), its path points on the links, and the
  ``WrapCylinder`` objects its path wraps round (quadrant ``all``: ``turn = "either"``).

The 3.x format (``Version`` 30000: the ground a body of the ``BodySet``, each joint inside its child
body with ``parent_body``, ``location_in_parent``, ``orientation_in_parent``, ``location``,
``orientation``, path points on a ``<body>``) is read the same way.

What is read (and what is refused with one :class:`~fatigue_pin.core.errors.ModelError` line naming
the element, its name and the file):

* joints: ``WeldJoint``, ``PinJoint`` (about the z axis of its frames), ``SliderJoint`` (along x) and
  ``CustomJoint`` whose every transform axis is either driven by one coordinate through the identity
  (``LinearFunction`` with coefficients ``1 0``, or a spline/piecewise-linear function whose points
  all lie on y = x) or constant 0, each coordinate driving one axis. The rotations of a
  ``CustomJoint`` are a body-fixed sequence (rotation1, then rotation2, then rotation3 about the
  turned axes), its translations are along the parent frame's axes, before the rotations. Refused:
  any other joint kind (``BallJoint``, ``FreeJoint``, ``UniversalJoint``, ``GimbalJoint``,
  ``EllipsoidJoint``, ``PlanarJoint``, ...), a coordinate that drives two axes or an axis driven by
  two coordinates (coupled), a non-identity function, a constant axis other than 0, any enforced
  constraint (``CoordinateCouplerConstraint``, ...), a body that no joint holds (it would float);
* coordinates: a ``locked`` coordinate is held at its ``default_value`` (its URDF joint is fixed,
  the motion at that value folded into the origin); clamped or not, the range is the joint's
  position bounds (the optimal control problems bound every joint by its range);
* muscles: refused are another force class, a ``MovingPathPoint`` or ``ConditionalPathPoint``, a
  point on a frame that is no body, a max force or an optimal length <= 0, a muscle whose points
  all move together (it crosses no joint);
* wraps: ``WrapCylinder`` of radius > 0, quadrant ``all``, over the whole path (``range -1 -1``);
  an inactive wrap object is left out. A ``WrapEllipsoid``, ``WrapSphere``, ``WrapTorus``, a cylinder
  of another quadrant or a restricted range is refused, unless ``ignore_wraps`` says to leave it out
  of the paths (``True``: every wrap that cannot be modelled; a list: those named). A wrap cylinder
  of radius <= 0 is refused in any case. The cylinder is taken as infinite (its ``length`` is not
  read) and the wrapping method (``hybrid``, ``midpoint``, ``axial``) is the project's analytic
  shortest path.

The torque or force limit of each joint is ``effort`` (an OpenSim coordinate has none); the
velocity limit is 10 pi (rad/s or m/s).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable

import numpy as np

from fatigue_pin.core.errors import ModelError
from fatigue_pin.robot.osim_xml import Frame, Reader, euler_xyz, flag, fmt, is_identity, objects, rot, text, urdf_joint, vec

__all__ = ["OsimModel", "read_osim", "MUSCLE_CLASSES", "JOINT_CLASSES"]

#: The OpenSim muscle classes whose parameters map onto the project's muscles.
MUSCLE_CLASSES = ("Thelen2003Muscle", "Millard2012EquilibriumMuscle", "DeGrooteFregly2016Muscle")
#: The OpenSim joint classes read.
JOINT_CLASSES = ("WeldJoint", "PinJoint", "SliderJoint", "CustomJoint")
_WRAP_CLASSES = ("WrapCylinder", "WrapEllipsoid", "WrapSphere", "WrapTorus", "WrapDoubleCylinderObst", "WrapCylinderObst")
_SPLINES = ("SimmSpline", "NaturalCubicSpline", "GCVSpline", "PiecewiseLinearFunction", "PiecewiseConstantFunction")
_FUNCTIONS = ("LinearFunction", "Constant", "PolynomialFunction", "MultiplierFunction", "SineFunction", "StepFunction",
              "LinearFunction") + _SPLINES
_AXES = ("rotation1", "rotation2", "rotation3", "translation1", "translation2", "translation3")


@dataclass(frozen=True)
class OsimModel:
    """An OpenSim model in the project's forms (module docstring).

    Attributes:
        path: the ``.osim`` file.
        name: the model's name (``<Model name=...>``).
        urdf: the URDF text of its skeleton (with a top-level ``<gravity xyz>``).
        muscles: the muscle file text (TOML) of its muscles and wrap cylinders; "" without muscles.
        gravity: gravity in the URDF's world frame (z up), m/s^2, shape (3,).
        dropped_wraps: the wrap objects left out of the paths (``ignore_wraps``), by name.
    """

    path: Path
    name: str
    urdf: str = field(repr=False)
    muscles: str = field(repr=False)
    gravity: tuple[float, float, float]
    dropped_wraps: tuple[str, ...] = ()


@dataclass
class _Axis:
    """One URDF joint of an OpenSim joint's chain."""

    name: str
    kind: str  # "revolute" or "prismatic"
    axis: np.ndarray
    lower: float
    upper: float
    locked: bool
    value: float  # the locked value


# -- the reader -----------------------------------------------------------------------------------


class _Osim:
    """One ``.osim`` file, parsed: its bodies, frames and gravity; :meth:`urdf` and :meth:`muscles`
    write the project's two forms (module docstring)."""

    def __init__(self, path: Path, ignore_wraps: bool | Iterable[str], effort: float) -> None:
        self.r = Reader(path)
        self.path = path
        self.effort = float(effort)
        self.ignore = ignore_wraps if isinstance(ignore_wraps, bool) else frozenset(ignore_wraps)
        try:
            root = ET.parse(path).getroot()
        except ET.ParseError as exc:
            raise ModelError(f"OpenSim model {str(path)!r} does not parse: {exc}") from None
        except OSError as exc:
            raise ModelError(f"OpenSim model {str(path)!r} cannot be read ({exc.strerror}); expected a readable .osim file") from None
        model = root if root.tag == "Model" else root.find("Model")
        if model is None:
            raise self.r.error(f"the root element is <{root.tag}> without a <Model>; expected <OpenSimDocument><Model>")
        self.model = model
        self.name = model.get("name") or path.stem
        version = root.get("Version", "40000")
        try:
            v = int(version)
        except ValueError:
            v = 40000
        ground = model.find("ground")
        listed = objects(model, "BodySet")
        # the 3.x format (30000): the ground is the body "ground" of the BodySet, each joint inside its child body
        self.legacy = ground is None and 30000 <= v < 40000 and any(b.get("name") == "ground" for b in listed)
        if ground is None and not self.legacy:
            raise self.r.error(f"file format {version} without a <ground>: expected an OpenSim 4.x model (Version >= 40000) or a "
                               "3.x one (30000, a body 'ground'); re-save it with OpenSim 4")
        self.ground = "ground" if self.legacy else ground.get("name") or "ground"
        self.bodies: dict[str, ET.Element] = {} if self.legacy else {self.ground: ground}
        for body in listed:
            if body.tag != "Body":
                raise self.r.error(f"<{body.tag} name={body.get('name')!r}> in the BodySet: expected <Body> elements")
            self.bodies[body.get("name")] = body
        self.frames: dict[str, Frame] = {b: Frame(b, np.eye(3), np.zeros(3)) for b in self.bodies}
        # offset frames by the joint or body that holds them, and by name (a name two of them share is ambiguous)
        self._scopes: dict[str, dict[str, ET.Element]] = {}
        for owner in [*objects(model, "JointSet"), *self.bodies.values()]:
            self._scopes.setdefault(owner.get("name"), {}).update(
                {f.get("name"): f for f in owner.iter("PhysicalOffsetFrame")})
        self._offsets: dict[str, list[ET.Element]] = {}
        for element in model.iter("PhysicalOffsetFrame"):
            self._offsets.setdefault(element.get("name"), []).append(element)
        gravity = self.r.numbers(model, "gravity", 3, "<Model>", default=(0.0, -9.80665, 0.0))
        self.gravity = tuple(float(x) for x in self.to_world(gravity))

    @staticmethod
    def to_world(v: np.ndarray) -> np.ndarray:
        """A vector of OpenSim's ground (y up) in the URDF's world (z up): Rx(+pi/2)."""
        return np.array([v[0], -v[2], v[1]]) + 0.0  # + 0.0: no -0.0

    # -- frames ------------------------------------------------------------------------------------

    def frame(self, reference: str, owner: str, local: dict[str, ET.Element] | None = None, depth: int = 0) -> Frame:
        """The frame a socket names: a body (``/bodyset/r_humerus``, ``/ground``), an offset frame
        of the joint at hand (``r_humerus_offset``) or one by its path (``/jointset/r_elbow/r_humerus_offset``)."""
        parts = [p for p in reference.strip().split("/") if p not in ("", ".", "..")]
        name = parts[-1] if parts else ""
        scope = self._scopes.get(parts[-2], {}) if len(parts) >= 2 else {}
        if name in scope:
            element = scope[name]
            local = scope
        elif name in (local or {}):
            element = local[name]
        elif name in self.bodies:
            return self.frames[name]
        elif len(self._offsets.get(name, [])) == 1:
            element = self._offsets[name][0]
        elif name in self._offsets:
            raise self.r.error(f"{owner} refers to frame {reference!r}, a name several offset frames have; expected its path "
                               "(/jointset/<joint>/<frame> or /bodyset/<body>/<frame>)")
        else:
            raise self.r.error(f"{owner} refers to frame {reference!r}, which is no body or offset frame of the model; "
                               f"its bodies are {list(self.bodies)}")
        if depth > 20:
            raise self.r.error(f"{owner}: offset frame {name!r} is offset from itself")
        parent = self.frame(text(element, "socket_parent"), f"offset frame {name!r}", local, depth + 1)
        R = euler_xyz(self.r.numbers(element, "orientation", 3, f"offset frame {name!r}", (0, 0, 0)))
        p = self.r.numbers(element, "translation", 3, f"offset frame {name!r}", (0, 0, 0))
        return Frame(parent.body, parent.R @ R, parent.R @ p + parent.p)

    # -- joints ------------------------------------------------------------------------------------

    def check_constraints(self) -> None:
        for c in objects(self.model, "ConstraintSet"):
            enforced = flag(c, "isEnforced", True) and not flag(c, "isDisabled", False)
            if enforced:
                raise self.r.error(f"{c.tag} {c.get('name')!r} constrains the coordinates; fatigue_pin reads models whose "
                                   "coordinates are independent (expected no enforced constraint)")

    def coordinates(self, joint: ET.Element, owner: str) -> dict[str, ET.Element]:
        holder = joint.find("coordinates") if joint.find("coordinates") is not None else joint.find("CoordinateSet")
        coords = list(holder) if holder is not None else []
        if holder is not None and holder.find("objects") is not None:
            coords = list(holder.find("objects"))
        return {c.get("name"): c for c in coords if c.tag == "Coordinate"}

    def axis_of(self, coord: ET.Element, name: str, kind: str, axis: np.ndarray, owner: str) -> _Axis:
        norm = float(np.linalg.norm(axis))
        if norm == 0:
            raise self.r.error(f"{owner}: coordinate {name!r} has the axis (0, 0, 0); expected a non-zero axis")
        lo, hi = self.r.numbers(coord, "range", 2, f"coordinate {name!r}", (-math.pi, math.pi) if kind == "revolute" else (-1, 1))
        if lo > hi:
            raise self.r.error(f"coordinate {name!r}: range {lo:g} {hi:g}; expected the lower bound first")
        value = self.r.number(coord, "default_value", f"coordinate {name!r}", 0.0)
        return _Axis(name, kind, axis / norm, float(lo), float(hi), flag(coord, "locked", False), value)

    def custom_axes(self, joint: ET.Element, coords: dict[str, ET.Element], owner: str) -> list[_Axis]:
        spatial = joint.find("SpatialTransform")
        if spatial is None:
            raise self.r.error(f"{owner} has no <SpatialTransform>")
        used: dict[str, str] = {}
        rotations, translations = [], []
        for transform in spatial.findall("TransformAxis"):
            axis_name = transform.get("name", "")
            where = f"{owner}, transform axis {axis_name!r}"
            names = text(transform, "coordinates").split()
            function = self.function(transform)
            if len(names) > 1:
                raise self.r.error(f"{where} is driven by the coordinates {names} together (coupled); expected one coordinate per axis")
            if not names:
                if function is not None and not self.is_zero(function):
                    raise self.r.error(f"{where}: a constant {function.tag} other than 0 (or a function of no coordinate); "
                                       "expected the unused axes of a CustomJoint constant 0")
                continue
            name = names[0]
            if name not in coords:
                raise self.r.error(f"{where} is driven by coordinate {name!r}, which is not a coordinate of the joint")
            if name in used:
                raise self.r.error(f"{owner}: coordinate {name!r} drives both {used[name]!r} and {axis_name!r} (coupled); "
                                   "expected each coordinate to drive one axis")
            used[name] = axis_name
            if function is None or not self.is_identity(function):
                kind = "no function" if function is None else function.tag
                raise self.r.error(f"{where}: coordinate {name!r} drives it through {kind}, not the identity; expected "
                                   "LinearFunction 1 0 (the axis turns or moves by the coordinate's value)")
            axis = self.r.numbers(transform, "axis", 3, where)
            kind = "revolute" if axis_name.startswith("rotation") else "prismatic"
            (rotations if kind == "revolute" else translations).append(self.axis_of(coords[name], name, kind, axis, where))
        unused = [c for c in coords if c not in used]
        if unused:
            raise self.r.error(f"{owner}: coordinate {unused[0]!r} drives no transform axis; expected each coordinate to drive one")
        return translations + rotations  # translations along the parent's axes first, then the body-fixed rotations

    def function(self, transform: ET.Element) -> ET.Element | None:
        holder = transform.find("function")
        candidates = list(holder) if holder is not None else [c for c in transform if c.tag in _FUNCTIONS or c.get("name") == "function"]
        return candidates[0] if candidates else None

    def is_zero(self, function: ET.Element) -> bool:
        if function.tag == "Constant":
            return abs(self.r.number(function, "value", "a Constant", 0.0)) == 0.0
        return False

    def is_identity(self, function: ET.Element) -> bool:
        if function.tag == "LinearFunction":
            slope, intercept = self.r.numbers(function, "coefficients", 2, "a LinearFunction")
            return slope == 1.0 and intercept == 0.0
        if function.tag in _SPLINES:
            x = self.r.numbers(function, "x", len(text(function, "x").split()), "a spline")
            y = self.r.numbers(function, "y", len(text(function, "y").split()), "a spline")
            return x.size >= 2 and x.size == y.size and bool(np.all(np.abs(x - y) <= 1e-12 * np.maximum(1, np.abs(x))))
        return False

    def joint_frames(self) -> list[tuple[ET.Element, Frame, Frame]]:
        """Every joint with its parent and child frames: from its sockets (4.x), or from
        ``parent_body``, ``location_in_parent``, ``orientation_in_parent``, ``location`` and
        ``orientation`` inside its child body (3.x)."""
        out = []
        joints = [(j, None) for j in objects(self.model, "JointSet")]
        if self.legacy:
            joints = [(j, body) for body, element in self.bodies.items() for holder in element.findall("Joint") for j in holder]
        for joint, body in joints:
            owner = f"{joint.tag} {joint.get('name')!r}"
            if joint.tag not in JOINT_CLASSES:
                raise self.r.error(f"{owner} is of a joint kind fatigue_pin does not read; expected one of {list(JOINT_CLASSES)}")
            if body is None:
                local = {f.get("name"): f for f in joint.iter("PhysicalOffsetFrame")}
                parent = self.frame(text(joint, "socket_parent_frame"), f"{owner} (socket_parent_frame)", local)
                child = self.frame(text(joint, "socket_child_frame"), f"{owner} (socket_child_frame)", local)
            else:
                parent_body = text(joint, "parent_body")
                if parent_body not in self.bodies:
                    raise self.r.error(f"{owner} has parent_body {parent_body!r}, which is no body of the model; its bodies are "
                                       f"{list(self.bodies)}")
                parent = Frame(parent_body, euler_xyz(self.r.numbers(joint, "orientation_in_parent", 3, owner, (0, 0, 0))),
                                self.r.numbers(joint, "location_in_parent", 3, owner, (0, 0, 0)))
                child = Frame(body, euler_xyz(self.r.numbers(joint, "orientation", 3, owner, (0, 0, 0))),
                               self.r.numbers(joint, "location", 3, owner, (0, 0, 0)))
            out.append((joint, parent, child))
        return out

    def joints(self) -> list[tuple[ET.Element, Frame, Frame, list[_Axis]]]:
        out = []
        children: dict[str, str] = {}
        for joint, parent, child in self.joint_frames():
            name = joint.get("name")
            owner = f"{joint.tag} {name!r}"
            if child.body == self.ground:
                raise self.r.error(f"{owner} has the ground as its child; expected the ground as a parent only")
            if child.body in children:
                raise self.r.error(f"{owner} joins body {child.body!r}, which joint {children[child.body]!r} joins already (a loop)")
            children[child.body] = name
            coords = self.coordinates(joint, owner)
            if joint.tag == "WeldJoint":
                if coords:
                    raise self.r.error(f"{owner} has coordinates; expected none for a weld")
                axes = []
            elif joint.tag in ("PinJoint", "SliderJoint"):
                if len(coords) != 1:
                    raise self.r.error(f"{owner} has {len(coords)} coordinates; expected 1")
                (cname, coord), = coords.items()
                kind, axis = ("revolute", np.array([0.0, 0, 1])) if joint.tag == "PinJoint" else ("prismatic", np.array([1.0, 0, 0]))
                axes = [self.axis_of(coord, cname, kind, axis, owner)]
            else:
                axes = self.custom_axes(joint, coords, owner)
            out.append((joint, parent, child, axes))
        floating = [b for b in self.bodies if b != self.ground and b not in children]
        if floating:
            raise self.r.error(f"body {floating[0]!r} is held by no joint (it would float); fatigue_pin reads fixed-base models "
                               "(expected every body joined to the ground through joints)")
        return out

    # -- the URDF ------------------------------------------------------------------------------------

    def urdf(self) -> tuple[str, dict[str, str]]:
        """The URDF text and, for every body, the body whose frame moves it with no joint between
        (itself, or the nearest parent it is welded or locked to)."""
        self.check_constraints()
        joints = self.joints()
        g = self.gravity
        lines = ['<?xml version="1.0"?>',
                 f"<!-- {self.name}: written by fatigue_pin from the OpenSim model {self.path.name} "
                 "(fatigue_pin.robot.osim); OpenSim's ground (y up) turned by Rx(+pi/2) into the world (z up). -->",
                 f'<robot name="{self.name}">',
                 f'  <gravity xyz="{vec(g)}"/>',
                 '  <link name="world"/>',
                 f'  <joint name="world_to_{self.ground}" type="fixed">',
                 '    <parent link="world"/>',
                 f'    <child link="{self.ground}"/>',
                 '    <origin xyz="0 0 0" rpy="1.5707963267948966 0 0"/>',
                 "  </joint>"]
        for body, element in self.bodies.items():
            lines += self.link(body, element)
        moved_by = {self.ground: self.ground}
        parent_of = {}
        for joint, parent, child, axes in joints:
            parent_of[child.body] = (parent.body, any(not a.locked for a in axes))
            lines += self.chain(joint, parent, child, axes)
        for body in self.bodies:  # the nearest body joined by a moving joint (for muscles that cross none)
            b, seen = body, 0
            while b != self.ground and not parent_of[b][1] and seen < len(self.bodies):
                b, seen = parent_of[b][0], seen + 1
            moved_by[body] = b
        lines.append("</robot>")
        return "\n".join(lines) + "\n", moved_by

    def link(self, body: str, element: ET.Element) -> list[str]:
        if body == self.ground:
            return [f'  <link name="{body}"/>']
        owner = f"body {body!r}"
        mass = self.r.number(element, "mass", owner)
        if mass < 0:
            raise self.r.error(f"{owner} has mass {mass:g}; expected a mass >= 0 (kg)")
        com = self.r.numbers(element, "mass_center", 3, owner, (0, 0, 0))
        if element.find("inertia") is None and element.find("inertia_xx") is not None:  # 3.x: one element per entry
            ixx, iyy, izz, ixy, ixz, iyz = (self.r.number(element, f"inertia_{k}", owner, 0.0) for k in ("xx", "yy", "zz", "xy", "xz", "yz"))
        else:
            ixx, iyy, izz, ixy, ixz, iyz = self.r.numbers(element, "inertia", 6, owner, (0,) * 6)
        if min(ixx, iyy, izz) < 0:
            raise self.r.error(f"{owner} has inertia {vec([ixx, iyy, izz])} on its diagonal; expected moments >= 0 (kg m^2)")
        if mass == 0 and not any((ixx, iyy, izz, ixy, ixz, iyz)):
            return [f'  <link name="{body}"/>']
        return [f'  <link name="{body}">', "    <inertial>", f'      <origin xyz="{vec(com)}" rpy="0 0 0"/>',
                f'      <mass value="{fmt(mass)}"/>',
                f'      <inertia ixx="{fmt(ixx)}" ixy="{fmt(ixy)}" ixz="{fmt(ixz)}" iyy="{fmt(iyy)}" iyz="{fmt(iyz)}" izz="{fmt(izz)}"/>',
                "    </inertial>", "  </link>"]

    def chain(self, joint: ET.Element, parent: Frame, child: Frame, axes: list[_Axis]) -> list[str]:
        """URDF joints from the parent body to the child body: origin at the parent offset frame,
        one joint per axis (massless links between), then the child offset frame's inverse."""
        name = joint.get("name")
        lines: list[str] = []
        link, R, p = parent.body, parent.R, parent.p  # the placement still to put in the next origin
        steps = list(axes)
        for k, a in enumerate(steps):
            last = k == len(steps) - 1 and is_identity(child)
            target = child.body if last else f"{name}_{a.name}_link"
            if a.locked:  # the motion at the held value folded into the placement
                M = rot(a.axis, a.value) if a.kind == "revolute" else np.eye(3)
                t = a.axis * a.value if a.kind == "prismatic" else np.zeros(3)
                R, p = R @ M, R @ t + p
                if not last:
                    continue
                lines += urdf_joint(f"{name}_{a.name}_locked", "fixed", link, target, R, p)
            else:
                lines += urdf_joint(a.name, a.kind, link, target, R, p, a.axis, (a.lower, a.upper, self.effort))
                R, p = np.eye(3), np.zeros(3)
            link = target
            if not last:
                lines.append(f'  <link name="{target}"/>')
        if not steps or not (is_identity(child) and link == child.body):
            Ri = child.R.T  # the child body's frame from the child offset frame
            pi = -Ri @ child.p
            kind_name = name if not steps else f"{name}_to_{child.body}"
            lines += urdf_joint(kind_name, "fixed", link, child.body, R @ Ri, R @ pi + p)
        return lines

    # -- muscles -----------------------------------------------------------------------------------

    def wraps(self) -> tuple[dict[str, tuple[str, ET.Element]], list[str]]:
        """Every wrap object by name: (its body, its element); and the names of those left out."""
        out, dropped = {}, []
        for body, element in self.bodies.items():
            for w in objects(element, "WrapObjectSet"):
                name = w.get("name")
                owner = f"{w.tag} {name!r} on body {body!r}"
                if w.tag == "WrapCylinder":
                    radius = self.r.number(w, "radius", owner)
                    if not radius > 0:
                        raise self.r.error(f"{owner} has radius {radius:g}; expected a cylinder radius > 0 (m)")
                if not flag(w, "active", True):
                    dropped.append(name)
                    continue
                out[name] = (body, w)
        return out, dropped

    def ignored(self, name: str) -> bool:
        return self.ignore is True or (not isinstance(self.ignore, bool) and name in self.ignore)

    def muscles(self, moved_by: dict[str, str]) -> tuple[str, tuple[str, ...]]:
        wraps, inactive = self.wraps()
        self.inactive = frozenset(inactive)
        if not isinstance(self.ignore, bool):
            unknown = sorted(set(self.ignore) - set(wraps) - set(inactive))
            if unknown:
                raise self.r.error(f"ignore_wraps names {unknown[0]!r}, which is no wrap object of the model; "
                                   f"its wrap objects are {sorted(wraps)}")
        used_wraps: dict[str, str] = {}
        dropped: list[str] = []
        blocks = []
        for force in objects(self.model, "ForceSet"):
            name = force.get("name")
            owner = f"{force.tag} {name!r}"
            if force.tag not in MUSCLE_CLASSES:
                raise self.r.error(f"{owner} is a force fatigue_pin does not read; expected muscles of the classes {list(MUSCLE_CLASSES)}")
            blocks.append(self.muscle(force, owner, wraps, used_wraps, dropped, moved_by))
        if not blocks:
            return "", ()
        head = [f"# The muscles of the OpenSim model {self.path.name}, written by fatigue_pin (fatigue_pin.robot.osim).", ""]
        for wname, body in used_wraps.items():
            w = wraps[wname][1]
            where = f"WrapCylinder {wname!r}"
            head += ["[[wraps]]", f'name = "{wname}"', f'frame = "{body}"',
                     f"translation = [{', '.join(fmt(x) for x in self.r.numbers(w, 'translation', 3, where, (0, 0, 0)))}]",
                     f"rotation = [{', '.join(fmt(x) for x in self.r.numbers(w, 'xyz_body_rotation', 3, where, (0, 0, 0)))}]",
                     f"radius = {fmt(self.r.number(w, 'radius', where))}", ""]
        return "\n".join(head + blocks), tuple(dict.fromkeys(dropped))

    def muscle(self, force: ET.Element, owner: str, wraps: dict, used_wraps: dict, dropped: list, moved_by: dict[str, str]) -> str:
        name = force.get("name")
        values = {}
        for key, tag in (("max_force", "max_isometric_force"), ("optimal_length", "optimal_fiber_length")):
            v = self.r.number(force, tag, owner)
            if not v > 0:
                raise self.r.error(f"{owner} has {tag} {v:g}; expected {'a force > 0 (N)' if key == 'max_force' else 'a length > 0 (m)'}")
            values[key] = v
        values["tendon_slack_length"] = self.r.number(force, "tendon_slack_length", owner)
        values["pennation"] = self.r.number(force, "pennation_angle_at_optimal", owner, 0.0)
        values["max_velocity"] = self.r.number(force, "max_contraction_velocity", owner, 10.0)
        strain = {"Thelen2003Muscle": "FmaxMuscleStrain", "DeGrooteFregly2016Muscle": "passive_fiber_strain_at_one_norm_force"}
        if force.tag in strain and force.find(strain[force.tag]) is not None:
            values["passive_strain"] = self.r.number(force, strain[force.tag], owner)
        passive = force.find(".//FiberForceLengthCurve")
        if force.tag == "Millard2012EquilibriumMuscle" and passive is not None and passive.find("strain_at_one_norm_force") is not None:
            values["passive_strain"] = self.r.number(passive, "strain_at_one_norm_force", owner)
        for key, tag in (("activation_time", "activation_time_constant"), ("deactivation_time", "deactivation_time_constant"),
                         ("damping", "fiber_damping"), ("activation_smoothing", "activation_dynamics_smoothing")):
            element = force.find(tag)
            element = force.find(f".//{tag}") if element is None else element
            if element is not None:
                values[key] = self.r.value(element, owner)
        path = force.find("GeometryPath")
        if path is None:
            raise self.r.error(f"{owner} has no <GeometryPath>; expected its path points")
        points = []
        for point in objects(path, "PathPointSet"):
            pname = point.get("name")
            where = f"{owner}, path point {pname!r}"
            if point.tag != "PathPoint":
                raise self.r.error(f"{where} is a {point.tag}; expected fixed PathPoints (a moving or conditional point is "
                                   "not read)")
            reference = text(point, "socket_parent_frame") or text(point, "body")
            frame = self.frame(reference, where)
            location = frame.R @ self.r.numbers(point, "location", 3, where) + frame.p
            points.append((frame.body, location))
        if len(points) < 2:
            raise self.r.error(f"{owner} has {len(points)} path points; expected an origin and an insertion at least")
        if len({moved_by[b] for b, _ in points}) == 1:
            raise self.r.error(f"{owner} crosses no joint: its points are all on {sorted({b for b, _ in points})}, which move "
                               "together; expected a path across at least one joint")
        uses = []
        for pw in objects(path, "PathWrapSet"):
            wname = text(pw, "wrap_object")
            where = f"{owner}, path wrap {wname!r}"
            if wname in self.inactive:
                continue  # an inactive wrap object
            if wname not in wraps:
                raise self.r.error(f"{where} names no wrap object of the model; its wrap objects are {sorted(wraps)}")
            body, w = wraps[wname]
            problem = None
            if w.tag != "WrapCylinder":
                problem = f"a {w.tag}, which fatigue_pin does not model (it models WrapCylinder)"
            elif text(w, "quadrant", "all").lower() not in ("all", ""):
                problem = f"a WrapCylinder constrained to quadrant {text(w, 'quadrant')!r}; fatigue_pin models quadrant 'all'"
            else:
                lo, hi = (int(x) for x in self.r.numbers(pw, "range", 2, where, (-1, -1)))
                if (lo, hi) != (-1, -1) and not (lo <= 1 and hi >= len(points)):
                    problem = f"a wrap restricted to path points {lo} to {hi}; fatigue_pin wraps the whole path (range -1 -1)"
            if problem is not None:
                if self.ignored(wname):
                    dropped.append(wname)
                    continue
                raise self.r.error(f"{where} is {problem}; expected it left out: [model] ignore_wraps = true "
                                   f"or [\"{wname}\"] (fatigue-pin info --ignore-wraps)")
            if self.ignored(wname) and not isinstance(self.ignore, bool):
                dropped.append(wname)
                continue
            used_wraps[wname] = body
            uses.append(wname)
        lines = ["[[muscles]]", f'name = "{name}"']
        lines += [f"{k} = {fmt(v)}" for k, v in values.items()]
        if uses:
            lines.append("wraps = [" + ", ".join(f'{{ name = "{u}", turn = "either" }}' for u in uses) + "]")
        lines.append("points = [")
        lines += [f'    {{ frame = "{b}", location = [{", ".join(fmt(x) for x in loc)}] }},' for b, loc in points]
        lines += ["]", ""]
        return "\n".join(lines)


def read_osim(path: str | Path, ignore_wraps: bool | Iterable[str] = False, effort: float = 50.0, muscles: bool = True) -> OsimModel:
    """An OpenSim model (``.osim``, format 4.x) as a URDF text and a muscle file text (module docstring).

    Args:
        path: the ``.osim`` file.
        ignore_wraps: wrap objects fatigue_pin cannot model (ellipsoids, spheres, tori, a
            cylinder of one quadrant or over part of the path) are refused unless left out here:
            ``True`` leaves every such one out; a list of names leaves those out (any kind).
        effort: the torque (N m) or force (N) limit given to every joint, > 0 (OpenSim's
            coordinates have none).
        muscles: False: the skeleton only (``muscles`` of the result is "", the ForceSet is not read).

    Raises:
        ModelError: one line naming the element, its name and the file (module docstring).
    """
    p = Path(path).expanduser()
    if not str(path).strip():
        raise ModelError("OpenSim model path '' is empty; expected the path of an existing .osim file")
    if p.is_dir():
        raise ModelError(f"OpenSim model path {str(p)!r} is a folder; expected the path of a .osim file")
    if not p.exists():
        raise ModelError(f"OpenSim model not found: {str(p)!r} (expected the path of an existing .osim file)")
    if isinstance(effort, bool) or not isinstance(effort, (int, float)) or not math.isfinite(effort) or effort <= 0:
        raise ModelError(f"OpenSim model {str(p)!r}: joint effort {effort!r}; expected a finite limit > 0 (N m or N)")
    reader = _Osim(p, ignore_wraps, effort)
    urdf, moved_by = reader.urdf()
    muscle_text, dropped = reader.muscles(moved_by) if muscles else ("", ())
    return OsimModel(p, reader.name, urdf, muscle_text, reader.gravity, dropped)
