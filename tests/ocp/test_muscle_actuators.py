"""Muscles as an actuation kind of the optimal control problems: the same optimum as torque
halves when the muscles are idealised with constant moment arms, and the muscle torque of arm26."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.fatigue.models import XiaFatigue
from fatigue_pin.muscles.geometry import FixedMomentArms
from fatigue_pin.muscles.muscle import Muscle, PathPoint
from fatigue_pin.muscles.muscle_set import MuscleSet
from fatigue_pin.ocp.actuation import Actuation
from fatigue_pin.ocp.muscle_actuators import MuscleActuators
from fatigue_pin.ocp.problem import Problem
from fatigue_pin.ocp.solver import SolverOptions
from fatigue_pin.ocp.transcription import Ocp

ARM, FMAX = 0.02, 2500.0  # 50 N m at full activation: the bundled arm26's torque limits
POINTS = (PathPoint("humerus", (0, 0, 0)), PathPoint("forearm", (0, 0, 0)))


def idealised_pairs(joints: tuple[str, ...]) -> tuple[MuscleSet, FixedMomentArms]:
    """A flexor and an extensor per joint, F = a F_max, moment arms +-ARM: r F_max = 50 N m."""
    muscles, r = [], []
    for j, name in enumerate(joints):
        for sign, side in ((1, "flexor"), (-1, "extensor")):
            muscles.append(Muscle(f"{name}_{side}", POINTS, FMAX, 0.1, 0.2, kind="idealized"))
            row = np.zeros(len(joints))
            row[j] = sign * ARM
            r.append(row)
    return MuscleSet(tuple(muscles)), FixedMomentArms(np.array(r), np.full(len(muscles), 0.3))


def test_idealised_muscles_with_constant_arms_reach_the_torque_halves_optimum(small_problem):
    base = small_problem
    muscles, geometry = idealised_pairs(base.model.joint_names)
    half = base.actuators.halves[0].params
    assert all(h.params == half for h in base.actuators.halves)
    actuators = MuscleActuators(base.model.joint_names, muscles, geometry, half)
    # the halves' torque and torque-rate costs are in (N m)^2, the muscles' in activations^2: the same terms times 50^2
    costs = tuple(dataclasses.replace(t, weight=t.weight * (50.0**2 if t.kind in ("torque", "torque_rate") else 1.0)) for t in base.costs)
    muscle_problem = Problem(base.model, actuators, base.task, costs, base.x_init)
    solver = SolverOptions(compile=False)
    torque = Ocp(base, 1, base_transcription(), solver).solve()
    muscle = Ocp(muscle_problem, 1, base_transcription(), solver).solve()
    assert torque.success and muscle.success
    assert muscle.objective == pytest.approx(torque.objective, rel=1e-6)
    assert np.allclose(muscle.x, torque.x, atol=1e-5)
    # the controls: activations times 50 N m are the halves' torques (flexors plus, extensors minus)
    a = muscle.u
    tau_plus, tau_minus = torque.u[:, :2], torque.u[:, 2:]
    assert np.allclose(50.0 * a[:, 0::2], tau_plus, atol=1e-3) and np.allclose(-50.0 * a[:, 1::2], tau_minus, atol=1e-3)


def base_transcription():
    from fatigue_pin.ocp.transcription import Transcription

    return Transcription(substeps=2)


def test_arm26_muscle_torque_is_moment_arms_times_forces(arm26):
    from fatigue_pin.muscles.files import load_muscles
    from fatigue_pin.muscles.geometry import MuscleGeometry

    muscles = load_muscles("arm26")
    geometry = MuscleGeometry(arm26.pin_model, muscles)
    A = MuscleActuators(arm26.joint_names, muscles, geometry, XiaFatigue(F=0.01, R=0.002, LD=10.0, LR=10.0))
    q, v, a = np.array([0.3, 1.4]), np.array([0.5, -1.0]), np.linspace(0.1, 0.6, 6)
    L, Ld = np.array(geometry.lengths(q)).ravel(), np.array(geometry.speeds(q, v)).ravel()
    F = np.array([m.force(a[i], L[i], Ld[i]) for i, m in enumerate(muscles.muscles)])
    tau = A.joint_torque(a, None, np.r_[q, v])
    assert np.allclose(tau, np.array(geometry.moment_arms(q)).T @ F, atol=1e-12)
    assert A.nu == 6 and A.n_states == 18 and A.state_names[:3] == ("TRIlong_ma", "TRIlong_mr", "TRIlong_mf")


def test_residual_torques_add_to_the_muscles(arm26, arm26_muscles, arm26_geometry):
    from fatigue_pin.ocp.actuators import SignedTorqueActuators

    xia = XiaFatigue(F=0.01, R=0.002, LD=10.0, LR=10.0)
    residuals = SignedTorqueActuators.from_model(arm26, xia)
    A = MuscleActuators(arm26.joint_names, arm26_muscles, arm26_geometry, xia, residuals=residuals)
    alone = MuscleActuators(arm26.joint_names, arm26_muscles, arm26_geometry, xia)
    y = np.array([0.3, 1.4, 0.5, -1.0])
    a, tau_r = np.full(6, 0.3), np.array([4.0, 0.0, 0.0, -7.0])  # (shoulder+, elbow+, shoulder-, elbow-)
    u = np.r_[a, tau_r]
    assert np.allclose(A.joint_torque(u, None, y), alone.joint_torque(a, None, y) + np.array([4.0, -7.0]), atol=1e-12)
    assert A.nu == 10 and A.n_states == 30 and A.half_names[6:] == ("shoulder_plus", "shoulder_minus", "elbow_plus", "elbow_minus")
    lo, hi = A.control_bounds()
    assert np.allclose(lo, [0] * 6 + [0, 0, -50, -50]) and np.allclose(hi, [1] * 6 + [50, 50, 0, 0])
    TL = np.array(A.target_loads(u)).ravel()
    assert np.allclose(TL, np.r_[a, 4.0 / 50, 0.0, 0.0, 7.0 / 50])  # units: muscles, then the halves in half order
    # the guess: activations first, the residuals take what the muscles cannot give
    tau = np.array([[30.0, 60.0]])
    guess = A.controls_for_torques(tau, y[None, :2], y[None, 2:])
    assert np.allclose(A.joint_torque(guess[0], None, y), tau[0], atol=1e-6)
    with pytest.raises(ParameterError, match=r"residual torques with coupling .tl\+mf<=1.*expected the muscles. coupling .active."):
        MuscleActuators(arm26.joint_names, arm26_muscles, arm26_geometry, xia, coupling="active", residuals=residuals)
    # beside muscles of the 'active' coupling, residual torques of the 'observed' one deliver their control
    direct = SignedTorqueActuators.from_model(arm26, xia, Actuation(coupling="observed"))
    B = MuscleActuators(arm26.joint_names, arm26_muscles, arm26_geometry, xia, coupling="active", residuals=direct)
    m = np.tile([0.25, 0.75, 0.0], 10)  # every unit's active fraction 0.25
    muscles_only = MuscleActuators(arm26.joint_names, arm26_muscles, arm26_geometry, xia, coupling="active")
    assert np.allclose(B.joint_torque(u, m, y), muscles_only.joint_torque(a, m[:18], y) + np.array([4.0, -7.0]), atol=1e-12)
    assert B.run_record_attributes()["residual_coupling"] == "observed" and not B.coupling_rows


def test_a_per_joint_torque_term_on_muscles_is_refused(small_problem):
    from fatigue_pin.ocp.costs import torque

    muscles, geometry = idealised_pairs(small_problem.model.joint_names)
    A = MuscleActuators(small_problem.model.joint_names, muscles, geometry, small_problem.actuators.halves[0].params)
    with pytest.raises(ParameterError, match=r"^cost term 'torque': a torque term per joint selects torque halves"):
        Problem(small_problem.model, A, small_problem.task, (torque(1.0, joints=["elbow"]),))


def test_gauss_newton_reaches_the_exact_optimum_with_a_state_dependent_torque(small_problem):
    # the rigid body's second derivatives dropped from the Hessian block of F_rb_active (the muscles'
    # torque inside the RK4 stages): the same KKT point, another path (blocks evaluated by CasADi)
    muscles, geometry = idealised_pairs(small_problem.model.joint_names)
    A = MuscleActuators(small_problem.model.joint_names, muscles, geometry, small_problem.actuators.halves[0].params)
    costs = tuple(dataclasses.replace(t, weight=t.weight * (50.0**2 if t.kind in ("torque", "torque_rate") else 1.0))
                  for t in small_problem.costs)  # as the halves' (first test)
    problem = Problem(small_problem.model, A, small_problem.task, costs, small_problem.x_init)
    exact = Ocp(problem, 1, base_transcription(), SolverOptions(compile=False, derivative_blocks=True)).solve()
    gn_ocp = Ocp(problem, 1, base_transcription(), SolverOptions(compile=False, derivative_blocks=True, hessian="gauss-newton"))
    assert gn_ocp.functions.blocks["F_rb_active"].hess is None
    gn = gn_ocp.solve()
    assert exact.success and gn.success
    assert gn.objective == pytest.approx(exact.objective, rel=1e-6)
    assert np.allclose(gn.x, exact.x, atol=1e-4)
