"""Tasks with an end (non-cyclic phases), start velocities, terminal and per-joint costs: each new
key against the Python API's own construction of the same problem, or a closed form."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from conftest import swing_up
from fatigue_pin.core.errors import ParameterError, TaskError
from fatigue_pin.ocp.costs import CostTerm, cost_term, state, torque, velocity
from fatigue_pin.ocp.solver import SolverOptions
from fatigue_pin.ocp.task import END, JointTarget, StateConstraint, StateTarget, Task
from fatigue_pin.ocp.transcription import Ocp, Transcription

FAST = SolverOptions(compile=False, mu_init=0.1)
GRID = Transcription(substeps=4)  # h LD = 2.5: inside RK4's stability for the fatigue (LD = 100)


def _solve(problem, cycles: int = 1, **kwargs):
    sol = Ocp(problem, cycles, GRID, FAST, **kwargs).solve()
    assert sol.success, sol.status
    return sol


def test_phase_nodes_of_cyclic_and_non_cyclic_tasks():
    cyclic = Task(1.0, 4, (JointTarget("elbow", 0.3, 0.0),))
    assert cyclic.cyclic and cyclic.nodes(0.0, 8) == [0, 4, 8] and cyclic.nodes(0.5, 8) == [2, 6]
    ends = Task(1.0, 4, (JointTarget("elbow", 0.3, 0.0), JointTarget("elbow", 1.0, "end")))
    assert not ends.cyclic  # an item at the end makes the task non-cyclic
    assert ends.nodes(0.0, 8) == [0, 4] and ends.nodes(END, 8) == [4, 8] and ends.nodes(None, 2) == [0, 1, 2]
    assert Task(1.0, 4, (JointTarget("elbow", 1.0, 1.0),)).items[0].at == END  # at = 1.0 is the end
    assert Task(1.0, 4, cyclic=False).nodes(0.0, 8) == [0, 4]
    with pytest.raises(TaskError, match="cyclic = true"):
        Task(1.0, 4, (JointTarget("elbow", 1.0, "end"),), cyclic=True)
    with pytest.raises(TaskError, match="final_node_offset = -1 in a non-cyclic task"):
        Task(1.0, 4, cyclic=False, final_node_offset=-1)
    with pytest.raises(TaskError, match="a value .* a velocity"):
        JointTarget("elbow")
    with pytest.raises(TaskError, match=r"at = 'later'"):
        JointTarget("elbow", 1.0, "later")


def test_bad_end_items_are_refused_with_their_values(pendulum):
    with pytest.raises(TaskError, match=r"target 9.0 of joint 'pendulum' is outside its range .* \(at the end\)"):
        swing_up(pendulum, JointTarget("pendulum", 9.0, "end"))
    with pytest.raises(TaskError, match=r"velocity target 99.0 of joint 'slider' is outside its velocity bounds .* \(at the end\)"):
        swing_up(pendulum, JointTarget("slider", velocity=99.0, at="end"))
    with pytest.raises(TaskError, match="state target 'slider_plus_mx' is not a state"):
        swing_up(pendulum, StateTarget("slider_plus_mx", 0.0))
    with pytest.raises(TaskError, match="qdot_init = \\[99.0, 0.0\\]"):
        swing_up(pendulum, qdot_init=(99.0, 0.0))


def test_an_end_target_is_the_state_constraint_the_api_builds_by_hand(pendulum):
    """The end targets (q and qdot at the end) against the construction a user of the cyclic task
    had to write: a StateConstraint on (q, qdot) at phase 0, which binds node N and is widened to
    the start state at node 0."""
    keyed = _solve(swing_up(pendulum))
    x = ca.SX.sym("x", keyed.layout.nx)
    target = np.array([0.0, 3.14, 0.0, 0.0])
    by_hand = StateConstraint("end_state", ca.Function("end_state", [x], [x[:4] - target]), 0.0, 0.0, at=0.0)
    handmade = _solve(swing_up(pendulum, by_hand))
    assert keyed.objective == pytest.approx(handmade.objective, rel=1e-6)
    np.testing.assert_allclose(keyed.x, handmade.x, atol=1e-5)
    np.testing.assert_allclose(keyed.x[-1, :4], target, atol=1e-8)  # the end, exactly (a bound)
    assert keyed.objective > 0


def test_qdot_init_is_the_start_state_the_api_gives(pendulum):
    keyed = swing_up(pendulum, qdot_init=(0.5, -1.0))
    x0 = keyed.initial_state()
    np.testing.assert_array_equal(x0[keyed.layout.v], [0.5, -1.0])
    by_hand = swing_up(pendulum).with_x_init(x0)
    a, b = _solve(keyed), _solve(by_hand)
    assert a.objective == pytest.approx(b.objective, rel=1e-8)
    np.testing.assert_allclose(a.x[0], x0)


def test_a_state_target_on_a_fatigue_state_is_the_bound_of_its_row(pendulum):
    """An end target on slider_plus_ma (the active fraction), a bound of the NLP, against a
    StateConstraint row on the same entry of x at the end, found by the layout's name. The swing-up
    has many local optima, so each is started from the other's optimum: the same NLP stays there."""
    free = _solve(swing_up(pendulum))
    layout = free.layout
    row = layout.state_row("slider_plus_ma")
    assert layout.state_names[row] == "slider_plus_ma" and row == 4  # after q (2) and qdot (2)
    cap = 0.8 * float(free.x[-1, row])
    items = swing_up(pendulum).task.items
    keyed_ocp = Ocp(swing_up(pendulum, *items, StateTarget("slider_plus_ma", 0.0, tolerance=cap)), 1, GRID, FAST)
    x = ca.SX.sym("x", layout.nx)
    by_hand = StateConstraint("ma", ca.Function("ma", [x], [x[row]]), -cap, cap, at=END)
    hand_ocp = Ocp(swing_up(pendulum, *items, by_hand), 1, GRID, FAST)
    keyed, handmade = keyed_ocp.solve(), hand_ocp.solve()
    assert keyed.success and handmade.success
    assert keyed.x[-1, row] <= cap + 1e-7 and handmade.x[-1, row] <= cap + 1e-7
    for ocp, other in ((hand_ocp, keyed), (keyed_ocp, handmade)):
        again = ocp.solve(guess=(other.x, other.u))
        assert again.success and again.objective == pytest.approx(other.objective, rel=1e-6)
    assert free.x[-1, row] > cap  # the bound binds


