"""The analytic cylinder wrap against closed forms and a numerical shortest path (scipy)."""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest
from scipy.optimize import minimize

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.muscles.wraps import CylinderWrap, WrapUse, euler_xyz, wrapped_length

P, S = ca.SX.sym("P", 3), ca.SX.sym("S", 3)
LENGTH = ca.Function("L", [P, S], [wrapped_length(P, S, 0.016)])


def length(p, s):
    return float(LENGTH(np.asarray(p, float), np.asarray(s, float)))


def shortest_round_circle(p, s, r):
    """The shortest path from p to s (2-D) made of a straight segment to a point a of the circle,
    the arc to a point b and a straight segment to s, neither segment entering the disc
    (``p . a >= r^2``, ``s . b >= r^2``): minimised over the angles of a and b (SLSQP), either
    way round."""
    p, s = np.asarray(p, float), np.asarray(s, float)
    on = lambda phi: r * np.array([math.cos(phi), math.sin(phi)])  # noqa: E731

    def total(phi, way):
        arc = (way * (phi[1] - phi[0])) % (2 * math.pi)
        return np.linalg.norm(on(phi[0]) - p) + r * arc + np.linalg.norm(s - on(phi[1]))

    outside = [{"type": "ineq", "fun": lambda phi: (p @ on(phi[0]) - r * r) / r},
               {"type": "ineq", "fun": lambda phi: (s @ on(phi[1]) - r * r) / r}]
    best = math.inf
    for way in (1, -1):
        for start in np.linspace(0, 2 * math.pi, 6, endpoint=False):
            for gap in (0.5,):
                res = minimize(total, [start, start + way * gap], args=(way,), method="SLSQP", constraints=outside,
                               options={"ftol": 1e-15, "maxiter": 500})
                if res.success and all(c["fun"](res.x) > -1e-10 for c in outside):
                    best = min(best, res.fun)
    return best


def test_a_segment_through_the_axis_goes_half_round():
    d, r = 0.05, 0.016
    expected = 2 * math.sqrt(d * d - r * r) + r * (math.pi - 2 * math.acos(r / d))
    assert length([d, 0, 0], [-d, 0, 0]) == pytest.approx(expected, rel=1e-12)


def test_a_segment_that_misses_the_cylinder_is_straight():
    p, s = [0.03, 0.02, -0.01], [-0.03, 0.025, 0.02]  # passes 2 cm from the axis
    assert length(p, s) == pytest.approx(np.linalg.norm(np.subtract(s, p)), rel=1e-14)
    p, s = [0.03, 0.0, 0.0], [0.05, 0.001, 0.0]  # beside the cylinder, the closest point at an end
    assert length(p, s) == pytest.approx(np.linalg.norm(np.subtract(s, p)), rel=1e-14)


@pytest.mark.parametrize("seed", range(4))
def test_wrapped_length_is_the_shortest_path_round_the_cylinder(seed):
    rng = np.random.default_rng(seed)
    r = 0.016
    while True:  # a segment that enters the circle, both ends outside
        a, b = rng.uniform(0, 2 * math.pi, 2)
        p = rng.uniform(0.02, 0.08) * np.array([math.cos(a), math.sin(a)])
        s = rng.uniform(0.02, 0.08) * np.array([math.cos(b), math.sin(b)])
        t = -p @ (s - p) / ((s - p) @ (s - p))
        if 0 < t < 1 and np.linalg.norm(p + t * (s - p)) < 0.8 * r:
            break
    zp, zs = rng.uniform(-0.03, 0.03, 2)
    plane = shortest_round_circle(p, s, r)
    expected = math.sqrt(plane ** 2 + (zs - zp) ** 2)  # unrolled: a straight line on the developed surface
    assert length([*p, zp], [*s, zs]) == pytest.approx(expected, abs=1e-9)
    assert length([*p, zp], [*s, zs]) > np.linalg.norm(np.r_[s - p, zs - zp])


def test_the_length_is_smooth_at_the_onset_of_wrapping():
    # the segment slides across the cylinder: at the onset the straight and wrapped lengths meet
    # with the same slope (C1), so a finite difference sees no kink
    r = 0.016
    ys = np.linspace(r - 0.004, r + 0.004, 801)
    L = np.array([length([0.05, y, 0.0], [-0.05, y, 0.01]) for y in ys])
    slope = np.diff(L) / np.diff(ys)
    assert np.max(np.abs(np.diff(slope))) < 20 * np.median(np.abs(np.diff(slope))) + 1e-6
    assert np.all(np.isfinite(slope))


def test_euler_angles_are_body_fixed_xyz():
    a, b, c = 0.3, -0.2, 1.1
    R = euler_xyz((a, b, c))
    # body-fixed X-Y-Z = rotations about the moving axes: the same as fixed-axis rotations Z, then Y, then X
    from scipy.spatial.transform import Rotation

    assert np.allclose(R, Rotation.from_euler("XYZ", [a, b, c]).as_matrix(), atol=1e-14)


@pytest.mark.parametrize("radius", [0.0, -0.01, float("nan"), "wide"])
def test_a_bad_radius_is_named(radius):
    with pytest.raises(ParameterError, match=r"wrap 'TRI' radius = .*expected a cylinder radius > 0"):
        CylinderWrap("TRI", "humerus", (0, 0, 0), (0, 0, 0), radius)


def test_a_fixed_turn_keeps_its_side_through_the_axis():
    # the segment sweeps through the axis: "either" flips sides there (the slope jumps), a fixed
    # turn keeps going round the same way, its length C1, and equals "either" while on its side
    r = 0.016
    P, S = ca.SX.sym("P", 3), ca.SX.sym("S", 3)
    either = ca.Function("e", [P, S], [wrapped_length(P, S, r)])
    fixed = ca.Function("f", [P, S], [wrapped_length(P, S, r, "positive")])
    ys = np.linspace(-0.01, 0.01, 401)
    Le = np.array([float(either([0.05, y, 0.0], [-0.05, 0.0, 0.01])) for y in ys])
    Lf = np.array([float(fixed([0.05, y, 0.0], [-0.05, 0.0, 0.01])) for y in ys])
    se, sf = np.diff(Le) / np.diff(ys), np.diff(Lf) / np.diff(ys)
    assert np.max(np.abs(np.diff(se))) > 0.5  # the kink where "either" changes sides
    assert np.max(np.abs(np.diff(sf))) < 0.02
    positive_side = ys > 1e-3  # cross(p, s) = 0.05 y > 0 there: the positive turn is the side the segment passes
    assert np.allclose(Le[positive_side], Lf[positive_side], atol=1e-15)
    assert np.all(Lf[ys < -1e-3] > Le[ys < -1e-3])


def test_a_bad_turn_is_named():
    with pytest.raises(ParameterError, match=r"wrap 'TRI' turn = 'left': expected one of \['either', 'positive', 'negative'\]"):
        WrapUse("TRI", "left")
