"""Reading an OpenSim model's XML (:mod:`fatigue_pin.robot.osim`): numbers and flags of its
elements, its sets, the rotations it writes (body-fixed X-Y-Z Euler angles, an angle about an
axis) and the URDF's (roll, pitch, yaw), frames fixed on bodies, and the URDF joints written with
numbers at full precision."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable

import numpy as np

from fatigue_pin.core.errors import ModelError

__all__ = ["Frame", "Reader", "euler_xyz", "flag", "fmt", "is_identity", "objects", "rot", "rpy", "text", "urdf_joint", "vec"]


class Reader:
    """Messages and numbers of one file."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def error(self, what: str) -> ModelError:
        return ModelError(f"OpenSim model {str(self.path)!r}: {what}")

    def numbers(self, element: ET.Element | None, tag: str, count: int, owner: str, default: Iterable[float] | None = None) -> np.ndarray:
        """The ``count`` finite numbers of ``element``'s child ``tag``, shape (count,); ``default``
        without one (None: a one-line error naming ``owner``, as for a wrong count)."""
        child = element.find(tag) if element is not None else None
        if child is None or child.text is None or not child.text.strip():
            if default is not None:
                return np.asarray(list(default), dtype=float)
            raise self.error(f"{owner} has no <{tag}>; expected {count} number{'s' if count > 1 else ''}")
        try:
            values = np.array([float(x) for x in child.text.split()])
        except ValueError:
            values = np.array([])
        if values.size != count or not np.all(np.isfinite(values)):
            raise self.error(f"{owner}: <{tag}>{child.text.strip()}</{tag}>: expected {count} finite number{'s' if count > 1 else ''}")
        return values

    def value(self, element: ET.Element, owner: str) -> float:
        """The one finite number an element holds."""
        try:
            v = float((element.text or "").strip())
        except ValueError:
            v = math.nan
        if not math.isfinite(v):
            raise self.error(f"{owner}: <{element.tag}>{(element.text or '').strip()}</{element.tag}>: expected a finite number")
        return v

    def number(self, element: ET.Element, tag: str, owner: str, default: float | None = None) -> float:
        """The one finite number of ``element``'s child ``tag`` (:meth:`numbers`)."""
        return float(self.numbers(element, tag, 1, owner, None if default is None else [default])[0])


def text(element: ET.Element | None, tag: str, default: str = "") -> str:
    """The stripped text of ``element``'s child ``tag``, or ``default`` without one."""
    child = element.find(tag) if element is not None else None
    return (child.text or "").strip() if child is not None else default


def flag(element: ET.Element, tag: str, default: bool) -> bool:
    """A boolean child (``true``/``false``), or ``default`` without one."""
    word = text(element, tag, "").lower()
    return default if not word else word in ("true", "1")


def objects(parent: ET.Element | None, set_tag: str) -> list[ET.Element]:
    """The children of ``<set_tag><objects>`` of ``parent``."""
    if parent is None:
        return []
    holder = parent.find(set_tag)
    if holder is None:
        return []
    objects = holder.find("objects")
    return list(objects) if objects is not None else []


def rot(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation matrix (3, 3) of ``angle`` (rad) about the unit vector ``axis``."""
    x, y, z = axis
    c, s, t = math.cos(angle), math.sin(angle), 1 - math.cos(angle)
    return np.array([[t * x * x + c, t * x * y - s * z, t * x * z + s * y],
                     [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
                     [t * x * z - s * y, t * y * z + s * x, t * z * z + c]])


def euler_xyz(angles: np.ndarray) -> np.ndarray:
    """Body-fixed X-Y-Z Euler angles (rad): Rx(a) Ry(b) Rz(c) (OpenSim's orientations)."""
    a, b, c = angles
    return rot(np.array([1.0, 0, 0]), a) @ rot(np.array([0, 1.0, 0]), b) @ rot(np.array([0, 0, 1.0]), c)


def rpy(R: np.ndarray) -> tuple[float, float, float]:
    """URDF roll, pitch, yaw (fixed axes X, Y, Z: R = Rz(yaw) Ry(pitch) Rx(roll)) of a rotation matrix."""
    pitch = math.atan2(-R[2, 0], math.hypot(R[0, 0], R[1, 0]))
    if abs(math.cos(pitch)) < 1e-12:  # gimbal lock: roll taken as 0
        return 0.0, pitch, math.atan2(-R[0, 1], R[1, 1])
    return math.atan2(R[2, 1], R[2, 2]), pitch, math.atan2(R[1, 0], R[0, 0])


def fmt(x: float) -> str:
    return repr(float(x)) if x != 0 else "0"


def vec(v: Iterable[float]) -> str:
    return " ".join(fmt(x) for x in v)


@dataclass
class Frame:
    """A frame fixed on a body: its placement (R, p) in the body's frame."""

    body: str
    R: np.ndarray
    p: np.ndarray


def is_identity(frame: Frame) -> bool:
    """The frame is its body's frame (no rotation, no offset)."""
    return bool(np.allclose(frame.R, np.eye(3), atol=0, rtol=0) and not np.any(frame.p))


def urdf_joint(name: str, kind: str, parent: str, child: str, R: np.ndarray, p: np.ndarray, axis: np.ndarray | None = None,
               limits: tuple[float, float, float] | None = None) -> list[str]:
    """The lines of a URDF ``<joint>``: origin (R, p) in the parent link, and for a revolute or
    prismatic joint its axis and limits (lower, upper, effort); velocity limit 10 pi."""
    lines = [f'  <joint name="{name}" type="{kind}">', f'    <parent link="{parent}"/>', f'    <child link="{child}"/>',
             f'    <origin xyz="{vec(p)}" rpy="{vec(rpy(R))}"/>']
    if axis is not None and limits is not None:
        lo, hi, effort = limits
        lines += [f'    <axis xyz="{vec(axis)}"/>',
                  f'    <limit lower="{fmt(lo)}" upper="{fmt(hi)}" effort="{fmt(effort)}" velocity="{fmt(10 * math.pi)}"/>']
    lines.append("  </joint>")
    return lines
