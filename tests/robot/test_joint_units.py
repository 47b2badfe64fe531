"""Units by joint kind: a prismatic joint is in m, m/s and N, a revolute one in rad, rad/s and N m,
in the model (the one owner), `fatigue-pin info` and the task's messages."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fatigue_pin.cli.main import main
from fatigue_pin.core.errors import ModelError, TaskError
from fatigue_pin.ocp.task import JointRange, JointTarget, Task
from fatigue_pin.robot.model import joint_kinds_of_urdf, load_model
from fatigue_pin.robot.units import units_of_kind

PENDULUM = Path(__file__).resolve().parents[2] / "urdf" / "pendulum.urdf"


@pytest.fixture(scope="module")
def pendulum():
    return load_model(PENDULUM)


def test_the_kinds_are_pinocchio_s_joint_types(pendulum, arm26):
    shortnames = [pendulum.pin_model.joints[i].shortname() for i in range(1, pendulum.pin_model.njoints)]
    assert shortnames == ["JointModelPY", "JointModelRX"]  # the URDF: slider along y, pendulum about x
    assert pendulum.joint_kinds == ("prismatic", "revolute")
    assert arm26.joint_kinds == ("revolute", "revolute")
    slider, pole = pendulum.joint_units("slider"), pendulum.joint_units(1)
    assert (slider.position, slider.velocity, slider.acceleration, slider.effort) == ("m", "m/s", "m/s^2", "N")
    assert (pole.position, pole.velocity, pole.acceleration, pole.effort) == ("rad", "rad/s", "rad/s^2", "N m")
    assert joint_kinds_of_urdf(PENDULUM.read_text()) == {"slider": "prismatic", "pendulum": "revolute"}
    with pytest.raises(ModelError, match="not in model"):
        pendulum.joint_units("elbow")
    with pytest.raises(ModelError, match="expected one of"):
        units_of_kind("spherical")


def test_display_converts_angles_only():
    np.testing.assert_allclose(units_of_kind("revolute").display([np.pi / 2]), [90.0])
    np.testing.assert_array_equal(units_of_kind("prismatic").display([0.73]), [0.73])


def _row(text: str, joint: str) -> str:
    (line,) = [ln for ln in text.splitlines() if ln.split()[:1] == [joint]]
    return line


def test_info_states_each_joint_s_units(capsys):
    assert main(["info", "--urdf", str(PENDULUM)]) == 0
    out = capsys.readouterr().out
    slider, pole = _row(out, "slider"), _row(out, "pendulum")
    assert "prismatic" in slider and "[-1.0000, 5.0000] m " in slider and "31.4159 m/s " in slider
    assert "[-100.0, 100.0] N " in slider and "rad" not in slider and "N m" not in slider
    assert "revolute" in pole and "[-6.2832, 6.2832] rad " in pole and "31.4159 rad/s " in pole
    assert "[-100.0, 100.0] N m " in pole
    # holding efforts at the middle of the ranges (2 m, 0 rad): no force along the horizontal rail,
    # and m g times the centre of mass's lateral offset (1 kg x 9.81 x 0.0688 m) about the pivot
    holding = out.splitlines()[-1]
    assert holding.startswith("  holding forces and torques at q = (2 m, 0 rad)")
    assert f"(0 N, {9.81 * 0.0688:.4g} N m)" in holding


def test_info_of_a_revolute_model_speaks_of_torques(arm26):
    text = arm26.summary()
    assert "holding torques at q = (0.07 rad, 0.2618 rad): (5.736 N m, 4.039 N m)" in text
    assert " N " not in text.replace("N m", "")


def test_task_messages_carry_the_joint_s_unit(pendulum):
    task = Task(1.0, 10, (JointTarget("slider", 6.0, 0.0),))
    with pytest.raises(TaskError, match=r"target 6.0 of joint 'slider' is outside its range \[-1.0, 5.0\] m( \(at phase 0\))?$"):
        task.check(pendulum)
    task = Task(1.0, 10, (JointRange("pendulum", 7.0, 8.0),))
    with pytest.raises(TaskError, match=r"range .7.0, 8.0. of joint 'pendulum' does not meet its range \[.*\] rad$"):
        task.check(pendulum)
    task = Task(1.0, 10, (JointTarget("slider", 0.5, 0.0),), q_init=(0.2, 0.0))
    with pytest.raises(TaskError, match=r"its target at phase 0 is 0.5 \(\+- 0\) m; expected"):
        task.check(pendulum)
    task = Task(1.0, 10, (JointTarget("slider", velocity=40.0, at="end"),))
    with pytest.raises(TaskError, match=r"velocity target 40.0 of joint 'slider' is outside its velocity bounds \[.*\] m/s \(at the end\)$"):
        task.check(pendulum)
