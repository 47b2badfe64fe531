"""Replay: scene and animation of a synthetic run, HTML export, local-only meshcat server.

``make_run`` builds the small synthetic run the plot and browser tests use too.
"""

from __future__ import annotations

import base64
import json
import re
from pathlib import Path

import numpy as np
import pytest

from conftest import make_curl_run
from fatigue_pin.io.results import ResultFileError, RunResult, read_run, write_run

@pytest.fixture
def run(tmp_path: Path) -> RunResult:
    """The synthetic run, written and read back."""
    path = write_run(tmp_path / "runs.h5", make_curl_run())
    return read_run(path)


def _commands(html: str) -> list[dict]:
    import umsgpack

    packed = json.loads(re.search(r"var commands = (\[.*?\]);", html).group(1))
    return [umsgpack.unpackb(base64.b64decode(c)) for c in packed]


def test_fatigue_color_scale() -> None:
    from fatigue_pin.viz.replay import FATIGUE_COLORS, fatigue_color

    np.testing.assert_allclose(fatigue_color([0.0, 0.5, 1.0, 2.0, -1.0]),
                               FATIGUE_COLORS[[0, 1, 2, 2, 0]])
    np.testing.assert_allclose(fatigue_color(0.25), (FATIGUE_COLORS[0] + FATIGUE_COLORS[1]) / 2)


def test_build_animation_frames_and_tracks(run: RunResult) -> None:
    from fatigue_pin.viz.replay import build_animation

    scene = build_animation(run)
    assert scene.n_frames == 101 and scene.fps == 50 and scene.duration_s == pytest.approx(2.0)
    np.testing.assert_allclose(scene.cycle_start_s, [0.0, 1.0])
    clips = {path.lower(): clip for path, clip in scene.animation.clips.items()}
    assert "/meshcat/fatigue_pin/visuals/forearm_0" in clips  # moves
    color = clips["/meshcat/fatigue_pin/fatigue/elbow_plus/<object>"].tracks["material.color"]
    assert len(color.frames) == 101
    np.testing.assert_allclose(color.values[0], [0.15, 0.70, 0.25])  # mf = 0: green
    assert color.values[-1][0] > color.values[-1][1]  # mf = 0.8: red dominates
    assert "/meshcat/fatigue_pin/visuals/dumbbell_0/<object>" not in clips  # keeps its colour

    assert scene.cycle_frames == [(0, 50), (50, 100)]

    one = build_animation(run, cycles=[1])
    assert one.n_frames == 51 and one.cycles == [1] and one.duration_s == pytest.approx(1.0)
    back = build_animation(run, cycles=[1, 0])  # not consecutive: the jump back takes one interval
    assert back.n_frames == 102 and back.cycle_frames == [(0, 50), (51, 101)]
    np.testing.assert_allclose(back.cycle_start_s, [0.0, 1.02])
    assert np.all(np.diff(back.frame_times_s) > 0)
    with pytest.raises(ResultFileError, match="out of range"):
        build_animation(run, cycles=[2])


def test_build_animation_uses_the_runs_urdf(run: RunResult) -> None:
    from fatigue_pin.robot.model import bundled_urdf
    from fatigue_pin.viz.replay import build_animation

    urdf = bundled_urdf().read_text().replace('length="0.28"', 'length="0.25"')
    run.urdf = urdf
    cmds = [c.lower() for c in build_animation(run, cycles=[0]).scene_commands]
    lengths = [g["height"] for c in cmds if c["type"] == "set_object" for g in c["object"]["geometries"]
               if g.get("type") == "CylinderGeometry"]
    assert 0.25 in lengths and 0.28 not in lengths


def test_export_html_is_self_contained(run: RunResult, tmp_path: Path) -> None:
    from fatigue_pin.viz.replay import export_html

    out = export_html(run, tmp_path / "sub" / "replay.html")
    html = out.read_text()
    assert "MeshCat.Viewer" in html and "handle_command_bytearray" in html
    assert "http://" not in html.split("<script>", 1)[0]  # nothing fetched before the viewer
    cmds = _commands(html)
    kinds = [c["type"] for c in cmds]
    assert kinds[-1] == "set_animation" and kinds.index("set_object") < kinds.index("set_animation")
    anim = cmds[-1]
    assert anim["options"]["play"] is True
    paths = {a["path"] for a in anim["animations"]}
    assert "/meshcat/fatigue_pin/visuals/humerus_0" in paths
    assert "/meshcat/fatigue_pin/fatigue/shoulder_minus/<object>" in paths
    objects = {c["path"] for c in cmds if c["type"] == "set_object"}
    assert {"/meshcat/fatigue_pin/visuals/thorax_0", "/meshcat/fatigue_pin/visuals/dumbbell_2"} <= objects
    assert '"cycles": [1, 2]' in html


