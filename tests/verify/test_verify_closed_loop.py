"""``fatigue-pin verify`` of a closed-loop run: the task is checked on the cycles the run counts as
repetitions, within the tolerance it counted them with (its ``target_tolerance``)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from conftest import TIRED_MPC_TABLES, small_mpc_study
from fatigue_pin.cli.main import main
from fatigue_pin.drivers.mpc_run import run_closed_loop
from fatigue_pin.io.mpc_study import MpcStudy
from fatigue_pin.io.results import ResultFile, read_run, write_run
from fatigue_pin.verify import VerifyTolerances, verify_run

#: 4 whole cycles, 3 repetitions with seed 5 (conftest); target_tolerance 0.05 (the default)
TIRED = TIRED_MPC_TABLES


@pytest.fixture(scope="module")
def stored(tmp_path_factory):
    out = tmp_path_factory.mktemp("verify_mpc") / "run.h5"
    study = MpcStudy.from_toml(small_mpc_study(TIRED, seed=5, max_cycles=4))
    run_closed_loop(study.closed_loop(), ResultFile(out), "mpc/tired", study=study.to_toml())
    return out


def test_the_task_is_checked_on_the_counted_cycles_within_the_runs_target_tolerance(stored, capsys):
    run = read_run(stored)
    errors = run.extras["task_error"]
    assert run.attrs["repetitions"] == 3 and run.n_cycles == 4 and errors[3] > 0.05  # the fixture's premise
    assert errors[:3].max() > VerifyTolerances().task  # a noisy plant misses its targets by more than 1e-4
    report = verify_run(run)
    assert report.passed, report.table()
    line = report.check("task joint targets")
    assert line.tolerance == 0.05 and line.value == pytest.approx(errors[:3].max(), abs=1e-12)
    assert int(line.where.split(",")[0].split()[-1]) <= 30  # a node of the 3 counted cycles
    assert report.check("initial state").tolerance == VerifyTolerances().task  # the plant starts there exactly
    assert any("the task is checked on the 3 cycle(s) it counts as repetitions (nodes 0-30), within its "
               "target_tolerance 0.05" in note for note in report.notes)
    assert main(["verify", str(stored)]) == 0
    assert "  PASSED" in capsys.readouterr().out


def _moved(run, node: int, by: float):
    q = run.q.copy()
    q[node, 1] += by  # the elbow
    return dataclasses.replace(run, q=q)


def test_a_counted_cycle_that_misses_its_target_fails(stored):
    """Node 15 (the 150 deg target of cycle 2) moved by 0.1 rad: past the 0.05 rad a repetition
    allows, the task line fails there."""
    run = read_run(stored)
    report = verify_run(_moved(run, 15, 0.1))
    line = report.check("task joint targets")
    assert not line.passed and "node 15" in line.where
    assert line.value == pytest.approx(abs(run.q[15, 1] + 0.1 - 2.6179938779914944), abs=1e-12)


def test_a_cycle_past_the_count_is_not_checked_against_the_task(stored, tmp_path):
    """Node 35 (the 150 deg target of cycle 4, not a repetition) moved: the task line does not
    change; the gap lines see the move (it is not the plant's flow any more)."""
    run = read_run(stored)
    before = verify_run(run).check("task joint targets").value
    moved = tmp_path / "moved.h5"
    write_run(moved, _moved(run, 35, 0.5))
    report = verify_run(read_run(moved))
    assert report.check("task joint targets").value == before
    assert {c.name for c in report.failures} >= {"gap q"} and "task joint targets" not in {c.name for c in report.failures}


def test_a_run_that_counts_no_repetition_has_its_task_not_checked(stored):
    run = read_run(stored)
    run.attrs = {**run.attrs, "repetitions": 0}
    report = verify_run(run)
    line = report.check("task joint targets")
    assert not line.checked and line.verdict == "not checked"
    assert any("counts no repetition" in note for note in report.notes)
    assert report.check("initial state").checked


def test_the_coupling_at_the_last_node_is_the_plants_next_torque(tmp_path):
    """The plant delivers at most its capacity 1 - mf at the start of every interval and holds that
    torque while mf rises: with the open-loop estimator the tired plant saturates, and the last
    interval's torque with the last node's mf is 0.02 past 1 (verify's u_N := u_{N-1} failed the
    run). At node N the plant's next delivered torque counts (extras tail_u); without one (the run
    ended there) node N is not a coupling node."""
    study = MpcStudy.from_toml(small_mpc_study(TIRED, seed=5, max_cycles=4)).replace({"mpc.estimator": "open-loop"})
    out = tmp_path / "open_loop.h5"
    run_closed_loop(study.closed_loop(), ResultFile(out), "mpc/open", study=study.to_toml())
    run = read_run(out)
    assert run.extras["tail_u"].shape[0] == 0
    assert (run.target_loads()[-1] + run.fatigued[-1]).max() > 1.01  # u_{N-1} with mf_N
    line = verify_run(run).check("coupling TL + m_fatigued in [0, 1]")
    assert line.passed and line.value < 1e-6, line
    # a next torque over the last node's capacity fails there
    capacity = 1.0 - run.fatigued[-1]  # per half: plus, minus of each joint
    limits = run.signed_limits
    over = np.array([[1.5 * capacity[0] * limits[0], 0.0, 0.0, 0.0]])  # shoulder_plus at 1.5 times its capacity
    bad = dataclasses.replace(run, extras={**run.extras, "tail_u": over})
    line = verify_run(bad).check("coupling TL + m_fatigued in [0, 1]")
    assert not line.passed and f"node {run.q.shape[0] - 1}" in line.where and "shoulder_plus" in line.where
    assert line.value == pytest.approx(0.5 * capacity[0], rel=1e-9)
