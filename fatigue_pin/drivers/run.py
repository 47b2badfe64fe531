"""The run record: what a driver hands back and stores after every step.

:class:`RunResult` holds one run (a full-horizon solve, a sliding-horizon run stitched from its
windows, a failed window): node times, states by name, controls, per-cycle costs and limits, the
labels of every column, its attributes and the study text that made it. :func:`to_run_result`
and :func:`solution_to_run` build it from an :class:`~fatigue_pin.ocp.transcription.Ocp` and its
states; nothing else does.

Drivers store runs through a :class:`RunStore` (:class:`fatigue_pin.io.results.ResultFile` is the
HDF5 one), so the drivers do not depend on the file format.
"""

from __future__ import annotations

import json
import unicodedata
from dataclasses import dataclass, field
from pathlib import Path
from collections.abc import Collection
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from fatigue_pin.core.errors import ParameterError, ResultFileError
from fatigue_pin.robot.units import JOINT_KINDS, JointUnits, units_of_kind

if TYPE_CHECKING:
    from fatigue_pin.ocp.transcription import Ocp, OcpSolution

#: Attributes every run group carries.
RUN_ATTRIBUTES = (
    "horizon", "n_cycles", "converged", "status", "wall_time_s", "build_time_s", "iterations", "solver", "model",
    "weights", "fatigue_params",
)

WINDOW_DTYPE = np.dtype([
    ("index", "i4"), ("first_cycle", "i4"), ("status", "S40"), ("converged", "?"),
    ("iterations", "i4"), ("wall_time_s", "f8"), ("objective", "f8"),
])

SEARCH_DTYPE = np.dtype([("n_cycles", "i4"), ("converged", "?"), ("status", "S40"), ("iterations", "i4"), ("wall_time_s", "f8"),
                         ("kind", "S24"), ("guess", "S24"), ("constraint_violation", "f8")])


