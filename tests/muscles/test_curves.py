"""The De Groote-Fregly curves against Moco's constants and formulas, written out here again."""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest

from fatigue_pin.muscles import curves

# OpenSim Moco, DeGrooteFregly2016Muscle: b11..b43, d1..d4, kPE, c1..c3 (typed again from Moco's source)
B = [(0.8150671134243542, 1.055033428970575, 0.162384573599574, 0.063303448465465),
     (0.433004984392647, 0.716775413397760, -0.029947116970696, 0.200356847296188),
     (0.1, 1.0, 0.353553390593274, 0.0)]
D1, D2, D3, D4 = -0.3211346127989808, -8.149, -0.374, 0.8825327733249912


def moco_fl(l):
    return sum(b1 * math.exp(-0.5 * (l - b2) ** 2 / (b3 + b4 * l) ** 2) for b1, b2, b3, b4 in B)


def moco_fpe(l, e0=0.6):
    off = math.exp(4 * (0.2 - 1) / e0)
    return (math.exp(4 * (l - 1) / e0) - off) / (math.exp(4) - off)


def moco_fv(v):
    return D1 * math.asinh(D2 * v + D3) + D4


def moco_ft(lt, e0=0.049):
    kt = math.log((1 + 0.2) / 0.2) / (1 + e0 - 1)
    return 0.2 * math.exp(kt * (lt - 1)) - 0.2


SAMPLES = np.linspace(0.3, 1.8, 16)


@pytest.mark.parametrize("l", SAMPLES)
def test_force_length_curves_are_mocos(l):
    assert curves.active_force_length(l) == pytest.approx(moco_fl(l), abs=1e-12)
    assert curves.passive_force_length(l) == pytest.approx(moco_fpe(l), abs=1e-12)


@pytest.mark.parametrize("v", np.linspace(-1, 1, 11))
def test_force_velocity_is_mocos_and_inverts(v):
    assert curves.force_velocity(v) == pytest.approx(moco_fv(v), abs=1e-12)
    assert curves.force_velocity_inverse(curves.force_velocity(v)) == pytest.approx(v, abs=1e-12)


@pytest.mark.parametrize("lt", [0.98, 1.0, 1.02, 1.049, 1.06])
def test_tendon_curve_is_mocos_and_inverts(lt):
    assert curves.tendon_force_length(lt) == pytest.approx(moco_ft(lt), abs=1e-12)
    assert curves.tendon_length(curves.tendon_force_length(lt)) == pytest.approx(lt, abs=1e-12)


def test_the_curves_hit_their_anchor_points():
    assert curves.active_force_length(1.0) == pytest.approx(1.0, abs=1e-12)
    assert curves.force_velocity(0.0) == pytest.approx(1.0, abs=1e-12)
    assert curves.force_velocity(-1.0) == pytest.approx(0.0, abs=1e-12)
    assert curves.passive_force_length(0.2) == pytest.approx(0.0, abs=1e-15)
    assert curves.passive_force_length(1.6) == pytest.approx(1.0, abs=1e-12)
    assert curves.tendon_force_length(1.0) == pytest.approx(0.0, abs=1e-12)
    assert curves.tendon_force_length(1.049) == pytest.approx(1.0, abs=1e-12)


def test_symbolic_numpy_and_float_agree():
    x = ca.SX.sym("x")
    for curve in (curves.active_force_length, curves.passive_force_length, curves.force_velocity):
        f = ca.Function("f", [x], [curve(x)])
        arr = np.array([0.4, 0.9, 1.3])
        assert np.allclose(np.array(f(arr.reshape(1, -1))).ravel(), curve(arr), atol=1e-14)
        assert np.allclose(curve(arr), [curve(float(a)) for a in arr], atol=1e-14)


def test_activation_rises_and_falls_at_the_time_constants():
    # with a steep smoothing the rate is (e - a) / (tau_act (0.5 + 1.5 a)) rising, (e - a)(0.5 + 1.5 a) / tau_deact falling
    tau_a, tau_d = 0.015, 0.060
    rise = curves.activation_rate(1.0, 0.2, tau_a, tau_d, 1000.0)
    fall = curves.activation_rate(0.0, 0.8, tau_a, tau_d, 1000.0)
    assert rise == pytest.approx(0.8 / (tau_a * (0.5 + 1.5 * 0.2)), rel=1e-9)
    assert fall == pytest.approx(-0.8 * (0.5 + 1.5 * 0.8) / tau_d, rel=1e-9)
    assert curves.activation_rate(0.4, 0.4, tau_a, tau_d, 0.1) == 0.0
