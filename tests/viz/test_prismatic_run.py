"""A solved run on a model with a prismatic joint (urdf/pendulum.urdf: a cart on a rail with a
pendulum) keeps its joints' kinds from the model to the file, the figures and verify's report."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fatigue_pin.cli.main import main
from fatigue_pin.io.results import read_run
from fatigue_pin.verify.verifier import verify_run
from fatigue_pin.viz import plots

PENDULUM = Path(__file__).resolve().parents[2] / "urdf" / "pendulum.urdf"

#: The cart goes 0.73 m along its rail and back in 1 s; the pendulum swings freely (no target).
STUDY = f"""
name = "pendulum_units"

[model]
urdf = "{PENDULUM}"

[fatigue]
model = "xia"
LD = 10.0
LR = 10.0
F = 0.2
R = 0.01
S = 10.0

[task]
cycle_duration = 1.0
intervals_per_cycle = 10

[[task.targets]]
joint = "slider"
value = 0.0
at = 0.0

[[task.targets]]
joint = "slider"
value = 0.73
at = 0.5

[costs]
torque = 1e-2

[transcription]
substeps = 2

[solver]
compile = false

[horizon]
kind = "full"
cycles = 1
"""


@pytest.fixture(scope="module")
def solved(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("pendulum")
    (folder / "pendulum.toml").write_text(STUDY)
    out = folder / "p.h5"
    assert main(["run", str(folder / "pendulum.toml"), "--out", str(out)]) == 0
    return out


def test_the_slider_is_drawn_in_metres(solved: Path, monkeypatch, tmp_path: Path) -> None:
    run = read_run(solved)
    assert run.converged and run.joint_kinds == ("prismatic", "revolute")
    assert run.q[5, 0] == pytest.approx(0.73, abs=1e-9)  # the target at phase 0.5, in m
    figures: list = []
    save = plots._save
    monkeypatch.setattr(plots, "_save", lambda fig, out, stem: figures.append(fig) or save(fig, out, stem))
    plots.plot_joint_angles(run, tmp_path)
    slider, pendulum = figures[-1].axes[:2]
    assert slider.get_ylabel() == "position (m)" and pendulum.get_ylabel() == "angle (deg)"
    (line,) = slider.get_lines()
    assert line.get_ydata()[5] == pytest.approx(0.73, abs=1e-9)  # not 41.8 (0.73 rad in deg)
    np.testing.assert_allclose(pendulum.get_lines()[0].get_ydata(), np.degrees(run.q[:, 1]))


def test_verify_states_the_joints_units(solved: Path) -> None:
    report = verify_run(read_run(solved))
    assert report.check("task joint targets").unit == "m"  # its only targets are the slider's
    assert report.check("bound q").unit == "m or rad" and report.check("gap qdot").unit == "m/s or rad/s"
    assert report.check("bound torques").unit == "N or N m"
    assert "  unit          tolerance" in report.table()
