"""What a stored run is checked against, rebuilt from what it stores (``fatigue-pin verify``).

* The rigid body the run was solved on: the run's URDF text with the stored study's gravity and
  ``[model.payload]``, through :meth:`fatigue_pin.io.study.Study.model` (the stored study with its
  ``model.urdf`` pointed at the stored text), so that the payload and gravity are read in one place.
* The task: :meth:`Study.task` of the stored study (the items of :mod:`fatigue_pin.ocp.task`).
* The fatigue models of every half: the ``fatigue_params`` attribute (kind and values per half).
* The torque limits and the target loads: :attr:`RunResult.signed_limits` and
  :meth:`RunResult.target_loads` (the stored ``tau_limits`` attribute, signed, one per half).
* The grid: ``dt``, ``intervals_per_cycle``, ``substeps`` attributes.
* A closed-loop run (``fatigue-pin mpc``) stores the plant's trajectory: it is checked against the
  plant, the stored closed-loop study's ``plant_study`` (its payload) and the
  ``plant_fatigue_params`` attribute (its true fatigue rates). A torque disturbance of the plant
  is not in the stored torques, so a note says that the gaps include it.

Everything is checked for what the reference integration needs (finite gravity, limits and time
step, the joints of the run); a run that lacks it raises :class:`ResultFileError` with one line.
"""

from __future__ import annotations

import dataclasses
import json
import math
import tempfile
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from fatigue_pin.core.errors import FatiguePinError, ResultFileError
from fatigue_pin.drivers.run import RunResult, half_joint
from fatigue_pin.verify.fatigue_rhs import numpy_rhs
from fatigue_pin.core.text import shown

__all__ = ["Half", "Stored", "rebuild"]


@dataclass
class Half:
    """One signed actuator half as the run stores it.

    Attributes:
        name: e.g. ``elbow_plus``; kind: fatigue model kind; model: its FatigueModel.
        params: the model's parameters by name; states: its state names, in order.
        limit: signed torque at TL = 1 (N m).
        rhs: ``(m, TL) -> dm/dt`` (numpy transcription, or the model's ``rates`` without one).
    """

    name: str
    kind: str
    model: Any
    params: dict[str, float]
    states: tuple[str, ...]
    limit: float
    rhs: Callable[[np.ndarray, float], np.ndarray]


