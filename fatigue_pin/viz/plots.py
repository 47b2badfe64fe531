"""Figures of result files (matplotlib, Agg canvas, no pyplot state): every figure is saved as PNG
and PDF, every function returns the paths it wrote.

Per OCP run (``<prefix>`` is the run name with '/' replaced by '_'):

* ``<prefix>_joint_angles``: each joint's position over the cycle, one line per cycle (revolute
  joints in deg, prismatic joints in m);
* ``<prefix>_fatigue_states``: stacked ma, mr, mf and the target load TL of every actuator half;
* ``<prefix>_torque_limits``: available torque (1 - mf) * tau_limit of every half at cycle ends
  (N m; N for the halves of prismatic joints, which exert forces);
* ``<prefix>_capacity``: (:func:`plot_capacity`, not in :func:`plot_run`) each joint's flexion
  and extension capacity at cycle ends against the peak torque the cycle used and, if given,
  the torque that holds the posture;
* ``<prefix>_cycle_costs``: the weighted cost terms of every cycle (log scale);
* ``<prefix>_solve_time``: solve time per cycle (sliding horizon: per window);
* ``<prefix>_motors`` (motor runs): each winding's temperature against its limit, and each
  joint's RMS torque per cycle (how the work is shared);
* ``<prefix>_muscles`` (muscle runs): :func:`plot_muscles`.

Per file: ``runs_comparison`` when it holds several runs, ``search_<name>`` for each max-cycles
search table, and the forward-study figures for ``forward_studies.h5``.
:func:`plot_file` picks what applies. The layouts are described in ``docs/results.md``.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

import matplotlib
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from fatigue_pin.io.results import ResultFileError, RunResult, list_runs, read_run, read_search

#: Colours of the fatigue compartments (as in the forward-study figures).
STATE_COLORS = {"ma": "#00cc96", "mr": "#ffa15a", "mf": "#ef553b"}
DPI = 120


def _figure(**kwargs: object) -> Figure:
    fig = Figure(**kwargs)
    FigureCanvasAgg(fig)
    return fig


def _save(fig: Figure, out_dir: Path, stem: str) -> list[Path]:
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = [out_dir / f"{stem}.png", out_dir / f"{stem}.pdf"]
    fig.savefig(paths[0], dpi=DPI)
    fig.savefig(paths[1])
    return paths


def run_prefix(run: RunResult | str) -> str:
    """File-name prefix of a run: its name with '/' replaced by '_'."""
    name = run if isinstance(run, str) else run.name
    return name.strip("/").replace("/", "_")


def _title(run: RunResult) -> str:
    a = run.attrs
    labels = [f"{k} {a[k]}" for k in ("cost", "S", "preset") if k in a]
    bits = [run.name, f"{a.get('model', '?')}", f"{a.get('horizon', '?')} horizon", *labels, f"{run.n_cycles} cycles", "converged" if run.converged else f"NOT CONVERGED ({a.get('status', '?')})"]
    return ", ".join(str(b) for b in bits)


def _cycle_colors(n: int) -> np.ndarray:
    from matplotlib import colormaps

    return colormaps["viridis"](np.linspace(0.0, 0.9, max(n, 1)))


# -- per-run figures -----------------------------------------------------------------------------


def _units_word(units: Sequence[str]) -> str:
    """One axis label's unit for columns of ``units``: the common one, or ``N m or N``."""
    return " or ".join(dict.fromkeys(units))


def _position_label(units) -> str:
    """``angle (deg)``, ``position (m)``: the y label of a joint's positions (:class:`JointUnits`)."""
    return f"{units.position_name} ({units.display_position})"


