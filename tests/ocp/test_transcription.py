"""The transcription: solutions satisfy the formulation, and bad settings are refused."""

from __future__ import annotations

import math

import numpy as np
import pytest

from conftest import small_curl
from fatigue_pin.core.errors import ParameterError, TaskError
from fatigue_pin.drivers.full import OcpBuilder
from fatigue_pin.paper.curl import curl_study
from fatigue_pin.ocp.solver import SolverOptions
from fatigue_pin.ocp.task import joint_target_pairs
from fatigue_pin.ocp.bounds import constraint_bounds
from fatigue_pin.ocp.transcription import Ocp, Transcription

COST_TERMS = ("posture", "torque_rate", "fatigue", "torque")


@pytest.fixture(scope="module")
def solved_one_cycle(arm26):
    """The paper's 1-cycle curl (50 intervals, RK4 x 5), uncompiled."""
    study = curl_study("full", solver={"compile": False})
    ocp = OcpBuilder(study.problem(arm26), study.transcription(), study.solver())(1)
    return ocp, ocp.solve()


def check_solution(ocp: Ocp, sol, gap_tol: float = 1e-6) -> None:
    """Assert that ``sol`` satisfies every part of the formulation."""
    assert sol.success, sol.status
    model, task = ocp.model, ocp.task
    for node, row, lo, hi in joint_target_pairs(task, model, ocp.n_intervals):
        assert lo - 1e-6 <= sol.q[node, row] <= hi + 1e-6
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


def test_two_cycles_reduced_problem(build):
    ocp = build(2)
    sol = ocp.solve()
    check_solution(ocp, sol)
    assert sol.cycle_costs.shape == (2, 4)
    # mf grows from the first to the second cycle for the most used half
    mf = sol.fatigue("mf")
    h = int(np.argmax(mf[-1]))
    assert mf[-1, h] > mf[10, h] > 0


def test_costs_are_weights_only(small_study):
    torque = small_curl(cost="torque").problem()
    fatigue = small_curl(cost="fatigue").problem()
    w = dict(zip(torque.cost_names, torque.weights))
    assert w["fatigue"] == 0 and w["torque"] == 1
    w = dict(zip(fatigue.cost_names, fatigue.weights))
    assert w["torque"] == 0 and w["fatigue"] == 1e3
    ac = small_curl(preset="authors-code")
    assert ac.data["costs"]["posture"]["weight"] == 1e4 and ac.data["fatigue"]["R"] == 0.0094
    assert small_study.data["fatigue"]["R"] == 0.00094


def test_one_ocp_serves_every_cost(build):
    """One NLP, three weightings: each cost gives its own solution, and each is the best of the
    three under its own weights."""
    ocp = build(1)
    names = ocp.cost_terms
    sols = {cost: ocp.solve(weights=small_curl(cost=cost).problem().weights) for cost in ("fatigue-torque", "fatigue", "torque")}
    assert all(s.success for s in sols.values())
    assert sols["torque"].cycle_costs[0, names.index("fatigue")] == 0
    assert sols["fatigue"].cycle_costs[0, names.index("torque")] == 0
    # the solutions differ ...
    assert np.abs(sols["torque"].u - sols["fatigue"].u).max() > 1e-2
    assert np.abs(sols["torque"].x - sols["fatigue-torque"].x).max() > 1e-4
    # ... and each is no worse than the others under its own weights
    for cost, sol in sols.items():
        w = small_curl(cost=cost).problem().weights
        own = ocp.cycle_costs(sol.x, sol.u, w).sum()
        for other in sols.values():
            assert own <= ocp.cycle_costs(other.x, other.u, w).sum() * (1 + 1e-6)


def test_cycle_costs_land_in_their_cycle(build):
    """Three cycles: each cycle's per-term cost equals the terms summed over that cycle's intervals
    only, and fatigue costs grow from cycle to cycle."""
    ocp = build(3)
    sol = ocp.solve()
    assert sol.success and sol.cycle_costs.shape == (3, 4)
    w = ocp.problem.weights
    n = ocp.task.intervals_per_cycle
    u_prev = np.vstack([sol.u[:1], sol.u[:-1]])
    for c in range(3):
        terms = sum(np.asarray(ocp.functions.terms(sol.x[k], sol.u[k], u_prev[k])).ravel() for k in range(c * n, (c + 1) * n))
        assert np.allclose(sol.cycle_costs[c], terms * w, rtol=1e-9, atol=1e-12)
    f = ocp.cost_terms.index("fatigue")
    assert sol.cycle_costs[0, f] < sol.cycle_costs[1, f] < sol.cycle_costs[2, f]
    assert sol.cycle_costs.sum() == pytest.approx(sol.objective, rel=1e-8)


