"""Node-wise bounds of the NLP: states on the grid, task constraint rows, node-0 target rows.

Every bound is a parameter of the NLP (:mod:`fatigue_pin.ocp.transcription`), so these functions
give values for one solve: the model's bounds, the task's ranges and targets at their nodes, the
start state at node 0 (which wins over whatever the task puts there), and a sliding window's end
box. :class:`~fatigue_pin.ocp.transcription.Ocp` calls them with its own model, task and grid.
"""

from __future__ import annotations

__all__ = ["constraint_bounds", "start_target_bounds", "state_bounds"]

import numpy as np

from fatigue_pin.ocp.task import joint_target_pairs


def state_bounds(model, task, layout, n_intervals: int, x_init: np.ndarray, x_end: np.ndarray | None = None, *,
                 target_rows: bool = False, end_tolerance: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Node-wise state bounds, each of shape (nx, N+1).

    Model bounds on q and qdot, [0, 1] on fatigue states, joint ranges, the joint targets at
    their nodes (unless ``target_rows``: then they are rows of g), ``x_init`` (nx,) at node 0 (it
    wins over a target there: the start state of a window is the previous window's state at the
    join, which misses the phase-0 target when the join is not one of its nodes, e.g.
    ``final_node_offset = -1`` with ``advance = window``) and, with ``end_tolerance`` set and
    ``x_end`` (nx,) given, q and qdot at the last node within ``x_end +- end_tolerance * range``
    (task targets at the last node win over that box).
    """
    L, N = layout, n_intervals
    nf = L.n_fatigue
    lo = np.concatenate([model.q_lower, model.v_lower, np.zeros(nf)])
    hi = np.concatenate([model.q_upper, model.v_upper, np.ones(nf)])
    X_lb = np.tile(lo[:, None], (1, N + 1))
    X_ub = np.tile(hi[:, None], (1, N + 1))
    for rng in task.joint_ranges:
        j = model.joint_names.index(rng.joint)
        X_lb[j, :] = np.maximum(X_lb[j, :], rng.lower)
        X_ub[j, :] = np.minimum(X_ub[j, :], rng.upper)
    targets = [] if target_rows else joint_target_pairs(task, model, N, L)
    for node, j, a, b in targets:
        X_lb[j, node], X_ub[j, node] = a, b
    if end_tolerance is not None and x_end is not None:
        rows = np.r_[np.arange(L.nq), L.nq + np.arange(L.nv)]
        span = (hi - lo)[rows]
        X_lb[rows, N] = np.maximum(X_lb[rows, N], x_end[rows] - end_tolerance * span)
        X_ub[rows, N] = np.minimum(X_ub[rows, N], x_end[rows] + end_tolerance * span)
        for node, j, a, b in targets:
            if node == N:
                X_lb[j, node], X_ub[j, node] = a, b
    X_lb[:, 0] = X_ub[:, 0] = x_init  # last: node 0 is the start state, whatever the task puts there
    return X_lb, X_ub


def constraint_bounds(sc, nodes: list[int], x_init: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of a task state constraint's rows (frame targets, planes, orientations,
    :class:`~fatigue_pin.ocp.task_items.StateConstraint`), each (rows, len(nodes)).

    At node 0 they are widened to the start state's value h(x_init) where it lies outside them:
    node 0 is fixed to ``x_init`` (:func:`state_bounds`), so a row there decides nothing and only
    makes the NLP infeasible when the start misses it (a closed loop's measured state below a
    plane or off a frame target; docs/mpc.md). A start that meets the row keeps its bounds.
    """
    lower = np.tile(np.asarray(sc.lower, dtype=float).reshape(-1, 1), (1, len(nodes)))
    upper = np.tile(np.asarray(sc.upper, dtype=float).reshape(-1, 1), (1, len(nodes)))
    if nodes and nodes[0] == 0:
        value = np.asarray(sc.expression(x_init), dtype=float).reshape(-1)
        lower[:, 0] = np.minimum(lower[:, 0], value)
        upper[:, 0] = np.maximum(upper[:, 0], value)
    return lower, upper


def start_target_bounds(task, model, n_intervals: int, layout, x_init: np.ndarray,
                        tolerance: float) -> tuple[list[float], list[float]]:
    """Bounds of the node-0 target rows (``Transcription.target_rows``): the targets, widened to
    the start state where it misses one by more than ``tolerance`` (IPOPT's ``constr_viol_tol``;
    the start state wins, as in :func:`state_bounds`; a start that meets the target within it
    keeps the row the paper's code has, violated by that little)."""
    starts = [(j, a, b) for node, j, a, b in joint_target_pairs(task, model, n_intervals, layout) if node == 0]
    lower = [a if x_init[j] >= a - tolerance else float(x_init[j]) for j, a, _ in starts]
    upper = [b if x_init[j] <= b + tolerance else float(x_init[j]) for j, _, b in starts]
    return lower, upper
