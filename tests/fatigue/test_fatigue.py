"""Tests of the 3CC / 3CC-S / 3CC-r fatigue dynamics (fatigue_pin.fatigue.models)."""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest

from fatigue_pin.core.errors import DimensionError, ParameterError
from fatigue_pin.paper.curl import elbow_params, ocp_params
from fatigue_pin.fatigue.interface import STABILITY_LIMITS, check_stabiliser
from fatigue_pin.fatigue.models import FatigueParams, fatigue_rhs
from fatigue_pin.fatigue.simulation import invariant_error, rhs_numeric, simulate

# Round numbers so the expected rates can be worked out by hand.
P = FatigueParams(LD=2.0, LR=3.0, F=0.1, R=0.05)


def rates(m, TL, params=P):
    return rhs_numeric(0.0, np.asarray(m, dtype=float), TL, params)


# -- the three branches of C, by hand ------------------------------------------------------------


def test_branch_1_develop_towards_target():
    # ma < TL and mr >= TL - ma: C = LD (TL - ma) = 2 * 0.3 = 0.6
    np.testing.assert_allclose(rates([0.2, 0.7, 0.1], 0.5), [0.6 - 0.02, -0.6 + 0.005, 0.02 - 0.005], atol=1e-15)


def test_branch_2_limited_by_resting_pool():
    # ma < TL and mr < TL - ma: C = LD mr = 2 * 0.1 = 0.2
    np.testing.assert_allclose(rates([0.2, 0.1, 0.7], 0.5), [0.2 - 0.02, -0.2 + 0.035, 0.02 - 0.035], atol=1e-15)


def test_branch_3_relax_towards_target():
    # ma >= TL: C = LR (TL - ma) = 3 * (-0.1) = -0.3
    np.testing.assert_allclose(rates([0.6, 0.3, 0.1], 0.5), [-0.3 - 0.06, 0.3 + 0.005, 0.06 - 0.005], atol=1e-15)


def test_branch_boundaries():
    # ma == TL belongs to branch 3: C = LR * 0 = 0.
    np.testing.assert_allclose(rates([0.5, 0.4, 0.1], 0.5), [-0.05, 0.005, 0.05 - 0.005], atol=1e-15)
    # mr == TL - ma belongs to branch 1 (and branch 2 gives the same value there: C is continuous).
    np.testing.assert_allclose(rates([0.25, 0.25, 0.5], 0.5)[0], 2 * 0.25 - 0.025, atol=1e-15)


def test_stabiliser_acts_on_mf_only():
    m = [0.2, 0.7, 0.2]  # sum 1.1
    base = rates(m, 0.5)
    stab = rates(m, 0.5, P.with_(S=4.0))
    np.testing.assert_allclose(stab - base, [0.0, 0.0, 4.0 * (1 - 1.1)], atol=1e-15)


@pytest.mark.parametrize("S", [0.0, 3.0, 10.0])
def test_sum_of_rates_is_stabiliser_term_in_every_branch(S):
    rng = np.random.default_rng(0)
    for _ in range(200):
        m = rng.uniform(-0.1, 1.1, 3)
        TL = rng.uniform(0, 1)
        dm = rates(m, TL, P.with_(S=S, r=2.5))
        assert dm.sum() == pytest.approx(S * (1 - m.sum()), abs=1e-14)


def test_rest_recovery_multiplier_3ccr():
    pr = P.with_(r=3.0)
    # ma >= TL (branch 3): R is multiplied by r in dmr and dmf.
    np.testing.assert_allclose(rates([0.6, 0.3, 0.1], 0.5, pr), [-0.36, 0.3 + 0.015, 0.06 - 0.015], atol=1e-15)
    # ma < TL: r has no effect.
    np.testing.assert_allclose(rates([0.2, 0.7, 0.1], 0.5, pr), rates([0.2, 0.7, 0.1], 0.5), atol=1e-15)
    # Rest (TL = 0) from a fatigued state recovers r times faster at first.
    m = [0.0, 0.5, 0.5]
    assert rates(m, 0.0, pr)[1] == pytest.approx(3.0 * rates(m, 0.0)[1])