def test_local_server_binds_loopback_only() -> None:
    import psutil

    from fatigue_pin.viz.server import LOCALHOST, start_local_server

    with start_local_server() as server:
        assert server.web_url.startswith("http://127.0.0.1:") and server.zmq_url.startswith("tcp://127.0.0.1:")
        listening = [c.laddr for c in psutil.Process(server.process.pid).net_connections(kind="inet")
                     if c.status == psutil.CONN_LISTEN]
        assert len(listening) >= 2, listening  # HTTP and ZeroMQ
        assert {addr.ip for addr in listening} == {LOCALHOST}, listening
    assert server.process.poll() is not None


def test_serve_plays_and_obeys_the_prompt(run: RunResult, capsys: pytest.CaptureFixture[str]) -> None:
    from fatigue_pin.viz.server import serve

    answers = iter(["9", "2", "q"])
    serve(run, cycle=0, input_fn=lambda _prompt: next(answers), wait_for_browser=False)
    out = capsys.readouterr().out
    assert "http://127.0.0.1:" in out
    assert out.count("cycle 1") == 1 and out.count("cycle 2\n") == 1
    assert "not a cycle number between 1 and 2: '9'" in out


def test_the_overlay_shows_each_joint_in_its_unit(tmp_path: Path) -> None:
    """A prismatic joint's position is shown in m as stored, a revolute one's in deg, at every frame."""
    from conftest import make_pendulum_run
    from fatigue_pin.viz.replay import build_animation, export_html

    run = read_run(write_run(tmp_path / "p.h5", make_pendulum_run(cycles=2, n=10)))
    scene = build_animation(run)
    slider, pendulum = scene.readouts
    assert (slider.joint, slider.unit, pendulum.joint, pendulum.unit) == ("slider", "m", "pendulum", "deg")
    np.testing.assert_array_equal(slider.values, run.q[:, 0])  # consecutive cycles: one frame per node
    np.testing.assert_allclose(pendulum.values, np.degrees(run.q[:, 1]))
    html = export_html(run, tmp_path / "replay.html").read_text()
    meta = json.loads(re.search(r"var meta = (\{.*?\});\n", html).group(1))
    assert [(j["name"], j["unit"]) for j in meta["joints"]] == [("slider", "m"), ("pendulum", "deg")]
    np.testing.assert_allclose(meta["joints"][0]["values"], run.q[:, 0], atol=1e-5)
    assert len(meta["times"]) == scene.n_frames and "fp-joints" in html


def test_a_muscle_run_draws_each_muscle_coloured_by_its_own_fatigue(two_muscle_run, arm26) -> None:
    """Every segment of a muscle's path runs between its points as numeric Pinocchio places them,
    coloured by that muscle's fatigued fraction at the frame."""
    import pinocchio as pin

    from fatigue_pin.muscles.files import read_muscles
    from fatigue_pin.viz.replay import build_animation, fatigue_color

    _, _, run = two_muscle_run
    scene = build_animation(run)
    last_poses, last_colors = scene.frames[-1]
    muscles = read_muscles(run.muscles)
    model, data = arm26.pin_model, arm26.pin_model.createData()
    pin.framesForwardKinematics(model, data, run.q[-1])
    for i, m in enumerate(muscles.muscles):
        world = [data.oMf[model.getFrameId(p.frame)].act(np.asarray(p.location)) for p in m.points]
        for k, (a, b) in enumerate(zip(world[:-1], world[1:])):
            T = last_poses[f"fatigue_pin/muscles/{m.name}/{k}"]
            y = T[:3, 1]  # the unit cylinder's axis, scaled to the segment
            assert np.allclose(T[:3, 3] - y / 2, a, atol=1e-9) and np.allclose(T[:3, 3] + y / 2, b, atol=1e-9)
            assert np.allclose(last_colors[f"fatigue_pin/muscles/{m.name}/{k}"], fatigue_color(run.fatigued[-1, i]))
    assert not np.allclose(fatigue_color(run.fatigued[-1, 0]), fatigue_color(run.fatigued[-1, 1]))  # each its own
