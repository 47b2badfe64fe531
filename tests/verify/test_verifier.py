"""``fatigue-pin verify``: an independent check of stored results (solve_ivp + numeric pinocchio.aba).

The reference integration only means something when the transcription's own RK4 error is below
the gap tolerance, so the results verified here use the small curl's 10 intervals per cycle with
8 substeps (sliding) and the paper's grid, 50 intervals and 5 substeps (one full cycle); the
conftest's 2 substeps are too coarse for the default tolerances, which verify says
(``test_coarse_grid_fails_and_says_why``).
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np
import pytest

from fatigue_pin.cli.main import main
from fatigue_pin.paper.curl import curl_study
from fatigue_pin.paper.reproduce import _verify_rows
from fatigue_pin.io.results import read_run, write_run
from fatigue_pin.io.study import Study, run_study
from fatigue_pin.ocp.transcription import IntervalFunctions, Transcription
from fatigue_pin.verify import VerifyTolerances, verify_run

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from conftest import small_curl  # noqa: E402


@pytest.fixture(scope="module")
def full_file(tmp_path_factory):
    """One full-horizon cycle on the paper's grid (50 intervals, 5 substeps)."""
    out = tmp_path_factory.mktemp("verify") / "full.h5"
    study = curl_study("full", cycles=1, intervals_per_cycle=50, substeps=5, solver={"compile": False})
    run = run_study(study, out).run
    assert run.converged
    return out, run.name


@pytest.fixture(scope="module")
def sliding_file(tmp_path_factory):
    """Sliding horizon, windows of 2 cycles advancing 1, 3 cycles kept: 2 windows, one join."""
    out = tmp_path_factory.mktemp("verify") / "sliding.h5"
    study = curl_study("sliding", cycles=2, max_cycles=3, intervals_per_cycle=10, substeps=8, solver={"compile": False})
    run = run_study(study, out).run
    assert run.windows.shape == (2,) and run.windows["converged"].all()
    return out, run.name


@pytest.fixture(scope="module")
def full_report(full_file):
    path, name = full_file
    return verify_run(read_run(path, name), single_shooting=True)


def _with(run, **changes):
    return dataclasses.replace(run, **changes)


def test_full_result_passes(full_file, full_report, capsys):
    r = full_report
    assert r.passed, r.table()
    assert r.gap < 1e-3 and r.gap_fatigue < 1e-7
    assert r.task == 0.0 and r.coupling < 1e-6 and r.bound < 1e-6
    assert r.rk4_residual < 1e-6  # the nodes solve their own discretisation (IPOPT's tolerance)
    assert "PASSED" in r.table()
    path, name = full_file
    assert main(["verify", str(path)]) == 0
    assert "PASSED" in capsys.readouterr().out


def test_sliding_result_passes_joins_included(sliding_file, capsys):
    path, name = sliding_file
    run = read_run(path, name)
    r = verify_run(run)
    assert r.passed, r.table()
    assert r.n_intervals == 30  # the stitched trajectory, across the join at node 10
    assert r.gap < 1e-3 and r.gap_fatigue < 1e-5
    assert any("cyclic end condition is not checked" in note for note in r.notes)
    assert main(["verify", str(path), name]) == 0
    assert "cyclic end condition is not checked" in capsys.readouterr().out


def test_changed_node_fails_with_the_gap_named(full_file, tmp_path, capsys):
    path, name = full_file
    run = read_run(path, name)
    q = run.q.copy()
    q[12, 1] += 0.01  # elbow, between the targets (nodes 0, 25, 50)
    bad = tmp_path / "bad.h5"
    write_run(bad, _with(run, q=q))
    assert main(["verify", str(bad)]) == 1
    out = capsys.readouterr().out
    failed = next(line for line in out.splitlines() if "FAILED" in line)
    assert "gap q" in failed and ("interval 11, elbow" in failed or "interval 12, elbow" in failed)
    r = verify_run(read_run(bad, name))
    assert 0.009 < r.gap_q < 0.011 and r.task == 0.0


