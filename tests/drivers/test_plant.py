"""The plant of a closed loop: true dynamics, the torque its fatigue allows, seeded noise."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from scipy.integrate import solve_ivp

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.drivers.plant import Plant, PlantDisturbance, PlantNoise, PlantSettings


@pytest.fixture(scope="module")
def plant(small_problem):
    return Plant(small_problem, small_problem.task.dt, PlantSettings(), substeps=2)


def _state(problem, mf: float) -> np.ndarray:
    """The initial state with every half at (ma, mr, mf) = (0, 1 - mf, mf)."""
    x = problem.initial_state()
    L = problem.layout
    for rows, value in ((L.fatigue_index("mr"), 1 - mf), (L.fatigue_index("mf"), mf)):
        x[rows] = value
    return x


def test_one_interval_matches_scipy_on_pinocchio(small_problem):
    """RK4 of the plant against scipy's RK45 on pinocchio.aba and each half's own rates."""
    plant = Plant(small_problem, small_problem.task.dt, PlantSettings(substeps=40))
    x0 = _state(small_problem, 0.2)
    u = np.array([8.0, 20.0, -3.0, -1.0])
    x1, delivered = plant.step(x0, u, 0)
    np.testing.assert_allclose(delivered, u)
    model, L, acts = small_problem.model, small_problem.layout, small_problem.actuators
    data = model.pin_model.createData()
    halves = acts.halves
    tau_half = [u[0], u[2], u[1], u[3]]  # half order (shoulder+, shoulder-, elbow+, elbow-)

    def rhs(t, x):
        a = pin.aba(model.pin_model, data, x[L.q], x[L.v], u[:2] + u[2:])
        dm = np.concatenate([h.params.rates(x[L.m][3 * i : 3 * i + 3], tau_half[i] / h.signed_limit) for i, h in enumerate(halves)])
        return np.concatenate([x[L.v], a, dm])

    ref = solve_ivp(rhs, (0, small_problem.task.dt), x0, rtol=1e-11, atol=1e-12).y[:, -1]
    np.testing.assert_allclose(x1, ref, atol=1e-7)
    adaptive = Plant(small_problem, small_problem.task.dt, PlantSettings(integrator="rk45"))
    np.testing.assert_allclose(adaptive.step(x0, u, 0)[0], ref, atol=1e-7)


def test_torque_is_limited_by_the_true_fatigue(plant, small_problem):
    """A half with mf = 0.6 delivers at most 40 % of its limit; one below it delivers its command."""
    x = _state(small_problem, 0.6)
    limits = small_problem.actuators.signed_limits  # (shoulder+, shoulder-, elbow+, elbow-)
    u = np.array([0.9 * limits[0], 0.1 * limits[2], 0.5 * limits[1], 0.3 * limits[3]])  # tau_plus, tau_minus
    delivered = plant.deliver(x, u)
    np.testing.assert_allclose(delivered, [0.4 * limits[0], 0.1 * limits[2], 0.4 * limits[1], 0.3 * limits[3]])
    _, applied = plant.step(x, u, 3)
    np.testing.assert_array_equal(applied, delivered)


def test_noise_and_disturbance_are_seeded_per_node(small_problem):
    noisy = PlantSettings(noise=PlantNoise(q=0.01, qdot=0.1, capacity=0.02), disturbance=PlantDisturbance(std=[1.0, 2.0]), seed=7)
    a = Plant(small_problem, small_problem.task.dt, noisy, 2)
    b = Plant(small_problem, small_problem.task.dt, noisy, 2)
    x = _state(small_problem, 0.1)
    for node in (0, 5, 5, 11):
        np.testing.assert_array_equal(np.concatenate(a.measure(x, node)), np.concatenate(b.measure(x, node)))
        np.testing.assert_array_equal(a.probe(x, node), b.probe(x, node))
        np.testing.assert_array_equal(a.disturbance(node), b.disturbance(node))
    assert not np.array_equal(a.measure(x, 1)[0], a.measure(x, 2)[0])
    q, v = a.measure(x, 4)
    assert 0 < np.abs(q - x[:2]).max() < 0.1 and 0 < np.abs(v - x[2:4]).max() < 1.0
    c = np.array([a.probe(x, k) for k in range(400)])
    assert abs(c.std(axis=0).mean() - 0.02) < 0.003 and abs(c.mean() - 0.9) < 0.005
    d = np.array([a.disturbance(k) for k in range(400)])
    np.testing.assert_allclose(d.std(axis=0), [1.0, 2.0], rtol=0.15)
    other = Plant(small_problem, small_problem.task.dt, PlantSettings(noise=noisy.noise, seed=8), 2)
    assert not np.array_equal(other.measure(x, 4)[0], q)
    constant = Plant(small_problem, small_problem.task.dt, PlantSettings(disturbance=PlantDisturbance(constant=[0.0, 5.0])), 2)
    np.testing.assert_array_equal(constant.disturbance(9), [0.0, 5.0])


def test_a_constant_disturbance_moves_the_plant(small_problem):
    """5 N m more at the elbow over a 1 ms interval: the velocity changes by about dt M^-1 d."""
    x = _state(small_problem, 0.0)
    dt = 1e-3
    base = Plant(small_problem, dt, PlantSettings(), 2)
    pushed = Plant(small_problem, dt, PlantSettings(disturbance=PlantDisturbance(constant=[0.0, 5.0])), 2)
    u = np.zeros(4)
    dv = pushed.step(x, u, 0)[0][2:4] - base.step(x, u, 0)[0][2:4]
    model = small_problem.model
    Minv = pin.computeMinverse(model.pin_model, model.pin_model.createData(), x[:2])
    np.testing.assert_allclose(dv, dt * Minv @ [0.0, 5.0], rtol=0.01)


@pytest.mark.parametrize("make, key", [
    (lambda: PlantNoise(q=-0.1), "plant.noise.q"),
    (lambda: PlantNoise(qdot=float("nan")), "plant.noise.qdot"),
    (lambda: PlantNoise(capacity=-1), "plant.noise.capacity"),
    (lambda: PlantDisturbance(std=[1.0, -2.0]), "plant.disturbance.std"),
    (lambda: PlantDisturbance(constant="x"), "plant.disturbance.constant"),
    (lambda: PlantSettings(seed=-1), "seed"),
    (lambda: PlantSettings(integrator="euler"), "plant.integrator"),
    (lambda: PlantSettings(substeps=0), "plant.substeps"),
])
def test_bad_plant_settings_name_the_key(make, key):
    with pytest.raises(ParameterError) as err:
        make()
    message = str(err.value)
    assert message.startswith(key + " = ") and "\n" not in message


def test_the_default_plant_follows_the_exact_flow_where_the_plans_rk4_does_not(small_problem):
    """The state of the closed loop's flail (elbow at -30 rad/s): 2 RK4 substeps of 0.05 s, the
    plan's own scheme, end about 1 rad/s from scipy's DOP853 on pinocchio.aba; the default plant
    (adaptive) within 1e-6, and its flow gap (verify's reference) is within verify's tolerances."""
    model, L = small_problem.model, small_problem.layout
    x0 = _state(small_problem, 0.2)
    x0[L.v] = [10.0, -30.0]
    u = np.array([8.0, 20.0, -3.0, -1.0])
    data = model.pin_model.createData()
    coarse = Plant(small_problem, 0.1, PlantSettings(integrator="rk4", substeps=2))
    default = Plant(small_problem, 0.1, PlantSettings())
    assert default.settings.integrator == "rk45"

    def body(t, y):
        return np.concatenate([y[2:], pin.aba(model.pin_model, data, y[:2], y[2:], u[:2] + u[2:])])

    ref = solve_ivp(body, (0, 0.1), x0[:4], method="DOP853", rtol=1e-12, atol=1e-13).y[:, -1]
    x_coarse, x_default = coarse.step(x0, u, 0)[0], default.step(x0, u, 0)[0]
    assert np.abs(x_coarse[:4] - ref).max() > 0.1
    np.testing.assert_allclose(x_default[:4], ref, atol=1e-6)
    assert default.flow_gap(x0, u, 0, x_default)[0] < 1e-6
    assert coarse.flow_gap(x0, u, 0, x_coarse)[0] > 0.1
