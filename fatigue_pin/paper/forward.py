"""Forward studies of the 3CC / 3CC-S fatigue model (paper section 2).

* Study 1: Xia's 3CC and the stabilised 3CC-S (S = 10) from the rested state (0, 1, 0): they give
  the same trajectories (RMSE, differences at the final time).
* Study 2: 3CC-S with S in {0, 5, 10, 20} from a sum off by +-1e-4, (0, 1.0001, 0) and (0, 0.9999, 0):
  how fast ``|1 - (ma + mr + mf)|`` falls below 1e-5 ... 1e-8, and the state differences at 60 s
  to the run started at (0, 1, 0) with the same S.

Both use the elbow parameters (LD = LR = 10, F = 0.00912, R = 0.00094 1/s), TL = 0.8, 60 s, and
scipy's RK45 with rtol 1e-3 and atol 1e-6, as in the paper. The results are evaluated on a uniform
``t_eval`` grid (scipy's dense output between the integrator's own steps), as the authors' code did
(it used ``np.linspace(0, 60, 100000)``); see ``docs/fatigue.md`` for the comparison.

:func:`run_forward_studies` runs both studies, writes ``forward_studies.h5`` and three PNG figures,
and returns a :class:`ForwardStudiesResult` whose ``table`` sets our numbers beside the paper's.
"""

from __future__ import annotations

import datetime
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from fatigue_pin.core.files import atomic_write
from fatigue_pin.fatigue.models import FatigueParams
from fatigue_pin.fatigue.simulation import FatigueTrajectory, simulate
from fatigue_pin.paper.curl import elbow_params
from fatigue_pin.core.text import shown

if TYPE_CHECKING:
    import h5py

__all__ = [
    "ForwardStudyConfig",
    "Study2Run",
    "ForwardStudiesResult",
    "PAPER_STUDY1",
    "PAPER_STUDY2",
    "PAPER_STUDY2_REMARKS",
    "time_to_precision",
    "time_to_first_precision",
    "rmse",
    "final_abs_error",
    "compute_forward_studies",
    "run_forward_studies",
    "write_h5",
    "plot_forward_studies",
    "format_table",
    "study2_group_name",
]

#: Paper, study 1: RMSE of each state between 3CC and 3CC-S "in the order of 1e-14", final
#: differences "below 1e-14".
PAPER_STUDY1: dict[str, float] = {"rmse_order": 1e-14, "final_abs_error_below": 1e-14}

#: Paper, study 2 (Table 3): (S, mr0) -> (times (s) to precision 1e-5, 1e-6, 1e-7, 1e-8 (NaN:
#: never), (|d ma|, |d mr|, |d mf|) at 60 s). Values as printed (paper section 2).
PAPER_STUDY2: dict[tuple[float, float], tuple[tuple[float, ...], tuple[float, ...]]] = {
    (5.0, 1.0001): ((0.46, 0.92, 1.40, 1.89), (7.04e-5, 2.57e-7, 7.06e-5)),
    (5.0, 0.9999): ((0.46, 0.92, 1.40, 1.89), (7.06e-5, 4.67e-8, 7.06e-5)),
    (10.0, 1.0001): ((0.23, 0.46, 0.70, math.nan), (7.07e-5, 7.21e-8, 7.05e-5)),
    (10.0, 0.9999): ((0.23, 0.46, 0.70, math.nan), (7.04e-5, 2.56e-7, 7.06e-5)),
}

#: Paper, study 2: what it says about the values of S without numbers in its table.
PAPER_STUDY2_REMARKS: dict[float, str] = {
    0.0: "keeps the initial error (no number given)",
    20.0: "oscillates around 1 and diverges; fails to stay within 1e-4 (no number given)",
}

_STATE_KEYS = ("ma", "mr", "mf")