@dataclass
class Stored:
    """A run and what it is checked against.

    Attributes:
        run: the run; robot: the :class:`~fatigue_pin.robot.model.RobotModel` it was solved on;
        task: the stored study's :class:`~fatigue_pin.ocp.task.Task` (None without a study).
        halves: the actuator halves; limits: signed torque limits, (2 nv,) (plus, minus per joint).
        horizon: ``full``, ``sliding`` or ``mpc``; dt: interval length (s); n: intervals per cycle;
        substeps: RK4 substeps of the transcription (0: unknown).
        Y: stored (q, qdot) per node, (N + 1, 2 nq); M: fatigue states, (N + 1, states), each
        half's states in its model's order; tau: joint torques tau_plus + tau_minus, (N, nv);
        TL: target loads, (N, halves) (:meth:`RunResult.target_loads`).
        notes: what was found while rebuilding (defaults taken, differences).
        muscles: a muscle run's muscles on its model, evaluated on numbers
            (:class:`~fatigue_pin.verify.muscle_torque.NumericMuscles`), or None; their torque at
            the activations ``activations`` (N, nm) adds to ``tau`` (then the residual torques).
        active: the columns of M of the states each muscle's force follows, which are then its
            activations (the rigid body is integrated with the fatigue states): its active
            fraction under the ``active`` coupling, its activation with activation dynamics;
            None: the activations are the stored controls.
    """

    run: RunResult
    robot: Any
    task: Any
    halves: list[Half]
    limits: np.ndarray
    horizon: str
    dt: float
    n: int
    substeps: int
    Y: np.ndarray = field(repr=False)
    M: np.ndarray = field(repr=False)
    tau: np.ndarray = field(repr=False)
    TL: np.ndarray = field(repr=False)
    notes: list[str] = field(default_factory=list)
    muscles: Any = None
    activations: np.ndarray | None = field(default=None, repr=False)
    active: list[int] | None = None

    @property
    def N(self) -> int:
        return int(self.tau.shape[0])

    @property
    def nq(self) -> int:
        return int(self.robot.nq)

    @property
    def joints(self) -> list[str]:
        return list(self.run.joint_names)

    def units(self, quantity: str) -> str:
        """The unit of a joint ``quantity`` (``position``, ``velocity``, ``effort``) over the run's
        joints: ``rad``, ``m`` or ``rad or m`` (``N m or N``, ...) when the joints' kinds differ."""
        return " or ".join(dict.fromkeys(getattr(self.run.joint_units(j), quantity) for j in range(len(self.joints))))

    @property
    def offsets(self) -> np.ndarray:
        """Start of each half's states in the columns of M (and the end of the last)."""
        return np.cumsum([0, *(len(h.states) for h in self.halves)])

    def invariant(self, M: np.ndarray) -> np.ndarray:
        """``|1 - sum|`` of each half's states that its model sums to 1
        (:meth:`~fatigue_pin.fatigue.interface.FatigueModel.total_states`), (nodes, halves), from
        fatigue states M laid out as :attr:`M`; NaN where the model has no such sum
        (``state_total`` None)."""
        off = self.offsets
        cols = [[off[i] + h.states.index(n) for n in h.model.total_states()] for i, h in enumerate(self.halves)]
        sums = np.column_stack([M[:, c].sum(axis=1) if h.model.state_total is not None else np.full(M.shape[0], np.nan)
                                for c, h in zip(cols, self.halves)]) if cols else np.zeros((M.shape[0], 0))
        return np.abs(1.0 - sums)  # NaN for a model without an invariant (a motor's temperatures)

    @property
    def state_labels(self) -> list[str]:
        return [f"{h.name} {s}" for h in self.halves for s in h.states]

    @property
    def x_labels(self) -> list[str]:
        return [f"q {j}" for j in self.joints] + [f"qdot {j}" for j in self.joints] + self.state_labels


def rebuild(run: RunResult) -> Stored:
    """Rebuild what ``run`` is checked against (see the module docstring).

    Raises:
        ResultFileError: the run lacks what is needed or is inconsistent (one line).
    """
    notes: list[str] = []
    coupling = str(run.attrs.get("coupling", "tl+mf<=1"))
    residual = str(run.attrs.get("residual_coupling", coupling))
    if coupling == "active" and (run.actuation != "muscles" or (len(run.actuator_names) > len(run.muscle_names) and residual == "active")):
        raise ResultFileError(f"run {run.name!r} has the coupling 'active' on torque halves (torque = ma x limit within each "
                              "interval); verify checks it for muscles only (their force from ma, residual torques their control)")
    N = _intervals(run)
    horizon, dt, n, substeps = _grid(run, notes)
    study = _study(run, notes)
    robot = _robot(run, study, notes)
    limits = _limits(run, robot, notes)
    halves = _halves(run, limits)
    task = _task(run, study, n, notes)
    cols = [run.fatigue[s][:, h] for h, half in enumerate(halves) for s in half.states]
    M = np.column_stack(cols).astype(float) if cols else np.zeros((N + 1, 0))
    muscles, activations = _muscles(run, robot, notes)
    active = None
    if coupling == "active" or run.attrs.get("activation_dynamics"):
        # each muscle's force follows a state (its active fraction, or its activation): its column of M
        from fatigue_pin.muscles.activation import ACTIVATION

        offsets = np.cumsum([0, *(len(h.states) for h in halves)])
        state = (lambda h: ACTIVATION) if run.attrs.get("activation_dynamics") else (lambda h: h.model.active_state)
        muscle_halves = halves[: len(run.muscle_names)]
        lacking = [h.name for h in muscle_halves if state(h) not in h.states]
        if lacking:
            raise ResultFileError(f"run {run.name!r}: the forces of muscles {lacking} follow a state their models do not have")
        active = [int(offsets[i] + h.states.index(state(h))) for i, h in enumerate(muscle_halves)]
    return Stored(run=run, robot=robot, task=task, halves=halves, limits=limits, horizon=horizon, dt=dt, n=n,
                  substeps=substeps, Y=np.hstack([run.q, run.qdot]).astype(float), M=M,
                  tau=np.asarray(run.tau_plus + run.tau_minus, dtype=float), TL=run.target_loads(), notes=notes,
                  muscles=muscles, activations=activations, active=active)


