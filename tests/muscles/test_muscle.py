"""Muscle forces: the rigid-tendon De Groote-Fregly unit and the idealised one, and what arm26's
muscles can do (against the figures computed with Moco's curves, docs/muscles.md)."""

from __future__ import annotations

import dataclasses
import math

import casadi as ca
import numpy as np
import pytest

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.muscles import curves
from fatigue_pin.muscles.muscle import Muscle, PathPoint

POINTS = (PathPoint("humerus", (0, 0, 0)), PathPoint("forearm", (0, 0, 0)))


def unit(**kw) -> Muscle:
    base = dict(name="m", points=POINTS, max_force=500.0, optimal_length=0.1, tendon_slack_length=0.2)
    return Muscle(**(base | kw))


def test_at_optimal_length_and_rest_the_force_is_activation_times_max_plus_passive():
    m = unit()
    F = m.force(0.7, 0.3, 0.0)
    assert F == pytest.approx(500.0 * (0.7 + curves.passive_force_length(1.0)), rel=1e-12)


def test_pennation_keeps_the_fibre_width_and_projects_the_force():
    m = unit(pennation=0.3)
    L = 0.2 + 0.1 * math.cos(0.3)  # the fibre at its optimal length, at the optimal pennation angle
    l, v, cos = m.fibre(L, 0.05)
    assert l == pytest.approx(1.0, rel=1e-12) and cos == pytest.approx(math.cos(0.3), rel=1e-12)
    assert v == pytest.approx(0.05 * math.cos(0.3) / (10 * 0.1), rel=1e-12)
    expected = 500 * (curves.force_velocity(v) + curves.passive_force_length(1.0)) * math.cos(0.3)
    assert m.force(1.0, L, 0.05) == pytest.approx(expected, rel=1e-12)


def test_shortening_at_max_velocity_gives_no_active_force():
    m = unit()
    assert m.force(1.0, 0.3, -10 * 0.1) == pytest.approx(500.0 * curves.passive_force_length(1.0), abs=1e-9)


def test_idealized_force_is_activation_times_max_force():
    m = unit(kind="idealized")
    assert m.force(0.25, 0.9, -3.0) == 125.0
    a = ca.SX.sym("a")
    assert float(ca.Function("f", [a], [m.force(a, 0.3, 0.0)])(0.5)) == 250.0


def test_arm26_flexors_and_extensors_at_the_elbow(arm26_geometry, arm26_muscles):
    # maximal active isometric moments, shoulder 0 (docs/muscles.md): extensors as computed with
    # OpenSim's geometry and Moco's curves; flexors within 3 N m of those, the biceps long head
    # lacking the humeral-head ellipsoid that lengthens it by about 3 mm in OpenSim
    def moments(elbow_deg):
        q = np.array([0.0, math.radians(elbow_deg)])
        L, r = np.array(arm26_geometry.lengths(q)).ravel(), np.array(arm26_geometry.moment_arms(q))[:, 1]
        active = []
        for m, Li in zip(arm26_muscles.muscles, L):
            l, _, cos = m.fibre(Li, 0.0)
            active.append(m.max_force * curves.active_force_length(l) * cos)
        t = r * np.array(active)
        return t[3:].sum(), t[:3].sum()

    for elbow, extensors, flexors in ((0, -23.2, 21.4), (40, -38.2, 42.2), (90, -32.7, 63.0), (130, -30.3, 15.4)):
        flex, ext = moments(elbow)
        assert ext == pytest.approx(extensors, abs=0.15)
        assert flex == pytest.approx(flexors, abs=3.0)


@pytest.mark.parametrize("key, value, message", [
    ("max_force", -5.0, r"muscle 'm': max_force = -5\.0: expected a force > 0 \(N\)"),
    ("max_force", 0, r"muscle 'm': max_force = 0: expected a force > 0 \(N\)"),
    ("optimal_length", 0.0, r"muscle 'm': optimal_length = 0\.0: expected a fibre length > 0 \(m\)"),
    ("pennation", 2.0, r"muscle 'm': pennation = 2\.0: expected an angle in \[0, pi/2\) \(rad\)"),
    ("kind", "thelen", r"muscle 'm': kind = 'thelen': expected one of \['degroote', 'idealized'\]"),
    ("points", POINTS[:1], r"muscle 'm': 1 path points: expected an origin and an insertion at least"),
])
def test_bad_muscle_parameters_are_named(key, value, message):
    with pytest.raises(ParameterError, match="^" + message):
        unit(**{key: value})


def test_a_replaced_muscle_is_checked_again():
    with pytest.raises(ParameterError, match="max_force"):
        dataclasses.replace(unit(), max_force=float("nan"))