def test_known_answer_reintegration_matches_the_nodes_at_fourth_order(full_file, full_report):
    """The package's RK4 (CasADi Pinocchio ABA) and the reference (DOP853, numeric pin.aba)
    agree: trajectories rolled out from the stored controls with the package's RK4 have gaps
    that shrink like h^4 as the substeps double (s steps of h = dt / s over an interval: error
    s * O(h^5) = O(dt h^4), a factor 16; measured 17 to 20)."""
    path, name = full_file
    run = read_run(path, name)
    study = Study.from_toml(run.study)
    problem = study.problem()
    L = problem.layout
    u = np.hstack([run.tau_plus, run.tau_minus])
    p = problem.actuators.param_vector()
    gaps = []
    for substeps in (2, 4, 8):
        fn = IntervalFunctions(problem, Transcription(substeps=substeps))
        x = np.zeros((u.shape[0] + 1, L.nx))
        x[0] = L.assemble(run.q[:1], run.qdot[:1], {k: v[:1] for k, v in run.fatigue.items()})[0]
        for k in range(u.shape[0]):
            x[k + 1] = fn.step(x[k], u[k], p)
        rolled = _with(run, q=x[:, L.q], qdot=x[:, L.v], fatigue={s: L.fatigue_columns(x, s) for s in L.state_kinds},
                       attrs={**run.attrs, "substeps": substeps})
        r = verify_run(rolled)
        assert r.rk4_residual < 1e-12  # the numpy RK4 of verify is the package's RK4
        gaps.append(r.gap_qdot)
    assert 12 < gaps[0] / gaps[1] < 30 and 12 < gaps[1] / gaps[2] < 30, gaps
    assert gaps[2] < 1e-5
    # and the stored (optimal) nodes themselves: within the paper grid's RK4 error of the flow
    assert full_report.gap_q < 1e-5 and full_report.gap_qdot < 3e-4


def test_single_shooting_drift_is_small_for_a_converged_solution(full_report):
    r = full_report
    assert r.drift_q < 1e-5 and r.drift_qdot < 3e-4 and r.drift_fatigue < 1e-7 and r.drift_invariant < 1e-8
    table = r.table()
    assert "single shooting: drift q" in table and "single shooting: invariant drift" in table


class _RecordingBar:
    def __init__(self, total):
        self.total, self.counts, self.closed = total, [], False

    def update(self, n=1, **postfix):
        self.counts.append((self.counts[-1] if self.counts else 0) + n)

    def close(self):
        self.closed = True


def test_progress_counts_every_interval_up_to_the_total(full_file, full_report, capsys):
    """verify_run reports its progress through a Reporter's bar: the count grows interval by
    interval to the total (the N intervals of the gaps, N more of the single shooting); the
    report is the same as a quiet one's. The command line draws it on standard error, and
    only on a terminal: not here, so standard error stays empty."""
    import io

    from fatigue_pin.core.progress import Reporter

    bars = []

    class Recording(Reporter):
        def bar(self, total, desc, unit="it"):
            bars.append(_RecordingBar(total))
            bars[-1].desc, bars[-1].unit = desc, unit
            return bars[-1]

    path, name = full_file
    run = read_run(path, name)
    report = verify_run(run, single_shooting=True, progress=Recording())
    (bar,) = bars
    assert bar.total == 2 * 50 and bar.unit == "interval" and name in bar.desc and bar.closed
    assert bar.counts == list(range(1, bar.total + 1))  # increasing by one interval, up to the total
    assert report.table() == full_report.table()
    stream = io.StringIO()  # a real Reporter with bars: tqdm's last state is the total
    verify_run(run, progress=Reporter(stream=stream, bars=True))
    assert "50/50" in stream.getvalue()
    capsys.readouterr()
    assert main(["verify", str(path)]) == 0
    captured = capsys.readouterr()
    assert "PASSED" in captured.out and captured.err == ""