@dataclass(frozen=True)
class ForwardStudyConfig:
    """Settings of the forward studies (defaults: the paper's).

    Attributes:
        params: fatigue parameters except S (elbow values of Looft et al. 2018).
        TL: constant target load (dimensionless).
        t_end: simulated time (s).
        n_eval: number of points of the uniform output grid ``linspace(0, t_end, n_eval)``.
        method, rtol, atol: scipy ``solve_ivp`` integrator and tolerances.
        study1_S: stabiliser of the 3CC-S run of study 1 (1/s).
        study2_S: stabilisers of study 2 (1/s).
        study2_mr0: perturbed initial ``mr`` of study 2 (``ma = mf = 0``).
        precisions: orders of precision of the invariant error.
    """

    params: FatigueParams = field(default_factory=elbow_params)
    TL: float = 0.8
    t_end: float = 60.0
    n_eval: int = 60001
    method: str = "RK45"
    rtol: float = 1e-3
    atol: float = 1e-6
    study1_S: float = 10.0
    study2_S: tuple[float, ...] = (0.0, 5.0, 10.0, 20.0)
    study2_mr0: tuple[float, ...] = (1.0001, 0.9999)
    precisions: tuple[float, ...] = (1e-5, 1e-6, 1e-7, 1e-8)

    @property
    def t_eval(self) -> np.ndarray:
        """The output grid (s), shape (n_eval,)."""
        return np.linspace(0.0, self.t_end, self.n_eval)


def time_to_precision(t: np.ndarray, err: np.ndarray, tol: float) -> float:
    """First time after which ``err`` stays below ``tol`` until the end.

    Args:
        t: times (s), shape (n,).
        err: invariant error ``|1 - (ma + mr + mf)|`` at ``t``, shape (n,).
        tol: order of precision.

    Returns:
        The time (s), ``t[0]`` if ``err < tol`` throughout, NaN if ``err`` is not below ``tol`` at the end.
    """
    below = np.asarray(err) < tol
    if not below[-1]:
        return math.nan
    bad = np.flatnonzero(~below)
    return float(t[bad[-1] + 1] if bad.size else t[0])


def time_to_first_precision(t: np.ndarray, err: np.ndarray, tol: float) -> float:
    """First time ``err`` is below ``tol`` (the definition of the authors' code), NaN if never (s)."""
    idx = np.flatnonzero(np.asarray(err) < tol)
    return float(t[idx[0]]) if idx.size else math.nan


def rmse(a: FatigueTrajectory, b: FatigueTrajectory) -> np.ndarray:
    """Root mean square difference of ``(ma, mr, mf)`` between two runs on the same grid, shape (3,)."""
    return np.sqrt(np.mean((a.m - b.m) ** 2, axis=1))


def final_abs_error(a: FatigueTrajectory, ref: FatigueTrajectory) -> np.ndarray:
    """``(|d ma|, |d mr|, |d mf|)`` at the final time between a run and its reference, shape (3,)."""
    return np.abs(a.m[:, -1] - ref.m[:, -1])


def study2_group_name(S: float, mr0: float) -> str:
    """HDF5 group of a study-2 run, e.g. ``study2/S5_mr1.0001`` (S as ``%g``, mr0 as ``repr``)."""
    return f"study2/S{float(S):g}_mr{float(mr0)!r}"


@dataclass(frozen=True)
class Study2Run:
    """One run of study 2.

    Attributes:
        S: stabiliser (1/s).
        mr0: initial resting state (ma = mf = 0).
        trajectory: the run, on the output grid.
        reference: the run from (0, 1, 0) with the same S, on the same grid.
        time_to_precision: time (s) after which the invariant error stays below each precision (NaN: never).
        time_to_first_precision: first time (s) it is below each precision (NaN: never).
        final_abs_error: ``(|d ma|, |d mr|, |d mf|)`` at the final time vs ``reference``.
        max_error_after_1s: largest invariant error for t >= 1 s.
    """

    S: float
    mr0: float
    trajectory: FatigueTrajectory
    reference: FatigueTrajectory
    time_to_precision: tuple[float, ...]
    time_to_first_precision: tuple[float, ...]
    final_abs_error: tuple[float, float, float]
    max_error_after_1s: float

    @property
    def group(self) -> str:
        """HDF5 group name."""
        return study2_group_name(self.S, self.mr0)


