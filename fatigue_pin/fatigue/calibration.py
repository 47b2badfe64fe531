"""Fit Xia's 3CC (F, R) or 3CC-r (F, R, r) to measured endurance times.

Data: a CSV file (UTF-8, a byte-order mark allowed; separated by commas, or by ``;`` with decimal
commas or by tabs, as Excel writes them; each column once) with columns ``target_load`` (fraction of maximum, in (0, 1)) and
``endurance_time_s`` (s, > 0), and optionally ``duty_cycle`` (in (0, 1]; 1 or empty: sustained) and
``cycle_s`` (s, > 0; needed when ``duty_cycle < 1``). Each row is one task's endurance time.

Model of a row (Xia's 3CC with instant activation, see :mod:`fatigue_pin.fatigue.endurance`):

* sustained: the closed form ``ET = -ln(1 - R (1 - TL) / (F TL)) / R``;
* intermittent: the exact cycle-by-cycle solution of the same model with the rest multiplier ``r``
  (:func:`~fatigue_pin.fatigue.endurance.intermittent_et_closed_form`), or, with ``intermittent="ode"``,
  the ODE simulation with the given ``LD``, ``LR`` (:func:`~fatigue_pin.fatigue.endurance.endurance_time`).

Fit: ``scipy.optimize.least_squares`` on ``log(ET_data) - log(ET_model)`` over the logarithms of
the parameters (so they stay > 0), started from the best point of a coarse grid. Confidence
intervals: the linearised covariance ``s^2 (J^T J)^-1`` with ``s^2 = SSR / (n - p)`` in log-parameter
space, Student-t quantile with ``n - p`` degrees of freedom, mapped back with ``exp`` (so the
intervals are asymmetric). The result is written as JSON usable as a preset
(``fatigue_pin.fatigue.presets.load_preset_json``).
"""

from __future__ import annotations

import datetime
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from fatigue_pin.fatigue.endurance import endurance_time, intermittent_et_closed_form, sustained_et_closed_form
from fatigue_pin.core.errors import CalibrationDataError
from fatigue_pin.core.files import atomic_write_bytes, check_output_file, csv_number, read_csv_table
from fatigue_pin.core.settings import check_fields, default_of, is_number, replaced, setting
from fatigue_pin.fatigue.models import XiaFatigue
from fatigue_pin.core.text import shown

__all__ = [
    "CalibrationDataError",
    "EnduranceData",
    "CalibrationResult",
    "CalibrationSettings",
    "MODELS",
    "read_endurance_csv",
    "predict",
    "calibrate",
    "plot_calibration",
    "check_output_file",
    "run_calibrate",
]

#: Calibrated model -> its fitted parameters.
MODELS: dict[str, tuple[str, ...]] = {"3cc": ("F", "R"), "3cc-r": ("F", "R", "r")}
_COLUMNS = ("target_load", "endurance_time_s", "duty_cycle", "cycle_s")
_LOG_LIMIT = 200.0  # the fit's log-parameters stay in [-200, 200] (exp of them is finite)
_BIG_ET = 1e9  # s: stands for an infinite predicted endurance time inside the residuals
#: Endurance times the fit accepts (s): from a millisecond (rates F ~ 1 / ET stay far from overflow)
#: up to ``_BIG_ET`` (which stands for an infinite time).
ET_RANGE = (1e-3, _BIG_ET)
#: How intermittent rows are predicted: the exact instant-activation cycles, or the ODE with LD, LR.
INTERMITTENT = ("closed-form", "ode")


@dataclass(frozen=True)
class CalibrationSettings:
    """How :func:`calibrate` fits (the options of ``fatigue-pin calibrate``, whose defaults are these).

    Attributes:
        model: the model fitted, a key of :data:`MODELS` (``3cc``: F, R; ``3cc-r``: F, R, r).
        LD: development factor written with the result, used by ``intermittent = "ode"`` (1/s).
        LR: relaxation factor written with the result, used by ``intermittent = "ode"`` (1/s).
        confidence: level of the confidence intervals, in (0, 1).
        intermittent: how intermittent rows are predicted (:data:`INTERMITTENT`).
    """

    model: str = setting("3cc", f"one of {sorted(MODELS)}", lambda v: v in MODELS)
    LD: float = setting(10.0, "a finite rate >= 0 (1/s)", lambda v: is_number(v) and v >= 0)
    LR: float = setting(10.0, "a finite rate >= 0 (1/s)", lambda v: is_number(v) and v >= 0)
    confidence: float = setting(0.95, "a level in (0, 1), e.g. 0.95", lambda v: is_number(v) and 0 < v < 1)
    intermittent: str = setting("closed-form", " or ".join(repr(k) for k in INTERMITTENT), lambda v: v in INTERMITTENT)

    def __post_init__(self) -> None:
        check_fields(self)


