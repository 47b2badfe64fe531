"""The heat budget of sliding windows (``[horizon] heat_budget``): every cycle a window plans,
repeated until the task's end, keeps each motor's winding below its limit."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import small_curl
from fatigue_pin.core.errors import FatiguePinError
from fatigue_pin.drivers.sliding import SlidingHorizon

#: Small, fast motors (time constants 0.5 s and 2 s) whose limit (55 deg C) a plain sliding run of
#: five cycles of the curl reaches.
TOY = {"preset": "maxon-re40", "gear_ratio": 150.0, "tau_w": 0.5, "tau_m": 2.0, "T_max": 55.0}
MAX_CYCLES = 5


def _run(heat_budget: bool):
    study = small_curl("sliding", cycles=2, max_cycles=MAX_CYCLES).replace(
        {"actuators.kind": "motors", "motors": TOY, "horizon.heat_budget": heat_budget})
    h = study.horizon_settings()
    runner = SlidingHorizon(study.problem(), h.sliding_settings(), study.transcription(), study.solver(), guess=h.guess)
    lines: list[str] = []
    return runner, runner.run(progress=lines.append), lines


def _repeated_windings(runner, run) -> np.ndarray:
    """Each motor's winding at the task's end if the cycle ending at each node were repeated until
    it, from the stitched states at that cycle's two ends (the layer's rows), (nodes, motors)."""
    L, n = runner.ocp.layout, runner.ocp.task.intervals_per_cycle
    x = L.assemble(run.q, run.qdot, run.fatigue)
    layer = runner.problem.actuators
    rows = []
    for i in range(n, x.shape[0]):
        E_last, E_before = layer.window_budget(runner.ocp.task.cycle_duration, (MAX_CYCLES * n - i) // n)
        rows.append(E_last @ x[i, L.m] + E_before @ x[i - n, L.m])
    return np.array(rows)


def test_windows_within_the_heat_budget_leave_the_remaining_cycles_their_heat():
    plain_runner, plain, _ = _run(False)
    runner, budget, lines = _run(True)
    assert plain.n_cycles == budget.n_cycles == MAX_CYCLES
    # the plain windows spend the heat of the cycles after them: repeating their cycles would
    # take a winding past its limit; within the budget every kept cycle could be repeated
    assert _repeated_windings(plain_runner, plain).max() > 1.01
    assert _repeated_windings(runner, budget).max() < 1 + 1e-6
    assert all("budget" in line and "solved without" not in line for line in lines if line.startswith("window"))
    # both stay within the limit at every node
    assert budget.fatigue["xw"].max() <= 1 + 1e-6 and plain.fatigue["xw"].max() <= 1 + 1e-6


def test_a_heat_budget_run_stopped_after_two_windows_resumes_to_the_same_run(tmp_path):
    """The budget of a window depends on the kept cycle before it, read back from the file."""
    from fatigue_pin.io.results import ResultFile

    runner, reference, _ = _run(True)
    out = tmp_path / "budget.h5"
    runner.run(ResultFile(out), stop_after=2)
    resumed = runner.run(ResultFile(out), resume=True)
    assert resumed.n_cycles == reference.n_cycles
    for name in ("q", "qdot", "tau_plus", "tau_minus"):
        assert np.allclose(getattr(resumed, name), getattr(reference, name), atol=1e-9), name
    assert np.allclose(resumed.fatigue["xw"], reference.fatigue["xw"], atol=1e-9)


def _motor_study(**changes):
    return small_curl("sliding", cycles=2, max_cycles=MAX_CYCLES).replace(
        {"actuators.kind": "motors", "motors": TOY, "horizon.heat_budget": True, **changes})


@pytest.mark.parametrize("make, message", [
    (lambda: small_curl("sliding", cycles=2).replace({"actuators.kind": "motors", "motors": TOY, "horizon.heat_budget": True}),
     "expected max_cycles too"),
    (lambda: small_curl("sliding", cycles=2, max_cycles=MAX_CYCLES).replace({"horizon.heat_budget": True}), "expected motors"),
    (lambda: _motor_study(**{"horizon.kind": "full"}), 'expected horizon.kind = "sliding"'),
])
def test_a_heat_budget_needs_motors_sliding_windows_and_the_task_length(make, message):
    with pytest.raises(FatiguePinError, match=message):
        study = make()
        h = study.horizon_settings()
        SlidingHorizon(study.problem(), h.sliding_settings(), study.transcription(), study.solver())


def test_a_closed_loop_whose_plant_is_its_model_reproduces_the_heat_budget_run():
    """No [plant], no noise, a re-plan every cycle, the plant on the plan's own RK4: the closed
    loop within the heat budget (its past cycle from the estimate) is the sliding run within it."""
    from fatigue_pin.drivers.mpc import ClosedLoop, MpcSettings
    from fatigue_pin.drivers.plant import PlantSettings

    study = small_curl("sliding", cycles=2, max_cycles=MAX_CYCLES, solver={"compile": False, "tol": 1e-10, "constr_viol_tol": 1e-10})
    study = study.replace({"actuators.kind": "motors", "motors": TOY, "horizon.heat_budget": True})
    h = study.horizon_settings()
    reference = SlidingHorizon(study.problem(), h.sliding_settings(), study.transcription(), study.solver()).run()
    loop = ClosedLoop(study.problem(), None, h.sliding_settings(), MpcSettings(), PlantSettings(integrator="rk4"),
                      study.transcription(), study.solver())
    state = loop.run()
    L = loop.problem.layout
    x = np.array(state.x)
    x_ref = L.assemble(reference.q, reference.qdot, reference.fatigue)
    # the plan takes the shoulder's winding to its limit in the last cycle; there the plant's motor
    # trips (x_w = 1 to rounding: it delivers nothing) and the loop ends, four nodes early
    at_limit = int(np.argmax(x_ref[:, L.m].max(axis=1) > 1 - 1e-6))
    assert at_limit > 4 * loop.n and x.shape[0] > at_limit
    assert np.abs(x[: at_limit + 1] - x_ref[: at_limit + 1]).max() < 1e-6
    assert all(r[4] for r in state.replans) and len(state.replans) == MAX_CYCLES - 1  # each converged within its budget
