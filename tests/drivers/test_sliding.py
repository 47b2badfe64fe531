"""Sliding-horizon runs: stitching, the window count rule, the file after every window, resume."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.io.results import list_runs, read_run
from fatigue_pin.drivers.sliding import SlidingHorizon, SlidingSettings, repetitions
from fatigue_pin.io.results import ResultFile
from fatigue_pin.io.study import Study


@pytest.fixture(scope="module")
def runner(small_problem, small_study):
    return SlidingHorizon(small_problem, SlidingSettings(window=3, advance=1, max_cycles=5), small_study.transcription(),
                          small_study.solver())


@pytest.fixture(scope="module")
def full_run(runner, tmp_path_factory):
    out = tmp_path_factory.mktemp("sliding") / "run.h5"
    return runner.run(ResultFile(out)), out


def test_window_count_rule(full_run):
    run, _ = full_run
    assert run.windows.shape == (3,)  # 5 cycles kept with a 3-cycle window advancing 1
    assert run.windows["converged"].all()
    assert list(run.windows["first_cycle"]) == [0, 1, 2]
    assert run.n_cycles == 5 == repetitions(3, SlidingSettings(window=3))
    assert run.q.shape == (5 * 10 + 1, 2) and run.tau_plus.shape == (50, 2)
    assert repetitions(19, SlidingSettings(window=3)) == 21
    assert repetitions(4, SlidingSettings(window=4, advance=2)) == 10


def test_stitched_trajectory_is_continuous(full_run, runner):
    run, _ = full_run
    ocp = runner.ocp
    L = ocp.layout
    x = L.assemble(run.q, run.qdot, run.fatigue)
    u = np.hstack([run.tau_plus, run.tau_minus])
    p = ocp.actuators.param_vector()
    gaps = [np.max(np.abs(ocp.functions.step(x[k], u[k], p) - x[k + 1])) for k in range(u.shape[0])]
    assert max(gaps) < 1e-6  # including across every window join
    elbow = np.degrees(run.q[::5, 1])
    assert np.allclose(elbow, np.tile([15, 150], 6)[:11], atol=1e-5)
    mf = run.mf.max(axis=1)
    assert mf[-1] > mf[10] > 0  # fatigue grows over the cycles


def test_each_window_starts_from_the_previous_one(runner):
    """The window's guess repeats the previous window's second cycle, with continuous fatigue."""
    ocp = runner.ocp
    x0 = ocp.initial_state()
    sol = ocp.solve(x_init=x0, x_end=x0)
    x_init = sol.x[10]
    gx, gu = runner.window_guess(x_init, sol.x, sol.u)
    assert np.allclose(gu[:10], sol.u[10:20]) and np.allclose(gu[20:30], sol.u[10:20])
    assert np.allclose(gx[0], x_init)
    p = ocp.actuators.param_vector()
    L = ocp.layout
    for k in range(30):
        assert np.allclose(ocp.functions.step(gx[k], gu[k], p)[L.m], gx[k + 1][L.m], atol=1e-12)


def test_file_written_after_every_window_and_resume_equals_uninterrupted(full_run, runner, tmp_path):
    reference, _ = full_run
    out = tmp_path / "resumed.h5"
    first = runner.run(ResultFile(out), stop_after=1)  # as if the run had been stopped after one window
    assert read_run(out, first.name).windows.shape == (1,)
    resumed = runner.run(ResultFile(out), resume=True)
    assert resumed.windows.shape == reference.windows.shape
    for name in ("q", "qdot", "tau_plus", "tau_minus", "ma", "mr", "mf", "cycle_costs"):
        assert np.allclose(getattr(resumed, name), getattr(reference, name), atol=1e-9), name


KILL_SCRIPT = textwrap.dedent(
    """
    import sys
    from fatigue_pin.paper.curl import curl_study
    from fatigue_pin.io.study import run_study
    study = curl_study("sliding", max_cycles=int(sys.argv[2]), intervals_per_cycle=10, substeps=2, solver={"compile": False})
    run_study(study, sys.argv[1], name="sliding/run", resume=True, progress=lambda line: print(line, flush=True))
    """
)


def test_killed_run_keeps_finished_windows_and_resumes(full_run, tmp_path):
    """SIGKILL a run after its first window; the file stays readable and a resumed run ends
    with the uninterrupted result."""
    reference, _ = full_run
    out = tmp_path / "killed.h5"
    script = tmp_path / "run.py"
    script.write_text(KILL_SCRIPT)
    proc = subprocess.Popen([sys.executable, str(script), str(out), "8"], stdout=subprocess.PIPE, text=True)
    try:
        for line in proc.stdout:  # wait for the first finished window
            if line.startswith("window   0"):
                break
        deadline = time.time() + 60
        while not out.exists() and time.time() < deadline:
            time.sleep(0.05)
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        proc.wait(timeout=60)
    name = list_runs(out)[0]
    partial = read_run(out, name)
    assert 1 <= partial.windows.shape[0] < 6
    subprocess.run([sys.executable, str(script), str(out), "5"], check=True, capture_output=True)
    resumed = read_run(out, name)
    assert np.allclose(resumed.q, reference.q, atol=1e-9) and np.allclose(resumed.mf, reference.mf, atol=1e-9)


def test_resume_refuses_other_settings(full_run, small_study, arm26):
    from conftest import small_curl
    from fatigue_pin.io.results import ResultFileError

    _, out = full_run
    other = SlidingHorizon(small_curl(cost="torque").problem(arm26), SlidingSettings(window=3, max_cycles=5), small_study.transcription(),
                           small_study.solver())
    with pytest.raises(ResultFileError, match="weights"):
        other.run(ResultFile(out), name=read_run(out).name, resume=True)


def test_bad_sliding_settings():
    from fatigue_pin.core.errors import ParameterError

    with pytest.raises(ParameterError, match="advance"):
        SlidingSettings(window=3, advance=4)
    with pytest.raises(ParameterError, match="max_cycles"):
        SlidingSettings(window=3, max_cycles=2)


def test_a_failed_window_is_kept_for_inspection(small_problem, small_study, tmp_path):
    """A window that fails (here: 3 iterations allowed) ends the run, and IPOPT's last iterate of
    it is stored as the run ``<name>_failed_window``, which file listings and default reads skip."""
    import dataclasses

    from fatigue_pin.drivers.run import failed_window_name

    solver = dataclasses.replace(small_study.solver(), max_iter=3)
    out = tmp_path / "failed.h5"
    run = SlidingHorizon(small_problem, SlidingSettings(window=3, advance=1, max_cycles=5), small_study.transcription(),
                         solver).run(ResultFile(out), name="sliding/s")
    assert run.n_cycles == 0 and not run.windows["converged"].any()
    assert list_runs(out) == ["sliding/s"] and read_run(out).name == "sliding/s"
    assert list_runs(out, failed_windows=True) == ["sliding/s", failed_window_name("sliding/s")]
    failed = read_run(out, failed_window_name("sliding/s"))
    assert failed.n_cycles == 3 and not failed.converged and failed.attrs["iterations"] == 3
    assert failed.attrs["kind"] in ("not-converged", "infeasible-growing")
    np.testing.assert_allclose(failed.q[0], small_problem.initial_state()[:2])  # the window starts at the fixed state


def test_resume_refuses_another_payload(small_study):
    """The fingerprint of a sliding run names the model's payload: a run with 6.4 kg more in the
    hand cannot resume one without it."""
    plain = small_study.replace({"horizon.kind": "sliding"})
    heavy = Study.from_dict({**plain.data, "model": {**plain.data["model"], "payload": {"frame": "dumbbell", "mass": 6.4}}})
    fingerprints = [SlidingHorizon(s.problem(), SlidingSettings(window=3), s.transcription(), s.solver()).fingerprint()
                    for s in (plain, heavy)]
    assert fingerprints[0] != fingerprints[1]


def test_copied_fatigue_guess_jumps_back_at_cycle_boundaries(small_problem, small_study):
    """guess_fatigue='copy' (the authors' window guess) repeats the previous window's 2nd cycle
    states verbatim, fatigue included; 'integrate' rolls the fatigue states forward instead."""
    settings = {g: SlidingHorizon(small_problem, SlidingSettings(window=3, guess_fatigue=g), small_study.transcription(),
                                  small_study.solver()) for g in ("integrate", "copy")}
    ocp = settings["copy"].ocp
    n = ocp.task.intervals_per_cycle
    sol = ocp.solve()
    x0 = sol.x[n]
    guesses = {g: r.window_guess(x0, sol.x, sol.u) for g, r in settings.items()}
    L = ocp.layout
    fat = slice(L.nq + L.nv, L.nx)
    copied, integrated = guesses["copy"][0], guesses["integrate"][0]
    np.testing.assert_array_equal(copied[n, fat], copied[0, fat])  # back to the cycle's start
    np.testing.assert_array_equal(copied[:n, fat], sol.x[n:2 * n, fat])
    assert not np.allclose(integrated[n:, fat], copied[n:, fat])  # rolled forward, no jump back
    np.testing.assert_array_equal(guesses["copy"][1], guesses["integrate"][1])
    with pytest.raises(Exception, match="guess_fatigue"):
        SlidingSettings(window=3, guess_fatigue="verbatim")


def test_real_time_factor_of_every_window_and_the_runs_median(full_run, runner):
    """Seconds of solving per second of motion advanced: a window's wall time over A cycles."""
    from fatigue_pin.drivers.sliding import real_time_factors

    run, _ = full_run
    advanced = runner.sliding.advance * runner.ocp.task.cycle_duration
    factors = real_time_factors(run.windows, advanced)
    assert np.allclose(factors, run.windows["wall_time_s"] / advanced)
    assert run.attrs["median_real_time_factor"] == pytest.approx(float(np.median(factors)))
    lines = []
    runner.run(None, progress=lines.append, stop_after=1)
    assert "real-time factor" in lines[0] and lines[-1].startswith("median real-time factor")


def test_warm_started_windows_reach_the_cold_windows_optima(small_problem, small_study, full_run):
    """``warm_start``: the windows after the first start from the previous one shifted; they
    converge to the same optima as cold-started windows (objective 1e-6 relative)."""
    cold, _ = full_run
    warm = SlidingHorizon(small_problem, SlidingSettings(window=3, advance=1, max_cycles=5, warm_start=True),
                          small_study.transcription(), small_study.solver()).run(None)
    assert warm.windows["converged"].all() and len(warm.windows) == len(cold.windows)
    assert np.allclose(warm.windows["objective"], cold.windows["objective"], rtol=1e-6)
    assert np.abs(warm.q - cold.q).max() < 1e-3


def test_shift_maps_move_every_variable_and_row_by_the_advance(runner):
    """The shifted start of a window: the state at node k is the previous solution's at node
    k + A n (the last A cycles repeat the last cycle), and each rigid-body gap row's multiplier
    is the one of the same gap A n intervals later."""
    from fatigue_pin.ocp.warm import shift_maps, shifted

    ocp = runner.ocp
    n, N, L = ocp.task.intervals_per_cycle, ocp.n_intervals, ocp.layout
    x_map, g_map = shift_maps(ocp, 1)
    rng = np.random.default_rng(0)
    z = rng.normal(size=ocp.nlp.n_x)
    x, u = ocp.unflatten(z)
    xs, us = ocp.unflatten(shifted(z, x_map))
    assert np.array_equal(xs[: N + 1 - n], x[n:]) and np.array_equal(xs[N + 1 - n :], x[N + 1 - n :])
    assert np.array_equal(us[: N - n], u[n:]) and np.array_equal(us[N - n :], u[N - n :])
    assert (g_map >= 0).all()  # every row has a counterpart
    lam = np.arange(ocp.nlp.n_g, dtype=float)
    moved = shifted(lam, g_map)
    # g starts with the torque rows T_k = tau_plus_k + tau_minus_k, nv per interval: a shift of
    # one cycle takes each from the row nv n further on, the last cycle's from themselves
    nv = L.nv
    assert ocp.transcription.torque_variable
    assert np.array_equal(moved[: nv * (N - n)], lam[: nv * (N - n)] + nv * n)
    assert np.array_equal(moved[nv * (N - n) : nv * N], lam[nv * (N - n) : nv * N])
def test_a_run_replaces_one_of_the_same_name_only_when_complete(full_run, runner, tmp_path):
    """A new run (not a resume) under the name of a run already in the file keeps its windows
    under ``<name>_in_progress``: stopped after a window, the old run is still whole; resumed
    to the end, it replaces the old run and the run in progress is gone."""
    import shutil

    from fatigue_pin.drivers.run import in_progress_name

    reference, path = full_run
    out = tmp_path / "replace.h5"
    shutil.copy(path, out)
    name = reference.name
    before = read_run(out, name)
    partial = runner.run(ResultFile(out), name=name, stop_after=1)
    assert partial.name == in_progress_name(name) and partial.windows.shape == (1,)
    kept = read_run(out, name)
    assert kept.windows.shape == before.windows.shape and np.array_equal(kept.q, before.q)
    assert list_runs(out) == [name]  # the run in progress is not listed with the runs
    assert in_progress_name(name) in list_runs(out, failed_windows=True)
    done = runner.run(ResultFile(out), name=name, resume=True)
    assert done.name == name and done.windows.shape == reference.windows.shape
    assert list_runs(out, failed_windows=True) == [name]
    assert np.allclose(read_run(out, name).q, reference.q, atol=1e-9)


@pytest.mark.parametrize("window", [1, 2])
@pytest.mark.parametrize("target_rows", [False, True])
def test_windows_advancing_their_length_start_where_the_previous_one_ended(target_rows, window):
    """Windows of K cycles advancing K with the last phase-0 target at node K n - 1: each join
    (a window's last node, not a target node) is the next window's start state, not its phase-0
    target. The stitched run solves its own RK4 across the joins (no jump), and verify passes it
    (gaps on a grid fine enough for its tolerance, 8 substeps; the targets on the nodes the
    windows put them)."""
    from conftest import small_curl
    from fatigue_pin.drivers.sliding import stitched_nodes
    from fatigue_pin.io.study import run_study
    from fatigue_pin.paper.curl import LOW
    from fatigue_pin.verify import verify_run

    K, n = window, 10
    study = small_curl("sliding", cycles=K, max_cycles=3 * K, substeps=8, transcription={"target_rows": target_rows})
    study = study.replace({"horizon.advance": K, "task.final_node_offset": -1})
    run = run_study(study).run
    assert list(run.windows["converged"]) == [True] * 3 and run.n_cycles == 3 * K
    joins = [K * n, 2 * K * n]
    ends = [K * n - 1, 2 * K * n - 1, 3 * K * n - 1]
    assert np.allclose(run.q[ends, 1], LOW, atol=1e-8)  # each window's last phase-0 target, node K n - 1
    assert np.all(np.abs(run.q[joins, 1] - LOW) > 1e-2)  # the joins: where the windows ended, within their end box
    report = verify_run(run)
    assert report.rk4_residual < 1e-6, report.table()  # no jump at the joins
    assert report.gap < 1e-3 and report.gap_fatigue < 1e-5 and report.task < 1e-8
    assert report.passed, report.table()
    first_cycles = [0, K, 2 * K]
    expected = sorted({0} | {c * n for c in range(1, 3 * K) if c % K} | set(ends))
    assert stitched_nodes(study.task(), 0.0, K, K, first_cycles) == expected
    assert stitched_nodes(study.task(), 0.5, K, K, first_cycles) == [c * n + 5 for c in range(3 * K)]


def test_stitched_nodes_of_overlapping_windows_are_the_task_nodes():
    """With advance < window the phase-0 targets of the stitched run are Task.nodes over it."""
    from conftest import small_curl
    from fatigue_pin.drivers.sliding import stitched_nodes

    study = small_curl("sliding").replace({"task.final_node_offset": -1})
    assert stitched_nodes(study.task(), 0.0, 3, 1, [0, 1, 2]) == [0, 10, 20, 30, 40, 49]  # = Task.nodes over 5 cycles

def test_the_ending_says_why_the_run_ended(full_run):
    """A run ends because the arm can no longer do the next K cycles (said in those words, with
    the window, its cycles and how the solver ended), or at the max_cycles cap."""
    from conftest import small_curl
    from fatigue_pin.drivers.sliding import ending
    from fatigue_pin.io.study import run_study

    assert ending(full_run[0]) == "stopped at the cap of 5 cycles (horizon.max_cycles), not by fatigue"
    tired = run_study(small_curl("sliding").replace({"fatigue.F": 5.0})).run  # tires within a few cycles
    last = tired.windows[-1]
    assert not last["converged"] and tired.n_cycles == repetitions(int(tired.windows["converged"].sum()), SlidingSettings(window=3))
    first, status, iterations = int(last["first_cycle"]), last["status"].decode(), int(last["iterations"])
    assert ending(tired) == (f"then the arm was too tired to go on: the solver found no motion for the next 3 cycles "
                             f"({first + 1}-{first + 3}) from the end of cycle {first} (window {int(last['index'])}: {status} "
                             f"after {iterations} iterations)")
    # the first window already fails (183 iterations to Infeasible_Problem_Detected; 30 suffice here)
    cold = run_study(small_curl("sliding").replace({"fatigue.F": 10.0, "solver.max_iter": 30})).run
    assert ending(cold).startswith("the arm could not do the first 3 cycles (the solver found no motion: ")


def test_the_window_has_no_default(small_problem):
    """A general class carries no paper number: the window (the paper's is 3) must be given."""
    with pytest.raises(TypeError, match="window"):
        SlidingSettings()
    with pytest.raises(TypeError, match="sliding"):
        SlidingHorizon(small_problem)
    with pytest.raises(ParameterError, match="expected SlidingSettings"):
        SlidingHorizon(small_problem, None)
    from fatigue_pin.drivers.mpc import ClosedLoop

    with pytest.raises(ParameterError, match="expected SlidingSettings"):
        ClosedLoop(small_problem)


def test_a_stalled_gauss_newton_window_is_finished_by_the_exact_hessian(small_problem, small_study, full_run):
    """``exact_finish``: Gauss-Newton windows stopped at 6 iterations (``not-converged``) are solved
    again with the exact Hessian from their last iterate; the run then keeps its windows, and
    they reach the optima of the exact Hessian's own run (``full_run``). Without it the first
    window ends the run."""
    import dataclasses

    gauss_newton = dataclasses.replace(small_study.solver(), derivative_blocks=True, hessian="gauss-newton", max_iter=6)
    settings = dict(window=3, advance=1, max_cycles=4)
    lines: list[str] = []
    finished = SlidingHorizon(small_problem, SlidingSettings(**settings, exact_finish=True), small_study.transcription(),
                              gauss_newton).run(progress=lines.append)
    exact, _ = full_run
    assert finished.windows["converged"].all() and finished.n_cycles == 4
    assert (finished.windows["iterations"] > 6).all()  # the stall's 6 and the finish's
    np.testing.assert_allclose(finished.windows["objective"], exact.windows["objective"][:2], rtol=1e-6)
    assert all("(exact finish: " in line for line in lines if line.startswith("window "))
    stalled = SlidingHorizon(small_problem, SlidingSettings(**settings), small_study.transcription(), gauss_newton).run()
    assert stalled.n_cycles == 0 and not stalled.windows["converged"].any()
