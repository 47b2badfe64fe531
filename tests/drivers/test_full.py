"""Full-horizon driver: the maximum-repetitions search and run records."""

from __future__ import annotations

import numpy as np

import fatigue_pin.drivers.full as full
from fatigue_pin.drivers.full import max_repetitions, resample_guess, solution_to_run, step_run_name
from fatigue_pin.io.results import read_run, read_search


class _FakeSolution:
    def __init__(self, n: int, ok: bool):
        self.success, self.status = ok, "Solve_Succeeded" if ok else "Infeasible_Problem_Detected"
        self.kind = "converged" if ok else "infeasible"
        self.iterations, self.wall_time_s = 10 * n, 0.1 * n
        self.nlp = type("Nlp", (), {"constraint_violation": 0.0 if ok else 1.0})()


class _FakeOcp:
    """Converges for N <= limit; records the guesses it was given."""

    limit = 5
    guesses: list = []

    def __init__(self, n_cycles):
        self.n_cycles, self.build_time_s = n_cycles, 0.0

    def initial_state(self):
        return None

    def solve(self, guess=None, x_end=None):
        _FakeOcp.guesses.append(guess is not None)
        sol = _FakeSolution(self.n_cycles, self.n_cycles <= _FakeOcp.limit)
        sol.x = sol.u = None
        return sol


class _FakeBuilder:
    def __init__(self, *args, **kwargs):
        pass

    def __call__(self, n, end_tolerance=None):
        return _FakeOcp(n)


def test_search_gallops_then_bisects(monkeypatch):
    monkeypatch.setattr(full, "OcpBuilder", _FakeBuilder)
    monkeypatch.setattr(full, "resample_guess", lambda ocp, sol: "guess")
    _FakeOcp.guesses = []
    result = max_repetitions(None, n_max=64)
    assert result.max_cycles == 5
    # a failed warm start is solved again from the default guess before it counts as a failure
    assert [r["n_cycles"] for r in result.tried] == [1, 2, 4, 8, 8, 6, 6, 5]
    assert _FakeOcp.guesses == [False, True, True, True, False, True, False, True]
    assert [r["guess"] for r in result.tried][:5] == ["rest", "warm N=1", "warm N=2", "warm N=4", "rest"]
    assert result.failures == {8: "infeasible", 6: "infeasible"}


def test_search_without_retry_counts_the_first_failure(monkeypatch):
    monkeypatch.setattr(full, "OcpBuilder", _FakeBuilder)
    monkeypatch.setattr(full, "resample_guess", lambda ocp, sol: "guess")
    result = max_repetitions(None, n_max=64, retry=False)
    assert result.max_cycles == 5 and [r["n_cycles"] for r in result.tried] == [1, 2, 4, 8, 6, 5]


def test_search_without_a_cap_gallops_until_a_failure(monkeypatch):
    monkeypatch.setattr(full, "OcpBuilder", _FakeBuilder)
    monkeypatch.setattr(full, "resample_guess", lambda ocp, sol: "guess")
    _FakeOcp.limit = 40
    try:
        result = max_repetitions(None, n_max=None)
    finally:
        _FakeOcp.limit = 5
    final = list(dict.fromkeys(r["n_cycles"] for r in result.tried))  # every N once, in order
    assert result.max_cycles == 40 and final == [1, 2, 4, 8, 16, 32, 64, 48, 40, 44, 42, 41]


def test_search_stops_at_n_max(monkeypatch):
    monkeypatch.setattr(full, "OcpBuilder", _FakeBuilder)
    monkeypatch.setattr(full, "resample_guess", lambda ocp, sol: "guess")
    _FakeOcp.limit = 100
    try:
        result = max_repetitions(None, n_max=12)
    finally:
        _FakeOcp.limit = 5
    assert result.max_cycles == 12 and [r["n_cycles"] for r in result.tried] == [1, 2, 4, 8, 12]


