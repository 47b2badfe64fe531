"""Tasks: constraint items placed on the nodes of the cycle."""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest

from conftest import small_curl
from fatigue_pin.core.errors import TaskError
from fatigue_pin.drivers.full import OcpBuilder
from fatigue_pin.ocp.problem import Problem
from fatigue_pin.ocp.task import JointRange, JointTarget, StateConstraint, Task, joint_target_pairs


def test_nodes_of_a_phase_repeat_every_cycle():
    task = Task(1.0, 10, (JointTarget("elbow", 0.3, 0.0), JointTarget("elbow", 2.0, 0.5)))
    assert task.nodes(0.0, 30) == [0, 10, 20, 30]
    assert task.nodes(0.5, 30) == [5, 15, 25]
    assert task.nodes(None, 3) == [0, 1, 2, 3]
    assert Task(1.0, 10, final_node_offset=-1).nodes(0.0, 20) == [0, 10, 19]


def test_reference_trajectory_is_the_curl_cosine(arm26):
    low, high = math.radians(15), math.radians(150)
    task = Task(1.0, 50, (JointTarget("elbow", low, 0.0), JointTarget("elbow", high, 0.5)))
    t = np.linspace(0, 2, 101)
    q, qd, qdd = task.reference_trajectory(arm26, t, np.array([0.07, low]))
    w = 2 * np.pi
    assert np.allclose(q[:, 1], low + (high - low) * 0.5 * (1 - np.cos(w * t)), atol=1e-12)
    assert np.allclose(qd[:, 1], (high - low) * 0.5 * w * np.sin(w * t), atol=1e-9)
    assert np.allclose(qdd[:, 1], (high - low) * 0.5 * w * w * np.cos(w * t), atol=1e-9)
    assert np.all(q[:, 0] == 0.07)


def test_tolerance_and_ranges_reach_the_bounds(arm26):
    study = small_curl("full", cycles=1)
    base = study.problem(arm26)
    task = Task(1.0, 10, (JointTarget("elbow", 2.0, 0.5, tolerance=0.1), JointRange("shoulder", -0.2, 0.3)), q_init=(0.0, 0.3))
    problem = Problem(base.model, base.actuators, task, base.costs)
    ocp = OcpBuilder(problem, study.transcription(), study.solver())(1)
    lb, ub = ocp.state_bounds(ocp.initial_state())
    assert lb[1, 5] == pytest.approx(1.9) and ub[1, 5] == pytest.approx(2.1)
    assert np.all(lb[0, 1:] == -0.2) and np.all(ub[0, 1:] == 0.3)
    sol = ocp.solve()
    assert sol.success
    assert 1.9 - 1e-6 <= sol.q[5, 1] <= 2.1 + 1e-6
    assert np.all(sol.q[:, 0] >= -0.2 - 1e-6) and np.all(sol.q[:, 0] <= 0.3 + 1e-6)
    assert joint_target_pairs(task, arm26, 10) == [(5, 1, pytest.approx(1.9), pytest.approx(2.1))]


def test_a_state_constraint_is_imposed_at_its_nodes(arm26):
    """A general expression of the state: the shoulder + elbow angle sum at phase 0.5."""
    study = small_curl("full", cycles=1)
    base = study.problem(arm26)
    x = ca.SX.sym("x", base.layout.nx)
    total = ca.Function("total", [x], [x[0] + x[1]])
    task = Task(1.0, 10, (JointTarget("elbow", 0.3, 0.0), StateConstraint("angle_sum", total, [1.5], [1.6], at=0.5)),
                q_init=(0.0, 0.3))
    ocp = OcpBuilder(Problem(base.model, base.actuators, task, base.costs), study.transcription(), study.solver())(2)
    sol = ocp.solve()
    assert sol.success
    for node in (5, 15):
        assert 1.5 - 1e-6 <= sol.q[node].sum() <= 1.6 + 1e-6


@pytest.mark.parametrize(
    "build, match",
    [
        (lambda: Task(0.0, 10), "cycle_duration"),
        (lambda: Task(1.0, 0), "intervals_per_cycle"),
        (lambda: Task(1.0, 10, (JointTarget("elbow", 1.0, 0.25),)), "not a node"),
        (lambda: JointTarget("elbow", math.inf), "value"),
        (lambda: JointTarget("elbow", 1.0, tolerance=-1), "tolerance"),
        (lambda: JointRange("elbow", 1.0, 0.0), "lower"),
        (lambda: Task(1.0, 10, final_node_offset=2), "final_node_offset"),
    ],
)
def test_bad_tasks_name_the_value(build, match):
    with pytest.raises(TaskError, match=match):
        build()


