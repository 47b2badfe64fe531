"""Polynomial muscle paths: a polynomial geometry is recovered exactly, arm26's fits stay within
their tolerance of the exact paths on poses the fit never saw, the moment arms are the
polynomials' own derivatives, and the stored form rebuilds the same functions."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from fatigue_pin.core.errors import ParameterError, StudyError
from fatigue_pin.muscles.polynomial_paths import PathPolynomial, PolynomialPaths

from conftest import muscle_curl


@pytest.fixture(scope="module")
def arm26_polynomials(arm26_geometry):
    """arm26's six muscles fitted with the default tolerance (1e-4 m) over the joints' ranges."""
    return PolynomialPaths(arm26_geometry)


class PolynomialGeometry:
    """A geometry whose lengths are known polynomials of the elbow (the muscles of arm26)."""

    def __init__(self, geometry, coefficients):
        self.model, self.muscles = geometry.model, geometry.muscles
        q = ca.SX.sym("q", 2)
        L = ca.vertcat(*[sum(c * q[1] ** k for k, c in enumerate(row)) for row in coefficients])
        self.lengths = ca.Function("muscle_lengths", [q], [L])
        self.moment_arms = ca.Function("muscle_moment_arms", [q], [-ca.jacobian(L, q)])


def test_a_geometry_that_is_a_polynomial_is_recovered_to_its_rounding(arm26_geometry):
    rng = np.random.default_rng(0)
    coefficients = rng.uniform(-0.02, 0.02, size=(6, 4))
    coefficients[:, 0] += 0.3
    exact = PolynomialGeometry(arm26_geometry, coefficients)
    fitted = PolynomialPaths(exact, tolerance=1e-9, max_order=6)
    q = np.c_[rng.uniform(-1, 3, 50), rng.uniform(0, 3, 50)]
    dL, dr = fitted.errors_along(q, exact)
    assert dL < 1e-9 and dr < 1e-8  # the coefficients are rounded to 1e-10 m
    # the biceps cross both joints; their fit takes the order of the elbow polynomial (3) all the same
    assert all(p.order <= 3 for p in fitted.polynomials)


def test_crossed_coordinates_follow_the_kinematic_tree(arm26_polynomials):
    crossed = {p.muscle: p.joints for p in arm26_polynomials.polynomials}
    assert crossed == {"TRIlong": (0, 1), "TRIlat": (1,), "TRImed": (1,), "BIClong": (0, 1), "BICshort": (0, 1), "BRA": (1,)}


def test_arm26_fits_hold_on_poses_the_fit_never_saw(arm26_geometry, arm26_polynomials):
    model = arm26_geometry.model
    rng = np.random.default_rng(7)
    q = rng.uniform(model.lowerPositionLimit, model.upperPositionLimit, size=(400, 2))
    n = q.shape[0]
    dL = np.array(arm26_polynomials.lengths.map(n)(q.T)) - np.array(arm26_geometry.lengths.map(n)(q.T))
    dr = np.array(arm26_polynomials.moment_arms.map(n)(q.T)) - np.array(arm26_geometry.moment_arms.map(n)(q.T))
    tol = arm26_polynomials.tolerance
    assert np.sqrt(np.mean(dL**2, axis=1)).max() < 1.5 * tol
    assert np.sqrt(np.mean(dr**2, axis=1)).max() < 1.5 * tol
    # over the curl's range the moment arms are within half a millimetre everywhere
    curl = np.c_[rng.uniform(0.0, 1.6, 400), rng.uniform(0.2, 2.7, 400)]
    assert arm26_polynomials.errors_along(curl, arm26_geometry)[1] < 5e-4


def test_moment_arms_and_speeds_are_the_polynomials_own_derivatives(arm26_polynomials):
    rng = np.random.default_rng(3)
    h = 1e-6
    for q in rng.uniform([0.0, 0.0], [1.6, 2.6], size=(4, 2)):
        arms = np.array(arm26_polynomials.moment_arms(q))
        v = rng.normal(size=2)
        assert np.allclose(np.array(arm26_polynomials.speeds(q, v)).ravel(), -arms @ v, atol=1e-14)
        for j in range(2):
            dq = np.zeros(2)
            dq[j] = h
            fd = -(np.array(arm26_polynomials.lengths(q + dq)) - np.array(arm26_polynomials.lengths(q - dq))).ravel() / (2 * h)
            assert np.allclose(arms[:, j], fd, atol=1e-8)
        # the numeric evaluation (numpy, what verify uses) equals the SX expression
        assert np.allclose(arm26_polynomials.numeric_lengths(q), np.array(arm26_polynomials.lengths(q)).ravel(), atol=1e-14)


def test_the_stored_form_rebuilds_the_same_paths(arm26_geometry, arm26_polynomials):
    stored = PolynomialPaths.polynomials_from_json(arm26_polynomials.to_json())
    assert all(isinstance(p, PathPolynomial) for p in stored)
    again = PolynomialPaths.from_polynomials(stored, arm26_geometry.muscles, arm26_geometry.model)
    q = np.array([0.4, 1.9])
    assert np.array_equal(np.array(again.lengths(q)), np.array(arm26_polynomials.lengths(q)))
    with pytest.raises(ParameterError, match="expected one per muscle"):
        PolynomialPaths.from_polynomials(stored[:-1], arm26_geometry.muscles, arm26_geometry.model)


def test_a_tolerance_no_order_reaches_is_refused_in_one_line(arm26_geometry):
    with pytest.raises(ParameterError) as err:
        PolynomialPaths(arm26_geometry, tolerance=1e-7, max_order=3)
    message = str(err.value)
    assert "\n" not in message and "muscle 'TRIlong'" in message and "expected both <= 1e-07" in message


@pytest.mark.parametrize("lower, upper, match", [([0.0, 0.0], [np.inf, 2.0], "joint 'r_shoulder_elev'|joint '.*' has the range"),
                                                 ([1.0, 0.0], [0.5, 2.0], "expected finite position limits, lower < upper")])
def test_a_range_that_is_not_finite_and_increasing_is_refused(arm26_geometry, lower, upper, match):
    with pytest.raises(ParameterError, match=match):
        PolynomialPaths(arm26_geometry, lower, upper)


def test_a_study_builds_its_muscles_on_polynomial_paths():
    study = muscle_curl(**{"actuators.paths": "polynomial", "actuators.path_tolerance": 3e-4})
    layer = study.actuators(study.model())
    assert isinstance(layer.geometry, PolynomialPaths) and layer.geometry.tolerance == 3e-4
    assert "muscle_paths" in layer.run_record_attributes()
    with pytest.raises(StudyError, match="actuators.paths = 'polynomial': polynomial paths are muscle paths"):
        muscle_curl().replace({"model.muscles": "", "actuators.kind": "torque", "actuators.residuals": 0.0,
                               "actuators.paths": "polynomial", "costs": {"torque": 1.0}})


def test_the_fit_does_not_follow_the_blas_threads(tmp_path):
    """The coefficients (and so the compiled-code cache key) are the same with 1 and 2 BLAS
    threads: without the ridge and the rounding, TRIlong's order-13 fit changed with them."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    import fatigue_pin

    home = str(Path(fatigue_pin.__file__).resolve().parents[1])  # the package these tests import
    code = ("import hashlib; from fatigue_pin import load_model, load_muscles, MuscleGeometry; "
            "from fatigue_pin.muscles.polynomial_paths import PolynomialPaths; m = load_model(); "
            "print(hashlib.sha1(PolynomialPaths(MuscleGeometry(m.pin_model, load_muscles('arm26'))).lengths.serialize().encode()).hexdigest())")
    keys = set()
    for n in (1, 2):
        env = {**os.environ, "OPENBLAS_NUM_THREADS": str(n), "OMP_NUM_THREADS": str(n),
               "PYTHONPATH": home + os.pathsep + os.environ.get("PYTHONPATH", "")}
        done = subprocess.run([sys.executable, "-c", code], env=env, cwd=tmp_path, capture_output=True, text=True)
        assert done.returncode == 0, done.stderr
        keys.add(done.stdout.strip())
    assert len(keys) == 1