def plot_joint_angles(run: RunResult, out_dir: Path) -> list[Path]:
    """Joint positions against time within the cycle (s), one line per cycle, one panel per joint:
    revolute joints in deg, prismatic joints in m (:meth:`RunResult.joint_units`)."""
    n = run.n_cycles
    colors = _cycle_colors(n)
    fig = _figure(figsize=(6 * len(run.joint_names), 4.2))
    axes = fig.subplots(1, len(run.joint_names), squeeze=False)[0]
    for j, (ax, joint) in enumerate(zip(axes, run.joint_names)):
        units = run.joint_units(j)
        for c in range(n):
            s = run.cycle_slice(c)
            tc = run.t[s] - run.t[s.start]
            edge = c in (0, n - 1)
            ax.plot(tc, units.display(run.q[s, j]), color=colors[c], lw=2.2 if edge else 0.8, alpha=1.0 if edge else 0.6,
                    zorder=3 if edge else 2, label=f"cycle {c + 1}" if edge else None)
        ax.set_title(joint)
        ax.set_xlabel("time in cycle (s)")
        ax.set_ylabel(_position_label(units))
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    if n > 1:
        from matplotlib.cm import ScalarMappable
        from matplotlib.colors import ListedColormap, Normalize

        sm = ScalarMappable(Normalize(1, n), ListedColormap(colors))
        fig.colorbar(sm, ax=list(axes), label="cycle", fraction=0.04)
    fig.suptitle(_title(run), fontsize=9)
    return _save(fig, out_dir, f"{run_prefix(run)}_joint_angles")


def plot_fatigue_states(run: RunResult, out_dir: Path) -> list[Path]:
    """The fatigue states of every half stacked (bottom to top, in the order the models declare
    them: ma, mr, mf for Xia's model), with its target load TL (black steps); TL must stay below
    1 - mf, the lower edge of the mf band."""
    halves = run.actuator_names
    tl = run.target_loads()
    ncols = 2
    nrows = (len(halves) + 1) // ncols
    fig = _figure(figsize=(12, 3.0 * nrows + 0.6))
    axes = fig.subplots(nrows, ncols, sharex=True, squeeze=False).reshape(-1)
    for h, (ax, name) in enumerate(zip(axes, halves)):
        states = [s for s in run.fatigue_states if np.all(np.isfinite(run.fatigue[s][:, h]))]
        palette = matplotlib.colormaps["tab10"]
        ax.stackplot(run.t, *[run.fatigue[s][:, h] for s in states], labels=states,
                     colors=[STATE_COLORS.get(s, palette(i)) for i, s in enumerate(states)], alpha=0.85, lw=0)
        ax.step(run.t[:-1], tl[:, h], where="post", color="k", lw=0.8, label="TL = tau / tau_limit")
        for c in range(1, run.n_cycles):
            ax.axvline(run.t[run.cycle_slice(c).start], color="w", lw=0.4, alpha=0.6)
        ax.set_ylim(0.0, 1.05)
        ax.set_xlim(run.t[0], run.t[-1])
        ax.set_title(f"{name} (limit {run.signed_limits[h]:+g} {run.unit_effort(h)})", fontsize=10)
        ax.set_ylabel("fraction (-)")
    for ax in axes[len(halves):]:
        ax.set_visible(False)
    for ax in axes[-ncols:]:
        ax.set_xlabel("time (s)")
    axes[0].legend(fontsize=8, loc="upper left", ncol=4)
    fig.suptitle(_title(run), fontsize=9)
    fig.tight_layout()
    return _save(fig, out_dir, f"{run_prefix(run)}_fatigue_states")


def plot_torque_limits(run: RunResult, out_dir: Path) -> list[Path]:
    """Available torque (1 - mf) * tau_limit (N m, or N for a prismatic joint's halves) of every
    half at the start and at the end of each cycle."""
    lim = run.signed_limits
    cycles = np.arange(0, run.n_cycles + 1)
    fig = _figure(figsize=(9, 5))
    axes = fig.subplots(1, 2, sharex=True)
    for h, name in enumerate(run.actuator_names):
        if name in run.muscle_names:  # a muscle's available activation: plot_muscles
            continue
        values = np.concatenate([[lim[h] * (1.0 - run.fatigued[0, h])], run.torque_limits[:, h]])
        ax = axes[1] if lim[h] < 0 else axes[0]
        ratio = values[0] / values[-1] if values[-1] != 0 else np.inf
        unit = run.half_units(h).effort
        ax.plot(cycles, values, "o-", ms=3, label=f"{name}: {values[0]:.3g} -> {values[-1]:.3g} {unit} ({ratio:.3g}x lower)")
    unit = _units_word([run.unit_effort(h) for h in range(len(run.actuator_names)) if run.actuator_names[h] not in run.muscle_names]
                       or ["N m"])
    for ax, kind in zip(axes, ("flexion halves (tau_plus)", "extension halves (tau_minus)")):
        ax.set_title(kind, fontsize=10)
        ax.set_xlabel("end of cycle (0: start)")
        ax.set_ylabel(f"torque limit ({unit})")
        ax.grid(alpha=0.3)
        if ax.lines:
            ax.legend(fontsize=7)
    fig.suptitle(_title(run), fontsize=9)
    fig.tight_layout()
    return _save(fig, out_dir, f"{run_prefix(run)}_torque_limits")


