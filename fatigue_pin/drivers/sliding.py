"""Sliding-horizon (cyclic NMPC) solves: a window of K cycles advancing A cycles at a time.

Paper section 3 (docs/ocp.md). One :class:`~fatigue_pin.ocp.transcription.Ocp` of K cycles is built
(and compiled) once; every window re-solves it with new parameters:

* its initial state is the previous window's state at node A * n (n intervals per cycle);
* its final q and qdot are bounded to that initial state +- ``end_tolerance`` (1 %) of their range;
* its initial guess is the previous window's cycle after the advance point (cycle A) copied into
  every cycle, the fatigue states integrated forward from the copied controls so they are
  continuous.

The first A cycles of every converged window are kept; the last converged window keeps all K.
The run stops at the first window that fails, or once ``max_cycles`` cycles are kept.
Repetitions = A * (converged windows - 1) + K.

After every window the stitched trajectory (kept cycles followed by the whole last converged
window) and the window table are written to the HDF5 file, atomically; ``resume=True`` reads
them back and continues with the next window, ending with the same result as an uninterrupted
run (the guess of a window only depends on the previous window's stored solution).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, replace
from typing import Any, Sequence

import numpy as np

from fatigue_pin.core.errors import ParameterError, ResultFileError
from fatigue_pin.core.settings import check_fields, is_bool, is_int, is_number, setting
from fatigue_pin.core.progress import Progress, as_reporter
from fatigue_pin.core.signals import Interrupted, deferred, signal_name
from fatigue_pin.core.text import shown
from fatigue_pin.drivers.full import OcpBuilder
from fatigue_pin.drivers.run import WINDOW_DTYPE, RunResult, RunStore, failed_window_name, in_progress_name, run_attributes, to_run_result
from fatigue_pin.ocp.guesses import shifted_window_guess
from fatigue_pin.ocp.problem import Problem
from fatigue_pin.ocp.solver import SolverOptions
from fatigue_pin.ocp.task import Task
from fatigue_pin.ocp.transcription import OcpSolution, Transcription
from fatigue_pin.ocp import window_budget as budgets
from fatigue_pin.ocp.window_budget import WindowBudget


@dataclass(frozen=True)
class SlidingSettings:
    """Settings of a sliding-horizon run.

    Attributes:
        window: cycles per window (K), required: a sliding horizon has no natural window length
            (the paper's is 3, given by its studies and :data:`fatigue_pin.paper.curl.WINDOW`).
        advance: cycles the window advances (A); 1 <= A <= K; default 1, the finest step.
        max_cycles: stop once this many cycles are kept (``None``: until a window fails); at least K.
        end_tolerance: end bounds of q and qdot, fraction of their range in [0, 1) (paper: 0.01).
        failure_iterations: IPOPT iteration limit of a window after the first ``warmup`` windows,
            as a multiple of the median iterations of the converged windows so far (a failing
            window is then recognised within about this factor of a normal window's cost).
            ``None`` keeps the solver's ``max_iter`` for every window (the paper's 3000).
        min_iterations: the iteration limit is never below this.
        warmup: windows solved with the solver's own ``max_iter`` before the limit applies.
        guess_fatigue: how a window's guess gets its fatigue states: ``integrate`` (from the
            window's initial state under the copied controls, so the guess has no fatigue gaps) or
            ``copy`` (copied with the rest of the previous window's second cycle, as the authors'
            code does: the guess jumps back at every cycle boundary).
        warm_start: start every window after the first from the previous converged window's
            primal and dual solution shifted by A cycles (:mod:`fatigue_pin.ocp.warm`), with
            IPOPT's ``warm_start_init_point``, instead of the guess above. A resumed run starts
            its first window cold.
        heat_budget: every window leaves the task's remaining cycles their heat (motors;
            :meth:`~fatigue_pin.ocp.actuation_layer.ActuationLayer.window_budget`): the cycle ending
            at each of its nodes, repeated until ``max_cycles`` (needed), keeps each winding below
            its limit. A window that fails within its budget is solved again without it.
        exact_finish: under an approximate Hessian (``solver.hessian`` not ``exact``), a window
            whose solve stops at its iteration limit without a verdict of infeasibility, or
            whose line search stalls at a feasible point
            (:func:`~fatigue_pin.ocp.solver.failure_kind` ``not-converged``) is solved again
            with the exact Hessian from its last iterate (primal and dual, IPOPT's warm start),
            within ``exact_finish_iterations``; the run ends only where that fails too.
            Gauss-Newton's linear convergence can stall near a window's optimum: the muscle
            exhaustion study's last window does (docs/muscles.md, "To exhaustion"). The exact
            Hessian's library is compiled on the first stall. No effect under ``exact``.
        exact_finish_iterations: IPOPT iteration limit of an exact finish.
    """

    window: int = setting(expected="an integer number of cycles >= 1", check=lambda v: is_int(v) and v >= 1)
    advance: int = setting(1, "an integer number of cycles >= 1", lambda v: is_int(v) and v >= 1)
    max_cycles: int | None = setting(None, "an integer number of cycles >= 1", lambda v: is_int(v) and v >= 1)
    end_tolerance: float = setting(0.01, "a fraction in [0, 1) of the joint ranges", lambda v: is_number(v) and 0 <= v < 1)
    failure_iterations: float | None = setting(10.0, "a multiple of the median window iterations >= 1",
                                               lambda v: is_number(v) and v >= 1)
    min_iterations: int = setting(200, "an integer >= 0", lambda v: is_int(v) and v >= 0)
    warmup: int = setting(3, "an integer >= 0", lambda v: is_int(v) and v >= 0)
    guess_fatigue: str = setting("integrate", "'integrate' or 'copy'", lambda v: v in ("integrate", "copy"))
    warm_start: bool = setting(False, "true or false", is_bool)
    heat_budget: bool = setting(False, "true or false", is_bool)
    exact_finish: bool = setting(False, "true or false", is_bool)
    exact_finish_iterations: int = setting(150, "an integer >= 1", lambda v: is_int(v) and v >= 1)

    def __post_init__(self) -> None:
        check_fields(self)
        if self.heat_budget and self.max_cycles is None:
            raise ParameterError("SlidingSettings.heat_budget = true: expected max_cycles too (the budget spreads the heat "
                                 "over the task's cycles)")
        if self.advance > self.window:
            raise ParameterError(f"SlidingSettings.advance = {shown(self.advance)}: expected an integer in [1, window = {self.window}]")
        if self.max_cycles is not None and self.max_cycles < self.window:
            raise ParameterError(f"SlidingSettings.max_cycles = {shown(self.max_cycles)}: expected at least the window, window = {self.window}")


@dataclass
class _State:
    """What the next window needs: the stitched run so far and the last converged window."""

    x: np.ndarray          # stitched states (nodes, nx), ends with the whole last converged window
    u: np.ndarray          # stitched controls (intervals, nu)
    costs: np.ndarray      # (cycles, terms)
    cycle_wall: np.ndarray  # (cycles,)
    windows: list[tuple]   # rows of WINDOW_DTYPE
    done: bool             # a window failed or max_cycles reached

    @property
    def n_cycles(self) -> int:
        return self.costs.shape[0]


def repetitions(converged_windows: int, settings: SlidingSettings) -> int:
    """Cycles achieved by a run whose first ``converged_windows`` windows converged."""
    if converged_windows <= 0:
        return 0
    return settings.advance * (converged_windows - 1) + settings.window


def real_time_factors(windows: np.ndarray, advanced_s: float) -> np.ndarray:
    """Seconds of solving per second of motion advanced, of every window of a window table
    (:data:`WINDOW_DTYPE`): its wall time over the ``advanced_s`` seconds (A cycles) it keeps.
    Below 1: the windows are planned faster than the robot moves."""
    return np.asarray(windows["wall_time_s"], dtype=float) / advanced_s


def median_real_time_factor(windows: np.ndarray, advanced_s: float) -> float:
    """Median :func:`real_time_factors` of the converged windows (NaN when none converged)."""
    ok = np.asarray(windows["converged"], dtype=bool) if len(windows) else np.zeros(0, dtype=bool)
    return float(np.median(real_time_factors(windows, advanced_s)[ok])) if ok.any() else float("nan")


def ending(run: RunResult) -> str:
    """Why a sliding-horizon run (a :class:`RunResult` of :meth:`SlidingHorizon.run`) ended, in
    words for beside its repetition count: the arm could no longer do the next K cycles (the
    window that failed, which cycles it planned, and how the solver ended), the ``max_cycles``
    cap, an interruption, or a run not finished yet."""
    a, windows = run.attrs, run.windows
    solved = 0 if windows is None else len(windows)
    if a.get("interrupted"):
        return f"interrupted ({a['interrupted']}) after {solved} windows; --resume continues"
    if not a.get("finished", False):
        return f"not finished: {solved} windows solved so far; --resume continues"
    if solved and not bool(windows["converged"][-1]):
        last = windows[-1]
        index, first, K = int(last["index"]), int(last["first_cycle"]), int(a["window"])
        status, iterations = last["status"].decode(), int(last["iterations"])
        how = (f"its limit of {iterations} iterations" if status.startswith("Maximum_Iterations")
               else f"{status} after {iterations} iterations")
        if first == 0:
            return f"the arm could not do the first {K} cycles (the solver found no motion: {how})"
        return (f"then the arm was too tired to go on: the solver found no motion for the next {K} cycles ({first + 1}-{first + K}) "
                f"from the end of cycle {first} (window {index}: {how})")
    cap = a.get("max_cycles", -1)
    if cap is not None and int(cap) > 0 and run.n_cycles >= int(cap):
        return f"stopped at the cap of {int(cap)} cycles (horizon.max_cycles), not by fatigue"
    return "finished"


def stitched_nodes(task: Task, at: float | None, window: int, advance: int, first_cycles: Sequence[int]) -> list[int]:
    """Nodes of a stitched run where the windows put the task's phase ``at`` (every node for
    ``None``), in order.

    Each converged window (its first cycle in ``first_cycles``, in order) contributes its own
    nodes of the phase (:meth:`Task.nodes` over its K cycles) shifted to its first cycle, within
    the part of it the run keeps: its first A cycles up to the join (the next window's node 0,
    which is this node), all K for the last window. A window's node 0 is its start state, not
    one of its target nodes (:meth:`Ocp.state_bounds`), except the run's first node. With
    ``advance < window`` these are ``Task.nodes`` over the stitched run; with ``advance ==
    window`` and ``final_node_offset = -1`` the phase-0 targets sit one node before each join.
    """
    n = task.intervals_per_cycle
    nodes: set[int] = set()
    for w, first in enumerate(first_cycles):
        kept = (window if w == len(first_cycles) - 1 else advance) * n
        nodes.update(first * n + k for k in task.nodes(at, window * n) if k <= kept and (k > 0 or w == 0))
    return sorted(nodes)


def iteration_limit(converged_iterations: list[int], settings: SlidingSettings, max_iter: int) -> int | None:
    """IPOPT iteration limit of the next window: ``failure_iterations`` times the median
    iterations of the first ``warmup`` converged windows (``converged_iterations``, in order;
    fixed once known, so a resumed run uses the same limit), at least ``min_iterations``, at most
    ``max_iter``; ``None`` before ``warmup`` windows converged."""
    iters = converged_iterations[: settings.warmup]
    if settings.failure_iterations is None or len(iters) < settings.warmup:
        return None
    return int(min(max_iter, max(settings.min_iterations, settings.failure_iterations * float(np.median(iters)))))


class SlidingHorizon:
    """A sliding-horizon run of a problem.

    Args:
        problem: the problem (its initial state starts the first window).
        sliding: window settings (required: the window has no default).
        transcription: discretisation settings.
        solver: IPOPT settings.
        guess: initial guess of the first window (``rest`` or ``physical``).
        study: the TOML text of the study, stored with the run.
        labels: attributes stored with the run (e.g. the paper's cost, S and preset).
        progress: where building (a compile) reports itself; default quiet.
    """

    def __init__(self, problem: Problem, sliding: SlidingSettings, transcription: Transcription | None = None,
                 solver: SolverOptions | None = None, guess: str = "rest", study: str = "",
                 labels: dict[str, Any] | None = None, progress: Progress = None) -> None:
        if not isinstance(sliding, SlidingSettings):
            raise ParameterError(f"SlidingHorizon: sliding = {shown(sliding)}: expected SlidingSettings (the window is required, "
                                 "e.g. SlidingSettings(window=3))")
        self.sliding = sliding
        self.problem = problem
        self.solver = solver or SolverOptions()
        # a cyclic task's windows end in a box around their start state; a non-cyclic task's windows end
        # at the targets of their phases' ends (no box)
        if self.sliding.heat_budget:
            budgets.require_window_budget(problem.actuators)
        end_box = self.sliding.end_tolerance if problem.task.cyclic else None
        self.ocp = OcpBuilder(problem, transcription, self.solver, guess, progress)(self.sliding.window, end_box,
                                                                                    window_budget=self.sliding.heat_budget)
        self._end_box = end_box
        #: the exact Hessian's builder of :meth:`_finish` (SlidingSettings.exact_finish), or None;
        #: its window OCP is built on the first stalled window
        exact = replace(self.solver, hessian="exact")
        self._exact = OcpBuilder(problem, transcription, exact, guess, progress) if self._finishes else None
        self._exact_ocp: Any = None
        self.model = problem.model
        self.study = study
        self.labels = dict(labels or {})

    def fingerprint(self) -> str:
        """What a resumed run must share with the stored one: weights, fatigue parameters, task,
        window settings (not ``max_cycles``, unless a heat budget spreads over it), transcription
        and the initial state."""
        s = self.sliding
        data = {
            "weights": dict(zip(self.ocp.cost_terms, self.problem.weights.tolist())),
            "fatigue": {h.name: [h.params.kind, *h.params.as_vector().tolist()] for h in self.problem.actuators.halves},
            "task": repr(self.problem.task),
            "window": [s.window, s.advance, s.end_tolerance, s.failure_iterations, s.min_iterations, s.warmup, s.guess_fatigue,
                       *(["heat_budget", s.max_cycles] if s.heat_budget else []),  # its budget depends on max_cycles
                       *(["exact_finish", s.exact_finish_iterations] if self._finishes else [])],
            "transcription": repr(self.ocp.transcription),
            "x_init": self.problem.initial_state().tolist(),
            "model": [self.model.name, repr(self.model.payload)],
        }
        return json.dumps(data, sort_keys=True)

    # -- window mechanics ------------------------------------------------------------------------

    @property
    def _n(self) -> int:
        return self.ocp.task.intervals_per_cycle

    @property
    def _advanced_s(self) -> float:
        """Seconds of motion a window advances (A cycles)."""
        return self.sliding.advance * self.ocp.task.cycle_duration

    def window_guess(self, x_init: np.ndarray, x_prev: np.ndarray, u_prev: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Guess of a window from the previous window's states (K n + 1, nx) and controls (K n, nu)
        (:func:`fatigue_pin.ocp.guesses.shifted_window_guess`)."""
        return shifted_window_guess(self.ocp, x_init, x_prev, u_prev, self.sliding.advance,
                                    copy_fatigue=self.sliding.guess_fatigue == "copy")

    def _warm_start(self, previous: Any) -> Any:
        """The previous window's NLP result shifted by A cycles (:mod:`fatigue_pin.ocp.warm`)."""
        from fatigue_pin.ocp.warm import shift_maps, shifted_result

        if getattr(self, "_shift", None) is None:
            self._shift = shift_maps(self.ocp, self.sliding.advance)
        return shifted_result(previous, self._shift)

    def window_budget(self, first_cycle: int, state: _State | None) -> WindowBudget | None:
        """Under ``heat_budget``, the budget of the window starting at cycle ``first_cycle``: the
        layer's rows of the cycle ending at each of its nodes ``1..K n``, for the whole cycles
        from that node to the end of cycle ``max_cycles``, with the kept states of the cycle before
        the window (``state``'s stitched run; none before the first window). None without it."""
        if not self.sliding.heat_budget:
            return None
        n, K, L = self._n, self.sliding.window, self.ocp.layout
        start = first_cycle * n
        past = np.zeros((n - 1, L.n_fatigue))
        if state is not None and start >= n:
            past = state.x[start - n + 1: start, L.m]
        return budgets.window_budget(self.problem.actuators, n, self.ocp.task.cycle_duration, start, K * n,
                                     int(self.sliding.max_cycles) * n, past)

    @property
    def _finishes(self) -> bool:
        """Whether stalled windows get an exact finish (:attr:`SlidingSettings.exact_finish`)."""
        return self.sliding.exact_finish and self.solver.hessian != "exact"

    def _finish(self, sol: OcpSolution, budget: WindowBudget | None, x_init: np.ndarray) -> tuple[OcpSolution, int]:
        """A stalled window (``not-converged``) from ``x_init`` solved again with the exact
        Hessian from its last iterate, when :attr:`_finishes`; its iterations and time count both
        solves. Returns the solution and the exact finish's iterations (0: none)."""
        if self._exact is None or sol.success or sol.nlp.kind != "not-converged":
            return sol, 0
        if self._exact_ocp is None:
            self._exact_ocp = self._exact(self.sliding.window, self._end_box, window_budget=self.sliding.heat_budget)
        again = self._exact_ocp.solve(x_init=x_init, guess=(sol.x, sol.u), x_end=x_init, warm=sol.nlp,
                                      warm_start=True, max_iter=self.sliding.exact_finish_iterations, budget=budget)
        return replace(again, iterations=sol.iterations + again.iterations, wall_time_s=sol.wall_time_s + again.wall_time_s), \
            again.iterations

    def _iteration_limit(self, state: _State) -> int | None:
        return iteration_limit([row[4] for row in state.windows if row[3]], self.sliding, self.solver.max_iter)

    def _failed_window(self, sol: Any, first_cycle: int, name: str) -> RunResult:
        """The last iterate of a failed window as a run (times from the window's first cycle)."""
        ocp = self.ocp
        attrs = run_attributes(ocp, "sliding-failed-window", self.labels)
        attrs.update(n_cycles=self.sliding.window, first_cycle=first_cycle, converged=False, status=sol.status,
                     kind=sol.kind, iterations=sol.iterations, wall_time_s=sol.wall_time_s)
        t = first_cycle * ocp.task.cycle_duration + np.arange(sol.x.shape[0]) * ocp.task.dt
        return to_run_result(ocp, t, sol.x, sol.u, sol.cycle_costs, name, attrs, np.zeros(self.sliding.window), study=self.study)

    def _run_result(self, state: _State, name: str, build_time: float, interrupted: str = "") -> RunResult:
        """The run of ``state``; ``interrupted`` (a signal's name): stored as interrupted, neither
        finished nor converged."""
        ocp = self.ocp
        attrs = run_attributes(ocp, "sliding", self.labels)
        attrs["fingerprint"] = self.fingerprint()
        table = np.array(state.windows, dtype=WINDOW_DTYPE)
        converged = int(table["converged"].sum()) if table.size else 0
        attrs.update(
            n_cycles=state.n_cycles,
            window=self.sliding.window,
            advance=self.sliding.advance,
            max_cycles=-1 if self.sliding.max_cycles is None else self.sliding.max_cycles,
            repetitions=state.n_cycles,
            converged=converged > 0,
            finished=state.done,
            status=str(table["status"][-1].decode()) if table.size else "not started",
            wall_time_s=float(table["wall_time_s"].sum()) if table.size else 0.0,
            build_time_s=build_time,
            # with the exact finish's library, when a stall had it compiled
            compile_time_s=ocp.compile_time_s + (self._exact_ocp.compile_time_s if self._exact_ocp is not None else 0.0),
            iterations=int(table["iterations"].sum()) if table.size else 0,
            converged_windows=converged,
            median_real_time_factor=median_real_time_factor(table, self._advanced_s),
        )
        if interrupted:
            attrs.update(interrupted=interrupted, finished=False, converged=False)
        t = np.arange(state.x.shape[0]) * ocp.task.dt
        return to_run_result(ocp, t, state.x, state.u, state.costs, name, attrs, state.cycle_wall, table, study=self.study)

    def _restore(self, store: RunStore, name: str) -> _State | None:
        if name not in store.runs():
            return None
        run = store.read(name)
        if run.windows is None:
            raise ResultFileError(f"run {name!r} in {store!r} has no window table; it is not a sliding-horizon run")
        if run.attrs.get("fingerprint") != self.fingerprint():
            stored = json.loads(run.attrs.get("fingerprint") or "{}")
            mine = json.loads(self.fingerprint())
            key = next((k for k in mine if stored.get(k) != mine[k]), "settings")
            raise ResultFileError(f"cannot resume run {name!r} in {store!r}: its {key} differ from this run's "
                                  f"({stored.get(key)!r} stored, {mine.get(key)!r} now)")
        x = self.ocp.layout.assemble(run.q, run.qdot, run.fatigue)
        u = self.ocp.actuators.controls(run.half_torques())
        windows = [tuple(row) for row in run.windows.tolist()]
        return _State(x, u, run.cycle_costs, run.cycle_wall_time_s, windows, bool(run.attrs.get("finished", False)))

    # -- the run ---------------------------------------------------------------------------------

    def _next_window(self, state: _State | None) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray], int]:
        """Initial state, guess and first cycle of the next window."""
        ocp, n, A, K = self.ocp, self._n, self.sliding.advance, self.sliding.window
        if state is None:
            x_init = ocp.initial_state()
            return x_init, ocp.initial_guess(x_init), 0
        x_prev, u_prev = state.x[-(K * n + 1):], state.u[-(K * n):]
        x_init = x_prev[A * n].copy()
        return x_init, self.window_guess(x_init, x_prev, u_prev), state.n_cycles - K + A

    def _advance(self, state: _State | None, sol: OcpSolution, row: tuple) -> _State:
        """The run after a window: a converged window keeps its first A cycles (replacing the
        previous window's unkept tail); a failed one ends the run."""
        n, A, K, L = self._n, self.sliding.advance, self.sliding.window, self.ocp.layout
        wall = np.zeros(K)  # a window's solve time goes to the A cycles it keeps
        wall[:A] = sol.wall_time_s / A
        if state is None:
            if sol.success:
                return _State(sol.x, sol.u, sol.cycle_costs, wall, [row], False)
            return _State(np.zeros((0, L.nx)), np.zeros((0, L.nu)), np.zeros((0, sol.cycle_costs.shape[1])), np.zeros(0), [row], True)
        state.windows.append(row)
        if not sol.success:
            state.done = True
            return state
        keep_nodes = state.x.shape[0] - (K - A) * n
        keep_int, keep_cyc = state.u.shape[0] - (K - A) * n, state.n_cycles - (K - A)
        state.x = np.vstack([state.x[: keep_nodes - 1], sol.x])
        state.u = np.vstack([state.u[:keep_int], sol.u])
        state.costs = np.vstack([state.costs[:keep_cyc], sol.cycle_costs])
        state.cycle_wall = np.concatenate([state.cycle_wall[:keep_cyc], wall])
        return state

    def run(
        self,
        store: RunStore | None = None,
        name: str | None = None,
        resume: bool = False,
        progress: Progress = None,
        stop_after: int | None = None,
    ) -> RunResult:
        """Solve windows until one fails or ``max_cycles`` cycles are kept.

        Args:
            store: where the run is written after every window (e.g.
                :class:`fatigue_pin.io.results.ResultFile`; ``None``: memory only).
            name: run name (default ``sliding/run``).
            resume: continue the run kept under ``name`` in ``store``.
            progress: a :class:`~fatigue_pin.core.progress.Reporter` (one line per window and a bar over
                the cycles kept), or a callable receiving the lines; default quiet.
            stop_after: solve at most this many windows in this call (for tests and batching).

        Returns:
            The stitched :class:`RunResult` (also in ``store``).
        """
        name = name or "sliding/run"
        ocp, n, A = self.ocp, self._n, self.sliding.advance
        work = self._working_name(store, name, resume)
        state = self._restore(store, work) if (resume and store is not None) else None
        rep = as_reporter(progress)
        if resume and state is not None:
            rep.line(f"resuming {work!r}: {len(state.windows)} windows done, {state.n_cycles} cycles")
        fatigued_rows = ocp.layout.fatigued_rows()
        bar = rep.bar(self.sliding.max_cycles, "cycles kept", "cycle")
        bar.update(state.n_cycles if state is not None else 0)
        solved = 0
        last = None  # the NLP result of the last window, if it converged (warm starts)
        try:
            while (state is None or not state.done) and (stop_after is None or solved < stop_after):
                x_init, guess, first_cycle = self._next_window(state)
                limit = self._iteration_limit(state) if state is not None else None
                warm = self._warm_start(last) if (self.sliding.warm_start and last is not None) else None
                if warm is not None:
                    guess = ocp.unflatten(warm.x)
                budget = self.window_budget(first_cycle, state)
                sol, within = budgets.solve_within(ocp, budget, x_init=x_init, guess=guess, x_end=x_init, max_iter=limit, warm=warm,
                                                   warm_start=warm is not None)
                sol, finished = self._finish(sol, budget if within else None, x_init)
                last = sol.nlp if sol.success else None
                solved += 1
                index = len(state.windows) if state is not None else 0
                row = (index, first_cycle, sol.status.encode()[:40], sol.success, sol.iterations, sol.wall_time_s, sol.objective)
                mf_end = sol.x[A * n, fatigued_rows]
                before = state.n_cycles if state is not None else 0
                with deferred():  # the window is kept and stored whole, or not at all
                    state = self._advance(state, sol, row)
                    if self.sliding.max_cycles is not None and state.n_cycles >= self.sliding.max_cycles:
                        state.done = True
                    if store is not None and not sol.success:  # IPOPT's last iterate of the failed window, to inspect
                        store.write(self._failed_window(sol, first_cycle, failed_window_name(name)))
                    if store is not None:
                        store.write(self._run_result(state, work, ocp.build_time_s))
                rep.line(self._window_line(index, first_cycle, sol, limit, mf_end.max(), budget, within, finished))
                bar.update(state.n_cycles - before, window=index, max_mf=f"{mf_end.max():.3f}", s_per_window=f"{sol.wall_time_s:.2f}")
            bar.close()
            if state is None:
                raise RuntimeError("no window was solved")
            self._complete(store, state, work, name)
        except Interrupted as exc:  # the windows kept so far stay, marked interrupted; --resume continues
            if store is not None and state is not None and not state.done:
                with deferred():
                    store.write(self._run_result(state, work, ocp.build_time_s, interrupted=signal_name(exc)))
            else:  # every window is done: complete it (unless the signal came once it was)
                self._complete(store, state, work, name)
            raise
        result = self._run_result(state, name if state.done else work, ocp.build_time_s)
        rep.line(f"median real-time factor {result.attrs['median_real_time_factor']:.2f} "
                 f"(s of solving per s of motion advanced, {result.attrs['converged_windows']} converged windows)")
        return result

    def _complete(self, store: RunStore | None, state: _State | None, work: str, name: str) -> None:
        """A finished run kept under a working name (:meth:`_working_name`) replaces the run it is
        to replace: it is written under ``name`` and the run in progress deleted, both or neither
        (a signal waits). Nothing to do for a run not finished, kept under its own name, or
        already completed (the signal came after this step)."""
        if store is None or state is None or not state.done or work == name:
            return
        with deferred():
            if work in store.runs():
                store.write(self._run_result(state, name, self.ocp.build_time_s))
                store.delete(work)

    def _window_line(self, index: int, first_cycle: int, sol: OcpSolution, limit: int | None, max_mf: float,
                     budget: WindowBudget | None = None, within: bool = False, finished: int = 0) -> str:
        """The progress line of a solved window; with a budget, its largest row (1: the limit
        at the task's end) and whether the window kept it; for a failed window, why
        (:func:`~fatigue_pin.ocp.solver.failure_kind`) and its last iterate's constraint violation:
        ``not-converged`` at a small one is a motion the solver did not show optimal, not an arm
        that can do no more (docs/muscles.md, "To exhaustion"); ``finished``: the iterations of
        an exact finish (:attr:`SlidingSettings.exact_finish`) among the window's."""
        K, L = self.sliding.window, self.ocp.layout
        note = f"  (exact finish: {finished} of these it)" if finished else ""
        if not sol.success and sol.nlp.kind:
            note += f"  ({sol.nlp.kind}: constraint violation {sol.nlp.constraint_violation:.1e} at the last iterate)"
        if budget is not None:
            before = np.vstack([budget.past, sol.x[:, L.m]])  # the node n before each node 1..K n
            rows = [E_last @ sol.x[i, L.m] + E_before @ before[i - 1] for i, (E_last, E_before) in enumerate(budget.rows, 1)]
            note += f"  budget {np.max(rows):.3f}" + ("" if within else " (failed within it: solved without)")
        return (f"window {index:3d} (cycles {first_cycle + 1}-{first_cycle + K}): "
                f"{'converged' if sol.success else 'FAILED   '} {sol.iterations:4d} it {sol.wall_time_s:6.2f} s"
                f" (real-time factor {sol.wall_time_s / self._advanced_s:.2f})"
                f"{'' if limit is None else f' (limit {limit} it)'}  max {self._fatigued_word} {max_mf:.3f}{note}")

    @property
    def _fatigued_word(self) -> str:
        """The units' fatigued state as the progress lines name it: ``mf``, or ``xw`` for motors."""
        names = {u.params.fatigued_state for u in self.ocp.actuators.halves}
        return names.pop() if len(names) == 1 else "fatigued state"

    @staticmethod
    def _working_name(store: RunStore | None, name: str, resume: bool) -> str:
        """Where the windows are kept as they come: ``name``, or, while ``store`` holds a run of
        that name that this run is to replace (not resume), :func:`in_progress_name` of it, so
        that the old run is replaced only by a complete one. A resume continues the run in
        progress if there is one."""
        if store is None:
            return name
        runs = store.runs()
        partial = in_progress_name(name)
        if resume:
            return partial if partial in runs else name
        return partial if name in runs else name
