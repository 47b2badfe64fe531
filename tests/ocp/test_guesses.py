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
