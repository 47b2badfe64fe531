"""Cartesian tasks (issue 13): frame targets, planes and orientations as task items, their study
keys and errors, the inverse-kinematics guess, and a small version of the UR5 carry study whose
result meets its targets (checked with numeric Pinocchio from the stored q)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fatigue_pin.cli.main import main
from fatigue_pin.core.errors import FatiguePinError, TaskError
from fatigue_pin.robot.kinematics import frame_placement
from fatigue_pin.io.results import read_run
from fatigue_pin.io.study import Study, StudyError, run_study
from fatigue_pin.ocp.task import FrameOrientation, FramePlane, FrameTarget, Task
from fatigue_pin.ocp.transcription import Ocp

STUDY = Path(__file__).resolve().parents[2] / "studies" / "ur5_carry.toml"
#: a quick version of the carry study: 10 intervals per cycle, uncompiled
QUICK = {"task.intervals_per_cycle": 10, "transcription.substeps": 2, "solver.compile": False}  # a coarse, quick grid


@pytest.fixture(scope="module")
def study() -> Study:
    return Study.from_file(STUDY)


@pytest.fixture(scope="module")
def model(study):
    return study.model()


def test_study_keys_round_trip(study):
    data = study.data
    assert data["model"]["payload"] == {"frame": "tool0", "mass": 4.0, "com": [0.0, 0.0, 0.05]}
    assert [t["frame"] for t in data["task"]["targets"]] == ["tool0", "tool0"]
    assert data["task"]["planes"] == [{"frame": "tool0", "normal": [0.0, 0.0, 1.0], "offset": 0.05}]
    assert Study.from_toml(study.to_toml()).data == data
    task = study.task()
    assert [type(i) for i in task.items] == [FrameTarget, FrameTarget, FramePlane]
    assert task.items[1].position == (0.3, -0.2, 0.6) and task.items[1].at == 0.5


def test_constraint_rows_evaluate_the_frame_position(model):
    """The rows of a ball, a box, a plane and an orientation at a posture: signs as expected."""
    q = np.array([0.3, -1.1, 1.4, -1.0, -1.5, 0.2])
    p = frame_placement(model.pin_model, "tool0", q)
    problem = Study.from_file(STUDY).problem(model)
    L = problem.layout
    x = np.zeros(L.nx)
    x[L.q] = q
    inside = FrameTarget("tool0", p.translation + [0.003, 0, 0], 0.0, 0.005)
    outside = FrameTarget("tool0", p.translation + [0.01, 0, 0], 0.0, 0.005)
    box = FrameTarget("tool0", p.translation + [0.004, -0.004, 0.004], 0.0, 0.005, "box")
    for item, ok in ((inside, True), (outside, False), (box, True)):
        sc = item.constraint(model, L)
        value = np.asarray(sc.expression(x)).ravel()
        assert np.all((value >= np.asarray(sc.lower) - 1e-12) & (value <= np.asarray(sc.upper) + 1e-12)) == ok
    # the ball row is about |d| - tol near the surface (metres)
    sc = FrameTarget("tool0", p.translation + [0.0055, 0, 0], 0.0, 0.005).constraint(model, L)
    assert float(sc.expression(x)) == pytest.approx(0.0055 - 0.005, rel=0.1)
    above, below = FramePlane("tool0", [0, 0, 2], p.translation[2] - 0.01), FramePlane("tool0", [0, 0, 1], p.translation[2] + 0.01)
    assert float(above.constraint(model, L).expression(x)) == pytest.approx(p.translation[2])  # normal made unit
    assert above.height(p.translation) == pytest.approx(0.01) and below.height(p.translation) == pytest.approx(-0.01)
    ori = FrameOrientation("tool0", p.rotation, 0.0, 0.05).constraint(model, L)
    assert float(ori.expression(x)) == pytest.approx(1 - np.cos(0.05))


def test_a_frame_target_on_some_axes_holds_only_those(model):
    """``axes``: the rows of the named world axes only, and the distance (and verify's check) on them."""
    q = np.array([0.3, -1.1, 1.4, -1.0, -1.5, 0.2])
    p = frame_placement(model.pin_model, "tool0", q).translation
    L = Study.from_file(STUDY).problem(model).layout
    x = np.zeros(L.nx)
    x[L.q] = q
    off_in_y = p + [0.0, 0.2, 0.0]
    xz = FrameTarget("tool0", off_in_y, "end", 0.0, "box", ["z", "x"])
    assert xz.axes == ("x", "z") and xz.at == "end"  # world order
    sc = xz.constraint(model, L)
    np.testing.assert_allclose(np.asarray(sc.expression(x)).ravel(), [0.0, 0.0], atol=1e-12)  # two rows, both met
    assert sc.lower == (0.0, 0.0) == sc.upper
    assert xz.distance(p) == pytest.approx(0.0, abs=1e-12)
    assert FrameTarget("tool0", off_in_y).distance(p) == pytest.approx(0.2)  # all three axes by default
    assert FrameTarget("tool0", off_in_y, 0.0, 0.1, "ball", ["y"]).distance(p) == pytest.approx(0.1)
    for bad in ([], ["x", "x"], ["w"], "x"):
        with pytest.raises(TaskError, match="axes"):
            FrameTarget("tool0", p, axes=bad)
    # inverse kinematics holds the named axes only: a point 10 m away in y is reached in x and z
    from fatigue_pin.robot.ik import solve_ik

    far = FrameTarget("tool0", p + [0.05, 10.0, -0.05], axes=["x", "z"])
    res = solve_ik(model, [far], q0=q)
    assert res.success and far.distance(frame_placement(model.pin_model, "tool0", res.q).translation) < 1e-6
    far.check(model)  # within reach on its axes


def _error(study: Study, changes: dict) -> str:
    with pytest.raises(FatiguePinError) as info:
        s = study.replace(changes) if changes else study
        s.problem()
    msg = str(info.value)
    assert "\n" not in msg
    return msg


def test_errors_name_the_value(study):
    targets = study.data["task"]["targets"]
    assert "'tool9' is not in model 'ur5'" in _error(study, {"task.targets": [{**targets[0], "frame": "tool9"}, targets[1]]})
    msg = _error(study, {"task.targets": [targets[0], {**targets[1], "position": [2.0, 0.0, 0.6]}]})
    assert "out of reach" in msg and "[2.0, 0.0, 0.6]" in msg
    assert "payload frame 'hand' is not in model" in _error(study, {"model.payload.frame": "hand"})
    assert "model.payload.mass = -1.0" in _error(study, {"model.payload.mass": -1.0})
    msg = _error(study, {"task.q_init": [0.0, -1.2, 1.0, -1.4, -1.57, 0.0]})
    assert "outside its phase-0 target" in msg and "task.q_init" in msg
    with pytest.raises(StudyError, match=r"task.targets\[0\]: expected either joint \+ value .*, frame \+ position"):
        study.replace({"task.targets": [{"at": 0.0}]})
    with pytest.raises(StudyError, match=r"task.targets\[0\].shape = 'cube'"):
        study.replace({"task.targets": [{**targets[0], "shape": "cube"}]})
    with pytest.raises(StudyError, match=r"unknown key task.targets\[0\].value"):
        study.replace({"task.targets": [{**targets[0], "value": 1.0}]})
    with pytest.raises(StudyError, match=r"task.planes\[0\].normal"):
        study.replace({"task.planes": [{"frame": "tool0", "normal": [0, 0, 0], "offset": 0.0}]})
    msg = _error(study, {"task.planes": [{"frame": "tool0", "normal": [0, 0, 1], "offset": 0.5}]})
    assert "below the plane" in msg


def test_unreachable_ik_target_is_a_clear_error_not_a_hang(model):
    """A point inside the reach ball that the joint limits forbid: the ik guess says so."""
    from fatigue_pin.ocp.guesses import phase_postures

    q0 = np.array([0.175723, -1.013522, 1.626825, -1.182826, -1.56642, 0.0])
    task = Task(2.0, 10, (FrameTarget("tool0", (0.5, 0.2, 0.1), 0.0, 0.005), FrameTarget("tool0", (0.0, 0.0, 1.3), 0.5, 0.005)), q0)
    with pytest.raises(TaskError, match=r"phase 0.5: inverse kinematics cannot place frame 'tool0' at \[0.0, 0.0, 1.3\]"):
        phase_postures(task, model, q0)


def test_ik_guess_meets_the_targets_at_their_phases(study, model):
    problem = study.replace(QUICK).problem(model)
    ocp = Ocp(problem, 2, study.transcription(), study.replace(QUICK).solver(), guess="ik")
    x, u = ocp.initial_guess()
    q = x[:, problem.layout.q]
    for node, target in ((0, (0.5, 0.2, 0.1)), (5, (0.3, -0.2, 0.6)), (10, (0.5, 0.2, 0.1)), (15, (0.3, -0.2, 0.6)), (20, (0.5, 0.2, 0.1))):
        assert np.linalg.norm(frame_placement(model.pin_model, "tool0", q[node]).translation - target) < 1e-6
    assert np.abs(u).max() > 10  # gravity compensation of the arm and its 4 kg


def _check_targets(run, study: Study) -> None:
    """Every stored configuration at a target phase puts the tool within the tolerance, and the
    tool stays above the table, recomputed with numeric Pinocchio (the robot without payload:
    kinematics do not depend on it)."""
    from fatigue_pin.robot.model import resolve_model

    pm = resolve_model("ur5").pin_model
    n = study.data["task"]["intervals_per_cycle"]
    for target in study.data["task"]["targets"]:
        nodes = range(int(round(target["at"] * n)), run.q.shape[0], n)
        for k in nodes:
            d = np.linalg.norm(frame_placement(pm, target["frame"], run.q[k]).translation - np.array(target["position"]))
            assert d <= target["tolerance"] + 1e-6, (k, d)
    heights = [frame_placement(pm, "tool0", q).translation[2] for q in run.q]
    assert min(heights) >= 0.05 - 1e-6


@pytest.mark.slow  # 30 s on 2 cores; by default the robot-study page's sliding carry runs from the CLI and verify checks its result
def test_small_carry_study_meets_its_targets_sliding(tmp_path, study):
    """The carry study in sliding horizon (2-cycle windows, 3 cycles kept) from the command line."""
    out = tmp_path / "carry.h5"
    args = ["run", str(STUDY), "--out", str(out), "--set", "horizon.cycles=2", "--set", "horizon.max_cycles=3"]
    for k, v in QUICK.items():
        args += ["--set", f"{k}={str(v).lower()}"]
    assert main(args) == 0
    run = read_run(out, "sliding/ur5_carry")
    assert run.windows["converged"].all() and run.q.shape == (31, 6)
    _check_targets(run, study.replace(QUICK))
    assert run.fatigue["mf"][-1].max() > 0.01
    assert Study.from_toml(run.study).data["model"]["payload"]["mass"] == 4.0


def test_small_carry_study_meets_its_targets_full_horizon(study):
    quick = study.replace({**QUICK, "horizon.kind": "full", "horizon.cycles": 1})
    run = run_study(quick).run
    assert run.attrs["converged"]
    _check_targets(run, quick)