def test_a_terminal_cost_is_added_once_on_the_end_state(pendulum):
    """A terminal velocity cost: the objective is the running cost plus w |qdot_N|^2 (evaluated
    here with numpy on the solution), and the per-cycle costs report it in its own column."""
    items = (JointTarget("pendulum", 3.14, "end"),)  # no velocity target: the terminal cost pulls qdot_N to 0
    w = 3.0
    sol = _solve(swing_up(pendulum, *items, costs=[torque(1.0), velocity(w, at="end")]))
    dt = 0.1
    running = dt * float(np.sum(sol.u ** 2))
    terminal = w * float(np.sum(sol.x[-1, sol.layout.v] ** 2))
    assert sol.objective == pytest.approx(running + terminal, rel=1e-9)
    np.testing.assert_allclose(sol.cycle_costs[0], [running, terminal], rtol=1e-9)
    free = _solve(swing_up(pendulum, *items))
    assert np.sum(sol.x[-1, sol.layout.v] ** 2) < np.sum(free.x[-1, free.layout.v] ** 2)


def test_a_stiff_terminal_state_cost_tends_to_the_end_target(pendulum):
    """Closed form of a penalty: with weight w on (q_N - target)^2, the end misses the target by
    O(1 / w), and the objective tends to the hard target's from below (each solve starts from the
    hard target's optimum: the swing-up has many local optima)."""
    hard = _solve(swing_up(pendulum))
    rest = (JointTarget("slider", 0.0, "end", velocity=0.0), JointTarget("pendulum", at="end", velocity=0.0))
    gaps = []
    for w in (1e3, 1e5):
        problem = swing_up(pendulum, *rest, costs=[torque(1.0), state(w, ["pendulum_q"], [3.14], at="end")])
        soft = Ocp(problem, 1, GRID, FAST).solve(guess=(hard.x, hard.u))
        assert soft.success
        gaps.append(abs(soft.x[-1, 1] - 3.14))
        assert hard.objective - 1e3 / w <= soft.objective <= hard.objective + 1e-9
    assert 0 < gaps[1] < gaps[0] / 30 and gaps[1] < 1e-3