def plot_cycle_costs(run: RunResult, out_dir: Path) -> list[Path]:
    """Each weighted cost term per cycle (log scale), and their sum."""
    cycles = np.arange(1, run.n_cycles + 1)
    fig = _figure(figsize=(8, 4.5))
    ax = fig.subplots()
    for k, term in enumerate(run.cost_terms):
        v = run.cycle_costs[:, k]
        if np.any(v > 0):
            ax.semilogy(cycles, np.where(v > 0, v, np.nan), "o-", ms=3, label=term)
    total = run.cycle_costs.sum(axis=1)
    if np.any(total > 0):
        ax.semilogy(cycles, np.where(total > 0, total, np.nan), "k--", lw=1, label="total")
    ax.set_xlabel("cycle")
    ax.set_ylabel("weighted cost (-)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    ax.set_title(_title(run), fontsize=9)
    fig.tight_layout()
    return _save(fig, out_dir, f"{run_prefix(run)}_cycle_costs")


def plot_solve_time(run: RunResult, out_dir: Path) -> list[Path]:
    """Solve time (s). Sliding horizon: each window's wall time as a bar at the cycle it starts
    (failed windows hatched), with the time attributed to each kept cycle. Full horizon: the total
    wall time spread evenly over the cycles."""
    fig = _figure(figsize=(8, 4.5))
    ax = fig.subplots()
    cycles = np.arange(1, run.n_cycles + 1)
    if run.attrs.get("horizon") == "sliding" and run.windows is not None and len(run.windows):
        from matplotlib import colormaps

        w = run.windows
        colors = colormaps["tab20"](np.arange(len(w)) % 20)
        bottom: dict[int, float] = {}
        for i, row in enumerate(w):
            c = int(row["first_cycle"]) + 1
            ax.bar(c, row["wall_time_s"], bottom=bottom.get(c, 0.0), color=colors[i], edgecolor="k", lw=0.4,
                   hatch=None if row["converged"] else "//", width=0.8)
            bottom[c] = bottom.get(c, 0.0) + float(row["wall_time_s"])
        if run.cycle_wall_time_s.size == run.n_cycles:
            ax.plot(cycles, run.cycle_wall_time_s, "k.-", lw=0.8, label="attributed to each kept cycle")
            ax.legend(fontsize=8)
        total = float(np.sum(w["wall_time_s"]))
        ax.set_xlabel("first cycle of the window")
        ax.set_ylabel("wall time per window (s)")
        ax.set_title(f"{len(w)} windows ({int(np.sum(~w['converged']))} failed, hatched), total {total:.1f} s, "
                     f"median {np.median(w['wall_time_s']):.2f} s per window", fontsize=9)
    else:
        per_cycle = run.cycle_wall_time_s
        if per_cycle.size != run.n_cycles:
            per_cycle = np.full(run.n_cycles, float(run.attrs.get("wall_time_s", np.nan)) / max(run.n_cycles, 1))
        ax.bar(cycles, per_cycle, color="tab:blue", width=0.8)
        ax.set_xlabel("cycle")
        ax.set_ylabel("wall time per cycle (s)")
        ax.set_title(f"one NLP over {run.n_cycles} cycles: {float(run.attrs.get('wall_time_s', np.nan)):.1f} s "
                     f"= {np.mean(per_cycle):.2f} s per cycle", fontsize=9)
    ax.grid(alpha=0.3, axis="y")
    fig.suptitle(_title(run), fontsize=9)
    fig.tight_layout()
    return _save(fig, out_dir, f"{run_prefix(run)}_solve_time")


def plot_muscles(run: RunResult, out_dir: Path) -> list[Path]:
    """A muscle run's muscles: each muscle's fatigued fraction over the run (cycle ends marked),
    its force at the start of every interval (N), and the joint torques the muscles and the
    residual torques give (N m)."""
    names = run.muscle_names
    idx = [run.actuator_names.index(m) for m in names]
    fig = _figure(figsize=(12, 8))
    ax_mf, ax_f, ax_tau = fig.subplots(3, 1, sharex=True)
    colors = matplotlib.colormaps["tab10"]
    ends = [run.cycle_slice(c).stop - 1 for c in range(run.n_cycles)]
    for i, (name, h) in enumerate(zip(names, idx)):
        ax_mf.plot(run.t, run.fatigued[:, h], color=colors(i % 10), lw=1.2, label=f"{name}: {run.fatigued[-1, h]:.3f} at the end")
        ax_mf.plot(run.t[ends], run.fatigued[ends, h], "o", ms=3, color=colors(i % 10))
        if "muscle_force" in run.extras:
            ax_f.step(run.t[:-1], run.extras["muscle_force"][:, i], where="post", color=colors(i % 10), lw=1, label=name)
    residual = run.tau_plus + run.tau_minus
    for j, joint in enumerate(run.joint_names):
        if "joint_torque" in run.extras:
            ax_tau.step(run.t[:-1], run.extras["joint_torque"][:, j] - residual[:, j], where="post", lw=1.2,
                        color=colors(j % 10), label=f"{joint}: muscles")
        ax_tau.step(run.t[:-1], residual[:, j], where="post", lw=1, ls="--", color=colors(j % 10), label=f"{joint}: residual")
    ax_mf.set_ylabel("fatigued fraction (-)")
    ax_f.set_ylabel("tendon force (N)")
    ax_tau.set_ylabel("joint torque (N m)")
    ax_tau.set_xlabel("time (s)")
    for ax in (ax_mf, ax_f, ax_tau):
        ax.grid(alpha=0.3)
        if ax.lines:
            ax.legend(fontsize=7, ncol=3)
    fig.suptitle(_title(run), fontsize=9)
    fig.tight_layout()
    return _save(fig, out_dir, f"{run_prefix(run)}_muscles")


def motor_limits(run: RunResult) -> np.ndarray:
    """Each motor's winding limit ``T_max - margin`` (deg C), (motors,), from the run's
    ``motors`` attribute."""
    table = json.loads(str(run.attrs.get("motors", "{}")))
    return np.array([table[j]["T_max"] - table[j]["margin"] for j in run.actuator_names])


def cycle_rms_torques(run: RunResult) -> np.ndarray:
    """Each unit's root-mean-square torque over every cycle (N m), (cycles, units)."""
    tau = run.half_torques()
    intervals = [slice(s.start, s.stop - 1) for s in map(run.cycle_slice, range(run.n_cycles))]  # nodes -> intervals
    return np.array([np.sqrt(np.mean(tau[i] ** 2, axis=0)) for i in intervals])


def plot_motors(run: RunResult, out_dir: Path) -> list[Path]:
    """A motor run's heat: each winding's temperature over the run against its limit
    ``T_max - margin`` (dashed), each housing's (dotted), and each joint's RMS torque per cycle
    (N m): how the joints share the work as they warm."""
    fig = _figure(figsize=(12, 7))
    ax_T, ax_tau = fig.subplots(2, 1)
    colors = matplotlib.colormaps["tab10"]
    t = run.t[:-1]  # the temperatures are stored at the start of every interval
    T_w, T_h, limits = run.extras["winding_C"], run.extras["housing_C"], motor_limits(run)
    rms = cycle_rms_torques(run)
    cycles = np.arange(1, run.n_cycles + 1)
    for k, joint in enumerate(run.actuator_names):
        c = colors(k % 10)
        ax_T.plot(t, T_w[:, k], color=c, lw=1.3, label=f"{joint}: {T_w[:, k].max():.1f} / {limits[k]:.1f} C")
        ax_T.plot(t, T_h[:, k], color=c, lw=0.8, ls=":")
        ax_T.axhline(limits[k], color=c, lw=0.8, ls="--")
        ax_tau.plot(cycles, rms[:, k], "o-", ms=3, color=c, label=joint)
    ax_T.set_ylabel("winding (solid), housing (dotted) (deg C)")
    ax_T.set_xlabel("time (s)")
    ax_tau.set_ylabel("RMS torque in the cycle (N m)")
    ax_tau.set_xlabel("cycle")
    for ax in (ax_T, ax_tau):
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, ncol=3)
    fig.suptitle(_title(run), fontsize=9)
    fig.tight_layout()
    return _save(fig, out_dir, f"{run_prefix(run)}_motors")


