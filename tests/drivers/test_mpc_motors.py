"""The closed loop with motors: a plant whose motors run hotter than the controller's model
([plant.motors]), probed through each motor's housing temperature, and the moving-horizon
estimator correcting the winding's temperature from it; a motor at its limit trips."""

from __future__ import annotations

import numpy as np

from conftest import small_curl, mhe_closed_loop

#: A small, fast motor (time constants of 0.5 s and 2 s, so that a 2 s loop sees its heat)
#: behind a gear of 150 on each of the curl's joints.
TOY = {"preset": "maxon-re40", "gear_ratio": 150.0, "tau_w": 0.5, "tau_m": 2.0, "T_max": 100.0}


def test_a_motor_closed_loop_estimates_the_hotter_plant_from_its_housings(tmp_path):
    """The plant's housings cool through twice the model's thermal resistance (R_ha 9.3 against
    4.65 K/W); a probe every cycle reads each housing's temperature; the MHE estimates each
    motor's housing cooling rate c = 1 / tau_m (tau_m is a product with R_ha), one-cycle windows
    re-planned every cycle."""
    study = small_curl("sliding", cycles=1, max_cycles=2).replace({"actuators.kind": "motors", "motors": TOY})
    # the housing probes are noisy: 0.005 of the allowed rise (0.3 K; seeded)
    run = mhe_closed_loop(tmp_path, study, "[plant.motors]\nR_ha = 9.3\n\n[plant.noise]\ncapacity = 0.005", ["q_h", "b", "c"])
    assert run.actuation == "motors" and run.n_cycles == 2
    # the plant ran hotter than the plan: its housings' rise is larger than the prediction's
    xh, pred = run.fatigue["xh"], run.extras["prediction"]
    ny = 2 * run.q.shape[1]
    assert np.all(xh[10] > pred[10, ny + 1::2] * 1.2)
    # the correction at the second re-plan (node 10) moves the estimate of the windings towards the plant's
    est, xw = run.extras["estimate"], run.fatigue["xw"]
    assert np.abs(est[10, 0::2] - xw[10]).max() < 0.5 * np.abs(pred[10, ny::2] - xw[10]).max()
    assert run.extras["flow_gap"].max() < 1e-5  # the plant's intervals on the exact flow
    # the probes read each housing with its noise: 1 - x_h off the plant's by about 0.005
    probes, nodes = run.extras["probes"], run.extras["probe_nodes"].astype(int)
    off = probes - (1 - xh[nodes])
    assert 1e-4 < np.abs(off).max() < 0.03


def test_a_motor_delivers_its_command_until_its_winding_reaches_the_limit():
    """Unlike a tired half (capped at 1 - mf), a warm motor delivers its whole command; at its
    limit (x_w = 1) it trips to 0."""
    from fatigue_pin.drivers.plant import Plant

    problem = small_curl("full").replace({"actuators.kind": "motors", "motors": TOY}).problem()
    plant = Plant(problem, problem.task.dt)
    L = problem.layout
    x = np.zeros(L.nx)
    x[L.nq + L.nv:] = [0.9, 0.5, 1.0, 0.7]  # shoulder warm (x_w 0.9), elbow at its limit
    u = np.array([30.0, -20.0])
    assert plant.deliver(x, u).tolist() == [30.0, 0.0]
    assert np.allclose(plant.probe(x, 0), [0.5, 0.3])  # 1 - x_h: the housings


def test_a_derated_motor_delivers_at_most_its_derated_torque():
    """``[motors] derate = true``: a warm motor delivers at most ``limit sqrt(1 - x_w)``."""
    from fatigue_pin.drivers.plant import Plant

    problem = small_curl("full").replace({"actuators.kind": "motors", "motors": {**TOY, "derate": True}}).problem()
    plant = Plant(problem, problem.task.dt)
    L = problem.layout
    x = np.zeros(L.nx)
    x[L.nq + L.nv:] = [0.75, 0.5, 1.0, 0.7]  # shoulder warm (x_w 0.75), elbow at its limit
    limits = problem.actuators.limits
    u = np.array([limits[0], -0.1 * limits[1]])
    assert np.allclose(plant.deliver(x, u), [0.5 * limits[0], 0.0])  # sqrt(1 - 0.75) = 0.5
    assert np.allclose(plant.deliver(x, -0.3 * limits), [-0.3 * limits[0], 0.0])  # within the derated limit
