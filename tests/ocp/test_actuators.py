"""Tests of the signed torque actuators (fatigue_pin.ocp.actuators)."""

from __future__ import annotations

from types import SimpleNamespace

import casadi as ca
import numpy as np
import pytest

from fatigue_pin.ocp.actuators import Actuation, ActuatorHalf, SignedTorqueActuators
from fatigue_pin.core.errors import DimensionError, ParameterError
from fatigue_pin.fatigue.models import FatigueParams
from fatigue_pin.fatigue.simulation import rhs_numeric
from fatigue_pin.paper.curl import elbow_params

MODEL = SimpleNamespace(
    joint_names=("shoulder", "elbow"), tau_lower=np.array([-40.0, -50.0]), tau_upper=np.array([50.0, 25.0])
)
SHOULDER = FatigueParams(LD=10, LR=10, F=0.5, R=0.01, S=10)
ELBOW_PLUS = FatigueParams(LD=5, LR=8, F=0.3, R=0.02, S=5)
ELBOW_MINUS = FatigueParams(LD=7, LR=9, F=0.2, R=0.03, S=0, r=2)


@pytest.fixture
def act() -> SignedTorqueActuators:
    return SignedTorqueActuators.from_model(MODEL, {"shoulder": SHOULDER, "elbow": (ELBOW_PLUS, ELBOW_MINUS)})


def num(x) -> np.ndarray:
    return np.asarray(ca.DM(x).full()).ravel()


def test_layout(act):
    assert act.nv == 2 and act.n_halves == 4 and act.n_states == 12
    assert act.half_names == ("shoulder_plus", "shoulder_minus", "elbow_plus", "elbow_minus")
    assert act.state_names[:4] == ("shoulder_plus_ma", "shoulder_plus_mr", "shoulder_plus_mf", "shoulder_minus_ma")
    np.testing.assert_array_equal(act.signed_limits, [50, -40, 25, -50])
    np.testing.assert_array_equal(act.tau_plus_limits, [50, 25])
    np.testing.assert_array_equal(act.tau_minus_limits, [-40, -50])
    assert act.halves[1].tau_bounds == (-40.0, 0.0) and act.halves[2].tau_bounds == (0.0, 25.0)
    assert act.params_of("elbow_minus") is ELBOW_MINUS and act.params_of("shoulder_minus") is SHOULDER
    np.testing.assert_array_equal(act.initial_state(), [0, 1, 0] * 4)
    p = act.param_vector()
    assert p.shape == (24,)
    np.testing.assert_array_equal(p[12:18], ELBOW_PLUS.as_vector())


def test_target_loads_coupling_available_torque(act):
    u = [25.0, 5.0, -10.0, -25.0]  # (tau_plus, tau_minus)
    np.testing.assert_allclose(num(act.target_loads(u)), [0.5, 0.25, 0.2, 0.5])
    np.testing.assert_allclose(num(act.joint_torque(ca.DM(u))), [15.0, -20.0])
    np.testing.assert_allclose(act.joint_torque(np.array([u, u])), [[15.0, -20.0]] * 2)
    m = np.array([0.3, 0.6, 0.1, 0.2, 0.6, 0.2, 0.1, 0.6, 0.3, 0.0, 0.6, 0.4])
    np.testing.assert_allclose(num(act.coupling(m, u)), [0.6, 0.45, 0.5, 0.9])
    mf = num(act.split_states(m)[2])
    np.testing.assert_allclose(mf, [0.1, 0.2, 0.3, 0.4])
    np.testing.assert_allclose(num(act.available_torque(mf)), [45.0, -32.0, 17.5, -30.0])


def test_fatigue_rates_use_each_halfs_params(act):
    rng = np.random.default_rng(1)
    m = rng.uniform(0, 1, 12)
    dm = num(act.fatigue_rates(m, [30.0, 20.0, -10.0, -45.0]))
    TL = [30 / 50, 10 / 40, 20 / 25, 45 / 50]
    params = [SHOULDER, SHOULDER, ELBOW_PLUS, ELBOW_MINUS]
    expected = np.concatenate([rhs_numeric(0, m[3 * i : 3 * i + 3], TL[i], params[i]) for i in range(4)])
    np.testing.assert_allclose(dm, expected, atol=1e-14)