def _muscles(run: RunResult, robot, notes: list[str]) -> tuple[Any, np.ndarray | None]:
    """A muscle run's muscles, read from the muscle file text it stores, on the rebuilt model, and
    their activations (N, nm); (None, None) for a run of torque halves. A run solved on polynomial
    paths (attribute ``muscle_paths``) is checked on those polynomials, and ``notes`` gets how far
    they are from the exact paths along the run."""
    if run.actuation in ("torque", "motors"):  # the joint torques are the stored controls
        return None, None
    if run.actuation != "muscles":
        raise ResultFileError(f"run {run.name!r}: actuation = {run.actuation!r}; verify checks runs of torque halves, muscles "
                              "and motors")
    from fatigue_pin.muscles.files import read_muscles
    from fatigue_pin.verify.muscle_torque import NumericMuscles

    if not run.muscles:
        raise ResultFileError(f"run {run.name!r} is a muscle run without its muscle file's text (attribute muscles); "
                              "cannot rebuild its muscles")
    try:
        muscles = read_muscles(run.muscles, f"the muscle file stored with run {run.name!r}")
    except FatiguePinError as exc:
        raise ResultFileError(f"run {run.name!r}: its stored muscles do not load: {exc}") from None
    if muscles.names != run.muscle_names or run.actuator_names[: len(muscles.names)] != muscles.names:
        raise ResultFileError(f"run {run.name!r}: its stored muscles {list(muscles.names)} are not its first units "
                              f"{list(run.actuator_names[: len(muscles.names)])}")
    missing = sorted({p.frame for m in muscles.muscles for p in m.points} - set(robot.pin_model.names) - {f.name for f in robot.pin_model.frames})
    if missing:
        raise ResultFileError(f"run {run.name!r}: its muscles' points are on links {missing}, which its model does not have")
    polynomials = None
    if run.attrs.get("muscle_paths"):
        from fatigue_pin.muscles.polynomial_paths import PolynomialPaths

        try:
            polynomials = PolynomialPaths.polynomials_from_json(str(run.attrs["muscle_paths"]))
        except (ValueError, KeyError, TypeError) as exc:
            raise ResultFileError(f"run {run.name!r}: its polynomial muscle paths (attribute muscle_paths) do not load ({exc})") from None
        if tuple(p.muscle for p in polynomials) != muscles.names:
            raise ResultFileError(f"run {run.name!r}: polynomial paths for {[p.muscle for p in polynomials]}; expected its muscles "
                                  f"{list(muscles.names)}")
    numeric = NumericMuscles(robot.pin_model, muscles, polynomials)
    if polynomials is not None:
        dL, dr = numeric.polynomial_errors(np.asarray(run.q, dtype=float))
        notes.append(f"muscle paths: the run's polynomials (checked as solved); along its motion they differ from the exact "
                     f"paths by at most {dL * 1e3:.3g} mm in length and {dr * 1e3:.3g} mm in moment arm")
    return numeric, run.half_torques()[:, : len(muscles.names)]


