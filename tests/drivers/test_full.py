"""Full-horizon solves."""

from __future__ import annotations

import numpy as np


def test_full_horizon_with_a_cyclic_end_box(arm26):
    """horizon.cyclic_end: q and qdot at the last node within end_tolerance of their range around
    the initial state (the authors' full horizon has this box)."""
    from conftest import small_curl
    from fatigue_pin.io.study import run_study

    run = run_study(small_curl("full", cycles=2).replace({"horizon.cyclic_end": True})).run
    assert run.converged
    span_q = arm26.q_upper - arm26.q_lower
    assert np.all(np.abs(run.q[-1] - run.q[0]) <= 0.01 * span_q + 1e-6)
    span_v = arm26.v_upper - arm26.v_lower
    assert np.all(np.abs(run.qdot[-1] - run.qdot[0]) <= 0.01 * span_v + 1e-6)
    free = run_study(small_curl("full", cycles=2)).run
    assert np.abs(free.q[-1, 0] - free.q[0, 0]) > np.abs(run.q[-1, 0] - run.q[0, 0])  # the box binds the shoulder
