"""Fatigue estimators: the open-loop model and moving-horizon estimation from capacity probes."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.drivers.estimation import History, MheEstimator, MheSettings, OpenLoopEstimator, make_estimator
from fatigue_pin.drivers.full import OcpBuilder


@pytest.fixture(scope="module")
def functions(small_problem, small_study):
    return OcpBuilder(small_problem, small_study.transcription(), small_study.solver())(1).functions


def _true_history(problem, F: float, cycles: int, probe_std: float, seed: int = 0) -> tuple[History, np.ndarray]:
    """Fatigue of every half under a varying load, integrated by scipy with each half's rates and
    rate F (1/s); a probe of 1 - mf (noise ``probe_std``) at the end of every cycle. Returns the
    history (estimates left at the rested state) and the true fatigue states (nodes, n_states)."""
    acts, task = problem.actuators, problem.task
    n, dt = task.intervals_per_cycle, task.dt
    halves = [h.params.with_(F=F) for h in acts.halves]
    rng = np.random.default_rng(seed)
    limits = acts.signed_limits
    m = acts.initial_state()
    truth, history = [m], History([m.copy()])
    for k in range(cycles * n):
        TL = np.array([0.15 + 0.1 * np.sin(2 * np.pi * k / n), 0.05, 0.2 + 0.1 * np.sin(2 * np.pi * k / n), 0.02])
        u = np.array([TL[0] * limits[0], TL[2] * limits[2], TL[1] * limits[1], TL[3] * limits[3]])

        def rhs(t, y):
            return np.concatenate([p.rates(y[3 * i : 3 * i + 3], TL[i]) for i, p in enumerate(halves)])

        m = solve_ivp(rhs, (0, dt), m, rtol=1e-10, atol=1e-12).y[:, -1]
        truth.append(m)
        history.u_command.append(u)
        history.u_delivered.append(u)
        if (k + 1) % n == 0:
            history.probes[k + 1] = 1 - m[2::3] + probe_std * rng.standard_normal(4)
    return history, np.array(truth)


def test_open_loop_follows_its_model(functions, small_problem):
    """With the model's own F the open-loop estimate is the truth; with a plant that tires twice
    as fast it falls behind."""
    est = OpenLoopEstimator(functions, small_problem.actuators)
    F = small_problem.actuators.halves[0].params.F
    for rate, close in ((F, True), (2 * F, False)):
        history, truth = _true_history(small_problem, rate, 2, 0.0)
        m = truth[0]
        for u in history.u_delivered:
            m = est.predict(m, u)
        error = np.abs(m[2::3] - truth[-1][2::3]).max()
        assert (error < 1e-4) if close else (error > 0.05), error
        assert np.array_equal(est.correct(20, History([m])), m)


def test_mhe_recovers_F_and_the_fatigue_from_probes(functions, small_problem):
    F = small_problem.actuators.halves[0].params.F
    history, truth = _true_history(small_problem, 2 * F, 3, 0.01)
    m = truth[0]
    est = MheEstimator(functions, small_problem.actuators, MheSettings(cycles=3, params=("F", "R")), 10)
    for k, u in enumerate(history.u_delivered):  # the predictions with the model's F
        m = est.predict(m, u)
        history.m.append(m)
    m_k = est.correct(30, history)
    loaded = [0, 2]  # shoulder_plus and elbow_plus carry the load
    F_hat = est.params[est.index].reshape(4, 2)[:, 0]
    np.testing.assert_allclose(F_hat[loaded], 2 * F, rtol=0.05)
    assert np.abs(m_k[2::3] - truth[-1][2::3]).max() < 0.02
    assert np.abs(history.m[-1][2::3] - truth[-1][2::3]).max() > 0.05  # the prediction alone was off
    assert est.last_wall_time_s > 0


def test_mhe_without_information_keeps_the_prediction(functions, small_problem):
    est = MheEstimator(functions, small_problem.actuators, MheSettings(), 10)
    m = small_problem.actuators.initial_state()
    history = History([m, m], [np.zeros(4)], [np.zeros(4)])
    assert np.array_equal(est.correct(1, history), m)
    np.testing.assert_array_equal(est.params, small_problem.actuators.param_vector())


def test_bad_estimator_settings(functions, small_problem):
    for make, key in ((lambda: MheSettings(cycles=0), "mpc.mhe.cycles"), (lambda: MheSettings(probe_std=0), "mpc.mhe.probe_std"),
                      (lambda: make_estimator("kalman", functions, small_problem.actuators), "mpc.estimator"),
                      (lambda: MheEstimator(functions, small_problem.actuators, MheSettings(params=("G",)), 10), "mpc.mhe.params")):
        with pytest.raises(ParameterError) as err:
            make()
        assert str(err.value).startswith(key) and "\n" not in str(err.value)


def test_mhe_with_a_passive_joint_sizes_its_controls_by_the_actuators():
    """A passive shoulder leaves 2 controls, not 2 nv = 4: the MHE's window takes the actuators'
    own count (it assumed 2 nv, and its CasADi call failed on the shape). With the elbow flexor's
    true F twice the model's, one cycle of probes moves its F up."""
    from conftest import small_curl

    study = small_curl("sliding").replace({"actuators.passive": ["shoulder"]})
    problem = study.problem()
    acts = problem.actuators
    assert acts.nu == 2 and acts.n_halves == 2
    fn = OcpBuilder(problem, study.transcription(), study.solver())(1).functions
    est = MheEstimator(fn, acts, MheSettings(cycles=1, params=("F",)), 10)
    F = acts.halves[0].params.F
    true = [h.params.with_(F=2 * F) for h in acts.halves]
    m = acts.initial_state()
    history = History([m.copy()])
    truth = m.copy()
    for k in range(10):
        u = np.array([0.3 * acts.signed_limits[0], 0.0])
        truth = solve_ivp(lambda t, y: np.concatenate([p.rates(y[3 * i : 3 * i + 3], u[i] / acts.signed_limits[i]) for i, p in enumerate(true)]),
                          (0, problem.task.dt), truth, rtol=1e-10, atol=1e-12).y[:, -1]
        history.u_command.append(u)
        history.u_delivered.append(u)
        history.m.append(est.predict(history.m[-1], u))
    history.probes[10] = 1 - truth[2::3]
    m_k = est.correct(10, history)
    assert m_k.shape == (6,) and est.params[est.index][0] > 1.5 * F
