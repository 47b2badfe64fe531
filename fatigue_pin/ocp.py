"""The fatigue optimal control problem of a cyclic task: the formulation, in one place.

Paper section 3 / SPEC section 4. For a model with nv joints and 2 nv signed actuator halves:

States at node k (nx = nq + nv + 3 * 2nv)::

    x_k = [q (nq), qdot (nv), (ma, mr, mf) of every half (3 * 2nv)]

Controls on interval k (nu = 2 nv), piecewise constant::

    u_k = [tau_plus (nv) in [0, tau_max], tau_minus (nv) in [tau_min, 0]]

Dynamics (continuous, integrated by RK4 with ``substeps`` steps per interval)::

    d/dt q     = qdot
    d/dt qdot  = ABA(q, qdot, tau_plus + tau_minus)                   (Pinocchio, model.aba)
    d/dt m_h   = 3CC-S(m_h, TL_h)   TL_h = tau_plus/tau_max or tau_minus/tau_min  (actuators)

Direct multiple shooting over N = cycles * intervals_per_cycle intervals of length dt::

    x_{k+1} = F(x_k, u_k)                                               (gaps, k = 0..N-1)
    0 <= TL_h(u_k) + mf_h(x_k) <= 1       every half h, every node k = 0..N (u_N := u_{N-1})
    x_0 = x_init                           (fixed initial state)
    q_task(25 j) = low (j even) or high (j odd)    (the curl: 15 deg / 150 deg every 25 nodes)
    bounds on q, qdot (model), m in [0, 1], u (actuator halves)
    optional end bounds: q, qdot at node N within +-tol * range of a reference state

Objective (Lagrange terms, rectangle rule on the intervals)::

    J = sum_k dt * ( w_posture * sum_{j in penalised} q_j(k)^2
                   + w_torque_rate * |u_k - u_{k-1}|^2   (k >= 1)
                   + w_fatigue * sum_h mf_h(k)^2
                   + w_torque * |u_k|^2 )

Costs ``fatigue-torque``, ``fatigue`` and ``torque`` only differ in which weights are zero. Every
weight, every fatigue parameter, the initial state and all bounds are *parameters* of one Opti
problem, so the NLP is built (and compiled) once per model and horizon length and then re-solved
for any cost, stabiliser, window or initial state.
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass, field, replace
from typing import Mapping

import casadi as ca
import numpy as np

from fatigue_pin.actuators import SignedTorqueActuators
from fatigue_pin.errors import ParameterError, TaskError
from fatigue_pin.fatigue import FatigueParams
from fatigue_pin.model import RobotModel
from fatigue_pin.solver import NlpResult, NlpSolver, SolverOptions, openmp_fallback_quiet

#: Names of the cost terms, in the order of :attr:`CostWeights.vector` and of ``cycle_costs``.
COST_TERMS = ("posture", "torque_rate", "fatigue", "torque")
#: The three costs of the paper and the terms each one uses.
COSTS: dict[str, tuple[str, ...]] = {
    "fatigue-torque": ("posture", "torque_rate", "fatigue", "torque"),
    "fatigue": ("posture", "torque_rate", "fatigue"),
    "torque": ("posture", "torque_rate", "torque"),
}


@dataclass(frozen=True)
class CostWeights:
    """Weights of the named cost terms (each multiplies a square integrated over time).

    Attributes:
        posture: penalised joint angles q_j^2 (1/(rad^2 s)); the paper's shoulder penalty.
        torque_rate: (u_k - u_{k-1})^2 of every actuator half (1/(N^2 m^2 s)).
        fatigue: mf^2 of every actuator half (1/s).
        torque: tau^2 of every actuator half (1/(N^2 m^2 s)).
    """

    posture: float = 1e5
    torque_rate: float = 0.1
    fatigue: float = 1e3
    torque: float = 1.0

    def __post_init__(self) -> None:
        for name in COST_TERMS:
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ParameterError(f"CostWeights.{name} = {value!r}: expected a finite weight >= 0")

    @property
    def vector(self) -> np.ndarray:
        """Weights in :data:`COST_TERMS` order, shape (4,)."""
        return np.array([getattr(self, name) for name in COST_TERMS], dtype=float)

    def for_cost(self, cost: str) -> CostWeights:
        """These weights with the terms that ``cost`` does not use set to zero."""
        if cost not in COSTS:
            raise ParameterError(f"cost = {cost!r}: expected one of {list(COSTS)}")
        return replace(self, **{name: 0.0 for name in COST_TERMS if name not in COSTS[cost]})


@dataclass(frozen=True)
class Preset:
    """Values on which the paper text and the authors' code differ (SPEC section 4).

    Attributes:
        name: ``paper`` (the text) or ``authors-code`` (the code that produced the published results).
        R: recovery rate of every actuator half (1/s).
        posture_weight: weight of the shoulder penalty.
        last_node_offset: where the last ``low`` angle is imposed relative to the final node
            (0: node 50 n; -1: node 50 n - 1 as in the authors' code).
    """

    name: str
    R: float
    posture_weight: float
    last_node_offset: int


PRESETS: dict[str, Preset] = {
    "paper": Preset("paper", R=0.00094, posture_weight=1e5, last_node_offset=0),
    "authors-code": Preset("authors-code", R=0.0094, posture_weight=1e4, last_node_offset=-1),
}


@dataclass(frozen=True)
class CyclicTask:
    """A repeated movement of one joint between two angles, one round trip per cycle.

    At node ``j * intervals_per_cycle / 2`` the ``joint`` is at ``low`` (j even) or ``high`` (j odd);
    the other joints are free, and those in ``penalised_joints`` are pulled towards 0 by the
    posture cost. Defaults: the paper's biceps curl (elbow 15 deg -> 150 deg -> 15 deg in 1 s).

    Attributes:
        joint: the joint that performs the movement.
        low, high: its angles (rad) at the start/end and at the middle of every cycle.
        q_init: initial configuration (rad), shape (nq,); ``None`` puts the task joint at
            ``low`` and the others at 0.
        penalised_joints: joints whose angle squared is the posture cost.
        cycle_duration: duration of one cycle (s).
        intervals_per_cycle: shooting intervals per cycle (even).
        last_node_offset: the final ``low`` angle is imposed at node N + offset (0 or -1).
    """

    joint: str = "elbow"
    low: float = math.radians(15.0)
    high: float = math.radians(150.0)
    q_init: tuple[float, ...] | None = (0.07, math.radians(15.0))
    penalised_joints: tuple[str, ...] = ("shoulder",)
    cycle_duration: float = 1.0
    intervals_per_cycle: int = 50
    last_node_offset: int = 0

    def __post_init__(self) -> None:
        if self.intervals_per_cycle < 2 or self.intervals_per_cycle % 2:
            raise TaskError(f"CyclicTask.intervals_per_cycle = {self.intervals_per_cycle}: expected an even number >= 2")
        if not (np.isfinite(self.cycle_duration) and self.cycle_duration > 0):
            raise TaskError(f"CyclicTask.cycle_duration = {self.cycle_duration!r}: expected seconds > 0")
        if self.last_node_offset not in (0, -1):
            raise TaskError(f"CyclicTask.last_node_offset = {self.last_node_offset}: expected 0 or -1")

    @property
    def dt(self) -> float:
        """Length of one shooting interval (s)."""
        return self.cycle_duration / self.intervals_per_cycle

    def check(self, model: RobotModel) -> None:
        """Raise TaskError if the task does not fit the model (unknown joint, angle out of range)."""
        for name in (self.joint, *self.penalised_joints):
            if name not in model.joint_names:
                raise TaskError(f"task joint {name!r} is not in model {model.name!r}; its joints are {list(model.joint_names)}")
        i = model.joint_names.index(self.joint)
        for label, angle in (("low", self.low), ("high", self.high)):
            if not (model.q_lower[i] <= angle <= model.q_upper[i]):
                raise TaskError(
                    f"task {label} angle {angle!r} rad of joint {self.joint!r} is outside its range "
                    f"[{model.q_lower[i]}, {model.q_upper[i]}] rad"
                )
        q = self.initial_configuration(model)
        bad = [model.joint_names[j] for j in range(model.nq) if not (model.q_lower[j] <= q[j] <= model.q_upper[j])]
        if bad:
            raise TaskError(f"task initial configuration {q.tolist()} is outside the range of joints {bad}")

    def initial_configuration(self, model: RobotModel) -> np.ndarray:
        """Initial q (rad), shape (nq,)."""
        if self.q_init is None:
            q = np.zeros(model.nq)
            q[model.joint_names.index(self.joint)] = self.low
            return q
        q = np.asarray(self.q_init, dtype=float).reshape(-1)
        if q.size != model.nq:
            raise TaskError(f"CyclicTask.q_init has {q.size} entries; model {model.name!r} has nq = {model.nq}")
        return q

    def targets(self, n_intervals: int) -> list[tuple[int, float]]:
        """(node, angle) pairs imposed on the task joint over ``n_intervals`` intervals."""
        half = self.intervals_per_cycle // 2
        pairs = []
        for node in range(0, n_intervals + 1, half):
            angle = self.low if (node // half) % 2 == 0 else self.high
            if node == n_intervals and node > 0:
                node += self.last_node_offset
            pairs.append((node, angle))
        return pairs


#: initial-guess strategies of :class:`OcpSettings`
GUESSES = ("rest", "physical")


@dataclass(frozen=True)
class OcpSettings:
    """Everything that defines one fatigue OCP; the defaults are the paper's.

    Attributes:
        n_cycles: number of task cycles in the horizon.
        cost: ``fatigue-torque``, ``fatigue`` or ``torque``.
        preset: ``paper`` or ``authors-code`` (see :data:`PRESETS`).
        S: stabiliser of every actuator half (1/s); 0 for Xia's original model.
        weights: cost weights before the cost's unused terms are zeroed (default: the preset's).
        fatigue: fatigue parameters for every half (default: LD = LR = 10, F = 0.456, the preset's R,
            and ``S``); a mapping joint name -> params or -> (plus, minus) gives per-actuator values.
        task: the cyclic task.
        substeps: RK4 steps per shooting interval.
        end_tolerance: if set, q and qdot at the last node are bounded to a reference state
            +- end_tolerance * (their bound range) (0.01 in the sliding windows).
        expand: integrate the rigid body as one expanded SX function per interval instead of MX
            calls of the SX dynamics (much longer compile, slower; kept for comparisons).
        parallel: how the interval functions are mapped over the horizon: ``serial``, ``thread``
            (CasADi's virtual machine on every core; no gain in generated code) or ``openmp`` (the
            generated C of a compiled NLP is built with ``-fopenmp`` and evaluates the intervals on
            ``OMP_NUM_THREADS`` cores; CasADi's own virtual machine, without OpenMP in the PyPI
            wheel, evaluates serially). ``auto``: ``openmp`` when compiled, else ``serial``.
        guess: default initial guess of a solve: ``rest`` (the paper's: the initial state at every
            node, zero torque) or ``physical`` (the task joint on a cosine, inverse-dynamics torques,
            fatigue integrated from them).
        scaling: IPOPT works on scaled variables: joint velocities divided by their bound,
            torques by their limit (fewer iterations, same solution).
        solver: IPOPT settings.
    """

    n_cycles: int = 1
    cost: str = "fatigue-torque"
    preset: str = "paper"
    S: float = 10.0
    weights: CostWeights | None = None
    fatigue: FatigueParams | Mapping[str, object] | None = None
    task: CyclicTask | None = None
    substeps: int = 5
    end_tolerance: float | None = None
    expand: bool = False
    scaling: bool = True
    guess: str = "rest"
    parallel: str = "auto"
    solver: SolverOptions = field(default_factory=SolverOptions)

    def __post_init__(self) -> None:
        if int(self.n_cycles) != self.n_cycles or self.n_cycles < 1:
            raise ParameterError(f"OcpSettings.n_cycles = {self.n_cycles!r}: expected an integer >= 1")
        if self.cost not in COSTS:
            raise ParameterError(f"OcpSettings.cost = {self.cost!r}: expected one of {list(COSTS)}")
        if self.preset not in PRESETS:
            raise ParameterError(f"OcpSettings.preset = {self.preset!r}: expected one of {list(PRESETS)}")
        if not (np.isfinite(self.S) and self.S >= 0):
            raise ParameterError(f"OcpSettings.S = {self.S!r}: expected a finite stabiliser >= 0 (1/s)")
        if int(self.substeps) != self.substeps or self.substeps < 1:
            raise ParameterError(f"OcpSettings.substeps = {self.substeps!r}: expected an integer >= 1")
        if self.guess not in GUESSES:
            raise ParameterError(f"OcpSettings.guess = {self.guess!r}: expected one of {list(GUESSES)}")
        if self.parallel not in ("auto", "serial", "openmp", "thread"):
            raise ParameterError(f"OcpSettings.parallel = {self.parallel!r}: expected 'auto', 'serial', 'openmp' or 'thread'")
        if self.end_tolerance is not None and not (0 <= self.end_tolerance < 1):
            raise ParameterError(f"OcpSettings.end_tolerance = {self.end_tolerance!r}: expected a fraction in [0, 1) or None")

    @property
    def map_mode(self) -> str:
        """How the interval functions are mapped: ``auto`` is ``openmp`` for a compiled NLP (the
        generated C runs the intervals on every core) and ``serial`` otherwise."""
        if self.parallel == "auto":
            return "openmp" if self.solver.compile else "serial"
        return self.parallel

    @property
    def preset_values(self) -> Preset:
        return PRESETS[self.preset]

    def resolved_task(self) -> CyclicTask:
        """The task, with the preset's last-node rule when no task was given."""
        if self.task is not None:
            return self.task
        return CyclicTask(last_node_offset=self.preset_values.last_node_offset)

    def resolved_weights(self) -> CostWeights:
        """Weights of this cost (unused terms zeroed)."""
        base = self.weights if self.weights is not None else CostWeights(posture=self.preset_values.posture_weight)
        return base.for_cost(self.cost)

    def resolved_fatigue(self) -> FatigueParams | Mapping[str, object]:
        """Fatigue parameters (one set or per joint)."""
        if self.fatigue is not None:
            return self.fatigue
        return FatigueParams(LD=10.0, LR=10.0, F=0.456, R=self.preset_values.R, S=self.S)

    def with_(self, **changes: object) -> OcpSettings:
        """A copy with some fields changed (validated again)."""
        return replace(self, **changes)


