"""The fatigue OCP: solutions satisfy the formulation, and bad settings are refused."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fatigue_pin.errors import ParameterError, TaskError
from fatigue_pin.ocp import COST_TERMS, CostWeights, CyclicTask, FatigueOcp, OcpSettings
from fatigue_pin.solver import SolverOptions


@pytest.fixture(scope="module")
def solved_one_cycle(arm26):
    """The paper's 1-cycle curl (50 intervals, RK4 x 5), uncompiled."""
    ocp = FatigueOcp(arm26, OcpSettings(n_cycles=1, solver=SolverOptions(compile=False)))
    return ocp, ocp.solve()


def check_solution(ocp: FatigueOcp, sol, gap_tol: float = 1e-6) -> None:
    """Assert that ``sol`` satisfies every part of the formulation."""
    assert sol.success, sol.status
    model, task = ocp.model, ocp.task
    elbow = model.joint_names.index(task.joint)
    for node, angle in task.targets(ocp.n_intervals):
        assert sol.q[node, elbow] == pytest.approx(angle, abs=1e-6)
    # dynamics continuity: every interval integrated again numerically lands on the next node
    p = ocp.actuators.param_vector()
    gaps = [np.max(np.abs(ocp.functions.step(sol.x[k], sol.u[k], p) - sol.x[k + 1])) for k in range(ocp.n_intervals)]
    assert max(gaps) < gap_tol
    # coupling 0 <= TL + mf <= 1 at every node
    u_nodes = np.vstack([sol.u, sol.u[-1]])
    coupling = np.array([np.asarray(ocp.functions.coupling(sol.x[k], u_nodes[k])).ravel() for k in range(ocp.n_intervals + 1)])
    assert coupling.max() <= 1 + 1e-6 and coupling.min() >= -1e-6
    # bounds
    tol = 1e-6
    assert np.all(sol.q >= model.q_lower - tol) and np.all(sol.q <= model.q_upper + tol)
    assert np.all(np.abs(sol.qdot) <= model.v_upper + tol)
    assert np.all(sol.tau_plus >= -tol) and np.all(sol.tau_plus <= model.tau_upper + tol)
    assert np.all(sol.tau_minus <= tol) and np.all(sol.tau_minus >= model.tau_lower - tol)
    for name in ("ma", "mr", "mf"):
        assert np.all(sol.fatigue(name) >= -tol) and np.all(sol.fatigue(name) <= 1 + tol)
    # the fatigue invariant
    total = sol.fatigue("ma") + sol.fatigue("mr") + sol.fatigue("mf")
    assert np.max(np.abs(1 - total)) < 1e-6
    # initial state is the task's
    assert np.allclose(sol.x[0], ocp.initial_state(), atol=1e-9)


def test_one_cycle_solution_satisfies_the_formulation(solved_one_cycle):
    ocp, sol = solved_one_cycle
    check_solution(ocp, sol)


def test_cycle_costs_add_up_to_the_objective(solved_one_cycle):
    ocp, sol = solved_one_cycle
    assert sol.cycle_costs.shape == (1, len(COST_TERMS))
    assert sol.cycle_costs.sum() == pytest.approx(sol.objective, rel=1e-8)


def test_fatigue_builds_up_and_shoulder_stays_near_zero(solved_one_cycle):
    ocp, sol = solved_one_cycle
    assert sol.fatigue("mf")[-1].max() > 0.01  # working halves fatigue
    assert np.max(np.abs(sol.q[:, 0])) < 0.2  # the posture cost keeps the shoulder close to 0 rad


def test_two_cycles_reduced_problem(arm26, small_settings):
    ocp = FatigueOcp(arm26, small_settings.with_(n_cycles=2))
    sol = ocp.solve()
    check_solution(ocp, sol)
    assert sol.cycle_costs.shape == (2, 4)
    # mf grows from the first to the second cycle for the most used half
    mf = sol.fatigue("mf")
    h = int(np.argmax(mf[-1]))
    assert mf[-1, h] > mf[10, h] > 0


def test_costs_are_weights_only(arm26, small_settings):
    torque = small_settings.with_(cost="torque").resolved_weights()
    fatigue = small_settings.with_(cost="fatigue").resolved_weights()
    assert torque.fatigue == 0 and torque.torque == 1
    assert fatigue.torque == 0 and fatigue.fatigue == 1e3
    assert OcpSettings(preset="authors-code").resolved_weights().posture == 1e4
    assert OcpSettings(preset="authors-code").resolved_fatigue().R == 0.0094
    assert OcpSettings().resolved_fatigue().R == 0.00094


def test_one_ocp_serves_every_cost(arm26, small_settings):
    ocp = FatigueOcp(arm26, small_settings.with_(n_cycles=1))
    a = ocp.solve(weights=CostWeights().for_cost("torque"))
    b = ocp.solve(weights=CostWeights().for_cost("fatigue"))
    assert a.success and b.success
    assert a.cycle_costs[0, COST_TERMS.index("fatigue")] == 0
    assert b.cycle_costs[0, COST_TERMS.index("torque")] == 0


def test_authors_code_last_node(arm26, small_settings):
    ocp = FatigueOcp(arm26, small_settings.with_(n_cycles=1, task=CyclicTask(intervals_per_cycle=10, last_node_offset=-1)))
    assert ocp.task.targets(10) == [(0, math.radians(15)), (5, math.radians(150)), (9, math.radians(15))]