@dataclass(frozen=True)
class EnduranceData:
    """Endurance times of tasks, one entry per task.

    Attributes:
        target_load: target loads (fraction of maximum), shape (n,).
        endurance_time_s: measured endurance times (s), shape (n,).
        duty_cycle: duty cycles, shape (n,) (1: sustained).
        cycle_s: cycle lengths (s), shape (n,) (NaN for sustained rows).
        source: where the data come from (a file name).
    """

    target_load: np.ndarray
    endurance_time_s: np.ndarray
    duty_cycle: np.ndarray
    cycle_s: np.ndarray
    source: str = ""

    @classmethod
    def from_arrays(
        cls,
        target_load: Sequence[float],
        endurance_time_s: Sequence[float],
        duty_cycle: Sequence[float] | None = None,
        cycle_s: Sequence[float] | None = None,
        source: str = "",
    ) -> "EnduranceData":
        """Build and validate (raises :class:`CalibrationDataError`)."""
        tl = np.asarray(target_load, dtype=float).reshape(-1)
        n = tl.size
        et = np.asarray(endurance_time_s, dtype=float).reshape(-1)
        dc = np.ones(n) if duty_cycle is None else np.asarray(duty_cycle, dtype=float).reshape(-1)
        cs = np.full(n, np.nan) if cycle_s is None else np.asarray(cycle_s, dtype=float).reshape(-1)
        for name, a in (("endurance_time_s", et), ("duty_cycle", dc), ("cycle_s", cs)):
            if a.size != n:
                raise CalibrationDataError(f"{name} has {a.size} entries: expected {n}, one per target_load")
        dc = np.where(np.isnan(dc), 1.0, dc)
        for i in range(n):
            _check_row(i + 1, tl[i], et[i], dc[i], cs[i], source)
        return cls(tl, et, dc, np.where(dc < 1.0, cs, np.nan), source)

    @property
    def n(self) -> int:
        return int(self.target_load.size)

    @property
    def intermittent(self) -> np.ndarray:
        """Rows with ``duty_cycle < 1``, boolean shape (n,)."""
        return self.duty_cycle < 1.0


def _where(row: int, source: str) -> str:
    return f"{source}: row {row}" if source else f"row {row}"


def _check_row(row: int, tl: float, et: float, dc: float, cs: float, source: str) -> None:
    at = _where(row, source)
    tl, et, dc, cs = float(tl), float(et), float(dc), float(cs)
    if not (math.isfinite(tl) and 0.0 < tl <= 1.0):
        raise CalibrationDataError(f"{at}: target_load = {tl!r}: expected a fraction of maximum in (0, 1]")
    if tl == 1.0:
        raise CalibrationDataError(
            f"{at}: target_load = 1.0: the 3CC with instant activation predicts ET = 0 at TL = 1 (any fatigue stops the "
            "task), so it cannot be fitted; expected a load < 1"
        )
    if not (math.isfinite(et) and ET_RANGE[0] <= et < ET_RANGE[1]):
        raise CalibrationDataError(f"{at}: endurance_time_s = {et!r}: expected a time in [{ET_RANGE[0]:g}, {ET_RANGE[1]:g}) s "
                                   "(beyond it the fit's rates over- or underflow)")
    if not (math.isfinite(dc) and 0.0 < dc <= 1.0):
        raise CalibrationDataError(f"{at}: duty_cycle = {shown(dc)}: expected a fraction in (0, 1] (1 or empty: sustained)")
    if dc < 1.0 and not (math.isfinite(cs) and cs > 0.0):
        raise CalibrationDataError(f"{at}: cycle_s = {shown(cs)} with duty_cycle {shown(dc)}: expected a cycle length > 0 (s)")