@dataclass(frozen=True)
class StateLayout:
    """Where each quantity sits in the state and control vectors."""

    nq: int
    nv: int
    n_halves: int

    @property
    def nx(self) -> int:
        return self.nq + self.nv + 3 * self.n_halves

    @property
    def nu(self) -> int:
        return 2 * self.nv

    @property
    def q(self) -> slice:
        return slice(0, self.nq)

    @property
    def v(self) -> slice:
        return slice(self.nq, self.nq + self.nv)

    @property
    def m(self) -> slice:
        return slice(self.nq + self.nv, self.nx)

    def fatigue_index(self, state: str) -> list[int]:
        """Rows of ``ma``, ``mr`` or ``mf`` of every half in x."""
        k = ("ma", "mr", "mf").index(state)
        return [self.nq + self.nv + 3 * h + k for h in range(self.n_halves)]


def rk4(f: ca.Function, x: ca.MX | ca.SX, args: tuple, h: float, steps: int) -> ca.MX | ca.SX:
    """``steps`` classical Runge-Kutta steps of length ``h`` of ``xdot = f(x, *args)``."""
    for _ in range(steps):
        k1 = f(x, *args)
        k2 = f(x + h / 2 * k1, *args)
        k3 = f(x + h / 2 * k2, *args)
        k4 = f(x + h * k3, *args)
        x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return x


