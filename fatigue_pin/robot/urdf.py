"""Checks of a URDF file's text before Pinocchio's URDF parser reads it.

The parser (urdfdom) writes its complaints on the process's standard error (several lines,
with its own source lines) and then raises a message that does not say what is wrong. The
checks here read the XML first and refuse, with one line naming the element and the value, every
kind of bad input the parser would reject or that fatigue_pin cannot model:

* not XML, a root other than ``<robot>``;
* a joint or link without a name, two joints or two links of the same name;
* a joint without type, without a known parent or child link;
* a revolute or prismatic joint without ``<limit>``, or without its ``effort`` or ``velocity``;
* a number that is not a finite number (``lower="zero"``, ``upper="nan"``, ``xyz="0 0"``);
* a lower position limit above the upper one, an effort limit < 0 (0 makes the joint passive), a velocity limit < 0, a
  zero joint axis;
* a ``<mass>`` without its value, an ``<inertia>`` without one of its six entries;
* a link of negative mass or with negative principal moments on the diagonal of its inertia.

:func:`quiet_stderr` silences the parser's own lines for what remains and keeps them for the
error message.
"""

from __future__ import annotations

from typing import Iterable

import math
import xml.etree.ElementTree as ET
from pathlib import Path

from fatigue_pin.core.errors import ModelError
from fatigue_pin.core.streams import captured

__all__ = ["check_urdf_text", "quiet_stderr", "urdf_gravity"]

#: Attributes holding numbers: element tag -> {attribute: count of numbers}.
_NUMBERS = {
    "limit": {"lower": 1, "upper": 1, "effort": 1, "velocity": 1},
    "origin": {"xyz": 3, "rpy": 3},
    "axis": {"xyz": 3},
    "mass": {"value": 1},
    "inertia": {"ixx": 1, "ixy": 1, "ixz": 1, "iyy": 1, "iyz": 1, "izz": 1},
    "mimic": {"multiplier": 1, "offset": 1},
    "dynamics": {"damping": 1, "friction": 1},
}


def _bad(path: Path, what: str) -> ModelError:
    return ModelError(f"URDF file {str(path)!r} does not parse: {what}")


def _numbers(path: Path, owner: str, element: ET.Element) -> None:
    """Every numeric attribute of ``element`` holds the expected count of finite numbers."""
    for attr, count in _NUMBERS.get(element.tag, {}).items():
        text = element.get(attr)
        if text is None:
            continue
        parts = text.split()
        try:
            values = [float(p) for p in parts]
        except ValueError:
            values = None
        if values is None or len(values) != count or not all(math.isfinite(v) for v in values):
            expected = "a finite number" if count == 1 else f"{count} finite numbers separated by spaces"
            raise _bad(path, f"{owner}: <{element.tag} {attr}={text!r}>: expected {expected}")


def _unique(path: Path, kind: str, names: list[str | None]) -> None:
    seen: set[str] = set()
    for name in names:
        if not name:
            raise _bad(path, f"a {kind} lacks its name attribute")
        if name in seen:
            raise _bad(path, f"two {kind}s are named {name!r}; expected unique {kind} names")
        seen.add(name)


def _check_joint(path: Path, joint: ET.Element, links: set[str]) -> None:
    name, kind = joint.get("name"), joint.get("type")
    if not kind:
        raise _bad(path, f"joint [{name}] lacks its type attribute")
    for end in ("parent", "child"):
        tag = joint.find(end)
        if tag is None or tag.get("link") not in links:
            raise _bad(path, f"joint [{name}]: no {end} link, or an unknown one")
    for element in joint.iter():
        _numbers(path, f"joint [{name}]", element)
    axis = joint.find("axis")
    if axis is not None and axis.get("xyz") is not None and all(float(v) == 0.0 for v in axis.get("xyz").split()):
        raise ModelError(f"{path}: joint {name!r} has axis xyz = {axis.get('xyz')!r}; expected a non-zero axis in its <axis> tag")
    limit = joint.find("limit")
    if kind not in ("revolute", "prismatic"):
        return
    if limit is None:
        raise _bad(path, f"joint [{name}]: a {kind} joint needs a <limit>")
    for key in ("effort", "velocity"):
        if limit.get(key) is None:
            raise _bad(path, f"joint [{name}]: limit has no {key}")
    effort, velocity = float(limit.get("effort")), float(limit.get("velocity"))
    if effort < 0:
        raise ModelError(f"{path}: joint {name!r} has effort limit {effort}; expected a finite effort >= 0 in its <limit> tag "
                         "(0: a passive joint)")
    if velocity < 0:
        raise ModelError(f"{path}: joint {name!r} has velocity limit {velocity}; expected a speed >= 0 in its <limit> tag "
                         "(0: none, taken as 10 pi)")
    lower, upper = float(limit.get("lower", 0.0)), float(limit.get("upper", 0.0))
    if lower > upper:
        raise ModelError(f"{path}: joint {name!r} has lower limit {lower:g} above its upper limit {upper:g}; "
                         "expected lower <= upper in its <limit> tag")


