"""Frame kinematics on CasADi symbols (issue 13): positions, rotations and velocities against
numeric Pinocchio on arm26, the UR5 and the Panda; the CasADi Jacobian against finite
differences; payloads; the reach estimate and inverse kinematics."""

from __future__ import annotations

import re

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest

from fatigue_pin.core.errors import ModelError
from fatigue_pin.ocp.guesses import solve_ik
from fatigue_pin.robot.kinematics import frame_placement, reach
from fatigue_pin.robot.model import Payload, bundled_urdf, load_model, resolve_model
from fatigue_pin.ocp.task import FrameTarget

ROBOTS = {"arm26": ("dumbbell", "forearm", "humerus"), "ur5": ("tool0", "ee_link", "forearm_link"),
          "panda": ("panda_hand_tcp", "panda_link4", "panda_rightfinger")}


@pytest.fixture(scope="module", params=sorted(ROBOTS))
def robot(request):
    locked = {"panda_finger_joint2": 0.0} if request.param == "panda" else None  # it mimics finger 1
    return request.param, resolve_model(request.param, locked_joints=locked)


def _random_states(model, n, seed=0):
    rng = np.random.default_rng(seed)
    lo = np.where(np.isfinite(model.q_lower), model.q_lower, -np.pi)
    hi = np.where(np.isfinite(model.q_upper), model.q_upper, np.pi)
    return [(rng.uniform(lo, hi), rng.uniform(-2.0, 2.0, model.nv)) for _ in range(n)]


def test_frame_kinematics_match_numeric_pinocchio(robot):
    """Position, rotation and LOCAL_WORLD_ALIGNED linear velocity of three frames of each robot,
    at 10 random states, to 1e-10."""
    name, model = robot
    pm = model.pin_model
    data = pm.createData()
    worst = 0.0
    for frame in ROBOTS[name]:
        fid = pm.getFrameId(frame)
        position, rotation, velocity = model.frame_position(frame), model.frame_rotation(frame), model.frame_velocity(frame)
        assert model.frame_position(frame) is position  # cached per frame
        for q, v in _random_states(model, 10):
            pin.forwardKinematics(pm, data, q, v)
            pin.updateFramePlacements(pm, data)
            ref_v = pin.getFrameVelocity(pm, data, fid, pin.LOCAL_WORLD_ALIGNED).linear
            errors = (np.abs(np.asarray(position(q)).ravel() - data.oMf[fid].translation).max(),
                      np.abs(np.asarray(rotation(q)) - data.oMf[fid].rotation).max(),
                      np.abs(np.asarray(velocity(q, v)).ravel() - ref_v).max())
            worst = max(worst, *errors)
    assert worst < 1e-10, worst


def test_casadi_jacobian_of_the_frame_position_matches_finite_differences(robot):
    name, model = robot
    frame = ROBOTS[name][0]
    q_sym = ca.SX.sym("q", model.nq)
    position = model.frame_position(frame)
    jac = ca.Function("J", [q_sym], [ca.jacobian(position(q_sym), q_sym)])
    pm = model.pin_model
    fid = pm.getFrameId(frame)
    data = pm.createData()
    for q, v in _random_states(model, 5, seed=1):
        J = np.asarray(jac(q))
        h = 1e-6
        fd = np.column_stack([(np.asarray(position(q + h * e)) - np.asarray(position(q - h * e))).ravel() / (2 * h)
                              for e in np.eye(model.nq)])
        assert np.abs(J - fd).max() < 1e-7
        # and the velocity is that Jacobian times v (the frame Jacobian of Pinocchio as well)
        pin.computeJointJacobians(pm, data, q)
        pin.framesForwardKinematics(pm, data, q)
        J_pin = pin.getFrameJacobian(pm, data, fid, pin.LOCAL_WORLD_ALIGNED)[:3]
        assert np.abs(J - J_pin).max() < 1e-10
        assert np.abs(J @ v - np.asarray(model.frame_velocity(frame)(q, v)).ravel()).max() < 1e-10


def test_unknown_frame_is_named():
    model = resolve_model("ur5")
    with pytest.raises(ModelError, match=r"frame 'tool9' is not in model 'ur5'.*tool0"):
        model.frame_position("tool9")


# -- payloads -----------------------------------------------------------------------------------

DUMBBELL_INERTIA = (0.00370584, 0.0, 0.0, 0.04669628, 0.0, 0.04669628)


