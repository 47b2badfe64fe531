"""Muscle studies: ``[model] muscles``, ``[actuators] kind = "muscles"``, residual torques and
per-muscle fatigue models, read from a study into the actuation layer (docs/muscles.md)."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import small_curl
from fatigue_pin.core.errors import FatiguePinError
from fatigue_pin.io.study import Study, StudyError
from fatigue_pin.muscles.geometry import MuscleGeometry
from fatigue_pin.ocp.actuators import SignedTorqueActuators
from fatigue_pin.ocp.muscle_actuators import MuscleActuators

#: The small curl driven by the bundled arm26 muscles with +-50 N m residual torques; the torque
#: rate term is per joint (refused with muscles), so the costs are the fatigue and the controls.
MUSCLES = {"model.muscles": "arm26", "actuators.kind": "muscles", "actuators.residuals": 50.0,
           "costs": {"fatigue": 1e3, "torque": 1.0, "posture": {"weight": 1e5, "joints": ["shoulder"]}}}


def muscle_study(**changes) -> Study:
    return small_curl("full").replace({**MUSCLES, **changes})


def test_a_muscle_study_builds_the_layer_a_python_user_would(arm26, arm26_muscles):
    study = muscle_study()
    layer = study.actuators(arm26)
    assert isinstance(layer, MuscleActuators) and layer.n_muscles == 6
    assert layer.half_names == (*arm26_muscles.names, "shoulder_plus", "shoulder_minus", "elbow_plus", "elbow_minus")
    xia = study.fatigue_spec(arm26)
    by_hand = MuscleActuators(arm26.joint_names, arm26_muscles, MuscleGeometry(arm26.pin_model, arm26_muscles), xia,
                              residuals=SignedTorqueActuators.from_limits(arm26.joint_names, -50 * np.ones(2), 50 * np.ones(2),
                                                                          xia.with_(F=0.0, R=0.0)))
    assert layer.structure_key() == by_hand.structure_key()  # muscles, paths, fatigue models, coupling, residuals
    assert np.array_equal(layer.control_bounds()[1], np.r_[np.ones(6), 50.0, 50.0, 0.0, 0.0])
    residual = [u.params for u in layer.halves[6:]]
    assert all(p.F == 0.0 and p.R == 0.0 for p in residual)  # they do not tire by default
    assert all(u.params == xia for u in layer.halves[:6])
    tired = muscle_study(**{"actuators.residual_fatigue": True}).actuators(arm26)
    assert all(u.params == xia for u in tired.halves)
    assert muscle_study(**{"actuators.residuals": 0.0}).actuators(arm26).half_names == arm26_muscles.names
    back = Study.from_toml(study.to_toml())
    assert back == study and back.data["model"]["muscles"] == "arm26"


def test_fatigue_models_per_muscle_and_per_group(arm26):
    study = muscle_study(**{"fatigue.muscles": {"elbow_flexors": {"F": 0.2}, "BRA": {"F": 0.3, "R": 0.01}}})
    params = {u.name: u.params for u in study.actuators(arm26).halves}
    assert params["BIClong"].F == params["BICshort"].F == 0.2  # the group's
    assert (params["BRA"].F, params["BRA"].R) == (0.3, 0.01)  # its own table wins over its group's
    assert params["TRIlong"].F == 0.456 and params["BRA"].LD == 10.0  # the rest from [fatigue]


@pytest.mark.parametrize("changes, message", [
    ({"model.muscles": ""}, "the model has no muscles; expected [model] muscles"),
    ({"model.muscles": "no/such.muscles.toml"}, "model.muscles = 'no/such.muscles.toml': muscle file 'no/such.muscles.toml' does not exist"),
    ({"model.muscles": "ur5"}, "bundled muscle file 'ur5' not found"),
    ({"fatigue.muscles": {"DELT1": {"F": 0.1}}}, "fatigue.muscles.DELT1: 'DELT1' is neither a muscle nor a group"),
    ({"fatigue.joints": {"elbow": {"F": 0.1}}}, "fatigue.joints: with muscles, per-joint fatigue models are those of the residual"),
])
def test_bad_muscle_studies_say_what_was_expected(arm26, changes, message):
    with pytest.raises(StudyError) as info:
        muscle_study(**changes).actuators(arm26)
    assert message in str(info.value) and "\n" not in str(info.value)


@pytest.mark.parametrize("term, message", [
    ("activation", "cost term 'activation': an activation term needs muscles"),
    ("residual", "cost term 'residual': a residual term needs residual torques beside muscles"),
])
def test_muscle_cost_terms_need_muscles(arm26, term, message):
    with pytest.raises(FatiguePinError, match=message):
        small_curl("full").replace({f"costs.{term}": 1.0}).problem(arm26)
    if term == "residual":  # muscles without residual torques
        with pytest.raises(FatiguePinError, match=message):
            muscle_study(**{"actuators.residuals": 0.0, "costs.residual": 1.0}).problem(arm26)


def test_muscle_keys_that_need_muscles_are_refused_on_torque_halves(arm26):
    with pytest.raises(StudyError, match=r"actuators.residuals = 50: residual torques go beside muscles; expected kind = 'muscles'"):
        small_curl("full").replace({"actuators.residuals": 50.0})
    with pytest.raises(StudyError, match="fatigue.muscles: per-muscle fatigue models need muscles"):
        small_curl("full").replace({"fatigue.muscles": {"BRA": {"F": 0.1}}}).actuators(arm26)
    with pytest.raises(StudyError, match=r"actuators.kind = 'pistons': expected one of \['torque', 'muscles', 'motors'\]"):
        small_curl("full").replace({"actuators.kind": "pistons"})


def test_the_exhaustion_study_is_the_sliding_one_with_weak_residuals(arm26):
    """studies/curl_muscles_exhaustion.toml differs from curl_muscles_sliding.toml only in its
    name, its residual bound (5 N m, which the run to exhaustion rests on: docs/muscles.md), its
    cycle cap and its end rule (the exact finish of stalled windows, IPOPT's acceptable objective
    change 1e-8); its residual halves are bounded at 5 N m and do not tire."""
    from pathlib import Path

    studies = Path(__file__).resolve().parents[2] / "studies"
    sliding = Study.from_file(studies / "curl_muscles_sliding.toml")
    exhaustion = Study.from_file(studies / "curl_muscles_exhaustion.toml")
    assert exhaustion.data["horizon"]["exact_finish"] is True
    back = exhaustion.replace({"name": sliding.data["name"], "actuators.residuals": 50.0,
                               "horizon.max_cycles": sliding.data["horizon"]["max_cycles"],
                               "solver.ipopt.acceptable_obj_change_tol": 1e-9,
                               "horizon.exact_finish": sliding.data["horizon"]["exact_finish"],
                               "horizon.exact_finish_iterations": sliding.data["horizon"]["exact_finish_iterations"]}).data
    assert back == sliding.data
    assert exhaustion.data["horizon"]["max_cycles"] > 30
    layer = exhaustion.replace({"actuators.paths": "exact"}).actuators(arm26)  # no fit of the paths: a short test
    assert np.array_equal(layer.control_bounds()[1], np.r_[np.ones(6), 5.0, 5.0, 0.0, 0.0])
    assert all(u.params.F == 0.0 and u.params.R == 0.0 for u in layer.halves[6:])
