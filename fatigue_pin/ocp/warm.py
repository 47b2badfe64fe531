"""Warm starts of a sliding window: the previous window's primal and dual solution, shifted.

(:func:`shift_maps_between` does the same between the NLPs of two windows whose tasks are
phase-shifted, e.g. the closed loop's re-plans a few intervals apart.)

A window of K cycles that starts A cycles after the previous one solves the same NLP (same
variables, same rows) with new parameters. Its start is the previous window's solution moved
A cycles earlier: every variable and every constraint row at node k takes the value (or the
multiplier) of the same variable or row at node k + A n of the previous window (n intervals
per cycle); the last A cycles, which the previous window did not reach, repeat its last cycle.

Which row is "the same row A n nodes later" is read off the constraint Jacobian's sparsity, so
no row layout is written twice: a row's *signature* is the set of (variable slot, node offset)
of the variables it depends on, relative to its first node; rows of equal signature (and equal
rank among such rows at their node) are the same constraint at other nodes.
"""

from __future__ import annotations

import dataclasses
from collections import defaultdict

import casadi as ca
import numpy as np


def variable_nodes(ocp) -> tuple[np.ndarray, np.ndarray]:
    """Node index and slot of every decision variable of ``ocp``'s NLP, each shape (n_x,).

    The slot says which variable of its node it is: state rows 0..nx-1, then the controls, then
    the joint torques (``torque_variable``)."""
    L, N = ocp.layout, ocp.n_intervals
    nodes = [np.repeat(np.arange(N + 1), L.nx), np.repeat(np.arange(N), L.nu)]
    slots = [np.tile(np.arange(L.nx), N + 1), L.nx + np.tile(np.arange(L.nu), N)]
    if ocp.torque_is_variable:
        nodes.append(np.repeat(np.arange(N), L.nv))
        slots.append(L.nx + L.nu + np.tile(np.arange(L.nv), N))
    return np.concatenate(nodes), np.concatenate(slots)


def _source(keys: list[tuple], shift: int, period: int, previous: list[tuple] | None = None) -> np.ndarray:
    """For entries with keys (signature, node, rank): the index of the entry of ``previous``
    (default: ``keys`` themselves) with the same signature and rank at node + shift, or (past the
    end) at node + shift - j * period for the smallest j that exists; -1 if none does."""
    previous = keys if previous is None else previous
    where = {k: i for i, k in enumerate(previous)}
    last = defaultdict(lambda: -1)
    for sig, node, rank in previous:
        last[sig, rank] = max(last[sig, rank], node)
    out = np.full(len(keys), -1, dtype=np.int64)
    for i, (sig, node, rank) in enumerate(keys):
        target = node + shift
        while target > last[sig, rank] and target - period >= node:
            target -= period
        out[i] = where.get((sig, target, rank), -1)
    return out


def _keys(ocp) -> tuple[list[tuple], list[tuple]]:
    """(signature, node, rank) of every variable and every constraint row of ``ocp``'s NLP."""
    node, slot = variable_nodes(ocp)
    x_keys = [((int(s),), int(k), 0) for k, s in zip(node, slot)]
    problem = ocp.nlp.problem
    sp = ca.jacobian_sparsity(problem["g"], problem["x"]) if "jac_g" not in ocp.nlp.derivatives \
        else ocp.nlp.derivatives["jac_g"].sparsity_out(1)
    rows, cols = (np.asarray(v, dtype=np.int64) for v in sp.get_triplet())
    by_row: dict[int, list[int]] = defaultdict(list)
    for r, c in zip(rows.tolist(), cols.tolist()):
        by_row[r].append(c)
    g_keys, rank = [], defaultdict(int)
    for r in range(sp.size1()):
        c = np.asarray(by_row.get(r, []), dtype=np.int64)
        if c.size == 0:
            g_keys.append((("empty", r), 0, 0))
            continue
        first = int(node[c].min())
        sig = tuple(sorted(zip(slot[c].tolist(), (node[c] - first).tolist())))
        g_keys.append((sig, first, rank[sig, first]))
        rank[sig, first] += 1
    return x_keys, g_keys


def shift_maps(ocp, cycles: int) -> tuple[np.ndarray, np.ndarray]:
    """Index maps ``(x_source, g_source)``: entry i of the shifted start takes entry
    ``source[i]`` of the previous solution (-1: zero), for a shift of ``cycles`` cycles."""
    n = ocp.task.intervals_per_cycle
    x_keys, g_keys = _keys(ocp)
    return _source(x_keys, cycles * n, n), _source(g_keys, cycles * n, n)


def shift_maps_between(previous, ocp, intervals: int) -> tuple[np.ndarray, np.ndarray]:
    """Index maps ``(x_source, g_source)`` from the NLP of ``previous`` to that of ``ocp``, a
    window starting ``intervals`` intervals later (its task phase-shifted by as much): entry i of
    ``ocp``'s start takes entry ``source[i]`` of ``previous``'s solution (-1: zero). Rows that
    ``ocp`` has and ``previous`` does not (a target that moved into the window) start at zero."""
    n = ocp.task.intervals_per_cycle
    x_new, g_new = _keys(ocp)
    x_old, g_old = _keys(previous)
    return _source(x_new, intervals, n, x_old), _source(g_new, intervals, n, g_old)


def shifted(values: np.ndarray, source: np.ndarray) -> np.ndarray:
    """``values`` taken through an index map of :func:`shift_maps` (zero where it is -1)."""
    values = np.asarray(values, dtype=float).reshape(-1)
    return np.where(source >= 0, values[np.maximum(source, 0)], 0.0)


def shifted_result(previous, maps: tuple[np.ndarray, np.ndarray]):
    """The NLP result ``previous`` (:class:`~fatigue_pin.ocp.solver.NlpResult`) with its primal
    and dual values taken through the index maps ``(x_source, g_source)`` of :func:`shift_maps`
    or :func:`shift_maps_between`: the start of a warm-started solve."""
    x_map, g_map = maps
    return dataclasses.replace(previous, x=shifted(previous.x, x_map), lam_x=shifted(previous.lam_x, x_map),
                               lam_g=shifted(previous.lam_g, g_map))
