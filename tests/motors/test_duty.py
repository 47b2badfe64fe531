"""Repeated duty: the periodic orbit, its mean (the RMS rule), the budget, the reference's duty table."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.integrate import quad, solve_ivp

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.motors.calibration import simulate
from fatigue_pin.motors.duty import cycle_heat_budget, cycle_mean_rise, cycle_propagator, periodic_orbit, repeated_cycle_winding
from fatigue_pin.motors.thermal_states import MotorThermal
from fatigue_pin.motors.presets import motor_preset

from conftest import integrate, network_ode


def test_the_periodic_orbit_is_where_repeated_cycles_go():
    net = motor_preset("maxon-ec45flat").network
    d, pw, ph = [3.0, 5.0, 2.0], [30.0, 0.0, 10.0], [5.4, 5.4, 5.4]
    orbit = periodic_orbit(net, d, pw, ph)
    x = np.zeros(2)
    for _ in range(400):  # 400 cycles of 10 s, 27 slow time constants: converged
        for dk, p, q in zip(d, pw, ph):
            x = integrate(network_ode(net.R_wh, net.R_ha, net.tau_w, net.tau_m, p, q), np.array([0.0, dk]), x)[-1]
    assert x == pytest.approx(orbit[0], abs=1e-7)


def test_the_orbit_mean_is_the_steady_state_at_the_mean_loss():
    net = motor_preset("maxon-re40").network
    d, pw = [2.0, 2.0], [45.0, 0.0]
    orbit = periodic_orbit(net, d, pw)
    mean = sum(quad(lambda s, k=k: net.response(s, pw[k], 0.0, orbit[k])[0, 0], 0.0, d[k], epsabs=1e-12)[0]
               for k in range(2)) / sum(d)
    assert mean == pytest.approx(cycle_mean_rise(net, d, pw)[0], rel=1e-10)
    assert cycle_mean_rise(net, d, pw)[0] == pytest.approx((net.R_wh + net.R_ha) * 22.5)


def test_the_budget_is_the_continuous_current():
    m = motor_preset("maxon-re30")
    assert cycle_heat_budget(m) == pytest.approx(m.resistance(m.T_limit) * m.continuous_current() ** 2, rel=1e-12)
    assert cycle_heat_budget(motor_preset("maxon-re30", no_load_loss=100.0)) == 0.0


def test_the_reference_duty_table_of_the_re40():
    # reference section 5.4: RE 40, alpha = 0.0039, 25 C, 4 s cycles of 2 s at I_on and 2 s at 0 A:
    # 2 I_N reaches 155 C in cycle 207, 2.5 I_N in cycle 65, 1.5 I_N never (plateau below 155)
    m = motor_preset("maxon-re40", margin=0.0)
    t = np.arange(0.0, 4 * 1500 + 1, 2.0)
    first = {}
    for k in (1.5, 2.0, 2.5):
        T = simulate(m, t, np.where(t % 4 < 2, k * 3.12, 0.0), (25.0, 25.0))[:, 0]
        over = np.nonzero(T >= 155.0)[0]
        first[k] = int(t[over[0]] // 4 + 1) if over.size else None
    assert first == {1.5: None, 2.0: 207, 2.5: 65}


def test_bad_segments_are_one_line():
    net = motor_preset("maxon-re30").network
    with pytest.raises(ParameterError, match=r"^periodic_orbit durations = \[1\.0, 0\.0\]: expected segment lengths > 0"):
        periodic_orbit(net, [1.0, 0.0], [1.0, 2.0])
    with pytest.raises(ParameterError, match=r"^periodic_orbit: 2 durations, 1 P_w"):
        periodic_orbit(net, [1.0, 2.0], [1.0])


def test_the_repeated_cycle_winding_is_the_cycle_integrated_again_and_again():
    """A cycle of two loads (TL 0.9 for 0.4 s, then 0.2 for 0.6 s) from a warm start, integrated
    by solve_ivp on the normalised equations written here (beta = 0: the resistance's rise is what
    the linear map leaves out): the winding after R more cycles equals the coefficients' prediction
    from the first cycle's two ends alone; R = 0 is the winding itself."""
    th = dataclasses.replace(MotorThermal.from_motor(motor_preset("maxon-ec45flat", tau_w=2.0, tau_m=8.0), 10.0), beta=0.0)

    def rhs(t, x):
        TL = 0.9 if (t % 1.0) < 0.4 else 0.2
        return [th.q_w * TL * TL - th.a * (x[0] - x[1]), th.q_h + th.b * (x[0] - x[1]) - th.c * x[1]]

    R = 6
    ends = [np.array([0.3, 0.1])]
    for k in range(R + 1):  # cycle by cycle, each segment on its own (the load steps)
        x = ends[-1]
        for t0, t1 in ((k, k + 0.4), (k + 0.4, k + 1.0)):
            x = solve_ivp(rhs, (t0, t1), x, method="DOP853", rtol=1e-12, atol=1e-13, first_step=1e-3).y[:, -1]
        ends.append(x)
    c_last, c_before = repeated_cycle_winding(th, 1.0, R)
    assert c_last @ ends[1] + c_before @ ends[0] == pytest.approx(ends[R + 1][0], abs=1e-9)
    # the propagator is the flow without losses
    free = solve_ivp(lambda t, x: [-th.a * (x[0] - x[1]), th.b * (x[0] - x[1]) - th.c * x[1]], (0, 1.0), [0.3, 0.1],
                     method="DOP853", rtol=1e-12, atol=1e-13).y[:, -1]
    assert np.allclose(cycle_propagator(th, 1.0) @ [0.3, 0.1], free, atol=1e-11)
    c_last, c_before = repeated_cycle_winding(th, 1.0, 0)
    assert c_last.tolist() == [1.0, 0.0] and c_before.tolist() == [0.0, 0.0]