def test_real_search_on_a_small_problem(small_study, small_problem, tmp_path):
    """S = 10, fatigue-torque, 10 intervals per cycle, capped at 3 cycles: all converge; every
    converged N is stored, and a resumed search solves nothing again and gives the same result."""
    out = tmp_path / "search.h5"
    kw = dict(n_max=3, out=out, name="full/fatigue-torque_S10")
    result = max_repetitions(small_problem, small_study.transcription(), small_study.solver(), **kw)
    assert result.max_cycles == 3 and [r["n_cycles"] for r in result.tried] == [1, 2, 3]
    table = read_search(out)["full_fatigue-torque_S10"]
    assert list(table["n_cycles"]) == [1, 2, 3] and table["converged"].all()
    run = read_run(out, "full/fatigue-torque_S10")
    assert run.n_cycles == 3 and run.converged
    assert read_run(out, step_run_name("full/fatigue-torque_S10", 2)).n_cycles == 2
    lines: list[str] = []
    again = max_repetitions(small_problem, small_study.transcription(), small_study.solver(), resume=True, progress=lines.append, **kw)
    assert again.max_cycles == 3
    assert [(r["n_cycles"], r["iterations"], r["status"]) for r in again.tried] == [(r["n_cycles"], r["iterations"], r["status"]) for r in result.tried]
    assert not [line for line in lines if line.startswith("N =")]  # nothing solved again
    assert np.array_equal(read_run(out, "full/fatigue-torque_S10").q, run.q)


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


def test_run_record_has_every_attribute(build, tmp_path):
    from fatigue_pin.io.results import RUN_ATTRIBUTES, write_run

    ocp = build(2)
    sol = ocp.solve()
    run = solution_to_run(ocp, sol, "full/test")
    write_run(tmp_path / "r.h5", run)
    back = read_run(tmp_path / "r.h5", "full/test")
    for key in RUN_ATTRIBUTES:
        assert key in back.attrs, key
    assert back.attrs["horizon"] == "full" and bool(back.attrs["converged"]) is True
    assert back.torque_limits.shape == (2, 4)
    assert np.allclose(back.torque_limits[:, 0], 50 * (1 - back.mf[[10, 20], 0]))
    assert back.actuator_names == ("shoulder_plus", "shoulder_minus", "elbow_plus", "elbow_minus")
    assert back.fatigue_states == ("ma", "mr", "mf")
    assert "<robot" in back.urdf


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


def test_failure_kinds_tell_infeasibility_from_limits():
    from fatigue_pin.ocp.solver import failure_kind

    assert failure_kind("Solve_Succeeded", [1.0, 1e-8], 1e-4) == "converged"
    assert failure_kind("Infeasible_Problem_Detected", [1.0], 1e-4) == "infeasible"
    assert failure_kind("Restoration_Failed", [1.0], 1e-4) == "infeasible"
    # stopped by a limit while the violation grew from its lowest point: moving away from feasibility
    assert failure_kind("Maximum_Iterations_Exceeded", [1.0, 1e-3, 0.5], 1e-4) == "infeasible-growing"
    # stopped by a limit while (nearly) feasible, or still decreasing: just not converged
    assert failure_kind("Maximum_Iterations_Exceeded", [1.0, 1e-3, 1e-6], 1e-4) == "not-converged"
    assert failure_kind("Maximum_WallTime_Exceeded", [1.0, 0.5, 0.4], 1e-4) == "not-converged"
    assert failure_kind("Error_In_Step_Computation", [1e-9], 1e-4) == "numerical"


def test_a_real_failure_is_classified_and_stored(small_study, small_problem, tmp_path):
    """An iteration limit of 3 cannot converge: the solve is a failure of kind not-converged (or
    infeasible-growing), stored with its guess and constraint violation in the search table."""
    import dataclasses

    solver = dataclasses.replace(small_study.solver(), max_iter=3)
    out = tmp_path / "s.h5"
    result = max_repetitions(small_problem, small_study.transcription(), solver, n_max=1, out=out, name="s")
    assert result.max_cycles == 0 and result.failures[1] in ("not-converged", "infeasible-growing")
    table = read_search(out)["s"]
    assert table["kind"][0].decode() == result.failures[1] and table["guess"][0].decode() == "rest"
    assert table["constraint_violation"][0] > 0