def test_authors_code_last_node(arm26):
    task = small_curl(preset="authors-code").task()
    assert joint_target_pairs(task, arm26, 10) == [(0, 1, math.radians(15), math.radians(15)), (5, 1, math.radians(150), math.radians(150)),
                                                  (9, 1, math.radians(15), math.radians(15))]


def test_compiled_solve_matches_uncompiled(small_problem, build, tmp_path):
    plain = build(1).solve()
    compiled_ocp = Ocp(small_problem, 1, build.transcription, SolverOptions(cache_dir=tmp_path, compile_mode="nlp", compiler_flags=("-O0",)))
    assert compiled_ocp.nlp.compiled_path is not None and compiled_ocp.nlp.compiled_path.exists()
    compiled = compiled_ocp.solve()
    assert compiled.success and compiled.objective == pytest.approx(plain.objective, rel=1e-6)
    # compiled problems map their intervals with OpenMP, and the library is built with it
    assert compiled_ocp.map_mode == "openmp" and plain.status == compiled.status
    assert b"GOMP_parallel" in compiled_ocp.nlp.compiled_path.read_bytes()
    # a second build finds the library in the cache instead of compiling again
    again = Ocp(small_problem, 1, build.transcription, SolverOptions(cache_dir=tmp_path, compile_mode="nlp", compiler_flags=("-O0",)))
    assert again.nlp.compile_time_s == 0.0 and again.nlp.compiled_path == compiled_ocp.nlp.compiled_path


def test_scaling_changes_iterations_not_the_solution(small_problem, build):
    scaled = build(2)
    plain = Ocp(small_problem, 2, Transcription(substeps=2, scaling=False), build.solver)
    assert scaled.u_scale.max() == 50.0 and plain.u_scale.max() == 1.0
    a, b = scaled.solve(), plain.solve()
    assert a.success and b.success
    assert a.objective == pytest.approx(b.objective, rel=1e-5)
    assert np.allclose(a.q, b.q, atol=1e-3)


def test_the_papers_code_structure_gives_the_same_solution(small_problem, build):
    """Targets as g rows and no joint-torque variable (the paper's code): the same optimum."""
    ours = build(2)
    theirs = Ocp(small_problem, 2, Transcription(substeps=2, torque_variable=False, target_rows=True), build.solver)
    n_targets = len(joint_target_pairs(ours.task, ours.model, ours.n_intervals))
    # g loses the nv x N torque rows and gains one row per target (node 0's included)
    assert theirs.nlp.n_g == ours.nlp.n_g - ours.layout.nv * ours.n_intervals + n_targets
    assert theirs.nlp.n_x == ours.nlp.n_x - ours.layout.nv * ours.n_intervals
    assert len(theirs.kept_rows) == n_targets
    a, b = ours.solve(), theirs.solve()
    assert a.success and b.success, (a.status, b.status)
    assert a.objective == pytest.approx(b.objective, rel=1e-5)
    assert np.allclose(a.q, b.q, atol=1e-3) and np.allclose(a.u, b.u, atol=1e-2)
    check_solution(theirs, b)


def test_rest_guess_is_the_initial_state_with_zero_torque(small_problem, build):
    ocp = build(2)
    x, u = ocp.initial_guess()
    assert x.shape == (21, ocp.layout.nx) and u.shape == (20, 4)
    assert np.all(x == ocp.initial_state()) and np.all(u == 0)
    xp, up = Ocp(small_problem, 2, build.transcription, build.solver, guess="physical").initial_guess()
    assert np.abs(up).max() > 1.0 and np.ptp(xp[:, 1]) > 2.0  # elbow swept 15 -> 150 deg


def test_failure_is_a_result(small_problem, build):
    ocp = Ocp(small_problem, 1, build.transcription, SolverOptions(compile=False, max_iter=2))
    sol = ocp.solve()
    assert not sol.success and sol.status == "Maximum_Iterations_Exceeded"
    assert sol.iterations == 2 and sol.x.shape == (11, ocp.layout.nx)


@pytest.mark.parametrize(
    "changes, match",
    [
        ({"substeps": 0}, "substeps"),
        ({"integrator": "euler"}, "integrator"),
        ({"parallel": "gpu"}, "parallel"),
        ({"target_rows": 1}, "target_rows"),
    ],
)
def test_bad_transcription(changes, match):
    with pytest.raises(ParameterError, match=match):
        Transcription(**changes)


def test_bad_horizon_and_guess(small_problem):
    with pytest.raises(ParameterError, match="n_cycles"):
        Ocp(small_problem, 0, solver=SolverOptions(compile=False))
    with pytest.raises(ParameterError, match="guess"):
        Ocp(small_problem, 1, solver=SolverOptions(compile=False), guess="zero")