def test_per_joint_costs_are_the_terms_a_user_writes(pendulum):
    """torque over joints = [slider] with joint_weights = [2] against the same term written as a
    CostTerm of one's own."""
    keyed = _solve(swing_up(pendulum, costs=[cost_term("torque", 1.0, joints=["slider"], joint_weights=[2.0]),
                                             cost_term("torque", 0.1, name="pendulum_torque", joints=["pendulum"])]))
    own = _solve(swing_up(pendulum, costs=[CostTerm("mine", 1.0, lambda v: 2.0 * (v.tau_plus[0] ** 2 + v.tau_minus[0] ** 2)),
                                           CostTerm("theirs", 0.1, lambda v: v.tau_plus[1] ** 2 + v.tau_minus[1] ** 2)]))
    assert keyed.objective == pytest.approx(own.objective, rel=1e-8)
    np.testing.assert_allclose(keyed.u, own.u, atol=1e-6)


def test_cost_options_are_checked_by_name():
    with pytest.raises(ParameterError, match="option 'at' is not an option of kind 'torque'.*terminal cost is a term of the state"):
        cost_term("torque", 1.0, at="end")
    with pytest.raises(ParameterError, match="joint_weights has 2 entries; expected one per joint"):
        cost_term("velocity", 1.0, joints=["a"], joint_weights=[1.0, 2.0])
    with pytest.raises(ParameterError, match="reads the controls"):
        from fatigue_pin.robot.model import load_model

        swing = swing_up(load_model(__import__("fatigue_pin").robot.model.bundled_urdf("pendulum")),
                         costs=[CostTerm("bad", 1.0, lambda v: ca.sumsqr(v.u), at="end")])
        Ocp(swing, 1, GRID, FAST)


def test_a_sliding_horizon_over_repeated_phases_meets_every_phase_end(pendulum):
    """Repeated non-cyclic phases: every phase must end upright at rest; the next starts there.
    The windows have no cyclic end box (it would pin the end to the start, hanging)."""
    from fatigue_pin.drivers.sliding import SlidingHorizon, SlidingSettings

    problem = swing_up(pendulum, n=10)
    runner = SlidingHorizon(problem, SlidingSettings(window=2, advance=1, max_cycles=3), GRID, FAST)
    assert runner.ocp.end_tolerance is None
    run = runner.run(None)
    assert run.attrs["repetitions"] == 3
    ends = [10, 20, 30]
    np.testing.assert_allclose(run.q[ends, 1], 3.14, atol=1e-6)
    np.testing.assert_allclose(run.qdot[ends], 0.0, atol=1e-6)


def test_the_reference_of_a_non_cyclic_task_goes_from_the_start_to_the_end_target(pendulum):
    """The guesses' reference motion: from q_init to the end target in the first phase, then from
    where each phase starts (the previous end) to its end; its velocity is the derivative of its
    position (central differences)."""
    task = swing_up(pendulum, JointTarget("pendulum", 3.14, "end"), n=10).task
    t = np.linspace(0.0, 2.0, 401)
    q, qd, _ = task.reference_trajectory(pendulum, t, np.array([0.0, 0.5]))
    assert q[0, 1] == pytest.approx(0.5) and q[200, 1] == pytest.approx(3.14) and q[-1, 1] == pytest.approx(3.14)
    np.testing.assert_allclose(q[200:, 1], 3.14, atol=1e-12)  # the second phase starts and ends at the target
    np.testing.assert_allclose(q[:, 0], 0.0)  # a joint without targets stays at q0
    fd = (q[2:200, 1] - q[:198, 1]) / (t[2] - t[0])
    np.testing.assert_allclose(qd[1:199, 1], fd, atol=1e-3)
