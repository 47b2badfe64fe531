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

from fatigue_pin.results import WINDOW_DTYPE, ResultFileError, RunResult, read_run, write_run

HALVES = ("shoulder_plus", "shoulder_minus", "elbow_plus", "elbow_minus")
TERMS = ("shoulder_angle", "torque_rate", "fatigue", "torque")


def make_run(name: str = "full/fatigue_torque", n_cycles: int = 2, n: int = 50, horizon: str = "full",
             urdf: str = "") -> RunResult:
    """A synthetic arm26 run: ``n_cycles`` curls of ``n`` intervals (0.02 s each for n = 50), elbow
    15 -> 150 -> 15 deg, every mf growing linearly-ish (elbow_plus 0 -> 0.8)."""
    nodes = n_cycles * n + 1
    t = np.linspace(0.0, n_cycles, nodes)
    phase = 2 * np.pi * t
    elbow = np.radians(15) + np.radians(135) * 0.5 * (1 - np.cos(phase))
    shoulder = 0.07 + 0.2 * np.sin(phase) * t / n_cycles
    q = np.column_stack([shoulder, elbow])
    qdot = np.gradient(q, t, axis=0)
    tau_plus = np.column_stack([10 + 5 * np.sin(phase[:-1]), 20 + 10 * np.sin(phase[:-1])])
    tau_minus = -np.column_stack([2 + np.cos(phase[:-1]), 3 + np.cos(phase[:-1])])
    frac = t / t[-1]
    mf = np.column_stack([0.4 * frac, 0.05 * frac, 0.8 * frac**1.5, 0.1 * frac])
    ma = np.column_stack([0.2 + 0.1 * np.sin(phase), 0.04 + 0 * t, 0.4 + 0.2 * np.sin(phase), 0.06 + 0 * t])
    mr = 1 - ma - mf
    costs = np.array([[1e2 * (c + 1), 0.1 * (c + 1), 10.0 * (c + 1) ** 2, 1e3] for c in range(n_cycles)])
    limits = np.array([50.0, -50.0, 50.0, -50.0])
    attrs = dict(horizon=horizon, cost="fatigue+torque", preset="test", S=10.0, F=0.456, R=0.0094, LD=10.0,
                 LR=10.0, n_cycles=n_cycles, converged=True, status="Solve_Succeeded", wall_time_s=12.0,
                 build_time_s=1.0, iterations=100, solver="ipopt", tau_limits=limits)
    windows = None
    if horizon == "sliding":
        n_win = max(n_cycles - 2, 1)
        windows = np.array([(i, i, b"Solve_Succeeded", True, 40 + i, 3.0 + i, 1.0) for i in range(n_win)],
                           dtype=WINDOW_DTYPE)
    return RunResult(
        name=name, attrs=attrs, t=t, q=q, qdot=qdot, tau_plus=tau_plus, tau_minus=tau_minus, fatigue={"ma": ma, "mr": mr, "mf": mf},
        cycle_costs=costs, torque_limits=(1 - mf[n::n]) * limits, joint_names=("shoulder", "elbow"),
        actuator_names=HALVES, cost_terms=TERMS, cycle_wall_time_s=np.full(n_cycles, 6.0), windows=windows,
        urdf=urdf,
    )


@pytest.fixture
def run(tmp_path: Path) -> RunResult:
    """The synthetic run, written and read back."""
    path = write_run(tmp_path / "runs.h5", make_run())
    return read_run(path)


def _commands(html: str) -> list[dict]:
    import umsgpack

    packed = json.loads(re.search(r"var commands = (\[.*?\]);", html).group(1))
    return [umsgpack.unpackb(base64.b64decode(c)) for c in packed]


def test_fatigue_color_scale() -> None:
    from fatigue_pin.replay import FATIGUE_COLORS, fatigue_color

    np.testing.assert_allclose(fatigue_color([0.0, 0.5, 1.0, 2.0, -1.0]),
                               FATIGUE_COLORS[[0, 1, 2, 2, 0]])
    np.testing.assert_allclose(fatigue_color(0.25), (FATIGUE_COLORS[0] + FATIGUE_COLORS[1]) / 2)


def test_build_animation_frames_and_tracks(run: RunResult) -> None:
    from fatigue_pin.replay import build_animation

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
    from fatigue_pin.model import bundled_urdf
    from fatigue_pin.replay import build_animation

    urdf = bundled_urdf().read_text().replace('length="0.28"', 'length="0.25"')
    run.urdf = urdf
    cmds = [c.lower() for c in build_animation(run, cycles=[0]).scene_commands]
    lengths = [g["height"] for c in cmds if c["type"] == "set_object" for g in c["object"]["geometries"]
               if g.get("type") == "CylinderGeometry"]
    assert 0.25 in lengths and 0.28 not in lengths


def test_export_html_is_self_contained(run: RunResult, tmp_path: Path) -> None:
    from fatigue_pin.replay import export_html

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

    from fatigue_pin.replay import LOCALHOST, start_local_server

    with start_local_server() as server:
        assert server.web_url.startswith("http://127.0.0.1:") and server.zmq_url.startswith("tcp://127.0.0.1:")
        listening = [c.laddr for c in psutil.Process(server.process.pid).net_connections(kind="inet")
                     if c.status == psutil.CONN_LISTEN]
        assert len(listening) >= 2, listening  # HTTP and ZeroMQ
        assert {addr.ip for addr in listening} == {LOCALHOST}, listening
    assert server.process.poll() is not None


def test_serve_plays_and_obeys_the_prompt(run: RunResult, capsys: pytest.CaptureFixture[str]) -> None:
    from fatigue_pin.replay import serve

    answers = iter(["9", "2", "q"])
    serve(run, cycle=0, input_fn=lambda _prompt: next(answers), wait_for_browser=False)
    out = capsys.readouterr().out
    assert "http://127.0.0.1:" in out
    assert out.count("cycle 1") == 1 and out.count("cycle 2\n") == 1
    assert "not a cycle number between 1 and 2: '9'" in out
