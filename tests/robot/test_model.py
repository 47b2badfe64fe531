"""Model loading: the bundled arm26, its numbers, other URDFs and bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fatigue_pin.core.errors import DimensionError, ModelError
from fatigue_pin.robot.model import bundled_urdf, load_model


@pytest.mark.parametrize(
    "q_elbow_deg, expected",
    [(15.0, (5.74, 4.04)), (90.0, (14.24, 12.64)), (150.0, (7.21, 5.63))],
)
def test_arm26_holding_torques_match_spec(arm26, q_elbow_deg, expected):
    g = arm26.gravity_torque([0.07, math.radians(q_elbow_deg)])
    assert np.allclose(g, expected, atol=0.01)


def test_arm26_bounds_and_names(arm26):
    assert arm26.joint_names == ("shoulder", "elbow")
    assert np.allclose(arm26.q_lower, [-1.0, 0.0]) and np.allclose(arm26.q_upper, [math.pi, math.pi])
    assert np.allclose(arm26.v_upper, 10 * math.pi) and np.allclose(arm26.v_lower, -10 * math.pi)
    assert np.allclose(arm26.tau_upper, 50.0) and np.allclose(arm26.tau_lower, -50.0)
    masses = arm26.body_masses()
    assert masses["shoulder"] == pytest.approx(1.864572)
    assert masses["elbow"] == pytest.approx(1.534315 + 3.6)


def test_arm26_shoulder_to_elbow_distance(arm26):
    import pinocchio as pin

    data = arm26.pin_model.createData()
    pin.forwardKinematics(arm26.pin_model, data, np.zeros(2))
    d = np.linalg.norm(data.oMi[2].translation - data.oMi[1].translation)
    assert d == pytest.approx(0.29072, abs=1e-5)


def test_gravity_pulls_down_along_world_z(arm26):
    # arm hanging (q = 0): the dumbbell sits below the shoulder in the z-up world
    import pinocchio as pin

    data = arm26.pin_model.createData()
    pin.forwardKinematics(arm26.pin_model, data, np.zeros(2))
    pin.updateFramePlacements(arm26.pin_model, data)
    dumbbell = data.oMf[arm26.pin_model.getFrameId("dumbbell")].translation
    assert dumbbell[2] < data.oMi[1].translation[2] - 0.5
    assert np.allclose(arm26.pin_model.gravity.linear, [0, 0, -9.81])


def test_summary_mentions_holding_torques(arm26):
    text = arm26.summary()
    assert "shoulder" in text and "elbow" in text and "5.7" in text and "4.0" in text


def test_missing_urdf(tmp_path):
    with pytest.raises(ModelError, match="not found"):
        load_model(tmp_path / "nope.urdf")


def test_urdf_that_does_not_parse(tmp_path):
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot name='x'><link name='a'></robot")
    with pytest.raises(ModelError, match="does not parse"):
        load_model(bad)


def _urdf_with_joint(tmp_path, joint_type: str):
    text = bundled_urdf().read_text().replace('<joint name="elbow" type="revolute">', f'<joint name="elbow" type="{joint_type}">')
    path = tmp_path / f"arm_{joint_type}.urdf"
    path.write_text(text)
    return path


def test_unsupported_joint_named(tmp_path):
    with pytest.raises(ModelError, match="elbow.*unsupported"):
        load_model(_urdf_with_joint(tmp_path, "continuous"))


def test_floating_base_rejected(tmp_path):
    text = bundled_urdf().read_text().replace('<joint name="world_to_thorax" type="fixed">', '<joint name="world_to_thorax" type="floating">')
    path = tmp_path / "floating.urdf"
    path.write_text(text)
    with pytest.raises(ModelError, match="floating"):
        load_model(path)


def test_wrong_state_size(arm26):
    with pytest.raises(DimensionError, match="q has 3 entries"):
        arm26.gravity_torque([0.0, 0.1, 0.2])
    with pytest.raises(DimensionError, match="tau has 1 entries"):
        arm26.forward_dynamics([0.0, 0.1], [0.0, 0.0], [1.0])


def test_unknown_joint_index(arm26):
    with pytest.raises(ModelError, match="wrist"):
        arm26.joint_index("wrist")


PANDA_FINGERS = {"panda_finger_joint1": 0.02, "panda_finger_joint2": 0.03}


def test_locked_joints_leave_the_model_and_keep_the_dynamics():
    """Locking the Panda's fingers removes them from q, v and tau (nv 9 -> 7); the inverse
    dynamics of the other joints equal numeric Pinocchio's RNEA of the full model with the
    fingers held at their values (zero finger velocity and acceleration)."""
    import pinocchio as pin

    from fatigue_pin.robot.model import resolve_model

    from fatigue_pin.robot.model import example_robot_urdf

    model = pin.buildModelFromUrdf(str(example_robot_urdf("panda")))  # the full model, fingers free
    locked = resolve_model("panda", locked_joints=PANDA_FINGERS)
    assert (model.nv, locked.nv) == (9, 7)
    assert locked.joint_names == tuple(model.names[1:8])
    assert dict(locked.locked_joints) == PANDA_FINGERS
    data = model.createData()
    rng = np.random.default_rng(0)
    for _ in range(3):
        q = rng.uniform(locked.q_lower, locked.q_upper)
        v, a = rng.normal(size=7), rng.normal(size=7)
        q_full = np.concatenate([q, [0.02, 0.03]])
        tau = pin.rnea(model, data, q_full, np.r_[v, 0.0, 0.0], np.r_[a, 0.0, 0.0])[:7]
        assert np.allclose(np.asarray(locked.rnea(q, v, a)).reshape(-1), tau, atol=1e-9)


@pytest.mark.parametrize("locked, message", [
    ({"panda_finger_joint3": 0.0}, "joint 'panda_finger_joint3' is not in panda.urdf"),
    ({"panda_finger_joint1": 0.05}, r"locked_joints.panda_finger_joint1 = 0.05: expected a position within the joint's limits \[0, 0.04\]"),
    ({"panda_finger_joint1": "open"}, "expected a finite joint position"),
])
def test_locked_joints_reject_unknown_names_and_values_outside_the_limits(locked, message):
    from fatigue_pin.robot.model import resolve_model

    with pytest.raises(ModelError, match=message) as info:
        resolve_model("panda", locked_joints={**locked, "panda_finger_joint2": 0.0})  # finger 2 mimics finger 1
    assert "\n" not in str(info.value)


def test_locking_every_joint_is_refused(arm26):
    with pytest.raises(ModelError, match="locks every joint"):
        load_model(None, locked_joints={"shoulder": 0.0, "elbow": 0.5})


def test_a_mimic_joint_must_be_locked(tmp_path):
    """The Panda's second finger follows the first (<mimic>): not an actuated joint of its own, so
    the model is refused until it is locked, with one line that says how."""
    from fatigue_pin.core.errors import ModelError
    from fatigue_pin.robot.model import resolve_model

    with pytest.raises(ModelError, match=r"joint 'panda_finger_joint2' mimics 'panda_finger_joint1' \(<mimic>\).*locked_joints"):
        resolve_model("panda")
    model = resolve_model("panda", locked_joints={"panda_finger_joint2": 0.0})
    assert "panda_finger_joint2" not in model.joint_names and "panda_finger_joint1" in model.joint_names
    urdf = tmp_path / "two.urdf"
    urdf.write_text("""<robot name="two"><link name="base"/><link name="a"><inertial><mass value="1"/><origin xyz="0 0 0"/>
<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
<link name="b"><inertial><mass value="1"/><origin xyz="0 0 0"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
<joint name="j1" type="revolute"><parent link="base"/><child link="a"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="10" velocity="1"/></joint>
<joint name="j2" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="10" velocity="1"/>
<mimic joint="j1" multiplier="1" offset="0"/></joint></robot>""")
    with pytest.raises(ModelError, match="joint 'j2' mimics 'j1'"):
        resolve_model(str(urdf))
