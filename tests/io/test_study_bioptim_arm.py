"""studies/bioptim_static_arm_xia.toml, the port of bioptim's muscle fatigue example (docs/porting.md,
"The static arm"): the model, the muscles and their coupling it builds, and a small solve that
reaches the optimum of its grid and meets the end target."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fatigue_pin.io.results import read_run
from fatigue_pin.io.study import Study, run_study
from fatigue_pin.ocp.muscle_actuators import MuscleActuators
from fatigue_pin.robot.kinematics import frame_placement

STUDY = Path(__file__).resolve().parents[2] / "studies" / "bioptim_static_arm_xia.toml"
#: bioptim's F_max (N) of arm26_constant's six idealised muscles
F_MAX = {"TRIlong": 798.52, "TRIlat": 624.3, "TRImed": 624.3, "BIClong": 624.3, "BICshort": 435.56, "BRA": 987.26}
#: a small grid, uncompiled (the study's Gauss-Newton Hessian from the derivative blocks): 10 intervals
#: of 0.08 s with 2 RK4 steps
SMALL = {"task.intervals_per_cycle": 10, "transcription.substeps": 2, "solver.compile": False, "solver.derivative_blocks": True}
#: the optimum of that grid (bioptim's 50 intervals: 17.2888; the study's 50 x 2 steps: 17.2856)
OPTIMUM_10 = 17.16405


@pytest.fixture(scope="module")
def study() -> Study:
    return Study.from_file(STUDY)


def test_the_study_builds_bioptims_arm(study):
    assert Study.from_toml(study.to_toml()) == study
    assert study.data["task"]["targets"][0]["axes"] == ["x", "z"]  # bioptim's X and Y, in the z-up world
    model = study.model()
    assert model.joint_names == ("shoulder", "elbow") and model.payload.mass == 3.0
    # bioptim's holding torques of arm26_constant at the start and at its optimum's end (N m)
    np.testing.assert_allclose(model.gravity_torque(np.array([0.07, 1.4])), [12.79, 11.37], atol=0.01)
    np.testing.assert_allclose(model.gravity_torque(np.array([1.644707, 2.250332])), [9.31, -6.82], atol=0.01)
    layer = study.actuators(model)
    assert isinstance(layer, MuscleActuators) and layer.coupling_kind == "active" and not layer.coupling_rows
    muscles = {m.name: m for m in layer.muscles.muscles}
    assert {n: m.max_force for n, m in muscles.items()} == F_MAX
    assert all(m.kind == "idealized" and not m.wraps for m in muscles.values()) and not layer.muscles.wraps
    # an idealised force is a F_max, whatever the length and speed
    assert float(muscles["BRA"].force(0.3, 0.05, -1.0)) == pytest.approx(0.3 * 987.26)
    assert all((u.params.F, u.params.R, u.params.LD, u.params.LR) == (0.01, 0.002, 10.0, 10.0) for u in layer.halves[:6])
    residual = layer.residuals
    assert residual.coupling_kind == "observed" and all(h.params.F == 0.0 for h in residual.halves)
    np.testing.assert_allclose(layer.control_bounds()[1], np.r_[np.ones(6), 10.0, 10.0, 0.0, 0.0])
    # bioptim's moment arms at its start (-dl/dq, m): BIClong, BRA (its table, to 1e-5 m)
    r = np.asarray(layer.geometry.moment_arms(np.array([0.07, 1.4])))
    names = list(muscles)
    np.testing.assert_allclose(r[names.index("BIClong")], [0.01691, 0.04696], atol=1e-5)
    np.testing.assert_allclose(r[names.index("BRA")], [0.0, 0.02120], atol=1e-5)


def test_the_muscles_force_follows_their_active_fraction_and_the_residuals_their_control(study):
    model = study.model()
    layer = study.actuators(model)
    u = np.r_[np.ones(6), 2.0, 0.0, 0.0, -3.0]  # every TL at 1, residuals (2, -3) N m
    m = np.tile([0.0, 1.0, 0.0], 10)  # rested: no muscle force yet
    y = np.r_[0.07, 1.4, 0.0, 0.0]
    np.testing.assert_allclose(layer.joint_torque(u, m, y), [2.0, -3.0], atol=1e-12)


def test_a_small_solve_reaches_its_optimum_and_the_target(study, tmp_path):
    """10 intervals, uncompiled: the optimum of that grid, the end on bioptim's target in its X and Y
    (world x and z), off it in z by about bioptim's 0.0296 m."""
    out = tmp_path / "arm.h5"
    result = run_study(study.replace(SMALL), out)
    assert result.converged
    run = read_run(out)
    terms = dict(zip(run.cost_terms, run.cycle_costs.sum(axis=0)))
    assert result.objective == pytest.approx(OPTIMUM_10, rel=1e-3)
    assert set(terms) == {"residual", "activation", "fatigue", "markers"}
    hand = frame_placement(study.model().pin_model, "forearm_com", run.q[-1]).translation
    np.testing.assert_allclose(hand[[0, 2]], [0.15, 0.15], atol=1e-6)
    assert hand[1] - (-0.17) == pytest.approx(0.0296, abs=1e-3)
    assert terms["markers"] == pytest.approx(0.01 * 0.0296**2, rel=0.05)