def test_the_command_draws_its_bar_on_a_terminal_stderr(full_file):
    """``fatigue-pin verify`` with standard error on a terminal (a pseudo-terminal here) draws the
    bar there, up to every interval (50, and 50 more with --single-shooting), while standard
    output, a pipe, holds the report only."""
    import fcntl
    import os
    import pty
    import struct
    import subprocess
    import termios

    import fatigue_pin

    path, name = full_file
    home = str(Path(fatigue_pin.__file__).resolve().parents[1])
    env = {**os.environ, "PYTHONPATH": home + os.pathsep + os.environ.get("PYTHONPATH", "")}
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 120, 0, 0))  # a terminal 120 columns wide
    proc = subprocess.Popen([sys.executable, "-c", "import sys; from fatigue_pin.cli.main import main; sys.exit(main())",
                             "verify", str(path), "--single-shooting"], stdout=subprocess.PIPE, stderr=slave, env=env,
                            cwd=Path(path).parent)  # not the source tree (python -c puts the folder first on sys.path)
    os.close(slave)
    err = b""
    while True:  # read the terminal until the child closes it
        try:
            chunk = os.read(master, 65536)
        except OSError:  # EIO: the child has exited and closed its end
            break
        if not chunk:
            break
        err += chunk
    out = proc.stdout.read().decode()
    assert proc.wait() == 0
    os.close(master)
    text = err.decode(errors="replace")
    assert f"verify {name}" in text and "100/100" in text and "interval" in text, text
    assert out.startswith(f"verify {name} ") and "PASSED" in out and "100/100" not in out and "\r" not in out


def test_a_diverging_single_shooting_is_reported_not_raised(full_file, monkeypatch):
    """When the open-loop integration of the rigid body fails (a long swinging horizon), verify
    reports an infinite drift with a note and still integrates the fatigue states to the end."""
    from fatigue_pin.verify import dynamics

    path, name = full_file
    real = dynamics.integrate
    calls = {"rigid": 0}

    def failing(f, y0, dt, ref):
        if y0.size == 4:  # the rigid body (q, qdot of 2 joints): 50 gap checks, then single shooting
            calls["rigid"] += 1
            if calls["rigid"] > 50 + 10:
                raise dynamics.IntegrationFailed("step size too small")
        return real(f, y0, dt, ref)

    monkeypatch.setattr(dynamics, "integrate", failing)
    r = verify_run(read_run(path, name), single_shooting=True, rtol=1e-3, atol=1e-6, method="RK45")
    assert r.drift_q == float("inf") and any("interval 10" in n for n in r.notes)
    assert r.single_shooting_invariant_final < 1e-12  # the fatigue states went on to the end
    assert not [c for c in r.failures if c.name.startswith("single shooting")]  # reported only


def test_invariant_is_reported(full_file, full_report):
    r = full_report
    assert r.invariant_sum == "xia: ma + mr + mf"
    assert r.invariant < 1e-8 and r.invariant_final <= r.invariant
    assert "invariant |1 - (ma + mr + mf)|" in r.table()
    path, name = full_file
    run = read_run(path, name)
    mr = run.fatigue["mr"].copy()
    mr[20, 3] -= 1e-3  # (the elbow extensor rests: mr ~ 1)
    r2 = verify_run(_with(run, fatigue={**run.fatigue, "mr": mr}))
    assert abs(r2.invariant - 1e-3) < 1e-6 and "node 20, elbow_minus" in r2.checks[[c.name for c in r2.checks].index(
        "invariant |1 - (ma + mr + mf)|")].where
    assert not r2.passed and [c.name for c in r2.failures] == ["gap fatigue states"]