# -- the casadi function ----------------------------------------------------------------------------


@pytest.mark.parametrize("m, TL, r_acts", [
    ([0.0, 0.6, 0.4], 0.0, True),     # rest: ma >= TL = 0
    ([0.4, 0.3, 0.3], 0.2, False),    # relaxing at a load: r acts only with rest_load >= 0.2
    ([0.1, 0.6, 0.3], 0.2, False),    # developing: never
])
def test_rest_load_option_selects_where_r_acts(m, TL, r_acts):
    base = P.with_(r=10.0)
    rest_only = base.with_(rest_load=0.0)
    R_eff = (10.0 if r_acts else 1.0) * P.R
    dm = rest_only.rates(m, TL)
    np.testing.assert_allclose(dm[2] - P.F * m[0], -R_eff * m[2], atol=1e-15)
    # the default (rest_load = 1): r on the whole relaxation branch ma >= TL, as before the option
    np.testing.assert_allclose(base.rates(m, TL)[2] - P.F * m[0], -(10.0 if m[0] >= TL else 1.0) * P.R * m[2], atol=1e-15)
    np.testing.assert_allclose(base.with_(rest_load=0.2).rates(m, TL), base.rates(m, TL), atol=1e-15)


def test_rest_load_default_keeps_the_equations_and_is_validated():
    assert P.rest_load == 1.0 and "rest_load" not in P.as_dict()  # result files and studies unchanged
    assert P.rhs().serialize() == fatigue_rhs().serialize() == fatigue_rhs(1.0).serialize()
    assert P.with_(rest_load=0.0).structure_key() != P.structure_key()
    assert P.with_(rest_load=0.0).as_dict()["rest_load"] == 0.0
    for bad in (-0.1, 1.5, math.nan, "0", True):
        with pytest.raises(ParameterError, match=r"XiaFatigue\.rest_load = .*expected a target load in \[0, 1\]"):
            P.with_(rest_load=bad)


def test_fatigue_rhs_is_built_once_and_symbolic():
    f = fatigue_rhs()
    assert f is fatigue_rhs()
    assert f.name_in() == ["m", "TL", "p"] and f.name_out() == ["dm"]
    assert f.size_in(0) == (3, 1) and f.size_in(2) == (6, 1) and f.size_out(0) == (3, 1)
    for sym in (ca.SX, ca.MX):
        m, tl, p = sym.sym("m", 3), sym.sym("tl"), sym.sym("p", 6)
        g = ca.Function("g", [m, tl, p], [f(m, tl, p)])
        np.testing.assert_allclose(
            g([0.2, 0.7, 0.1], 0.5, P.as_vector()).full().ravel(), rates([0.2, 0.7, 0.1], 0.5), atol=1e-15
        )


def test_rhs_numeric_checks_size():
    with pytest.raises(DimensionError, match="3 entries"):
        rhs_numeric(0.0, [0.0, 1.0], 0.5, P)
    with pytest.raises(DimensionError, match="6 entries"):
        rhs_numeric(0.0, [0.0, 1.0, 0.0], 0.5, [1.0, 2.0])


# -- invariant ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("S", [0.0, 10.0])
def test_exact_invariant_from_rest(S):
    tr = simulate(elbow_params(S=S), 0.8, (0.0, 1.0, 0.0), 60.0, method="DOP853", rtol=1e-12, atol=1e-12)
    assert tr.success
    assert np.max(tr.invariant_error) < 1e-10


def test_perturbed_sum_decays_like_exp_minus_S_t():
    S = 5.0
    t = np.linspace(0.0, 4.0, 401)
    tr = simulate(elbow_params(S=S), 0.8, (0.0, 1.0001, 0.0), 4.0, t_eval=t, method="DOP853", rtol=1e-12, atol=1e-14)
    assert tr.success
    expected = -1e-4 * np.exp(-S * t)  # 1 - sum(t) = (1 - sum0) exp(-S t)
    np.testing.assert_allclose(1.0 - tr.total, expected, rtol=0, atol=1e-13)