def read_endurance_csv(path: str | Path) -> EnduranceData:
    """Read and validate an endurance CSV file (see the module docstring for the columns).

    Raises:
        CalibrationDataError: missing file or column, an unparsable or bad value (the message names
            the row, the column and the value).
    """
    p = Path(path)
    header, rows, delimiter = read_csv_table(p, "endurance data")
    twice = sorted({h for h in header if header.count(h) > 1})
    if twice:
        raise CalibrationDataError(f"{p.name}: column(s) {twice} appear more than once (columns: {header}): expected each column once")
    for col in _COLUMNS[:2]:
        if col not in header:
            raise CalibrationDataError(
                f"{p.name}: missing column {col!r} (columns: {header}): expected target_load, endurance_time_s "
                "[, duty_cycle, cycle_s]"
            )
    unknown = [h for h in header if h not in _COLUMNS]
    if unknown:
        raise CalibrationDataError(f"{p.name}: unknown column(s) {unknown}: expected some of {list(_COLUMNS)}")
    values: dict[str, list[float]] = {c: [] for c in _COLUMNS}
    for i, row in enumerate(rows, start=1):
        for col in _COLUMNS:
            text = row.get(col, "")
            if text == "" and col in ("duty_cycle", "cycle_s"):
                values[col].append(math.nan)
                continue
            values[col].append(csv_number(text, delimiter, f"{p.name}: row {i}: {col}"))
    if not rows:
        raise CalibrationDataError(f"{p.name}: no data rows: expected one row per task")
    return EnduranceData.from_arrays(values["target_load"], values["endurance_time_s"], values["duty_cycle"],
                                     values["cycle_s"], source=p.name)


# -- model --------------------------------------------------------------------------------------------


def predict(params: dict[str, float], data: EnduranceData, settings: CalibrationSettings | None = None) -> np.ndarray:
    """Predicted endurance times (s) of the tasks of ``data`` for ``params`` (``F``, ``R``, optional
    ``r``); intermittent rows as ``settings.intermittent`` says (with its LD, LR for ``ode``)."""
    settings = settings or CalibrationSettings()
    intermittent, LD, LR = settings.intermittent, settings.LD, settings.LR
    F, R, r = params["F"], params["R"], params.get("r", 1.0)
    out = np.empty(data.n)
    for i in range(data.n):
        tl, dc, cs = data.target_load[i], data.duty_cycle[i], data.cycle_s[i]
        if dc == 1.0:
            out[i] = sustained_et_closed_form(F, R, tl)
        elif intermittent == "ode":
            model = XiaFatigue(LD=LD, LR=LR, F=F, R=R, S=0.0, r=r)
            out[i] = endurance_time(model, tl, dc, cs, rtol=1e-6, atol=1e-9)
        else:
            out[i] = intermittent_et_closed_form(F, R, tl, dc, cs, r)
    return out


def _residuals(x: np.ndarray, names: tuple[str, ...], data: EnduranceData, **kw) -> np.ndarray:
    params = dict(zip(names, np.exp(np.clip(x, -_LOG_LIMIT, _LOG_LIMIT))))
    try:
        with np.errstate(all="ignore"):
            et = predict(params, data, **kw)
    except ArithmeticError:  # a step of the fit far out of range: an infinite predicted time
        et = np.full(data.n, _BIG_ET)
    et = np.where(np.isfinite(et) & (et > 0), et, _BIG_ET)
    return np.log(data.endurance_time_s) - np.log(np.minimum(et, _BIG_ET))


def _start(names: tuple[str, ...], data: EnduranceData, **kw) -> np.ndarray:
    """Best point of a coarse grid: F around the no-recovery estimate (1 - TL) / (TL ET), R / F
    below the largest value that keeps every sustained prediction finite, r in 1..30."""
    tl, et = data.target_load, data.endurance_time_s
    F0 = float(np.median((1.0 - tl) / (tl * et)))
    rho_max = float(np.min(tl / (1.0 - tl)))  # R / F must stay below TL / (1 - TL) for a finite ET
    best, best_x = math.inf, None
    for f in F0 * np.geomspace(0.2, 5.0, 15):
        for rho in rho_max * np.geomspace(1e-3, 0.98, 15):
            for r in ((1.0, 3.0, 10.0, 30.0) if "r" in names else (1.0,)):
                x = np.log([f, rho * f, r][: len(names)])
                ssr = float(np.sum(_residuals(x, names, data, **kw) ** 2))
                if ssr < best:
                    best, best_x = ssr, x
    return best_x


