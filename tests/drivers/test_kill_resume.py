"""Runs killed with SIGKILL, or stopped with SIGINT or SIGTERM (exit codes 130, 143), at chosen and
random moments (during a write of the result file, and during a solve) resume to the
uninterrupted result; the file always opens and loses nothing finished, and an interrupted solve
is never stored as finished or converged. The full version (20 kills of each kind):
``benchmarks/kill_resume.py``."""

from __future__ import annotations

import signal
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

from kill_resume import campaign, report, segment  # noqa: E402


def _check(fig, kills):
    assert fig.kills == kills, report([fig])
    assert fig.unreadable == 0 and fig.lost == 0, report([fig])
    assert fig.equal == fig.runs >= 1, report([fig])


def test_killed_sliding_run_resumes_to_the_same_result(tmp_path):
    """Killed just after the HDF5 edit of its first window's write (before the fsync and the
    rename), then, resumed, at the fsync of that write."""
    fig = campaign("sliding", 5, 2, tmp_path, plan=[("at", "h5-written"), ("at", "fsync")], say=lambda _: None)
    _check(fig, 2)
    assert fig.where == {"h5-written": 1, "fsync": 1}


def test_killed_search_resumes_to_the_same_result(tmp_path):
    """Killed at the byte copy of its second write (the best run), once the step run of N = 1 is
    stored but not yet its row of the search table: the resumed search solves N = 1 again."""
    fig = campaign("max-cycles", 2, 1, tmp_path, plan=[("at", "copy")], say=lambda _: None)
    _check(fig, 1)
    assert fig.where == {"copy": 1}


@pytest.mark.slow
@pytest.mark.parametrize("kind, n", [("sliding", 8), ("max-cycles", 6)])
def test_twenty_random_kills(tmp_path, kind, n):
    fig = campaign(kind, n, 20, tmp_path, seed=7)
    print(report([fig]))
    _check(fig, 20)


def test_sigint_and_sigterm_stop_a_sliding_run_that_resumes_to_the_same_result(tmp_path):
    """SIGINT during the second window's solve, then SIGTERM at the fsync of a write of the
    resumed run: the child exits with 130 and 143 (it handles them as fatigue-pin does), the
    file keeps every finished window, and the run resumes to the uninterrupted result."""
    fig = campaign("sliding", 5, 2, tmp_path, plan=[("after-write", 0.3, signal.SIGINT), ("at", "fsync", signal.SIGTERM)],
                   say=lambda _: None)
    _check(fig, 2)


def test_an_interrupted_window_is_stored_as_interrupted_and_resumed(tmp_path):
    """The run stored after SIGINT at the start of the second window's solve is neither finished
    nor converged, names the signal, and holds only the window finished before it; --resume
    continues it."""
    from fatigue_pin.io.results import read_run

    out = tmp_path / "run.h5"
    written, killed, last, _ = segment("sliding", out, 5, ("at", "solve", signal.SIGINT, 2))
    assert killed and written == 1
    run = read_run(out, "run")
    assert run.attrs["interrupted"] == "SIGINT" and not run.attrs["finished"] and not run.attrs["converged"]
    assert len(run.windows) == written and all(bool(w["converged"]) for w in run.windows)
    assert b"NonIpopt" not in b"".join(bytes(w["status"]) for w in run.windows)
    segment("sliding", out, 5, None)
    run = read_run(out, "run")
    assert run.attrs["finished"] and "interrupted" not in run.attrs and run.n_cycles == 5


#: The steps a SIGINT is sent at: every step of a write of the result file, the start of a solve,
#: and between two solves (a progress line, once the last one is stored), for each driver.
WRITE_STEPS = ("copy", "h5", "h5-written", "fsync", "rename")
BETWEEN = {"sliding": "window", "max-cycles": "N", "mpc": "re-plan"}
SIZES = {"sliding": 5, "max-cycles": 2, "mpc": 3}


@pytest.fixture(scope="module")
def references(tmp_path_factory):
    """The uninterrupted run of each driver (made once, on first use)."""
    from kill_resume import reference

    folder, made = tmp_path_factory.mktemp("references"), {}

    def get(kind):
        if kind not in made:
            made[kind] = reference(kind, SIZES[kind], folder)
        return made[kind]

    return get


def _stored_as_interrupted(kind, out):
    from fatigue_pin.io.results import read_run, read_search_attrs

    if kind == "max-cycles":
        return read_search_attrs(out)["run"].get("interrupted")
    run = read_run(out, "run")
    return run.attrs.get("interrupted") if not run.attrs["finished"] and not run.attrs["converged"] else "finished"


def _cases():
    """Every step for the sliding driver; for the others, the steps that differ by driver (the
    solve, between two solves, and the write of their own items), with the rest of the shared
    write path of the result file (:func:`fatigue_pin.core.files.atomic_write`) marked slow: it is the
    sliding driver's write path too."""
    for kind in ("sliding", "max-cycles", "mpc"):
        for step in (*WRITE_STEPS, "solve", "between"):
            shared = kind != "sliding" and step in ("copy", "h5", "fsync", "rename")
            yield pytest.param(kind, step, marks=pytest.mark.slow) if shared else (kind, step)


@pytest.mark.parametrize("kind, step", list(_cases()))
def test_a_sigint_at_any_step_is_stored_as_interrupted_and_resumes_to_the_same_result(tmp_path, references, kind, step):
    """SIGINT at the second occurrence of ``step`` (the first copy: the first write makes the
    file, so it has no copy): the child exits with 130, the file says the run was interrupted and keeps
    every item it reported written, and --resume ends at the uninterrupted result."""
    from kill_resume import same_result, stored

    tag = BETWEEN[kind] if step == "between" else step
    out = tmp_path / "run.h5"
    written, killed, _, _ = segment(kind, out, SIZES[kind], ("at", tag, signal.SIGINT, 1 if tag == "copy" else 2))
    assert killed, f"the {kind} child was not interrupted at {tag}"
    assert written >= 1 and len(stored(kind, out)) >= written
    assert _stored_as_interrupted(kind, out) == "SIGINT"
    segment(kind, out, SIZES[kind], None)
    ref, _ = references(kind)
    assert same_result(kind, out, ref) is None
    if kind == "max-cycles":
        from fatigue_pin.io.results import read_search_attrs

        assert "interrupted" not in read_search_attrs(out)["run"]


def test_sigterm_stops_a_search(tmp_path):
    """SIGTERM during a solve of the maximum-repetitions search: exit 143, the search stops (no
    further N is tried), every finished N is kept, and it resumes to the uninterrupted result."""
    fig = campaign("max-cycles", 3, 1, tmp_path, plan=[("after-write", 0.2, signal.SIGTERM)], say=lambda _: None)
    _check(fig, 1)
