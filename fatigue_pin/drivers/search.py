"""The search for the maximum number of repetitions: the largest N for which the full-horizon
OCP of N cycles converges.

The paper raised N one at a time until IPOPT failed. :func:`max_repetitions` gallops instead
(N = 1, 2, 4, ... until a failure), then bisects between the largest success and the smallest
failure, each solve warm-started from the nearest converged solution with fewer cycles, stretched
in time (:func:`fatigue_pin.ocp.guesses.resample_guess`). Every N tried is reported and, with a
store, kept as it finishes, so a killed search resumes (``resume=True``) to the same result. Like
the paper's search it assumes that convergence is monotone in N.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from fatigue_pin.core.progress import Progress, as_reporter
from fatigue_pin.core.signals import Interrupted, deferred, signal_name
from fatigue_pin.drivers.full import OcpBuilder
from fatigue_pin.drivers.run import RunResult, RunStore, solution_to_run
from fatigue_pin.ocp.guesses import resample_guess
from fatigue_pin.ocp.task import check_horizon
from fatigue_pin.ocp.problem import Problem, StateLayout
from fatigue_pin.ocp.solver import SolverOptions
from fatigue_pin.ocp.transcription import Ocp, OcpSolution, Transcription

Solution = tuple[np.ndarray, np.ndarray]  # states (nodes, nx), controls (intervals, nu)


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
            from a store and the best N was not solved again; read it from the store).
        run: the best run as stored (None without a store).
    """

    max_cycles: int
    tried: list[dict[str, object]] = field(default_factory=list)
    best: tuple[Ocp, OcpSolution] | None = None
    run: RunResult | None = None

    @property
    def failures(self) -> dict[int, str]:
        final = {int(r["n_cycles"]): r for r in self.tried}  # the last solve of every N
        return {n: str(r["kind"]) for n, r in sorted(final.items()) if not r["converged"]}


def search_table_name(name: str) -> str:
    """Name of the search table of run ``name`` (``/search/<table>`` in a result file)."""
    return name.replace("/", "_")


def step_run_name(name: str, n: int) -> str:
    """Name of the stored converged solution with ``n`` cycles of the search for run ``name``."""
    return f"searched/{search_table_name(name)}/N{n}"


