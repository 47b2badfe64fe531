"""A joint motor: current through the gear, R(T), the datasheet's own numbers, bad input."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.motors.motor import MotorParameters
from fatigue_pin.motors.presets import MOTOR_PRESETS, ROBOT_MOTORS, motor_preset, scaled_to

from conftest import integrate


def test_re30_at_nominal_current_reaches_its_T_max_in_steady_state():
    # the datasheet's nominal current is the one that holds the winding at T_max = 125 deg C
    motor = motor_preset("maxon-re30", margin=0.0)
    T_w, T_h = motor.steady_state(MOTOR_PRESETS["maxon-re30"].nominal_current)
    assert abs(T_w - 125.0) < 1.0
    # the same steady state from the ODE with R(T_w), integrated for an hour past the slow constant
    i = MOTOR_PRESETS["maxon-re30"].nominal_current

    def f(t, T):
        return list(motor.derivative(T[0], T[1], i))

    end = integrate(f, np.array([0.0, 20000.0]), (25.0, 25.0))[-1]
    assert end == pytest.approx([T_w, T_h], abs=1e-6)


def test_steady_state_with_resistance_rising_is_the_closed_form():
    m = motor_preset("maxon-re40", no_load_loss=2.0)
    i = 3.0
    T_w, T_h = m.steady_state(i)
    P_w = m.resistance(T_w) * i * i
    assert T_w == pytest.approx(m.T_ambient + P_w * (m.R_wh + m.R_ha) + 2.0 * m.R_ha, rel=1e-12)
    assert m.derivative(T_w, T_h, i) == pytest.approx((0.0, 0.0), abs=1e-12)


def test_runaway_current_has_no_steady_state():
    m = motor_preset("maxon-re30")
    with pytest.raises(ParameterError, match=r"^current 20\.0 A: expected below the runaway current"):
        m.steady_state(20.0)


def test_casadi_rhs_is_the_numeric_derivative():
    m = motor_preset("maxon-ec45flat", T_ambient=35.0)
    f = m.rhs()
    for T, i in (((40.0, 30.0), 2.0), ((100.0, 80.0), 0.0), ((60.0, 60.0), -3.0)):
        assert np.asarray(f(T, i)).ravel() == pytest.approx(m.derivative(*T, i), rel=1e-14)


def test_current_through_the_gear_and_friction():
    m = MotorParameters(R25=1.0, k_t=0.05, gear_ratio=100.0, R_wh=1.0, R_ha=2.0, tau_w=10.0, tau_m=100.0, T_max=125.0,
                        efficiency=0.8, friction=0.01, friction_speed=2.0)
    assert m.current(40.0, 0.0) == pytest.approx(40.0 / (100 * 0.8) / 0.05)
    assert m.current(0.0, 10.0) == pytest.approx(0.01 * np.tanh(100 * 10 / 2.0) / 0.05)
    tau, qd = ca.SX.sym("tau"), ca.SX.sym("qd")
    sym = ca.Function("i", [tau, qd], [m.current(tau, qd)])
    assert float(sym(12.0, -0.01)) == pytest.approx(m.current(12.0, -0.01), rel=1e-14)


def test_continuous_current_holds_the_limit_and_derating():
    m = motor_preset("maxon-re40")
    T_w, _ = m.steady_state(m.continuous_current())
    assert T_w == pytest.approx(m.T_limit, abs=1e-9)
    assert m.continuous_torque() == pytest.approx(m.gear_ratio * m.k_t * m.continuous_current())
    assert m.derating([m.T_ambient, m.T_limit, m.T_limit + 5]) == pytest.approx([1.0, 0.0, 0.0])
    # Kollmorgen's ambient derating: sqrt of the ratio of the allowed rises (no no-load loss, alpha = 0)
    lin = motor_preset("maxon-re40", alpha=0.0)
    ratio = lin.continuous_torque(65.0) / lin.continuous_torque(25.0)
    assert ratio == pytest.approx(np.sqrt((lin.T_limit - 65.0) / (lin.T_limit - 25.0)), rel=1e-12)


def test_stand_ins_carry_one_third_of_the_peak_torque():
    peaks = {"ur5/size3": 150.0, "ur5/size1": 28.0, "panda/large": 87.0, "panda/small": 12.0}
    for name, peak in peaks.items():
        assert motor_preset(name).continuous_torque() == pytest.approx(peak / 3, rel=1e-12)
    assert len(ROBOT_MOTORS["ur5"]) == 6 and len(ROBOT_MOTORS["panda"]) == 7
    with pytest.raises(ParameterError, match=r"^scaled_to continuous_torque = -1\.0"):
        scaled_to(motor_preset("maxon-re40"), -1.0)


@pytest.mark.parametrize("changes, match", [
    ({"gear_ratio": 0.0}, r"^MotorParameters\.gear_ratio = 0\.0: expected a gear ratio > 0$"),
    ({"gear_ratio": -3.0}, r"^MotorParameters\.gear_ratio = -3\.0: expected a gear ratio > 0$"),
    ({"R_ha": -1.0}, r"^MotorParameters\.R_ha = -1\.0: expected a thermal resistance > 0 \(K/W\)$"),
    ({"R_wh": 0.0}, r"^MotorParameters\.R_wh = 0\.0: expected a thermal resistance > 0 \(K/W\)$"),
    ({"T_ambient": 130.0}, r"^MotorParameters\.T_max = 125\.0: expected above T_ambient \+ margin"),
    ({"efficiency": 1.5}, r"^MotorParameters\.efficiency = 1\.5: expected an efficiency in \(0, 1\]$"),
])
def test_bad_motor_is_one_line(changes, match):
    with pytest.raises(ParameterError, match=match) as e:
        motor_preset("maxon-re30", **changes)
    assert "\n" not in str(e.value)


def test_unknown_preset_or_field_is_one_line():
    with pytest.raises(ParameterError, match=r"^motor preset 'maxon-re50': expected one of"):
        motor_preset("maxon-re50")
    with pytest.raises(ParameterError, match=r"^motor preset 'maxon-re30': unknown field 'gear'"):
        motor_preset("maxon-re30", gear=3.0)