@dataclass
class RunResult:
    """One OCP run (full horizon, or sliding horizon stitched from its windows).

    Shapes: nodes = n_cycles * intervals_per_cycle + 1, intervals = nodes - 1, halves = 2 na (two
    per actuated joint; a passive joint has none).

    Attributes:
        name: group name in the file.
        attrs: run attributes (see :data:`RUN_ATTRIBUTES`; more may be present).
        t: node times (s), (nodes,).
        q, qdot: joint positions (rad or m) and velocities (rad/s or m/s), (nodes, nq), each
            column in its joint's units (:meth:`joint_units`).
        tau_plus, tau_minus: actuator half torques (N m) or forces (N), (intervals, nv), a column
            per joint, 0 on passive joints (:meth:`half_torques`: the halves that exist).
        fatigue: fatigue states by name (Xia: ``ma``, ``mr``, ``mf``), each (nodes, halves); NaN in
            the columns of halves whose model has no such state.
        cycle_costs: weighted cost terms per cycle, (cycles, len(cost_terms)).
        torque_limits: available torque (1 - mf) * tau_limit of every half at the end of each
            cycle (N m or N, signed like the half), (cycles, halves).
        joint_names, actuator_names, cost_terms: labels of the columns.
        joint_kinds: the kind of every joint of ``joint_names`` (``revolute``, ``prismatic``),
            which gives its units (:meth:`joint_units`); empty: every joint revolute.
        cycle_wall_time_s: solve time attributed to each cycle (s), (cycles,).
        windows: sliding-horizon window table (structured, :data:`WINDOW_DTYPE`), or None.
        urdf: the model's URDF text (so the file reproduces itself), or "".
        study: the TOML text of the study that produced the run, or "" (built in Python).
        fatigued: the fatigued fraction of every half (each model's fatigued state), (nodes, halves).
        extras: further arrays of a driver, by name (numeric or structured; e.g. the closed loop's
            re-plan table, measurements, prediction and estimate, :mod:`fatigue_pin.drivers.mpc`;
            a muscle run's ``muscle_force`` (intervals, muscles), N, and ``joint_torque``
            (intervals, nv), N m or N, at the start of every interval).
        unit_controls: for actuator kinds other than torque halves (attribute ``actuation``),
            the control of every unit of :attr:`actuator_names`, (intervals, units): a muscle's
            activation (1), a residual half's torque (N m or N); None for torque halves (their
            controls are ``tau_plus`` and ``tau_minus``, which then hold the residual torques).
        muscles: the muscle file's text of a muscle run (so the file reproduces itself), or "".
    """

    name: str
    attrs: dict[str, Any]
    t: np.ndarray
    q: np.ndarray
    qdot: np.ndarray
    tau_plus: np.ndarray
    tau_minus: np.ndarray
    fatigue: dict[str, np.ndarray]
    cycle_costs: np.ndarray
    torque_limits: np.ndarray
    joint_names: tuple[str, ...]
    actuator_names: tuple[str, ...]
    cost_terms: tuple[str, ...]
    cycle_wall_time_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    windows: np.ndarray | None = None
    urdf: str = ""
    study: str = ""
    fatigued: np.ndarray | None = None
    extras: dict[str, np.ndarray] = field(default_factory=dict)
    joint_kinds: tuple[str, ...] = ()
    unit_controls: np.ndarray | None = None
    muscles: str = ""

    def __post_init__(self) -> None:
        if self.fatigued is None:
            raise ResultFileError(f"run {self.name!r}: the fatigued fraction of every half (fatigued, (nodes, halves)) "
                                  "is required; the reader supplies it for files that predate it")
        self.joint_kinds = tuple(self.joint_kinds) or ("revolute",) * len(self.joint_names)
        if len(self.joint_kinds) != len(self.joint_names) or not set(self.joint_kinds) <= set(JOINT_KINDS):
            raise ResultFileError(f"run {self.name!r}: joint kinds {list(self.joint_kinds)}: expected one of {list(JOINT_KINDS)} "
                                  f"for each of its {len(self.joint_names)} joints {list(self.joint_names)}")

    def joint_units(self, joint: int | str) -> JointUnits:
        """The units of joint ``joint`` (its column in q, or its name): rad, rad/s, N m for a
        revolute joint; m, m/s, N for a prismatic one (:class:`~fatigue_pin.robot.model.JointUnits`)."""
        j = self.joint_names.index(joint) if isinstance(joint, str) and joint in self.joint_names else joint
        if not isinstance(j, int) or not 0 <= j < len(self.joint_names):
            raise ResultFileError(f"run {self.name!r}: joint {joint!r} is not one of its joints {list(self.joint_names)}")
        return units_of_kind(self.joint_kinds[j])

    def half_units(self, half: int | str) -> JointUnits:
        """The units of the joint that actuator half ``half`` (its column, or its name
        ``<joint>_plus`` / ``<joint>_minus``; a motor's name is its joint's) drives."""
        name = self.actuator_names[half] if isinstance(half, int) else half
        return self.joint_units(unit_joint(name, self.joint_names)[0])

    @property
    def actuation(self) -> str:
        """The actuator kind of the run (``torque``: signed torque halves; ``muscles``; ``motors``)."""
        return str(self.attrs.get("actuation", "torque"))

    @property
    def muscle_names(self) -> tuple[str, ...]:
        """The muscles among :attr:`actuator_names` (the first units of a muscle run), or ()."""
        raw = self.attrs.get("muscle_names")
        return tuple(json.loads(raw)) if isinstance(raw, str) and raw else ()

    def unit_effort(self, unit: int) -> str:
        """The unit of the control of actuator unit ``unit`` (its column): ``1`` for a muscle's
        activation, else the effort unit of the joint its half drives (N m or N)."""
        return "1" if self.actuator_names[unit] in self.muscle_names else self.half_units(unit).effort

    def check_shapes(self) -> None:
        """Refuse a run whose arrays disagree (a damaged or hand-edited file): every array 2-D
        where a table is expected, nodes = intervals + 1 = cycles * intervals_per_cycle + 1,
        and as many columns as labels. Raises ResultFileError naming the arrays."""
        def bad(what: str) -> ResultFileError:
            return ResultFileError(f"run {self.name!r}: {what}; expected the arrays of one run (docs/results.md), "
                                   "the file is damaged or was edited")

        arrays = {"q": self.q, "qdot": self.qdot, "tau_plus": self.tau_plus, "tau_minus": self.tau_minus,
                  "cycle_costs": self.cycle_costs, "torque_limits": self.torque_limits, "fatigued": self.fatigued,
                  **self.fatigue, **({"unit_controls": self.unit_controls} if self.unit_controls is not None else {})}
        if np.ndim(self.t) != 1:
            raise bad(f"t has shape {np.shape(self.t)}")
        for key, a in arrays.items():
            if np.ndim(a) != 2:
                raise bad(f"{key} has shape {np.shape(a)}, not a table")
            if not np.issubdtype(np.asarray(a).dtype, np.number):
                raise bad(f"{key} holds {np.asarray(a).dtype} values, not numbers")
        nodes, cycles = self.t.shape[0], self.cycle_costs.shape[0]
        rows = {"q": nodes, "qdot": nodes, "fatigued": nodes, **{k: nodes for k in self.fatigue},
                "tau_plus": max(nodes - 1, 0), "tau_minus": max(nodes - 1, 0), "torque_limits": cycles,
                **({"unit_controls": max(nodes - 1, 0)} if self.unit_controls is not None else {})}
        wrong = {k: arrays[k].shape[0] for k, n in rows.items() if arrays[k].shape[0] != n}
        if wrong:
            raise bad(f"t has {nodes} nodes and cycle_costs {cycles} cycles, but the rows of {wrong} disagree")
        if cycles and (nodes - 1) % cycles:
            raise bad(f"{nodes - 1} intervals do not make {cycles} equal cycles")
        columns = {"q": len(self.joint_names), "qdot": len(self.joint_names), "tau_plus": len(self.joint_names),
                   "tau_minus": len(self.joint_names), "cycle_costs": len(self.cost_terms), "fatigued": len(self.actuator_names),
                   "torque_limits": len(self.actuator_names), **{k: len(self.actuator_names) for k in self.fatigue},
                   **({"unit_controls": len(self.actuator_names)} if self.unit_controls is not None else {})}
        wrong = {k: arrays[k].shape[1] for k, n in columns.items() if arrays[k].shape[1] != n}
        if wrong:
            raise bad(f"the columns of {wrong} disagree with the labels ({len(self.joint_names)} joints, "
                      f"{len(self.actuator_names)} halves, {len(self.cost_terms)} cost terms)")

    def require_cycles(self, what: str) -> None:
        """Refuse to ``what`` (plot, replay, verify) a run without a cycle: a sliding run whose
        first window failed keeps no cycle (its last iterate is the ``_failed_window`` run)."""
        if self.n_cycles == 0 or self.t.size == 0:
            status = self.attrs.get("status", "")
            raise ResultFileError(
                f"run {self.name!r} has no cycle to {what}: no window converged (status {status!s}); expected a run "
                f"with cycles (IPOPT's last iterate of its failed window is the run {failed_window_name(self.name)!r})"
            )

    @property
    def signed_limits(self) -> np.ndarray:
        """Signed torque limit of every half (N m), (halves,): + for plus halves, - for minus
        halves, as stored in the run attribute ``tau_limits``."""
        lim = self.attrs.get("tau_limits")
        if lim is None or np.size(lim) != len(self.actuator_names):
            raise ResultFileError(f"run {self.name!r} has no torque limits of its {len(self.actuator_names)} halves "
                                  "(attribute tau_limits); expected a run written by fatigue_pin")
        return np.asarray(lim, dtype=float).reshape(-1)

    def target_loads(self) -> np.ndarray:
        """Target load TL = tau / tau_limit of every half on every interval (dimensionless, >= 0),
        (intervals, halves), halves ordered as :attr:`actuator_names` (plus, minus of each joint)."""
        return self.half_torques() / self.signed_limits[None, :]

    def half_torques(self) -> np.ndarray:
        """Torque of every half on every interval (N m), (intervals, halves), in the order of
        :attr:`actuator_names` (``<joint>_plus`` from ``tau_plus``, ``<joint>_minus`` from
        ``tau_minus``). For a run of another actuator kind, the control of every unit
        (:attr:`unit_controls`: a muscle's activation, a residual half's torque)."""
        if self.unit_controls is not None:
            return np.asarray(self.unit_controls, dtype=float)
        columns = []
        for name in self.actuator_names:
            joint, side = half_joint(name)
            if joint not in self.joint_names:
                raise ResultFileError(f"run {self.name!r}: actuator half {name!r} drives no joint of {list(self.joint_names)}")
            source = self.tau_plus if side == "plus" else self.tau_minus
            columns.append(np.asarray(source)[:, self.joint_names.index(joint)])
        return np.column_stack(columns) if columns else np.zeros((self.tau_plus.shape[0], 0))

    @property
    def passive_joints(self) -> tuple[str, ...]:
        """The joints without actuator halves."""
        driven = {unit_joint(n, self.joint_names)[0] for n in self.actuator_names if n not in self.muscle_names}
        return tuple(j for j in self.joint_names if j not in driven)

    @property
    def fatigue_states(self) -> tuple[str, ...]:
        return tuple(self.fatigue)

    def state(self, name: str) -> np.ndarray:
        """Fatigue state ``name`` of every half, (nodes, halves)."""
        if name not in self.fatigue:
            raise ResultFileError(f"run {self.name!r} has no fatigue state {name!r}; its states are {list(self.fatigue)}")
        return self.fatigue[name]

    @property
    def ma(self) -> np.ndarray:
        return self.state("ma")

    @property
    def mr(self) -> np.ndarray:
        return self.state("mr")

    @property
    def mf(self) -> np.ndarray:
        return self.state("mf")

    @property
    def n_cycles(self) -> int:
        return int(self.cycle_costs.shape[0])

    @property
    def converged(self) -> bool:
        return bool(self.attrs.get("converged", False))

    @property
    def intervals_per_cycle(self) -> int:
        return (self.t.size - 1) // max(self.n_cycles, 1)

    def invariant_error(self) -> np.ndarray:
        """|1 - (sum of the fatigue states)| of every half at every node, (nodes, halves) (for
        Xia's model |1 - (ma + mr + mf)|; states a half lacks count as 0)."""
        total = sum(np.nan_to_num(v) for v in self.fatigue.values())
        return np.abs(1.0 - total)

    def cycle_slice(self, cycle: int) -> slice:
        """Node slice of cycle ``cycle`` (0-based), both ends included."""
        n = self.intervals_per_cycle
        if not 0 <= cycle < self.n_cycles:
            raise ResultFileError(f"cycle {cycle} is out of range: run {self.name!r} has cycles 0..{self.n_cycles - 1}")
        return slice(cycle * n, (cycle + 1) * n + 1)