def test_3cc_equals_3ccs_from_consistent_start():
    t = np.linspace(0.0, 60.0, 601)
    a = simulate(elbow_params(S=0.0), 0.8, (0.0, 1.0, 0.0), 60.0, t_eval=t)
    b = simulate(elbow_params(S=10.0), 0.8, (0.0, 1.0, 0.0), 60.0, t_eval=t)
    assert np.max(np.abs(a.m - b.m)) < 1e-12


def test_simulate_time_varying_load():
    # TL(t) = 0 (rest) then 0.5: ma stays 0 while resting, then rises towards 0.5.
    tr = simulate(P, lambda t: 0.0 if t < 1.0 else 0.5, (0.0, 1.0, 0.0), 4.0, t_eval=np.array([0.5, 4.0]), max_step=0.05)
    assert abs(tr.ma[0]) < 1e-12 and tr.ma[1] == pytest.approx(0.5, abs=0.05)


def test_invariant_error_shapes():
    assert invariant_error([0.2, 0.7, 0.1]) == pytest.approx(0.0, abs=1e-15)
    np.testing.assert_allclose(invariant_error(np.array([[0.0, 0.1], [1.0, 1.0], [0.0, 0.1]])), [0.0, 0.2], atol=1e-15)
    with pytest.raises(DimensionError):
        invariant_error(np.zeros((2, 5)))


# -- parameters ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("field", ["LD", "LR", "F", "R", "S", "r"])
@pytest.mark.parametrize("bad", [-0.1, math.nan, math.inf, "1", True])
def test_bad_fields_raise_naming_the_field(field, bad):
    kwargs = dict(LD=10.0, LR=10.0, F=0.1, R=0.01, S=0.0, r=1.0)
    kwargs[field] = bad
    with pytest.raises(ParameterError, match=rf"XiaFatigue\.{field} = .*expected a finite"):
        FatigueParams(**kwargs)


def test_presets_and_with():
    e = elbow_params()
    assert (e.LD, e.LR, e.F, e.R, e.S, e.r) == (10.0, 10.0, 0.00912, 0.00094, 0.0, 1.0)
    assert ocp_params().R == 0.0094 and ocp_params("paper").R == 0.00094
    assert ocp_params().F == 0.456 and ocp_params().S == 10.0
    assert e.with_(S=5).S == 5.0 and e.S == 0.0
    with pytest.raises(ParameterError, match="XiaFatigue.S"):
        e.with_(S=-1)
    with pytest.raises(ParameterError, match="unknown field"):
        e.with_(Q=1)
    with pytest.raises(ParameterError, match="preset"):
        ocp_params("other")
    np.testing.assert_array_equal(e.as_vector(), [10, 10, 0.00912, 0.00094, 0, 1])


# -- stabiliser check ---------------------------------------------------------------------------------


def test_stabiliser_check_rk4():
    dt = 0.02 / 5
    amp = check_stabiliser(ocp_params(), dt, "rk4")  # S dt = 0.04
    z = -0.04
    assert amp == pytest.approx(1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24)
    limit = STABILITY_LIMITS["rk4"]
    assert check_stabiliser(0.99 * limit / dt, dt) > -1.0
    with pytest.raises(ParameterError, match=r"S = 700.0.*dt = 0.004.*2.78529"):
        check_stabiliser(ocp_params(S=700.0), dt, "rk4")


def test_stabiliser_check_other_methods():
    with pytest.raises(ParameterError, match="must be < 2"):
        check_stabiliser(100.0, 0.02, "euler")
    assert check_stabiliser(99.0, 0.02, "euler") == pytest.approx(1 - 1.98)
    assert check_stabiliser(1e6, 0.02, "RK45") is None  # adaptive: not checked
    with pytest.raises(ParameterError, match="method"):
        check_stabiliser(10.0, 0.01, "trapezoid")
    with pytest.raises(ParameterError, match="dt"):
        check_stabiliser(10.0, 0.0)