def _arm26_without_dumbbell(tmp_path, keep_link: bool):
    text = bundled_urdf("arm26").read_text()
    if keep_link:  # the dumbbell link stays as a massless frame
        text = re.sub(r"(<link name=\"dumbbell\">)\s*<inertial>.*?</inertial>", r"\1", text, flags=re.S)
    else:  # no dumbbell at all
        text = re.sub(r"<joint name=\"hand_to_dumbbell\".*?</joint>", "", text, flags=re.S)
        text = re.sub(r"<link name=\"dumbbell\">.*?</link>", "", text, flags=re.S)
    path = tmp_path / f"arm26_bare_{keep_link}.urdf"
    path.write_text(text)
    return path


@pytest.mark.parametrize("keep_link", [True, False])
def test_arm26_dumbbell_as_a_payload_gives_the_same_dynamics(tmp_path, keep_link):
    """arm26 without its dumbbell plus a 3.6 kg payload where the URDF attaches it (the dumbbell
    frame, or the forearm frame at the hand with the inertia turned by Ry(pi/2)) gives the same
    gravity torques and the same forward dynamics as the bundled arm26."""
    reference = load_model()
    path = _arm26_without_dumbbell(tmp_path, keep_link)
    bare = load_model(path)
    if keep_link:
        payload = Payload("dumbbell", 3.6, (0.0, 0.0, 0.0), DUMBBELL_INERTIA)
    else:
        R = pin.rpy.rpyToMatrix(0.0, np.pi / 2, 0.0)
        I = R @ Payload.inertia_matrix(DUMBBELL_INERTIA) @ R.T
        payload = Payload("forearm", 3.6, (0.0, -0.28, 0.05), (I[0, 0], I[0, 1], I[0, 2], I[1, 1], I[1, 2], I[2, 2]))
    loaded = load_model(path, payload=payload)
    assert loaded.payload == payload and loaded.urdf_path == path.resolve()
    rng = np.random.default_rng(3)
    for _ in range(5):
        q, v, tau = rng.uniform(0.1, 2.0, 2), rng.uniform(-3, 3, 2), rng.uniform(-20, 20, 2)
        assert np.allclose(loaded.gravity_torque(q), reference.gravity_torque(q), atol=1e-10)
        assert np.allclose(loaded.forward_dynamics(q, v, tau), reference.forward_dynamics(q, v, tau), atol=1e-9)
        assert not np.allclose(bare.gravity_torque(q), reference.gravity_torque(q), atol=1e-3)


def test_payload_errors_name_the_value():
    with pytest.raises(ModelError, match=r"payload mass = -2.0"):
        Payload("tool0", -2.0)
    with pytest.raises(ModelError, match=r"payload frame 'hand' is not in model 'ur5'"):
        resolve_model("ur5", payload=Payload("hand", 2.0))
    with pytest.raises(ModelError, match=r"payload inertia"):
        Payload("tool0", 2.0, inertia=(-1, 0, 0, 1, 0, 1))


def test_ur5_payload_raises_the_holding_torques():
    """3 kg at the tool adds J^T (0, 0, 3 * 9.81) N to the holding torques (J: the tool's
    world-aligned linear Jacobian)."""
    bare, loaded = resolve_model("ur5"), resolve_model("ur5", payload=Payload("tool0", 3.0))
    q = np.array([0.0, -1.0, 1.0, 0.0, 0.0, 0.0])
    pm, data = bare.pin_model, bare.pin_model.createData()
    pin.computeJointJacobians(pm, data, q)
    pin.framesForwardKinematics(pm, data, q)
    J = pin.getFrameJacobian(pm, data, pm.getFrameId("tool0"), pin.LOCAL_WORLD_ALIGNED)[:3]
    expected = J.T @ np.array([0.0, 0.0, 3.0 * 9.81])
    assert np.allclose(loaded.gravity_torque(q) - bare.gravity_torque(q), expected, atol=1e-9)
    assert abs(expected[bare.joint_index("shoulder_lift_joint")]) > 15.0  # N m, a lever of ~0.6 m


# -- reach and inverse kinematics ----------------------------------------------------------------


def test_reach_holds_every_random_posture(robot):
    name, model = robot
    frame = ROBOTS[name][0]
    centre, radius = reach(model.pin_model, frame)
    for q, _ in _random_states(model, 200, seed=5):
        assert np.linalg.norm(frame_placement(model.pin_model, frame, q).translation - centre) <= radius + 1e-12


def test_inverse_kinematics_reaches_a_point_of_the_workspace():
    model = resolve_model("ur5")
    q_goal = np.array([0.4, -1.0, 1.2, -0.5, 1.2, 0.3])
    goal = frame_placement(model.pin_model, "tool0", q_goal).translation
    res = solve_ik(model, [FrameTarget("tool0", goal, 0.0, 1e-4)], q0=np.array([0.0, -1.2, 1.0, 0.0, 0.0, 0.0]))
    assert res.success
    assert np.linalg.norm(frame_placement(model.pin_model, "tool0", res.q).translation - goal) <= 1e-4 + 1e-9
