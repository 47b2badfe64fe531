"""Initial guesses from another solution."""

from __future__ import annotations

import numpy as np

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
