"""Passive joints and couplings (``[actuators]``, docs/model.md): each solved two ways, or against
a closed form / an independent integration.

The model is urdf/pendulum.urdf: a slider (prismatic, along y) carrying a pendulum (revolute).
The task moves the slider to 0.5 m at mid-cycle and back; the cost is the halves' torques
squared. Small grids (10 intervals of 0.1 s, 5 RK4 steps), uncompiled: each solve is a fraction
of a second.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from scipy.integrate import solve_ivp

from fatigue_pin.fatigue.models import XiaFatigue
from fatigue_pin.io.results import read_run, write_run
from fatigue_pin.io.study import Study
from fatigue_pin.drivers.run import solution_to_run
from fatigue_pin.ocp.actuators import Actuation
from fatigue_pin.ocp.costs import torque
from fatigue_pin.ocp.problem import Problem
from fatigue_pin.ocp.solver import SolverOptions
from fatigue_pin.ocp.task import JointTarget, Task
from fatigue_pin.ocp.transcription import Ocp, Transcription
from fatigue_pin.robot.model import load_model

URDF = Path(__file__).resolve().parents[2] / "urdf" / "pendulum.urdf"
XIA = XiaFatigue(LD=100, LR=100, F=5, R=10, S=10)
TASK = Task(1.0, 10, items=(JointTarget("slider", 0.5, at=0.5),), q_init=(0.0, 0.0))
TRANSCRIPTION = Transcription(substeps=5)
SOLVER = SolverOptions(compile=False, tol=1e-10)  # tight: the equivalences compare optima


@pytest.fixture(scope="module")
def pendulum():
    return load_model(URDF)


def _solve(model, actuation: Actuation | None = None, ocp_class: type = Ocp, weight: float = 1.0,
           transcription: Transcription = TRANSCRIPTION):
    problem = Problem.build(model, XIA, TASK, [torque(weight)], actuation=actuation)
    ocp = ocp_class(problem, 1, transcription, SOLVER)
    sol = ocp.solve()
    assert sol.success, sol.status
    return ocp, sol


class PendulumHalvesAtZero(Ocp):
    """The fully actuated pendulum with the two halves of joint ``pendulum`` bounded to 0: the
    Python API's construction of a joint without torque."""

    def control_bounds(self):
        lo, hi = super().control_bounds()
        rows = [r for h, r in zip(self.actuators.halves, self.actuators.control_rows()) if h.joint == "pendulum"]
        lo[rows], hi[rows] = 0.0, 0.0
        return lo, hi


def test_a_passive_joint_is_the_joint_with_its_torque_bounded_to_zero(pendulum):
    ocp_p, passive = _solve(pendulum, Actuation(passive=("pendulum",)))
    ocp_b, bounded = _solve(pendulum, None, PendulumHalvesAtZero)
    assert ocp_p.layout.nu == 2 and ocp_b.layout.nu == 4 and ocp_p.layout.nx == ocp_b.layout.nx - 6
    assert np.max(np.abs(bounded.tau_plus[:, 1])) < 1e-7 and np.max(np.abs(bounded.tau_minus[:, 1])) < 1e-7
    assert passive.objective == pytest.approx(bounded.objective, rel=1e-6)
    np.testing.assert_allclose(passive.q, bounded.q, atol=1e-6)
    np.testing.assert_allclose(passive.qdot, bounded.qdot, atol=1e-5)
    # the slider's halves: the same torques and fatigue states; the pendulum's columns are 0
    np.testing.assert_allclose(passive.tau_plus, bounded.tau_plus, atol=1e-5)
    np.testing.assert_allclose(passive.tau_minus, bounded.tau_minus, atol=1e-5)
    np.testing.assert_array_equal(passive.tau_plus[:, 1], 0.0)
    np.testing.assert_allclose(passive.fatigue("mf"), bounded.fatigue("mf")[:, :2], atol=1e-7)
    # the joint torque the dynamics take: the halves' sum, 0 on the pendulum
    np.testing.assert_allclose(passive.tau, passive.tau_plus + passive.tau_minus)
    assert np.max(np.abs(passive.q[:, 1])) > 0.1  # the pendulum does swing (the test could fail)


