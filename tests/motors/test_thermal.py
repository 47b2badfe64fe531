"""The two-node network against its closed forms and an independent integration."""

from __future__ import annotations

import numpy as np
import pytest

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.motors.presets import MOTOR_PRESETS
from fatigue_pin.motors.thermal import ThermalNetwork

from conftest import integrate, network_ode, step_from_ambient

NETWORKS = {name: ThermalNetwork(*(p.values[k] for k in ("R_wh", "R_ha", "tau_w", "tau_m")))
            for name, p in MOTOR_PRESETS.items() if name.startswith("maxon")}


@pytest.mark.parametrize("name", sorted(NETWORKS))
def test_step_response_is_the_integrated_network_to_1e_8_K(name):
    net = NETWORKS[name]
    t = np.linspace(0.0, 600.0, 121)
    for P_w, P_h, theta0 in ((45.2, 0.0, (0.0, 0.0)), (20.0, 3.4, (0.0, 0.0)), (0.0, 0.0, (80.0, 30.0)), (5.0, 1.0, (10.0, 40.0))):
        ours = net.response(t, P_w, P_h, theta0)
        ref = integrate(network_ode(net.R_wh, net.R_ha, net.tau_w, net.tau_m, P_w, P_h), t, theta0)
        assert np.max(np.abs(ours - ref)) < 1e-8


@pytest.mark.parametrize("name", sorted(NETWORKS))
def test_step_from_ambient_is_the_two_exponential_form(name):
    net = NETWORKS[name]
    t = np.linspace(0.0, 3000.0, 301)
    ref = step_from_ambient(net.R_wh, net.R_ha, net.tau_w, net.tau_m, 10.0, t)
    assert np.max(np.abs(net.response(t, 10.0) - ref)) < 1e-9


def test_re40_step_coefficients_of_the_reference():
    # section 5.3: RE 40, P = 45.2 W: theta_w_inf = 297 K, K_f = 72.8 K, K_s = 224.4 K
    net = NETWORKS["maxon-re40"]
    P = 45.2
    assert net.steady_state(P)[0] == pytest.approx(297.0, abs=0.5)
    tf, ts = net.eigen_time_constants()
    ramp = net.response(np.array([0.0]), P)[0]
    assert ramp == pytest.approx([0.0, 0.0], abs=1e-9)
    Kf = tf * (P * ts / net.C_w - net.steady_state(P)[0]) / (ts - tf)
    assert Kf == pytest.approx(72.8, abs=0.1)


@pytest.mark.parametrize("name", sorted(NETWORKS))
def test_steady_state_is_ambient_plus_P_times_the_resistances(name):
    net = NETWORKS[name]
    P = 12.5
    assert net.steady_state(P)[0] == pytest.approx(P * (net.R_wh + net.R_ha), rel=1e-14)
    late = net.response(np.array([60 * max(net.eigen_time_constants())]), P)[0]
    assert late[0] == pytest.approx(P * (net.R_wh + net.R_ha), rel=1e-12)
    assert net.steady_state(P, 3.0)[1] == pytest.approx(net.R_ha * (P + 3.0))


@pytest.mark.parametrize("name", sorted(NETWORKS))
def test_eigen_time_constants_multiply_to_tau_w_tau_m(name):
    net = NETWORKS[name]
    tf, ts = net.eigen_time_constants()
    assert tf * ts == pytest.approx(net.tau_w * net.tau_m, rel=1e-12)
    assert tf + ts == pytest.approx(net.tau_w + net.tau_m + net.C_w * net.R_ha, rel=1e-12)
    assert sorted(-1 / np.linalg.eigvals(net.A)) == pytest.approx([tf, ts], rel=1e-12)


def test_published_eigen_time_constants():
    # reference section 2.3: 38.1 / 1224, 15.3 / 654, 36.4 / 150 s
    got = {k: NETWORKS[k].eigen_time_constants() for k in NETWORKS}
    assert got["maxon-re40"] == pytest.approx((38.1, 1224), abs=0.5)
    assert got["maxon-re30"] == pytest.approx((15.3, 654), abs=0.5)
    assert got["maxon-ec45flat"] == pytest.approx((36.4, 150), abs=0.5)


def test_propagator_is_the_exact_zero_order_hold_step():
    net = NETWORKS["maxon-re30"]
    Phi, Gamma = net.propagator(2.0)
    x = np.array([30.0, 10.0])
    for _ in range(5):
        x = Phi @ x + Gamma @ [8.0, 1.0]
    assert x == pytest.approx(net.response(np.array([10.0]), 8.0, 1.0, (30.0, 10.0))[0], abs=1e-10)


@pytest.mark.parametrize("field", ["R_wh", "R_ha", "tau_w", "tau_m"])
def test_a_resistance_or_time_constant_not_positive_is_one_line(field):
    values = {"R_wh": 1.0, "R_ha": 2.0, "tau_w": 10.0, "tau_m": 100.0, field: 0.0}
    with pytest.raises(ParameterError, match=rf"^ThermalNetwork\.{field} = 0\.0: expected .* > 0") as e:
        ThermalNetwork(**values)
    assert "\n" not in str(e.value)
