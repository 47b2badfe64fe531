"""Motors as an actuation kind: the layer's pieces on numbers, a motor on a joint the model lacks,
and a short full-horizon UR5 solve whose temperatures are re-integrated independently."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.motors.presets import ROBOT_MOTORS, motor_preset
from fatigue_pin.ocp.motor_actuators import MotorActuators

from conftest import integrate

JOINTS = ("a", "b", "c")


def _layer():
    return MotorActuators(JOINTS, {"a": motor_preset("ur5/size3"), "c": motor_preset("ur5/size1")}, {"a": 150.0, "c": 28.0})


def test_controls_torques_and_target_loads():
    layer = _layer()
    assert layer.nu == 2 and layer.n_states == 4 and layer.state_names == ("a_xw", "a_xh", "c_xw", "c_xh")
    u = np.array([[30.0, -14.0]])
    assert layer.joint_torque(u) == pytest.approx(np.array([[30.0, 0.0, -14.0]]))
    plus, minus = layer.per_joint(u)
    assert plus.tolist() == [[30.0, 0.0, 0.0]] and minus.tolist() == [[0.0, 0.0, -14.0]]
    assert np.asarray(layer.target_loads(u)).ravel() == pytest.approx([0.2, -0.5])
    assert layer.control_bounds()[1] == pytest.approx([150.0, 28.0])


def test_layer_rates_are_the_motors_temperature_rates():
    layer = _layer()
    m = np.array([0.3, 0.1, 0.5, 0.4])
    u = np.array([30.0, -14.0])
    rates = np.asarray(layer.fatigue_rates(m, u)).ravel()
    T_w, T_h = layer.temperatures(m)
    for k, (unit, tau) in enumerate(zip(layer.halves, u)):
        D = unit.motor.T_limit - unit.motor.T_ambient
        want = np.asarray(unit.motor.derivative(T_w[k], T_h[k], unit.motor.current(tau, 0.0))) / D
        assert rates[2 * k: 2 * k + 2] == pytest.approx(want, rel=1e-12)


def test_a_motor_on_a_joint_the_model_lacks_is_one_line():
    with pytest.raises(ParameterError, match=r"^motor on joint 'elbow': expected a joint of the model \['a', 'b', 'c'\]$"):
        MotorActuators(JOINTS, {"elbow": motor_preset("maxon-re30")}, {"elbow": 5.0})


@pytest.mark.slow
def test_a_short_ur5_full_horizon_with_motors_and_its_temperatures():
    from fatigue_pin.drivers.full import solve_full
    from fatigue_pin.io.study import Study
    from fatigue_pin.ocp.problem import Problem

    study = Study.from_file(Path(__file__).resolve().parents[2] / "studies" / "ur5_lift_swing.toml").replace({"task.intervals_per_cycle": 10, "solver.compile": False})
    model = study.model()
    layer = MotorActuators.from_model(model, {j: motor_preset(p) for j, p in zip(model.joint_names, ROBOT_MOTORS["ur5"])})
    problem = Problem(model, layer, study.task(), tuple(study.costs()))
    ocp, sol = solve_full(problem, 2, study.transcription(), study.solver(), guess="physical")
    assert sol.success
    m = sol.x[:, 2 * model.nv:]
    assert m.min() >= -1e-6 and m[:, 0::2].max() <= 1 + 1e-6  # T_w <= T_max - margin
    T_w, T_h = layer.temperatures(m)
    for k, unit in enumerate(layer.halves):  # each motor's temperatures by solve_ivp, interval by interval
        T = np.array([T_w[0, k], T_h[0, k]])
        for n in range(sol.u.shape[0]):
            i = unit.motor.current(sol.u[n, k], 0.0)
            T = integrate(lambda s, y: list(unit.motor.derivative(y[0], y[1], i)), np.array([0.0, sol.t[n + 1] - sol.t[n]]), T)[-1]
            assert T == pytest.approx([T_w[n + 1, k], T_h[n + 1, k]], abs=1e-6)
    assert T_w[-1, 1] > T_w[0, 1]  # the shoulder lift warms