def test_task_checks_against_the_model(arm26):
    with pytest.raises(TaskError, match="'knee' is not in model"):
        Task(1.0, 10, (JointTarget("knee", 1.0),)).check(arm26)
    with pytest.raises(TaskError, match="q_init"):
        Task(1.0, 10, q_init=(0.0, 9.0)).check(arm26)
    with pytest.raises(TaskError, match="nq = 2"):
        Task(1.0, 10, q_init=(0.0,)).check(arm26)


def test_one_target_per_joint_and_phase():
    """Two targets of one joint at one node that differ are refused (the later one replaced the
    earlier one's bounds); identical ones, and ones on other joints or phases, are accepted.
    Phase 0 and a phase that rounds to node 0 are the same node."""
    with pytest.raises(TaskError, match=r"task targets 2.0 \(\+- 0\) and 1.0 \(\+- 0\) of joint 'elbow' at phase 0.5"):
        Task(1.0, 10, (JointTarget("elbow", 2.0, 0.5), JointTarget("elbow", 1.0, 0.5)))
    with pytest.raises(TaskError, match=r"and 2.0 \(\+- 0.1\) of joint 'elbow'"):
        Task(1.0, 10, (JointTarget("elbow", 2.0, 0.5), JointTarget("elbow", 2.0, 0.5, tolerance=0.1)))
    task = Task(1.0, 10, (JointTarget("elbow", 2.0, 0.5), JointTarget("elbow", 2.0, 0.5), JointTarget("shoulder", 1.0, 0.5),
                          JointTarget("elbow", 1.0, 0.0)))
    assert len(task.joint_targets) == 4


def test_q_init_must_meet_the_phase_0_targets(arm26):
    """A q_init off a phase-0 target was overridden at node 0 without a word; now it is refused,
    within the target's tolerance it is accepted, and without q_init the start is the target."""
    with pytest.raises(TaskError, match=r"q_init = \[0.07, 0.5\] puts joint 'elbow' at 0.5, but its target at phase 0 is 0.3"):
        Task(1.0, 10, (JointTarget("elbow", 0.3, 0.0),), q_init=(0.07, 0.5)).check(arm26)
    Task(1.0, 10, (JointTarget("elbow", 0.3, 0.0, tolerance=0.25),), q_init=(0.07, 0.5)).check(arm26)
    Task(1.0, 10, (JointTarget("elbow", 0.3, 0.5),), q_init=(0.07, 0.5)).check(arm26)  # not at phase 0
    assert Task(1.0, 10, (JointTarget("elbow", 0.3, 0.0),)).initial_configuration(arm26)[1] == 0.3


def test_x_init_must_meet_the_phase_0_targets():
    from fatigue_pin.core.errors import ParameterError

    problem = small_curl("full").problem()
    x = problem.initial_state()
    x[1] += 0.2
    with pytest.raises(ParameterError, match=r"x_init's q = .* puts joint 'elbow' at"):
        problem.with_x_init(x)
    x[1] -= 0.2
    assert np.array_equal(problem.with_x_init(x).initial_state(), x)


def test_horizon_size_is_bounded_before_anything_is_built():
    from fatigue_pin.core.errors import ParameterError
    from fatigue_pin.ocp.task import MAX_INTERVALS, check_horizon

    task = Task(1.0, 10)
    assert check_horizon(task, MAX_INTERVALS // 10) == MAX_INTERVALS // 10
    for bad, match in ((MAX_INTERVALS // 10 + 1, "expected at most 1000000 in one OCP"), (10**20, "shooting intervals"),
                       (0, "expected an integer number of cycles >= 1"), (2.0, "expected an integer"), (True, "expected an integer")):
        with pytest.raises(ParameterError, match=match):
            check_horizon(task, bad)
    with pytest.raises(TaskError, match=r"intervals_per_cycle = 1000001: expected an integer in \[1, 1000000\]"):
        Task(1.0, MAX_INTERVALS + 1)


def test_a_given_start_has_no_start_posture_to_check(arm26):
    """A task whose every solve gives the start state (``given_start``: a closed loop's window that
    starts mid-cycle) has no start posture: the default one (every joint at 0, here below the
    plane) is not checked, as it is otherwise; its frames still are, and a q_init is refused."""
    from fatigue_pin.ocp.task import FramePlane

    items = (JointTarget("elbow", 2.6, 0.5), FramePlane("dumbbell", (0.0, 0.0, 1.0), -0.57))  # every joint at 0: z = -0.577 m
    with pytest.raises(TaskError, match="below the plane"):
        Task(1.0, 10, items).check(arm26)
    Task(1.0, 10, items, given_start=True).check(arm26)
    with pytest.raises(TaskError, match="'hand'"):
        Task(1.0, 10, (FramePlane("hand", (0.0, 0.0, 1.0), 0.0),), given_start=True).check(arm26)
    with pytest.raises(TaskError, match="q_init with given_start"):
        Task(1.0, 10, items, q_init=(0.07, 0.3), given_start=True)
