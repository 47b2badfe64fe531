"""Full-horizon solves: one OCP over the whole task, and the search for the maximum repetitions.

The paper raised the number of cycles N one at a time until IPOPT failed. :func:`max_repetitions`
gallops instead (N = 1, 2, 4, ... until a failure), then bisects between the largest success and
the smallest failure, each solve warm-started from the nearest converged solution with fewer
cycles, stretched in time (:func:`resample_guess`). Every N tried is reported and, with ``out``,
stored as it finishes, so a killed search resumes (``resume=True``) to the same result. Like the
paper's search it assumes that convergence is monotone in N.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from fatigue_pin.ocp.problem import Problem, StateLayout
from fatigue_pin.io.results import RunResult, list_runs, read_run, read_search, torque_limits_at_cycle_ends, write_run, write_search
from fatigue_pin.ocp.solver import SolverOptions
from fatigue_pin.ocp.task import check_horizon
from fatigue_pin.ocp.transcription import IntervalFunctions, Ocp, OcpSolution, Transcription

from fatigue_pin.core.progress import Progress, as_reporter


def run_attributes(ocp: Ocp, horizon: str, labels: dict[str, Any] | None = None) -> dict[str, object]:
    """Attributes describing a run of ``ocp``: horizon, sizes, weights and fatigue parameters by
    name (JSON), solver, model, and the study's ``labels`` (e.g. cost, S, preset)."""
    s = ocp.solver_options
    per_half = {h.name: {"model": h.params.kind, **h.params.as_dict()} for h in ocp.actuators.halves}
    attrs: dict[str, object] = {
        "horizon": horizon,
        "n_cycles": ocp.n_cycles,
        "solver": f"ipopt/{s.linear_solver}" + ("/compiled" if s.compile else ""),
        "model": ocp.model.name,
        "weights": json.dumps(dict(zip(ocp.cost_terms, ocp.problem.weights.tolist()))),
        "fatigue_params": json.dumps(per_half),
        "tau_limits": ocp.actuators.signed_limits,
        "intervals_per_cycle": ocp.task.intervals_per_cycle,
        "dt": ocp.task.dt,
        "substeps": ocp.transcription.substeps,
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
    L = ocp.layout
    fatigued = x[:, [L.nq + L.nv + r for r in ocp.actuators.fatigued_rows()]]
    return RunResult(
        name=name,
        attrs=attrs,
        t=t,
        q=x[:, L.q],
        qdot=x[:, L.v],
        tau_plus=u[:, : L.nv],
        tau_minus=u[:, L.nv :],
        fatigue={s: L.fatigue_columns(x, s) for s in L.state_kinds},
        cycle_costs=cycle_costs,
        torque_limits=torque_limits_at_cycle_ends(fatigued, ocp.actuators.signed_limits, ocp.task.intervals_per_cycle),
        joint_names=ocp.model.joint_names,
        actuator_names=ocp.actuators.half_names,
        cost_terms=ocp.cost_terms,
        cycle_wall_time_s=cycle_wall_time_s,
        windows=windows,
        urdf=Path(ocp.model.urdf_path).read_text(),
        study=study,
        fatigued=fatigued,
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


def resample_guess(ocp: Ocp, previous: OcpSolution | RunResult | tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Initial guess for ``ocp`` from a solution with another number of cycles, stretched in time.

    Cycle c of the new horizon (N_new cycles) copies cycle floor(c * N_prev / N_new) of the
    previous solution, states and controls alike, and the last node copies the last node. The
    fatigue trajectory is thus stretched over the new horizon (its gaps are not closed), so the
    guess keeps the previous solution's pacing: exhausted at the end, not half way. Measured on
    arm26 (authors-code, fatigue-torque, S = 10) with the default solver options: 32 cycles from
    the 16-cycle solution take 113 IPOPT iterations against 212 from the rest guess (16 from 8:
    104 against 101).

    Args:
        previous: an :class:`OcpSolution`, or ``(x, u)`` with x (nodes, nx) and u (intervals, nu).
    """
    x_prev, u_prev = previous if isinstance(previous, tuple) else (previous.x, previous.u)
    n = ocp.task.intervals_per_cycle
    n_new = ocp.n_cycles
    n_prev = u_prev.shape[0] // n
    src_cycle = (np.arange(n_new) * n_prev) // n_new
    idx_u = (src_cycle[:, None] * n + np.arange(n)[None, :]).reshape(-1)
    idx_x = np.append(idx_u, u_prev.shape[0])
    return x_prev[idx_x].copy(), u_prev[idx_u].copy()


class OcpBuilder:
    """Builds the OCPs of one problem for any horizon, sharing its interval functions.

    Args:
        problem, transcription, solver: as for :class:`Ocp`; guess: the default initial guess.
    """

    def __init__(self, problem: Problem, transcription: Transcription | None = None, solver: SolverOptions | None = None,
                 guess: str = "rest", progress: Progress = None) -> None:
        self.problem = problem
        self.transcription = transcription or Transcription()
        self.solver = solver or SolverOptions()
        self.guess = guess
        self.progress = progress
        self._functions: IntervalFunctions | None = None

    def __call__(self, n_cycles: int, end_tolerance: float | None = None) -> Ocp:
        ocp = Ocp(self.problem, n_cycles, self.transcription, self.solver, end_tolerance, self.guess, self._functions,
                  progress=self.progress)
        self._functions = ocp.functions
        return ocp


def solve_full(problem: Problem, n_cycles: int, transcription: Transcription | None = None, solver: SolverOptions | None = None,
               guess: str = "rest", progress: Progress = None, end_tolerance: float | None = None) -> tuple[Ocp, OcpSolution]:
    """Build and solve one full-horizon OCP of ``n_cycles`` cycles (``progress``: a Reporter or
    a line callback; default quiet). ``end_tolerance``: bound q and qdot at the last node to the
    initial state +- this fraction of their range (the authors' full horizon does, with 0.01)."""
    check_horizon(problem.task, n_cycles)
    rep = as_reporter(progress)
    rep.line(f"building the {n_cycles}-cycle OCP of {problem.model.name} ...")
    ocp = OcpBuilder(problem, transcription, solver, guess, rep)(n_cycles, end_tolerance)
    compiled = f", compiled in {ocp.compile_time_s:.1f} s" if ocp.compile_time_s else ""
    rep.line(f"built in {ocp.build_time_s:.1f} s{compiled}; solving with IPOPT ...")
    with rep.task(f"solving the {n_cycles}-cycle OCP with IPOPT"):
        sol = ocp.solve()
    rep.line(f"{sol.status}: {sol.iterations} iterations, {sol.wall_time_s:.2f} s, objective {sol.objective:.6g}")
    return ocp, sol


@dataclass
class SearchResult:
    """Outcome of a maximum-repetitions search.

    Attributes:
        max_cycles: the largest N that converged (0 if none did).
        tried: one row per solve, in order: n_cycles, converged, status, iterations, wall_time_s,
            build_time_s, kind (:func:`fatigue_pin.ocp.solver.failure_kind`), guess (``warm N=<n>``
            or the guess name) and constraint_violation. A failed warm start is followed by a
            second row of the same N (the retry).
        failures: the kind of every N that failed after its retry, by N.
        best: the converged solution with ``max_cycles`` cycles, and its OCP (None when resumed
            from a file and the best N was not solved again; read it from the file).
        run: the best run as stored in ``out`` (None without ``out``).
    """

    max_cycles: int
    tried: list[dict[str, object]] = field(default_factory=list)
    best: tuple[Ocp, OcpSolution] | None = None
    run: RunResult | None = None

    @property
    def failures(self) -> dict[int, str]:
        final = {int(r["n_cycles"]): r for r in self.tried}  # the last solve of every N
        return {n: str(r["kind"]) for n, r in sorted(final.items()) if not r["converged"]}


def _search_name(name: str) -> str:
    return name.replace("/", "_")


def step_run_name(name: str, n: int) -> str:
    """Name of the stored converged solution with ``n`` cycles of the search for run ``name``."""
    return f"searched/{_search_name(name)}/N{n}"


def max_repetitions(
    problem: Problem,
    transcription: Transcription | None = None,
    solver: SolverOptions | None = None,
    n_max: int | None = None,
    guess: str = "rest",
    progress: Progress = None,
    out: str | Path | None = None,
    name: str = "full/search",
    study: str = "",
    labels: dict[str, Any] | None = None,
    resume: bool = False,
    end_tolerance: float | None = None,
    retry: bool = True,
) -> SearchResult:
    """Largest number of cycles for which the full-horizon OCP converges.

    Args:
        problem: the problem.
        transcription, solver: discretisation and IPOPT settings.
        n_max: largest N tried (``None``: gallop until a failure).
        guess: initial guess of the first solve.
        progress: a Reporter (a line per step and a bar over the steps) or a line callback.
        out: HDF5 file; after every solve the search table (``/search/<name>``) and the converged
            solution of that N (run :func:`step_run_name`) are written, and the best run as ``name``.
        name: run name of the best solution.
        resume: continue the search stored in ``out`` (same problem), re-solving nothing already done.
        end_tolerance: bound q and qdot at the last node of every horizon to the initial state +-
            this fraction of their range (as the authors' full horizon does), or None.
        retry: when a warm-started solve fails, solve the same N again from ``guess`` before
            counting it as a failure (both solves are rows of the search table).

    A failed N is classified by :func:`fatigue_pin.ocp.solver.failure_kind` (column ``kind``):
    infeasibility (IPOPT's certificate, a failed restoration, a growing constraint violation) is
    told from non-convergence (iteration or time limit) and from a broken step computation.
    """
    if n_max is not None:
        check_horizon(problem.task, n_max, "n_max")
    rep = as_reporter(progress)
    build = OcpBuilder(problem, transcription, solver, guess, rep)
    bar = rep.bar(None, "search steps", "solve")
    solutions: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    done: dict[int, list[dict[str, object]]] = {}
    result = SearchResult(max_cycles=0)
    table = _search_name(name)
    if resume and out is not None and Path(out).exists():
        done, solutions = _restore_search(Path(out), table, name, problem.layout)
        if done:
            rep.line(f"resuming the search {name!r}: N = {sorted(done)} already done")

    def solve(ocp: Any, n: int, start: tuple[np.ndarray, np.ndarray] | None, label: str) -> Any:
        sol = ocp.solve(guess=start)
        row = {"n_cycles": n, "converged": sol.success, "status": sol.status, "iterations": sol.iterations,
               "wall_time_s": sol.wall_time_s, "build_time_s": ocp.build_time_s, "kind": sol.kind, "guess": label,
               "constraint_violation": sol.nlp.constraint_violation}
        result.tried.append(row)
        rep.line(f"N = {n:3d}: {'converged' if sol.success else 'failed   '} ({sol.status}, {sol.kind}, from {label}, "
                 f"{sol.iterations} iterations, {sol.wall_time_s:.1f} s solve, {ocp.build_time_s:.1f} s build)")
        return sol

    def attempt(n: int) -> bool:
        if n in done:
            result.tried.extend(done[n])
            return bool(done[n][-1]["converged"])
        ocp = build(n, end_tolerance)
        prior = [k for k in solutions if k <= n]
        if prior:
            sol = solve(ocp, n, resample_guess(ocp, solutions[max(prior)]), f"warm N={max(prior)}")
            if not sol.success and retry:  # another start before calling it a failure
                sol = solve(ocp, n, None, guess)
        else:
            sol = solve(ocp, n, None, guess)
        bar.update(1, N=n, status="converged" if sol.success else sol.kind, best=max(solutions) if solutions else 0)
        if sol.success:
            solutions[n] = (sol.x, sol.u)
            if n >= result.max_cycles:
                result.max_cycles, result.best = n, (ocp, sol)
        if out is not None:
            if sol.success:
                run = solution_to_run(ocp, sol, step_run_name(name, n), study, labels)
                write_run(out, run)
                if n >= max([k for k in solutions] or [0]):
                    best = solution_to_run(ocp, sol, name, study, labels)
                    write_run(out, best)
            write_search(out, table, result.tried, {**(labels or {}), "run": name, "max_cycles": max(solutions) if solutions else 0})
        return sol.success

    low, high = 0, None  # largest success, smallest failure
    n = 1
    while n_max is None or n <= n_max:
        if attempt(n):
            low = n
            n *= 2
        else:
            high = n
            break
    if high is None and n_max is not None and low < n_max:
        if attempt(n_max):
            low = n_max
        else:
            high = n_max
    while high is not None and high - low > 1:
        mid = (low + high) // 2
        if attempt(mid):
            low = mid
        else:
            high = mid
    bar.close()
    result.max_cycles = low
    if result.best is not None and result.best[0].n_cycles != low:
        result.best = None
    if out is not None and low > 0 and name in list_runs(out):
        result.run = read_run(out, name)
    return result


def _restore_search(path: Path, table: str, name: str, layout: StateLayout
                    ) -> tuple[dict[int, list[dict[str, object]]], dict[int, tuple[np.ndarray, np.ndarray]]]:
    """Rows (the solves of every N, in order) and converged solutions (states in ``layout``,
    controls) of a stored search."""
    tables = read_search(path)
    if table not in tables:
        return {}, {}
    done: dict[int, list[dict[str, object]]] = {}
    solutions: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    runs = set(list_runs(path))
    rows = tables[table]
    names = rows.dtype.names or ()

    def text(row: np.void, key: str) -> str:
        if key not in names:
            return ""
        value = row[key]
        return value.decode() if isinstance(value, bytes) else str(value)

    for row in rows:
        n = int(row["n_cycles"])
        converged = bool(row["converged"])
        if converged and step_run_name(name, n) not in runs:
            continue  # the table was written but the run was not: solve it again
        done.setdefault(n, []).append({
            "n_cycles": n, "converged": converged, "status": text(row, "status"), "iterations": int(row["iterations"]),
            "wall_time_s": float(row["wall_time_s"]), "build_time_s": 0.0, "kind": text(row, "kind"),
            "guess": text(row, "guess"),
            "constraint_violation": float(row["constraint_violation"]) if "constraint_violation" in names else float("nan")})
    for n, attempts in done.items():
        if attempts[-1]["converged"]:
            run = read_run(path, step_run_name(name, n))
            solutions[n] = (layout.assemble(run.q, run.qdot, run.fatigue), np.hstack([run.tau_plus, run.tau_minus]))
    return done, solutions