def _intervals(run: RunResult) -> int:
    run.require_cycles("verify")  # a sliding run whose first window failed: named, not "0 nodes for 0 intervals"
    N = run.tau_plus.shape[0]
    if run.q.shape[0] != N + 1 or run.t.size != N + 1 or run.qdot.shape[0] != N + 1 or run.tau_minus.shape[0] != N:
        raise ResultFileError(f"run {run.name!r}: {run.q.shape[0]} nodes for {N} intervals; expected {N + 1}")
    if N == 0:
        raise ResultFileError(f"run {run.name!r} has no interval (a failed first window?); nothing to verify")
    return N


def _grid(run: RunResult, notes: list[str]) -> tuple[str, float, int, int]:
    """Horizon kind, dt (s), intervals per cycle and substeps, checked."""
    horizon = str(run.attrs.get("horizon", "full"))
    try:
        dt = float(run.attrs["dt"]) if "dt" in run.attrs else float(run.t[1] - run.t[0])
        n = int(run.attrs.get("intervals_per_cycle", run.intervals_per_cycle))
        substeps = int(run.attrs.get("substeps", 0))
    except (TypeError, ValueError) as exc:
        raise ResultFileError(f"run {run.name!r}: its grid attributes (dt, intervals_per_cycle, substeps) are not numbers ({exc})") from None
    if not math.isfinite(dt) or dt <= 0:
        raise ResultFileError(f"run {run.name!r}: interval length dt = {shown(dt)}; expected a finite duration > 0 (s)")
    if n < 1 or substeps < 0:
        raise ResultFileError(f"run {run.name!r}: intervals_per_cycle = {n}, substeps = {substeps}; expected >= 1 and >= 0")
    with np.errstate(invalid="ignore"):
        if not np.allclose(np.diff(run.t), dt, rtol=1e-9, atol=1e-12):
            notes.append(f"node times are not spaced by dt = {dt:g} s; dt taken from the attribute")
    if not substeps:
        notes.append("no substeps attribute: the transcription's RK4 is not re-evaluated")
    return horizon, dt, n, substeps


def _study(run: RunResult, notes: list[str] | None = None):
    """The run's stored study, or None when it stores none. For a closed-loop run, the plant's
    study (the trajectory is the plant's)."""
    from fatigue_pin.io.mpc_study import MpcStudy, is_closed_loop_table
    from fatigue_pin.io.study import Study

    if not run.study:
        return None
    source = f"the study stored with run {run.name!r}"
    try:
        data = tomllib.loads(run.study)
    except tomllib.TOMLDecodeError:
        data = None  # Study.from_toml names the error
    try:
        if data is not None and is_closed_loop_table(data):
            closed_loop = MpcStudy.from_dict(data)
            if notes is not None:
                notes.append("closed-loop run: the plant's trajectory, checked against the plant's model and fatigue rates")
                disturbance = closed_loop.plant.disturbance
                if np.any(np.asarray(disturbance.constant) != 0) or np.any(np.asarray(disturbance.std) > 0):
                    notes.append("the plant's torque disturbance is not in the stored torques: the gaps include it")
            return closed_loop.plant_study
        return Study.from_toml(run.study, source)
    except FatiguePinError as exc:
        raise ResultFileError(f"run {run.name!r}: its stored study does not load, so the model and task it was solved on "
                              f"cannot be rebuilt: {exc}") from None


