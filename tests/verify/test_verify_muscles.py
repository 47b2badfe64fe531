"""verify on muscle runs: the muscles' torque on numbers (numeric Pinocchio, finite differences of
the path lengths, the curves on numpy), apart from the transcription's CasADi expressions."""

from __future__ import annotations

import numpy as np

from fatigue_pin.ocp.muscle_actuators import MuscleActuators
from fatigue_pin.verify.muscle_torque import NumericMuscles
from fatigue_pin.verify.verifier import verify_run
from fatigue_pin.fatigue.models import XiaFatigue


def test_numeric_muscles_equal_the_layers_expressions(arm26, arm26_muscles, arm26_geometry):
    numeric = NumericMuscles(arm26.pin_model, arm26_muscles)
    layer = MuscleActuators(arm26.joint_names, arm26_muscles, arm26_geometry, XiaFatigue(LD=10.0, LR=10.0, F=0.01, R=0.002))
    rng = np.random.default_rng(3)
    wrapped = 0
    for _ in range(12):
        q = np.radians([rng.uniform(0, 90), rng.uniform(0, 150)])
        v, a = rng.uniform(-3, 3, 2), rng.uniform(0, 1, 6)
        L = np.asarray(arm26_geometry.lengths(q)).ravel()
        assert np.allclose(numeric.lengths(q), L, rtol=0, atol=1e-12)
        r = np.asarray(arm26_geometry.moment_arms(q))
        assert np.allclose(-numeric.length_gradient(q)[1], r, rtol=0, atol=1e-9)  # finite differences against AD
        tau = np.asarray(layer.torque(q, v, a)).ravel()
        assert np.allclose(numeric.torque(q, v, a), tau, rtol=1e-7, atol=1e-6)
        wrapped += int(np.linalg.norm(L - numeric_unwrapped(arm26, arm26_muscles, q)) > 1e-6)
    assert wrapped >= 3  # poses where the humeral cylinder shapes the triceps' or the brachialis' path


def numeric_unwrapped(arm26, muscles, q):
    return NumericMuscles(arm26.pin_model, muscles.without_wraps()).lengths(q)


def test_verify_re_integrates_a_muscle_run_with_the_numeric_muscles(two_muscle_run):
    _, _, run = two_muscle_run
    report = verify_run(run)
    checks = {c.name: c for c in report.checks}
    # the transcription's RK4 written again with the numeric muscle torque reproduces the nodes
    assert report.rk4_residual < 1e-6
    assert checks["bound torques"].value <= 1e-6 and checks["task joint targets"].value <= 1e-4
    # the small curl's grid (2 RK4 substeps of 0.05 s) is coarse for the muscles: named as such
    assert report.gap_qdot > 1e-3 and any("too coarse for the gap tolerance" in n for n in report.notes)
    assert abs(report.rk4_truncation - max(report.gap_q, report.gap_qdot)) <= 1e-6  # the gaps are the grid's RK4 error


def test_a_run_on_polynomial_paths_is_checked_on_its_own_polynomials(tmp_path):
    from conftest import muscle_curl, two_muscle_file

    from fatigue_pin.io.results import read_run
    from fatigue_pin.io.study import run_study
    from fatigue_pin.muscles.polynomial_paths import PolynomialPaths

    study = muscle_curl(two_muscle_file(tmp_path), **{"actuators.paths": "polynomial", "solver.compile": False})
    out = tmp_path / "poly.h5"
    run_study(study, out=out, name="full/poly")
    run = read_run(out, "full/poly")
    assert run.attrs["muscle_paths"]
    report = verify_run(run)
    # the RK4 written again with the run's polynomials, on numbers, reproduces its nodes ...
    assert report.rk4_residual < 1e-6
    # ... and the report says how far those polynomials are from the exact paths on the motion
    note = next(n for n in report.notes if n.startswith("muscle paths: the run's polynomials"))
    assert "mm in length" in note
    # checked on the exact paths instead, the same nodes are off by more than the polynomials' RK4 residual
    exact = NumericMuscles(study.model().pin_model, study.muscles())
    numeric = NumericMuscles(study.model().pin_model, study.muscles(), PolynomialPaths.polynomials_from_json(run.attrs["muscle_paths"]))
    q = np.asarray(run.q[3], dtype=float)
    assert 1e-9 < np.max(np.abs(exact.lengths(q) - numeric.lengths(q))) < 1e-3


def test_verify_integrates_an_active_muscle_run_with_its_fatigue_states(tmp_path):
    """studies/bioptim_static_arm_xia.toml (the ``active`` coupling: each force from its muscle's
    active fraction, a state) on a small grid: verify's RK4, written again with the rigid body and
    the fatigue states integrated together, reproduces the nodes; read as if the force followed the
    control (``observed``), or with one muscle's stored active fraction changed, it does not. (The
    grid, 2 RK4 steps of 0.04 s, is coarse for the gap tolerances: the shipped one passes them,
    tests/verify/test_verify_studies.py.)"""
    import dataclasses
    from pathlib import Path

    from fatigue_pin.io.results import read_run
    from fatigue_pin.io.study import Study, run_study

    study = Study.from_file(Path(__file__).resolve().parents[2] / "studies" / "bioptim_static_arm_xia.toml")
    out = tmp_path / "arm.h5"
    run_study(study.replace({"task.intervals_per_cycle": 10, "transcription.substeps": 2, "solver.compile": False,
                             "solver.derivative_blocks": True}), out)
    run = read_run(out)
    assert run.attrs["coupling"] == "active" and run.attrs["residual_coupling"] == "observed"
    report = verify_run(run)
    checks = {c.name: c for c in report.checks}
    assert report.rk4_residual < 1e-9 and checks["task frame targets"].passed
    assert report.gap_qdot < 1e-2  # RK4's truncation on this grid, not a wrong torque
    as_observed = verify_run(dataclasses.replace(run, attrs={**run.attrs, "coupling": "observed"}))
    assert as_observed.rk4_residual > 1e-2 and as_observed.gap_qdot > 1e-1  # the activations are not the controls
    fatigue = {k: v.copy() for k, v in run.fatigue.items()}
    fatigue["ma"][4, run.actuator_names.index("BIClong")] += 0.05  # node 4: more of the biceps active than solved
    moved = verify_run(dataclasses.replace(run, fatigue=fatigue))
    assert moved.rk4_residual > 1e-3 and not moved.passed
