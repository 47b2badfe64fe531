"""The task checks of ``fatigue-pin verify``: every item of the stored study's
:class:`~fatigue_pin.ocp.task.Task`, evaluated on the stored nodes with numeric Pinocchio
(``pinocchio.framesForwardKinematics``, ``data.oMf``) on the model the run was solved on.

One report line per item kind the task holds, the worst violation over its items and nodes
(beyond the item's own tolerance; 0 when every node meets it):

============================  ================================================  ======
kind                          violation at a node k of the item                  unit
============================  ================================================  ======
``JointTarget``               ``|q_j,k - value| - tolerance`` (and
                              ``|qdot_j,k - velocity| - velocity_tolerance``)    rad (rad/s), or m (m/s)
``StateTarget``               ``|x_s,k - value| - tolerance``, state s by name   its unit
``JointRange``                ``max(lower - q_j,k, q_j,k - upper)``              rad or m
``FrameTarget``               ``FrameTarget.distance(p_k)`` (ball or box)        m
``FramePlane``                ``-FramePlane.height(p_k)``                        m
``FrameOrientation``          ``angle(R_k, rotation) - tolerance``               rad
============================  ================================================  ======

(a joint line's unit is its joints': rad for revolute joints, m for prismatic ones,
``rad or m`` when its items name both; and rad/s or m/s for velocity targets), with ``p_k``, ``R_k`` the frame's world position and
rotation at node k, and the nodes
:meth:`Task.nodes` gives for the item's phase (every node for ranges and planes without a phase);
for a sliding run, the nodes its windows gave the phase
(:func:`~fatigue_pin.drivers.sliding.stitched_nodes`: a window's node 0 is its start state).
For a closed-loop run (horizon ``mpc``), the plant's, the task lines check the nodes of the cycles
the run counts as repetitions (its ``repetitions`` attribute: nodes 0 to ``repetitions n``), with
the tolerance it counted them with (its ``target_tolerance``, rad or m) in place of ``--task-tol``:
the claim a closed-loop run makes is that the plant met its task within that tolerance in those
cycles (:meth:`fatigue_pin.drivers.mpc.ClosedLoop.repetitions`), not that a noisy plant driven by
feed-forward torques met it to 1e-4. A run that counts no repetition has its task lines "not
checked", with a note; the initial state keeps ``--task-tol`` (the plant starts at it exactly).
A kind verify does not know (e.g. a Python :class:`StateConstraint`, whose expression is the
package's own CasADi) is shown as "not checked", with a note naming it. The initial state is
checked against the task's initial configuration, its initial velocities (``qdot_init``, default
zero) and every half at rest.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from fatigue_pin.core.errors import FatiguePinError
from fatigue_pin.robot.units import JointUnits
from fatigue_pin.ocp.task import FrameOrientation, FramePlane, FrameTarget, JointRange, JointTarget, StateTarget, phase_label
from fatigue_pin.verify.report import VerifyCheck, worst
from fatigue_pin.verify.stored import Stored
from fatigue_pin.core.text import shown

__all__ = ["task_checks", "KINDS"]

Violation = tuple[float, str]  # (worst violation of one item, where)


class _Frames:
    """World placements of the frames the task names, at every stored node (numeric Pinocchio)."""

    def __init__(self, model, q: np.ndarray) -> None:
        self.model, self.q = model, q
        self._placements: dict[str, tuple[np.ndarray, np.ndarray]] = {}

    def placements(self, frame: str) -> tuple[np.ndarray, np.ndarray]:
        """Positions (nodes, 3) in m and rotations (nodes, 3, 3) of ``frame`` (NaN at non-finite nodes)."""
        if frame not in self._placements:
            import pinocchio as pin

            from fatigue_pin.robot.kinematics import frame_id

            fid = frame_id(self.model, frame)
            data = self.model.createData()
            p = np.full((self.q.shape[0], 3), np.nan)
            R = np.full((self.q.shape[0], 3, 3), np.nan)
            for k, qk in enumerate(self.q):
                if np.all(np.isfinite(qk)):
                    pin.framesForwardKinematics(self.model, data, qk)
                    p[k], R[k] = data.oMf[fid].translation, data.oMf[fid].rotation
            self._placements[frame] = (p, R)
        return self._placements[frame]


@dataclass
class _Context:
    q: np.ndarray  # (nodes, nq)
    joints: list[str]
    units: list[JointUnits]  # the units of every joint of ``joints``
    frames: _Frames
    nodes: Callable[[float | None], list[int]]  # nodes of a phase (None: every node)
    states: dict[str, np.ndarray]  # every state by its layout name ("elbow_q", "elbow_qdot", "elbow_plus_mf"), (nodes,)


def _worst_at(values: np.ndarray, nodes: list[int], describe: str) -> Violation:
    values = np.asarray(values, dtype=float)
    if not nodes or not np.isfinite(values).any():
        return -math.inf, ""
    i = int(np.nanargmax(values))
    return float(values[i]), f"node {nodes[i]}, {describe}"


def _joint(item, ctx: _Context) -> np.ndarray:
    if item.joint not in ctx.joints:
        raise FatiguePinError(f"joint {item.joint!r} is not a joint of the run {ctx.joints}")
    return ctx.q[:, ctx.joints.index(item.joint)]


def _joint_target(item: JointTarget, ctx: _Context) -> Violation:
    nodes = ctx.nodes(item.at)
    out: Violation = (-math.inf, "")
    if item.value is not None:
        v = np.abs(_joint(item, ctx)[nodes] - item.value) - item.tolerance
        out = max(out, _worst_at(v, nodes, f"{item.joint} at {item.value:.6g}"), key=lambda r: r[0])
    if item.velocity is not None:
        _joint(item, ctx)
        v = np.abs(ctx.states[f"{item.joint}_qdot"][nodes] - item.velocity) - item.velocity_tolerance
        out = max(out, _worst_at(v, nodes, f"{item.joint} moving at {item.velocity:.6g}"), key=lambda r: r[0])
    return out


def _state_target(item: StateTarget, ctx: _Context) -> Violation:
    if item.state not in ctx.states:
        raise FatiguePinError(f"state {item.state!r} is not a state of the run {sorted(ctx.states)}")
    nodes = ctx.nodes(item.at)
    v = np.abs(ctx.states[item.state][nodes] - item.value) - item.tolerance
    return _worst_at(v, nodes, f"{item.state} at {item.value:.6g} (phase {phase_label(item.at)})")


def _joint_range(item: JointRange, ctx: _Context) -> Violation:
    q = _joint(item, ctx)
    nodes = ctx.nodes(None)
    return _worst_at(np.maximum(item.lower - q, q - item.upper), nodes, f"{item.joint} in [{item.lower:.6g}, {item.upper:.6g}]")


def _frame_target(item: FrameTarget, ctx: _Context) -> Violation:
    nodes = ctx.nodes(item.at)
    p, _ = ctx.frames.placements(item.frame)
    v = [item.distance(p[k]) if np.all(np.isfinite(p[k])) else np.nan for k in nodes]
    axes = "" if len(item.axes) == 3 else f", axes {''.join(item.axes)}"
    return _worst_at(v, nodes, f"{item.frame} at {shown(item.position)} +- {item.tolerance:g} m ({item.shape}{axes})")


def _frame_plane(item: FramePlane, ctx: _Context) -> Violation:
    nodes = ctx.nodes(item.at)
    p, _ = ctx.frames.placements(item.frame)
    v = [-item.height(p[k]) for k in nodes]
    return _worst_at(v, nodes, f"{item.frame} on {shown(np.round(item.normal, 6))} . p >= {item.offset:g} m")


def _frame_orientation(item: FrameOrientation, ctx: _Context) -> Violation:
    nodes = ctx.nodes(item.at)
    _, R = ctx.frames.placements(item.frame)
    cos = [(np.trace(item.matrix.T @ R[k]) - 1.0) / 2.0 for k in nodes]
    angle = np.arccos(np.clip(np.asarray(cos, dtype=float), -1.0, 1.0))
    return _worst_at(angle - item.tolerance, nodes, f"{item.frame} within {item.tolerance:g} rad of its rotation")


@dataclass(frozen=True)
class Kind:
    """A task item kind verify checks: its report line, unit ("joint": the position unit of its
    items' joints) and evaluation."""

    line: str
    unit: str
    evaluate: Callable[[Any, _Context], Violation]


#: The task item kinds verify checks, in report order.
KINDS: dict[type, Kind] = {
    JointTarget: Kind("task joint targets", "joint", _joint_target),
    JointRange: Kind("task joint ranges", "joint", _joint_range),
    StateTarget: Kind("task state targets", "", _state_target),
    FrameTarget: Kind("task frame targets", "m", _frame_target),
    FramePlane: Kind("task frame planes", "m", _frame_plane),
    FrameOrientation: Kind("task frame orientations", "rad", _frame_orientation),
}


def _unit(kind: Kind, items: list, ctx: _Context) -> str:
    """The unit of a kind's line: its own, or for joint items their joints' (``rad``, ``m``, ``rad
    or m``; with velocity targets also ``rad/s``, ``m/s``)."""
    if kind.unit != "joint":
        return kind.unit
    units = []
    for item in items:
        if item.joint in ctx.joints:
            u = ctx.units[ctx.joints.index(item.joint)]
            units += [u.position] if getattr(item, "value", 0.0) is not None else []
            units += [u.velocity] if getattr(item, "velocity", None) is not None else []
    return " or ".join(dict.fromkeys(units)) or "rad or m"


def _kind_line(kind: Kind, items: list, ctx: _Context, tol: float, notes: list[str]) -> VerifyCheck:
    """The worst violation over the items of one kind (NaN with a note if one cannot be evaluated)."""
    unit = _unit(kind, items, ctx)
    value, where = -math.inf, ""
    for item in items:
        try:
            v, at = kind.evaluate(item, ctx)
        except FatiguePinError as exc:
            notes.append(f"{kind.line}: {' '.join(str(exc).split())}: not checked")
            return VerifyCheck(kind.line, float("nan"), unit, tol, "not checked")
        if v > value:
            value, where = v, at
    return VerifyCheck(kind.line, max(value, 0.0), unit, tol, where if value > 0 else f"{len(items)} item(s), every node met")


def task_checks(s: Stored, tol: float, notes: list[str]) -> list[VerifyCheck]:
    """One line per task item kind of the stored task, a "not checked" line per unknown kind, and
    the initial state (see the module docstring). Without a stored task: "not checked" lines."""
    if s.task is None:
        return [VerifyCheck("task", float("nan"), "", tol, "not checked"), VerifyCheck("initial state", float("nan"), "", tol, "not checked")]
    task = s.task
    nodes = _phase_nodes(s, notes)
    item_tol, counted = tol, None
    if s.horizon == "mpc":
        item_tol, counted = _closed_loop_scope(s, tol, notes)
        nodes = _within(nodes, counted * s.n) if counted is not None else nodes
    q, qdot = np.asarray(s.run.q, dtype=float), np.asarray(s.run.qdot, dtype=float)
    states = {**{f"{j}_q": q[:, i] for i, j in enumerate(s.joints)}, **{f"{j}_qdot": qdot[:, i] for i, j in enumerate(s.joints)},
              **{f"{h.name}_{name}": s.M[:, s.offsets[k] + i] for k, h in enumerate(s.halves) for i, name in enumerate(h.states)}}
    units = [s.run.joint_units(j) for j in range(len(s.joints))]
    ctx = _Context(q, s.joints, units, _Frames(s.robot.pin_model, q), nodes, states)
    checks = []
    for cls, kind in KINDS.items():
        items = [i for i in task.items if type(i) is cls]
        if items and counted == 0:
            checks.append(VerifyCheck(kind.line, float("nan"), _unit(kind, items, ctx), item_tol, "not checked"))
        elif items:
            checks.append(_kind_line(kind, items, ctx, item_tol, notes))
    unknown: dict[str, int] = {}
    for item in task.items:
        if type(item) not in KINDS:
            unknown[type(item).__name__] = unknown.get(type(item).__name__, 0) + 1
    for name, count in unknown.items():
        checks.append(VerifyCheck(f"task {name}", float("nan"), "", tol, "not checked"))
        notes.append(f"task items of kind {name} ({count}) not checked: verify evaluates "
                     f"{', '.join(c.__name__ for c in KINDS)}")
    if not task.items:
        notes.append("the stored task has no items: only the initial state is checked")
    checks.append(_initial_state(s, tol, notes))
    return checks


def _closed_loop_scope(s: Stored, tol: float, notes: list[str]) -> tuple[float, int | None]:
    """The tolerance of a closed-loop run's task lines and the cycles they check: its
    ``target_tolerance`` and ``repetitions`` (``tol`` and every stored cycle, with a note, for a
    run that lacks them)."""
    a = s.run.attrs
    try:
        target, counted = float(a["target_tolerance"]), int(a["repetitions"])
    except (KeyError, TypeError, ValueError):
        notes.append("closed-loop run without target_tolerance and repetitions attributes: its task is checked on every "
                     f"stored cycle with the task tolerance {tol:g}")
        return tol, None
    if not math.isfinite(target) or target < 0:
        notes.append(f"closed-loop run with target_tolerance = {target:g}: its task is checked with the task tolerance {tol:g}")
        target = tol
    counted = max(0, min(counted, s.N // s.n))
    if counted == 0:
        notes.append("closed-loop run that counts no repetition: its task is not checked (it claims no cycle)")
    else:
        notes.append(f"closed-loop run: the task is checked on the {counted} cycle(s) it counts as repetitions (nodes 0-"
                     f"{counted * s.n}), within its target_tolerance {target:g} (rad or m)")
    return target, counted


def _within(nodes: Callable[[float | None], list[int]], last: int) -> Callable[[float | None], list[int]]:
    """``nodes`` restricted to the nodes up to ``last``."""
    return lambda at: [k for k in nodes(at) if k <= last]


def _phase_nodes(s: Stored, notes: list[str]) -> Callable[[float | None], list[int]]:
    """The nodes of a phase: :meth:`Task.nodes` over the run, or, for a sliding run with its
    window table, the nodes its windows put the phase on
    (:func:`~fatigue_pin.drivers.sliding.stitched_nodes`)."""
    task, run = s.task, s.run
    whole = lambda at: task.nodes(at, s.N)  # noqa: E731
    if s.horizon != "sliding" or run.windows is None:
        return whole
    try:
        window, advance = int(run.attrs["window"]), int(run.attrs["advance"])
        first = [int(c) for c in np.asarray(run.windows["first_cycle"])[np.asarray(run.windows["converged"], dtype=bool)]]
    except (KeyError, TypeError, ValueError):
        first = []
    if not first or (first[-1] + window) * s.n != s.N:
        notes.append("sliding run without a window table that matches its nodes: the task is checked on the nodes of one "
                     "horizon of its length")
        return whole
    from fatigue_pin.drivers.sliding import stitched_nodes

    return lambda at: stitched_nodes(task, at, window, advance, first)


def _initial_state(s: Stored, tol: float, notes: list[str]) -> VerifyCheck:
    """abs(x_0 - (q_init, qdot_init, rest state of each half))."""
    try:
        q0, v0 = s.task.initial_configuration(s.robot), s.task.initial_velocity(s.robot)
    except FatiguePinError as exc:
        notes.append(f"initial state not checked: {exc}")
        return VerifyCheck("initial state", float("nan"), "", tol, "not checked")
    rest = np.concatenate([h.model.rest_state() for h in s.halves]) if s.halves else np.zeros(0)
    err = np.concatenate([np.abs(s.run.q[0] - q0), np.abs(s.run.qdot[0] - v0), np.abs(s.M[0] - rest)])
    value, where = worst(err[None, :], s.x_labels, "node")
    return VerifyCheck("initial state", value, "", tol, where or "node 0")