class IntervalFunctions:
    """The functions of one shooting interval, built once per model, actuators and dt.

    With piecewise-constant controls the rigid-body states (q, qdot) and the fatigue states m
    evolve independently over an interval, so RK4 on the whole state equals RK4 on each part.
    The two parts are integrated by separate functions, which keeps their derivatives (and the
    exact Hessian) small.

    Attributes:
        f_rb: ``f_rb(y, tau) -> ydot`` with y = (q, qdot): Pinocchio's ABA (SX).
        f_fatigue: ``f_fatigue(m, u, p) -> mdot`` of all actuator halves (SX).
        F_rb: ``F_rb(y, tau) -> y_next``, RK4 over one interval (MX calls of f_rb, or SX if expand).
        F_fatigue: ``F_fatigue(m, u, p) -> m_next``, RK4 over one interval (SX).
        coupling: ``coupling(x, u) -> TL + mf`` of every half.
        terms: unweighted cost terms of one interval ``terms(x, u, u_prev) -> (4,)``, times dt.
    """

    def __init__(self, model: RobotModel, actuators: SignedTorqueActuators, task: CyclicTask, substeps: int,
                 expand: bool = False) -> None:
        layout = StateLayout(model.nq, model.nv, actuators.n_halves)
        self.layout = layout
        nx, nu, nv, nq = layout.nx, layout.nu, layout.nv, layout.nq
        h = task.dt / substeps

        y = ca.SX.sym("y", nq + nv)
        tau = ca.SX.sym("tau", nv)
        self.f_rb = ca.Function("f_rb", [y, tau], [ca.vertcat(y[nq:], model.aba(y[:nq], y[nq:], tau))], ["y", "tau"], ["ydot"])
        if expand:
            self.F_rb = ca.Function("F_rb", [y, tau], [rk4(self.f_rb, y, (tau,), h, substeps)], ["y", "tau"], ["y_next"])
        else:
            # RK4 as MX calls of the SX f_rb: its derivative code stays small (fast to compile)
            y_mx, tau_mx = ca.MX.sym("y", nq + nv), ca.MX.sym("tau", nv)
            self.F_rb = ca.Function("F_rb", [y_mx, tau_mx], [rk4(self.f_rb, y_mx, (tau_mx,), h, substeps)], ["y", "tau"], ["y_next"])

        m = ca.SX.sym("m", 3 * actuators.n_halves)
        u = ca.SX.sym("u", nu)
        p = ca.SX.sym("p_fatigue", 6 * actuators.n_halves)
        self.f_fatigue = ca.Function("f_fatigue", [m, u, p], [actuators.fatigue_rates(m, u[:nv], u[nv:], p)], ["m", "u", "p"], ["mdot"])
        self.F_fatigue = ca.Function("F_fatigue", [m, u, p], [rk4(self.f_fatigue, m, (u, p), h, substeps)], ["m", "u", "p"], ["m_next"])

        x = ca.SX.sym("x", nx)
        u_prev = ca.SX.sym("u_prev", nu)
        q = x[layout.q]
        mf = x[layout.fatigue_index("mf")]
        self.coupling = ca.Function("coupling", [x, u], [actuators.coupling(x[layout.m], u[:nv], u[nv:])], ["x", "u"], ["TL_plus_mf"])
        posture_rows = [model.joint_names.index(j) for j in task.penalised_joints]
        posture = ca.sumsqr(q[posture_rows]) if posture_rows else ca.SX(0)
        terms = ca.vertcat(posture, ca.sumsqr(u - u_prev), ca.sumsqr(mf), ca.sumsqr(u)) * task.dt
        self.terms = ca.Function("terms", [x, u, u_prev], [terms], ["x", "u", "u_prev"], ["terms"])

    def step(self, x: np.ndarray, u: np.ndarray, p: np.ndarray) -> np.ndarray:
        """Numeric state after one interval, shape (nx,)."""
        L = self.layout
        nv = L.nv
        y = np.asarray(self.F_rb(x[: L.nq + nv], u[:nv] + u[nv:])).reshape(-1)
        m = np.asarray(self.F_fatigue(x[L.m], u, p)).reshape(-1)
        return np.concatenate([y, m])


