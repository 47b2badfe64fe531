"""Motor studies: ``[actuators] kind = "motors"`` and the ``[motors]`` table (motors/study_table.py),
their runs stored and checked by verify (the temperatures re-integrated, the torques signed)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from conftest import small_curl
from fatigue_pin.io.study import Study, StudyError
from fatigue_pin.motors.presets import ROBOT_MOTORS, motor_preset
from fatigue_pin.ocp.motor_actuators import MotorActuators


def motor_curl(**motors) -> Study:
    """The small curl (one cycle) driven by maxon RE 40 motors through a gear of 20."""
    return small_curl("full").replace({"actuators.kind": "motors", "horizon.cycles": 1,
                                        "motors": {"preset": "maxon-re40", "gear_ratio": 20.0, **motors}})


def test_the_model_names_its_stand_ins_and_a_joint_table_wins(arm26):
    ur5 = Study.from_file(__import__("pathlib").Path(__file__).resolve().parents[2] / "studies" / "ur5_motors_lift.toml")
    layer = ur5.problem().actuators
    assert isinstance(layer, MotorActuators) and layer.half_names == ur5.model().joint_names
    want = [dataclasses.replace(motor_preset(p), T_ambient=35.0, margin=10.0) for p in ROBOT_MOTORS["ur5"]]
    assert [u.motor for u in layer.halves] == want
    # the study's own table: every motor's fields, then a joint's own preset and fields
    study = motor_curl(joints={"elbow": {"preset": "maxon-re30", "gear_ratio": 50.0}})
    shoulder, elbow = study.actuators(arm26).halves
    assert shoulder.motor == motor_preset("maxon-re40", gear_ratio=20.0)
    assert elbow.motor == motor_preset("maxon-re30", gear_ratio=50.0)
    # a passive joint gets no motor; the table round-trips through TOML
    passive = motor_curl().replace({"actuators.passive": ["shoulder"]})
    assert passive.actuators(arm26).half_names == ("elbow",)
    again = Study.from_toml(study.to_toml())
    assert again.data == study.data and again.data["motors"]["joints"]["elbow"]["preset"] == "maxon-re30"


def test_motor_tables_are_refused_where_they_do_not_apply(arm26):
    with pytest.raises(StudyError, match=r"\[motors\]: motors are an actuator kind; expected \[actuators\] kind = \"motors\""):
        small_curl().replace({"motors": {"preset": "maxon-re40"}})
    with pytest.raises(StudyError, match=r"unknown key motors.inertia; expected 'preset', joints, derate or a motor field"):
        motor_curl(inertia=1.0)
    with pytest.raises(StudyError, match=r"motors.preset: no motor for joint 'shoulder' of model 'arm26'"):
        small_curl().replace({"actuators.kind": "motors"}).actuators(arm26)
    with pytest.raises(StudyError, match=r"motors.preset = 'ur5': the ur5 stand-ins are for 6 joints; the model has 2"):
        motor_curl(preset="ur5").actuators(arm26)
    with pytest.raises(StudyError, match=r"coupling = 'active' with kind = 'motors'"):
        motor_curl().replace({"actuators.coupling": "active"})


@pytest.fixture(scope="module")
def motor_run(tmp_path_factory):
    from fatigue_pin.io.results import read_run
    from fatigue_pin.io.study import run_study

    out = tmp_path_factory.mktemp("motors") / "motors.h5"
    # 20 RK4 substeps of 5 ms: the swing without fatigue limits within verify's gap tolerances (8 of 12.5 ms: qdot 0.025 rad/s)
    run_study(motor_curl().replace({"transcription.substeps": 20}), out=out, name="full/motors")
    return read_run(out, "full/motors")


def test_a_motor_run_stores_signed_torques_and_temperatures_and_passes_verify(motor_run):
    from fatigue_pin.verify.verifier import verify_run

    run = motor_run
    assert run.actuation == "motors" and run.actuator_names == ("shoulder", "elbow") and set(run.fatigue) == {"xw", "xh"}
    tau = run.half_torques()
    assert np.array_equal(tau, run.tau_plus + run.tau_minus)  # one signed torque per joint
    assert tau.min() < 0 < tau.max()
    T_w = run.extras["winding_C"]
    assert T_w[0].tolist() == [25.0, 25.0] and T_w[-1].max() > 25.0  # a cold start, then the winding warms
    report = verify_run(run)
    checks = {c.name: c for c in report.checks}
    assert report.passed, [(c.name, c.value) for c in report.checks if c.passed is False]
    assert checks["gap fatigue states"].value < 1e-8 and report.rk4_residual < 1e-6  # IPOPT's constraint tolerance
    assert "invariant (none: the states have no sum)" in checks


def test_verify_fails_a_motor_run_whose_temperature_is_moved(motor_run):
    from fatigue_pin.verify.verifier import verify_run

    moved = dataclasses.replace(motor_run, fatigue={k: v.copy() for k, v in motor_run.fatigue.items()})
    moved.fatigue["xw"][5, 1] += 1e-3  # the elbow's winding, 0.1 % of its allowed rise
    report = verify_run(moved)
    assert not report.passed and report.gap_fatigue > 1e-4


def test_derated_motors_keep_each_torque_within_its_datasheet_derating(tmp_path):
    """``[motors] derate = true``: each torque within ``limit sqrt(1 - x_w)``. Checked against the
    motor's own derating factor at the stored winding temperatures (``MotorParameters.derating``):
    the bound holds at every interval and binds (fast motors, tau_w 0.5 s, warm within the cycle);
    verify checks the rows and passes."""
    from fatigue_pin.io.results import read_run
    from fatigue_pin.io.study import run_study
    from fatigue_pin.verify.verifier import verify_run

    study = motor_curl(derate=True, tau_w=0.5, tau_m=2.0).replace({"transcription.substeps": 20})
    layer = study.problem().actuators
    assert layer.derated and layer.coupling_kind == "derated"
    run_study(study, out=tmp_path / "derated.h5", name="full/derated")
    run = read_run(tmp_path / "derated.h5", "full/derated")
    assert run.attrs["coupling"] == "derated"
    T_w = run.extras["winding_C"]  # at the start of every interval
    derated = np.column_stack([u.limit * np.array([u.motor.derating(T) for T in T_w[:, k]]) for k, u in enumerate(layer.halves)])
    ratio = np.abs(run.half_torques()) / derated
    assert ratio.max() <= 1 + 1e-5 and ratio.max() > 0.999  # the rows hold to IPOPT's tolerance
    report = verify_run(run)
    checks = {c.name: c for c in report.checks}
    assert report.passed and checks["derated torque TL^2 + x_w in [0, 1]"].value < 1e-6


def test_derate_is_true_or_false():
    with pytest.raises(StudyError, match=r"motors.derate = 'yes': expected true or false"):
        motor_curl(derate="yes")
