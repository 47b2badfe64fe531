"""The task checks of verify (fatigue_pin.verify.task_checks) on a synthetic arm26 run: each kind's
violation against a value computed here, "not checked" for a kind verify does not know, and no
task without a stored study. Real results of frame-target studies: test_verify_studies.py."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest

from fatigue_pin.io.study import Study
from fatigue_pin.ocp.task import FrameTarget, JointRange, StateConstraint
from fatigue_pin.robot.model import bundled_urdf
from fatigue_pin.verify import verify_run
from fatigue_pin.verify.stored import rebuild
from fatigue_pin.verify.task_checks import task_checks

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from conftest import make_curl_run, small_curl  # noqa: E402


@pytest.fixture(scope="module")
def run():
    """Two synthetic curls of 10 intervals, with the arm26 URDF and the small curl's study."""
    return dataclasses.replace(make_curl_run(n_cycles=2, n=10, urdf=bundled_urdf().read_text()), study=small_curl("full").to_toml())


def _checks(run, *items, tol: float = 1e-4):
    stored = rebuild(run)
    stored = dataclasses.replace(stored, task=dataclasses.replace(stored.task, items=stored.task.items + tuple(items)))
    notes: list[str] = []
    return {c.name: c for c in task_checks(stored, tol, notes)}, notes, stored


def test_joint_targets_and_ranges(run):
    checks, notes, stored = _checks(run, JointRange("elbow", 0.5, 2.0))
    target = checks["task joint targets"]
    # the synthetic elbow is at 15 deg at phase 0 and 150 deg at 0.5: the curl's targets, met
    assert target.value == pytest.approx(0.0, abs=1e-12)
    rng = checks["task joint ranges"]
    elbow = run.q[:, 1]
    assert rng.value == pytest.approx(max(0.5 - elbow.min(), elbow.max() - 2.0), rel=1e-12)
    assert rng.where.startswith(f"node {int(np.argmax(np.maximum(0.5 - elbow, elbow - 2.0)))},")


def test_frame_target_box_and_ball(run):
    model = rebuild(run).robot.pin_model
    data = model.createData()
    k = 5  # phase 0.5
    pin.framesForwardKinematics(model, data, run.q[k])
    p = data.oMf[model.getFrameId("dumbbell")].translation.copy()
    d = np.array([0.01, -0.02, 0.005])
    box = FrameTarget("dumbbell", tuple(p + d), at=0.5, tolerance=0.004, shape="box")
    checks, _, _ = _checks(run, box)
    assert checks["task frame targets"].value == pytest.approx(0.02 - 0.004, abs=1e-12)
    ball = FrameTarget("dumbbell", tuple(p + d), at=0.5, tolerance=0.004)
    checks, _, _ = _checks(run, ball)
    line = checks["task frame targets"]
    assert line.value == pytest.approx(np.linalg.norm(d) - 0.004, abs=1e-12) and line.where.startswith("node 5,") and line.unit == "m"


def test_an_unknown_frame_is_not_checked_with_a_note(run):
    checks, notes, _ = _checks(run, FrameTarget("no_such_frame", (0.0, 0.0, 0.0), at=0.0, tolerance=0.1))
    assert not checks["task frame targets"].checked
    assert any("no_such_frame" in n and "not checked" in n for n in notes)


def test_an_unknown_kind_is_not_checked_with_a_note(run):
    x = ca.SX.sym("x", 2 * 2 + 4 * 3)
    sc = StateConstraint("shoulder_ahead", ca.Function("f", [x], [x[0]]), 0.0, 1.0)
    checks, notes, _ = _checks(run, sc)
    line = checks["task StateConstraint"]
    assert not line.checked and line.verdict == "not checked"
    assert any("StateConstraint (1) not checked" in n and "FramePlane" in n for n in notes)
    assert checks["task joint targets"].checked  # the known kinds still are


def test_a_kind_verify_does_not_know_never_raises(run, monkeypatch):
    """Whatever kind a future study declares, verify reports it as not checked."""

    @dataclasses.dataclass(frozen=True)
    class FrameSpeed:
        frame: str
        limit: float

        def constraint(self, model, layout):  # what Task asks of a Cartesian item
            raise NotImplementedError

    original = Study.task

    def with_speed(self):
        task = original(self)
        return dataclasses.replace(task, items=task.items + (FrameSpeed("dumbbell", 1.0),))

    monkeypatch.setattr(Study, "task", with_speed)
    r = verify_run(run, single_shooting=False)
    assert r.check("task FrameSpeed").verdict == "not checked"
    assert any("FrameSpeed (1) not checked" in n for n in r.notes)
    assert "not checked" in r.table() and "Traceback" not in r.table()


def test_no_study_no_task(run):
    r = verify_run(dataclasses.replace(run, study=""))
    assert "no study stored: task not checked" in r.notes
    assert not r.check("task").checked and not r.check("initial state").checked and np.isnan(r.task)


def test_frame_checks_say_their_vectors_as_plain_numbers(run):
    """The line of a plane and of a frame target shows its vectors as plain numbers, e.g.
    ``dumbbell on [0.0, 0.0, 1.0] . p >= 10 m``, never ``[np.float64(0.0), ...]`` (both are
    missed: the hand is nowhere near 10 m up, nor at 10 m from the base)."""
    from fatigue_pin.ocp.task import FramePlane

    plane = FramePlane("dumbbell", np.array([0.0, 0.0, 2.0]), np.float64(10.0))
    target = FrameTarget("dumbbell", np.array([10.0, 0.2, 0.3]), at=0.5, tolerance=1.0)
    checks, _, _ = _checks(run, plane, target)
    planes, targets = checks["task frame planes"], checks["task frame targets"]
    assert "dumbbell on [0.0, 0.0, 1.0] . p >= 10 m" in planes.where, planes.where
    assert "dumbbell at [10.0, 0.2, 0.3] +- 1 m (ball)" in targets.where, targets.where
    for line in (planes, targets):
        assert "np." not in line.where and "array(" not in line.where