def unit_joint(name: str, joints: Collection[str]) -> tuple[str, str]:
    """The joint a unit drives and its side: ``("elbow", "plus")`` for the half ``elbow_plus``
    (:func:`half_joint`), ``("elbow", "")`` for a motor, which is named after its joint."""
    return (name, "") if name in joints else half_joint(name)


def half_joint(name: str) -> tuple[str, str]:
    """``("elbow", "plus")`` from the half name ``"elbow_plus"`` (:attr:`ActuatorHalf.name
    <fatigue_pin.ocp.actuators.ActuatorHalf.name>`)."""
    joint, _, side = name.rpartition("_")
    if side not in ("plus", "minus") or not joint:
        raise ResultFileError(f"actuator half {name!r}: expected <joint>_plus or <joint>_minus")
    return joint, side


def joint_columns(run_joints: tuple[str, ...], halves: tuple[str, ...], tau_halves: np.ndarray,
                  skip: Collection[str] = ()) -> tuple[np.ndarray, np.ndarray]:
    """``(tau_plus, tau_minus)``, each (intervals, joints) with 0 on joints without a half, from
    the torques of the named halves (intervals, halves): the inverse of :meth:`RunResult.half_torques`.
    The columns of the units named in ``skip`` (a muscle run's muscles) are left out; a unit named
    after a joint (a motor) gives its signed torque's positive and negative parts."""
    tau_halves = np.asarray(tau_halves, dtype=float).reshape(-1, len(halves))
    plus, minus = np.zeros((tau_halves.shape[0], len(run_joints))), np.zeros((tau_halves.shape[0], len(run_joints)))
    for k, name in enumerate(halves):
        if name in skip:
            continue
        joint, side = unit_joint(name, run_joints)
        if joint not in run_joints:
            raise ResultFileError(f"actuator half {name!r} drives no joint of {list(run_joints)}")
        if not side:  # a motor: its signed torque
            j = run_joints.index(joint)
            plus[:, j], minus[:, j] = np.maximum(tau_halves[:, k], 0.0), np.minimum(tau_halves[:, k], 0.0)
            continue
        (plus if side == "plus" else minus)[:, run_joints.index(joint)] = tau_halves[:, k]
    return plus, minus


