"""A window's budget of capacity: rows that keep every cycle a window plans repeatable until the
task's end (a sliding run's ``heat_budget``; docs/motors.md).

The cycle ending at node ``i`` of the window (``i = 1..N``) starts at node ``i - n``; for
``i < n`` that node is before the window, one of the ``n - 1`` states of the cycle already done
(``past``). Each row of the actuation layer's budget
(:meth:`~fatigue_pin.ocp.actuation_layer.ActuationLayer.window_budget`) then reads

    E_last[i] m(i) + E_before[i] m(i - n) <= 1

with ``m`` the capacity states. The coefficients depend on the cycles left after node ``i``, so
they are parameters of every solve (zero coefficients: no bound).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import casadi as ca
import numpy as np

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.ocp.actuation_layer import ActuationLayer
from fatigue_pin.ocp.solution import OcpSolution, ParameterLayout

if TYPE_CHECKING:
    from fatigue_pin.ocp.transcription import Ocp

__all__ = ["WindowBudget", "add_budget_rows", "budget_values", "require_window_budget", "solve_within", "window_budget"]


def require_window_budget(actuators: ActuationLayer) -> None:
    """Refuse (one line) a heat budget for actuators without a window budget
    (:attr:`~fatigue_pin.ocp.actuation_layer.ActuationLayer.has_window_budget`)."""
    if not actuators.has_window_budget:
        raise ParameterError(f"horizon.heat_budget = true: expected motors (actuators.kind = \"motors\"); the actuators "
                             f"are {actuators.kind!r}, which have no heat")


@dataclass(frozen=True)
class WindowBudget:
    """The budget of one solve.

    Attributes:
        rows: ``(E_last, E_before)`` of the cycle ending at each node ``1..N``, each
            (n_window_budget, n_fatigue).
        past: the capacity states (n - 1, n_fatigue) at the ``n - 1`` nodes before the window's
            first node, oldest first (zeros, with zero ``E_before`` for those nodes, where the run
            has none).
    """

    rows: Sequence[tuple[np.ndarray, np.ndarray]]
    past: np.ndarray


def add_budget_rows(opti: ca.Opti, params: ParameterLayout, M: ca.MX, n: int, nb: int) -> None:
    """The budget's rows on the capacity states ``M`` (n_fatigue, N+1) of an NLP of ``n``
    intervals per cycle, ``nb`` rows per node, their coefficients parameters of ``params``
    (a :class:`~fatigue_pin.ocp.solution.ParameterLayout`)."""
    ns, N = M.size1(), M.size2() - 1
    past = params.add("budget_past", ns, n - 1) if n > 1 else ca.MX(ns, 0)
    before = ca.horzcat(past, M[:, : N - n + 1])  # the start of the cycle ending at nodes 1..N
    for b in range(nb):
        E_last, E_before = params.add(f"budget_last_{b}", ns, N), params.add(f"budget_before_{b}", ns, N)
        opti.subject_to(ca.sum1(E_last * M[:, 1:]) + ca.sum1(E_before * before) <= 1)


def budget_values(budget: WindowBudget | None, n: int, N: int, nb: int, ns: int) -> dict[str, np.ndarray]:
    """The parameter values of :func:`add_budget_rows` for ``budget`` (None: zero, no bound)."""
    if budget is None:
        budget = WindowBudget([(np.zeros((nb, ns)), np.zeros((nb, ns)))] * N, np.zeros((max(n - 1, 0), ns)))
    if len(budget.rows) != N:
        raise ParameterError(f"window budget has rows for {len(budget.rows)} nodes; expected one pair per node 1..N, {N}")
    past = np.asarray(budget.past, dtype=float).reshape(max(n - 1, 0), ns)
    last = np.stack([np.asarray(e, dtype=float).reshape(nb, ns) for e, _ in budget.rows], axis=2)  # (nb, ns, N)
    before = np.stack([np.asarray(e, dtype=float).reshape(nb, ns) for _, e in budget.rows], axis=2)
    values = {"budget_past": past.T} if n > 1 else {}
    for b in range(nb):
        values[f"budget_last_{b}"], values[f"budget_before_{b}"] = last[b], before[b]
    return values


def window_budget(actuators: ActuationLayer, n: int, cycle_s: float, start: int, nodes: int, task_end: int,
                  past: np.ndarray) -> WindowBudget:
    """The budget of a window of ``nodes`` intervals whose first node is node ``start`` of the
    run, in a task that ends at node ``task_end`` (``max_cycles`` whole cycles of ``n``
    intervals): the layer's rows
    (:meth:`~fatigue_pin.ocp.actuation_layer.ActuationLayer.window_budget`) of the cycle ending at
    each node ``start + i`` (i = 1..nodes), for the whole cycles from it to ``task_end``; none for
    a cycle that would start before the run.

    Args:
        actuators: the actuation layer (with ``has_window_budget``).
        past: the capacity states (n - 1, n_fatigue) of the nodes ``start - n + 1 .. start - 1``
            (rows of nodes before the run are not read).
    """
    nb, ns = actuators.n_window_budget, actuators.n_states
    none = (np.zeros((nb, ns)), np.zeros((nb, ns)))
    by_cycles: dict[int, tuple[np.ndarray, np.ndarray]] = {}  # the rows depend on the cycles left only
    rows = []
    for i in range(1, nodes + 1):
        after = max((task_end - start - i) // n, 0)
        if start + i >= n and after not in by_cycles:
            by_cycles[after] = actuators.window_budget(cycle_s, after)
        rows.append(by_cycles[after] if start + i >= n else none)
    return WindowBudget(rows, np.asarray(past, dtype=float).reshape(max(n - 1, 0), ns))


def solve_within(ocp: "Ocp", budget: WindowBudget | None, **solve: Any) -> tuple[OcpSolution, bool]:
    """``ocp.solve(**solve)`` within ``budget``; a solve that fails there is done again without
    it, from the same guess and warm start, its iterations and time counting both solves.
    Returns the solution and whether it kept the budget (False without one)."""
    sol = ocp.solve(**solve, budget=budget)
    if budget is None or sol.success:
        return sol, budget is not None
    again = ocp.solve(**solve)
    return replace(again, iterations=sol.iterations + again.iterations, wall_time_s=sol.wall_time_s + again.wall_time_s), False