def test_task_coupling_and_bounds_violations(full_file):
    path, name = full_file
    run = read_run(path, name)
    tol = VerifyTolerances(gap=1.0, gap_fatigue=1.0)  # look at the other checks only
    q = run.q.copy()
    q[25, 1] += 2e-3  # the 150 deg target
    r = verify_run(_with(run, q=q), tol)
    assert [c.name for c in r.failures] == ["task joint targets"] and abs(r.task - 2e-3) < 1e-9
    mf = run.fatigue["mf"].copy()
    mf[10, 2] = 0.999  # elbow_plus: TL + mf > 1 where it pulls
    tp = run.tau_plus.copy()
    tp[10, 1] = max(tp[10, 1], 5.0)
    fatigued = run.fatigued.copy()
    fatigued[10, 2] = 0.999
    r = verify_run(_with(run, fatigue={**run.fatigue, "mf": mf}, fatigued=fatigued, tau_plus=tp), tol)
    assert "coupling TL + m_fatigued in [0, 1]" in [c.name for c in r.failures]
    assert "node 10, elbow_plus" in next(c.where for c in r.checks if c.name.startswith("coupling"))
    tm = run.tau_minus.copy()
    tm[3, 0] = -50.5
    r = verify_run(_with(run, tau_minus=tm), tol)
    assert "bound torques" in [c.name for c in r.failures] and abs(r.bound - 0.5) < 1e-9


def test_no_study_stored(full_file):
    path, name = full_file
    r = verify_run(_with(read_run(path, name), study=""))
    assert "no study stored: task not checked" in r.notes
    assert np.isnan(r.task) and r.passed
    assert "not checked" in r.table()


def test_coarse_grid_fails_and_says_why():
    """On the conftest's grid (2 substeps of 0.05 s) the optimiser whips the elbow to its velocity
    bound in the last interval, where RK4 is off by rad/s: verify fails on the gap and says that
    the nodes do solve their own discretisation."""
    run = run_study(small_curl("full", cycles=1)).run
    r = verify_run(run)
    assert not r.passed and "gap qdot" in [c.name for c in r.failures]
    assert r.rk4_residual < 1e-6 and r.rk4_truncation == pytest.approx(r.gap_qdot, rel=1e-6)
    assert any("too coarse" in note for note in r.notes)
    assert verify_run(run, VerifyTolerances(gap=10.0, gap_fatigue=1e-2)).passed


def test_cli_all_and_bad_input(full_file, sliding_file, tmp_path, capsys):
    path, name = full_file
    both = tmp_path / "both.h5"
    write_run(both, read_run(path, name))
    write_run(both, read_run(*sliding_file))
    assert main(["verify", str(both), "--all"]) == 0
    assert "2 of 2 runs passed" in capsys.readouterr().out
    assert main(["verify", str(both), "--all", "--gap-tol", "1e-9"]) == 1
    assert "0 of 2 runs passed" in capsys.readouterr().out
    assert main(["verify", str(both)]) == 2  # several runs, none named
    assert main(["verify", str(tmp_path / "missing.h5")]) == 2
    assert main(["verify", str(path), "no/such/run"]) == 2
    assert main(["verify", str(path), "--coupling-tol", "-1"]) == 2
    assert main(["verify", str(path), "--single-shooting", "--rtol", "1e-8", "--atol", "1e-10"]) == 0
    assert "single shooting: drift qdot" in capsys.readouterr().out


def test_reproduce_report_rows(full_file):
    path, name = full_file
    rows = _verify_rows([path])
    assert len(rows) == 1 and rows[0].startswith(f"| {name} |") and rows[0].endswith("| passed |")


# -- bad input: one line and exit 2, never a hang or a traceback --------------------------------------


@pytest.fixture
def alarm():
    """Fail, rather than hang, a verify that does not return within 60 s (a NaN tolerance or a
    NaN gravity made ``solve_ivp`` loop for ever)."""
    import signal

    def handler(signum, frame):
        raise TimeoutError("verify did not return within 60 s")

    old = signal.signal(signal.SIGALRM, handler)
    signal.alarm(60)
    yield
    signal.alarm(0)
    signal.signal(signal.SIGALRM, old)


def _changed(path, name, tmp_path, **changes) -> str:
    """A copy of the run with ``changes`` (RunResult fields; ``gravity``: a stored study with
    that gravity; ``attrs``: attributes changed)."""
    run = read_run(path, name)
    if "gravity" in changes:
        study = Study.from_toml(run.study)
        text = study.to_toml().replace("[model]\n", f"[model]\ngravity = {changes.pop('gravity')}\n", 1)
        changes["study"] = text
    if "attrs" in changes:
        changes["attrs"] = {**run.attrs, **changes["attrs"]}
    out = tmp_path / "changed.h5"
    write_run(out, _with(run, **changes))
    return str(out)