def torque_limits_at_cycle_ends(mf: np.ndarray, signed_limits: np.ndarray, intervals_per_cycle: int) -> np.ndarray:
    """(1 - mf) * limit at nodes n, 2n, ..., shape (cycles, halves); ``signed_limits`` (halves,)."""
    ends = np.arange(intervals_per_cycle, mf.shape[0], intervals_per_cycle)
    return (1.0 - mf[ends]) * np.asarray(signed_limits)[None, :]


#: Suffix of the run that keeps a sliding run's failed window (IPOPT's last iterate), e.g.
#: ``sliding/torque_S0_failed_window``.
FAILED_WINDOW_SUFFIX = "_failed_window"
#: Suffix of the run that holds a sliding run's windows while it replaces a run of the same name
#: (the old run stays until the new one is complete), e.g. ``sliding/torque_S0_in_progress``.
IN_PROGRESS_SUFFIX = "_in_progress"


#: Groups of a result file that hold no user run: search tables and the searches' step runs.
RESERVED_GROUPS = ("search", "searched")
#: The grammar of run names, as said in messages and docs/results.md.
RUN_NAME_GRAMMAR = ("segments of letters and digits of any script and _ - . + = , separated by '/' (none empty, none "
                    "starting with '.'), at most 200 characters, not under search/ or searched/, not ending with "
                    "_failed_window or _in_progress")