def _robot(run: RunResult, study, notes: list[str]):
    """The model the run was solved on: its URDF text with the study's gravity and payload."""
    from fatigue_pin.robot.model import load_model

    try:
        if not run.urdf:
            if study is None:
                raise ResultFileError(f"run {run.name!r} stores neither a URDF text nor a study; cannot rebuild its model")
            notes.append(f"no URDF text stored: the model is the stored study's model.urdf = "
                         f"{study.data['model']['urdf'] or study.data['model'].get('osim')!r}")
            robot = study.model()
        else:
            with tempfile.TemporaryDirectory(prefix="fatigue_pin_verify_") as tmp:
                path = Path(tmp) / "stored.urdf"
                path.write_text(run.urdf)
                if study is None:
                    notes.append("no study stored: the model is the stored URDF with Pinocchio's gravity and no payload")
                    robot = load_model(path)
                else:
                    # an OpenSim model's URDF text carries its gravity; its muscles are the stored muscle file's
                    osim = {"model.osim": "", "model.ignore_wraps": False} if study.data["model"].get("osim") else {}
                    robot = study.replace({"model.urdf": str(path), **osim}).model()
    except ResultFileError:
        raise
    except FatiguePinError as exc:
        text = " ".join(str(exc).split())
        if run.urdf:
            text = text.replace(f"URDF file {str(path)!r}", "its stored URDF text").replace(str(path), "its stored URDF text")
        raise ResultFileError(f"run {run.name!r}: the model it was solved on cannot be rebuilt: {text}") from None
    g = np.asarray(robot.pin_model.gravity.linear, dtype=float)
    if not np.all(np.isfinite(g)):
        raise ResultFileError(f"run {run.name!r}: its stored gravity {g.tolist()} m/s^2 is not finite; expected 3 finite numbers")
    if tuple(robot.joint_names) != tuple(run.joint_names):
        raise ResultFileError(f"run {run.name!r}: joints {list(run.joint_names)} differ from its model's {list(robot.joint_names)}")
    if robot.pin_model.nq != robot.pin_model.nv:
        raise ResultFileError(f"run {run.name!r}: model with nq = {robot.pin_model.nq} != nv = {robot.pin_model.nv}; "
                              "verify handles one-DoF joints only")
    return robot


def _limits(run: RunResult, robot, notes: list[str]) -> np.ndarray:
    """Signed torque limits (plus, minus per joint), as stored (:attr:`RunResult.signed_limits`);
    for a muscle run, 1 for each muscle (its activation at TL = 1), then its residual halves'; for
    a motor run, each motor's limit (> 0; its torque is signed)."""
    try:
        signed = run.signed_limits
    except (TypeError, ValueError) as exc:
        if isinstance(exc, ResultFileError):
            raise
        raise ResultFileError(f"run {run.name!r}: attribute tau_limits = {shown(run.attrs.get('tau_limits'))} is not a list of numbers") from None
    if run.actuation == "motors":  # a motor's limit bounds its signed torque on its joint
        if signed.size != len(run.actuator_names) or not np.all(np.isfinite(signed)) or np.any(signed <= 0) \
                or any(j not in robot.joint_names for j in run.actuator_names):
            raise ResultFileError(f"run {run.name!r}: torque limits {signed.tolist()} N m for the motors {list(run.actuator_names)}; "
                                  "expected a finite limit > 0 for each motor, on a joint of the model")
        return signed
    nm = len(run.muscle_names)
    if nm:
        if not np.array_equal(signed[:nm], np.ones(nm)):
            raise ResultFileError(f"run {run.name!r}: limits {signed[:nm].tolist()} of its muscles; expected 1 (activation) for each")
        if signed.size == nm:
            return signed
        halves = _limits(dataclasses.replace(run, actuator_names=run.actuator_names[nm:], attrs={**run.attrs, "tau_limits": signed[nm:],
                                                                                             "muscle_names": ""}), robot, notes)
        return np.concatenate([signed[:nm], halves])
    if not np.all(np.isfinite(signed)) or np.any(signed[0::2] <= 0) or np.any(signed[1::2] >= 0):
        raise ResultFileError(f"run {run.name!r}: torque limits {signed.tolist()} N m; expected finite limits, > 0 for "
                              "each plus half and < 0 for each minus half")
    joints = [half_joint(name)[0] for name in run.actuator_names[0::2]]  # the actuated joints
    if signed.size != 2 * len(joints) or any(j not in robot.joint_names for j in joints):
        raise ResultFileError(f"run {run.name!r}: {signed.size} torque limits for the halves {list(run.actuator_names)}")
    effort = np.asarray(robot.tau_upper, dtype=float)[[list(robot.joint_names).index(j) for j in joints]]
    if not np.allclose(signed, np.ravel(np.column_stack([effort, -effort]))):
        notes.append(f"stored torque limits {signed.tolist()} differ from the URDF effort limits {effort.tolist()}")
    return signed


