"""Units of a joint's quantities by its kind: rad, rad/s, N m for a revolute joint; m, m/s, N
for a prismatic one.

:class:`~fatigue_pin.robot.model.RobotModel` knows the kind of each of its joints (Pinocchio's
joint type) and gives their units (``model.joint_units(j)``); a stored run keeps the kinds
(``RunResult.joint_kinds``) so that readers (``fatigue-pin info``, result files, figures, the
replay) state the same units without loading the model. This module imports numpy only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fatigue_pin.core.errors import ModelError
from fatigue_pin.core.text import shown

__all__ = ["JOINT_KINDS", "JointUnits", "units_of_kind"]


@dataclass(frozen=True)
class JointUnits:
    """The units of one joint's position, velocity, acceleration and effort, by its kind.

    Attributes:
        kind: ``"revolute"`` or ``"prismatic"`` (:data:`JOINT_KINDS`).
        position, velocity, acceleration, effort: SI unit words (rad, rad/s, rad/s^2, N m for a
            revolute joint; m, m/s, m/s^2, N for a prismatic one).
        effort_name: what the effort is called (``torque`` or ``force``).
        display_position: the unit figures show positions in (deg for a revolute joint, m for a
            prismatic one); :meth:`display` converts to it.
        position_name: what a position is called in figures (``angle`` or ``position``).
        display_digits: decimals a position is shown with in :attr:`display_position` (0.1 deg, 1 mm).
    """

    kind: str
    position: str
    velocity: str
    acceleration: str
    effort: str
    effort_name: str
    display_position: str
    position_name: str
    display_digits: int

    def display(self, values: np.ndarray | float) -> np.ndarray:
        """Positions (rad or m) in :attr:`display_position` (deg or m), same shape."""
        values = np.asarray(values, dtype=float)
        return np.degrees(values) if self.kind == "revolute" else values.copy()


#: The units of every joint kind the models support, by kind.
JOINT_KINDS = {
    "revolute": JointUnits("revolute", "rad", "rad/s", "rad/s^2", "N m", "torque", "deg", "angle", 1),
    "prismatic": JointUnits("prismatic", "m", "m/s", "m/s^2", "N", "force", "m", "position", 3),
}


def units_of_kind(kind: str) -> JointUnits:
    """The :class:`JointUnits` of a joint kind (``revolute``, ``prismatic``); ModelError otherwise."""
    if kind not in JOINT_KINDS:
        raise ModelError(f"joint kind {shown(kind)}: expected one of {list(JOINT_KINDS)}")
    return JOINT_KINDS[kind]