@dataclass
class OcpSolution:
    """A solved (or failed) OCP on its node grid.

    Attributes:
        t: node times (s), shape (N+1,).
        x: states, shape (N+1, nx); u: controls, shape (N, nu).
        layout: the state layout; actuator_names: names of the halves (columns of ma, mr, mf).
        status, success, iterations, wall_time_s: from IPOPT (a failure keeps the last iterate).
        nlp: the raw NLP result (flat vectors and multipliers, for warm starts).
        cycle_costs: weighted cost terms per cycle, shape (n_cycles, 4), columns COST_TERMS.
    """

    t: np.ndarray
    x: np.ndarray
    u: np.ndarray
    layout: StateLayout
    actuator_names: tuple[str, ...]
    status: str
    success: bool
    iterations: int
    wall_time_s: float
    nlp: NlpResult
    cycle_costs: np.ndarray
    objective: float

    @property
    def q(self) -> np.ndarray:
        return self.x[:, self.layout.q]

    @property
    def qdot(self) -> np.ndarray:
        return self.x[:, self.layout.v]

    def fatigue(self, state: str) -> np.ndarray:
        """``ma``, ``mr`` or ``mf`` of every half, shape (N+1, n_halves)."""
        return self.x[:, self.layout.fatigue_index(state)]

    @property
    def tau_plus(self) -> np.ndarray:
        return self.u[:, : self.layout.nv]

    @property
    def tau_minus(self) -> np.ndarray:
        return self.u[:, self.layout.nv :]