@pytest.mark.parametrize("sym", [ca.SX, ca.MX])
def test_symbolic(act, sym):
    m, u = sym.sym("m", 12), sym.sym("u", 4)
    f = ca.Function("f", [m, u], [act.fatigue_rates(m, u), act.coupling(m, u), act.target_loads(u)])
    m0 = act.initial_state()
    dm, c, tl = f(m0, [50.0, 0.0, 0.0, -25.0])
    np.testing.assert_allclose(num(tl), [1.0, 0.0, 0.0, 0.5])
    np.testing.assert_allclose(num(c), [1.0, 0.0, 0.0, 0.5])
    # Rested shoulder_plus at TL = 1: C = LD (1 - 0) = 10.
    np.testing.assert_allclose(num(dm)[:3], [10.0, -10.0, 0.0])
    # Symbolic parameters.
    p = sym.sym("p", 24)
    g = ca.Function("g", [m, u, p], [act.fatigue_rates(m, u, p)])
    np.testing.assert_allclose(num(g(m0, [50.0, 0.0, 0.0, -25.0], act.param_vector())), num(dm))


def test_one_params_for_all():
    act = SignedTorqueActuators.from_limits(["a", "b", "c"], [-1, -2, -3], [1, 2, 3], elbow_params())
    assert act.n_halves == 6 and all(h.params == elbow_params() for h in act.halves)


def test_bad_params_dicts():
    with pytest.raises(ParameterError, match=r"unknown joint\(s\) \['wrist'\]"):
        SignedTorqueActuators.from_model(MODEL, {"shoulder": SHOULDER, "elbow": SHOULDER, "wrist": SHOULDER})
    with pytest.raises(ParameterError, match=r"no fatigue params for joint\(s\) \['elbow'\]"):
        SignedTorqueActuators.from_model(MODEL, {"shoulder": SHOULDER})
    with pytest.raises(ParameterError, match="elbow"):
        SignedTorqueActuators.from_model(MODEL, {"shoulder": SHOULDER, "elbow": (SHOULDER,)})
    with pytest.raises(ParameterError, match="expected a FatigueParams"):
        SignedTorqueActuators.from_model(MODEL, 3.0)


def test_bad_limits_and_shapes(act):
    with pytest.raises(ParameterError, match="tau_lower of joint 'b'"):
        SignedTorqueActuators.from_limits(["a", "b"], [-1, 0], [1, 1], SHOULDER)
    with pytest.raises(ParameterError, match="tau_upper of joint 'a'"):
        SignedTorqueActuators.from_limits(["a", "b"], [-1, -1], [-1, 1], SHOULDER)
    with pytest.raises(DimensionError):
        SignedTorqueActuators.from_limits(["a", "b"], [-1], [1, 1], SHOULDER)
    with pytest.raises(DimensionError, match="controls u"):
        act.target_loads([1.0, 2.0, 3.0])
    with pytest.raises(DimensionError, match="fatigue states"):
        act.fatigue_rates(np.zeros(11), [0.0] * 4)
    with pytest.raises(ParameterError, match="sign"):
        ActuatorHalf("a", 0, 1.0, SHOULDER)
    with pytest.raises(ParameterError, match="tau_limit"):
        ActuatorHalf("a", 1, -1.0, SHOULDER)
    with pytest.raises(ParameterError, match="plus then the minus"):
        SignedTorqueActuators([ActuatorHalf("a", -1, 1.0, SHOULDER), ActuatorHalf("a", 1, 1.0, SHOULDER)])


def test_stabiliser_check_names_the_half():
    act = SignedTorqueActuators.from_model(MODEL, {"shoulder": SHOULDER, "elbow": SHOULDER.with_(S=1000.0)})
    with pytest.raises(ParameterError, match="elbow_plus"):
        act.check_stabiliser(0.004, "rk4")
    SignedTorqueActuators.from_model(MODEL, SHOULDER).check_stabiliser(0.004, "rk4")


# -- passive joints and couplings ------------------------------------------------------------------

THREE = SimpleNamespace(joint_names=("a", "b", "c"), tau_lower=np.array([-10.0, 0.0, -30.0]), tau_upper=np.array([20.0, 0.0, 40.0]))