@dataclass
class CalibrationResult:
    """Fitted parameters of Xia's 3CC (``F``, ``R``) or 3CC-r (and ``r``).

    Attributes:
        model: ``"3cc"`` or ``"3cc-r"``.
        params: fitted values, e.g. ``{"F": ..., "R": ...}`` (1/s; ``r`` dimensionless).
        LD, LR: controller factors written with the result (not fitted) (1/s).
        confidence: level of the intervals (e.g. 0.95).
        ci: parameter -> (low, high), or None where undefined (``n == p`` or singular Jacobian).
        se_log: standard errors of the log-parameters, or None.
        residuals_log: ``log(ET_data) - log(ET_fit)`` per row.
        et_fit: fitted endurance times (s) per row.
        data: the data fitted.
        success, message, nfev: as reported by ``least_squares``.
        intermittent: how intermittent rows were predicted (``"closed-form"`` or ``"ode"``).
    """

    model: str
    params: dict[str, float]
    LD: float
    LR: float
    confidence: float
    ci: dict[str, tuple[float, float] | None]
    se_log: dict[str, float] | None
    residuals_log: np.ndarray
    et_fit: np.ndarray
    data: EnduranceData
    success: bool
    message: str
    nfev: int
    intermittent: str = default_of(CalibrationSettings, "intermittent")
    notes: list[str] = field(default_factory=list)

    @property
    def dof(self) -> int:
        return self.data.n - len(self.params)

    @property
    def rms_log(self) -> float:
        return float(np.sqrt(np.mean(self.residuals_log**2)))

    def fatigue_model(self) -> XiaFatigue:
        """The fitted model (S = 0)."""
        return XiaFatigue(LD=self.LD, LR=self.LR, F=self.params["F"], R=self.params["R"], S=0.0,
                          r=self.params.get("r", 1.0))

    def to_dict(self) -> dict:
        """The JSON content: ``model``, parameters at the top level (a preset), then the fit's details."""
        d: dict = {"model": self.model}
        d.update({k: float(v) for k, v in self.params.items()})
        d.update({"LD": self.LD, "LR": self.LR, "S": 0.0})
        if "r" not in self.params:
            d["r"] = 1.0
        d["confidence_level"] = self.confidence
        d["confidence_intervals"] = {k: (None if v is None else [float(v[0]), float(v[1])]) for k, v in self.ci.items()}
        d["standard_errors_log"] = None if self.se_log is None else {k: float(v) for k, v in self.se_log.items()}
        d["n_points"] = self.data.n
        d["dof"] = self.dof
        d["rms_log_residual"] = self.rms_log
        d["data"] = {
            "source": self.data.source,
            "target_load": self.data.target_load.tolist(),
            "endurance_time_s": self.data.endurance_time_s.tolist(),
            "duty_cycle": self.data.duty_cycle.tolist(),
            "cycle_s": [None if not np.isfinite(c) else float(c) for c in self.data.cycle_s],
        }
        d["et_fit_s"] = [None if not np.isfinite(e) else float(e) for e in self.et_fit]
        d["residuals_log"] = self.residuals_log.tolist()
        d["method"] = (
            "scipy.optimize.least_squares on log(ET); sustained rows: closed form of 3CC with instant activation; "
            f"intermittent rows: {self.intermittent}; CIs: linearised, Student-t with n - p dof, in log-parameter space"
        )
        d["success"] = self.success
        d["message"] = self.message
        d["notes"] = list(self.notes)
        d["source"] = (
            f"fatigue_pin calibration of {self.model} to {self.data.source or 'endurance data'} "
            f"({datetime.datetime.now(datetime.timezone.utc).isoformat(timespec='seconds')}); LD, LR not fitted"
        )
        return d

    def write_json(self, path: str | Path) -> Path:
        return atomic_write_bytes(Path(path), (json.dumps(self.to_dict(), indent=2) + "\n").encode())


