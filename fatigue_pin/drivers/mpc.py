"""Closed-loop MPC: the sliding-horizon plan meets a plant that tires differently.

Four parts (as in MPC toolkits): the *model* (the controller's problem), the *controller* (the
sliding-horizon OCP of K cycles, :mod:`fatigue_pin.drivers.sliding`, re-planned every
``replan_every`` intervals), the *simulator* (:class:`~fatigue_pin.drivers.plant.Plant`, the
plant's own problem) and the *estimator* (:mod:`fatigue_pin.drivers.estimation`). With r =
``replan_every``, n intervals per cycle and H = K n::

    node k = 0, r, 2r, ... (until the run is done):
        measure q, qdot (noisy); correct the fatigue estimate (estimator)
        solve the window from x_init = (measured q, qdot, estimated m) with the estimated fatigue
        parameters, the window's phase k mod n, guess = the previous plan shifted by r
    every interval k: the plant applies u_k of the last converged plan (interval k - start),
        limited by its true fatigue; the estimator propagates with the delivered torques;
        every ``probe_every`` cycles (nodes c n, c >= 1) the controller gets a capacity probe

A window that starts mid-cycle (r not a multiple of n) uses the task shifted by its phase
(:func:`phase_shifted`); one OCP per phase, sharing the interval functions. The controller stops
re-planning when a window fails or once its plans reach ``max_cycles`` (the sliding horizon's
rules), and the plant then runs out the last converged plan; the run also ends when the plant
leaves the model's joint range (a joint stop). With the plant equal to the model, no noise and
r = A n, the plant therefore follows the sliding-horizon run. With ``end = "receding"`` the
controller instead re-plans until the plant has done ``max_cycles`` cycles (no open-loop tail).

With real-time iterations (``iterations_per_replan``), every re-plan after the first makes a
bounded number of IPOPT iterations from the plan in force, shifted, and uses its last iterate:
one plan improved across the re-plans, each re-plan as short as the motion it plans for. Such
plans do not fail when the plant is spent, so the first cycle the plant misses ends the
re-planning.

The plant's *repetitions* are its leading cycles whose task error (:func:`task_errors`) is at
most ``target_tolerance`` and whose every interval follows the exact flow (:meth:`Plant.flow_gap`
within the gap tolerances of :mod:`fatigue_pin.core.accuracy`, verify's): a cycle is credited only
where ``fatigue-pin verify`` accepts the plant's motion.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from fatigue_pin.core.accuracy import GAP_TOLERANCE, GAP_TOLERANCE_FATIGUE
from fatigue_pin.core.errors import ParameterError
from fatigue_pin.core.progress import Progress, as_reporter
from fatigue_pin.drivers.estimation import ESTIMATORS, History, MheSettings, make_estimator
from fatigue_pin.drivers.plant import Plant, PlantSettings
from fatigue_pin.drivers.sliding import SlidingSettings, iteration_limit
from fatigue_pin.ocp.guesses import shifted_plan_guess, shifted_window_guess
from fatigue_pin.ocp.problem import Problem
from fatigue_pin.ocp.solver import SolverOptions
from fatigue_pin.ocp.task import joint_target_pairs
from fatigue_pin.ocp.transcription import Ocp, Transcription
from fatigue_pin.ocp.window_budget import WindowBudget, require_window_budget, solve_within, window_budget

#: How far (rad) the plant's q may be outside the model's joint range before the run ends.
BOUND_TOLERANCE = 1e-6

#: IPOPT's status of a solve stopped at its iteration limit: a real-time re-plan's usual end.
BOUNDED_STATUS = "Maximum_Iterations_Exceeded"

#: How max_cycles ends a closed loop (:attr:`MpcSettings.end`).
MPC_ENDS = ("run-out", "receding")

#: Table of the re-plans of a closed-loop run.
REPLAN_DTYPE = np.dtype([
    ("index", "i4"), ("node", "i4"), ("phase", "i4"), ("status", "S40"), ("converged", "?"), ("iterations", "i4"),
    ("wall_time_s", "f8"), ("estimator_time_s", "f8"), ("objective", "f8"), ("real_time_factor", "f8"),
])


@dataclass(frozen=True)
class MpcSettings:
    """Settings of the closed loop (the window itself is :class:`SlidingSettings`).

    Attributes:
        replan_every: intervals between re-plans (>= 1, at most the window's K n); ``None``: the
            sliding horizon's advance, A n.
        estimator: ``open-loop`` or ``mhe`` (:mod:`fatigue_pin.drivers.estimation`).
        probe_every: cycles between capacity probes (>= 1).
        target_tolerance: a cycle is achieved when the plant meets every task target within
            this (rad for joint targets, the constraint's unit for frame targets).
        capacity_margin: the controller plans as if every half were this much more fatigued
            than estimated (mf + margin, and mr - margin where the model has mr): a back-off
            that keeps a plan within the plant's capacity despite estimation errors (0: none).
        end: how ``max_cycles`` ends the run: ``run-out`` (the sliding horizon's rule: no
            re-plan once the plans reach ``max_cycles``; the plant runs out the last plan, open
            loop) or ``receding`` (re-plan every ``replan_every`` intervals until the plant has
            done ``max_cycles`` cycles; the windows look past it).
        mhe: settings of the moving-horizon estimator.
        iterations_per_replan: real-time iterations: every re-plan after the first runs at
            most this many IPOPT iterations, warm-started from the plan in force shifted to the
            re-plan's node (:func:`~fatigue_pin.ocp.guesses.shifted_plan_guess`, its multipliers
            too), and its last iterate becomes the plan, converged or not; the plan improves
            over the re-plans instead of within one. The first plan is solved to convergence
            (before the motion starts). A re-plan that fails otherwise (an infeasibility,
            a failed restoration, a non-finite iterate) ends the re-planning, and so does a
            cycle whose task error exceeds ``target_tolerance``. ``None`` (default): every
            re-plan is solved to convergence (docs/mpc.md, "Real-time iterations").
    """

    replan_every: int | None = None
    estimator: str = "open-loop"
    probe_every: int = 1
    target_tolerance: float = 0.05
    capacity_margin: float = 0.0
    end: str = "run-out"
    mhe: MheSettings = field(default_factory=MheSettings)
    iterations_per_replan: int | None = None

    def __post_init__(self) -> None:
        r = self.replan_every
        if r is not None and (isinstance(r, bool) or not isinstance(r, (int, np.integer)) or r < 1):
            raise ParameterError(f"mpc.replan_every = {r!r}: expected an integer number of intervals >= 1")
        if self.estimator not in ESTIMATORS:
            raise ParameterError(f"mpc.estimator = {self.estimator!r}: expected one of {list(ESTIMATORS)}")
        p = self.probe_every
        if isinstance(p, bool) or not isinstance(p, (int, np.integer)) or p < 1:
            raise ParameterError(f"mpc.probe_every = {p!r}: expected an integer number of cycles >= 1")
        tol = self.target_tolerance
        if isinstance(tol, bool) or not isinstance(tol, (int, float)) or not math.isfinite(tol) or tol < 0:
            raise ParameterError(f"mpc.target_tolerance = {tol!r}: expected a tolerance >= 0")
        c = self.capacity_margin
        if isinstance(c, bool) or not isinstance(c, (int, float)) or not 0 <= c < 1:
            raise ParameterError(f"mpc.capacity_margin = {c!r}: expected a fraction of the capacity in [0, 1)")
        if self.end not in MPC_ENDS:
            raise ParameterError(f"mpc.end = {self.end!r}: expected one of {list(MPC_ENDS)}")
        if not isinstance(self.mhe, MheSettings):
            raise ParameterError(f"mpc.mhe = {self.mhe!r}: expected MheSettings")
        it = self.iterations_per_replan
        if it is not None and (isinstance(it, bool) or not isinstance(it, (int, np.integer)) or it < 1):
            raise ParameterError(f"mpc.iterations_per_replan = {it!r}: expected an integer number of IPOPT iterations >= 1 "
                                 "(or none: every re-plan solved to convergence)")


def _structure(problem: Problem) -> tuple:
    """What a plant must share with the model: joints, halves and their fatigue states."""
    return (problem.model.joint_names, problem.model.nq, problem.actuators.half_names,
            tuple(h.params.state_names for h in problem.actuators.halves))


def phase_shifted(problem: Problem, shift: int) -> Problem:
    """The problem whose horizon starts ``shift`` intervals into the cycle: every task item at a
    phase ``at`` moves to ``at - shift / n`` (mod 1), and the task's ``q_init`` (the start of a
    cycle) is dropped: a shifted window starts from the state it is given (``Task.given_start``)."""
    task = problem.task
    n = task.intervals_per_cycle
    shift %= n
    if shift == 0:
        return problem
    items = []
    for item in task.items:
        at = getattr(item, "at", None)
        if at is None:
            items.append(item)
        else:
            items.append(dataclasses.replace(item, at=((int(round(at * n)) - shift) % n) / n))
    # q_init is the start of the cycle, not of a shifted window (every window gets its measured
    # state as x_init): dropped, and no default posture (every joint at 0) is checked in its
    # place against the shifted phase-0 targets and the planes (Task.given_start)
    return dataclasses.replace(problem, task=dataclasses.replace(task, items=tuple(items), q_init=None, given_start=True))


def task_errors(problem: Problem, x: np.ndarray, n_cycles: int) -> np.ndarray:
    """Task error of every cycle of a trajectory x (nodes >= n_cycles n + 1, nx): the largest
    distance of a target item (joint targets, and task constraints at a phase) from its bounds at
    the cycle's nodes, the phase-0 targets at both ends of the cycle included. Shape (n_cycles,)."""
    task, model, L = problem.task, problem.model, problem.layout
    n = task.intervals_per_cycle
    N = n_cycles * n
    err = np.zeros(n_cycles)
    checks = [(node, x[node, j], lo, hi) for node, j, lo, hi in joint_target_pairs(task, model, N, L)]
    for sc in task.expression_constraints(model, L):
        if sc.at is None:
            continue
        for node in task.nodes(sc.at, N):
            value = np.asarray(sc.expression(x[node])).reshape(-1)
            checks += [(node, v, lo, hi) for v, lo, hi in zip(value, sc.lower, sc.upper)]
    for node, value, lo, hi in checks:
        e = max(0.0, lo - value, value - hi)
        for c in {node // n, node // n - 1 if node % n == 0 else node // n}:  # a cycle's end is the next one's start
            if 0 <= c < n_cycles:
                err[c] = max(err[c], e)
    return err


def repetitions_achieved(errors: np.ndarray, tolerance: float, follows_flow: np.ndarray | None = None) -> int:
    """Leading cycles whose task error (cycles,) is at most ``tolerance`` and, with
    ``follows_flow`` (cycles,) bool, whose motion follows the exact flow."""
    bad = np.asarray(errors) > tolerance
    if follows_flow is not None:
        bad = bad | ~np.asarray(follows_flow, dtype=bool)
    first = np.flatnonzero(bad)
    return int(first[0]) if first.size else int(bad.size)


def cycle_gaps(gaps: np.ndarray, n: int, n_cycles: int) -> np.ndarray:
    """The largest flow gap of every cycle, (n_cycles, 2) (q and qdot, fatigue states), from the
    gaps of every interval (intervals >= n_cycles n, 2)."""
    gaps = np.asarray(gaps, dtype=float).reshape(-1, 2)[: n_cycles * n]
    return gaps.reshape(n_cycles, n, 2).max(axis=1) if n_cycles else np.zeros((0, 2))


def follows_flow(gaps: np.ndarray) -> np.ndarray:
    """Whether each row (q and qdot gap, fatigue gap) is within verify's gap tolerances, bool."""
    gaps = np.asarray(gaps, dtype=float).reshape(-1, 2)
    return (gaps[:, 0] <= GAP_TOLERANCE) & (gaps[:, 1] <= GAP_TOLERANCE_FATIGUE)


@dataclass
class LoopState:
    """Everything a closed loop has done so far (what a resumed run restarts from).

    Attributes:
        x: plant states at every node reached, each (nx,).
        y: measured (q, qdot) at every node, each (nq + nv,).
        prediction: the controller's predicted state at every node: that of the plan whose
            control led there (at node 0 the measured state and the estimate).
        history: what the estimator knows (estimates, commanded and delivered torques, probes).
        replans: rows of :data:`REPLAN_DTYPE`.
        params: estimated fatigue parameters after every re-plan's correction, each (n_params,).
        plan: the last converged plan ``(x (H+1, nx), u (H, nu), start node)``, or None.
        done: the controller stopped re-planning (a window failed, or max_cycles was reached).
        solution: the NLP solution (primal and dual) of ``plan``, for warm starts
            (``horizon.warm_start``); not stored, so a resumed run's first re-plan starts cold.
    """

    x: list[np.ndarray]
    y: list[np.ndarray]
    prediction: list[np.ndarray]
    history: History
    replans: list[tuple] = field(default_factory=list)
    params: list[np.ndarray] = field(default_factory=list)
    plan: tuple[np.ndarray, np.ndarray, int] | None = None
    done: bool = False
    solution: Any = field(default=None, repr=False, compare=False)

    @property
    def node(self) -> int:
        return len(self.x) - 1

    @property
    def last_replan(self) -> int:
        return int(self.replans[-1][1]) if self.replans else -1


class ClosedLoop:
    """A closed-loop run of a problem against a plant.

    Args:
        problem: the controller's problem (its model).
        plant_problem: the plant's problem (true payload and fatigue parameters); default
            ``problem``. Its state layout must be the controller's.
        sliding: the window (K, end tolerance, max_cycles, iteration limits, guess_fatigue); required.
        mpc: re-planning, estimator and probes; plant: noise, disturbance, seed, integrator.
        transcription: as for :class:`SlidingHorizon`.
        solver: as for :class:`SlidingHorizon`.
        guess: as for :class:`SlidingHorizon`.
        progress: where building reports itself.
    """

    def __init__(self, problem: Problem, plant_problem: Problem | None = None, sliding: SlidingSettings | None = None,
                 mpc: MpcSettings | None = None, plant: PlantSettings | None = None,
                 transcription: Transcription | None = None, solver: SolverOptions | None = None, guess: str = "rest",
                 progress: Progress = None) -> None:
        self.problem = problem
        self.plant_problem = plant_problem or problem
        if not isinstance(sliding, SlidingSettings):
            raise ParameterError(f"ClosedLoop: sliding = {sliding!r}: expected SlidingSettings (the controller's window is "
                                 "required, e.g. SlidingSettings(window=3))")
        if sliding.heat_budget:
            require_window_budget(problem.actuators)
        self.sliding = sliding
        self.mpc = mpc or MpcSettings()
        self.plant_settings = plant or PlantSettings()
        self.transcription = transcription or Transcription()
        self.solver = solver or SolverOptions()
        self.guess = guess
        self.progress = progress
        task = problem.task
        if not task.cyclic:
            raise ParameterError("closed loop: the task is not cyclic (task.cyclic = false, or an item at \"end\"); the closed loop "
                                 "re-plans cyclic tasks only: expected a cyclic task (or horizon kind full / sliding)")
        self.n = task.intervals_per_cycle
        self.H = self.sliding.window * self.n
        self.replan_every = self.mpc.replan_every or self.sliding.advance * self.n
        if self.replan_every > self.H:
            raise ParameterError(f"mpc.replan_every = {self.replan_every}: expected at most the window, "
                                 f"{self.sliding.window} cycles x {self.n} = {self.H} intervals")
        if _structure(self.plant_problem) != _structure(problem):
            raise ParameterError("plant: its state layout (joints, actuator halves, fatigue states) differs from the "
                                 "model's; a plant may change parameter values and the payload, not the structure")
        if self.plant_problem.task.dt != task.dt:
            raise ParameterError(f"plant: interval {self.plant_problem.task.dt} s differs from the model's {task.dt} s")
        self._ocps: dict[int, Ocp] = {}
        #: flow gaps of the plant's intervals, per node: (x_k, x_k+1, delivered u_k, gaps)
        self._gaps: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray, tuple[float, float]]] = {}
        #: warm-start index maps per (previous phase, phase, intervals between)
        self._shifts: dict[tuple[int, int, int], tuple[np.ndarray, np.ndarray]] = {}
        self.ocp = self.window_ocp(0)
        self.plant = Plant(self.plant_problem, task.dt, self.plant_settings, self.transcription.substeps)

    def window_ocp(self, phase: int) -> Ocp:
        """The window OCP whose first node is at ``phase`` (intervals into the cycle), built once."""
        phase %= self.n
        if phase not in self._ocps:
            functions = self._ocps[0].functions if self._ocps else None
            # node 0 is the measured state even where the shifted task puts a target there (Ocp.state_bounds)
            self._ocps[phase] = Ocp(phase_shifted(self.problem, phase), self.sliding.window, self.transcription,
                                    self.solver, self.sliding.end_tolerance, self.guess, functions, self.progress,
                                    window_budget=self.sliding.heat_budget)
        return self._ocps[phase]

    def window_ocps(self) -> None:
        """Build the window OCP of every phase the re-plans start at (multiples of
        ``replan_every`` modulo n), as a controller does before the motion starts; in real time,
        also the warm-start maps from each to the next (0.3 s each on arm26)."""
        phases = sorted({(j * self.replan_every) % self.n for j in range(self.n)})
        for phase in phases:
            self.window_ocp(phase)
        if self.real_time:
            for phase in phases:
                self._shift_map(phase, phase + self.replan_every)

    def new_estimator(self):
        return make_estimator(self.mpc.estimator, self.ocp.functions, self.problem.actuators, self.mpc.mhe, self.n)

    def initial_state(self) -> LoopState:
        """The state before anything happened: the plant at the problem's initial state."""
        x0 = self.plant_problem.initial_state()
        L = self.problem.layout
        m0 = self.problem.initial_state()[L.m]  # the controller knows the plant starts rested
        y0 = np.concatenate(self.plant.measure(x0, 0))
        return LoopState([x0], [y0], [np.concatenate([y0, m0])], History([m0]))

    # -- one re-plan -----------------------------------------------------------------------------

    def planned_fatigue(self, m: np.ndarray) -> np.ndarray:
        """The fatigue states a window starts from: the estimate ``m`` (n_states,) with the
        capacity margin moved from mr to mf."""
        margin = self.mpc.capacity_margin
        if margin == 0:
            return m
        acts = self.problem.actuators
        out = m.copy()
        for h, rows in zip(acts.halves, zip(acts.fatigued_rows(), acts.state_rows("mr"))):
            fatigued, rest = rows
            shift = min(margin, 1.0 - out[fatigued]) if rest is None else min(margin, 1.0 - out[fatigued], out[rest])
            out[fatigued] += shift
            if rest is not None:
                out[rest] -= shift
        return out

    def end_reference(self, state: LoopState, x_init: np.ndarray) -> np.ndarray:
        """The reference of the window's end box (q, qdot at its last node within ``end_tolerance``
        of the reference's, :meth:`Ocp.state_bounds`), shape (nx,): the state the plan in force
        predicted for the current node (``state.prediction[-1]``), a state on the planned
        periodic motion at the window's phase (the window ends K whole cycles later, at the same
        phase); before the first plan, ``x_init``.

        Not the measured start: a plant off its plan (a heavier payload, noise) would have every
        window end as far off, and where the window's last node carries a target (a window
        starting at a target's phase) that end box and the target can exclude each other (the UR5
        study, docs/mpc.md). With the plant equal to the model and no noise the prediction is the
        start state, as in the sliding horizon."""
        if state.plan is None:
            return x_init
        return np.asarray(state.prediction[-1], dtype=float)

    @property
    def real_time(self) -> bool:
        """Whether the re-plans after the first are real-time iterations
        (:attr:`MpcSettings.iterations_per_replan`)."""
        return self.mpc.iterations_per_replan is not None

    def replan(self, state: LoopState, estimator) -> Any:
        """Correct the estimate at the current node and solve the window from it; update
        ``state`` (its table, parameters, plan and ``done``). Returns the solution (None when the
        window's bounds are empty, so no window can be posed: status ``Plant_Outside_Bounds``).
        A re-plan's time is the controller's: its guess, its warm start and its solve (and the
        estimator's, apart)."""
        k = state.node
        m = np.clip(estimator.correct(k, state.history), 0.0, 1.0)
        state.history.m[-1] = m
        est_time = getattr(estimator, "last_wall_time_s", 0.0)
        ocp = self.window_ocp(k)  # built once per phase, not a re-plan's time (:meth:`window_ocps`)
        t0 = time.perf_counter()
        x_init = np.concatenate([state.y[-1], self.planned_fatigue(m)])
        x_end = self.end_reference(state, x_init)
        lo, hi = ocp.state_bounds(x_init, x_end)
        if np.any(lo > hi):  # an end box outside the model's bounds: no window can be posed
            sol, status, success, iterations, objective = None, "Plant_Outside_Bounds", False, 0, math.nan
        else:
            sol = self._solve(state, estimator, ocp, x_init, x_end)
            status, success, iterations, objective = sol.status, sol.success, sol.iterations, sol.objective
        wall = time.perf_counter() - t0
        horizon_s = self.replan_every * self.problem.task.dt
        state.replans.append((len(state.replans), k, k % self.n, status.encode()[:40], success, iterations,
                              wall, est_time, objective, (wall + est_time) / horizon_s))
        state.params.append(np.asarray(estimator.params, dtype=float).copy())
        if success or (sol is not None and self._usable(state, sol)):
            state.plan = (sol.x, sol.u, k)
            state.solution = sol.nlp
        else:
            state.done = True
        max_cycles = self.sliding.max_cycles
        if max_cycles is not None and self.mpc.end == "run-out" and k + self.H >= max_cycles * self.n:
            state.done = True
        return sol

    def _solve(self, state: LoopState, estimator, ocp: Ocp, x_init: np.ndarray, x_end: np.ndarray) -> Any:
        """The window's solve from ``x_init``: to convergence from the previous plan shifted (the
        sliding horizon's guess), or, in real time after the first plan, at most
        ``iterations_per_replan`` IPOPT iterations from the plan in force shifted exactly, with
        its multipliers."""
        k = state.node
        if state.plan is None:
            guess = ocp.initial_guess(x_init)
        elif self.real_time:
            x_prev, u_prev, start = state.plan
            guess = shifted_plan_guess(ocp, x_init, x_prev, u_prev, k - start, fatigue=estimator.params)
            return ocp.solve(x_init=x_init, guess=guess, x_end=x_end, max_iter=self.mpc.iterations_per_replan,
                             fatigue=estimator.params, warm=self._warm_start(state, k), warm_start=True)
        else:
            x_prev, u_prev, start = state.plan
            guess = shifted_window_guess(ocp, x_init, x_prev, u_prev, 0, self.sliding.guess_fatigue == "copy",
                                         intervals=k - start, fatigue=estimator.params)
        limit = iteration_limit([int(r[5]) for r in state.replans if r[4]], self.sliding, self.solver.max_iter)
        warm = self._warm_start(state, k) if self.sliding.warm_start else None
        sol, _ = solve_within(ocp, self.window_budget(state, k), x_init=x_init, guess=guess, x_end=x_end, max_iter=limit,
                              fatigue=estimator.params, warm=warm, warm_start=warm is not None)
        return sol

    def _usable(self, state: LoopState, sol: Any) -> bool:
        """Whether a real-time re-plan that stopped at its iteration bound becomes the plan: its
        iterate is finite (a first plan, or one that failed otherwise, is not)."""
        return (self.real_time and state.plan is not None and sol.status == BOUNDED_STATUS
                and bool(np.all(np.isfinite(sol.x)) and np.all(np.isfinite(sol.u))))

    def window_budget(self, state: LoopState, node: int) -> WindowBudget | None:
        """Under ``heat_budget``, the budget of the window starting at ``node``
        (:func:`~fatigue_pin.ocp.window_budget.window_budget`), the cycles before it from the
        estimated states; None without it."""
        if not self.sliding.heat_budget:
            return None
        n, ns = self.n, self.problem.layout.n_fatigue
        past = np.array([state.history.m[j] if j >= 0 else np.zeros(ns) for j in range(node - n + 1, node)]).reshape(n - 1, ns)
        return window_budget(self.problem.actuators, n, self.problem.task.cycle_duration, node, self.H,
                             int(self.sliding.max_cycles) * n, past)

    def _warm_start(self, state: LoopState, node: int) -> Any:
        """The last converged plan's multipliers (and primal) moved to the window starting at
        ``node`` (:func:`fatigue_pin.ocp.warm.shift_maps_between`: the two windows' tasks are
        phase-shifted by the intervals between them), or None without one."""
        from fatigue_pin.ocp.warm import shifted_result

        if state.solution is None:
            return None
        return shifted_result(state.solution, self._shift_map(state.plan[2], node))

    def _shift_map(self, start: int, node: int) -> tuple[np.ndarray, np.ndarray]:
        """The warm-start index maps from the window starting at node ``start`` to the one at
        ``node`` (:func:`fatigue_pin.ocp.warm.shift_maps_between`), built once per key."""
        from fatigue_pin.ocp.warm import shift_maps_between

        key = (start % self.n, node % self.n, node - start)
        if key not in self._shifts:
            self._shifts[key] = shift_maps_between(self.window_ocp(start), self.window_ocp(node), node - start)
        return self._shifts[key]

    # -- the loop --------------------------------------------------------------------------------

    def advance(self, state: LoopState, estimator) -> bool:
        """Apply one interval of the plan in force; False when there is no plan left."""
        if state.plan is None:
            return False
        x_plan, u_plan, start = state.plan
        j = state.node - start
        if j >= u_plan.shape[0]:
            return False
        k = state.node
        x_next, u_del = self.plant.step(state.x[-1], u_plan[j], k)
        h = state.history
        h.u_command.append(u_plan[j].copy())
        h.u_delivered.append(u_del)
        h.m.append(np.clip(estimator.predict(h.m[-1], u_del), 0.0, 1.0))
        state.x.append(x_next)
        state.y.append(np.concatenate(self.plant.measure(x_next, k + 1)))
        state.prediction.append(x_plan[j + 1].copy())
        if (k + 1) % (self.mpc.probe_every * self.n) == 0:
            h.probes[k + 1] = self.plant.probe(x_next, k + 1)
        if not self.within_bounds(x_next):  # the plant hit a joint stop: the run ends
            state.plan, state.done = None, True
        elif self.real_time and (k + 1) % self.n == 0 and not state.done:
            # real-time plans do not fail when the plant is spent; its missed cycle ends the re-planning
            errors = task_errors(self.plant_problem, np.array(state.x), (k + 1) // self.n)
            state.done = bool(errors[-1] > self.mpc.target_tolerance)
        return True

    def within_bounds(self, x: np.ndarray) -> bool:
        """Whether the plant's q and qdot are finite and q is within the model's joint range
        (+- :data:`BOUND_TOLERANCE`). Velocities may overshoot their bound (an optimisation bound,
        not a joint stop); a window starting there is posed as long as its end box is not empty."""
        L, m = self.problem.layout, self.problem.model
        y = x[: L.nq + L.nv]
        q = y[: L.nq]
        return bool(np.all(np.isfinite(y)) and np.all(q >= m.q_lower - BOUND_TOLERANCE) and np.all(q <= m.q_upper + BOUND_TOLERANCE))

    def run(self, state: LoopState | None = None, checkpoint: Callable[[LoopState], None] | None = None,
            progress: Progress = None, stop_after: int | None = None) -> LoopState:
        """Run the loop until the plant has run out the last plan.

        Args:
            state: a state to continue (a resumed run); default :meth:`initial_state`.
            checkpoint: called with the state after every re-plan and at the end.
            progress: a Reporter or a line callback (one line per re-plan).
            stop_after: re-plan at most this many times in this call (then return).
        """
        rep = as_reporter(progress)
        state = state or self.initial_state()
        if self.real_time:
            self.window_ocps()
        estimator = self.new_estimator()
        if state.params:
            estimator.params = state.params[-1].copy()
        replanned = 0
        while True:
            k = state.node
            if self._plant_done(state):
                state.done = True
                break
            if not state.done and k % self.replan_every == 0 and k > state.last_replan:
                if stop_after is not None and replanned >= stop_after:
                    return state
                self.replan(state, estimator)
                replanned += 1
                row = state.replans[-1]
                said = "converged" if row[4] else "bounded" if state.plan is not None and state.plan[2] == k else row[3].decode()
                rep.line(f"re-plan {row[0]:3d} at node {k} (cycle {k / self.n:.2f}): "
                         f"{said:9s} {row[5]:4d} it {row[6]:6.2f} s"
                         f"  real-time factor {row[9]:.2f}")
                if checkpoint is not None:
                    checkpoint(state)
            if not self.advance(state, estimator):
                break
        if checkpoint is not None:
            checkpoint(state)
        return state

    # -- summaries -------------------------------------------------------------------------------

    def _plant_done(self, state: LoopState) -> bool:
        """With ``end = "receding"``: whether the plant has done ``max_cycles`` cycles."""
        max_cycles = self.sliding.max_cycles
        return self.mpc.end == "receding" and max_cycles is not None and state.node >= max_cycles * self.n

    def finished(self, state: LoopState) -> bool:
        """Whether the run is over: no more re-plans and no plan left to run out."""
        if self._plant_done(state):
            return True
        if not state.done:
            return False
        return state.plan is None or state.node - state.plan[2] >= state.plan[1].shape[0]

    def cycles(self, state: LoopState) -> int:
        """Whole cycles the plant has completed."""
        return state.node // self.n

    def task_errors(self, state: LoopState) -> np.ndarray:
        """Task error of every completed cycle of the plant (:func:`task_errors`)."""
        return task_errors(self.plant_problem, np.array(state.x), self.cycles(state))

    def flow_gaps(self, state: LoopState) -> np.ndarray:
        """The flow gap (:meth:`Plant.flow_gap`) of every interval the plant did, (intervals, 2):
        q and qdot (rad, rad/s), fatigue states. Each interval is re-integrated once (the gaps
        are kept while its nodes and torques stay those of ``state``)."""
        x, u = state.x, state.history.u_delivered
        out = np.zeros((len(x) - 1, 2))
        for k in range(len(x) - 1):
            kept = self._gaps.get(k)
            if kept is None or not (np.array_equal(kept[0], x[k]) and np.array_equal(kept[1], x[k + 1])
                                    and np.array_equal(kept[2], u[k])):
                kept = (np.array(x[k]), np.array(x[k + 1]), np.array(u[k]), self.plant.flow_gap(x[k], u[k], k, x[k + 1]))
                self._gaps[k] = kept
            out[k] = kept[3]
        return out

    def cycle_gaps(self, state: LoopState) -> np.ndarray:
        """The largest flow gap of every completed cycle, (cycles, 2) (:func:`cycle_gaps`)."""
        return cycle_gaps(self.flow_gaps(state), self.n, self.cycles(state))

    def repetitions(self, state: LoopState) -> int:
        """Cycles the plant achieved: leading cycles within ``target_tolerance`` whose motion
        follows the exact flow (:func:`follows_flow` of :meth:`cycle_gaps`)."""
        return repetitions_achieved(self.task_errors(state), self.mpc.target_tolerance, follows_flow(self.cycle_gaps(state)))
