"""Figures of a closed-loop run (:mod:`fatigue_pin.drivers.mpc_run`), PNG and PDF.

* ``<prefix>_mpc_fatigue``: the fatigued fraction mf of every half: the plant's (true), the
  controller's estimate and the prediction of the plan in force, with the capacity probes;
* ``<prefix>_mpc_task_error``: the plant's task error of every whole cycle against the tolerance
  that counts a repetition;
* ``<prefix>_mpc_replans``: the real-time factor of every re-plan (solve + estimator time over
  the time between re-plans).

:func:`plot_mpc` writes all three; :func:`fatigue_pin.viz.plots.plot_file` calls it for every
run with horizon ``mpc``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from fatigue_pin.drivers.mpc import BOUNDED_STATUS
from fatigue_pin.drivers.mpc_run import estimation_error
from fatigue_pin.drivers.run import RunResult
from fatigue_pin.viz.plots import STATE_COLORS, _figure, _save, _title, run_prefix


def _nodes_t(run: RunResult) -> np.ndarray:
    """Times of every node the plant reached (s)."""
    n = len(run.extras["estimate"])
    return np.arange(n) * float(run.attrs["dt"])


def plot_mpc_fatigue(run: RunResult, out_dir: Path) -> list[Path]:
    """mf of every half: plant, estimate, prediction; probes as dots (1 - probed capacity)."""
    e = run.extras
    t = _nodes_t(run)
    err = estimation_error(run)
    rows = np.asarray(run.attrs["fatigued_rows"], dtype=int)
    estimate = np.asarray(e["estimate"])[:, rows]
    true = estimate - err
    nqv = run.q.shape[1] + run.qdot.shape[1]
    predicted = np.asarray(e["prediction"])[:, nqv + rows]
    halves = run.actuator_names
    ncols = 2
    nrows = (len(halves) + 1) // ncols
    fig = _figure(figsize=(12, 2.8 * nrows + 0.6))
    axes = fig.subplots(nrows, ncols, sharex=True, squeeze=False).reshape(-1)
    probe_t = np.asarray(e["probe_nodes"]) * float(run.attrs["dt"])
    for h, (ax, name) in enumerate(zip(axes, halves)):
        ax.plot(t, true[:, h], color=STATE_COLORS["mf"], lw=2.0, label="plant (true)")
        ax.plot(t, estimate[:, h], color="k", lw=1.0, label=f"estimate ({run.attrs['estimator']})")
        ax.plot(t, predicted[:, h], color="#636efa", lw=0.8, ls="--", label="plan's prediction")
        if probe_t.size:
            ax.plot(probe_t, 1 - np.asarray(e["probes"])[:, h], "o", ms=3, color="#ab63fa", label="1 - probe")
        for node in np.asarray(e["replans"]["node"]):
            ax.axvline(node * float(run.attrs["dt"]), color="0.85", lw=0.5, zorder=0)
        ax.set_title(name, fontsize=10)
        ax.set_ylabel("mf (-)")
        ax.set_xlim(t[0], t[-1])
    for ax in axes[len(halves):]:
        ax.set_visible(False)
    for ax in axes[-ncols:]:
        ax.set_xlabel("time (s); grey: re-plans")
    axes[0].legend(fontsize=8, loc="upper left")
    fig.suptitle(_title(run), fontsize=9)
    fig.tight_layout()
    return _save(fig, out_dir, f"{run_prefix(run)}_mpc_fatigue")


def plot_mpc_task_error(run: RunResult, out_dir: Path) -> list[Path]:
    """Task error of every whole cycle of the plant (log scale), the tolerance as a line."""
    err = np.asarray(run.extras["task_error"], dtype=float)
    tol = float(run.attrs["target_tolerance"])
    fig = _figure(figsize=(8, 3.6))
    ax = fig.subplots()
    cycles = np.arange(1, err.size + 1)
    colors = ["#00cc96" if c <= run.attrs["repetitions"] else "#ef553b" for c in cycles]
    ax.bar(cycles, np.maximum(err, 1e-12), color=colors)
    ax.axhline(tol, color="k", lw=0.8, ls="--", label=f"tolerance {tol:g}")
    ax.set_yscale("log")
    ax.set_xlabel("cycle")
    ax.set_ylabel("task error (rad, or the target's unit)")
    ax.set_title(f"{run.attrs['repetitions']} repetitions achieved (green)", fontsize=10)
    ax.legend(fontsize=8)
    fig.suptitle(_title(run), fontsize=9)
    fig.tight_layout()
    return _save(fig, out_dir, f"{run_prefix(run)}_mpc_task_error")


def plot_mpc_replans(run: RunResult, out_dir: Path) -> list[Path]:
    """Real-time factor of every re-plan (1: as fast as the motion)."""
    table = run.extras["replans"]
    fig = _figure(figsize=(8, 3.6))
    ax = fig.subplots()
    t = np.asarray(table["node"]) * float(run.attrs["dt"])
    ok = np.asarray(table["converged"], dtype=bool)
    # real-time iterations: a re-plan stopped at its bound is a plan, not a failure
    bounded = ~ok & (np.asarray(table["status"]) == BOUNDED_STATUS.encode()) & (int(run.attrs.get("iterations_per_replan", 0)) > 0)
    if ok.any():
        ax.plot(t[ok], table["real_time_factor"][ok], "o-", ms=3, lw=0.8, label="converged")
    if bounded.any():
        ax.plot(t[bounded], table["real_time_factor"][bounded], ".", ms=3, color="#636efa",
                label=f"at most {int(run.attrs['iterations_per_replan'])} iterations (real time)")
    failed = ~ok & ~bounded
    if failed.any():
        ax.plot(t[failed], table["real_time_factor"][failed], "x", color="#ef553b", label="failed")
    ax.axhline(1.0, color="k", lw=0.8, ls="--", label="real time")
    ax.set_xlabel("time of the re-plan (s)")
    ax.set_ylabel("(re-plan + estimator) / time between re-plans")
    ax.legend(fontsize=8)
    fig.suptitle(_title(run), fontsize=9)
    fig.tight_layout()
    return _save(fig, out_dir, f"{run_prefix(run)}_mpc_replans")


def plot_mpc(run: RunResult, out_dir: Path) -> list[Path]:
    """Every closed-loop figure of ``run``."""
    return plot_mpc_fatigue(run, out_dir) + plot_mpc_task_error(run, out_dir) + plot_mpc_replans(run, out_dir)