@dataclass(frozen=True)
class ForwardStudiesResult:
    """Everything the forward studies produced.

    Attributes:
        config: the settings.
        study1: ``{"3cc": run with S = 0, "3cc_s": run with S = study1_S}``, both from (0, 1, 0).
        study1_rmse: RMSE of (ma, mr, mf) between the two runs, shape (3,).
        study1_final_abs_error: state differences at the final time, shape (3,).
        study2: the study-2 runs, S-major then mr0 in config order.
        study2_references: S -> run from (0, 1, 0).
        h5_path: the HDF5 file written (None if not written).
        figures: figure name -> PNG path.
    """

    config: ForwardStudyConfig
    study1: dict[str, FatigueTrajectory]
    study1_rmse: np.ndarray
    study1_final_abs_error: np.ndarray
    study2: tuple[Study2Run, ...]
    study2_references: dict[float, FatigueTrajectory]
    h5_path: Path | None = None
    figures: dict[str, Path] = field(default_factory=dict)

    def run(self, S: float, mr0: float) -> Study2Run:
        """The study-2 run with stabiliser ``S`` and initial ``mr0``."""
        for r in self.study2:
            if r.S == float(S) and r.mr0 == float(mr0):
                return r
        raise KeyError(f"no study-2 run with S = {shown(S)}, mr0 = {shown(mr0)}")

    @property
    def table(self) -> str:
        """Our numbers beside the paper's, as a plain-text table."""
        return format_table(self)


# -- running ---------------------------------------------------------------------------------------


def _run(cfg: ForwardStudyConfig, S: float, m0: tuple[float, float, float]) -> FatigueTrajectory:
    tr = simulate(
        cfg.params.with_(S=S), cfg.TL, m0, cfg.t_end, t_eval=cfg.t_eval,
        method=cfg.method, rtol=cfg.rtol, atol=cfg.atol, dense_output=False,
    )
    if not tr.success:
        raise RuntimeError(f"forward run S = {S}, m0 = {m0} failed: {tr.message}")
    return tr


def compute_forward_studies(
    config: ForwardStudyConfig | None = None, progress: Callable[[str], object] | None = print
) -> ForwardStudiesResult:
    """Run studies 1 and 2 in memory (no files)."""
    cfg = config or ForwardStudyConfig()
    say = progress or (lambda _msg: None)

    say(f"study 1: 3CC and 3CC-S (S = {cfg.study1_S:g}) from (0, 1, 0)")
    s1 = {"3cc": _run(cfg, 0.0, (0.0, 1.0, 0.0)), "3cc_s": _run(cfg, cfg.study1_S, (0.0, 1.0, 0.0))}
    s1_rmse = rmse(s1["3cc"], s1["3cc_s"])
    s1_final = final_abs_error(s1["3cc_s"], s1["3cc"])

    refs: dict[float, FatigueTrajectory] = {}
    runs: list[Study2Run] = []
    for S in cfg.study2_S:
        S = float(S)
        say(f"study 2: S = {S:g}")
        refs[S] = _run(cfg, S, (0.0, 1.0, 0.0))
        for mr0 in cfg.study2_mr0:
            tr = _run(cfg, S, (0.0, float(mr0), 0.0))
            err = tr.invariant_error
            late = tr.t >= 1.0
            runs.append(
                Study2Run(
                    S=S,
                    mr0=float(mr0),
                    trajectory=tr,
                    reference=refs[S],
                    time_to_precision=tuple(time_to_precision(tr.t, err, p) for p in cfg.precisions),
                    time_to_first_precision=tuple(time_to_first_precision(tr.t, err, p) for p in cfg.precisions),
                    final_abs_error=tuple(float(x) for x in final_abs_error(tr, refs[S])),
                    max_error_after_1s=float(err[late].max()) if late.any() else math.nan,
                )
            )
    return ForwardStudiesResult(cfg, s1, s1_rmse, s1_final, tuple(runs), refs)