class FatigueOcp:
    """The fatigue OCP of a cyclic task over a horizon of ``n_cycles`` cycles.

    Build once (symbolic functions, Opti problem, IPOPT solver, compiled code), then call
    :meth:`solve` any number of times with other initial states, end bounds, costs, stabilisers,
    fatigue parameters or initial guesses: they are all parameters.

    Args:
        model: the rigid-body model.
        settings: problem settings; ``settings.n_cycles`` fixes the horizon (the structure).
    """

    def __init__(self, model: RobotModel, settings: OcpSettings | None = None) -> None:
        t0 = time.perf_counter()
        settings = settings or OcpSettings()
        self.model = model
        self.settings = settings
        self.task = task = settings.resolved_task()
        task.check(model)
        self.actuators = SignedTorqueActuators.from_model(model, settings.resolved_fatigue())
        self.actuators.check_stabiliser(task.dt / settings.substeps, "rk4")
        self.n_intervals = N = settings.n_cycles * task.intervals_per_cycle
        self.functions = IntervalFunctions(model, self.actuators, task, settings.substeps, expand=settings.expand)
        self.layout = self.functions.layout
        with openmp_fallback_quiet():
            opti = self._formulate()
            self.nlp = NlpSolver(opti, settings.solver, name=f"fatigue_ocp_{model.name}_{N}")
        self._p_index = self._parameter_slices()
        self.build_time_s = time.perf_counter() - t0
        self.t = np.linspace(0.0, N * task.dt, N + 1)

    def _formulate(self) -> ca.Opti:
        """The NLP of SPEC section 4 as a ``casadi.Opti`` problem (variables, parameters,
        constraints, objective); sets ``X, U, T``, the parameters and the cost-term functions."""
        settings, fn, layout, N = self.settings, self.functions, self.layout, self.n_intervals
        nx, nu = layout.nx, layout.nu
        opti = ca.Opti()
        self.opti = opti
        # IPOPT sees scaled variables (torques in units of their limit, velocities of their bound)
        self.x_scale, self.u_scale, self.t_scale = self._variable_scales()
        Xs = opti.variable(nx, N + 1)
        Us = opti.variable(nu, N)
        # joint torque tau_plus + tau_minus as its own variable: the rigid-body dynamics then
        # depend on nv torques instead of 2 nv halves, which halves the exact Hessian's cost
        Ts = opti.variable(layout.nv, N)
        X = ca.diag(ca.DM(self.x_scale)) @ Xs
        U = ca.diag(ca.DM(self.u_scale)) @ Us
        T = ca.diag(ca.DM(self.t_scale)) @ Ts
        self.X, self.U, self.T = X, U, T
        P_fatigue = opti.parameter(self.actuators.n_halves * 6)
        P_weights = opti.parameter(len(COST_TERMS))
        X_lb, X_ub = opti.parameter(nx, N + 1), opti.parameter(nx, N + 1)
        U_lb, U_ub = opti.parameter(nu, N), opti.parameter(nu, N)
        self._params = (P_fatigue, P_weights, X_lb, X_ub, U_lb, U_ub)

        # Dynamics: multiple-shooting gaps, one mapped RK4 interval function.
        ny, nv = layout.nq + layout.nv, layout.nv
        mode = settings.map_mode
        par = (mode, max(1, os.cpu_count() or 1)) if mode == "thread" else (mode,)
        opti.subject_to(T == U[:nv, :] + U[nv:, :])
        opti.subject_to(X[:ny, 1:] == fn.F_rb.map(N, *par)(X[:ny, :N], T))
        opti.subject_to(X[ny:, 1:] == fn.F_fatigue.map(N, *par)(X[ny:, :N], U, P_fatigue))
        # Torque / fatigue coupling at every node (the last node uses the last control).
        coupling = fn.coupling.map(N + 1)(X, ca.horzcat(U, U[:, N - 1]))
        opti.subject_to(opti.bounded(0, coupling, 1))
        # Bounds (states, task angles, initial and end states are all in X_lb / X_ub).
        opti.subject_to(opti.bounded(X_lb, X, X_ub))
        opti.subject_to(opti.bounded(U_lb, U, U_ub))
        # Objective: weighted named terms, summed over intervals. The terms of every interval,
        # (4, N), as a function of states and controls, also evaluates the per-cycle costs.
        Xn, Un = ca.MX.sym("X", nx, N + 1), ca.MX.sym("U", nu, N)
        terms = fn.terms.map(N)(Xn[:, :N], Un, ca.horzcat(Un[:, 0], Un[:, : N - 1]))
        self._terms_fn = ca.Function("interval_terms", [Xn, Un], [terms])
        opti.minimize(ca.dot(P_weights, ca.sum2(self._terms_fn(X, U))))
        return opti

    # -- parameters and bounds -------------------------------------------------------------------

    def _variable_scales(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Scales of the decision variables (state, control, joint torque): IPOPT solves for
        value / scale. Velocities are scaled by their bound, torques by their limit."""
        L = self.layout
        x = np.ones(L.nx)
        u = np.ones(L.nu)
        t = np.ones(L.nv)
        if self.settings.scaling:

            def magnitude(lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
                """Largest |bound| per joint; 1 where it is infinite or zero."""
                m = np.maximum(np.abs(lower), np.abs(upper))
                return np.where(np.isfinite(m) & (m > 0), m, 1.0)

            x[L.v] = magnitude(self.model.v_lower, self.model.v_upper)
            tmax = magnitude(self.model.tau_lower, self.model.tau_upper)
            u = np.concatenate([tmax, tmax])
            t = tmax
        return x, u, t

    def _parameter_slices(self) -> list[slice]:
        """Slices of the Opti parameter vector for each parameter, in creation order."""
        slices, start = [], 0
        for par in self._params:
            slices.append(slice(start, start + par.numel()))
            start += par.numel()
        if start != self.opti.p.numel():
            raise RuntimeError("unexpected Opti parameter layout")
        return slices

    def initial_state(self) -> np.ndarray:
        """The task's initial state: q_init, zero velocity, every half at (ma, mr, mf) = (0, 1, 0)."""
        x0 = np.zeros(self.layout.nx)
        x0[self.layout.q] = self.task.initial_configuration(self.model)
        x0[self.layout.fatigue_index("mr")] = 1.0
        return x0

    def _x_init(self, x_init: np.ndarray | None) -> np.ndarray:
        """``x_init`` as a flat float array of nx entries; :meth:`initial_state` if None."""
        if x_init is None:
            return self.initial_state()
        x_init = np.asarray(x_init, dtype=float).reshape(-1)
        if x_init.size != self.layout.nx:
            raise ParameterError(f"x_init has {x_init.size} entries; expected nx = {self.layout.nx}")
        return x_init

    def state_bounds(self, x_init: np.ndarray, x_end: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Node-wise state bounds, each of shape (nx, N+1).

        Model bounds on q and qdot, [0, 1] on fatigue states, ``x_init`` at node 0, the task
        angles at their nodes and, with ``end_tolerance`` set and ``x_end`` given, q and qdot at
        the last node within ``x_end +- end_tolerance * range``.
        """
        L, N = self.layout, self.n_intervals
        lo = np.concatenate([self.model.q_lower, self.model.v_lower, np.zeros(3 * self.actuators.n_halves)])
        hi = np.concatenate([self.model.q_upper, self.model.v_upper, np.ones(3 * self.actuators.n_halves)])
        X_lb = np.tile(lo[:, None], (1, N + 1))
        X_ub = np.tile(hi[:, None], (1, N + 1))
        X_lb[:, 0] = X_ub[:, 0] = x_init
        j = self.model.joint_names.index(self.task.joint)
        for node, angle in self.task.targets(N):
            X_lb[j, node] = X_ub[j, node] = angle
        tol = self.settings.end_tolerance
        if tol is not None and x_end is not None:
            rows = np.r_[np.arange(L.nq), L.nq + np.arange(L.nv)]
            span = (hi - lo)[rows]
            X_lb[rows, N] = np.maximum(X_lb[rows, N], x_end[rows] - tol * span)
            X_ub[rows, N] = np.minimum(X_ub[rows, N], x_end[rows] + tol * span)
            for node, angle in self.task.targets(N):  # task angles win over the end box
                X_lb[j, node] = X_ub[j, node] = angle
        return X_lb, X_ub

    def control_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounds of the actuator halves, each of shape (nu, N)."""
        N, nv = self.n_intervals, self.layout.nv
        lo = np.concatenate([np.zeros(nv), self.model.tau_lower])
        hi = np.concatenate([self.model.tau_upper, np.zeros(nv)])
        return np.tile(lo[:, None], (1, N)), np.tile(hi[:, None], (1, N))

    def parameter_vector(
        self,
        x_init: np.ndarray | None = None,
        x_end: np.ndarray | None = None,
        weights: CostWeights | None = None,
        fatigue: np.ndarray | None = None,
    ) -> np.ndarray:
        """Opti parameter vector for one solve.

        Args:
            x_init: initial state (nx,); default :meth:`initial_state`.
            x_end: reference of the end bounds (nx,), used when ``end_tolerance`` is set.
            weights: cost weights (already zeroed for the cost); default the settings'.
            fatigue: stacked fatigue parameters (6 * n_halves,); default the actuators'.
        """
        x_init = self._x_init(x_init)
        weights = self.settings.resolved_weights() if weights is None else weights
        fatigue = self.actuators.param_vector() if fatigue is None else np.asarray(fatigue, dtype=float).reshape(-1)
        X_lb, X_ub = self.state_bounds(x_init, x_end)
        U_lb, U_ub = self.control_bounds()
        parts = [fatigue, weights.vector, X_lb, X_ub, U_lb, U_ub]
        return np.concatenate([np.asarray(a, dtype=float).reshape(-1, order="F") for a in parts])

    # -- initial guess ------------------------------------------------------------------------------

    def rollout_fatigue(self, x_init: np.ndarray, q: np.ndarray, qdot: np.ndarray, u: np.ndarray) -> np.ndarray:
        """States (N+1, nx) from given q, qdot and controls, with the fatigue states integrated
        forward from ``x_init``'s through the interval function, so that they are continuous."""
        N, L = self.n_intervals, self.layout
        x = np.zeros((N + 1, L.nx))
        x[:, L.q], x[:, L.v] = q, qdot
        x[0, L.m] = x_init[L.m]
        p = self.actuators.param_vector()
        for k in range(N):
            step = self.functions.step(np.r_[q[k], qdot[k], x[k, L.m]], u[k], p)
            x[k + 1, L.m] = np.clip(step[L.m], 0.0, 1.0)
        return x

    def rest_guess(self, x_init: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The paper's initial guess: every node at the initial state, zero torque.
        Shapes (N+1, nx), (N, nu)."""
        x_init = self._x_init(x_init)
        return np.tile(x_init, (self.n_intervals + 1, 1)), np.zeros((self.n_intervals, self.layout.nu))

    def initial_guess(self, x_init: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The initial guess named by ``settings.guess`` (``rest`` or ``physical``)."""
        if self.settings.guess == "physical":
            return self.physical_guess(x_init)
        return self.rest_guess(x_init)

    def physical_guess(self, x_init: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """A physical initial guess: the task joint on a cosine between its targets, the other
        joints at their initial angles, the inverse-dynamics torques split into the actuator
        halves, and the fatigue states integrated from those torques. Shapes (N+1, nx), (N, nu)."""
        x_init = self._x_init(x_init)
        N, L, task = self.n_intervals, self.layout, self.task
        j = self.model.joint_names.index(task.joint)
        t = self.t
        phase = 2 * np.pi * t / task.cycle_duration
        q = np.tile(x_init[L.q], (N + 1, 1))
        q[:, j] = task.low + (task.high - task.low) * 0.5 * (1 - np.cos(phase))
        w = 2 * np.pi / task.cycle_duration
        qdot = np.zeros((N + 1, L.nv))
        qdot[:, j] = (task.high - task.low) * 0.5 * w * np.sin(phase)
        qddot = np.zeros((N + 1, L.nv))
        qddot[:, j] = (task.high - task.low) * 0.5 * w * w * np.cos(phase)
        tau = np.array([np.asarray(self.model.rnea(q[k], qdot[k], qddot[k])).reshape(-1) for k in range(N)])
        tau = np.clip(tau, self.model.tau_lower, self.model.tau_upper)
        u = np.hstack([np.maximum(tau, 0.0), np.minimum(tau, 0.0)])
        x = self.rollout_fatigue(x_init, q, qdot, u)
        return x, u

    def flatten(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Decision vector in Opti's order (X, U, T) from states (N+1, nx) and controls (N, nu)."""
        x, u = np.asarray(x, dtype=float), np.asarray(u, dtype=float)
        nv = self.layout.nv
        tau = u[:, :nv] + u[:, nv:]
        xs, us, ts = x / self.x_scale, u / self.u_scale, tau / self.t_scale
        return np.concatenate([xs.T.reshape(-1, order="F"), us.T.reshape(-1, order="F"), ts.T.reshape(-1, order="F")])

    def unflatten(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """States (N+1, nx) and controls (N, nu) from a decision vector."""
        N, L = self.n_intervals, self.layout
        nX, nU = L.nx * (N + 1), L.nu * N
        x = z[:nX].reshape((L.nx, N + 1), order="F").T * self.x_scale
        u = z[nX : nX + nU].reshape((L.nu, N), order="F").T * self.u_scale
        return x, u

    # -- solving ----------------------------------------------------------------------------------

    def solve(
        self,
        x_init: np.ndarray | None = None,
        guess: tuple[np.ndarray, np.ndarray] | None = None,
        x_end: np.ndarray | None = None,
        warm: NlpResult | None = None,
        weights: CostWeights | None = None,
        max_iter: int | None = None,
    ) -> OcpSolution:
        """Solve the OCP.

        Args:
            x_init: fixed initial state (nx,); default :meth:`initial_state`.
            guess: initial guess (states (N+1, nx), controls (N, nu)); default :meth:`initial_guess`.
            x_end: reference state of the end bounds (with ``end_tolerance`` set).
            warm: a previous result of the same problem whose multipliers start this solve.
            weights: cost weights for this solve (default: the settings').
            max_iter: IPOPT iteration limit of this solve (default: the solver options').

        Returns:
            An :class:`OcpSolution`; check ``success`` before using it as optimal.
        """
        x_init = self._x_init(x_init)
        if guess is None:
            guess = self.initial_guess(x_init)
        p = self.parameter_vector(x_init, x_end, weights)
        z0 = self.flatten(*guess)
        res = self.nlp.solve(p, z0, warm.lam_x if warm else None, warm.lam_g if warm else None, max_iter=max_iter)
        x, u = self.unflatten(res.x)
        w = (weights or self.settings.resolved_weights()).vector
        terms = np.asarray(self._terms_fn(x.T, u.T))  # (4, N)
        per_cycle = terms.reshape(4, self.settings.n_cycles, self.task.intervals_per_cycle).sum(axis=2).T * w
        return OcpSolution(
            t=self.t.copy(),
            x=x,
            u=u,
            layout=self.layout,
            actuator_names=self.actuators.half_names,
            status=res.status,
            success=res.success,
            iterations=res.iterations,
            wall_time_s=res.wall_time_s,
            nlp=res,
            cycle_costs=per_cycle,
            objective=res.f,
        )