#: Characters of a run name besides letters, digits and their combining marks (Unicode categories
#: L, M, N: HDF5 stores names as UTF-8).
_NAME_MARKS = "_.+=,-"


def _name_character(c: str) -> bool:
    return c in _NAME_MARKS or unicodedata.category(c)[0] in "LMN"


def _bad_character(name: str) -> str:
    """`` ('x', U+0078)``-style words naming the first character of ``name`` a run name cannot
    hold, or '' if there is none."""
    bad = next((c for c in name if c != "/" and not _name_character(c)), None)
    if bad is None:
        return ""
    shown = repr(bad) if bad.isprintable() and not bad.isspace() else "a space" if bad == " " else "a control character"
    return f" holds {shown} (U+{ord(bad):04X}), which is not allowed;"


def check_run_name(name: object, internal: bool = False) -> str:
    """``name`` once it follows :data:`RUN_NAME_GRAMMAR` (checked before any work).

    A run name is a path of groups in a result file: ``full/torque_S10``. Empty segments
    (``a//b``, a leading or trailing ``/``), ``.`` and ``..``, characters HDF5 or a shell treat
    specially, and the groups the file keeps for itself (:data:`RESERVED_GROUPS`, the
    ``_failed_window`` runs) would let a run land on something else and delete it.

    Args:
        internal: allow the names the drivers make themselves (``searched/<table>/N<n>``,
            ``<run>_failed_window``).

    Raises:
        ParameterError: naming the name and the grammar.
    """
    bad = ParameterError(f"run name {name!r}: expected {RUN_NAME_GRAMMAR}")
    if not isinstance(name, str) or not name or len(name) > 200:
        raise bad
    segments = name.split("/")
    if not all(s and s[0] != "." and all(_name_character(c) for c in s) for s in segments):
        raise ParameterError(f"run name {name!r}:{_bad_character(name)} expected {RUN_NAME_GRAMMAR}")
    own = name.endswith(FAILED_WINDOW_SUFFIX) or name.endswith(IN_PROGRESS_SUFFIX)  # the drivers name these
    if segments[0] == "search" or not internal and (segments[0] in RESERVED_GROUPS or own):
        raise bad
    return name


class RunStore(Protocol):
    """Where a driver keeps its runs and search tables as it goes (e.g. an HDF5 file,
    :class:`fatigue_pin.io.results.ResultFile`). ``write`` replaces a run of the same name
    atomically: after a crash the store holds the old run or the new one, whole."""

    def runs(self) -> list[str]:
        """Names of the stored runs, failed windows included."""
        ...

    def read(self, name: str) -> RunResult:
        """The stored run ``name``."""
        ...

    def write(self, run: RunResult) -> None:
        """Add or replace run ``run.name``."""
        ...

    def tables(self) -> dict[str, np.ndarray]:
        """Every stored search table (:data:`SEARCH_DTYPE`), by name."""
        ...

    def write_table(self, name: str, rows: list[dict[str, Any]], attrs: dict[str, Any]) -> None:
        """Add or replace search table ``name``: one row per solve (:data:`SEARCH_DTYPE` fields)."""
        ...

    def delete(self, name: str) -> None:
        """Remove run ``name`` (only a run; nothing if there is none)."""
        ...


def in_progress_name(name: str) -> str:
    """Run name under which a sliding run replacing the run ``name`` keeps its windows until it is complete."""
    return f"{name}{IN_PROGRESS_SUFFIX}"


def failed_window_name(name: str) -> str:
    """Run name of the failed window of the sliding run ``name`` (its last IPOPT iterate)."""
    return f"{name}{FAILED_WINDOW_SUFFIX}"


