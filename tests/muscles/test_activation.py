"""Activation dynamics (fatigue_pin/muscles/activation.py): the activation as the first state of a
muscle's unit, driven by its excitation, against closed forms of De Groote's dynamics; a muscle
run with it, its force following the activation state, checked by verify."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from fatigue_pin.core.errors import FatiguePinError, ParameterError
from fatigue_pin.fatigue.models import XiaFatigue
from fatigue_pin.muscles.activation import activated, activation_stiffness, with_activation
from fatigue_pin.ocp.actuation_layer import unit_model

XIA = XiaFatigue(LD=10.0, LR=10.0, F=0.01, R=0.002, S=10.0)


def moco_rate(e: float, a: float, tau_a: float, tau_d: float, b: float) -> float:
    """De Groote et al. (2016) as Moco writes it, again here: da/dt (1/s)."""
    f = 0.5 * math.tanh(b * (e - a))
    z = 0.5 + 1.5 * a
    return ((f + 0.5) / (tau_a * z) + (0.5 - f) * z / tau_d) * (e - a)


def test_the_activated_model_puts_the_activation_in_front_of_the_fatigue_states():
    model = with_activation(XIA, 0.015, 0.060, 0.1)
    assert model.state_names == ("a", "ma", "mr", "mf") and model.kind == "xia+activation"
    assert model.param_names[-3:] == ("activation_time", "deactivation_time", "activation_smoothing")
    assert model.total_states() == ("ma", "mr", "mf") and model.fatigued_state == "mf"
    assert np.array_equal(model.rest_state(), [0.0, 0.0, 1.0, 0.0])
    rng = np.random.default_rng(1)
    for _ in range(20):
        a, e = rng.uniform(0, 1, 2)
        m = np.concatenate([[a], rng.dirichlet([1, 1, 1])])
        rates = model.rates(m, e)
        assert rates[0] == pytest.approx(moco_rate(e, a, 0.015, 0.060, 0.1), rel=1e-12)
        assert np.allclose(rates[1:], XIA.rates(m[1:], e), rtol=1e-12, atol=1e-14)  # TL = the excitation
    # stored as a run stores it (kind and parameters by name), the same model comes back
    assert unit_model(model.kind, **model.as_dict()) == model
    assert activated(XiaFatigue) is type(model)  # one class per fatigue model


def test_activation_and_deactivation_follow_their_closed_forms():
    """With a large smoothing b the switch is a step: from rest under e = 1,
    t(a) = tau_a (-1.5 a - 2 ln(1 - a)); relaxing under e = 0 from a0,
    t(a) = -2 tau_d ln(a (0.5 + 1.5 a0) / (a0 (0.5 + 1.5 a)))."""
    tau_a, tau_d = 0.015, 0.060
    model = with_activation(XIA, tau_a, tau_d, 1e3)
    rest = model.rest_state()

    def run(e, m0, t):
        sol = solve_ivp(lambda _t, m: model.rates(m, e), (0.0, t[-1]), m0, t_eval=t, method="LSODA", rtol=1e-11, atol=1e-13)
        return sol.y[0]

    targets = np.array([0.2, 0.5, 0.8, 0.9])
    t_up = tau_a * (-1.5 * targets - 2.0 * np.log(1.0 - targets))
    assert np.allclose(run(1.0, rest, t_up), targets, rtol=0, atol=1e-7)
    a0 = 0.9
    down = np.array([0.6, 0.3, 0.1])
    t_down = -2.0 * tau_d * np.log(down * (0.5 + 1.5 * a0) / (a0 * (0.5 + 1.5 * down)))
    assert np.allclose(run(0.0, np.concatenate([[a0], rest[1:]]), t_down), down, rtol=0, atol=1e-7)


def test_an_explicit_step_too_long_for_the_activation_is_refused():
    model = with_activation(XIA, 0.015, 0.060, 0.1)
    rate = activation_stiffness(0.015, 0.060, 0.1)
    # the stiffest -d(da/dt)/da by finite differences of the test's own formula, on a grid
    grid = np.linspace(0, 1, 101)
    fd = max(-(moco_rate(e, a + 1e-7, 0.015, 0.060, 0.1) - moco_rate(e, a, 0.015, 0.060, 0.1)) / 1e-7
             for e in grid for a in grid[:-1])
    assert rate == pytest.approx(fd, rel=2e-2)
    model.check_step(0.9 * 2.785 / rate)
    with pytest.raises(ParameterError, match=r"activation dynamics .* outside the method's stability interval"):
        model.check_step(1.1 * 2.785 / rate)
    with pytest.raises(ParameterError, match=r"activation_time = 0(\.0)?: expected a time constant > 0 \(s\)"):
        with_activation(XIA, 0.0, 0.06, 0.1)


def test_the_keys_are_refused_where_they_do_not_apply():
    from conftest import muscle_curl, small_curl

    with pytest.raises(FatiguePinError, match="activation_dynamics = true: activations are muscle states"):
        small_curl().replace({"actuators.activation_dynamics": True}).problem()
    with pytest.raises(FatiguePinError, match="activation_dynamics = true with coupling = 'active'"):
        muscle_curl(**{"actuators.activation_dynamics": True, "actuators.coupling": "active"}).problem()


def slow_muscles(folder: Path) -> str:
    """Two of arm26's muscles with slower time constants (0.05 s, 0.2 s), so that the small
    curl's 4 RK4 substeps of 0.025 s resolve their activation (the muscle file's own keys)."""
    from conftest import two_muscle_file

    path = Path(two_muscle_file(folder))
    text = re.sub(r'(name = "(BRA|TRIlat)"\n)', r'\1activation_time = 0.05\ndeactivation_time = 0.2\n', path.read_text())
    path.write_text(text)
    return str(path)


def test_a_muscle_run_with_activation_dynamics_follows_its_activation_states(tmp_path):
    from conftest import muscle_curl

    from fatigue_pin.io.results import read_run
    from fatigue_pin.io.study import run_study
    from fatigue_pin.verify.verifier import verify_run

    study = muscle_curl(slow_muscles(tmp_path), **{"actuators.activation_dynamics": True, "transcription.substeps": 4})
    out = tmp_path / "act.h5"
    run_study(study, out=out, name="full/act")
    run = read_run(out, "full/act")
    assert run.attrs["activation_dynamics"] and run.attrs["converged"]
    a, e = run.fatigue["a"][:, :2], run.unit_controls[:, :2]
    assert np.all(np.isnan(run.fatigue["a"][:, 2:]))  # the residual halves carry no activation
    assert np.array_equal(a[0], [0.0, 0.0])  # from rest
    # the activation is each interval's excitation filtered by the muscle's dynamics: the test's
    # formula on the transcription's grid (RK4, 4 steps of 0.025 s) meets the nodes to round-off, and
    # the exact flow (solve_ivp) within that grid's RK4 error
    rk4_gap = exact_gap = 0.0
    for k in range(e.shape[0]):
        for i in range(2):
            def f(x, ek=e[k, i]):
                return moco_rate(ek, x, 0.05, 0.2, 0.1)
            x, h = a[k, i], 0.025
            for _ in range(4):
                k1 = f(x); k2 = f(x + h / 2 * k1); k3 = f(x + h / 2 * k2); k4 = f(x + h * k3)
                x += h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
            rk4_gap = max(rk4_gap, abs(x - a[k + 1, i]))
            sol = solve_ivp(lambda _t, y: [f(y[0])], (0, 0.1), [a[k, i]], rtol=1e-10, atol=1e-12)
            exact_gap = max(exact_gap, abs(sol.y[0, -1] - a[k + 1, i]))
    assert rk4_gap < 1e-6 and exact_gap < 1e-2
    # the stored forces follow the activation state, not the excitation
    layer = study.problem().actuators
    q, qdot, F = run.q[:-1], run.qdot[:-1], run.extras["muscle_force"]
    at_state = np.array([np.asarray(layer.forces(q[k], qdot[k], a[k])).ravel() for k in range(len(F))])
    at_control = np.array([np.asarray(layer.forces(q[k], qdot[k], e[k])).ravel() for k in range(len(F))])
    assert np.allclose(F, at_state, rtol=1e-9, atol=1e-9) and np.abs(F - at_control).max() > 1.0  # N
    report = verify_run(run)
    assert report.rk4_residual < 1e-6  # the transcription written again, the muscles' torque from the a column
    assert report.invariant < 1e-6 and "xia+activation: ma + mr + mf" in report.invariant_sum
    assert any("too coarse for the gap tolerance" in n for n in report.notes)
