"""Runs killed with SIGKILL at chosen and random moments (during a write of the result file, and
during a solve) resume to the uninterrupted result; the file always opens and loses nothing
finished. The full version (20 kills of each kind): ``benchmarks/kill_resume.py``."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

from kill_resume import campaign, report  # noqa: E402


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
