"""Replay an OCP run in the browser with meshcat, fatigue shown as colour on the model.

The scene holds the model's visual geometry (from the URDF stored in the run, or the bundled
arm26) and, for every actuated joint, two spheres next to the joint: the flexion half
(``<joint>_plus``, anterior, +x of the parent body) and the extension half (``<joint>_minus``,
posterior). Each sphere is coloured by the fatigued fraction ``mf`` of its half, green (0) ->
yellow (0.5) -> red (1); the segment driven by a joint is coloured by the larger ``mf`` of the
joint's two halves. The motion plays in real time (one frame per node, 0.02 s), cycle after cycle.
The HTML overlay shows every joint's position as it plays, in its joint's units (deg for a revolute
joint, m for a prismatic one: :meth:`RunResult.joint_units`).

A muscle run (docs/muscles.md) also draws every muscle as thin cylinders through its path points
(read from the muscle file's text the run stores), each coloured by that muscle's own fatigued
fraction; a wrapped segment is drawn straight between its points (the arc round the cylinder is
not drawn). The spheres then show the residual torque halves, if any.

Three ways to watch a run:

* :func:`export_html`: one self-contained HTML file (meshcat's viewer inlined, no server); the
  animation plays in a loop as soon as the page opens, the meshcat panel (top right,
  "Animations") pauses, scrubs and slows it; an overlay shows the cycle and the colour scale.
* :func:`fatigue_pin.viz.server.serve`: a meshcat server on 127.0.0.1 only; Python plays the
  frames, a prompt picks the cycle.
* :func:`build_animation`: the scene and its :class:`meshcat.animation.Animation`, to embed elsewhere.

Colours are keyframed as three.js ``material.color`` tracks of the meshes (meshcat's animation
player accepts any three.js track type); this needs the meshes to exist before the animation is
loaded, which is why :func:`export_html` writes the commands in recorded order rather than
meshcat's ``static_html`` (whose scene walk sends the animation before the objects).

Cycle numbers shown to people (overlay, prompt, ``--cycle``) start at 1; the ``cycles``
arguments of the functions are 0-based indices like :meth:`RunResult.cycle_slice`.
"""

from __future__ import annotations

import base64
import html
import json
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from fatigue_pin.io.results import ResultFileError, RunResult

#: Address every server of this module binds to: the local machine only.
LOCALHOST = "127.0.0.1"

#: Fatigue colour scale: mf = 0, 0.5, 1 -> green, yellow, red (RGB in [0, 1]).
FATIGUE_COLORS = np.array([[0.15, 0.70, 0.25], [0.98, 0.80, 0.10], [0.85, 0.10, 0.10]])

ROOT = "fatigue_pin"  # meshcat root node of the model
_MARKER_RADIUS = 0.022  # m
_MARKER_OFFSET = (0.05, 0.0, 0.04)  # m, in the parent body frame at the joint: (anterior, -, lateral)
_MUSCLE_RADIUS = 0.004  # m, of the cylinders that draw a muscle's path


def fatigue_color(mf: np.ndarray | float) -> np.ndarray:
    """RGB colour of a fatigued fraction: green (0) -> yellow (0.5) -> red (1); shape (..., 3)."""
    x = np.clip(np.asarray(mf, dtype=float), 0.0, 1.0)[..., None] * 2.0
    lo = np.minimum(np.floor(x), 1.0).astype(int)[..., 0]
    w = x - lo[..., None]
    return (1.0 - w) * FATIGUE_COLORS[lo] + w * FATIGUE_COLORS[lo + 1]


# -- model ---------------------------------------------------------------------------------------


def build_models(urdf: str = "") -> tuple[Any, Any]:
    """Pinocchio model and visual geometry model from URDF text (empty: the bundled arm26).

    Only kinematics and visuals are built; no dynamics, no compiled extension.
    """
    import pinocchio as pin

    if not urdf.strip():
        from fatigue_pin.robot.model import bundled_urdf

        urdf = bundled_urdf().read_text()
    from fatigue_pin.robot.model import package_dirs

    model = pin.buildModelFromXML(urdf)
    try:
        visual = pin.buildGeomFromUrdfString(model, urdf, pin.GeometryType.VISUAL, package_dirs=package_dirs())
    except ValueError as exc:  # a mesh that cannot be found
        raise ResultFileError(f"the run's model has visuals that cannot be loaded: {exc}") from None
    return model, visual


