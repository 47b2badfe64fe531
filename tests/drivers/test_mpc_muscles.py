"""The closed loop with muscles: the plant integrates the muscles' torque at its own q and qdot,
the moving-horizon estimator corrects each muscle's fatigue, and the plant's run keeps its muscle
forces."""

from __future__ import annotations

import numpy as np

from conftest import muscle_curl, two_muscle_file, mhe_closed_loop


def test_a_muscle_closed_loop_estimates_its_muscles_fatigue(tmp_path):
    """Two muscles and residual torques; the plant's muscles tire 20 times slower than the
    controller believes (F = 0.0228 against 0.456); one-cycle windows re-planned every cycle,
    the moving-horizon estimator with a capacity probe every cycle."""
    study = muscle_curl(two_muscle_file(tmp_path), **{"horizon.kind": "sliding", "horizon.cycles": 1, "horizon.max_cycles": 2})
    run = mhe_closed_loop(tmp_path, study, "[plant.fatigue]\nF = 0.0228", ["F"])
    assert run.actuation == "muscles" and run.n_cycles == 2 and run.attrs["repetitions"] == 2
    intervals = run.tau_plus.shape[0]
    # the plant's muscles: their forces and the joint torque at every interval start, stored
    assert run.extras["muscle_force"].shape == (intervals, 2) and run.extras["joint_torque"].shape == (intervals, 2)
    assert np.all(run.extras["muscle_force"] >= 0) and run.extras["muscle_force"].max() > 50.0  # N
    # the estimator moved each muscle's F from the controller's 0.456 towards the plant's
    params = run.extras["params"]
    layer_F = [k for k, n in enumerate(_param_names(run)) if n in ("TRIlat.F", "BRA.F")]
    assert np.all(params[0, layer_F] == 0.456) and np.all(params[-1, layer_F] < 0.3)
    # and its estimate of mf, corrected at the second re-plan (node 10), is nearer the plant's
    # than the first plan's prediction was
    est, plant, pred = run.extras["estimate"], run.fatigue["mf"][:, :2], run.extras["prediction"]
    mf_rows = np.asarray(run.attrs["fatigued_rows"])[:2]
    ny = run.q.shape[1] * 2
    assert [int(r["node"]) for r in run.extras["replans"]] == [0, 10]
    assert np.abs(est[10, mf_rows] - plant[10]).max() < 0.5 * np.abs(pred[10, ny + mf_rows] - plant[10]).max()
    # every plant interval on the exact flow of its muscles (the plant's own reference integration,
    # verify's). `fatigue-pin verify` passes on this run too (measured: 8 s more, not repeated here)
    assert run.extras["flow_gap"].max() < 1e-5


def _param_names(run) -> list[str]:
    import json

    per_half = json.loads(run.attrs["fatigue_params"])
    return [f"{h}.{k}" for h in run.actuator_names for k in per_half[h] if k != "model"]
