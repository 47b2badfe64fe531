"""What the body must do every cycle: a set of constraints placed on the nodes of the cycle.

A task is a list of constraint items, each ``(expression of the state at some nodes, lower,
upper)``. Items that bound one state entry (a joint at a phase, a joint range) become variable
bounds of the NLP (cheap, and IPOPT handles them as simple bounds); items with a general
expression (``expression`` of :class:`StateConstraint`) become constraint rows whose bounds are
NLP parameters. Kinds:

* :class:`JointTarget`: joint ``joint`` at ``value`` (+- ``tolerance``) at phase ``at`` of every
  cycle (the curl is two of these: the elbow at 15 deg at phase 0 and at 150 deg at phase 0.5);
* :class:`JointRange`: joint ``joint`` within ``[lower, upper]`` at every node;
* :class:`StateConstraint`: any expression of the state (a ``casadi.Function`` of x, built by the
  caller from the model) within bounds at a phase, or at every node;
* :class:`FrameTarget`, :class:`FramePlane`, :class:`FrameOrientation`: Cartesian items (a frame
  at a point within a ball or box, a frame above a plane, a frame's orientation); each builds its
  :class:`StateConstraint` from the model's frame kinematics (``constraint(model, layout)``,
  gathered by :meth:`Task.expression_constraints`);
* the cyclic end condition of a sliding-horizon window is added by the horizon driver
  (``end_tolerance`` of :class:`fatigue_pin.ocp.transcription.Ocp`).

Phases are fractions of the cycle in [0, 1); ``at * intervals_per_cycle`` must be a node.
A target at phase 0 also applies to the end of the last cycle (node N, or N + ``final_node_offset``).

A task need not be cyclic (``cyclic = False``, or any item at ``at = "end"``, :data:`END`): each
cycle is then a phase with an end of its own, a point-to-point motion. Its items at ``"end"``
apply to the last node of every phase (nodes n, 2n, ..., N for n intervals per phase), its
phase-0 items to the first node of every phase only (not to node N), and the horizon drivers put
no cyclic end box on its windows. :class:`JointTarget` also bounds velocities (``velocity``), and
:class:`StateTarget` any state by name (a fatigue state such as ``"slider_plus_mf"``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from fatigue_pin.core.errors import ParameterError, TaskError
from fatigue_pin.core.text import shown
from fatigue_pin.ocp.task_items import (  # noqa: F401  (the items, importable from here as before)
    END, FRAME_TARGET_SHAPES, FrameOrientation, FramePlane, FrameTarget, JointRange, JointTarget, Phase, StateConstraint,
    StateTarget, TaskItem, _finite, _item_label, _target_text, phase_label, phase_value,
)

#: Most shooting intervals of one OCP (a cycle, or all the cycles of a horizon): beyond it the
#: NLP would not fit in memory (arm26: 16 states and 4 controls per interval).
MAX_INTERVALS = 1_000_000


def check_horizon(task: "Task", n_cycles: object, what: str = "cycles") -> int:
    """``n_cycles`` as an int, once it is a whole number >= 1 whose OCP (``n_cycles *
    intervals_per_cycle`` intervals) stays within :data:`MAX_INTERVALS`; ParameterError naming
    ``what`` otherwise (checked before anything is built or compiled)."""
    if isinstance(n_cycles, bool) or not isinstance(n_cycles, (int, np.integer)) or n_cycles < 1:
        raise ParameterError(f"{what} = {shown(n_cycles)}: expected an integer number of cycles >= 1")
    n = int(n_cycles)
    if n * task.intervals_per_cycle > MAX_INTERVALS:
        raise ParameterError(f"{what} = {n}: {n} cycles of {task.intervals_per_cycle} intervals are {n * task.intervals_per_cycle} "
                             f"shooting intervals; expected at most {MAX_INTERVALS} in one OCP")
    return n


@dataclass(frozen=True)
class Task:
    """A task: the cycle's timing, its constraints and the initial state.

    Attributes:
        cycle_duration: duration of one cycle (phase) (s).
        intervals_per_cycle: shooting intervals per cycle.
        items: the constraints (:class:`JointTarget`, :class:`JointRange`, :class:`StateTarget`,
            :class:`StateConstraint`, frame items).
        q_init: initial configuration (rad or m), shape (nq,); ``None``: every joint at 0, or at
            its phase-0 target where it has one. A given q_init must meet the phase-0 targets
            within their tolerances (node 0 is theirs too; :meth:`check_start`).
        final_node_offset: (cyclic tasks) targets at phase 0 apply to the end of the last cycle
            at node N + offset (0, or -1 to impose it one node before the end).
        given_start: every solve gives the start state (a closed loop's window that starts
            mid-cycle from the measured state, :func:`fatigue_pin.drivers.mpc.phase_shifted`):
            the task has no start posture of its own (``q_init`` must be None), and
            :meth:`check` checks none against the phase-0 items and the planes (node 0 is the
            given state, which wins over them: :meth:`Ocp.state_bounds`,
            :meth:`Ocp.parameter_vector`). Not a study key.
        qdot_init: initial velocities (rad/s or m/s), shape (nv,); ``None``: at rest.
        cyclic: whether each cycle ends where the next starts (its phase-0 items bind the last
            node too, and sliding windows end in a box around their start); ``False``: every
            cycle is a phase with an end of its own (items at ``"end"`` bind its last node).
            ``None`` (default): cyclic unless an item is at ``"end"``.
    """

    cycle_duration: float
    intervals_per_cycle: int
    items: tuple[TaskItem, ...] = ()
    q_init: tuple[float, ...] | None = None
    final_node_offset: int = 0
    given_start: bool = field(default=False, metadata={"study": False})
    qdot_init: tuple[float, ...] | None = None
    cyclic: bool | None = None

    def __post_init__(self) -> None:
        d = _finite("Task", "cycle_duration", self.cycle_duration, "a duration in seconds > 0")
        if d <= 0:
            raise TaskError(f"Task.cycle_duration = {shown(self.cycle_duration)}: expected a duration in seconds > 0")
        object.__setattr__(self, "cycle_duration", d)
        n = self.intervals_per_cycle
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise TaskError(f"Task.intervals_per_cycle = {shown(n)}: expected an integer >= 1")
        if n > MAX_INTERVALS:
            raise TaskError(f"Task.intervals_per_cycle = {shown(n)}: expected an integer in [1, {MAX_INTERVALS}]")
        object.__setattr__(self, "intervals_per_cycle", int(n))
        object.__setattr__(self, "items", tuple(self.items))
        for item in self.items:
            if not isinstance(item, (JointTarget, JointRange, StateTarget, StateConstraint)) and not callable(getattr(item, "constraint", None)):
                raise TaskError(f"task item {item!r}: expected a JointTarget, JointRange, StateTarget, StateConstraint or an item "
                                "with a constraint(model, layout) method (FrameTarget, FramePlane, FrameOrientation)")
            at = getattr(item, "at", None)
            if at is not None and at != END and abs(at * n - round(at * n)) > 1e-9:
                raise TaskError(
                    f"task phase at = {shown(at)} is not a node: at * intervals_per_cycle = {at * n:g}; expected a whole number"
                )
        ends = [item for item in self.items if getattr(item, "at", None) == END]
        if self.cyclic is None:
            object.__setattr__(self, "cyclic", not ends)
        elif not isinstance(self.cyclic, (bool, np.bool_)):
            raise TaskError(f"Task.cyclic = {shown(self.cyclic)}: expected true or false")
        elif self.cyclic and ends:
            raise TaskError(f"task item {_item_label(ends[0])} is at the end, but Task.cyclic = true: a cyclic task ends where its "
                            'next cycle starts (phase 0); expected cyclic = false (or no key cyclic) for a task with an "end"')
        object.__setattr__(self, "cyclic", bool(self.cyclic))
        self._check_one_target_per_node()
        if self.final_node_offset not in (0, -1):
            raise TaskError(f"Task.final_node_offset = {shown(self.final_node_offset)}: expected 0 or -1")
        if self.final_node_offset and not self.cyclic:
            raise TaskError("Task.final_node_offset = -1 in a non-cyclic task: expected 0 (the offset moves the phase-0 targets "
                            "of a cyclic task's last node; a non-cyclic task's end has its own targets)")
        if not isinstance(self.given_start, (bool, np.bool_)):
            raise TaskError(f"Task.given_start = {shown(self.given_start)}: expected true or false")
        for name in ("q_init", "qdot_init"):
            if self.given_start and getattr(self, name) is not None:
                raise TaskError(f"Task.{name} with given_start: expected no {name} (every solve gives the start state)")
        for name in ("q_init", "qdot_init"):
            value = getattr(self, name)
            if value is not None:
                what = "a list of finite joint positions" if name == "q_init" else "a list of finite joint velocities"
                if isinstance(value, (str, bytes)) or np.ndim(value) == 0:
                    raise TaskError(f"Task.{name} = {shown(value)}: expected {what}")
                object.__setattr__(self, name, tuple(_finite("Task", name, v, what) for v in np.ravel(value)))

    def _check_one_target_per_node(self) -> None:
        """Refuse two joint targets of one joint at one node of the cycle that differ (the later
        one would replace the earlier one's bounds without a word); identical ones are one."""
        n = self.intervals_per_cycle
        seen: dict[tuple[str, object], JointTarget] = {}
        for t in self.items:
            if not isinstance(t, JointTarget):
                continue
            key = (t.joint, t.at if t.at == END else int(round(t.at * n)) % n)
            first = seen.setdefault(key, t)
            if (first.value, first.tolerance, first.velocity, first.velocity_tolerance) != (t.value, t.tolerance, t.velocity, t.velocity_tolerance):
                raise TaskError(
                    f"task targets {_target_text(first)} and {_target_text(t)} of joint {t.joint!r} at phase {phase_label(t.at)}: "
                    "expected one target per joint and phase"
                )

    def check_start(self, model, q: np.ndarray, what: str = "q_init", slack: float = 1e-9) -> None:
        """Refuse a start configuration ``q`` (nq,) that misses a target at phase 0 (the first
        node is that target's node too, and the target would override ``q`` there without a
        word): each such joint must be within the target's tolerance (+ ``slack``)."""
        for t in self.joint_targets:
            if t.at != 0.0 or t.value is None or t.joint not in model.joint_names:
                continue
            j = model.joint_names.index(t.joint)
            if abs(float(q[j]) - t.value) > t.tolerance + slack:
                raise TaskError(
                    f"task {what} = {[float(x) for x in q]} puts joint {t.joint!r} at {float(q[j])!r}, but its target at phase 0 "
                    f"is {shown(t.value)} (+- {t.tolerance:g}) {model.joint_units(j).position}; expected the start within the phase-0 target (or no {what}: "
                    "it then starts at its targets)"
                )

    @property
    def dt(self) -> float:
        """Length of one shooting interval (s)."""
        return self.cycle_duration / self.intervals_per_cycle

    @property
    def joint_targets(self) -> tuple[JointTarget, ...]:
        return tuple(i for i in self.items if isinstance(i, JointTarget))

    @property
    def joint_ranges(self) -> tuple[JointRange, ...]:
        return tuple(i for i in self.items if isinstance(i, JointRange))

    @property
    def state_constraints(self) -> tuple[StateConstraint, ...]:
        return tuple(i for i in self.items if isinstance(i, StateConstraint))

    @property
    def frame_targets(self) -> tuple[FrameTarget, ...]:
        return tuple(i for i in self.items if isinstance(i, FrameTarget))

    def expression_constraints(self, model, layout) -> tuple[StateConstraint, ...]:
        """Every constraint row of the task, in item order: its :class:`StateConstraint` items and
        the ones its other items build from the model (``item.constraint(model, layout)``: frame
        targets, planes, orientations). Names are made unique (``_2``, ``_3``, ...)."""
        out: list[StateConstraint] = []
        seen: dict[str, int] = {}
        for item in self.items:
            if isinstance(item, StateConstraint):
                sc = item
            elif callable(getattr(item, "constraint", None)):
                sc = item.constraint(model, layout)
            else:
                continue
            seen[sc.name] = seen.get(sc.name, 0) + 1
            if seen[sc.name] > 1:
                sc = StateConstraint(f"{sc.name}_{seen[sc.name]}", sc.expression, sc.lower, sc.upper, sc.at)
            out.append(sc)
        return tuple(out)

    @property
    def state_targets(self) -> tuple[StateTarget, ...]:
        return tuple(i for i in self.items if isinstance(i, StateTarget))

    def nodes(self, at: Phase | None, n_intervals: int) -> list[int]:
        """Nodes of a horizon of ``n_intervals`` intervals at phase ``at`` of every cycle (every
        node for ``None``). Cyclic: phase 0 includes the final node (N + ``final_node_offset``).
        Non-cyclic: phase 0 is the first node of every phase, :data:`END` its last (n, 2n, ..., N)."""
        n = self.intervals_per_cycle
        if at is None:
            return list(range(n_intervals + 1))
        if at == END:
            return list(range(n, n_intervals + 1, n))
        offset = int(round(at * n))
        nodes = list(range(offset, n_intervals, n))
        if offset == 0 and n_intervals > 0 and self.cyclic:
            nodes.append(n_intervals + self.final_node_offset)
        return nodes

    def check_states(self, state_names: Sequence[str]) -> None:
        """Refuse a :class:`StateTarget` naming a state that is not in ``state_names`` (the
        problem's layout, :meth:`~fatigue_pin.ocp.problem.StateLayout.state_names`)."""
        for t in self.state_targets:
            if t.state not in state_names:
                raise TaskError(f"task state target {t.state!r} is not a state of the problem; its states are {list(state_names)}")

    def check(self, model) -> None:
        """Raise TaskError if the task does not fit ``model`` (a :class:`~fatigue_pin.robot.model.RobotModel`):
        unknown joints, targets or ranges outside the joint limits, a bad initial state."""
        for item in self.items:
            if isinstance(item, (JointTarget, JointRange)):
                if item.joint not in model.joint_names:
                    raise TaskError(f"task joint {item.joint!r} is not in model {model.name!r}; its joints are {list(model.joint_names)}")
                j = model.joint_names.index(item.joint)
                lo, hi = model.q_lower[j], model.q_upper[j]
                if isinstance(item, JointTarget):
                    where = f" (at {'the end' if item.at == END else f'phase {item.at:g}'})"
                    if item.value is not None and not (lo <= item.value <= hi):
                        raise TaskError(f"task target {shown(item.value)} of joint {item.joint!r} is outside its range [{lo}, {hi}] {model.joint_units(j).position}{where}")
                    vlo, vhi = model.v_lower[j], model.v_upper[j]
                    if item.velocity is not None and not (vlo <= item.velocity <= vhi):
                        raise TaskError(f"task velocity target {shown(item.velocity)} of joint {item.joint!r} is outside its "
                                        f"velocity bounds [{vlo}, {vhi}] {model.joint_units(j).velocity}{where}")
                elif item.upper < lo or item.lower > hi:
                    raise TaskError(f"task range {shown((item.lower, item.upper))} of joint {item.joint!r} does not meet its range [{lo}, {hi}] {model.joint_units(j).position}")
        q = None if self.given_start else self.initial_configuration(model)  # given_start: no posture to check
        if q is not None:
            bad = [model.joint_names[j] for j in range(model.nq) if not (model.q_lower[j] <= q[j] <= model.q_upper[j])]
            if bad:
                raise TaskError(f"task initial configuration q_init = {q.tolist()} is outside the range of joints {bad}")
            self.check_start(model, q)
            v = self.initial_velocity(model)
            bad = [model.joint_names[j] for j in range(model.nv) if not (model.v_lower[j] <= v[j] <= model.v_upper[j])]
            if bad:
                raise TaskError(f"task initial velocities qdot_init = {v.tolist()} are outside the velocity bounds of joints {bad}")
        for item in self.items:  # frame targets, planes, orientations: unknown frames, reach (and the start posture)
            if not isinstance(item, (JointTarget, JointRange, StateTarget, StateConstraint)) and callable(getattr(item, "check", None)):
                item.check(model, q)

    def initial_velocity(self, model) -> np.ndarray:
        """Initial qdot (rad/s or m/s), shape (nv,): ``qdot_init``, or at rest."""
        if self.qdot_init is None:
            return np.zeros(model.nv)
        v = np.asarray(self.qdot_init, dtype=float).reshape(-1)
        if v.size != model.nv:
            raise TaskError(f"task qdot_init has {v.size} entries; model {model.name!r} has nv = {model.nv}")
        return v

    def initial_configuration(self, model) -> np.ndarray:
        """Initial q (rad or m), shape (nq,)."""
        if self.q_init is None:
            q = np.zeros(model.nq)
            for t in self.joint_targets:
                if t.at == 0.0 and t.value is not None and t.joint in model.joint_names:
                    q[model.joint_names.index(t.joint)] = t.value
            return q
        q = np.asarray(self.q_init, dtype=float).reshape(-1)
        if q.size != model.nq:
            raise TaskError(f"task q_init has {q.size} entries; model {model.name!r} has nq = {model.nq}")
        return q

    def reference_trajectory(self, model, t: np.ndarray, q0: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """A smooth motion through the joint targets, for initial guesses.

        Each joint with targets follows a half-cosine from one target to the next in phase
        order (periodic over the cycle); the others stay at ``q0``. For the curl (15 deg at phase
        0, 150 deg at 0.5) this is ``low + (high - low) (1 - cos(2 pi t / T)) / 2``. A non-cyclic
        task goes from ``q0`` at phase 0 (or the phase-0 target) through its targets to the one at
        the end, in every phase.

        Returns:
            q (len(t), nq), qdot (len(t), nv), qddot (len(t), nv).
        """
        T = self.cycle_duration
        q = np.tile(np.asarray(q0, dtype=float), (t.size, 1))
        qd = np.zeros((t.size, model.nv))
        qdd = np.zeros((t.size, model.nv))
        by_joint: dict[str, list[JointTarget]] = {}
        for tgt in self.joint_targets:
            if tgt.value is not None:
                by_joint.setdefault(tgt.joint, []).append(tgt)
        # phase in [0, 1) of every time; a non-cyclic task's phase ends at 1 (t = T is an end)
        phase = np.mod(t / T, 1.0)
        if not self.cyclic:
            near = np.round(t / T)
            phase = np.where(np.isclose(t / T, near, rtol=0, atol=1e-9), 0.0, phase)
            phase = np.where((phase == 0.0) & (t > 0), 1.0, phase)
        for joint, targets in by_joint.items():
            j = model.joint_names.index(joint)
            pts = sorted(targets, key=lambda x: phase_value(x.at))
            ats, vals = [phase_value(p.at) for p in pts], [p.value for p in pts]
            if self.cyclic:
                if len(pts) == 1:
                    q[:, j] = pts[0].value
                    continue
                ats, vals = ats + [ats[0] + 1.0], vals + [vals[0]]
            else:
                # the first phase starts at q0, each later one where the previous ended
                later = np.floor(t / T - 1e-9) >= 1
                start = np.where(later, vals[-1], float(q0[j])) if ats[0] > 0.0 else None
                if ats[0] > 0.0:
                    ats, vals = [0.0] + ats, [float(q0[j])] + vals
                if ats[-1] < 1.0:
                    ats, vals = ats + [1.0], vals + [vals[-1]]
                if len(ats) == 1:
                    q[:, j] = vals[0]
                    continue
            ph = np.where(phase < ats[0], phase + 1.0, phase)
            for k in range(len(ats) - 1):
                last = k == len(ats) - 2
                sel = (ph >= ats[k]) & ((ph <= ats[k + 1]) if last else (ph < ats[k + 1]))
                span = (ats[k + 1] - ats[k]) * T
                if span <= 0:
                    continue
                s = (ph[sel] - ats[k]) * T / span  # 0..1 within the segment
                # a non-cyclic phase's first segment starts where the phase starts
                a = start[sel] if not self.cyclic and k == 0 and start is not None else vals[k]
                b = vals[k + 1]
                w = math.pi / span
                q[sel, j] = a + (b - a) * 0.5 * (1 - np.cos(math.pi * s))
                qd[sel, j] = (b - a) * 0.5 * w * np.sin(math.pi * s)
                qdd[sel, j] = (b - a) * 0.5 * w * w * np.cos(math.pi * s)
        return q, qd, qdd


def joint_target_pairs(task: Task, model, n_intervals: int, layout=None) -> list[tuple[int, int, float, float]]:
    """``(node, row of x, lower, upper)`` of every target over a horizon: joint targets' values
    (rows of q) and velocities (rows of qdot, nq + j), and, with ``layout`` (a
    :class:`~fatigue_pin.ocp.problem.StateLayout`), the :class:`StateTarget` items (their rows)."""
    out = []
    for tgt in task.joint_targets:
        j = model.joint_names.index(tgt.joint)
        for node in task.nodes(tgt.at, n_intervals):
            if tgt.value is not None:
                out.append((node, j, tgt.value - tgt.tolerance, tgt.value + tgt.tolerance))
            if tgt.velocity is not None:
                out.append((node, model.nq + j, tgt.velocity - tgt.velocity_tolerance, tgt.velocity + tgt.velocity_tolerance))
    if layout is not None:
        names = layout.state_names
        for tgt in task.state_targets:
            row = names.index(tgt.state)
            for node in task.nodes(tgt.at, n_intervals):
                out.append((node, row, tgt.value - tgt.tolerance, tgt.value + tgt.tolerance))
    elif task.state_targets:
        raise TaskError("task state targets need the problem's state layout to find their rows")
    return sorted(out, key=lambda r: (r[0], r[1]))
