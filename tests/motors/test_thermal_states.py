"""The normalised motor states against the motor's own temperatures and the closed form."""

from __future__ import annotations

import numpy as np
import pytest

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.motors.presets import motor_preset
from fatigue_pin.motors.thermal_states import MotorThermal

from conftest import integrate, step_from_ambient


@pytest.mark.parametrize("name", ["maxon-re30", "ur5/size3"])
def test_rates_are_the_motors_temperature_rates_over_the_allowed_rise(name):
    motor = motor_preset(name, T_ambient=30.0)
    limit = 3.0 * motor.continuous_torque()
    model = MotorThermal.from_motor(motor, limit)
    D = motor.T_limit - motor.T_ambient
    for x, tau in (((0.0, 0.0), 0.5 * limit), ((0.6, 0.3), -limit), ((1.0, 0.9), 0.0)):
        T = motor.T_ambient + D * np.asarray(x)
        want = np.asarray(motor.derivative(T[0], T[1], motor.current(tau, 0.0))) / D
        assert model.rates(x, tau / limit) == pytest.approx(want, rel=1e-12, abs=1e-15)


def test_constant_load_from_cold_is_the_closed_form():
    motor = motor_preset("maxon-re40", alpha=0.0)
    limit = 100.0
    model = MotorThermal.from_motor(motor, limit)
    D = motor.T_limit - motor.T_ambient
    t = np.linspace(0.0, 2000.0, 51)
    TL = 0.3
    P = motor.R25 * motor.current(TL * limit, 0.0) ** 2
    want = step_from_ambient(motor.R_wh, motor.R_ha, motor.tau_w, motor.tau_m, P, t) / D
    got = integrate(lambda s, x: model.rates(x, TL), t, model.rest_state())
    assert np.max(np.abs(got - want)) * D < 1e-8  # K


def test_the_limit_is_the_state_bound_one():
    motor = motor_preset("maxon-re30")
    model = MotorThermal.from_motor(motor, 1.0)
    # the continuous current holds x_w = 1 (T_w = T_max - margin) in steady state
    TL = motor.continuous_current() / motor.current(1.0, 0.0)  # the continuous current over the current at TL = 1
    x = integrate(lambda s, y: model.rates(y, TL), np.array([0.0, 20000.0]), (0.0, 0.0))[-1]
    assert x[0] == pytest.approx(1.0, abs=1e-9)
    model.check_state(x)
    assert model.fatigued_state == "xw" and model.active_state is None
    with pytest.raises(ParameterError, match=r"^MotorThermal torque_ref = 0\.0: expected a joint torque > 0"):
        MotorThermal.from_motor(motor, 0.0)