def test_unstable_stabiliser_is_refused(arm26):
    # RK4 substep 0.02 / 5 = 0.004 s: S * h must stay below 2.785
    with pytest.raises(ParameterError, match="S = 800"):
        Ocp(curl_study("full", S=800.0).problem(arm26), 1, Transcription(substeps=5), SolverOptions(compile=False))


def test_bad_tasks(arm26):
    with pytest.raises(TaskError, match="wrist"):
        small_curl().replace({"task.targets": [{"joint": "wrist", "value": 0.1}]}).problem(arm26)
    with pytest.raises(TaskError, match="outside its range"):
        small_curl().replace({"task.targets": [{"joint": "elbow", "value": 4.0, "at": 0.5}]}).problem(arm26)
    with pytest.raises(TaskError, match="not a node"):
        small_curl().replace({"task.targets": [{"joint": "elbow", "value": 1.0, "at": 0.33}]}).problem(arm26)


def test_task_on_another_robot():
    """Any model from load_model gets a task of its own (UR5 from example-robot-data)."""
    from fatigue_pin.ocp.costs import posture
    from fatigue_pin.robot.model import resolve_model
    from fatigue_pin.paper.curl import ocp_params
    from fatigue_pin.ocp.problem import Problem
    from fatigue_pin.ocp.task import JointTarget, Task

    model = resolve_model("ur5")
    task = Task(1.0, 10, (JointTarget("elbow_joint", 0.5, 0.0), JointTarget("elbow_joint", 1.5, 0.5)))
    problem = Problem.build(model, ocp_params(), task, [posture(1.0, ["shoulder_lift_joint"])])
    ocp = Ocp(problem, 1, Transcription(substeps=2), SolverOptions(compile=False), guess="physical")
    assert ocp.layout.nx == 6 + 6 + 3 * 12 and ocp.actuators.n_halves == 12
    x, u = ocp.initial_guess()
    assert x.shape == (11, ocp.layout.nx) and u.shape == (10, 12)
    assert x[5, model.joint_names.index("elbow_joint")] == pytest.approx(1.5)


def test_the_curl_with_michauds_model_converges(tmp_path):
    """Michaud's model (four states, effort E) on every half: the OCP converges, the result file
    carries E, and the four states keep their sum."""
    from fatigue_pin.io.study import run_study

    study = small_curl("full", cycles=2).replace({
        "name": "michaud_curl",
        "fatigue": {"model": "michaud", "LD": 10.0, "LR": 10.0, "F": 0.456, "R": 0.0094, "effort_threshold": 0.2,
                    "effort_factor": 0.1, "stabilization_factor": 10.0},
    })
    run = run_study(study, tmp_path / "michaud.h5").run
    assert run.converged
    assert run.fatigue_states == ("ma", "mr", "mf", "E")
    assert run.fatigue["E"].max() > 1e-4  # effort builds up above the threshold
    assert run.invariant_error().max() < 1e-6  # ma + mr + mf + E = 1


def test_a_start_that_misses_a_node_0_row_is_not_infeasible(small_problem, build):
    """A task row at node 0 that the start state misses (here a plane at every node, the start 3 mm
    below it: a closed loop's measured state, docs/mpc.md) made the NLP infeasible, node 0 being
    fixed to x_init. Its bounds at node 0 are widened to the start's value; every other node keeps
    the row, and a start that meets the row keeps its bounds."""
    import dataclasses

    from fatigue_pin.ocp.task import FramePlane
    from fatigue_pin.robot.kinematics import frame_placement

    pm = small_problem.model.pin_model

    def height(x):
        return frame_placement(pm, "dumbbell", x[:2]).translation[2]

    x0 = small_problem.initial_state()
    plane = FramePlane("dumbbell", (0.0, 0.0, 1.0), height(x0) - 0.002)  # q_init 2 mm above the plane
    task = dataclasses.replace(small_problem.task, items=small_problem.task.items + (plane,))
    ocp = Ocp(dataclasses.replace(small_problem, task=task), 1, build.transcription, build.solver)
    x_init = x0.copy()
    x_init[0] = 0.02  # the shoulder 0.05 rad lower than q_init: the dumbbell 3.3 mm below the plane
    assert height(x_init) - plane.offset < -0.003
    sol = ocp.solve(x_init=x_init)
    assert sol.success, sol.status
    np.testing.assert_allclose(sol.x[0], x_init, atol=1e-12)
    assert min(height(x) for x in sol.x[1:]) >= plane.offset - 1e-6
    sc, nodes = ocp._state_constraints[0]
    lower, upper = constraint_bounds(sc, nodes, x_init)
    assert lower[0, 0] == pytest.approx(height(x_init)) and np.all(lower[0, 1:] == plane.offset) and np.all(upper == np.inf)
    assert np.all(constraint_bounds(sc, nodes, x0)[0] == plane.offset)  # a start above keeps the row
