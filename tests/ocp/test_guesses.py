"""Initial guesses from another solution."""

from __future__ import annotations

import numpy as np
import pytest

from fatigue_pin.ocp.guesses import resample_guess


def test_resample_guess_stretches_cycles_in_time(build):
    two = build(2)
    sol = two.solve()
    n = two.task.intervals_per_cycle
    four = build(4)
    x, u = resample_guess(four, sol)
    assert x.shape == (4 * n + 1, four.layout.nx) and u.shape == (4 * n, 4)
    # cycles 0, 1 copy cycle 0; cycles 2, 3 copy cycle 1; the last node copies the last node
    assert np.allclose(u[:n], sol.u[:n]) and np.allclose(u[n : 2 * n], sol.u[:n])
    assert np.allclose(u[3 * n :], sol.u[n:]) and np.allclose(x[3 * n : 4 * n], sol.x[n : 2 * n])
    assert np.allclose(x[-1], sol.x[-1])
    # three cycles from two: cycle c copies cycle floor(2 c / 3) = 0, 0, 1
    three = build(3)
    _, u3 = resample_guess(three, sol)
    assert np.allclose(u3[n : 2 * n], sol.u[:n]) and np.allclose(u3[2 * n :], sol.u[n:])


def test_a_one_cycle_window_re_planned_mid_cycle_is_guessed_in_its_new_phase(build):
    """A closed loop with one-cycle windows re-planning at interval 3 of n: there is no whole cycle
    earlier to copy, so the guess takes intervals 3..n-1 of the previous plan, then 0..2 (the same
    phases a cycle earlier). (It used to slice from interval 3 - n < 0: an empty guess.)"""
    from fatigue_pin.ocp.guesses import shifted_window_guess

    one = build(1)
    sol = one.solve()
    n = one.task.intervals_per_cycle
    x, u = shifted_window_guess(one, sol.x[3], sol.x, sol.u, 0, copy_fatigue=True, intervals=3)
    assert x.shape == sol.x.shape and u.shape == sol.u.shape
    order = [*range(3, n), 0, 1, 2]
    assert np.array_equal(u, sol.u[order]) and np.array_equal(x[:-1], sol.x[order]) and np.array_equal(x[-1], sol.x[3])
    # with its fatigue states integrated from the new start instead
    x2, u2 = shifted_window_guess(one, sol.x[3], sol.x, sol.u, 0, intervals=3)
    assert np.array_equal(u2, u) and np.allclose(x2[0], sol.x[3])


def test_the_fatigue_rollout_is_the_loop_of_one_interval_steps_clipped(build):
    """``IntervalFunctions.fatigue_rollout`` (one mapped call) gives the states of a Python loop of
    ``F_fatigue`` steps clipped to [0, 1], bit for bit, including controls that overdrive a half."""
    from fatigue_pin.ocp.guesses import rollout_fatigue

    ocp = build(1)
    L, N = ocp.layout, ocp.n_intervals
    rng = np.random.default_rng(3)
    u = rng.uniform(0.0, 1.5, (N, L.nu)) * ocp.actuators.param_vector().max()  # some beyond any limit
    x0 = ocp.problem.initial_state()
    q, v = np.tile(x0[L.q], (N + 1, 1)), np.tile(x0[L.v], (N + 1, 1))
    x = rollout_fatigue(ocp, x0, q, v, u)
    p = ocp.actuators.param_vector()
    m = [x0[L.m]]
    for k in range(N):
        m.append(np.clip(np.asarray(ocp.functions.F_fatigue(m[-1], u[k], p)).reshape(-1), 0.0, 1.0))
    assert np.array_equal(x[:, L.m], np.array(m)) and np.array_equal(x[:, L.q], q)
    assert x[:, L.m].max() > 0.1  # the controls did tire the halves


def test_a_plan_shifted_exactly_keeps_its_timing_and_continues_as_it_began(build):
    """``shifted_plan_guess``: node j of a window re-planned 3 intervals after the plan is the
    plan's node j + 3; the last 3 intervals take the plan's first ones (the window ends where it
    starts, whole cycles later); node 0 has the new start's q and qdot; the fatigue states are
    integrated from the new start's. A shift outside the plan is refused in one line."""
    from fatigue_pin.core.errors import ParameterError
    from fatigue_pin.ocp.guesses import rollout_fatigue, shifted_plan_guess

    ocp = build(2)
    sol = ocp.solve()
    L, H = ocp.layout, ocp.n_intervals
    x_init = sol.x[3].copy()
    x_init[L.q] += 0.01
    x, u = shifted_plan_guess(ocp, x_init, sol.x, sol.u, 3)
    assert np.array_equal(u, np.vstack([sol.u[3:], sol.u[:3]]))
    assert np.array_equal(x[1 : H - 2, L.q], sol.x[4:H + 1, L.q]) and np.array_equal(x[H - 2 :, L.v], sol.x[1:4, L.v])
    assert np.array_equal(x[0, L.q], x_init[L.q])
    np.testing.assert_array_equal(x, rollout_fatigue(ocp, x_init, x[:, L.q], x[:, L.v], u))
    with pytest.raises(ParameterError, match="^shifted_plan_guess: a shift of 0 intervals"):
        shifted_plan_guess(ocp, x_init, sol.x, sol.u, 0)