def calibrate(data: EnduranceData, settings: CalibrationSettings | None = None, **changes: Any) -> CalibrationResult:
    """Fit the model of ``settings`` (:class:`CalibrationSettings`, with ``changes`` to its fields
    by name, e.g. ``model="3cc-r"``) to ``data``; see the module docstring.

    Raises:
        CalibrationDataError: fewer rows than parameters, or ``3cc-r`` without intermittent rows.
        ParameterError: unknown model or ``intermittent`` option, bad LD, LR or confidence.
    """
    settings = replaced(CalibrationSettings, settings, changes)
    model, confidence, intermittent = settings.model, settings.confidence, settings.intermittent
    names = MODELS[model]
    if data.n < len(names):
        raise CalibrationDataError(
            f"{data.n} data row(s) for the {model} model: expected at least {len(names)} (one per parameter {list(names)})"
        )
    if model == "3cc-r" and not data.intermittent.any():
        raise CalibrationDataError(
            "3cc-r model with sustained tasks only: r acts during rests and cannot be fitted; expected rows with "
            "duty_cycle < 1 (or use --model 3cc)"
        )
    from scipy.optimize import least_squares  # here, not at import: scipy.optimize and .stats take 1.4 s, and every
    from scipy.stats import t as student_t      # command line builds its parser from this module's settings

    kw = dict(settings=settings)
    x0 = _start(names, data, **kw)
    diff_step = 1e-6 if intermittent == "closed-form" and not data.intermittent.any() else 1e-4
    try:
        with np.errstate(all="ignore"):
            sol = least_squares(_residuals, x0, args=(names, data), kwargs=kw, method="trf", diff_step=diff_step,
                                x_scale=1.0, xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=2000)
    except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
        raise CalibrationDataError(f"the {model} fit to {data.source or 'the endurance data'} failed ({exc}); "
                                   "expected endurance times a 3CC model can reach with finite rates") from None
    if not np.all(np.isfinite(sol.x)) or not np.all(np.isfinite(sol.fun)):
        raise CalibrationDataError(f"the {model} fit to {data.source or 'the endurance data'} ended at non-finite parameters "
                                   f"{dict(zip(names, np.exp(sol.x).tolist()))}; expected data a 3CC model can reach with finite rates")
    params = dict(zip(names, (float(v) for v in np.exp(sol.x))))
    et_fit = predict(params, data, **kw)
    res = sol.fun
    n, p = data.n, len(names)
    notes: list[str] = []
    ci: dict[str, tuple[float, float] | None] = {k: None for k in names}
    se_log = None
    if n > p:
        J = sol.jac
        s2 = float(res @ res) / (n - p)
        try:
            cov = s2 * np.linalg.inv(J.T @ J)
            se = np.sqrt(np.diag(cov))
            if not np.all(np.isfinite(se)):
                raise np.linalg.LinAlgError("non-finite covariance")
            q = float(student_t.ppf(0.5 + confidence / 2.0, n - p))
            se_log = dict(zip(names, (float(v) for v in se)))
            ci = {k: (float(np.exp(sol.x[i] - q * se[i])), float(np.exp(sol.x[i] + q * se[i]))) for i, k in enumerate(names)}
        except np.linalg.LinAlgError:
            notes.append("J^T J is singular at the solution: the parameters are not identifiable from these data; no CIs")
    else:
        notes.append(f"{n} rows for {p} parameters: the fit interpolates the data and has no residual dof; no CIs")
    if not np.all(np.isfinite(et_fit)):
        notes.append("some fitted endurance times are infinite (the fatigued fraction settles below 1 - TL)")
    return CalibrationResult(model, params, float(settings.LD), float(settings.LR), float(confidence), ci, se_log, res.copy(), et_fit,
                             data, bool(sol.success), str(sol.message), int(sol.nfev), intermittent, notes)


# -- figure and files ---------------------------------------------------------------------------------


def plot_calibration(result: CalibrationResult, path: str | Path) -> Path:
    """Log-log figure: measured endurance times vs target load, the fitted curve (sustained) and
    the fitted values of the intermittent rows (PNG)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.5, 5))
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    d = result.data
    sus = ~d.intermittent
    F, R = result.params["F"], result.params["R"]
    fine = np.linspace(max(0.02, d.target_load.min() * 0.8), min(0.99, d.target_load.max() * 1.05), 200)
    if sus.any():
        ax.loglog(d.target_load[sus], d.endurance_time_s[sus], "o", color="C0", label="data, sustained")
    ax.loglog(fine, sustained_et_closed_form(F, R, fine), "-", color="C0", lw=1.2, label=f"fit, sustained (F = {F:.4g}, R = {R:.4g})")
    if d.intermittent.any():
        it = d.intermittent
        ax.loglog(d.target_load[it], d.endurance_time_s[it], "s", color="C1", label="data, intermittent")
        ax.loglog(d.target_load[it], result.et_fit[it], "x", color="C1", ms=9,
                  label="fit, intermittent" + (f" (r = {result.params['r']:.3g})" if "r" in result.params else ""))
    ax.set_xlabel("target load TL (fraction of maximum)")
    ax.set_ylabel("endurance time (s)")
    ax.set_title(f"{result.model} fit, RMS log residual {result.rms_log:.3g}")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out, dpi=120)
    return out


def run_calibrate(data_csv: str | Path, out_json: str | Path, settings: CalibrationSettings | None = None,
                  **changes: Any) -> tuple[CalibrationResult, dict[str, Path]]:
    """Read ``data_csv``, fit (:func:`calibrate` with ``settings`` and ``changes``), write
    ``out_json`` and ``<out_json stem>.png`` beside it (settings and output checked first)."""
    settings = replaced(CalibrationSettings, settings, changes)
    out = check_output_file(out_json, ".json")
    data = read_endurance_csv(data_csv)
    result = calibrate(data, settings)
    paths = {"json": result.write_json(out), "png": plot_calibration(result, out.with_suffix(".png"))}
    return result, paths
