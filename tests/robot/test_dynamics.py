"""CasADi ABA/RNEA (fatigue_pin.robot.dynamics) against Pinocchio's double-precision algorithms."""

from __future__ import annotations

import sys
from pathlib import Path

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest

from fatigue_pin.robot import dynamics
from fatigue_pin.core.errors import ModelError

N_STATES = 200


def _example_robot_data_dir() -> Path | None:
    """example-robot-data 6 ships only data, under <site-packages>/cmeel.prefix/share/."""
    for entry in sys.path:
        robots = Path(entry or ".") / "cmeel.prefix" / "share" / "example-robot-data" / "robots"
        if robots.is_dir():
            return robots
    return None


def _erd_model(relative: str) -> pin.Model:
    robots = _example_robot_data_dir()
    if robots is None or not (robots / relative).is_file():
        pytest.skip(f"example-robot-data file {relative} not found")
    return pin.buildModelFromUrdf(str(robots / relative))


MODELS = {
    "ur5": lambda: _erd_model("ur_description/urdf/ur5_robot.urdf"),
    "panda": lambda: _erd_model("panda_description/urdf/panda.urdf"),
    "sample_manipulator": pin.buildSampleModelManipulator,
}


def _random_states(model: pin.Model, rng: np.random.Generator):
    """N_STATES states (as nq x N and nv x N arrays) inside the joint limits."""
    assert model.nq == model.nv, "these test models only have 1-DoF joints"
    lo = np.clip(model.lowerPositionLimit, -np.pi, np.pi)
    hi = np.clip(model.upperPositionLimit, -np.pi, np.pi)
    q = lo[:, None] + (hi - lo)[:, None] * rng.random((model.nq, N_STATES))
    v = rng.uniform(-2.0, 2.0, (model.nv, N_STATES))
    a = rng.uniform(-5.0, 5.0, (model.nv, N_STATES))
    # Torques of a moderate size for each joint: those that produce a moderate acceleration.
    data = model.createData()
    tau = np.column_stack(
        [pin.rnea(model, data, q[:, k], v[:, k], a[:, k]) for k in range(N_STATES)]
    )
    tau += rng.normal(0.0, 0.1, tau.shape)
    return q, v, tau


def _reference_aba(model: pin.Model, q, v, tau) -> np.ndarray:
    data = model.createData()
    return np.column_stack(
        [pin.aba(model, data, q[:, k], v[:, k], tau[:, k]).copy() for k in range(q.shape[1])]
    )


def _close(actual, expected, tol):
    err = np.abs(np.asarray(actual) - expected).max()
    assert err <= tol, f"max absolute error {err:.3e} > {tol:.0e}"


@pytest.fixture(params=sorted(MODELS))
def model(request) -> pin.Model:
    return MODELS[request.param]()


def test_signatures(model):
    aba, rnea = dynamics.casadi_dynamics(model)
    assert isinstance(aba, ca.Function) and isinstance(rnea, ca.Function)
    assert aba.name_in() == ["q", "v", "tau"] and aba.name_out() == ["ddq"]
    assert rnea.name_in() == ["q", "v", "a"] and rnea.name_out() == ["tau"]
    assert [aba.size1_in(i) for i in range(3)] == [model.nq, model.nv, model.nv]
    assert [rnea.size1_in(i) for i in range(3)] == [model.nq, model.nv, model.nv]
    assert aba.size1_out(0) == rnea.size1_out(0) == model.nv
    assert aba.is_a("SXFunction") and rnea.is_a("SXFunction")


def test_aba_matches_pinocchio_and_rnea_inverts_it(model):
    rng = np.random.default_rng(20230517)
    q, v, tau = _random_states(model, rng)
    aba, rnea = dynamics.casadi_dynamics(model)
    ddq = np.asarray(aba.map(N_STATES)(q, v, tau))
    _close(ddq, _reference_aba(model, q, v, tau), 1e-10)
    tau_back = np.asarray(rnea.map(N_STATES)(q, v, ddq))
    _close(tau_back, tau, 1e-9)


