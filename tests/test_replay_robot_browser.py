"""The replay of the robot study (UR5 carrying a load, Collada meshes from example-robot-data)
renders in headless Chromium: no script error, the robot in view, the motion moves it and the
fatigue colour of its mesh segments changes (issue 13).

The run is synthetic and quick to make: the carry study's inverse-kinematics motion
(:func:`fatigue_pin.ik.ik_reference`) over two cycles, every half's mf rising (the shoulder
lift's minus half fastest, 0 -> 0.9). Same Chromium requirements as tests/test_replay_browser.py.
"""

from __future__ import annotations

import asyncio
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from fatigue_pin.ik import ik_reference
from fatigue_pin.replay import build_animation, export_html
from fatigue_pin.results import RunResult
from fatigue_pin.study import Study
from test_replay_browser import _chromium, _share, open_replay

pytestmark = pytest.mark.browser

STUDY = Path(__file__).resolve().parents[1] / "studies" / "ur5_carry.toml"
SEGMENT = "upper_arm_link_0"  # the UR5 mesh moved by shoulder_lift_joint


def make_carry_run(n_cycles: int = 2) -> RunResult:
    study = Study.from_file(STUDY)
    model, task = study.model(), study.task()
    n = task.intervals_per_cycle
    t = np.linspace(0.0, n_cycles * task.cycle_duration, n_cycles * n + 1)
    q, qdot, _ = ik_reference(task, model, t, np.array(task.q_init))
    halves = tuple(f"{j}_{s}" for j in model.joint_names for s in ("plus", "minus"))
    frac = t / t[-1]
    mf = np.column_stack([0.1 * frac] * len(halves))
    lift = halves.index("shoulder_lift_joint_minus")  # the lift holds the load up with negative torques
    mf[:, lift] = 0.9 * frac
    ma = np.full_like(mf, 0.05)
    limits = np.repeat(model.tau_upper, 2) * np.tile([1.0, -1.0], model.nv)
    attrs = dict(horizon="sliding", n_cycles=n_cycles, converged=True, status="Solve_Succeeded", tau_limits=limits)
    return RunResult(
        name="sliding/ur5_carry", attrs=attrs, t=t, q=q, qdot=qdot, tau_plus=np.zeros((t.size - 1, model.nv)),
        tau_minus=np.zeros((t.size - 1, model.nv)), fatigue={"ma": ma, "mr": 1 - ma - mf, "mf": mf},
        cycle_costs=np.zeros((n_cycles, 1)), torque_limits=(1 - mf[n::n]) * limits, joint_names=model.joint_names,
        actuator_names=halves, cost_terms=("fatigue",), cycle_wall_time_s=np.ones(n_cycles),
        urdf=Path(model.urdf_path).read_text(),
    )


def test_mesh_segments_are_colourable_triangles():
    """The UR5's Collada segments are sent as triangle meshes with a Phong material (no Collada
    command left for them), so their colour can be keyframed; the base keeps its Collada mesh."""
    scene = build_animation(make_carry_run(1))
    kinds = {}
    for c in scene.scene_commands:
        path = getattr(c, "path", None)
        if path is not None and type(c).__name__ in ("SetObject", "DaeMeshGeometry"):
            kind = type(c).__name__ if type(c).__name__ == "DaeMeshGeometry" else type(c.object.geometry).__name__
            kinds[path.lower().split("/")[-1]] = kind
    assert kinds[SEGMENT] == "TriangularMeshGeometry"
    assert kinds["base_link_0"] == "DaeMeshGeometry"
    colours = scene.frames[-1][1]
    assert f"fatigue_pin/visuals/{SEGMENT}" in colours


def _mesh_color(name: str) -> str:
    return f"viewer.scene_tree.find(['meshcat','fatigue_pin','visuals','{name}','<object>']).object.material.color.toArray()"


async def _drive(chromium: str, html: Path, out: Path) -> dict:
    async with open_replay(chromium, html, out, timeout_s=60) as page:
        await asyncio.sleep(1.0)  # the base's Collada mesh loads asynchronously
        report = {"duration": await page.js("viewer.animator.duration")}
        report["first"] = await page.screenshot_at(0.0, out / "robot_t0.png")
        report["color_first"] = await page.js(_mesh_color(SEGMENT))
        report["middle"] = await page.screenshot_at(1.0, out / "robot_t1.png")
        report["last"] = await page.screenshot_at(report["duration"] - 1e-3, out / "robot_end.png")
        report["color_last"] = await page.js(_mesh_color(SEGMENT))
    report["errors"] = page.errors  # including the late events collected on closing
    return report


def test_robot_study_replay_renders_with_fatigue_colours(tmp_path: Path) -> None:
    chromium = _chromium()
    html = export_html(make_carry_run(2), tmp_path / "carry.html")
    report = asyncio.run(_drive(chromium, html, tmp_path))
    keep = os.environ.get("FATIGUE_PIN_SCREENSHOT_DIR")
    if keep:
        Path(keep).mkdir(parents=True, exist_ok=True)
        for png in tmp_path.glob("robot_*.png"):
            shutil.copy(png, Path(keep) / png.name)

    assert report["errors"] == [], report["errors"]
    assert report["duration"] == pytest.approx(4.0)  # 2 cycles of 2 s, in real time
    first, middle, last = report["first"], report["middle"], report["last"]
    for img in (first, middle, last):
        assert (img != img[0, 0]).any()  # not blank
        # the robot in view: its green (rested) or yellow-red segments cover part of the picture,
        # away from its sides (the background is a blue gradient)
        r, g, b = img[..., 0], img[..., 1], img[..., 2]
        robot = ((g > 0.45) & (g > b + 0.15)) | ((r > 0.6) & (r > b + 0.25))
        assert _share(robot) > 0.01
        rows, cols = np.nonzero(robot)
        assert rows.min() > 0 and cols.min() > 0 and rows.max() < img.shape[0] - 1 and cols.max() < img.shape[1] - 1
    assert np.abs(first - middle).mean() > 1e-3  # the robot moves
    c0, c1 = np.array(report["color_first"]), np.array(report["color_last"])
    assert c0[1] > c0[0] and c1[0] > c1[1], (c0, c1)  # the upper arm turns from green to red
