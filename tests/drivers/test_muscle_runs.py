"""Runs of muscle studies: what the drivers store (docs/muscles.md, docs/results.md): every unit's
control (activations, residual torques), the muscle file's text, each muscle's force and the
joint torque at every interval's start, read back from HDF5 as they were written."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from fatigue_pin.io.results import read_run, write_run


def test_a_muscle_run_stores_its_units_controls_forces_and_muscles(two_muscle_run, arm26):
    study, out, run = two_muscle_run
    assert run.actuation == "muscles" and run.muscle_names == ("TRIlat", "BRA")
    assert run.actuator_names == ("TRIlat", "BRA", "shoulder_plus", "shoulder_minus", "elbow_plus", "elbow_minus")
    assert run.muscles == Path(study.data["model"]["muscles"]).read_text()  # the file reproduces itself
    assert run.converged and run.unit_controls.shape == (10, 6)
    a = run.unit_controls[:, :2]
    assert np.all(a >= -1e-8) and np.all(a <= 1 + 1e-8) and a.max() > 0.05  # activations, and the muscles work
    # target loads: the activations, then the residual halves' tau / limit
    TL = run.target_loads()
    assert np.array_equal(TL[:, :2], a)
    assert np.allclose(TL[:, 2:] * [50, -50, 50, -50], run.unit_controls[:, 2:])
    # tau_plus / tau_minus hold the residual torques per joint
    assert np.allclose(run.tau_plus[:, 1], run.unit_controls[:, 4]) and np.allclose(run.tau_minus[:, 0], run.unit_controls[:, 3])
    # the forces and the joint torque at each interval's start, from the layer on the stored states
    layer = study.actuators(arm26)
    F = np.array([np.asarray(layer.forces(run.q[k], run.qdot[k], a[k])).ravel() for k in range(10)])
    assert np.allclose(run.extras["muscle_force"], F, rtol=1e-12, atol=1e-9) and F.max() > 10.0
    tau = np.array([np.asarray(layer.torque(run.q[k], run.qdot[k], a[k])).ravel() for k in range(10)])
    assert np.allclose(run.extras["joint_torque"], tau + run.tau_plus + run.tau_minus, atol=1e-9)


def test_a_muscle_run_reads_back_as_written(two_muscle_run, tmp_path):
    _, _, run = two_muscle_run
    path = write_run(tmp_path / "again.h5", run)
    back = read_run(path, run.name)
    for key in ("unit_controls", "tau_plus", "tau_minus", "q", "fatigued"):
        assert np.array_equal(getattr(back, key), getattr(run, key)), key
    assert back.muscles == run.muscles and back.muscle_names == run.muscle_names
    assert set(back.extras) == {"muscle_force", "joint_torque"}


def test_the_layer_gives_the_controls_back_from_the_units(two_muscle_run, arm26):
    study, _, run = two_muscle_run
    layer = study.actuators(arm26)
    u = layer.controls(run.unit_controls)
    assert u.shape == (10, layer.nu) and np.array_equal(layer.half_torques(u), run.unit_controls)
    lo, hi = layer.control_bounds()
    assert np.all(u >= lo - 1e-8) and np.all(u <= hi + 1e-8)


def test_the_activation_and_residual_terms_are_what_the_run_stores(two_muscle_run):
    """Each cycle's activation and residual costs are dt * w * the sums of squares of the stored controls."""
    study, _, run = two_muscle_run
    dt, costs = run.attrs["dt"], dict(zip(run.cost_terms, run.cycle_costs[0]))
    assert np.isclose(costs["activation"], dt * np.sum(run.unit_controls[:, :2] ** 2), rtol=1e-9)
    assert np.isclose(costs["residual"], dt * np.sum(run.unit_controls[:, 2:] ** 2), rtol=1e-9)
    assert costs["activation"] > 0 and costs["residual"] > 0


def test_a_sliding_muscle_run_stitches_its_windows_and_resumes_to_the_same_run(tmp_path):
    """Two one-cycle windows; run again with resume, the finished run is read back, not solved again."""
    from conftest import muscle_curl, two_muscle_file
    from fatigue_pin.io.study import run_study

    study = muscle_curl(two_muscle_file(tmp_path), **{"horizon.kind": "sliding", "horizon.cycles": 1, "horizon.advance": 1,
                                                      "horizon.max_cycles": 2})
    out = tmp_path / "sliding.h5"
    first = run_study(study, out=out).run
    assert first.n_cycles == 2 and first.unit_controls.shape == (20, 6) and len(first.windows) == 2
    assert all(bool(w["converged"]) for w in first.windows) and first.fatigued[-1, :2].max() > first.fatigued[10, :2].max() > 0
    again = run_study(study, out=out, resume=True).run
    assert np.array_equal(again.unit_controls, first.unit_controls) and np.array_equal(again.q, first.q)
    assert read_run(out, first.name).muscles == first.muscles