def test_gravity_of_the_model_is_used(model):
    rng = np.random.default_rng(7)
    q, v, tau = _random_states(model, rng)
    q, v, tau = q[:, :20], v[:, :20], tau[:, :20]
    zeros = np.zeros((model.nv, 20))
    default_aba, _ = dynamics.casadi_dynamics(model)

    tilted = model.copy()
    tilted.gravity = pin.Motion(np.array([3.0, -4.0, -7.5, 0.0, 0.0, 0.0]))
    aba, rnea = dynamics.casadi_dynamics(tilted)
    ddq = np.asarray(aba.map(20)(q, v, tau))
    _close(ddq, _reference_aba(tilted, q, v, tau), 1e-10)
    assert np.abs(ddq - np.asarray(default_aba.map(20)(q, v, tau))).max() > 1e-3
    data = tilted.createData()
    gravity_torque = np.column_stack(
        [pin.computeGeneralizedGravity(tilted, data, q[:, k]).copy() for k in range(20)]
    )
    _close(np.asarray(rnea.map(20)(q, zeros, zeros)), gravity_torque, 1e-10)

    weightless = model.copy()
    weightless.gravity = pin.Motion.Zero()
    _, rnea0 = dynamics.casadi_dynamics(weightless)
    assert np.abs(np.asarray(rnea0.map(20)(q, zeros, zeros))).max() < 1e-12


def test_backend_is_available():
    """The compiled bridge (or pinocchio.casadi) must be there: no silent skip of the others."""
    name = dynamics.backend_name()
    assert name in ("fatigue_pin._pinocchio_casadi", "pinocchio.casadi")
    if name == "fatigue_pin._pinocchio_casadi":
        from fatigue_pin import _pinocchio_casadi as ext

        assert ext.casadi_version == ca.__version__
        assert ext.pinocchio_version == pin.__version__
    else:
        import pinocchio.casadi as cpin

        assert hasattr(cpin, "aba") and hasattr(cpin, "rnea")


def test_missing_extension_is_a_model_error(monkeypatch):
    import fatigue_pin

    monkeypatch.setitem(sys.modules, "pinocchio.casadi", None)
    monkeypatch.setitem(sys.modules, "fatigue_pin._pinocchio_casadi", None)
    monkeypatch.delattr(fatigue_pin, "_pinocchio_casadi", raising=False)
    with pytest.raises(ModelError, match="install fatigue_pin with pip"):
        dynamics.casadi_dynamics(pin.buildSampleModelManipulator())


def test_aba_derivatives_match_pinocchios_numeric_derivatives(model):
    """``casadi_aba_derivatives``: ddq, d ddq/dq, d ddq/dv against numeric
    ``pinocchio.computeABADerivatives``, and Minv against the inverse of CRBA's mass matrix."""
    rng = np.random.default_rng(11)
    q, v, tau = _random_states(model, rng)
    f = dynamics.casadi_aba_derivatives(model)
    assert f.name_out() == ["ddq", "ddq_dq", "ddq_dv", "Minv"]
    data = model.createData()
    for k in range(10):
        ddq, dq, dv, minv = (np.asarray(o) for o in f(q[:, k], v[:, k], tau[:, k]))
        pin.computeABADerivatives(model, data, q[:, k], v[:, k], tau[:, k])
        scale = max(1.0, np.abs(data.ddq_dq).max())
        _close(ddq.ravel(), _reference_aba(model, q[:, k:k + 1], v[:, k:k + 1], tau[:, k:k + 1]).ravel(), 1e-10)
        _close(dq, data.ddq_dq, 1e-10 * scale)
        _close(dv, data.ddq_dv, 1e-10 * scale)
        M = pin.crba(model, model.createData(), q[:, k])
        M = np.triu(M) + np.triu(M, 1).T
        _close(minv, np.linalg.inv(M), 1e-9 * max(1.0, np.abs(minv).max()))


def test_no_aba_derivatives_for_joints_whose_configuration_is_not_their_tangent():
    """A continuous joint (nq = 2, nv = 1): d/dq is not a derivative in q, so None."""
    model = pin.Model()
    joint = model.addJoint(0, pin.JointModelRUBZ(), pin.SE3.Identity(), "wheel")
    model.appendBodyToJoint(joint, pin.Inertia.FromCylinder(1.0, 0.1, 0.1), pin.SE3.Identity())
    assert model.nq == 2 and model.nv == 1
    assert dynamics.casadi_aba_derivatives(model) is None