def test_a_zero_effort_joint_and_a_named_joint_are_passive():
    """Joint b has a zero effort limit (passive by the model), joint c is named passive: only a
    keeps halves; the controls are its two halves, and the joint torque has zeros at b and c."""
    act = SignedTorqueActuators.from_model(THREE, SHOULDER, Actuation(passive=("c",)))
    assert act.joint_names == ("a", "b", "c") and act.actuated_joints == ("a",) and act.passive_joints == ("b", "c")
    assert act.nv == 3 and act.nu == 2 and act.half_names == ("a_plus", "a_minus") and act.n_states == 6
    np.testing.assert_array_equal(act.torque_matrix(), [[1, 1], [0, 0], [0, 0]])
    np.testing.assert_allclose(num(act.joint_torque(ca.DM([5.0, -2.0]))), [3.0, 0.0, 0.0])
    plus, minus = act.per_joint(np.array([[5.0, -2.0]]))
    np.testing.assert_array_equal(plus, [[5.0, 0.0, 0.0]]) and np.testing.assert_array_equal(minus, [[-2.0, 0.0, 0.0]])
    np.testing.assert_array_equal(act.controls(act.half_torques(np.array([5.0, -2.0]))), [5.0, -2.0])
    lo, hi = act.control_bounds()
    np.testing.assert_array_equal(lo, [0.0, -10.0]) and np.testing.assert_array_equal(hi, [20.0, 0.0])
    # every joint passive, or a passive joint that is not a joint
    with pytest.raises(ParameterError, match="expected at least one actuated joint"):
        SignedTorqueActuators.from_model(THREE, SHOULDER, Actuation(passive=("a", "c")))
    with pytest.raises(ParameterError, match="actuators.passive names joint 'd'"):
        SignedTorqueActuators.from_model(THREE, SHOULDER, Actuation(passive=("d",)))


def test_the_controls_order_with_a_passive_joint_between():
    """Halves of joints a and c around the passive b: controls (a+, c+, a-, c-), rows of the halves."""
    act = SignedTorqueActuators.from_model(THREE, SHOULDER)
    assert act.half_names == ("a_plus", "a_minus", "c_plus", "c_minus") and act.control_rows() == [0, 2, 1, 3]
    u = np.array([10.0, 20.0, -5.0, -15.0])
    np.testing.assert_allclose(act.joint_torque(u), [5.0, 0.0, 5.0])
    np.testing.assert_allclose(act.half_torques(u), [10.0, -5.0, 20.0, -15.0])
    np.testing.assert_allclose(num(act.target_loads(u)), [0.5, 0.5, 0.5, 0.5])


def test_the_active_coupling_delivers_ma_times_the_limit():
    """Under ``active`` the joint torque is sum_h ma_h * signed limit_h, whatever the controls."""
    act = SignedTorqueActuators.from_model(MODEL, SHOULDER, Actuation(coupling="active"))
    m = np.array([0.3, 0.6, 0.1, 0.2, 0.6, 0.2, 0.1, 0.6, 0.3, 0.0, 0.6, 0.4])  # ma = 0.3, 0.2, 0.1, 0.0
    expected = [0.3 * 50 - 0.2 * 40, 0.1 * 25 - 0.0 * 50]
    np.testing.assert_allclose(num(act.joint_torque(ca.DM([1.0, 2.0, -3.0, -4.0]), ca.DM(m))), expected)
    np.testing.assert_allclose(act.joint_torque(np.zeros((1, 4)), m[None, :]), [expected])
    with pytest.raises(ParameterError, match="expected the fatigue states m"):
        act.joint_torque(ca.DM.zeros(4))
    assert act.coupling_kind == "active" and not act.coupling_rows
    assert SignedTorqueActuators.from_model(MODEL, SHOULDER).coupling_rows


def test_actuation_settings_are_checked():
    with pytest.raises(ParameterError, match=r"Actuation.coupling = 'both': expected one of \['tl\+mf<=1', 'observed', 'active'\]"):
        Actuation(coupling="both")
    with pytest.raises(ParameterError, match="Actuation.passive = 'a': expected a list of joint names"):
        Actuation(passive="a")