def fatigue_parameters(halves) -> str:
    """The ``fatigue_params`` attribute: JSON of half name -> {"model": kind, parameters...}, for
    the actuator halves ``halves`` (:attr:`SignedTorqueActuators.halves`)."""
    return json.dumps({h.name: {"model": h.params.kind, **h.params.as_dict()} for h in halves})


def run_attributes(ocp: Ocp, horizon: str, labels: dict[str, Any] | None = None) -> dict[str, object]:
    """Attributes describing a run of ``ocp``: horizon, sizes, weights and fatigue parameters by
    name (JSON), solver, model, and the study's ``labels`` (e.g. cost, S, preset)."""
    s = ocp.nlp.options  # the solver's options, its linear solver as chosen ("auto" resolved)
    attrs: dict[str, object] = {
        "horizon": horizon,
        "n_cycles": ocp.n_cycles,
        "solver": f"ipopt/{s.linear_solver}" + ("/compiled" if s.compile else ""),
        "model": ocp.model.name,
        "weights": json.dumps(dict(zip(ocp.cost_terms, ocp.problem.weights.tolist()))),
        "fatigue_params": fatigue_parameters(ocp.actuators.halves),
        "tau_limits": ocp.actuators.signed_limits,
        "coupling": ocp.actuators.coupling_kind,
        "intervals_per_cycle": ocp.task.intervals_per_cycle,
        "dt": ocp.task.dt,
        "substeps": ocp.transcription.substeps,
        **ocp.actuators.run_record_attributes(),
    }
    # parameters shared by every half (e.g. S of a study with one fatigue model), by name
    halves = ocp.actuators.halves
    for key in halves[0].params.param_names:
        values = {getattr(h.params, key, None) for h in halves}
        if len(values) == 1 and None not in values:
            attrs[key] = float(values.pop())
    attrs.update(labels or {})
    return attrs


def to_run_result(
    ocp: Ocp,
    t: np.ndarray,
    x: np.ndarray,
    u: np.ndarray,
    cycle_costs: np.ndarray,
    name: str,
    attrs: dict[str, object],
    cycle_wall_time_s: np.ndarray,
    windows: np.ndarray | None = None,
    study: str = "",
) -> RunResult:
    """Assemble a :class:`RunResult` from node states (nodes, nx) and controls (intervals, nu)."""
    L, A = ocp.layout, ocp.actuators
    fatigued = L.fatigued(x)
    record = A.run_record(x[:-1, L.q], x[:-1, L.v], u, x[:-1, L.m])
    return RunResult(
        name=name,
        attrs=attrs,
        t=t,
        q=x[:, L.q],
        qdot=x[:, L.v],
        tau_plus=ocp.actuators.per_joint(u)[0],
        tau_minus=ocp.actuators.per_joint(u)[1],
        fatigue={s: L.fatigue_columns(x, s) for s in L.state_kinds},
        cycle_costs=cycle_costs,
        torque_limits=torque_limits_at_cycle_ends(fatigued, ocp.actuators.signed_limits, ocp.task.intervals_per_cycle),
        joint_names=ocp.model.joint_names,
        joint_kinds=ocp.model.joint_kinds,
        actuator_names=ocp.actuators.half_names,
        cost_terms=ocp.cost_terms,
        cycle_wall_time_s=cycle_wall_time_s,
        windows=windows,
        urdf=ocp.model.urdf_text or Path(ocp.model.urdf_path).read_text(),
        study=study,
        fatigued=fatigued,
        extras=record.extras,
        unit_controls=record.unit_controls,
        muscles=record.muscles,
    )


def solution_to_run(ocp: Ocp, sol: OcpSolution, name: str, study: str = "", labels: dict[str, Any] | None = None) -> RunResult:
    """The :class:`RunResult` of a full-horizon solution."""
    attrs = run_attributes(ocp, "full", labels)
    attrs.update(
        converged=sol.success,
        status=sol.status,
        wall_time_s=sol.wall_time_s,
        build_time_s=ocp.build_time_s,
        compile_time_s=ocp.compile_time_s,
        iterations=sol.iterations,
        objective=sol.objective,
    )
    per_cycle = np.full(ocp.n_cycles, sol.wall_time_s / ocp.n_cycles)
    return to_run_result(ocp, sol.t, sol.x, sol.u, sol.cycle_costs, name, attrs, per_cycle, study=study)