#: (case, argv after "verify FILE" or a change of the stored run, the message): docs/errors.md
#: lists them under "verify".
BAD_INPUT = [
    ("verify-nan-rtol", ["--rtol", "nan"], {}, r"rtol = nan: expected a finite relative tolerance > 0"),
    ("verify-zero-rtol", ["--rtol", "0"], {}, r"rtol = 0.0: expected a finite relative tolerance > 0"),
    ("verify-negative-atol", ["--atol", "-1"], {}, r"atol = -1.0: expected a finite absolute tolerance >= 0"),
    ("verify-infinite-atol", ["--atol", "inf"], {}, r"atol = inf: expected a finite absolute tolerance >= 0"),
    ("verify-nan-gap-tol", ["--gap-tol", "nan"], {}, r"VerifyTolerances.gap = nan: expected a finite tolerance >= 0"),
    ("verify-nan-gravity", [], {"gravity": "[nan, 0.0, -9.81]"}, r"gravity.*nan"),
    ("verify-nan-dt", [], {"attrs": {"dt": float("nan")}}, r"interval length dt = nan; expected a finite duration > 0"),
    ("verify-bad-torque-limits", [], {"attrs": {"tau_limits": np.array([50.0, -50.0, np.nan, -50.0])}},
     r"torque limits \[50.0, -50.0, nan, -50.0\] N m; expected finite limits"),
    ("verify-study-unloadable", [], {"study": "name = \n[model"}, r"its stored study does not load"),
]


@pytest.mark.parametrize("case, argv, changes, message", BAD_INPUT, ids=[c[0] for c in BAD_INPUT])
def test_bad_input_is_one_line_and_exit_2(case, argv, changes, message, full_file, tmp_path, capsys, alarm):
    import re

    path, name = full_file
    target = _changed(path, name, tmp_path, **changes) if changes else str(path)
    code = main(["verify", target, *argv])
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.count("\n") == 1 and err.startswith("fatigue-pin: error: ") and "Traceback" not in err
    assert re.search(message, err), err


@pytest.mark.parametrize("field, row, column, where", [("q", 12, 1, "node 12, q elbow"), ("qdot", 0, 0, "node 0, qdot shoulder"),
                                                       ("tau_plus", 7, 1, "interval 7, tau_plus elbow")])
def test_non_finite_stored_values_fail_a_check(field, row, column, where, full_file, tmp_path, capsys, alarm):
    path, name = full_file
    run = read_run(path, name)
    values = getattr(run, field).copy()
    values[row, column] = np.nan
    bad = _changed(path, name, tmp_path, **{field: values})
    assert main(["verify", bad, "--single-shooting"]) == 1
    out = capsys.readouterr().out
    failed = next(line for line in out.splitlines() if "FAILED" in line)
    assert f"finite stored values 1.000e+00 > 0 ({where})" in failed
    assert "not re-integrated: their stored values are not finite" in out and "Traceback" not in out


def test_an_absurd_interval_is_bounded(full_file, tmp_path, capsys, alarm):
    """A stored dt of 1e9 s would take the reference integration for ever: each interval stops
    after MAX_EVALUATIONS rate evaluations, and after MAX_FAILED_INTERVALS the gap check stops."""
    from fatigue_pin.verify.dynamics import MAX_FAILED_INTERVALS

    path, name = full_file
    bad = _changed(path, name, tmp_path, attrs={"dt": 1e9})
    assert main(["verify", bad]) == 1
    out = capsys.readouterr().out
    assert "gap q inf > 0.001 (interval 0, " in out
    assert f"failed on {MAX_FAILED_INTERVALS} intervals already" in out and "evaluations of the rates" in out


def test_the_catalogue_lists_the_verify_cases():
    doc = (Path(__file__).resolve().parents[2] / "docs" / "errors.md").read_text()
    missing = [case for case, *_ in BAD_INPUT if f"`{case}`" not in doc]
    assert not missing, f"docs/errors.md lacks {missing}"
