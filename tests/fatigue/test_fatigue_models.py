"""Tests of Michaud's fatigue model (fatigue_pin.fatigue.michaud.MichaudFatigue) and of mixing models."""

from __future__ import annotations

from types import SimpleNamespace

import casadi as ca
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from fatigue_pin.ocp.actuators import SignedTorqueActuators
from fatigue_pin.core.errors import ParameterError
from fatigue_pin.fatigue.michaud import MichaudFatigue
from fatigue_pin.fatigue.models import FATIGUE_MODELS, XiaFatigue, fatigue_model

# Round numbers so the rates can be worked out by hand.
M = MichaudFatigue(LD=2.0, LR=3.0, F=0.1, R=0.05, effort_threshold=0.2, effort_factor=0.5, stabilization_factor=4.0)


def test_registered_and_described():
    assert FATIGUE_MODELS["michaud"] is MichaudFatigue
    m = fatigue_model("michaud", LD=2, LR=3, F=0.1, R=0.05, effort_threshold=0.2, effort_factor=0.5)
    assert m.stabilization_factor == 1.0  # bioptim's default
    assert MichaudFatigue.state_names == ("ma", "mr", "mf", "E") and MichaudFatigue.fatigued_state == "mf"
    np.testing.assert_array_equal(MichaudFatigue.rest_state(), [0, 1, 0, 0])
    assert M.as_vector().tolist() == [2.0, 3.0, 0.1, 0.05, 0.2, 0.5, 4.0]


def test_rhs_above_threshold_by_hand():
    # TL = 0.5 > th = 0.2, ma < TL, mr = 0.7 > TL - ma: C = LD (TL - ma) = 0.6;
    # e = k (TL - th) (1 - E) / (1 - th) = 0.5 * 0.3 * 0.95 / 0.8 = 0.178125, taken from ma.
    e = 0.5 * 0.3 * 0.95 / 0.8
    np.testing.assert_allclose(
        M.rates([0.2, 0.7, 0.05, 0.05], 0.5), [0.6 - 0.02 - e, -0.6 + 0.0025, 0.02 - 0.0025, e], atol=1e-15
    )


def test_rhs_below_threshold_by_hand():
    # TL = 0.1 < th, ma >= TL: C = LR (TL - ma) = -1.5; e = k (TL - th) E / th = -0.0125, given back to mr.
    e = 0.5 * (0.1 - 0.2) * 0.05 / 0.2
    np.testing.assert_allclose(
        M.rates([0.6, 0.3, 0.05, 0.05], 0.1), [-1.5 - 0.06, 1.5 + 0.0025 - e, 0.06 - 0.0025, e], atol=1e-15
    )


def test_rhs_resting_pool_branch_and_stabiliser_on_E_only():
    # mr = 0.1 < TL - ma = 0.3: C = LD mr = 0.2. Sum 1.1: the stabiliser adds S (1 - 1.1) to dE only.
    m = [0.2, 0.1, 0.7, 0.1]
    base = M.with_(stabilization_factor=0.0).rates(m, 0.5)
    e = 0.5 * 0.3 * 0.9 / 0.8
    np.testing.assert_allclose(base, [0.2 - 0.02 - e, -0.2 + 0.035, 0.02 - 0.035, e], atol=1e-15)
    np.testing.assert_allclose(M.rates(m, 0.5) - base, [0, 0, 0, 4.0 * (1 - 1.1)], atol=1e-15)


@pytest.mark.parametrize("TL", [0.0, 0.1, 0.2, 0.5, 0.9])
def test_sum_rate_is_stabiliser_term(TL):
    rng = np.random.default_rng(3)
    for _ in range(20):
        m = rng.uniform(0, 0.5, 4)
        assert M.rates(m, TL).sum() == pytest.approx(4.0 * (1 - m.sum()), abs=1e-14)


def _simulate(model, TL, t_end, m0):
    f = model.rhs()
    p = model.as_vector()
    return solve_ivp(lambda t, y: f(y, TL(t), p).full().ravel(), (0, t_end), m0, method="LSODA", rtol=1e-10,
                     atol=1e-12, max_step=0.5)


def test_forward_simulation_conserves_the_four_state_sum_and_builds_effort():
    # Without stabiliser, ma + mr + mf + E = 1 is conserved exactly by the equations (not ma + mr + mf).
    model = MichaudFatigue(LD=10, LR=10, F=0.02, R=0.002, effort_threshold=0.2, effort_factor=0.05, stabilization_factor=0)
    out = _simulate(model, lambda t: 0.4 if t < 20 else 0.05, 60.0, model.rest_state())
    assert out.success
    total = out.y.sum(axis=0)
    np.testing.assert_allclose(total, 1.0, atol=1e-9)
    E = out.y[3]
    k20 = np.searchsorted(out.t, 20.0) - 1
    assert E[k20] > 0.1  # effort built up above the threshold
    assert E[-1] < 0.8 * E[k20]  # and relaxes below it, back into mr
    assert np.ptp(out.y[0] + out.y[1] + out.y[2]) > 0.1  # the three Xia states alone do not sum to 1
    assert np.all(out.y > -1e-9) and np.all(out.y < 1 + 1e-9)


