"""Full-horizon solves: one OCP over the whole task (:func:`solve_full`), and the builder of the
OCPs of one problem for any number of cycles (:class:`OcpBuilder`, shared by every driver)."""

from __future__ import annotations

from fatigue_pin.ocp.problem import Problem
from fatigue_pin.ocp.solver import SolverOptions, resolve_first_compile
from fatigue_pin.ocp.task import check_horizon
from fatigue_pin.ocp.transcription import IntervalFunctions, Ocp, OcpSolution, Transcription

from fatigue_pin.core.progress import Progress, as_reporter


class OcpBuilder:
    """Builds the OCPs of one problem for any horizon, sharing its interval functions.

    Args:
        problem: as for :class:`Ocp`.
        transcription: as for :class:`Ocp`.
        solver: as for :class:`Ocp`.
        guess: the default initial guess.
        progress: a Reporter or a line callback (default quiet).
    """

    def __init__(self, problem: Problem, transcription: Transcription | None = None, solver: SolverOptions | None = None,
                 guess: str = "rest", progress: Progress = None) -> None:
        self.problem = problem
        self.transcription = transcription or Transcription()
        self.solver = solver or SolverOptions()
        self.guess = guess
        self.progress = progress
        self._functions: IntervalFunctions | None = None

    def __call__(self, n_cycles: int, end_tolerance: float | None = None, window_budget: bool = False) -> Ocp:
        ocp = Ocp(self.problem, n_cycles, self.transcription, self.solver, end_tolerance, self.guess, self._functions,
                  progress=self.progress, window_budget=window_budget)
        self._functions = ocp.functions
        return ocp


def solve_full(problem: Problem, n_cycles: int, transcription: Transcription | None = None, solver: SolverOptions | None = None,
               guess: str = "rest", progress: Progress = None, end_tolerance: float | None = None) -> tuple[Ocp, OcpSolution]:
    """Build and solve one full-horizon OCP of ``n_cycles`` cycles (``progress``: a Reporter or
    a line callback; default quiet). ``end_tolerance``: bound q and qdot at the last node to the
    initial state +- this fraction of their range (the authors' full horizon does, with 0.01).
    ``solver.first_compile = "auto"`` compiles in the background on a short horizon
    (:func:`fatigue_pin.ocp.solver.resolve_first_compile`)."""
    check_horizon(problem.task, n_cycles)
    rep = as_reporter(progress)
    rep.line(f"building the {n_cycles}-cycle OCP of {problem.model.name} ...")
    solver = resolve_first_compile(solver or SolverOptions(), n_cycles * problem.task.intervals_per_cycle)
    ocp = OcpBuilder(problem, transcription, solver, guess, rep)(n_cycles, end_tolerance)
    compiled = f", compiled in {ocp.compile_time_s:.1f} s" if ocp.compile_time_s else ""
    rep.line(f"built in {ocp.build_time_s:.1f} s{compiled}; solving with IPOPT ...")
    with rep.task(f"solving the {n_cycles}-cycle OCP with IPOPT"):
        sol = ocp.solve()
    rep.line(f"{sol.status}: {sol.iterations} iterations, {sol.wall_time_s:.2f} s, objective {sol.objective:.6g}")
    return ocp, sol


