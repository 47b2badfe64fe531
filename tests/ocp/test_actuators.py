"""Tests of the signed torque actuators (fatigue_pin.ocp.actuators)."""

from __future__ import annotations

from types import SimpleNamespace

import casadi as ca
import numpy as np
import pytest

from fatigue_pin.ocp.actuators import ActuatorHalf, SignedTorqueActuators
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
    tp, tm = [25.0, 5.0], [-10.0, -25.0]
    np.testing.assert_allclose(num(act.target_loads(tp, tm)), [0.5, 0.25, 0.2, 0.5])
    np.testing.assert_allclose(num(act.joint_torque(tp, tm)), [15.0, -20.0])
    m = np.array([0.3, 0.6, 0.1, 0.2, 0.6, 0.2, 0.1, 0.6, 0.3, 0.0, 0.6, 0.4])
    np.testing.assert_allclose(num(act.coupling(m, tp, tm)), [0.6, 0.45, 0.5, 0.9])
    mf = num(act.split_states(m)[2])
    np.testing.assert_allclose(mf, [0.1, 0.2, 0.3, 0.4])
    np.testing.assert_allclose(num(act.available_torque(mf)), [45.0, -32.0, 17.5, -30.0])


def test_fatigue_rates_use_each_halfs_params(act):
    rng = np.random.default_rng(1)
    m = rng.uniform(0, 1, 12)
    tp, tm = [30.0, 20.0], [-10.0, -45.0]
    dm = num(act.fatigue_rates(m, tp, tm))
    TL = [30 / 50, 10 / 40, 20 / 25, 45 / 50]
    params = [SHOULDER, SHOULDER, ELBOW_PLUS, ELBOW_MINUS]
    expected = np.concatenate([rhs_numeric(0, m[3 * i : 3 * i + 3], TL[i], params[i]) for i in range(4)])
    np.testing.assert_allclose(dm, expected, atol=1e-14)


@pytest.mark.parametrize("sym", [ca.SX, ca.MX])
def test_symbolic(act, sym):
    m, tp, tm = sym.sym("m", 12), sym.sym("tp", 2), sym.sym("tm", 2)
    f = ca.Function("f", [m, tp, tm], [act.fatigue_rates(m, tp, tm), act.coupling(m, tp, tm), act.target_loads(tp, tm)])
    m0 = act.initial_state()
    dm, c, tl = f(m0, [50.0, 0.0], [0.0, -25.0])
    np.testing.assert_allclose(num(tl), [1.0, 0.0, 0.0, 0.5])
    np.testing.assert_allclose(num(c), [1.0, 0.0, 0.0, 0.5])
    # Rested shoulder_plus at TL = 1: C = LD (1 - 0) = 10.
    np.testing.assert_allclose(num(dm)[:3], [10.0, -10.0, 0.0])
    # Symbolic parameters.
    p = sym.sym("p", 24)
    g = ca.Function("g", [m, tp, tm, p], [act.fatigue_rates(m, tp, tm, p)])
    np.testing.assert_allclose(num(g(m0, [50.0, 0.0], [0.0, -25.0], act.param_vector())), num(dm))


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
    with pytest.raises(DimensionError, match="tau_plus"):
        act.target_loads([1.0, 2.0, 3.0], [0.0, 0.0])
    with pytest.raises(DimensionError, match="fatigue states"):
        act.fatigue_rates(np.zeros(11), [0.0, 0.0], [0.0, 0.0])
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
