"""The maximum-repetitions search: gallop then bisect (on a fake OCP), a real search on a small
problem stored and resumed, and how failures are classified and stored."""

from __future__ import annotations

import numpy as np
import fatigue_pin.drivers.search as search
from fatigue_pin.drivers.search import max_repetitions, step_run_name
from fatigue_pin.io.results import ResultFile, read_run, read_search


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
    monkeypatch.setattr(search, "OcpBuilder", _FakeBuilder)
    monkeypatch.setattr(search, "resample_guess", lambda ocp, sol: "guess")
    _FakeOcp.guesses = []
    result = max_repetitions(None, n_max=64)
    assert result.max_cycles == 5
    # a failed warm start is solved again from the default guess before it counts as a failure
    assert [r["n_cycles"] for r in result.tried] == [1, 2, 4, 8, 8, 6, 6, 5]
    assert _FakeOcp.guesses == [False, True, True, True, False, True, False, True]
    assert [r["guess"] for r in result.tried][:5] == ["rest", "warm N=1", "warm N=2", "warm N=4", "rest"]
    assert result.failures == {8: "infeasible", 6: "infeasible"}


def test_search_without_retry_counts_the_first_failure(monkeypatch):
    monkeypatch.setattr(search, "OcpBuilder", _FakeBuilder)
    monkeypatch.setattr(search, "resample_guess", lambda ocp, sol: "guess")
    result = max_repetitions(None, n_max=64, retry=False)
    assert result.max_cycles == 5 and [r["n_cycles"] for r in result.tried] == [1, 2, 4, 8, 6, 5]


def test_search_without_a_cap_gallops_until_a_failure(monkeypatch):
    monkeypatch.setattr(search, "OcpBuilder", _FakeBuilder)
    monkeypatch.setattr(search, "resample_guess", lambda ocp, sol: "guess")
    _FakeOcp.limit = 40
    try:
        result = max_repetitions(None, n_max=None)
    finally:
        _FakeOcp.limit = 5
    final = list(dict.fromkeys(r["n_cycles"] for r in result.tried))  # every N once, in order
    assert result.max_cycles == 40 and final == [1, 2, 4, 8, 16, 32, 64, 48, 40, 44, 42, 41]


def test_search_stops_at_n_max(monkeypatch):
    monkeypatch.setattr(search, "OcpBuilder", _FakeBuilder)
    monkeypatch.setattr(search, "resample_guess", lambda ocp, sol: "guess")
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
    kw = dict(n_max=3, store=ResultFile(out), name="full/fatigue-torque_S10")
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


def test_a_real_failure_is_classified_and_stored(small_study, small_problem, tmp_path):
    """An iteration limit of 3 cannot converge: the solve is a failure of kind not-converged (or
    infeasible-growing), stored with its guess and constraint violation in the search table."""
    import dataclasses

    solver = dataclasses.replace(small_study.solver(), max_iter=3)
    out = tmp_path / "s.h5"
    result = max_repetitions(small_problem, small_study.transcription(), solver, n_max=1, store=ResultFile(out), name="s")
    assert result.max_cycles == 0 and result.failures[1] in ("not-converged", "infeasible-growing")
    table = read_search(out)["s"]
    assert table["kind"][0].decode() == result.failures[1] and table["guess"][0].decode() == "rest"
    assert table["constraint_violation"][0] > 0
