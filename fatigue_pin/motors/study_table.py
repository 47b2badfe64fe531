"""The ``[motors]`` table of a study: which motor drives each joint (``[actuators] kind =
"motors"``, docs/motors.md).

    [motors]
    preset = "ur5"                 # a robot's stand-ins, joint by joint (ROBOT_MOTORS), or a motor
                                   # preset (MOTOR_PRESETS) or a calibration JSON for every joint
    T_ambient = 30.0               # any field of MotorParameters: for every motor
    derate = true                  # bound each torque by its derated limit, limit sqrt(1 - x_w)
    [motors.joints.elbow_joint]    # one joint's own preset and fields
    preset = "maxon-re40"
    gear_ratio = 80.0

Without ``preset`` the model's name chooses the robot's stand-ins (``ur5``, ``panda``). A joint's
own fields win over the table's, which win over the preset's.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from typing import Any

from fatigue_pin.core.errors import FatiguePinError, ParameterError
from fatigue_pin.core.text import shown
from fatigue_pin.motors.motor import MotorParameters
from fatigue_pin.motors.presets import MOTOR_PRESETS, ROBOT_MOTORS, motor_preset

__all__ = ["MOTOR_FIELDS", "check_motors_table", "motors_of"]

#: The fields of :class:`MotorParameters` a ``[motors]`` table may set.
MOTOR_FIELDS: tuple[str, ...] = tuple(f.name for f in dataclasses.fields(MotorParameters))


def _check_level(table: Any, where: str, nested: bool) -> dict[str, Any]:
    if not isinstance(table, dict):
        raise ParameterError(f"{where} = {shown(table)}: expected a table")
    allowed = {"preset", *MOTOR_FIELDS, *(("joints", "derate") if nested else ())}
    for key, value in table.items():
        if key not in allowed:
            raise ParameterError(f"unknown key {where}.{key}; expected 'preset'{', joints, derate' if nested else ''} or a motor field "
                                 f"{list(MOTOR_FIELDS)}")
        if key == "derate" and not isinstance(value, bool):
            raise ParameterError(f"{where}.derate = {shown(value)}: expected true or false")
        if key == "preset" and not (isinstance(value, str) and value):
            raise ParameterError(f"{where}.preset = {shown(value)}: expected a robot ({sorted(ROBOT_MOTORS)}), a motor preset "
                                 f"({sorted(MOTOR_PRESETS)}) or a .json file of fatigue-pin calibrate-thermal")
        if key in MOTOR_FIELDS and (isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value)):
            raise ParameterError(f"{where}.{key} = {shown(value)}: expected a finite number")
    return dict(table)


def check_motors_table(table: Any) -> dict[str, Any]:
    """The ``[motors]`` table, its keys and value types checked (the values themselves are
    checked when the motors are built, :func:`motors_of`)."""
    out = _check_level(table, "motors", nested=True)
    joints = out.get("joints", {})
    if not isinstance(joints, dict):
        raise ParameterError(f"motors.joints = {shown(joints)}: expected a table of joint names")
    if "joints" in out:
        out["joints"] = {j: _check_level(t, f"motors.joints.{j}", nested=False) for j, t in joints.items()}
    return out


def motors_of(table: Mapping[str, Any], joint_names: Sequence[str], actuated: Sequence[str], model_name: str) -> dict[str, MotorParameters]:
    """The motor of every actuated joint from a checked ``[motors]`` table.

    Args:
        table: the table (:func:`check_motors_table`).
        joint_names: every joint of the model, in order.
        actuated: the joints that get a motor (not passive).
        model_name: the model's name, whose stand-ins are the default preset.

    Raises:
        ParameterError: a joint the model does not have, no preset for a joint, a bad preset or
            field value (one line, naming the key).
    """
    unknown = [j for j in table.get("joints", {}) if j not in joint_names]
    if unknown:
        raise ParameterError(f"motors.joints.{unknown[0]}: motor on joint {unknown[0]!r}: expected a joint of the model "
                             f"{list(joint_names)}")
    preset = table.get("preset") or (model_name if model_name in ROBOT_MOTORS else "")
    common = {k: v for k, v in table.items() if k in MOTOR_FIELDS}
    if preset in ROBOT_MOTORS and len(ROBOT_MOTORS[preset]) != len(joint_names):
        raise ParameterError(f"motors.preset = {preset!r}: the {preset} stand-ins are for {len(ROBOT_MOTORS[preset])} joints; "
                             f"the model has {len(joint_names)}; expected a motor preset for every joint")
    out: dict[str, MotorParameters] = {}
    for j in actuated:
        own = table.get("joints", {}).get(j, {})
        name = own.get("preset") or (ROBOT_MOTORS[preset][list(joint_names).index(j)] if preset in ROBOT_MOTORS else preset)
        where = f"motors.joints.{j}" if own.get("preset") else "motors"
        if not name:
            raise ParameterError(f"motors.preset: no motor for joint {j!r} of model {model_name!r}; expected a robot "
                                 f"({sorted(ROBOT_MOTORS)}), a motor preset ({sorted(MOTOR_PRESETS)}) or a calibration .json, "
                                 f"here or in [motors.joints.{j}]")
        fields = {**common, **{k: v for k, v in own.items() if k in MOTOR_FIELDS}}
        try:
            out[j] = motor_preset(name, **fields)
        except FatiguePinError as exc:
            raise ParameterError(f"{where}: joint {j!r}: {exc}") from None
    return out