def _half_columns(run: RunResult, joint: str) -> tuple[int, int] | None:
    """Columns of ``<joint>_plus`` and ``<joint>_minus`` in ``mf``; None for a passive joint (no halves)."""
    names = list(run.actuator_names)
    if joint in run.passive_joints:
        return None
    try:
        return names.index(f"{joint}_plus"), names.index(f"{joint}_minus")
    except ValueError:
        raise ResultFileError(
            f"run {run.name!r}: no actuator halves {joint}_plus / {joint}_minus among {names}"
        ) from None


@dataclass
class _Kinematics:
    """What moves and what is coloured, for one run on one model."""

    model: Any
    visual: Any
    joint_ids: list[int]  # Pinocchio joint id of every run joint
    halves: list[tuple[int, int] | None]  # (plus, minus) mf columns of every run joint (None: passive)
    segment_of: dict[str, int] = field(default_factory=dict)  # visual name -> index of its joint in joint_ids
    # coloured visuals whose mesh file (Collada) is sent as triangles: a Collada scene is a group
    # without one material, so its colour could not be keyframed; the triangles are the mesh as
    # Pinocchio loaded it (coal, scale applied), with one Phong material
    triangle_meshes: set[str] = field(default_factory=set)
    # a muscle run's muscles: (name, fatigued column, [(frame id, point in the frame), ...]) each
    muscles: list[tuple[str, int, list[tuple[int, np.ndarray]]]] = field(default_factory=list)

    def visual_path(self, name: str) -> str:
        return f"{ROOT}/visuals/{name}"

    @staticmethod
    def muscle_path(muscle: str, segment: int) -> str:
        return f"{ROOT}/muscles/{muscle}/{segment}"

    @staticmethod
    def marker_path(joint: str, sign: str) -> str:
        return f"{ROOT}/fatigue/{joint}_{sign}"


def _kinematics(run: RunResult) -> _Kinematics:
    import pinocchio as pin

    model, visual = build_models(run.urdf)
    joint_ids = []
    for name in run.joint_names:
        if not model.existJointName(name):
            raise ResultFileError(f"run {run.name!r}: joint {name!r} is not in the model's URDF")
        joint_ids.append(model.getJointId(name))
    if model.nq != run.q.shape[1]:
        raise ResultFileError(f"run {run.name!r}: q has {run.q.shape[1]} columns, the model nq = {model.nq}")
    kin = _Kinematics(model, visual, joint_ids, [_half_columns(run, j) for j in run.joint_names], muscles=_muscles(run, model))
    # A visual is a segment of joint j when its body is attached to joint j directly (not
    # through a fixed joint: the dumbbell keeps its colour).
    for g in visual.geometryObjects:
        frame = model.frames[g.parentFrame]
        previous = model.frames[frame.parentFrame]
        if previous.type == pin.FrameType.JOINT and g.parentJoint in joint_ids:
            kin.segment_of[g.name] = joint_ids.index(g.parentJoint)
            if g.meshPath.lower().endswith(".dae") and hasattr(g.geometry, "num_tris"):
                kin.triangle_meshes.add(g.name)
    return kin


def _muscles(run: RunResult, model: Any) -> list[tuple[str, int, list[tuple[int, np.ndarray]]]]:
    """The muscles of a muscle run on ``model``'s frames (none for a run of torque halves)."""
    if not run.muscle_names:
        return []
    from fatigue_pin.core.errors import FatiguePinError
    from fatigue_pin.muscles.files import read_muscles

    try:
        muscles = read_muscles(run.muscles, f"the muscle file stored with run {run.name!r}")
    except FatiguePinError as exc:
        raise ResultFileError(f"run {run.name!r}: its stored muscles do not load: {exc}") from None
    out = []
    for m in muscles.muscles:
        if m.name not in run.actuator_names:
            raise ResultFileError(f"run {run.name!r}: its stored muscle {m.name!r} is not one of its units {list(run.actuator_names)}")
        missing = [p.frame for p in m.points if not model.existFrame(p.frame)]
        if missing:
            raise ResultFileError(f"run {run.name!r}: muscle {m.name!r} has points on {missing}, which its model does not have")
        out.append((m.name, run.actuator_names.index(m.name),
                    [(model.getFrameId(p.frame), np.asarray(p.location, dtype=float)) for p in m.points]))
    return out


