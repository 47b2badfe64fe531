"""A closed-loop run as a stored run: written after every re-plan, resumed bit for bit, reported."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import TIRED_MPC_TABLES, small_mpc_study
from fatigue_pin.core.errors import ResultFileError
from fatigue_pin.drivers.mpc_run import estimate_run, estimation_error, prediction_run, report, run_closed_loop
from fatigue_pin.io.mpc_study import MpcStudy
from fatigue_pin.io.results import ResultFile, read_run

TIRED = TIRED_MPC_TABLES


@pytest.fixture(scope="module")
def study():
    return MpcStudy.from_toml(small_mpc_study(TIRED, seed=5, max_cycles=4))


@pytest.fixture(scope="module")
def stored(study, tmp_path_factory):
    out = tmp_path_factory.mktemp("mpc") / "run.h5"
    loop = study.closed_loop()
    return loop, run_closed_loop(loop, ResultFile(out), "mpc/tired", study=study.to_toml()), out


def test_the_file_holds_plant_prediction_and_estimate(stored):
    loop, run, out = stored
    back = read_run(out, "mpc/tired")
    assert back.attrs["horizon"] == "mpc" and back.attrs["repetitions"] == run.attrs["repetitions"] == 3
    assert back.n_cycles == 4 and back.q.shape == (41, 2)
    # the 4th whole cycle is not a repetition: the plant misses its targets there, though it follows
    # the exact flow (the adaptive plant), as in every cycle
    errors, gaps = back.extras["task_error"], back.extras["flow_gap"]
    assert errors.shape == (4,) and gaps.shape == (4, 2)
    assert np.all(errors[:3] <= 0.05) and errors[3] > 0.05
    assert np.all(gaps[:, 0] < 1e-6) and np.all(gaps[:, 1] < 1e-8)
    for key, value in run.extras.items():
        np.testing.assert_array_equal(back.extras[key], value)
    e = back.extras
    assert e["prediction"].shape == (41, loop.problem.layout.nx) and e["estimate"].shape == (41, 12)
    assert e["replans"].shape == (4,) and list(e["replans"]["node"]) == [0, 10, 20, 30]
    assert list(e["probe_nodes"]) == [10, 20, 30, 40]
    # the plant's delivered torques are stored as the run's torques, the commands beside them
    assert e["u_command"].shape == (40, 4) and back.tau_plus.shape == (40, 2)
    # the estimate is what the controller knew: measured q, qdot and estimated fatigue
    est, pred = estimate_run(loop, back), prediction_run(loop, back)
    np.testing.assert_array_equal(est.q, e["measured"][:, :2])
    assert not np.array_equal(est.q, back.q)  # noise
    np.testing.assert_allclose(est.mf, back.mf + estimation_error(back), atol=1e-12)
    assert pred.name == "mpc/tired_prediction" and pred.q.shape == back.q.shape


def test_estimation_error_against_the_plant(stored):
    _, run, _ = stored
    err = estimation_error(run)
    L = run.attrs["fatigued_rows"]
    np.testing.assert_allclose(err[:, 2], run.extras["estimate"][:, L[2]] - run.mf[:, 2])
    assert np.abs(err[-1]).max() < 0.05  # MHE from probes every cycle


def test_resume_equals_an_uninterrupted_run_bit_for_bit(study, stored, tmp_path):
    loop, reference, _ = stored
    out = tmp_path / "resumed.h5"
    partial = run_closed_loop(study.closed_loop(), ResultFile(out), "mpc/tired", stop_after=2)
    assert len(read_run(out, "mpc/tired").extras["replans"]) == 2 and partial.n_cycles == 2  # stopped at the 3rd re-plan
    resumed = run_closed_loop(study.closed_loop(), ResultFile(out), "mpc/tired", resume=True)
    for name in ("q", "qdot", "tau_plus", "tau_minus", "mf", "ma"):
        np.testing.assert_array_equal(getattr(resumed, name), getattr(reference, name))
    for key in ("measured", "prediction", "estimate", "u_command", "params", "probes", "task_error"):
        np.testing.assert_array_equal(resumed.extras[key], reference.extras[key])


def test_resume_refuses_another_plant(study, stored):
    _, _, out = stored
    other = MpcStudy.from_toml(small_mpc_study(TIRED, seed=6, max_cycles=4))
    with pytest.raises(ResultFileError, match="plant_settings"):
        run_closed_loop(other.closed_loop(), ResultFile(out), "mpc/tired", resume=True)


def test_report(stored):
    _, run, _ = stored
    text = report(run)
    assert "repetitions achieved by the plant: **3** of 4" in text
    assert text.count("| Solve_Succeeded |") == 4
    for half in run.actuator_names:
        assert f"| {half} |" in text
    rtf = run.extras["replans"]["real_time_factor"]
    np.testing.assert_allclose(rtf, (run.extras["replans"]["wall_time_s"] + run.extras["replans"]["estimator_time_s"]) / 1.0)