def test_a_zero_effort_limit_is_the_passive_key(pendulum, tmp_path):
    urdf = tmp_path / "pendulum_free.urdf"
    text = URDF.read_text()
    limit = 'upper="6.283185307179586" effort="100.0"'
    assert text.count(limit) == 1
    urdf.write_text(text.replace(limit, 'upper="6.283185307179586" effort="0"'))
    free = load_model(urdf)
    np.testing.assert_array_equal(free.tau_upper, [100.0, 0.0])
    ocp_z, zero = _solve(free)
    _, passive = _solve(pendulum, Actuation(passive=("pendulum",)))
    assert ocp_z.actuators.passive_joints == ("pendulum",)
    assert zero.objective == pytest.approx(passive.objective, rel=1e-9)
    np.testing.assert_allclose(zero.x, passive.x, atol=1e-9)


def test_the_study_key_builds_the_python_api_actuators(pendulum):
    study = Study.from_dict({
        "model": {"urdf": str(URDF)}, "actuators": {"passive": ["pendulum"], "coupling": "observed"},
        "fatigue": {"LD": 100.0, "LR": 100.0, "F": 5.0, "R": 10.0, "S": 10.0},
        "task": {"cycle_duration": 1.0, "intervals_per_cycle": 10, "q_init": [0.0, 0.0],
                 "targets": [{"joint": "slider", "value": 0.5, "at": 0.5}]},
        "costs": {"torque": 1.0},
    })
    assert "[actuators]" in study.to_toml() and Study.from_toml(study.to_toml()).data == study.data
    api = Problem.build(pendulum, XIA, TASK, [torque(1.0)], actuation=Actuation(passive=("pendulum",), coupling="observed"))
    built = study.problem(pendulum)
    assert built.actuators.structure_key() == api.actuators.structure_key()
    assert built.actuators.passive_joints == ("pendulum",) and built.actuators.coupling_kind == "observed"


def test_observed_is_tl_mf_where_the_row_is_inactive(pendulum):
    ocp, row = _solve(pendulum, Actuation(passive=("pendulum",)))
    _, observed = _solve(pendulum, Actuation(passive=("pendulum",), coupling="observed"))
    u = np.vstack([row.u, row.u[-1:]])
    coupling = np.array([np.asarray(ocp.functions.coupling(row.x[k], u[k])).ravel() for k in range(u.shape[0])])
    assert coupling.max() < 0.5  # the row is inactive at the optimum
    assert observed.objective == pytest.approx(row.objective, rel=1e-5)
    np.testing.assert_allclose(observed.q, row.q, atol=1e-5)


def test_observed_lets_the_torque_pass_the_fatigue_limit():
    """The slider alone (the pendulum locked) driven 2 m out and back with fatigue fast enough to
    bind (F = 40/s): tl+mf<=1 holds TL + mf <= 1 and costs more; observed passes 1."""
    model = load_model(URDF, locked_joints={"pendulum": 0.0})
    fast = XiaFatigue(LD=50, LR=50, F=40, R=0.1, S=10)
    task = Task(1.0, 10, items=(JointTarget("slider", 2.0, at=0.5),), q_init=(0.0,))
    worst, objective = {}, {}
    for coupling in ("tl+mf<=1", "observed"):
        problem = Problem.build(model, fast, task, [torque(1e-3)], actuation=Actuation(coupling=coupling))
        ocp = Ocp(problem, 1, TRANSCRIPTION, SOLVER)
        sol = ocp.solve()
        assert sol.success, sol.status
        u = np.vstack([sol.u, sol.u[-1:]])
        worst[coupling] = max(np.asarray(ocp.functions.coupling(sol.x[k], u[k])).max() for k in range(u.shape[0]))
        objective[coupling] = sol.objective
    assert worst["tl+mf<=1"] <= 1 + 1e-6 and worst["observed"] > 1.03
    assert objective["observed"] < 0.99 * objective["tl+mf<=1"]