def plot_run(run: RunResult, out_dir: Path) -> list[Path]:
    """Every per-run figure of ``run`` (ResultFileError for a run without a cycle); a muscle run
    adds :func:`plot_muscles`, a motor run :func:`plot_motors`."""
    run.require_cycles("plot")
    paths: list[Path] = []
    for plot in (plot_joint_angles, plot_fatigue_states, plot_torque_limits, plot_cycle_costs, plot_solve_time):
        paths += plot(run, out_dir)
    if run.muscle_names:
        paths += plot_muscles(run, out_dir)
    if run.actuation == "motors" and "winding_C" in run.extras:
        paths += plot_motors(run, out_dir)
    return paths


def peak_torques(run: RunResult) -> np.ndarray:
    """Largest |tau| of every half within each cycle (N m, or N for a prismatic joint; >= 0), (cycles, halves)."""
    tau = np.abs(run.target_loads() * run.signed_limits)
    n = run.n_cycles
    per = tau.shape[0] // max(n, 1)
    return np.array([tau[c * per:(c + 1) * per].max(axis=0) for c in range(n)]).reshape(n, -1)


def plot_capacity(run: RunResult, out_dir: Path, holding: dict[str, float] | None = None,
                  stem: str = "capacity") -> list[Path]:
    """Why a run cannot do one more cycle: for every half, its capacity |(1 - mf) tau_limit| at
    the end of each cycle (N m, or N for a prismatic joint) against the largest |torque| the cycle
    used, and a horizontal line at ``holding[joint]`` (same unit, e.g. the gravity torque at the
    cycle's start posture), if given.
    One panel per half that does any work."""
    lim = run.signed_limits
    peak = peak_torques(run)
    used = [h for h in range(len(run.actuator_names)) if peak[:, h].max() > 1e-3 * abs(lim[h])]
    fig = _figure(figsize=(4.2 * max(len(used), 1), 4))
    axes = np.atleast_1d(fig.subplots(1, max(len(used), 1)))
    cycles = np.arange(1, run.n_cycles + 1)
    for ax, h in zip(axes, used):
        name = run.actuator_names[h]
        cap = np.abs(run.torque_limits[:, h])
        units = run.half_units(h)
        ax.plot(cycles, cap, "o-", ms=3, color="tab:blue", label="capacity at cycle end")
        ax.plot(cycles, peak[:, h], "s-", ms=3, color="tab:red", label="peak |torque| in the cycle")
        joint = name.rpartition("_")[0]
        if holding and joint in holding:
            ax.axhline(abs(holding[joint]), color="k", ls="--", lw=1,
                       label=f"holding {units.effort_name} {abs(holding[joint]):.2f} {units.effort}")
        ax.set_title(f"{name}: {cap[-1]:.3g} {units.effort} left, peak {peak[-1, h]:.3g}", fontsize=9)
        ax.set_xlabel("cycle")
        ax.set_ylabel(f"{units.effort_name} ({units.effort})")
        ax.set_ylim(bottom=0)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(_title(run), fontsize=9)
    fig.tight_layout()
    return _save(fig, out_dir, f"{run_prefix(run)}_{stem}")