def test_effort_drains_ma_below_zero_once_mr_is_exhausted_as_in_bioptim():
    # bioptim's effort flux k (TL - th) (1 - E) / (1 - th) does not scale with ma: once mr is used up,
    # it keeps draining ma below 0. bioptim's OCPs bound every state to [0, 1]; the equations do not.
    model = MichaudFatigue(LD=10, LR=10, F=0.02, R=0.002, effort_threshold=0.2, effort_factor=0.05, stabilization_factor=0)
    out = _simulate(model, lambda t: 0.6, 60.0, model.rest_state())
    assert out.y[0].min() < -0.01
    np.testing.assert_allclose(out.y.sum(axis=0), 1.0, atol=1e-9)


@pytest.mark.parametrize("delta", [1e-3, -1e-3])
def test_stabiliser_pulls_a_perturbed_sum_back(delta):
    S = 5.0
    model = MichaudFatigue(LD=10, LR=10, F=0.02, R=0.002, effort_threshold=0.2, effort_factor=0.05, stabilization_factor=S)
    m0 = np.array([0.0, 1.0 + delta, 0.0, 0.0])
    out = _simulate(model, lambda t: 0.5, 4.0, m0)
    err = 1.0 - out.y.sum(axis=0)
    # Exact: e(t) = e(0) exp(-S t) on every branch.
    np.testing.assert_allclose(err, -delta * np.exp(-S * out.t), rtol=1e-5, atol=1e-10)
    unstab = _simulate(model.with_(stabilization_factor=0.0), lambda t: 0.5, 4.0, m0)
    np.testing.assert_allclose(1.0 - unstab.y.sum(axis=0), -delta, atol=1e-9)


def test_bad_parameters():
    with pytest.raises(ParameterError, match="effort_threshold = 0.0"):
        M.with_(effort_threshold=0.0)
    with pytest.raises(ParameterError, match="effort_threshold = 1.0"):
        M.with_(effort_threshold=1.0)
    with pytest.raises(ParameterError, match="effort_factor = -1.0"):
        M.with_(effort_factor=-1.0)
    with pytest.raises(ParameterError, match="needs parameter"):
        fatigue_model("michaud", LD=1, LR=1, F=1, R=1)


def test_check_step_uses_the_stabiliser():
    M.check_step(0.004, "rk4")
    with pytest.raises(ParameterError, match="S\\*dt"):
        M.with_(stabilization_factor=1000.0).check_step(0.004, "rk4")


def test_actuators_with_halves_of_different_models():
    xia = XiaFatigue(LD=10, LR=10, F=0.5, R=0.01, S=10)
    mich = MichaudFatigue(LD=10, LR=10, F=0.3, R=0.02, effort_threshold=0.2, effort_factor=0.1, stabilization_factor=5)
    model = SimpleNamespace(joint_names=("shoulder", "elbow"), tau_lower=np.array([-40.0, -50.0]),
                            tau_upper=np.array([50.0, 25.0]))
    act = SignedTorqueActuators.from_model(model, {"shoulder": xia, "elbow": (mich, xia)})
    assert act.n_states == 3 + 3 + 4 + 3 and act.n_params == 6 + 6 + 7 + 6
    assert act.state_offsets() == [0, 3, 6, 10]
    assert act.state_names[6:10] == ("elbow_plus_ma", "elbow_plus_mr", "elbow_plus_mf", "elbow_plus_E")
    assert act.fatigued_rows() == [2, 5, 8, 12]
    np.testing.assert_array_equal(act.initial_state(), [0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 0, 1, 0])

    rng = np.random.default_rng(0)
    m = rng.uniform(0, 0.5, act.n_states)
    u = np.array([20.0, 10.0, -8.0, -30.0])  # (tau_plus, tau_minus)
    rates = np.asarray(ca.DM(act.fatigue_rates(m, u)).full()).ravel()
    TL = [20 / 50, 8 / 40, 10 / 25, 30 / 50]
    np.testing.assert_allclose(rates[0:3], xia.rates(m[0:3], TL[0]), atol=1e-15)
    np.testing.assert_allclose(rates[3:6], xia.rates(m[3:6], TL[1]), atol=1e-15)
    np.testing.assert_allclose(rates[6:10], mich.rates(m[6:10], TL[2]), atol=1e-15)
    np.testing.assert_allclose(rates[10:13], xia.rates(m[10:13], TL[3]), atol=1e-15)
    # The same with the parameter vector as a symbol (as an OCP passes it).
    p = ca.SX.sym("p", act.n_params)
    f = ca.Function("f", [p], [act.fatigue_rates(m, u, p)])
    np.testing.assert_allclose(np.asarray(f(act.param_vector())).ravel(), rates, atol=1e-15)
    coupling = np.asarray(ca.DM(act.coupling(m, u)).full()).ravel()
    np.testing.assert_allclose(coupling, np.array(TL) + m[[2, 5, 8, 12]], atol=1e-15)
    act.check_stabiliser(0.004, "rk4")
    assert "michaud" in act.structure_key()