def test_active_interval_is_the_closed_form_of_xia_on_a_point_mass():
    """The locked pendulum leaves a point mass m on the slider (no gravity along y). Under the
    ``active`` coupling, from rest with TL = u / limit on the plus half, Xia's controller gives
    ma(t) = a (1 - exp(-k t)), a = LD TL / (LD + F), k = LD + F (while ma < TL <= mr), so the
    force is limit * ma(t) and y(t) = limit a / m (t^2 / 2 - t / k + (1 - exp(-k t)) / k^2)."""
    model = load_model(URDF, locked_joints={"pendulum": 0.0})
    mass = float(pin.crba(model.pin_model, model.pin_model.createData(), np.zeros(1))[0, 0])
    problem = Problem.build(model, XIA, Task(1.0, 10, q_init=(0.0,)), [torque(1.0)], actuation=Actuation(coupling="active"))
    ocp = Ocp(problem, 1, Transcription(substeps=50), SOLVER)
    u = np.array([40.0, 0.0])  # TL = 0.4 on the plus half
    x0 = problem.initial_state()
    x1 = ocp.functions.step(x0, u, problem.actuators.param_vector())
    t, TL, lim = 0.1, 0.4, 100.0
    a, k = XIA.LD * TL / (XIA.LD + XIA.F), XIA.LD + XIA.F
    y = lim * a / mass * (t**2 / 2 - t / k + (1 - np.exp(-k * t)) / k**2)
    v = lim * a / mass * (t - (1 - np.exp(-k * t)) / k)
    assert x1[0] == pytest.approx(y, rel=1e-8) and x1[1] == pytest.approx(v, rel=1e-8)
    assert x1[2] == pytest.approx(a * (1 - np.exp(-k * t)), rel=1e-8)  # ma of the plus half
    # the observed coupling takes the control itself: y = u t^2 / (2 m)
    observed = Ocp(Problem.build(model, XIA, Task(1.0, 10, q_init=(0.0,)), [torque(1.0)]), 1, Transcription(substeps=50), SOLVER)
    assert observed.functions.step(x0, u, problem.actuators.param_vector())[0] == pytest.approx(40.0 * t**2 / (2 * mass), rel=1e-9)


def test_an_active_solution_follows_the_flow_of_ma_times_the_limit(pendulum):
    """The active OCP's states, re-integrated interval by interval with scipy (numeric Pinocchio,
    the models' own rates, torque = sum ma x limit at every instant), match its nodes (50 RK4
    steps per interval: Xia's controller switches branch, which RK4 follows at first order)."""
    ocp, sol = _solve(pendulum, Actuation(passive=("pendulum",), coupling="active"), transcription=Transcription(substeps=50))
    A, L = ocp.actuators, ocp.layout
    data = pendulum.pin_model.createData()

    def rhs(_t, x, u):
        m = x[L.m]
        tau = np.zeros(L.nv)
        for h, (half, off) in enumerate(zip(A.halves, A.state_offsets())):
            tau[A.joint_names.index(half.joint)] += m[off + half.params.state_index("ma")] * half.signed_limit
        TL = A.half_torques(u) / A.signed_limits
        rates = [half.params.rates(m[off:off + half.params.n_states()], TL[h])
                 for h, (half, off) in enumerate(zip(A.halves, A.state_offsets()))]
        return np.concatenate([x[L.v], pin.aba(pendulum.pin_model, data, x[L.q], x[L.v], tau), *rates])

    for k in range(ocp.n_intervals):
        end = solve_ivp(rhs, (0.0, TASK.dt), sol.x[k], args=(sol.u[k],), method="DOP853", rtol=1e-10, atol=1e-12).y[:, -1]
        np.testing.assert_allclose(end, sol.x[k + 1], atol=2e-6)
    # the delivered torque is not the control: at node 0 (rested, ma = 0) it is 0
    assert np.all(sol.tau[0] == 0.0) and np.abs(sol.u[0]).max() > 0.1