def test_compiled_solve_matches_uncompiled(arm26, small_settings, tmp_path):
    settings = small_settings.with_(n_cycles=1)
    plain = FatigueOcp(arm26, settings).solve()
    compiled_ocp = FatigueOcp(arm26, settings.with_(solver=SolverOptions(cache_dir=tmp_path)))
    assert compiled_ocp.nlp.compiled_path is not None and compiled_ocp.nlp.compiled_path.exists()
    compiled = compiled_ocp.solve()
    assert compiled.success and compiled.objective == pytest.approx(plain.objective, rel=1e-6)
    # compiled problems map their intervals with OpenMP, and the library is built with it
    assert compiled_ocp.settings.map_mode == "openmp" and plain.status == compiled.status
    assert b"GOMP_parallel" in compiled_ocp.nlp.compiled_path.read_bytes()
    # a second build finds the library in the cache instead of compiling again
    again = FatigueOcp(arm26, settings.with_(solver=SolverOptions(cache_dir=tmp_path)))
    assert again.nlp.compile_time_s == 0.0 and again.nlp.compiled_path == compiled_ocp.nlp.compiled_path


def test_building_a_compiled_problem_prints_no_openmp_fallback_warning(arm26, small_settings, tmp_path, capsys):
    FatigueOcp(arm26, small_settings.with_(n_cycles=1, solver=SolverOptions(cache_dir=tmp_path)))
    assert "WITH_OPENMP" not in capsys.readouterr().err


def test_scaling_changes_iterations_not_the_solution(arm26, small_settings):
    scaled = FatigueOcp(arm26, small_settings.with_(n_cycles=2))
    plain = FatigueOcp(arm26, small_settings.with_(n_cycles=2, scaling=False))
    assert scaled.u_scale.max() == 50.0 and plain.u_scale.max() == 1.0
    a, b = scaled.solve(), plain.solve()
    assert a.success and b.success
    assert a.objective == pytest.approx(b.objective, rel=1e-5)
    assert np.allclose(a.q, b.q, atol=1e-3)


def test_rest_guess_is_the_initial_state_with_zero_torque(arm26, small_settings):
    ocp = FatigueOcp(arm26, small_settings.with_(n_cycles=2))
    x, u = ocp.initial_guess()
    assert x.shape == (21, ocp.layout.nx) and u.shape == (20, 4)
    assert np.all(x == ocp.initial_state()) and np.all(u == 0)
    xp, up = FatigueOcp(arm26, small_settings.with_(n_cycles=2, guess="physical")).initial_guess()
    assert np.abs(up).max() > 1.0 and np.ptp(xp[:, 1]) > 2.0  # elbow swept 15 -> 150 deg


def test_failure_is_a_result(arm26, small_settings):
    ocp = FatigueOcp(arm26, small_settings.with_(n_cycles=1, solver=SolverOptions(compile=False, max_iter=2)))
    sol = ocp.solve()
    assert not sol.success and sol.status == "Maximum_Iterations_Exceeded"
    assert sol.iterations == 2 and sol.x.shape == (11, ocp.layout.nx)


@pytest.mark.parametrize(
    "changes, match",
    [
        ({"cost": "speed"}, "cost"),
        ({"S": -1.0}, "S"),
        ({"n_cycles": 0}, "n_cycles"),
        ({"preset": "mine"}, "preset"),
        ({"guess": "zero"}, "guess"),
    ],
)
def test_bad_settings(changes, match):
    with pytest.raises(ParameterError, match=match):
        OcpSettings(**changes)


def test_unstable_stabiliser_is_refused(arm26):
    # RK4 substep 0.02 / 5 = 0.004 s: S * h must stay below 2.785
    with pytest.raises(ParameterError, match="S = 800"):
        FatigueOcp(arm26, OcpSettings(S=800.0, solver=SolverOptions(compile=False)))


def test_bad_tasks(arm26):
    with pytest.raises(TaskError, match="wrist"):
        FatigueOcp(arm26, OcpSettings(task=CyclicTask(joint="wrist"), solver=SolverOptions(compile=False)))
    with pytest.raises(TaskError, match="outside its range"):
        FatigueOcp(arm26, OcpSettings(task=CyclicTask(high=4.0), solver=SolverOptions(compile=False)))
    with pytest.raises(TaskError, match="even"):
        CyclicTask(intervals_per_cycle=7)


def test_task_on_another_robot():
    """Any model from load_model gets a task of its own (UR5 from example-robot-data)."""
    from fatigue_pin.model import example_robot_urdf, load_model

    model = load_model(example_robot_urdf("ur5"))
    task = CyclicTask(joint="elbow_joint", low=0.5, high=1.5, q_init=None, penalised_joints=("shoulder_lift_joint",),
                      intervals_per_cycle=10)
    ocp = FatigueOcp(model, OcpSettings(task=task, substeps=2, solver=SolverOptions(compile=False)))
    assert ocp.layout.nx == 6 + 6 + 3 * 12 and ocp.actuators.n_halves == 12
    x, u = ocp.physical_guess()
    assert x.shape == (11, ocp.layout.nx) and u.shape == (10, 12)
