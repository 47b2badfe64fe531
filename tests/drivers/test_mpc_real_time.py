"""Real-time iterations of the closed loop (``mpc.iterations_per_replan``): bounded re-plans
whose last iterates are the plans."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import small_curl
from fatigue_pin.drivers.mpc import BOUNDED_STATUS, ClosedLoop, MpcSettings
from fatigue_pin.drivers.mpc_run import _mpc_settings
from fatigue_pin.drivers.sliding import SlidingSettings


def _real_time_loop(iterations, tolerance=0.05, max_cycles=3, replan_every=5):
    study = small_curl("sliding", substeps=4)
    return ClosedLoop(study.problem(), None, SlidingSettings(window=3, advance=1, max_cycles=max_cycles),
                      MpcSettings(replan_every=replan_every, iterations_per_replan=iterations, end="receding",
                                  target_tolerance=tolerance), None, study.transcription(), study.solver())


@pytest.fixture(scope="module")
def real_time():
    """The loop and its run; the warm-start maps built during the run are counted
    (``loop.maps_built_in_motion``)."""
    import fatigue_pin.ocp.warm as warm

    loop = _real_time_loop(3)
    loop.window_ocps()  # what ``run`` does first: the windows and the warm-start maps
    built, build = [], warm.shift_maps_between
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(warm, "shift_maps_between", lambda *a: built.append(a) or build(*a))
        state = loop.run()
    loop.maps_built_in_motion = len(built)
    return loop, state


def test_real_time_warm_start_maps_are_built_before_the_motion(real_time):
    """A real-time re-plan starts from the plan before, moved to its window by an index map that
    takes 0.3 s to build on arm26: all are built with the windows, before the first re-plan, so no
    re-plan of the first cycle pays for one."""
    loop, state = real_time
    assert loop.maps_built_in_motion == 0
    assert {(p, (p + 5) % loop.n, 5) for p in range(0, loop.n, 5)} <= set(loop._shifts)


def test_real_time_re_plans_are_bounded_and_their_last_iterates_are_the_plans(real_time):
    """The first plan is solved to convergence; every later re-plan stops at 3 IPOPT iterations
    (or converges within them), and the plant runs its last iterate: every re-plan's plan is in
    force until the next. The plant meets every target of the 3 cycles."""
    loop, state = real_time
    rows = state.replans
    assert [int(r[1]) for r in rows] == [0, 5, 10, 15, 20, 25]
    assert rows[0][4] and int(rows[0][5]) > 3  # the first plan converged, in more than 3 iterations
    assert all(int(r[5]) <= 3 and (r[4] or r[3].decode() == BOUNDED_STATUS) for r in rows[1:])
    assert any(not r[4] for r in rows[1:])  # some re-plans did stop at the bound
    assert state.plan[2] == 25  # the last re-plan's iterate is the plan in force
    # the plant applied each re-plan's first controls (node 25's plan from node 25 on)
    x_plan, u_plan, start = state.plan
    np.testing.assert_array_equal(np.array(state.history.u_command[start:]), u_plan[: len(state.x) - 1 - start])
    errors = loop.task_errors(state)
    assert len(errors) == 3 and errors.max() < loop.mpc.target_tolerance
    assert not state.done or loop.finished(state)


def test_a_missed_cycle_ends_real_time_re_planning():
    """Real-time plans do not fail when the plant is spent, so a cycle the plant misses ends the
    re-planning: with a tolerance no bounded plan meets (1e-9 rad), the re-plans stop at the end of
    the first cycle and the plant runs out the plan in force (to ``max_cycles``)."""
    loop = _real_time_loop(2, tolerance=1e-9)
    state = loop.run()
    n = loop.n
    assert state.done and max(int(r[1]) for r in state.replans) < n + 1
    assert loop.task_errors(state)[0] > 1e-9 and loop.repetitions(state) == 0
    assert loop.finished(state) and len(state.x) - 1 == 3 * n  # the plant ran out the plan to max_cycles


def test_real_time_settings_join_the_fingerprint_only_where_they_are_set():
    """Runs stored before real-time iterations keep their fingerprints: the key is absent when
    unset, and a run with it set cannot be resumed as one without."""
    study = small_curl("sliding")
    loops = [ClosedLoop(study.problem(), None, SlidingSettings(window=3, advance=1, max_cycles=3), MpcSettings(iterations_per_replan=it),
                        None, study.transcription(), study.solver()) for it in (None, 4)]
    assert "iterations_per_replan" not in _mpc_settings(loops[0]) and _mpc_settings(loops[1])["iterations_per_replan"] == 4