class _Search:
    """One search: the solves done so far, the converged solutions, and where they are kept."""

    def __init__(self, build: OcpBuilder, guess: str, retry: bool, end_tolerance: float | None, store: RunStore | None,
                 name: str, study: str, labels: dict[str, Any], rep: Any) -> None:
        self.build, self.guess, self.retry, self.end_tolerance = build, guess, retry, end_tolerance
        self.store, self.name, self.study, self.labels, self.rep = store, name, study, labels, rep
        self.result = SearchResult(max_cycles=0)
        self.solutions: dict[int, Solution] = {}
        self.done: dict[int, list[dict[str, object]]] = {}
        self.kept = 0  # rows of result.tried that the stored table holds
        self.bar = rep.bar(None, "search steps", "solve")

    def _solve(self, ocp: Ocp, n: int, start: Solution | None, label: str) -> OcpSolution:
        sol = ocp.solve(guess=start)
        row = {"n_cycles": n, "converged": sol.success, "status": sol.status, "iterations": sol.iterations,
               "wall_time_s": sol.wall_time_s, "build_time_s": ocp.build_time_s, "kind": sol.kind, "guess": label,
               "constraint_violation": sol.nlp.constraint_violation}
        self.result.tried.append(row)
        self.rep.line(f"N = {n:3d}: {'converged' if sol.success else 'failed   '} ({sol.status}, {sol.kind}, from {label}, "
                      f"{sol.iterations} iterations, {sol.wall_time_s:.1f} s solve, {ocp.build_time_s:.1f} s build)")
        return sol

    def attempt(self, n: int) -> bool:
        """Solve N = ``n`` (or take its stored outcome); True if it converged."""
        if n in self.done:
            self.result.tried.extend(self.done[n])
            self.kept = len(self.result.tried)
            return bool(self.done[n][-1]["converged"])
        ocp = self.build(n, self.end_tolerance)
        prior = [k for k in self.solutions if k <= n]
        if prior:
            sol = self._solve(ocp, n, resample_guess(ocp, self.solutions[max(prior)]), f"warm N={max(prior)}")
            if not sol.success and self.retry:  # another start before calling it a failure
                sol = self._solve(ocp, n, None, self.guess)
        else:
            sol = self._solve(ocp, n, None, self.guess)
        best = max(self.solutions) if self.solutions else 0
        self.bar.update(1, N=n, status="converged" if sol.success else sol.kind, best=best)
        with deferred():  # N is kept and stored whole, or not at all
            if sol.success:
                self.solutions[n] = (sol.x, sol.u)
                if n >= self.result.max_cycles:
                    self.result.max_cycles, self.result.best = n, (ocp, sol)
            self._keep(ocp, sol, n)
        return sol.success

    def _table_attrs(self, interrupted: str = "") -> dict[str, Any]:
        """The search table's attributes; ``interrupted``: the signal that stopped the search."""
        best = max(self.solutions) if self.solutions else 0
        attrs = {**self.labels, "run": self.name, "max_cycles": best}
        return attrs | {"interrupted": interrupted} if interrupted else attrs

    def interrupted(self, exc: Interrupted) -> None:
        """Mark the stored search as interrupted by ``exc``'s signal (every N kept stays; a solve
        whose outcome was not yet kept is solved again on resuming)."""
        if self.store is not None and self.kept:
            with deferred():
                self.store.write_table(search_table_name(self.name), self.result.tried[: self.kept],
                                       self._table_attrs(signal_name(exc)))

    def _keep(self, ocp: Ocp, sol: OcpSolution, n: int) -> None:
        """Store the converged solution of N (and as the best run when it is the largest so far)
        and the search table."""
        if self.store is None:
            return
        if sol.success:
            self.store.write(solution_to_run(ocp, sol, step_run_name(self.name, n), self.study, self.labels))
            if n >= max(self.solutions):
                self.store.write(solution_to_run(ocp, sol, self.name, self.study, self.labels))
        self.store.write_table(search_table_name(self.name), self.result.tried, self._table_attrs())
        self.kept = len(self.result.tried)

    def restore(self, layout: StateLayout) -> None:
        """Take the solves and converged solutions of a stored search of the same run."""
        table = self.store.tables().get(search_table_name(self.name)) if self.store is not None else None
        if table is None:
            return
        runs = set(self.store.runs())
        names = table.dtype.names or ()

        def text(row: np.void, key: str) -> str:
            value = row[key] if key in names else ""
            return value.decode() if isinstance(value, bytes) else str(value)

        for row in table:
            n, converged = int(row["n_cycles"]), bool(row["converged"])
            if converged and step_run_name(self.name, n) not in runs:
                continue  # the table was written but the run was not: solve it again
            self.done.setdefault(n, []).append({
                "n_cycles": n, "converged": converged, "status": text(row, "status"), "iterations": int(row["iterations"]),
                "wall_time_s": float(row["wall_time_s"]), "build_time_s": 0.0, "kind": text(row, "kind"),
                "guess": text(row, "guess"),
                "constraint_violation": float(row["constraint_violation"]) if "constraint_violation" in names else float("nan")})
        for n, attempts in self.done.items():
            if attempts[-1]["converged"]:
                run = self.store.read(step_run_name(self.name, n))
                self.solutions[n] = (layout.assemble(run.q, run.qdot, run.fatigue), layout.actuators.controls(run.half_torques()))
        if self.done:
            self.rep.line(f"resuming the search {self.name!r}: N = {sorted(self.done)} already done")

    def run(self, n_max: int | None) -> SearchResult:
        """Gallop, then bisect; returns the outcome. Interrupted (SIGINT, SIGTERM): the stored
        table says so, and the exception goes on."""
        try:
            return self._run(n_max)
        except Interrupted as exc:
            self.interrupted(exc)
            raise

    def _run(self, n_max: int | None) -> SearchResult:
        low, high, n = 0, None, 1  # largest success, smallest failure, next N
        while n_max is None or n <= n_max:
            if not self.attempt(n):
                high = n
                break
            low, n = n, 2 * n
        if high is None and n_max is not None and low < n_max:
            low, high = (n_max, None) if self.attempt(n_max) else (low, n_max)
        while high is not None and high - low > 1:
            mid = (low + high) // 2
            low, high = (mid, high) if self.attempt(mid) else (low, mid)
        self.bar.close()
        result = self.result
        result.max_cycles = low
        if result.best is not None and result.best[0].n_cycles != low:
            result.best = None
        if self.store is not None and low > 0 and self.name in self.store.runs():
            result.run = self.store.read(self.name)
        return result


def max_repetitions(
    problem: Problem,
    transcription: Transcription | None = None,
    solver: SolverOptions | None = None,
    n_max: int | None = None,
    guess: str = "rest",
    progress: Progress = None,
    store: RunStore | None = None,
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
        transcription: discretisation settings.
        solver: IPOPT settings.
        n_max: largest N tried (``None``: gallop until a failure).
        guess: initial guess of the first solve.
        progress: a Reporter (a line per step and a bar over the steps) or a line callback.
        store: where runs are kept (e.g. :class:`fatigue_pin.io.results.ResultFile`); after every
            solve the search table (:func:`search_table_name`) and the converged solution of that N
            (run :func:`step_run_name`) are written, and the best run as ``name``.
        name: run name of the best solution.
        resume: continue the search kept in ``store`` (same problem), re-solving nothing already done.
        end_tolerance: bound q and qdot at the last node of every horizon to the initial state +-
            this fraction of their range (as the authors' full horizon does), or None.
        retry: when a warm-started solve fails, solve the same N again from ``guess`` before
            counting it as a failure (both solves are rows of the search table).

    A failed N is classified by :func:`fatigue_pin.ocp.solver.failure_kind` (column ``kind``):
    infeasibility (IPOPT's certificate, a failed restoration, a growing constraint violation) is
    told from non-convergence (iteration or time limit) and from a broken step computation.
    """
    if n_max is not None and problem is not None:  # (tests stand in a fake builder for the problem)
        check_horizon(problem.task, n_max, "n_max")
    rep = as_reporter(progress)
    search = _Search(OcpBuilder(problem, transcription, solver, guess, rep), guess, retry, end_tolerance, store, name, study,
                     dict(labels or {}), rep)
    if resume:
        search.restore(problem.layout)
    return search.run(n_max)
