"""Full-horizon solves: one OCP over the whole task, and the search for the maximum repetitions.

The paper raised the number of cycles N one at a time until IPOPT failed. :func:`max_repetitions`
gallops instead (N = 1, 2, 4, ... until a failure), then bisects between the largest success and
the smallest failure, each solve warm-started from the nearest converged solution with fewer
cycles, stretched in time (:func:`resample_guess`). Every N tried is
reported. Like the paper's search it assumes that convergence is monotone in N.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from fatigue_pin.model import RobotModel
from fatigue_pin.ocp import COST_TERMS, FatigueOcp, OcpSettings, OcpSolution
from fatigue_pin.results import RunResult, config_json, torque_limits_at_cycle_ends, write_run, write_search

Progress = Callable[[str], None]


def _quiet(_: str) -> None:
    pass


def run_attributes(ocp: FatigueOcp, horizon: str) -> dict[str, object]:
    """Attributes describing a run of ``ocp`` (settings, fatigue parameters, solver)."""
    s = ocp.settings
    first = ocp.actuators.halves[0].params
    per_half = {h.name: h.params.as_dict() for h in ocp.actuators.halves}
    return {
        "horizon": horizon,
        "cost": s.cost,
        "preset": s.preset,
        "S": first.S,
        "F": first.F,
        "R": first.R,
        "LD": first.LD,
        "LR": first.LR,
        "n_cycles": s.n_cycles,
        "solver": f"ipopt/{s.solver.linear_solver}" + ("/compiled" if s.solver.compile else ""),
        "model": ocp.model.name,
        "fatigue_params": json.dumps(per_half),
        "tau_limits": ocp.actuators.signed_limits,
        "intervals_per_cycle": ocp.task.intervals_per_cycle,
        "dt": ocp.task.dt,
        "substeps": s.substeps,
        "config": config_json(s),
    }


def to_run_result(
    ocp: FatigueOcp,
    t: np.ndarray,
    x: np.ndarray,
    u: np.ndarray,
    cycle_costs: np.ndarray,
    name: str,
    attrs: dict[str, object],
    cycle_wall_time_s: np.ndarray,
    windows: np.ndarray | None = None,
) -> RunResult:
    """Assemble a :class:`RunResult` from node states (nodes, nx) and controls (intervals, nu)."""
    L = ocp.layout
    mf = x[:, L.fatigue_index("mf")]
    return RunResult(
        name=name,
        attrs=attrs,
        t=t,
        q=x[:, L.q],
        qdot=x[:, L.v],
        tau_plus=u[:, : L.nv],
        tau_minus=u[:, L.nv :],
        ma=x[:, L.fatigue_index("ma")],
        mr=x[:, L.fatigue_index("mr")],
        mf=mf,
        cycle_costs=cycle_costs,
        torque_limits=torque_limits_at_cycle_ends(mf, ocp.actuators.signed_limits, ocp.task.intervals_per_cycle),
        joint_names=ocp.model.joint_names,
        actuator_names=ocp.actuators.half_names,
        cost_terms=COST_TERMS,
        cycle_wall_time_s=cycle_wall_time_s,
        windows=windows,
        urdf=Path(ocp.model.urdf_path).read_text(),
    )


def solution_to_run(ocp: FatigueOcp, sol: OcpSolution, name: str) -> RunResult:
    """The :class:`RunResult` of a full-horizon solution."""
    attrs = run_attributes(ocp, "full")
    attrs.update(
        converged=sol.success,
        status=sol.status,
        wall_time_s=sol.wall_time_s,
        build_time_s=ocp.build_time_s,
        compile_time_s=ocp.nlp.compile_time_s,
        iterations=sol.iterations,
        objective=sol.objective,
    )
    per_cycle = np.full(ocp.settings.n_cycles, sol.wall_time_s / ocp.settings.n_cycles)
    return to_run_result(ocp, sol.t, sol.x, sol.u, sol.cycle_costs, name, attrs, per_cycle)


def default_run_name(settings: OcpSettings, horizon: str) -> str:
    """``full/fatigue-torque_S10`` style group names."""
    return f"{horizon}/{settings.cost}_S{settings.S:g}"


def resample_guess(ocp: FatigueOcp, previous: OcpSolution) -> tuple[np.ndarray, np.ndarray]:
    """Initial guess for ``ocp`` from a solution with another number of cycles, stretched in time.

    Cycle c of the new horizon (N_new cycles) copies cycle floor(c * N_prev / N_new) of the
    previous solution, states and controls alike, and the last node copies the last node. The
    fatigue trajectory is thus stretched over the new horizon (its gaps are not closed), so the
    guess keeps the previous solution's pacing: exhausted at the end, not half way. Measured on
    arm26 (authors-code, fatigue-torque, S = 10) with the default solver options: 32 cycles from
    the 16-cycle solution take 113 IPOPT iterations against 212 from the rest guess (16 from 8:
    104 against 101). With IPOPT's own mu_init and perturb_dec_fact, 16 from 8 took 74 against
    114, and 109 when the fatigue was integrated forward from the copied controls instead.
    """
    n = ocp.task.intervals_per_cycle
    n_new = ocp.settings.n_cycles
    n_prev = previous.u.shape[0] // n
    src_cycle = (np.arange(n_new) * n_prev) // n_new
    idx_u = (src_cycle[:, None] * n + np.arange(n)[None, :]).reshape(-1)
    idx_x = np.append(idx_u, previous.u.shape[0])
    return previous.x[idx_x].copy(), previous.u[idx_u].copy()


def solve_full(model: RobotModel, settings: OcpSettings, progress: Progress = _quiet) -> tuple[FatigueOcp, OcpSolution]:
    """Build and solve one full-horizon OCP (``settings.n_cycles`` cycles)."""
    progress(f"building the {settings.n_cycles}-cycle OCP ({settings.cost}, S = {settings.S:g}, preset {settings.preset}) ...")
    ocp = FatigueOcp(model, settings)
    compiled = f", compiled in {ocp.nlp.compile_time_s:.1f} s" if ocp.nlp.compile_time_s else ""
    progress(f"built in {ocp.build_time_s:.1f} s{compiled}; solving with IPOPT ...")
    sol = ocp.solve()
    progress(f"{sol.status}: {sol.iterations} iterations, {sol.wall_time_s:.2f} s, objective {sol.objective:.6g}")
    return ocp, sol


@dataclass
class SearchResult:
    """Outcome of a maximum-repetitions search.

    Attributes:
        max_cycles: the largest N that converged (0 if none did).
        tried: one row per N tried, in order: n_cycles, converged, status, iterations, wall_time_s.
        best: the converged solution with ``max_cycles`` cycles, and its OCP.
    """

    max_cycles: int
    tried: list[dict[str, object]] = field(default_factory=list)
    best: tuple[FatigueOcp, OcpSolution] | None = None


def max_repetitions(
    model: RobotModel,
    settings: OcpSettings,
    n_max: int = 33,
    progress: Progress = _quiet,
    out: str | Path | None = None,
) -> SearchResult:
    """Largest number of cycles for which the full-horizon OCP converges.

    Args:
        model: the rigid-body model.
        settings: problem settings (``n_cycles`` is ignored).
        n_max: largest N tried.
        progress: called with one line per step.
        out: if given, the search table and the best run are written to this HDF5 file after
            every solve, so an interrupted search keeps what it found.
    """
    solutions: dict[int, tuple[FatigueOcp, OcpSolution]] = {}
    result = SearchResult(max_cycles=0)

    def attempt(n: int) -> bool:
        ocp = FatigueOcp(model, settings.with_(n_cycles=n))
        done = [k for k in solutions if k <= n]
        guess = resample_guess(ocp, solutions[max(done)][1]) if done else None
        sol = ocp.solve(guess=guess)
        row = {"n_cycles": n, "converged": sol.success, "status": sol.status, "iterations": sol.iterations,
               "wall_time_s": sol.wall_time_s, "build_time_s": ocp.build_time_s}
        result.tried.append(row)
        progress(f"N = {n:3d}: {'converged' if sol.success else 'failed   '} ({sol.status}, {sol.iterations} iterations, "
                 f"{sol.wall_time_s:.1f} s solve, {ocp.build_time_s:.1f} s build)")
        if sol.success:
            solutions[n] = (ocp, sol)
            if n > result.max_cycles:
                result.max_cycles, result.best = n, (ocp, sol)
        if out is not None:
            write_search(out, f"{settings.cost}_S{settings.S:g}", result.tried,
                         {"cost": settings.cost, "S": settings.S, "preset": settings.preset, "max_cycles": result.max_cycles})
            if sol.success and result.best is not None and result.best[1] is sol:
                write_run(out, solution_to_run(ocp, sol, default_run_name(settings, "full")))
        return sol.success

    low, high = 0, None  # largest success, smallest failure
    n = 1
    while n <= n_max:
        if attempt(n):
            low = n
            n *= 2
        else:
            high = n
            break
    if high is None and low < n_max:
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
    result.max_cycles = low
    result.best = solutions.get(low)
    return result