def test_a_passive_run_stores_the_halves_that_exist(pendulum, tmp_path):
    ocp, sol = _solve(pendulum, Actuation(passive=("pendulum",)))
    run = solution_to_run(ocp, sol, "full/passive")
    write_run(tmp_path / "r.h5", run)
    back = read_run(tmp_path / "r.h5", "full/passive")
    assert back.actuator_names == ("slider_plus", "slider_minus") and back.passive_joints == ("pendulum",)
    np.testing.assert_allclose(back.half_torques(), A_halves := ocp.actuators.half_torques(sol.u))
    np.testing.assert_array_equal(back.tau_plus[:, 1], 0.0)
    np.testing.assert_allclose(back.target_loads(), A_halves / ocp.actuators.signed_limits)
    assert back.attrs["coupling"] == "tl+mf<=1"


def test_a_passive_run_plots_replays_and_verifies(pendulum, tmp_path):
    """The views ask the run for its halves: a figure per half that exists, the passive joint
    drawn rested in the replay, and verify's checks (gaps against scipy) pass."""
    from fatigue_pin.verify.verifier import verify_run
    from fatigue_pin.viz.plots import plot_run
    from fatigue_pin.viz.replay import build_animation

    ocp, sol = _solve(pendulum, Actuation(passive=("pendulum",)), transcription=Transcription(substeps=20))
    write_run(tmp_path / "r.h5", solution_to_run(ocp, sol, "full/passive"))
    run = read_run(tmp_path / "r.h5", "full/passive")
    assert plot_run(run, tmp_path / "figures")
    scene = build_animation(run)
    assert scene.n_frames == run.t.size
    report = verify_run(run)
    assert report.passed, report


def test_verify_refuses_an_active_run_of_torque_halves_with_one_line(pendulum):
    from fatigue_pin.core.errors import ResultFileError
    from fatigue_pin.verify.verifier import verify_run

    ocp, sol = _solve(pendulum, Actuation(passive=("pendulum",), coupling="active"))
    with pytest.raises(ResultFileError, match=r"has the coupling 'active' on torque halves .*verify checks it for muscles only"):
        verify_run(solution_to_run(ocp, sol, "full/active"))


@pytest.mark.slow
@pytest.mark.parametrize("coupling", ["tl+mf<=1", "active"])
def test_the_compiled_library_solves_passive_and_active_as_uncompiled(pendulum, coupling, tmp_path):
    """Library mode (compiled interval functions, derivative blocks; F_rb_active under
    ``active``) gives the uncompiled optimum."""
    actuation = Actuation(passive=("pendulum",), coupling=coupling)
    _, reference = _solve(pendulum, actuation)
    problem = Problem.build(pendulum, XIA, TASK, [torque(1.0)], actuation=actuation)
    ocp = Ocp(problem, 1, TRANSCRIPTION, SolverOptions(tol=1e-10, cache_dir=tmp_path, compiler_flags=("-O1",)))
    sol = ocp.solve()
    assert ocp.library is not None and sol.success
    assert ("F_rb_active" in ocp.library.names) == (coupling == "active")
    assert sol.objective == pytest.approx(reference.objective, rel=1e-9)
    np.testing.assert_allclose(sol.x, reference.x, atol=1e-8)


def test_the_bioptim_pendulum_study_reaches_bioptims_optimum(tmp_path):
    """studies/bioptim_pendulum_xia.toml (the passive pendulum, the ``observed`` coupling) on
    bioptim's grid: bioptim's objective for its example, 41.58259 (issue 32), and the same with
    ``tl+mf<=1``, whose row is inactive there."""
    from fatigue_pin.io.study import run_study

    study = Study.from_file(URDF.parents[1] / "studies" / "bioptim_pendulum_xia.toml").replace({"solver.compile": False})
    for coupling in ("observed", "tl+mf<=1"):
        out = tmp_path / f"{coupling.replace('<=', '_')}.h5"
        run_study(study.replace({"actuators.coupling": coupling}), out)
        run = read_run(out)
        assert run.converged and run.attrs["coupling"] == coupling
        assert run.attrs["objective"] == pytest.approx(41.58259, rel=1e-5)
        assert run.actuator_names == ("slider_plus", "slider_minus")
        np.testing.assert_allclose(run.q[-1], [0.0, 3.14], atol=1e-8)