# -- per-file figures ----------------------------------------------------------------------------


def plot_comparison(runs: Sequence[RunResult], out_dir: Path) -> list[Path]:
    """Several runs side by side: cycles reached, and the joint positions of each run's last cycle
    (deg for revolute joints, m for prismatic ones, as the first run's joints)."""
    fig = _figure(figsize=(12, 4.5))
    ax_n, *ax_q = fig.subplots(1, 1 + len(runs[0].joint_names))
    names = [r.name for r in runs]
    ax_n.barh(names, [r.n_cycles for r in runs], color=["tab:blue" if r.converged else "tab:red" for r in runs])
    ax_n.set_xlabel("cycles (red: not converged)")
    ax_n.invert_yaxis()
    ax_n.tick_params(axis="y", labelsize=7)
    for r in runs:
        s = r.cycle_slice(r.n_cycles - 1)
        for j, ax in enumerate(ax_q):
            if j < r.q.shape[1]:
                ax.plot(r.t[s] - r.t[s.start], r.joint_units(j).display(r.q[s, j]), label=r.name)
    for j, (ax, joint) in enumerate(zip(ax_q, runs[0].joint_names)):
        ax.set_title(f"{joint}, last cycle", fontsize=10)
        ax.set_xlabel("time in cycle (s)")
        ax.set_ylabel(_position_label(runs[0].joint_units(j)))
        ax.grid(alpha=0.3)
    ax_q[-1].legend(fontsize=6)
    fig.tight_layout()
    return _save(fig, out_dir, "runs_comparison")


