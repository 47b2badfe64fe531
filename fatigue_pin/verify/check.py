"""An independent check of a stored result: ``fatigue-pin verify FILE.h5 [RUN]``.

Everything is rebuilt from what the run stores, without the package's interval functions
(``F_rb``, ``F_fatigue``, ``IntervalFunctions.step``) or its CasADi dynamics:

* the rigid body from the run's URDF text (``pinocchio.buildModelFromXML``), its accelerations
  from numeric ``pinocchio.aba``;
* the fatigue models from the ``fatigue_params`` attribute (kind and values per half), their
  right-hand side from a numpy transcription of the equations (Xia's 3CC/3CC-S/3CC-r, Michaud),
  cross-checked against the model's own ``rates`` on every stored node (models without a numpy
  transcription are integrated with ``rates``);
* the integration with ``scipy.integrate.solve_ivp`` (DOP853, rtol 1e-10, atol 1e-12 by default)
  over each interval, with the stored piecewise-constant control;
* the task from the stored study's TOML text (joint targets, ranges, initial posture).

Checked (``docs/verify.md`` gives the equations): multiple-shooting gaps (q, qdot, fatigue states),
task violation, coupling ``0 <= TL + m_fatigued <= 1`` at every node (``u_N := u_{N-1}``), bounds
(q, qdot, torques, fatigue states in [0, 1]), the invariant ``|1 - sum of states|`` and, on request,
the single-shooting drift over the whole horizon. Gaps, task, coupling and bounds have tolerances
(:class:`VerifyTolerances`); the invariant, the right-hand-side cross-check and the drift are
reported only.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.io.results import ResultFileError, RunResult

__all__ = ["VerifyTolerances", "VerifyCheck", "VerifyReport", "verify_run", "numpy_rhs", "DEFAULT_RTOL", "DEFAULT_ATOL"]

#: Default tolerances of the reference integration (DOP853).
DEFAULT_RTOL = 1e-10
DEFAULT_ATOL = 1e-12
#: Velocity bound where the URDF gives none (as :func:`fatigue_pin.robot.model.load_model`).
DEFAULT_VELOCITY_LIMIT = 10 * math.pi


@dataclass(frozen=True)
class VerifyTolerances:
    """Tolerances of the checks that decide ``passed`` (absolute, in the unit of each check).

    Attributes:
        gap: multiple-shooting gap of q (rad or m) and qdot (rad/s or m/s). It must admit the
            transcription's own RK4 error: about 1e-4 on the test discretisation (10 intervals per
            cycle, 2 substeps), 1e-8 on the paper's (50 intervals, 5 substeps).
        gap_fatigue: multiple-shooting gap of the fatigue states (dimensionless).
        task: joint targets (beyond their own tolerance), joint ranges and the initial state.
        coupling: ``TL + m_fatigued`` outside [0, 1] (IPOPT's ``constr_viol_tol`` is 1e-4).
        bound: q, qdot, torques (N m) and fatigue states outside their bounds.
    """

    gap: float = 1e-3
    gap_fatigue: float = 1e-5
    task: float = 1e-4
    coupling: float = 1e-4
    bound: float = 1e-4

    def __post_init__(self) -> None:
        for name in ("gap", "gap_fatigue", "task", "coupling", "bound"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
                raise ParameterError(f"VerifyTolerances.{name} = {value!r}: expected a finite tolerance >= 0")


@dataclass(frozen=True)
class VerifyCheck:
    """One line of the report.

    Attributes:
        name: what is checked (e.g. ``gap qdot``).
        value: the worst violation or error (NaN when not checked).
        unit: the unit of ``value``.
        tolerance: the limit that decides pass/fail, or None (reported only).
        where: where the worst value is (e.g. ``interval 13, elbow``).
    """

    name: str
    value: float
    unit: str
    tolerance: float | None = None
    where: str = ""

    @property
    def checked(self) -> bool:
        return not math.isnan(self.value)

    @property
    def passed(self) -> bool:
        return self.tolerance is None or not self.checked or self.value <= self.tolerance

    @property
    def verdict(self) -> str:
        if not self.checked:
            return "not checked"
        if self.tolerance is None:
            return "reported"
        return "ok" if self.passed else "FAIL"


@dataclass
class VerifyReport:
    """The outcome of :func:`verify_run`.

    Attributes:
        run: run name; horizon: ``full`` or ``sliding``.
        n_intervals, dt, substeps: the run's grid (substeps: of the stored transcription, 0 if unknown).
        checks: every check, in table order (:class:`VerifyCheck`).
        gap_q, gap_qdot, gap_fatigue: worst multiple-shooting gaps (rad, rad/s, 1).
        task: worst task violation (NaN when the run stores no study).
        coupling: worst coupling violation (TL + fatigued fraction outside [0, 1]).
        bound: worst bound violation (q, qdot, torques, fatigue states).
        invariant: worst |1 - sum of states| over nodes and halves; invariant_final: at the last node.
        invariant_sum: the sum used per model kind (e.g. ``xia: ma + mr + mf``).
        rhs_check: worst |numpy rhs - model rates| over the nodes (NaN without a numpy transcription).
        rk4_residual: worst |RK4(x_k, u_k) - x_{k+1}| with the stored substeps, RK4 written again in
            numpy (the NLP's own gaps: small when it was solved); NaN when substeps are unknown.
        rk4_truncation: worst |RK4(x_k, u_k) - exact flow(x_k, u_k)|: how coarse the grid is.
        drift_q, drift_qdot, drift_fatigue, drift_invariant: single-shooting drift (NaN unless asked).
        single_shooting_invariant, single_shooting_invariant_final: |1 - sum| of the
            single-shooting states, worst over nodes and at the last node (NaN unless asked).
        notes: what was not checked and why.
        tolerances: the tolerances used; rtol, atol: of the reference integration.
    """

    run: str
    horizon: str
    n_intervals: int
    dt: float
    substeps: int
    checks: list[VerifyCheck]
    gap_q: float
    gap_qdot: float
    gap_fatigue: float
    task: float
    coupling: float
    bound: float
    invariant: float
    invariant_final: float
    invariant_sum: str
    rhs_check: float
    rk4_residual: float
    rk4_truncation: float
    tolerances: VerifyTolerances
    rtol: float
    atol: float
    method: str = "DOP853"
    drift_q: float = float("nan")
    drift_qdot: float = float("nan")
    drift_fatigue: float = float("nan")
    drift_invariant: float = float("nan")
    single_shooting_invariant: float = float("nan")
    single_shooting_invariant_final: float = float("nan")
    notes: list[str] = field(default_factory=list)

    @property
    def gap(self) -> float:
        """Worst gap of q and qdot."""
        return max(self.gap_q, self.gap_qdot)

    @property
    def failures(self) -> list[VerifyCheck]:
        return [c for c in self.checks if not c.passed]

    @property
    def passed(self) -> bool:
        return not self.failures

    def table(self) -> str:
        """The report as text: one line per check, notes, and the verdict."""
        head = (f"verify {self.run} ({self.horizon}, {self.n_intervals} intervals of {self.dt:g} s"
                f"{f', {self.substeps} RK4 substeps' if self.substeps else ''}; reference {self.method} rtol {self.rtol:g} atol {self.atol:g})")
        lines = [head, f"  {'check':<36}{'worst':>11}  {'unit':<7}{'tolerance':>10}  {'result':<12}where"]
        for c in self.checks:
            value = "-" if not c.checked else f"{c.value:.3e}"
            tol = "-" if c.tolerance is None else f"{c.tolerance:.0e}"
            lines.append(f"  {c.name:<36}{value:>11}  {c.unit:<7}{tol:>10}  {c.verdict:<12}{c.where}")
        for note in self.notes:
            lines.append(f"  note: {note}")
        if self.passed:
            lines.append("  PASSED")
        else:
            lines.append("  FAILED: " + "; ".join(f"{c.name} {c.value:.3e} > {c.tolerance:g} ({c.where})" for c in self.failures))
        return "\n".join(lines)


# -- the fatigue right-hand sides, in numpy ---------------------------------------------------------


def _xia(m: np.ndarray, TL: float, p: dict[str, float]) -> np.ndarray:
    """Xia's 3CC with stabiliser S and rest multiplier r (docs/fatigue.md)."""
    ma, mr, mf = m
    if ma < TL:
        C = p["LD"] * (TL - ma) if mr >= TL - ma else p["LD"] * mr
        R = p["R"]
    else:
        C = p["LR"] * (TL - ma)
        R = p["r"] * p["R"]
    return np.array([
        C - p["F"] * ma,
        -C + R * mf,
        p["F"] * ma - R * mf + p["S"] * (1.0 - ma - mr - mf),
    ])


def _michaud(m: np.ndarray, TL: float, p: dict[str, float]) -> np.ndarray:
    """Michaud's model as bioptim writes it (fatigue_pin.fatigue.models.michaud_rhs docstring)."""
    ma, mr, mf, E = m
    th, k, S = p["effort_threshold"], p["effort_factor"], p["stabilization_factor"]
    if ma < TL:
        C = p["LD"] * (TL - ma) if mr > TL - ma else p["LD"] * mr
    else:
        C = p["LR"] * (TL - ma)
    above, below = TL > th, TL < th
    e = k * (TL - th) * ((1.0 - E) / (1.0 - th) if above else E / th)
    return np.array([
        C - p["F"] * ma - (e if above else 0.0),
        -C + p["R"] * mf - (e if below else 0.0),
        p["F"] * ma - p["R"] * mf,
        e + S * (1.0 - ma - mr - mf - E),
    ])


_NUMPY_RHS: dict[str, Callable[[np.ndarray, float, dict[str, float]], np.ndarray]] = {"xia": _xia, "michaud": _michaud}


def numpy_rhs(kind: str) -> Callable[[np.ndarray, float, dict[str, float]], np.ndarray] | None:
    """The numpy right-hand side ``(m, TL, params by name) -> dm/dt`` of a fatigue model kind, or
    None when there is no numpy transcription of it."""
    return _NUMPY_RHS.get(kind)


# -- what the run stores, rebuilt ------------------------------------------------------------------


@dataclass
class _Half:
    name: str
    kind: str
    model: Any  # FatigueModel
    params: dict[str, float]
    states: tuple[str, ...]
    fatigued: str
    limit: float  # signed torque at TL = 1
    rhs: Callable[[np.ndarray, float], np.ndarray]


def _halves(run: RunResult, signed_limits: np.ndarray) -> list[_Half]:
    from fatigue_pin.core.errors import FatiguePinError
    from fatigue_pin.fatigue.models import FATIGUE_MODELS, fatigue_model

    raw = run.attrs.get("fatigue_params")
    if raw:
        try:
            per_half = json.loads(raw)
        except (TypeError, json.JSONDecodeError) as exc:
            raise ResultFileError(f"run {run.name!r}: attribute fatigue_params is not JSON ({exc})") from None
    elif all(k in run.attrs for k in ("LD", "LR", "F", "R", "S")):  # files of the first layout: one Xia model
        per_half = {h: {"model": "xia", **{k: float(run.attrs[k]) for k in ("LD", "LR", "F", "R", "S")}} for h in run.actuator_names}
    else:
        raise ResultFileError(f"run {run.name!r} stores no fatigue parameters (attribute fatigue_params); cannot verify it")
    out = []
    for h, name in enumerate(run.actuator_names):
        if name not in per_half:
            raise ResultFileError(f"run {run.name!r}: fatigue_params has no entry for half {name!r}; it has {sorted(per_half)}")
        values = dict(per_half[name])
        kind = values.pop("model", "xia")
        if kind not in FATIGUE_MODELS:
            raise ResultFileError(f"run {run.name!r}: half {name!r} uses fatigue model {kind!r}, unknown here; known: {sorted(FATIGUE_MODELS)}")
        try:
            model = fatigue_model(kind, **values)
        except FatiguePinError as exc:
            raise ResultFileError(f"run {run.name!r}: fatigue parameters of half {name!r}: {exc}") from None
        params = model.as_dict()
        f = numpy_rhs(kind)
        rhs = (lambda m, TL, f=f, params=params: f(m, TL, params)) if f is not None else model.rates
        missing = [s for s in model.state_names if s not in run.fatigue]
        if missing:
            raise ResultFileError(f"run {run.name!r}: half {name!r} ({kind}) needs fatigue states {missing}, which the run does not store")
        out.append(_Half(name, kind, model, params, tuple(model.state_names), model.fatigued_state, float(signed_limits[h]), rhs))
    return out


def _pin_model(run: RunResult, gravity: list[float] | None):
    import pinocchio as pin

    if not run.urdf:
        raise ResultFileError(f"run {run.name!r} stores no URDF text; cannot rebuild its model")
    try:
        model = pin.buildModelFromXML(run.urdf)
    except Exception as exc:  # Pinocchio raises ValueError/RuntimeError with the parser's message
        raise ResultFileError(f"run {run.name!r}: its URDF text does not parse: {exc}") from None
    if gravity is not None:
        model.gravity.linear = np.asarray(gravity, dtype=float)
    names = tuple(model.names[i] for i in range(1, model.njoints))
    if names != tuple(run.joint_names):
        raise ResultFileError(f"run {run.name!r}: joints {list(run.joint_names)} differ from its URDF's {list(names)}")
    if model.nq != model.nv:
        raise ResultFileError(f"run {run.name!r}: model with nq = {model.nq} != nv = {model.nv}; verify handles one-DoF joints only")
    return model


def _where(k: int, what: str, label: str = "") -> str:
    return f"{what} {k}" + (f", {label}" if label else "")


def _worst(values: np.ndarray, labels: tuple[str, ...] | list[str], what: str, offset: int = 0) -> tuple[float, str]:
    """Max of a (rows, columns) array and where it is."""
    values = np.asarray(values, dtype=float)
    if values.size == 0:
        return 0.0, ""
    flat = np.nan_to_num(values, nan=0.0)
    k, j = np.unravel_index(int(np.argmax(flat)), flat.shape)
    if not flat[k, j] > 0:
        return 0.0, ""
    return float(flat[k, j]), _where(int(k) + offset, what, labels[j] if len(labels) > j else "")


class _Dynamics:
    """Numeric right-hand sides of the rigid body (pin.aba) and the fatigue states."""

    def __init__(self, pin_model, halves: list[_Half]) -> None:
        import pinocchio as pin

        self.pin = pin
        self.model = pin_model
        self.data = pin_model.createData()
        self.nq = pin_model.nq
        self.halves = halves
        self.sizes = [len(h.states) for h in halves]
        self.offsets = np.cumsum([0, *self.sizes])

    def rigid(self, tau: np.ndarray) -> Callable[[float, np.ndarray], np.ndarray]:
        nq, pin, model, data = self.nq, self.pin, self.model, self.data

        def f(_t: float, y: np.ndarray) -> np.ndarray:
            return np.concatenate([y[nq:], pin.aba(model, data, y[:nq], y[nq:], tau)])

        return f

    def fatigue(self, TL: np.ndarray) -> Callable[[float, np.ndarray], np.ndarray]:
        halves, off = self.halves, self.offsets

        def f(_t: float, m: np.ndarray) -> np.ndarray:
            return np.concatenate([h.rhs(m[off[i]:off[i + 1]], TL[i]) for i, h in enumerate(halves)])

        return f


def _integrate(f: Callable[[float, np.ndarray], np.ndarray], y0: np.ndarray, dt: float, rtol: float, atol: float,
               method: str = "DOP853") -> np.ndarray:
    from scipy.integrate import solve_ivp

    sol = solve_ivp(f, (0.0, dt), y0, method=method, rtol=rtol, atol=atol)
    if not sol.success:
        raise ResultFileError(f"the reference integration failed: {sol.message}")
    return sol.y[:, -1]


def _rk4(f: Callable[[float, np.ndarray], np.ndarray], y: np.ndarray, dt: float, steps: int) -> np.ndarray:
    """``steps`` classical Runge-Kutta steps over ``dt`` (the transcription's scheme, written again)."""
    h = dt / steps
    for _ in range(steps):
        k1 = f(0.0, y)
        k2 = f(0.0, y + h / 2 * k1)
        k3 = f(0.0, y + h / 2 * k2)
        k4 = f(0.0, y + h * k3)
        y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return y


def _target_loads(run: RunResult, halves: list[_Half]) -> np.ndarray:
    """TL of every half on every interval, (intervals, halves): tau_plus / limit, tau_minus / limit."""
    nv = run.tau_plus.shape[1]
    tau = np.empty((run.tau_plus.shape[0], 2 * nv))
    tau[:, 0::2], tau[:, 1::2] = run.tau_plus, run.tau_minus
    return tau / np.array([h.limit for h in halves])[None, :]


def _fatigue_matrix(run: RunResult, halves: list[_Half]) -> np.ndarray:
    """Fatigue states (nodes, n_states): each half's states in its model's order, halves in order."""
    cols = [run.fatigue[s][:, h] for h, half in enumerate(halves) for s in half.states]
    return np.column_stack(cols) if cols else np.zeros((run.t.size, 0))


def _state_labels(halves: list[_Half]) -> list[str]:
    return [f"{h.name} {s}" for h in halves for s in h.states]


# -- the checks ------------------------------------------------------------------------------------


def _task_checks(run: RunResult, pin_model, study_data: dict | None, n: int, N: int, tol: float,
                 x0_fatigue: np.ndarray, halves: list[_Half], notes: list[str]) -> list[VerifyCheck]:
    """Joint targets, joint ranges and the initial state against the stored study's task."""
    if study_data is None:
        notes.append("no study stored: task not checked")
        return [VerifyCheck("task targets", float("nan"), "rad", tol), VerifyCheck("task ranges", float("nan"), "rad", tol),
                VerifyCheck("initial state", float("nan"), "", tol)]
    task = study_data["task"]
    names = list(run.joint_names)
    if int(task["intervals_per_cycle"]) != n:
        notes.append(f"the stored study has {task['intervals_per_cycle']} intervals per cycle, the run {n}: "
                     "task nodes placed on the run's grid")
    # joint targets at phase `at` of every cycle; phase 0 also at the final node N + final_node_offset
    def joint(name: str) -> int:
        if name not in names:
            raise ResultFileError(f"run {run.name!r}: the study's task names joint {name!r}, not a joint of the run {names}")
        return names.index(name)

    worst, where = -math.inf, "no targets"
    for tgt in task["targets"]:
        j = joint(tgt["joint"])
        first = int(round(float(tgt["at"]) * n))
        nodes = list(range(first, N, n)) + ([N + int(task["final_node_offset"])] if first == 0 else [])
        for k in nodes:
            v = abs(run.q[k, j] - float(tgt["value"])) - float(tgt["tolerance"])
            if v > worst:
                worst, where = v, f"node {k}, {tgt['joint']} at {float(tgt['value']):.6g}"
    checks = [VerifyCheck("task targets", worst if worst > 0 else 0.0, "rad", tol, where)]
    worst, where = -math.inf, "no ranges"
    for rng in task["ranges"]:
        j = joint(rng["joint"])
        v = np.maximum(float(rng["lower"]) - run.q[:, j], run.q[:, j] - float(rng["upper"]))
        k = int(np.argmax(v))
        if v[k] > worst:
            worst, where = float(v[k]), f"node {k}, {rng['joint']} in [{float(rng['lower']):.6g}, {float(rng['upper']):.6g}]"
    checks.append(VerifyCheck("task ranges", worst if worst > 0 else 0.0, "rad", tol, where))
    # initial state: q_init (or the phase-0 targets, else 0), qdot = 0, every half rested
    if task.get("q_init") is not None:
        q0 = np.asarray(task["q_init"], dtype=float)
    else:
        q0 = np.zeros(pin_model.nq)
        for tgt in task["targets"]:
            if float(tgt["at"]) == 0.0:
                q0[names.index(tgt["joint"])] = float(tgt["value"])
    rest = np.concatenate([h.model.rest_state() for h in halves]) if halves else np.zeros(0)
    err = np.concatenate([np.abs(run.q[0] - q0), np.abs(run.qdot[0]), np.abs(x0_fatigue - rest)])
    labels = [f"q {j}" for j in names] + [f"qdot {j}" for j in names] + _state_labels(halves)
    k = int(np.argmax(err))
    checks.append(VerifyCheck("initial state", float(err[k]), "", tol, f"node 0, {labels[k]}"))
    return checks


def verify_run(run: RunResult, tolerances: VerifyTolerances | None = None, single_shooting: bool = False,
               rtol: float = DEFAULT_RTOL, atol: float = DEFAULT_ATOL, method: str = "DOP853") -> VerifyReport:
    """Check a stored run independently of the package's transcription.

    Args:
        run: a run read with :func:`fatigue_pin.io.results.read_run`.
        tolerances: the limits that decide ``passed`` (default :class:`VerifyTolerances`).
        single_shooting: also integrate the stored controls over the whole horizon from the
            stored initial state and report the drift of the states and of the invariant.
        rtol, atol, method: tolerances and method of ``solve_ivp`` (DOP853 by default; e.g.
            ``RK45`` with rtol 1e-3, atol 1e-6 as the paper's single shooting). They apply to the
            gap check too, so loose values loosen its reference.

    Returns:
        A :class:`VerifyReport`.

    Raises:
        ResultFileError: the run lacks what is needed (URDF, fatigue parameters) or is inconsistent.
    """
    from fatigue_pin.io.study import Study, StudyError

    tol = tolerances or VerifyTolerances()
    notes: list[str] = []
    run.require_cycles("verify")
    N = run.tau_plus.shape[0]
    if run.q.shape[0] != N + 1 or run.t.size != N + 1:
        raise ResultFileError(f"run {run.name!r}: {run.q.shape[0]} nodes for {N} intervals; expected {N + 1}")
    if N == 0:
        raise ResultFileError(f"run {run.name!r} has no interval (a failed first window?); nothing to verify")
    horizon = str(run.attrs.get("horizon", "full"))
    dt = float(run.attrs["dt"]) if "dt" in run.attrs else float(run.t[1] - run.t[0])
    if not np.allclose(np.diff(run.t), dt, rtol=1e-9, atol=1e-12):
        notes.append(f"node times are not spaced by dt = {dt:g} s; dt taken from the attribute")
    n = int(run.attrs.get("intervals_per_cycle", run.intervals_per_cycle))
    substeps = int(run.attrs.get("substeps", 0))

    study_data = None
    if run.study:
        try:
            study_data = Study.from_toml(run.study, f"the study stored with run {run.name!r}").data
        except StudyError as exc:
            notes.append(f"the stored study does not load ({exc}): task not checked")
    gravity = None if study_data is None else study_data["model"].get("gravity")
    pin_model = _pin_model(run, gravity)
    nq = pin_model.nq
    urdf_effort = np.array(pin_model.effortLimit, dtype=float)
    if run.attrs.get("tau_limits") is not None:
        signed = np.asarray(run.attrs["tau_limits"], dtype=float).reshape(-1)
    else:
        signed = np.ravel(np.column_stack([urdf_effort, -urdf_effort]))
        notes.append("no tau_limits attribute: torque limits from the URDF effort limits")
    if signed.size != 2 * pin_model.nv:
        raise ResultFileError(f"run {run.name!r}: {signed.size} torque limits for {2 * pin_model.nv} halves")
    if not np.allclose(np.abs(signed[0::2]), urdf_effort) or not np.allclose(np.abs(signed[1::2]), urdf_effort):
        notes.append(f"stored torque limits {signed.tolist()} differ from the URDF effort limits {urdf_effort.tolist()}")
    halves = _halves(run, signed)
    dyn = _Dynamics(pin_model, halves)

    Y = np.hstack([run.q, run.qdot])  # (nodes, 2 nq)
    M = _fatigue_matrix(run, halves)  # (nodes, n_states)
    TL = _target_loads(run, halves)  # (intervals, halves)
    tau = run.tau_plus + run.tau_minus
    labels_m = _state_labels(halves)
    joints = list(run.joint_names)

    # -- right-hand side cross-check: numpy transcription against the model's rates
    TL_nodes = np.vstack([TL, TL[-1:]])  # u_N := u_{N-1}
    rhs_err = float("nan")
    if any(numpy_rhs(h.kind) for h in halves):
        rhs_err = 0.0
        for k in range(N + 1):
            for i, h in enumerate(halves):
                if numpy_rhs(h.kind) is None:
                    continue
                m = M[k, dyn.offsets[i]:dyn.offsets[i + 1]]
                rhs_err = max(rhs_err, float(np.max(np.abs(h.rhs(m, TL_nodes[k, i]) - h.model.rates(m, TL_nodes[k, i])))))
    without = sorted({h.kind for h in halves if numpy_rhs(h.kind) is None})
    if without:
        notes.append(f"no numpy transcription of fatigue model(s) {without}: integrated with the model's rates")

    # -- multiple-shooting gaps: each interval from its stored node, stored control held
    # (and, with the stored number of substeps, the transcription's RK4 written again in numpy:
    # its residual says whether the NLP was solved, its distance to the exact flow how coarse the
    # grid is)
    gy = np.zeros((N, 2 * nq))
    gm = np.zeros((N, M.shape[1]))
    res = np.zeros((N, gy.shape[1] + gm.shape[1]))
    trunc = np.zeros_like(res)
    for k in range(N):
        fy, fm = dyn.rigid(tau[k]), dyn.fatigue(TL[k])
        ey = _integrate(fy, Y[k], dt, rtol, atol, method)
        em = _integrate(fm, M[k], dt, rtol, atol, method) if M.shape[1] else M[k]
        gy[k], gm[k] = np.abs(ey - Y[k + 1]), np.abs(em - M[k + 1])
        if substeps:
            ry = _rk4(fy, Y[k], dt, substeps)
            rm = _rk4(fm, M[k], dt, substeps) if M.shape[1] else M[k]
            res[k] = np.abs(np.concatenate([ry - Y[k + 1], rm - M[k + 1]]))
            trunc[k] = np.abs(np.concatenate([ry - ey, rm - em]))
    gap_q, at_q = _worst(gy[:, :nq], joints, "interval")
    gap_v, at_v = _worst(gy[:, nq:], joints, "interval")
    gap_m, at_m = _worst(gm, labels_m, "interval")
    labels_x = [f"q {j}" for j in joints] + [f"qdot {j}" for j in joints] + labels_m
    if substeps:
        rk4_res, at_res = _worst(res, labels_x, "interval")
        rk4_trunc, at_trunc = _worst(trunc, labels_x, "interval")
    else:
        rk4_res = rk4_trunc = float("nan")
        at_res = at_trunc = ""
        notes.append("no substeps attribute: the transcription's RK4 is not re-evaluated")
    if horizon == "sliding":
        notes.append("sliding horizon: each window's cyclic end condition is not checked (its end nodes are not kept); "
                     "the stitched trajectory's gaps are, joins included")

    # -- coupling 0 <= TL + m_fatigued <= 1 at every node
    fatigued = np.column_stack([run.fatigue[h.fatigued][:, i] for i, h in enumerate(halves)])
    c = TL_nodes + fatigued
    coupling, at_c = _worst(np.maximum(-c, c - 1.0), [h.name for h in halves], "node")

    # -- bounds
    q_lo, q_hi = np.array(pin_model.lowerPositionLimit), np.array(pin_model.upperPositionLimit)
    v_max = np.array(pin_model.velocityLimit, dtype=float)
    v_max = np.where(np.isfinite(v_max) & (v_max > 0), v_max, DEFAULT_VELOCITY_LIMIT)
    b_q, at_bq = _worst(np.maximum(q_lo - run.q, run.q - q_hi), joints, "node")
    b_v, at_bv = _worst(np.abs(run.qdot) - v_max, joints, "node")
    lim_plus, lim_minus = signed[0::2], signed[1::2]
    b_tp = np.maximum(-run.tau_plus, run.tau_plus - lim_plus)
    b_tm = np.maximum(run.tau_minus, lim_minus - run.tau_minus)
    b_t, at_bt = _worst(np.column_stack([b_tp, b_tm]), [f"{j} plus" for j in joints] + [f"{j} minus" for j in joints], "interval")
    b_m, at_bm = _worst(np.maximum(-M, M - 1.0), labels_m, "node")

    # -- invariant |1 - sum of each half's states|
    sums = np.column_stack([M[:, dyn.offsets[i]:dyn.offsets[i + 1]].sum(axis=1) for i in range(len(halves))])
    inv = np.abs(1.0 - sums)
    invariant, at_inv = _worst(inv, [h.name for h in halves], "node")
    inv_final = float(inv[-1].max()) if inv.size else 0.0
    kinds = {h.kind: " + ".join(h.states) for h in halves}
    invariant_sum = "; ".join(f"{k}: {s}" for k, s in kinds.items())

    name_sum = next(iter(kinds.values())) if len(kinds) == 1 else "sum of each half's states"
    checks = [
        VerifyCheck("gap q", gap_q, "rad", tol.gap, at_q),
        VerifyCheck("gap qdot", gap_v, "rad/s", tol.gap, at_v),
        VerifyCheck("gap fatigue states", gap_m, "1", tol.gap_fatigue, at_m),
        *_task_checks(run, pin_model, study_data, n, N, tol.task, M[0], halves, notes),
        VerifyCheck("coupling TL + m_fatigued in [0, 1]", coupling, "1", tol.coupling, at_c),
        VerifyCheck("bound q", b_q, "rad", tol.bound, at_bq),
        VerifyCheck("bound qdot", b_v, "rad/s", tol.bound, at_bv),
        VerifyCheck("bound torques", b_t, "N m", tol.bound, at_bt),
        VerifyCheck("bound fatigue states in [0, 1]", b_m, "1", tol.bound, at_bm),
        VerifyCheck(f"invariant |1 - ({name_sum})|", invariant, "1", None, at_inv),
        VerifyCheck("invariant at the last node", inv_final, "1", None, f"node {N}"),
        VerifyCheck("rhs: numpy vs model rates", rhs_err, "1/s", None, "every node"),
        VerifyCheck(f"RK4 residual ({substeps} substeps, numpy)", rk4_res, "state", None, at_res),
        VerifyCheck("RK4 truncation (RK4 - exact flow)", rk4_trunc, "state", None, at_trunc),
    ]
    failing = [c for c in checks if c.name.startswith("gap") and not c.passed]
    if failing and substeps and rk4_res <= 0.1 * min(c.tolerance for c in failing):
        notes.append(f"the gaps are the transcription's own RK4 error ({rk4_trunc:.2e} at {at_trunc}): the nodes solve "
                     f"the discretised problem (RK4 residual {rk4_res:.1e}) but the grid ({substeps} substeps of "
                     f"{dt / substeps:g} s) is too coarse for the gap tolerance")
    if len(kinds) > 1:
        notes.append(f"invariant sums: {invariant_sum}")
    report = VerifyReport(
        run=run.name, horizon=horizon, n_intervals=N, dt=dt, substeps=substeps, checks=checks,
        gap_q=gap_q, gap_qdot=gap_v, gap_fatigue=gap_m,
        task=max((c.value for c in checks if c.name in ("task targets", "task ranges", "initial state")), default=float("nan")),
        coupling=coupling, bound=max(b_q, b_v, b_t, b_m), invariant=invariant, invariant_final=inv_final,
        invariant_sum=invariant_sum, rhs_check=rhs_err, rk4_residual=rk4_res, rk4_truncation=rk4_trunc, tolerances=tol, rtol=rtol, atol=atol, method=method, notes=notes,
    )

    # -- single shooting: the stored controls over the whole horizon from the stored initial state
    if single_shooting:
        ys, ms = np.full_like(Y, np.nan), np.zeros_like(M)
        ys[0], ms[0] = Y[0], M[0]
        diverged = None  # the rigid body's open-loop integration can blow up over long horizons
        for k in range(N):
            if diverged is None:
                try:
                    ys[k + 1] = _integrate(dyn.rigid(tau[k]), ys[k], dt, rtol, atol, method)
                except ResultFileError:
                    diverged = k
            if M.shape[1]:  # the fatigue states depend on the controls only: always integrated
                ms[k + 1] = _integrate(dyn.fatigue(TL[k]), ms[k], dt, rtol, atol, method)
        dq, at_dq = _worst(np.abs(ys[:, :nq] - Y[:, :nq]), joints, "node")
        dv, at_dv = _worst(np.abs(ys[:, nq:] - Y[:, nq:]), joints, "node")
        if diverged is not None:
            dq, dv = float("inf"), float("inf")
            at_dq = at_dv = f"diverged on interval {diverged} (open-loop integration of the rigid body)"
            report.notes.append(f"single shooting: the rigid body's integration failed on interval {diverged} of {N}: "
                                "an open-loop swing amplifies small differences; the fatigue states were integrated to the end")
        dm, at_dm = _worst(np.abs(ms - M), labels_m, "node")
        inv_ss = np.abs(1.0 - np.column_stack([ms[:, dyn.offsets[i]:dyn.offsets[i + 1]].sum(axis=1) for i in range(len(halves))]))
        d_inv, at_di = _worst(np.abs(inv_ss - inv), [h.name for h in halves], "node")
        report.drift_q, report.drift_qdot, report.drift_fatigue, report.drift_invariant = dq, dv, dm, d_inv
        if inv_ss.size:
            report.single_shooting_invariant, report.single_shooting_invariant_final = float(inv_ss.max()), float(inv_ss[-1].max())
        report.checks += [
            VerifyCheck("single shooting: drift q", dq, "rad", None, at_dq),
            VerifyCheck("single shooting: drift qdot", dv, "rad/s", None, at_dv),
            VerifyCheck("single shooting: drift fatigue", dm, "1", None, at_dm),
            VerifyCheck("single shooting: invariant there", float(inv_ss.max()) if inv_ss.size else 0.0, "1", None,
                        f"max over nodes; {float(inv_ss[-1].max()) if inv_ss.size else 0.0:.3e} at node {N}"),
            VerifyCheck("single shooting: invariant drift", d_inv, "1", None, at_di),
        ]
    return report