def _check_link(path: Path, link: ET.Element) -> None:
    name = link.get("name")
    for element in link.iter():
        _numbers(path, f"link [{name}]", element)
    inertial = link.find("inertial")
    if inertial is None:
        return
    mass = inertial.find("mass")
    if mass is not None and mass.get("value") is None:
        raise _bad(path, f"link [{name}]: <mass> has no value; expected <mass value=\"...\"/> (kg)")
    inertia = inertial.find("inertia")
    missing = [k for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz") if inertia is not None and inertia.get(k) is None]
    if missing:
        raise _bad(path, f"link [{name}]: <inertia> lacks {missing}; expected ixx, ixy, ixz, iyy, iyz and izz (kg m^2)")
    if mass is not None and float(mass.get("value")) < 0:
        raise ModelError(f"{path}: link {name!r} has mass {float(mass.get('value')):g}; expected a mass >= 0 (kg) in its <inertial>")
    inertia = inertial.find("inertia")
    if inertia is not None:
        for key in ("ixx", "iyy", "izz"):
            if float(inertia.get(key, 0.0)) < 0:
                raise ModelError(f"{path}: link {name!r} has {key} = {float(inertia.get(key)):g}; "
                                 "expected moments of inertia >= 0 (kg m^2) in its <inertia>")


def urdf_gravity(root: ET.Element, path: Path) -> tuple[float, float, float] | None:
    """The gravity a URDF carries in a top-level ``<gravity xyz="x y z"/>`` element (m/s^2, world
    frame; a fatigue_pin extension, written by the OpenSim import, :mod:`fatigue_pin.robot.osim`),
    or None without one. ModelError for an ``xyz`` that is not three finite numbers."""
    element = root.find("gravity")
    if element is None:
        return None
    text = element.get("xyz", "")
    try:
        values = [float(v) for v in text.split()]
    except ValueError:
        values = []
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise _bad(path, f"<gravity xyz={text!r}>: expected 3 finite numbers separated by spaces (m/s^2)")
    return (values[0], values[1], values[2])


def check_urdf_text(path: Path, locked: Iterable[str] = (), text: str | None = None) -> tuple[float, float, float] | None:
    """Refuse, with one line naming the element and the value, a URDF that the URDF parser would
    reject or that fatigue_pin cannot model (see the module docstring), including a ``<mimic>``
    joint that is not among the ``locked`` joints: a mimic joint is driven by another joint, not by
    an actuator of its own, and fatigue_pin gives every joint a plus and a minus actuator half, so
    loading it as an independent joint would be a different robot.

    ``text``: the URDF's text, when it is not read from ``path`` (``path`` then only names it).

    Returns:
        the gravity the URDF carries (:func:`urdf_gravity`), or None.

    Raises:
        ModelError: the first problem found.
    """
    try:
        root = ET.fromstring(text) if text is not None else ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise _bad(path, str(exc)) from None
    except OSError as exc:
        raise ModelError(f"URDF file {str(path)!r} cannot be read ({exc.strerror}); expected a readable .urdf file") from None
    if root.tag != "robot":
        raise _bad(path, f"the root element is <{root.tag}>; expected <robot>")
    links = root.findall("link")
    joints = root.findall("joint")  # not root.iter: <transmission> elements hold <joint name=...> too
    _unique(path, "link", [link.get("name") for link in links])
    _unique(path, "joint", [joint.get("name") for joint in joints])
    names = {link.get("name") for link in links}
    for link in links:
        _check_link(path, link)
    for joint in joints:
        _check_joint(path, joint, names)
    _check_mimic(path, joints, set(locked))
    return urdf_gravity(root, path)


def _check_mimic(path: Path, joints: list[ET.Element], locked: set[str]) -> None:
    """Refuse the first ``<mimic>`` joint that is not locked, naming the joint it follows and the fix."""
    for joint in joints:
        mimic = joint.find("mimic")
        if mimic is not None and joint.get("name") not in locked:
            raise ModelError(f"{path.name}: joint {joint.get('name')!r} mimics {mimic.get('joint')!r} (<mimic>); fatigue_pin "
                             f"actuates every joint on its own: lock it, [model] locked_joints = {{ {joint.get('name')} = <position> }}")


def quiet_stderr():
    """The process's standard error captured for the block (:func:`fatigue_pin.core.streams.captured`)."""
    return captured(2)