def plot_search(name: str, table: np.ndarray, out_dir: Path) -> list[Path]:
    """A max-cycles search: wall time (s) of each attempted number of cycles, converged or not."""
    fig = _figure(figsize=(7, 4))
    ax = fig.subplots()
    ok = table["converged"].astype(bool)
    ax.plot(table["n_cycles"][ok], table["wall_time_s"][ok], "o", color="tab:blue", label="converged")
    ax.plot(table["n_cycles"][~ok], table["wall_time_s"][~ok], "x", color="tab:red", ms=8, label="failed")
    best = int(table["n_cycles"][ok].max()) if ok.any() else None
    ax.set_title(f"search {name}: largest converged = {best}", fontsize=10)
    ax.set_xlabel("cycles in the OCP")
    ax.set_ylabel("wall time (s)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return _save(fig, out_dir, f"search_{run_prefix(name)}")


def png_as_pdf(png: Path) -> Path:
    """A PDF page holding a PNG (raster), for figures drawn elsewhere as PNG only."""
    import matplotlib.image

    img = matplotlib.image.imread(png)
    h, w = img.shape[:2]
    fig = _figure(figsize=(w / DPI, h / DPI))
    ax = fig.add_axes((0, 0, 1, 1))
    ax.imshow(img)
    ax.axis("off")
    pdf = png.with_suffix(".pdf")
    fig.savefig(pdf, dpi=DPI)
    return pdf


def plot_file(path: Path, out_dir: Path) -> list[Path]:
    """Every applicable figure of a result file: per run (and a comparison when there are
    several), per max-cycles search, or a sweep's folder. Returns the files written. Runs
    without a cycle (a sliding run whose first window failed) have no figure; a file of only
    such runs is a ResultFileError."""
    path = Path(path)
    if path.is_dir() and (path / "summary.csv").is_file():  # a sweep's output folder
        from fatigue_pin.viz.sweeps import plot_sweep

        return plot_sweep(path, out_dir)
    runs = list_runs(path)  # also checks that the file is readable HDF5
    if runs:
        loaded = [read_run(path, name) for name in runs]
        with_cycles = [run for run in loaded if run.n_cycles > 0]  # a sliding run whose first window failed has none
        if not with_cycles and not any(len(t) for t in read_search(path).values()):
            loaded[0].require_cycles("plot")
        loaded = with_cycles
        paths: list[Path] = []
        for run in loaded:
            paths += plot_run(run, out_dir)
            if run.attrs.get("horizon") == "mpc":  # a closed loop: plant, estimate, prediction
                from fatigue_pin.viz.mpc import plot_mpc

                paths += plot_mpc(run, out_dir)
        if len(loaded) > 1:
            paths += plot_comparison(loaded, out_dir)
        for name, table in read_search(path).items():
            if len(table):
                paths += plot_search(name, table, out_dir)
        return paths
    searches = [p for name, table in read_search(path).items() if len(table) for p in plot_search(name, table, out_dir)]
    if searches:
        return searches
    raise ResultFileError(f"{str(path)!r} holds neither OCP runs nor max-cycles searches")