def run_forward_studies(
    out_dir: Path | str,
    progress: Callable[[str], object] | None = print,
    config: ForwardStudyConfig | None = None,
) -> ForwardStudiesResult:
    """Run the forward studies, write ``out_dir/forward_studies.h5`` and the figures.

    Args:
        out_dir: output directory (created if needed).
        progress: called with one line of text per step (``None``: silent).
        config: settings (default: the paper's).

    Returns:
        The results, with ``h5_path``, ``figures`` and ``table`` (our numbers beside the paper's).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    say = progress or (lambda _msg: None)
    res = compute_forward_studies(config, progress)
    h5_path = write_h5(res, out / "forward_studies.h5")
    say(f"wrote {h5_path}")
    figures = plot_forward_studies(res, out)
    for p in figures.values():
        say(f"wrote {p}")
    return ForwardStudiesResult(
        res.config, res.study1, res.study1_rmse, res.study1_final_abs_error, res.study2, res.study2_references,
        h5_path, figures,
    )


# -- HDF5 ----------------------------------------------------------------------------------------


def _write_run(
    h5: h5py.File, name: str, tr: FatigueTrajectory, cfg: ForwardStudyConfig, m0: tuple[float, ...], model: str
) -> h5py.Group:
    """Write one run as group ``name``: datasets t, ma, mr, mf and its configuration as attributes."""
    g = h5.create_group(name)
    for key, data, unit in (("t", tr.t, "s"), ("ma", tr.ma, "1"), ("mr", tr.mr, "1"), ("mf", tr.mf, "1")):
        d = g.create_dataset(key, data=np.asarray(data, dtype=float), compression="gzip", shuffle=True)
        d.attrs["unit"] = unit
    p = tr.params
    g.attrs["model"] = model
    g.attrs["S"] = p.S
    g.attrs["TL"] = float(cfg.TL)
    g.attrs["m0"] = np.asarray(m0, dtype=float)
    g.attrs["LD"] = p.LD
    g.attrs["LR"] = p.LR
    g.attrs["F"] = p.F
    g.attrs["R"] = p.R
    g.attrs["r"] = p.r
    g.attrs["t_end"] = float(cfg.t_end)
    g.attrs["method"] = tr.method
    g.attrs["rtol"] = tr.rtol
    g.attrs["atol"] = tr.atol
    g.attrs["success"] = tr.success
    g.attrs["nfev"] = tr.nfev
    return g


def write_h5(res: ForwardStudiesResult, path: Path | str) -> Path:
    """Write the results to ``path`` (atomic: :func:`fatigue_pin.core.files.atomic_write`). Layout: ``docs/results.md``."""
    import h5py

    from fatigue_pin.core.version import __version__ as version

    path = Path(path)
    cfg = res.config
    def fill(tmp: Path) -> None:
        with h5py.File(tmp, "w") as h5:
            h5.attrs["description"] = "fatigue_pin forward studies of the 3CC / 3CC-S fatigue model (paper section 2)"
            h5.attrs["fatigue_pin_version"] = version
            h5.attrs["created"] = datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")
            h5.attrs["precisions"] = np.asarray(cfg.precisions, dtype=float)
            h5.attrs["time_to_precision_definition"] = (
                "first time after which |1 - (ma + mr + mf)| stays below the precision until t_end; NaN if never"
            )
            h5.attrs["n_eval"] = int(cfg.n_eval)

            rest = (0.0, 1.0, 0.0)
            for key, model in (("3cc", "3CC"), ("3cc_s", "3CC-S")):
                g = _write_run(h5, f"study1/{key}", res.study1[key], cfg, rest, model)
                g.attrs["rmse"] = np.asarray(res.study1_rmse, dtype=float)
                g.attrs["final_abs_error"] = np.asarray(res.study1_final_abs_error, dtype=float)

            for S, ref in res.study2_references.items():
                g = _write_run(h5, study2_group_name(S, 1.0), ref, cfg, rest, "3CC-S")
                g.attrs["role"] = "reference"
                err = ref.invariant_error
                g.attrs["time_to_precision"] = np.array([time_to_precision(ref.t, err, p) for p in cfg.precisions])
                g.attrs["time_to_first_precision"] = np.array(
                    [time_to_first_precision(ref.t, err, p) for p in cfg.precisions]
                )
                g.attrs["final_abs_error"] = np.zeros(3)
            for run in res.study2:
                g = _write_run(h5, run.group, run.trajectory, cfg, (0.0, run.mr0, 0.0), "3CC-S")
                g.attrs["role"] = "perturbed"
                g.attrs["reference"] = study2_group_name(run.S, 1.0)
                g.attrs["time_to_precision"] = np.asarray(run.time_to_precision, dtype=float)
                g.attrs["time_to_first_precision"] = np.asarray(run.time_to_first_precision, dtype=float)
                g.attrs["final_abs_error"] = np.asarray(run.final_abs_error, dtype=float)
                g.attrs["max_error_after_1s"] = run.max_error_after_1s
    atomic_write(path, fill)
    return path


# -- figures -------------------------------------------------------------------------------------

_COLORS = {"ma": "#00cc96", "mr": "#ffa15a", "mf": "#ef553b"}


def plot_forward_studies(res: ForwardStudiesResult, out_dir: Path | str) -> dict[str, Path]:
    """Save ``study1_states.png``, ``study2_states.png`` and ``study2_invariant_error.png`` in ``out_dir``."""
    # The object-oriented API with an explicit Agg canvas: no pyplot state, no global backend switch.
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    def new_figure(**kwargs: object) -> Figure:
        fig = Figure(**kwargs)
        FigureCanvasAgg(fig)
        return fig

    out = Path(out_dir)
    cfg = res.config
    paths: dict[str, Path] = {}

    # Study 1: states of both models.
    fig = new_figure(figsize=(10, 4.5))
    ax = fig.subplots()
    for key, style, label in (("3cc", "-", "3CC"), ("3cc_s", "--", f"3CC-S (S = {cfg.study1_S:g})")):
        tr = res.study1[key]
        for s in _STATE_KEYS:
            ax.plot(tr.t, getattr(tr, s), style, color=_COLORS[s], label=f"{s}, {label}")
        ax.plot(tr.t, tr.total, style, color="k", lw=0.8, label=f"ma + mr + mf, {label}")
    ax.axhline(cfg.TL, color="tab:blue", lw=2, alpha=0.5, label="TL")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("fraction of capacity (-)")
    ax.set_title(f"Study 1: 3CC vs 3CC-S from (0, 1, 0), TL = {cfg.TL:g}")
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.tight_layout()
    paths["study1_states"] = out / "study1_states.png"
    fig.savefig(paths["study1_states"], dpi=120)

    # Study 2: states, one panel per S.
    S_values = list(res.study2_references)
    fig = new_figure(figsize=(10, 2.4 * len(S_values)))
    axes = fig.subplots(len(S_values), 1, sharex=True, squeeze=False)
    styles = ["-", "--", ":", "-."]
    for ax, S in zip(axes[:, 0], S_values):
        runs = [r for r in res.study2 if r.S == S]
        for k, run in enumerate(runs):
            tr = run.trajectory
            for s in _STATE_KEYS:
                ax.plot(tr.t, getattr(tr, s), styles[k % 4], color=_COLORS[s], label=f"{s}, mr0 = {run.mr0!r}")
        ax.axhline(cfg.TL, color="tab:blue", lw=2, alpha=0.5)
        ax.set_ylabel("fraction (-)")
        ax.set_title(f"S = {S:g} 1/s", fontsize=9)
    axes[0, 0].legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    axes[-1, 0].set_xlabel("time (s)")
    fig.suptitle("Study 2: 3CC-S states from (0, 1 +- 1e-4, 0)")
    fig.tight_layout()
    paths["study2_states"] = out / "study2_states.png"
    fig.savefig(paths["study2_states"], dpi=120)

    # Study 2: invariant error on a log scale, one panel per S.
    floor = 1e-17
    fig = new_figure(figsize=(8, 2.4 * len(S_values)))
    axes = fig.subplots(len(S_values), 1, sharex=True, squeeze=False)
    for ax, S in zip(axes[:, 0], S_values):
        for k, run in enumerate(r for r in res.study2 if r.S == S):
            tr = run.trajectory
            ax.semilogy(tr.t, np.maximum(tr.invariant_error, floor), styles[k % 4], lw=0.8, label=f"mr0 = {run.mr0!r}")
        ref = res.study2_references[S]
        ax.semilogy(ref.t, np.maximum(ref.invariant_error, floor), color="0.6", lw=0.8, label="mr0 = 1.0")
        for p in cfg.precisions:
            ax.axhline(p, color="0.8", lw=0.6, ls=":")
        ax.set_ylim(floor, 1e-2)
        ax.set_ylabel("|1 - sum| (-)")
        ax.set_title(f"S = {S:g} 1/s", fontsize=9)
        ax.legend(fontsize=7, loc="upper right")
    axes[-1, 0].set_xlabel("time (s)")
    fig.suptitle(f"Study 2: |1 - (ma + mr + mf)| (RK45, rtol {cfg.rtol:g}, atol {cfg.atol:g}; floor {floor:g})")
    fig.tight_layout()
    paths["study2_invariant_error"] = out / "study2_invariant_error.png"
    fig.savefig(paths["study2_invariant_error"], dpi=120)
    return paths


# -- table ---------------------------------------------------------------------------------------


def _t(x: float) -> str:
    return "never" if math.isnan(x) else f"{x:.3f}"


def _tp(x: float) -> str:
    return "never" if math.isnan(x) else f"{x:.2f}"


def format_table(res: ForwardStudiesResult) -> str:
    """Our forward-study numbers beside the paper's (plain text)."""
    cfg = res.config
    p = cfg.params
    lines = [
        f"Forward studies: TL = {cfg.TL:g}, {cfg.t_end:g} s, scipy {cfg.method} rtol {cfg.rtol:g} atol {cfg.atol:g}, "
        f"LD = {p.LD:g}, LR = {p.LR:g}, F = {p.F:g}, R = {p.R:g} 1/s, output grid {cfg.n_eval} points",
        "",
        f"Study 1: 3CC vs 3CC-S (S = {cfg.study1_S:g}) from (0, 1, 0)",
        f"  {'':8s} {'ma':>10s} {'mr':>10s} {'mf':>10s}",
        "  RMSE     " + " ".join(f"{x:10.2e}" for x in res.study1_rmse) + f"   paper: ~{PAPER_STUDY1['rmse_order']:.0e}",
        "  |d| 60 s " + " ".join(f"{x:10.2e}" for x in res.study1_final_abs_error)
        + f"   paper: < {PAPER_STUDY1['final_abs_error_below']:.0e}",
        "",
        "Study 2: time (s) after which |1 - (ma + mr + mf)| stays below each precision; "
        "|d| at 60 s vs the run from (0, 1, 0)",
        f"  {'S':>3s} {'mr0':>7s} {'':6s}" + "".join(f"{x:>8.0e}" for x in cfg.precisions)
        + f" {'|d ma|':>10s} {'|d mr|':>10s} {'|d mf|':>10s}",
    ]
    for run in res.study2:
        lines.append(
            f"  {run.S:>3g} {run.mr0!r:>7s} {'ours':6s}" + "".join(f"{_t(x):>8s}" for x in run.time_to_precision)
            + "".join(f" {x:10.2e}" for x in run.final_abs_error)
        )
        paper = PAPER_STUDY2.get((run.S, run.mr0))
        if paper is not None:
            times, errs = paper
            lines.append(
                f"  {'':3s} {'':7s} {'paper':6s}" + "".join(f"{_tp(x):>8s}" for x in times)
                + "".join(f" {x:10.2e}" for x in errs)
            )
        elif run.S in PAPER_STUDY2_REMARKS:
            lines.append(f"  {'':3s} {'':7s} {'paper':6s}  {PAPER_STUDY2_REMARKS[run.S]}")
        if any(
            not (math.isnan(a) and math.isnan(b)) and a != b
            for a, b in zip(run.time_to_precision, run.time_to_first_precision)
        ):
            lines.append(
                f"  {'':3s} {'':7s} {'first':6s}" + "".join(f"{_t(x):>8s}" for x in run.time_to_first_precision)
                + "   (first time below; the error comes back above)"
            )
        if run.S >= 20 or run.S == 0:
            lines.append(f"  {'':3s} {'':7s} {'':6s}  max |1 - sum| for t >= 1 s: {run.max_error_after_1s:.2e}")
    return "\n".join(lines)
