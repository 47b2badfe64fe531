"""Muscle paths on arm26: against OpenSim 4.6's own lengths and moment arms (a table computed by
experiments/opensim_arm26_geometry.py), and moment arms and torques against finite differences."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from fatigue_pin.core.errors import ModelError, ParameterError
from fatigue_pin.muscles.geometry import MuscleGeometry
from fatigue_pin.muscles.muscle import PathPoint
from fatigue_pin.muscles.muscle_set import MuscleSet
from conftest import opensim_geometry_rows as opensim_rows


@pytest.mark.parametrize("wraps, tol_length, tol_arm", [("none", 1e-6, 1e-6), ("TRI", 5e-4, 5e-4)])
def test_lengths_and_moment_arms_match_opensim(arm26_geometry, arm26_geometry_unwrapped, wraps, tol_length, tol_arm):
    geometry = arm26_geometry if wraps == "TRI" else arm26_geometry_unwrapped
    names = list(geometry.muscles.names)
    rows = opensim_rows(wraps)
    assert len(rows) == 7 * 14 * 6
    worst = {"length": 0.0, "shoulder": 0.0, "elbow": 0.0}
    for r in rows:
        q = np.radians([float(r["shoulder_deg"]), float(r["elbow_deg"])])
        i = names.index(r["muscle"])
        L = float(geometry.lengths(q)[i])
        arm = np.array(geometry.moment_arms(q))[i]
        worst["length"] = max(worst["length"], abs(L - float(r["length_m"])))
        worst["shoulder"] = max(worst["shoulder"], abs(arm[0] - float(r["moment_arm_shoulder_m"])))
        worst["elbow"] = max(worst["elbow"], abs(arm[1] - float(r["moment_arm_elbow_m"])))
    assert worst["length"] < tol_length, worst
    assert worst["elbow"] < tol_arm, worst
    assert worst["shoulder"] < tol_arm, worst


def test_moment_arms_are_minus_the_length_derivative(arm26_geometry):
    rng = np.random.default_rng(3)
    h = 1e-6
    for q in rng.uniform([0.0, 0.0], [1.6, 2.3], size=(5, 2)):
        arms = np.array(arm26_geometry.moment_arms(q))
        for j in range(2):
            dq = np.zeros(2)
            dq[j] = h
            fd = -(np.array(arm26_geometry.lengths(q + dq)) - np.array(arm26_geometry.lengths(q - dq))).ravel() / (2 * h)
            assert np.allclose(arms[:, j], fd, atol=1e-8)


def test_joint_torque_is_the_sum_of_moment_arm_times_force(arm26_geometry):
    # virtual work: the torque on joint j is -sum_i F_i dL_i/dq_j, the lengths differenced numerically
    import casadi as ca

    q, F = np.array([0.4, 1.9]), np.array([120.0, 40.0, 60.0, 300.0, 210.0, 450.0])
    tau = np.array(arm26_geometry.joint_torque(ca.DM(q), ca.DM(F))).ravel()
    h = 1e-6
    for j in range(2):
        dq = np.zeros(2)
        dq[j] = h
        dL = (np.array(arm26_geometry.lengths(q + dq)) - np.array(arm26_geometry.lengths(q - dq))).ravel() / (2 * h)
        assert tau[j] == pytest.approx(-F @ dL, abs=1e-7)


def test_lengthening_speed_follows_the_path(arm26_geometry):
    q, v, h = np.array([0.3, 1.2]), np.array([0.8, -2.0]), 1e-6
    fd = (np.array(arm26_geometry.lengths(q + h * v)) - np.array(arm26_geometry.lengths(q - h * v))).ravel() / (2 * h)
    assert np.allclose(np.array(arm26_geometry.speeds(q, v)).ravel(), fd, atol=1e-8)


def test_a_point_on_an_unknown_link_is_named(arm26, arm26_muscles):
    bra = arm26_muscles.muscles[-1]
    bad = dataclasses.replace(bra, points=(PathPoint("scapula", (0, 0, 0)), bra.points[1]), wraps=())
    with pytest.raises(ModelError, match=r"^muscle 'BRA' has a path point on 'scapula'.*its links are \['world', 'thorax'"):
        MuscleGeometry(arm26.pin_model, MuscleSet((bad,)))


def test_a_muscle_that_crosses_no_joint_is_named(arm26, arm26_muscles):
    bra = arm26_muscles.muscles[-1]
    bad = dataclasses.replace(bra, points=(bra.points[0], PathPoint("humerus", (0.01, -0.25, 0.0))), wraps=())
    with pytest.raises(ParameterError, match=r"^muscle 'BRA' crosses no joint: its points are all on \['humerus'\]"):
        MuscleGeometry(arm26.pin_model, MuscleSet((bad,)))