def _segment(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Placement (4 x 4) of meshcat's unit cylinder (height 1 along its y axis) drawn from a to b."""
    d = b - a
    length = float(np.linalg.norm(d))
    y = d / length if length > 1e-12 else np.array([0.0, 1.0, 0.0])
    x = np.cross(y, [0.0, 0.0, 1.0] if abs(y[2]) < 0.9 else [1.0, 0.0, 0.0])
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, y * length, np.cross(x, y), (a + b) / 2
    return T


def _poses(kin: _Kinematics, q: np.ndarray) -> dict[str, np.ndarray]:
    """World placements (4 x 4) of every visual and fatigue marker at configuration ``q``, by meshcat path."""
    import pinocchio as pin

    model, data = kin.model, kin.model.createData()
    gdata = pin.GeometryData(kin.visual)
    pin.forwardKinematics(model, data, q)
    pin.updateGeometryPlacements(model, data, kin.visual, gdata)
    out = {}
    for k, g in enumerate(kin.visual.geometryObjects):
        T = gdata.oMg[k].homogeneous.copy()
        if g.name not in kin.triangle_meshes:  # the triangles are already scaled
            T[:3, :3] = T[:3, :3] @ np.diag(g.meshScale)
        out[kin.visual_path(g.name)] = T
    for jid in kin.joint_ids:
        at_joint = data.oMi[model.parents[jid]] * model.jointPlacements[jid]
        for sign, s in (("plus", 1.0), ("minus", -1.0)):
            offset = np.array(_MARKER_OFFSET) * (s, 1.0, 1.0)
            M = at_joint * pin.SE3(np.eye(3), offset)
            out[kin.marker_path(model.names[jid], sign)] = M.homogeneous
    if kin.muscles:
        pin.updateFramePlacements(model, data)
        for name, _, points in kin.muscles:
            world = [data.oMf[f].rotation @ c + data.oMf[f].translation for f, c in points]
            for k, (a, b) in enumerate(zip(world[:-1], world[1:])):
                out[kin.muscle_path(name, k)] = _segment(a, b)
    return out


def _colors(kin: _Kinematics, mf_row: np.ndarray) -> dict[str, np.ndarray]:
    """RGB of every fatigue marker and coloured segment for one node of ``mf`` (halves,), by meshcat path."""
    out = {}
    def mf(j: int) -> tuple[float, float]:  # a passive joint never tires: drawn rested
        cols = kin.halves[j]
        return (0.0, 0.0) if cols is None else (mf_row[cols[0]], mf_row[cols[1]])

    for j, jid in enumerate(kin.joint_ids):
        name, (p, m) = kin.model.names[jid], mf(j)
        out[kin.marker_path(name, "plus")] = fatigue_color(p)
        out[kin.marker_path(name, "minus")] = fatigue_color(m)
    for gname, j in kin.segment_of.items():
        out[kin.visual_path(gname)] = fatigue_color(max(mf(j)))
    for name, column, points in kin.muscles:
        for k in range(len(points) - 1):
            out[kin.muscle_path(name, k)] = fatigue_color(mf_row[column])
    return out


# -- scene ---------------------------------------------------------------------------------------


class _Recorder:
    """Stand-in for a meshcat ``ViewerWindow``: keeps the commands, in order, instead of sending them."""

    def __init__(self) -> None:
        self.commands: list[Any] = []
        self.web_url = ""

    def send(self, command: Any) -> None:
        self.commands.append(command)


@dataclass
class ReplayScene:
    """A recorded meshcat scene of one run and its animation.

    Attributes:
        run_name: the run.
        cycles: the 0-based cycles animated, in play order.
        fps: frame rate of the meshcat clip (frames per second).
        n_frames: number of frames (one per node; consecutive cycles share their boundary node).
        frame_times_s: time of every frame in the animation (s), (n_frames,): the nodes' times,
            so the animation plays in real time.
        cycle_frames: (first, last) frame index of each animated cycle, both included.
        visualizer: ``meshcat.Visualizer`` whose window records the commands.
        animation: the ``meshcat.animation.Animation`` (poses and colours of every frame).
        frames: per frame, the meshcat path -> placement (4 x 4) and path -> RGB dictionaries.
        readouts: every joint's position at every frame, as the overlay shows it.
    """

    run_name: str
    cycles: list[int]
    fps: int
    n_frames: int
    frame_times_s: np.ndarray
    cycle_frames: list[tuple[int, int]]
    visualizer: Any
    animation: Any
    frames: list[tuple[dict[str, np.ndarray], dict[str, np.ndarray]]] = field(repr=False)
    readouts: tuple["JointReadout", ...] = field(default=(), repr=False)

    @property
    def duration_s(self) -> float:
        """Length of the animation (s)."""
        return float(self.frame_times_s[-1])

    @property
    def cycle_start_s(self) -> np.ndarray:
        """Start time (s) of each animated cycle in the animation, (len(cycles),)."""
        return self.frame_times_s[[first for first, _ in self.cycle_frames]]

    @property
    def scene_commands(self) -> list[Any]:
        """The recorded meshcat commands that build the scene (objects, first frame, camera)."""
        return list(self.visualizer.window.commands)


@dataclass(frozen=True)
class JointReadout:
    """One joint's position at every frame of a replay, in the unit it is shown in.

    Attributes:
        joint: the joint's name.
        unit: ``deg`` (revolute joint) or ``m`` (prismatic joint), :attr:`JointUnits.display_position`.
        digits: decimals shown.
        values: the position at every frame in ``unit``, (n_frames,).
    """

    joint: str
    unit: str
    digits: int
    values: np.ndarray = field(repr=False)


def joint_readouts(run: RunResult, nodes: np.ndarray) -> tuple[JointReadout, ...]:
    """Every joint's position at ``nodes`` (node indices), revolute joints in deg and prismatic
    joints in m (:meth:`RunResult.joint_units`)."""
    out = []
    for j, joint in enumerate(run.joint_names):
        u = run.joint_units(j)
        out.append(JointReadout(joint, u.display_position, u.display_digits, u.display(run.q[nodes, j])))
    return tuple(out)


def _set_camera(vis: Any, target: np.ndarray, eye: np.ndarray) -> None:
    """Centre the view on ``target`` and put the camera at ``eye`` (world frame, m).

    meshcat 0.3.2's orbit controls always look at the world origin, so the model's root node is
    shifted by ``-target`` instead of moving the camera target. The camera lives in a frame
    rotated by Rx(pi/2): world (x, y, z) is (x, z, -y) there.
    """
    shift = np.eye(4)
    shift[:3, 3] = -np.asarray(target, dtype=float)
    vis[ROOT].set_transform(shift)
    d = np.asarray(eye, dtype=float) - np.asarray(target, dtype=float)
    vis["/Cameras/default/rotated/<object>"].set_property("position", [float(d[0]), float(d[2]), float(-d[1])])


def _camera_for(frames: list[tuple[dict[str, np.ndarray], dict[str, np.ndarray]]]) -> tuple[np.ndarray, np.ndarray]:
    """Camera (target, eye), world frame (m): beside the model (lateral, -y for arm26) and a little
    in front of and above it, at the distance where the whole motion fills the view."""
    pts = np.array([T[:3, 3] for poses, _ in frames[:: max(1, len(frames) // 100)] for T in poses.values()])
    lo, hi = pts.min(axis=0) - 0.12, pts.max(axis=0) + 0.12
    target = (lo + hi) / 2
    half = float(np.max(hi - lo)) / 2
    direction = np.array([0.55, -0.8, 0.3])
    distance = 1.5 * half / np.tan(np.radians(37.5))  # meshcat's camera: 75 deg vertical field of view
    return target, target + direction / np.linalg.norm(direction) * distance


def select_cycles(run: RunResult, cycles: Sequence[int] | None) -> list[int]:
    run.require_cycles("replay")
    chosen = list(range(run.n_cycles)) if cycles is None else [int(c) for c in cycles]
    if not chosen:
        raise ResultFileError(f"run {run.name!r}: no cycle to replay")
    for c in chosen:
        run.cycle_slice(c)  # raises a clear error when out of range
    return chosen


def _frame_nodes(run: RunResult, cycles: list[int]) -> tuple[np.ndarray, np.ndarray, list[tuple[int, int]]]:
    """Node index and time (s) of every frame, and the (first, last) frame of each cycle: each
    cycle's nodes in turn, the boundary node of two consecutive cycles once; a jump between
    non-consecutive cycles takes one interval."""
    nodes: list[int] = []
    times: list[float] = []
    spans: list[tuple[int, int]] = []
    for c in cycles:
        s = run.cycle_slice(c)
        idx = list(range(s.start, s.stop))
        t = list(run.t[s] - run.t[s.start] + (times[-1] if times else 0.0))
        if nodes and nodes[-1] == idx[0]:
            idx, t = idx[1:], t[1:]
            spans.append((len(nodes) - 1, len(nodes) + len(idx) - 1))
        else:
            if times:
                t = [v + float(run.t[s.start + 1] - run.t[s.start]) for v in t]
            spans.append((len(nodes), len(nodes) + len(idx) - 1))
        nodes.extend(idx)
        times.extend(t)
    return np.asarray(nodes), np.asarray(times), spans


def _send_triangle_meshes(vis: Any, kin: _Kinematics) -> None:
    """Replace the Collada objects of coloured segments by their triangles with a Phong material
    (see :attr:`_Kinematics.triangle_meshes`); the Collada commands are dropped from the record."""
    if not kin.triangle_meshes:
        return
    import meshcat.geometry as mg
    from pinocchio.visualize.meshcat_visualizer import loadMesh

    paths = {kin.visual_path(name) for name in kin.triangle_meshes}
    full = {vis[p].path.lower() for p in paths}
    vis.window.commands = [c for c in vis.window.commands
                           if not (type(c).__name__ in ("SetObject", "DaeMeshGeometry") and getattr(c, "path", None) is not None
                                   and c.path.lower() in full)]
    for g in kin.visual.geometryObjects:
        if g.name in kin.triangle_meshes:
            rgb = np.clip(np.asarray(g.meshColor[:3], dtype=float), 0.0, 1.0)
            color = int(round(255 * rgb[0])) * 65536 + int(round(255 * rgb[1])) * 256 + int(round(255 * rgb[2]))
            vis[kin.visual_path(g.name)].set_object(loadMesh(g.geometry), mg.MeshPhongMaterial(color=color))


def build_animation(run: RunResult, cycles: list[int] | None = None, fps: int = 50) -> ReplayScene:
    """Meshcat scene of ``run`` (visuals, fatigue markers, camera) and its animation.

    Args:
        run: an OCP run; its ``urdf`` attribute gives the model (bundled arm26 if empty).
        cycles: 0-based cycles to animate, in play order (default: all).
        fps: frame rate of the meshcat clip; keys sit at the nodes' times (every 0.02 s in the
            paper's task), so the playback is in real time whatever the rate.

    Returns:
        The recorded scene; nothing is sent anywhere (see :func:`export_html`, :func:`serve`).
    """
    import meshcat
    import meshcat.geometry as mg
    from meshcat.animation import Animation
    from pinocchio.visualize import MeshcatVisualizer

    chosen = select_cycles(run, cycles)
    kin = _kinematics(run)
    nodes, times, spans = _frame_nodes(run, chosen)
    frames = [(_poses(kin, run.q[k]), _colors(kin, run.fatigued[k])) for k in nodes]

    vis = meshcat.Visualizer(window=_Recorder())
    viz = MeshcatVisualizer(kin.model, None, kin.visual)
    viz.initViewer(viewer=vis)
    viz.loadViewerModel(rootNodeName=ROOT)
    _send_triangle_meshes(vis, kin)
    for jid in kin.joint_ids:
        for sign in ("plus", "minus"):
            path = kin.marker_path(kin.model.names[jid], sign)
            vis[path].set_object(mg.Sphere(_MARKER_RADIUS), mg.MeshPhongMaterial(color=0x26b340))
    for name, _, points in kin.muscles:
        for k in range(len(points) - 1):
            vis[kin.muscle_path(name, k)].set_object(mg.Cylinder(1.0, _MUSCLE_RADIUS), mg.MeshPhongMaterial(color=0x26b340))
    poses0, colors0 = frames[0]
    for path, T in poses0.items():
        vis[path].set_transform(T)
    for path, rgb in colors0.items():
        vis[path].set_property("color", [*map(float, rgb), 1.0])
    vis["/Axes"].set_property("visible", False)
    vis["/Grid"].set_property("visible", False)
    _set_camera(vis, *_camera_for(frames))

    anim = Animation(default_framerate=fps)
    for t, (poses, colors) in zip(times, frames):
        with anim.at_frame(vis, float(t * fps)) as frame:
            for path, T in poses.items():
                frame[path].set_transform(T)
            for path, rgb in colors.items():
                frame[path]["<object>"].set_property("material.color", "color", [float(v) for v in rgb])

    return ReplayScene(run.name, chosen, fps, len(frames), times, spans, vis, anim, frames, joint_readouts(run, nodes))


# -- static HTML ---------------------------------------------------------------------------------

_OVERLAY = """
<div id="fp-overlay" style="position:fixed;left:10px;top:10px;font:14px sans-serif;color:#222;
     background:rgba(255,255,255,0.8);padding:6px 10px;border-radius:4px;pointer-events:none">
  <div><b id="fp-title"></b></div>
  <div id="fp-cycle" style="font-size:20px;margin:2px 0"></div>
  <div id="fp-joints" style="font-size:12px;margin:2px 0;white-space:pre"></div>
  <div style="display:flex;align-items:center;gap:6px">mf 0
    <span style="display:inline-block;width:120px;height:10px;background:linear-gradient(to right,__SCALE__)"></span> 1</div>
  <div style="font-size:11px">spheres: plus half (front; flexion) / minus half (back; extension) of each joint;<br>
    segments: the more fatigued half of their joint</div>
</div>
"""

_PLAYER_JS = """
var viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));
(function () {
  var meta = __META__;
  var commands = __COMMANDS__;
  for (var i = 0; i < commands.length; i++) {
    var s = atob(commands[i]), a = new Uint8Array(s.length);
    for (var k = 0; k < s.length; k++) a[k] = s.charCodeAt(k);
    viewer.handle_command_bytearray(a);
  }
  document.getElementById("fp-title").textContent = meta.title;
  var label = document.getElementById("fp-cycle");
  var joints = document.getElementById("fp-joints");
  function update() {
    var acts = viewer.animator.actions, t = acts.length ? acts[0].time : 0, j = 0;
    while (j + 1 < meta.starts.length && t >= meta.starts[j + 1] - 1e-9) j++;
    label.textContent = "cycle " + meta.cycles[j] + " of " + meta.n_cycles + "   t = " + t.toFixed(2) + " s";
    var lo = 0, hi = meta.times.length - 1;  // the last frame at or before t
    while (lo < hi) { var mid = (lo + hi + 1) >> 1; if (meta.times[mid] <= t + 1e-9) lo = mid; else hi = mid - 1; }
    joints.textContent = meta.joints.map(function (q) {
      return q.name + " " + q.values[lo].toFixed(q.digits) + " " + q.unit;
    }).join("   ");
    requestAnimationFrame(update);
  }
  update();
})();
"""


def _packed(command: Any) -> str:
    import umsgpack

    return base64.b64encode(umsgpack.packb(command.lower())).decode("ascii")


def scene_html(scene: ReplayScene, n_cycles: int, loop: bool = True) -> str:
    """Self-contained HTML page of a recorded scene and its animation (meshcat's viewer inlined)."""
    import meshcat
    from meshcat.commands import SetAnimation

    js_path = Path(meshcat.__file__).parent / "viewer" / "dist" / "main.min.js"
    commands = [*scene.scene_commands, SetAnimation(scene.animation, play=True, repetitions=float("inf") if loop else 1)]
    meta = {
        "title": f"fatigue_pin replay: {scene.run_name}",
        "cycles": [c + 1 for c in scene.cycles],
        "n_cycles": n_cycles,
        "starts": [float(s) for s in scene.cycle_start_s],
        "times": [round(float(t), 6) for t in scene.frame_times_s],
        "joints": [{"name": r.joint, "unit": r.unit, "digits": r.digits,
                    "values": [round(float(v), r.digits + 2) for v in r.values]} for r in scene.readouts],
    }
    player = _PLAYER_JS.replace("__META__", json.dumps(meta).replace("</", "<\\/")).replace(
        "__COMMANDS__", json.dumps([_packed(c) for c in commands])
    )
    scale = ",".join("rgb({},{},{})".format(*(round(255 * v) for v in rgb)) for rgb in FATIGUE_COLORS)
    return (
        "<!DOCTYPE html>\n<html>\n<head><meta charset=\"utf-8\"><title>"
        + html.escape(meta["title"])
        + "</title>\n<style>body{margin:0} #meshcat-pane{width:100vw;height:100vh;overflow:hidden}</style>\n</head>\n<body>\n"
        + '<div id="meshcat-pane"></div>\n'
        + _OVERLAY.replace("__SCALE__", scale)
        + "<script>\n"
        + js_path.read_text()
        + "\n</script>\n<script>\n"
        + player
        + "</script>\n</body>\n</html>\n"
    )


def export_html(run: RunResult, out_html: Path, cycles: list[int] | None = None, loop: bool = True) -> Path:
    """Write a self-contained HTML replay of ``run`` (no server needed; opens in any browser).

    Args:
        run: the OCP run.
        out_html: output file (parent folders are created).
        cycles: 0-based cycles to play (default: all).
        loop: replay forever (True) or once, then rest at the first frame.

    Returns:
        ``out_html``.
    """
    scene = build_animation(run, cycles)
    out = Path(out_html)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(scene_html(scene, run.n_cycles, loop), encoding="utf-8")
    return out