def _fatigue_params(run: RunResult) -> dict[str, dict]:
    """Fatigue model and parameters per half: the plant's (``plant_fatigue_params``) for a
    closed-loop run, else the run's own."""
    raw = run.attrs.get("plant_fatigue_params") or run.attrs.get("fatigue_params")
    if raw:
        try:
            per_half = json.loads(raw)
        except (TypeError, json.JSONDecodeError) as exc:
            raise ResultFileError(f"run {run.name!r}: attribute fatigue_params is not JSON ({exc})") from None
        if not isinstance(per_half, dict) or not all(isinstance(v, dict) for v in per_half.values()):
            raise ResultFileError(f"run {run.name!r}: attribute fatigue_params is not a table of tables (half -> parameters)")
        return per_half
    if all(k in run.attrs for k in ("LD", "LR", "F", "R", "S")):  # files of the first layout: one Xia model
        return {h: {"model": "xia", **{k: float(run.attrs[k]) for k in ("LD", "LR", "F", "R", "S")}} for h in run.actuator_names}
    raise ResultFileError(f"run {run.name!r} stores no fatigue parameters (attribute fatigue_params); cannot verify it")


def _halves(run: RunResult, limits: np.ndarray) -> list[Half]:
    """The actuator halves from the ``fatigue_params`` attribute."""
    from fatigue_pin.ocp.actuation_layer import unit_model

    per_half = _fatigue_params(run)
    if len(run.actuator_names) != limits.size:
        raise ResultFileError(f"run {run.name!r}: {len(run.actuator_names)} actuator halves for {limits.size} torque limits")
    out = []
    for h, name in enumerate(run.actuator_names):
        if name not in per_half:
            raise ResultFileError(f"run {run.name!r}: fatigue_params has no entry for half {name!r}; it has {sorted(per_half)}")
        values = dict(per_half[name])
        kind = values.pop("model", "xia")
        try:
            model = unit_model(kind, **values)
        except (FatiguePinError, TypeError) as exc:
            raise ResultFileError(f"run {run.name!r}: fatigue parameters of half {name!r}: {exc}") from None
        params = model.as_dict()
        f = numpy_rhs(kind)
        rhs = (lambda m, TL, f=f, params=params: f(m, TL, params)) if f is not None else model.rates
        missing = [s for s in model.state_names if s not in run.fatigue]
        if missing:
            raise ResultFileError(f"run {run.name!r}: half {name!r} ({kind}) needs fatigue states {missing}, which the run does not store")
        out.append(Half(name, kind, model, params, tuple(model.state_names), float(limits[h]), rhs))
    return out


def _task(run: RunResult, study, n: int, notes: list[str]):
    """The stored study's task, its phases placed on the run's grid; None without a study."""
    from fatigue_pin.core.errors import TaskError

    if study is None:
        notes.append("no study stored: task not checked")
        return None
    try:
        task = study.task()
    except FatiguePinError as exc:
        raise ResultFileError(f"run {run.name!r}: the task of its stored study does not build: {exc}") from None
    if task.intervals_per_cycle != n:
        notes.append(f"the stored study has {task.intervals_per_cycle} intervals per cycle, the run {n}: "
                     "task nodes placed on the run's grid")
        try:
            task = dataclasses.replace(task, intervals_per_cycle=n)
        except TaskError as exc:
            notes.append(f"the task's phases are not nodes of the run's grid ({exc}): task not checked")
            return None
    return task
