"""Maximum endurance time (ET) of isometric tasks predicted by a fatigue model.

**Definition.** A task asks an actuator for a target load ``TL`` (sustained, or during the "on"
part of each cycle of an intermittent task). The actuator can hold ``TL`` as long as its
capacity, the active plus resting fractions ``ma + mr``, is at least ``TL``: in Xia's controller
this is exactly the switch from branch 1 (``mr >= TL - ma``, ``ma`` tracks ``TL``) to branch 2
(``mr < TL - ma``, ``ma`` can only fall). The **endurance time** is the first time at which
``ma + mr < TL`` while the task asks for ``TL``, counted from the start of the task from a rested
actuator (including the rest periods of an intermittent task). It is found with ``solve_ivp``
and a terminal event on ``ma + mr - TL``; any fatigue model with states ``ma`` and ``mr`` works
(Xia's 3CC/3CC-S/3CC-r, Michaud's model).

**Closed forms** (Xia's 3CC with instant activation, ``LD, LR -> infinity``): while holding,
``ma = TL`` and ``dmf/dt = F TL - R mf``, so ``mf(t) = (F TL / R)(1 - exp(-R t))`` and the
capacity ``1 - mf`` reaches ``TL`` at

    ET = -ln(1 - R (1 - TL) / (F TL)) / R        (inf where the argument of ln is <= 0)

For an intermittent task (duty cycle ``d``, cycle ``T``), ``mf`` follows the same exponential
towards ``F TL / R`` during each "on" part and decays like ``exp(-r R t)`` during each rest
(3CC-r: Looft et al.'s rest multiplier ``r``); :func:`intermittent_et_closed_form` solves this
cycle recursion exactly. Finite ``LD`` holds ``ma`` at ``TL LD / (LD + F)`` instead of ``TL`` and
the event fires when ``mr = F TL / (LD + F)`` rather than 0; both shift ET by a relative amount of
order ``F / LD`` (about 1e-3 for LD = 10), see ``docs/fatigue.md`` for measured values.

**Empirical curves.** :data:`FREY_LAW_AVIN_2010`: the pooled power models ``ET = b0 * TL^b1``
(s, TL as a fraction of maximum) of Frey-Law & Avin (2010), Ergonomics 53:109-129,
doi:10.1080/00140130903389068, Table 2, per joint region; the 3CC parameters of Frey-Law, Looft &
Heitsman (2012) were fitted to these curves. The coefficients agree with three independent
transcriptions of the table, MyoSuite's among them (``docs/source/fatigue_validation.rst``,
MyoHub/myosuite at commit 416c185ebc7ee3504500f70d1e8f2d2428c38a6d).
:func:`compare_frey_law_avin` sets them side by side.

Tables as text, the HDF5 file and the figure: :mod:`fatigue_pin.fatigue.endurance_report`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from fatigue_pin.core.errors import FatiguePinError, OutputLocationError, ParameterError
from fatigue_pin.core.progress import Progress, as_reporter
from fatigue_pin.fatigue.interface import FatigueModel
from fatigue_pin.fatigue.models import XiaFatigue
from fatigue_pin.core.text import shown


def _solve_ivp(*args, **kwargs):
    """``scipy.integrate.solve_ivp``, imported at the first call: scipy.integrate takes 0.8 s to
    import, and every command line reads this module (through the calibration's settings)."""
    from scipy.integrate import solve_ivp

    return solve_ivp(*args, **kwargs)


__all__ = [
    "FREY_LAW_AVIN_2010",
    "FREY_LAW_AVIN_SOURCE",
    "DEFAULT_LOADS",
    "MAX_CYCLES",
    "OutputLocationError",
    "sustained_et_closed_form",
    "intermittent_et_closed_form",
    "power_model_et",
    "endurance_time",
    "EnduranceTable",
    "endurance_table",
    "compare_frey_law_avin",
]

#: Frey-Law & Avin (2010) pooled power models ``ET = b0 * TL^b1`` (ET in s, TL in (0, 1]): joint -> (b0, b1).
FREY_LAW_AVIN_2010: dict[str, tuple[float, float]] = {
    "general": (21.92, -1.98),
    "ankle": (34.71, -2.06),
    "trunk": (22.69, -2.27),
    "elbow": (17.98, -2.21),
    "hand": (33.55, -1.61),
    "knee": (19.38, -1.88),
    "shoulder": (14.86, -1.83),
}
FREY_LAW_AVIN_2010["grip"] = FREY_LAW_AVIN_2010["hand"]

FREY_LAW_AVIN_SOURCE = (
    "Frey-Law & Avin (2010), Endurance time is joint-specific: a modelling and meta-analysis investigation, "
    "Ergonomics 53:109-129, doi:10.1080/00140130903389068, pooled power models ET = b0 * TL^b1"
)

#: Most cycles of an intermittent task :func:`endurance_time` simulates (a few ms each).
MAX_CYCLES = 10_000
#: Cycles between two progress lines of :func:`endurance_time`.
PROGRESS_EVERY = 1000

#: Target loads of the tables: 0.1, 0.2, ..., 0.9.
DEFAULT_LOADS: tuple[float, ...] = tuple(round(0.1 * k, 1) for k in range(1, 10))


# -- closed forms ------------------------------------------------------------------------------------


def _check_load(TL: float, who: str) -> float:
    x = float(TL)
    if not (math.isfinite(x) and 0.0 < x <= 1.0):
        raise ParameterError(f"{who}: target load TL = {TL!r}: expected a fraction in (0, 1]")
    return x


def sustained_et_closed_form(F: float, R: float, TL: float | np.ndarray) -> float | np.ndarray:
    """Endurance time (s) of a sustained contraction at ``TL`` for Xia's 3CC with instant activation.

    ``ET = -ln(1 - R (1 - TL) / (F TL)) / R``; ``inf`` where the argument is <= 0 (the fatigued
    fraction settles below ``1 - TL``); ``(1 - TL) / (F TL)`` for ``R = 0``; ``inf`` for ``F = 0``.
    """
    tl = np.asarray(TL, dtype=float)
    F, R = float(F), float(R)
    with np.errstate(divide="ignore", invalid="ignore"):
        if F <= 0.0:
            et = np.full_like(tl, np.inf)
        elif R == 0.0:
            et = (1.0 - tl) / (F * tl)
        else:
            arg = 1.0 - R * (1.0 - tl) / (F * tl)
            et = np.where(arg > 0.0, -np.log1p(-R * (1.0 - tl) / (F * tl)) / R, np.inf)
    return float(et) if et.ndim == 0 else et


def intermittent_et_closed_form(
    F: float, R: float, TL: float, duty_cycle: float = 1.0, cycle_s: float | None = None, r: float = 1.0
) -> float:
    """Endurance time (s, elapsed, rests included) of an intermittent task for 3CC-r with instant activation.

    Each cycle of length ``cycle_s`` starts with ``duty_cycle * cycle_s`` at ``TL`` ("on"), then rests
    at 0. With ``A = F TL / R``: on, ``mf -> A + (mf - A) exp(-R t)``; at rest, ``mf -> mf exp(-r R t)``.
    The start-of-cycle values obey ``s_{k+1} = a s_k + b`` (``a = exp(-R d T - r R (1-d) T)``), so the
    first failing cycle and the time within it are solved exactly. ``duty_cycle = 1`` gives
    :func:`sustained_et_closed_form`.
    """
    TL = _check_load(TL, "intermittent_et_closed_form")
    d = float(duty_cycle)
    if not (math.isfinite(d) and 0.0 < d <= 1.0):
        raise ParameterError(f"intermittent_et_closed_form: duty_cycle = {shown(duty_cycle)}: expected a fraction in (0, 1]")
    if d == 1.0:
        return sustained_et_closed_form(F, R, TL)
    if cycle_s is None or not (math.isfinite(float(cycle_s)) and float(cycle_s) > 0.0):
        raise ParameterError(f"intermittent_et_closed_form: cycle_s = {shown(cycle_s)}: expected a cycle length > 0 (s)")
    T = float(cycle_s)
    F, R, r = float(F), float(R), float(r)
    L = 1.0 - TL  # failure when mf >= L during an "on" part
    if F <= 0.0:
        return math.inf
    if R <= 0.0:
        # No recovery: mf grows by F TL d T per cycle.
        inc = F * TL * d * T  # growth of mf per "on" part
        k = max(0, math.ceil(L / inc) - 1)  # the "on" part in which mf reaches L
        while k > 0 and k * inc >= L:
            k -= 1
        return k * T + (L - k * inc) / (F * TL)
    A = F * TL / R
    if A <= L:
        return math.inf
    e_on = math.exp(-R * d * T)
    e_off = math.exp(-r * R * (1.0 - d) * T)
    a = e_on * e_off
    b = e_off * A * (1.0 - e_on)
    s_star = b / (1.0 - a)
    # Cycle k fails iff its on-end value A + (s_k - A) e_on >= L, i.e. s_k >= s_crit.
    s0 = 0.0
    s_crit = (L - A * (1.0 - e_on)) / e_on if e_on > 0.0 else -math.inf  # e_on = 0: each "on" part reaches A > L
    if s0 >= s_crit:
        k = 0
    elif s_star <= s_crit:
        return math.inf
    else:
        k = max(0, math.ceil(math.log((s_crit - s_star) / (s0 - s_star)) / math.log(a)))
        # Guard the ceil against round-off.
        while k > 0 and s_star + (s0 - s_star) * a ** (k - 1) >= s_crit:
            k -= 1
        while s_star + (s0 - s_star) * a**k < s_crit:
            k += 1
    s_k = s_star + (s0 - s_star) * a**k
    t_in = -math.log((L - A) / (s_k - A)) / R if s_k < L else 0.0
    return k * T + min(t_in, d * T)


def power_model_et(joint: str, TL: float | np.ndarray) -> float | np.ndarray:
    """Frey-Law & Avin (2010) pooled power model ``ET = b0 * TL^b1`` (s) of ``joint``."""
    if joint not in FREY_LAW_AVIN_2010:
        raise ParameterError(f"joint {joint!r} has no Frey-Law & Avin (2010) power model; expected one of {sorted(FREY_LAW_AVIN_2010)}")
    b0, b1 = FREY_LAW_AVIN_2010[joint]
    et = b0 * np.asarray(TL, dtype=float) ** b1
    return float(et) if et.ndim == 0 else et


# -- simulation ---------------------------------------------------------------------------------------


def _fixed_functions(model: FatigueModel, TL: float):
    """Numeric ``f(y)`` and Jacobian ``J(y)`` of the model at constant ``TL``."""
    m = ca.SX.sym("m", model.n_states())
    dm = model.rhs()(m, TL, ca.DM(model.as_vector()))
    f = ca.Function("f", [m], [dm])
    J = ca.Function("J", [m], [ca.jacobian(dm, m)])
    return (lambda t, y: f(y).full().ravel()), (lambda t, y: J(y).full())


def endurance_time(
    model: FatigueModel,
    TL: float,
    duty_cycle: float = 1.0,
    cycle_s: float | None = None,
    t_max: float = 1e5,
    method: str = "LSODA",
    rtol: float = 1e-8,
    atol: float = 1e-10,
    steady_stop: bool = True,
    max_cycles: int = MAX_CYCLES,
    progress: Progress = None,
) -> float:
    """Endurance time (s) of a task at target load ``TL`` by forward simulation of ``model``.

    The actuator starts rested (``model.rest_state()``). Sustained (``duty_cycle = 1``): ``TL`` is
    held from t = 0. Intermittent: each cycle of ``cycle_s`` seconds asks for ``TL`` during its
    first ``duty_cycle * cycle_s`` seconds and 0 during the rest. The result is the first time at
    which ``ma + mr < TL`` during an "on" part (see the module docstring), or ``inf`` if that does
    not happen before ``t_max``. With ``steady_stop``, an intermittent task also returns ``inf``
    once the end-of-"on" margins ``ma + mr - TL`` of successive cycles converge geometrically to a
    limit above 1e-4 (Aitken extrapolation), instead of simulating up to ``t_max``.

    An intermittent task simulates at most ``max_cycles`` cycles (each takes a few milliseconds);
    ``progress`` (a :class:`~fatigue_pin.core.progress.Reporter` or a line callback) receives a
    line every :data:`PROGRESS_EVERY` cycles.

    Raises:
        ParameterError: a bad load, duty cycle, cycle length or ``max_cycles``, a model without
            ``ma``/``mr``, or ``max_cycles`` cycles simulated without failure or a steady state.
    """
    TL = _check_load(TL, "endurance_time")
    d = float(duty_cycle)
    if not (math.isfinite(d) and 0.0 < d <= 1.0):
        raise ParameterError(f"endurance_time: duty_cycle = {shown(duty_cycle)}: expected a fraction in (0, 1]")
    if d < 1.0 and (cycle_s is None or not (math.isfinite(float(cycle_s)) and float(cycle_s) > 0.0)):
        raise ParameterError(f"endurance_time: cycle_s = {shown(cycle_s)}: expected a cycle length > 0 (s) for duty_cycle {d}")
    ia, ir = model.state_index("ma"), model.state_index("mr")

    def event(t: float, y: np.ndarray) -> float:
        return y[ia] + y[ir] - TL

    event.terminal = True
    event.direction = -1

    f_on, J_on = _fixed_functions(model, TL)
    opts = dict(method=method, rtol=rtol, atol=atol, events=event)
    if method in ("Radau", "BDF", "LSODA"):
        opts["jac"] = J_on
    y = model.rest_state().astype(float)
    if d == 1.0:
        out = _solve_ivp(f_on, (0.0, float(t_max)), y, **opts)
        _check_solve(out, model, TL)
        return float(out.t_events[0][0]) if out.t_events[0].size else math.inf

    if isinstance(max_cycles, bool) or not isinstance(max_cycles, (int, np.integer)) or max_cycles < 1:
        raise ParameterError(f"endurance_time: max_cycles = {max_cycles!r}: expected an integer number of cycles >= 1")
    f_off, J_off = _fixed_functions(model, 0.0)

    def ma_negative(t: float, y: np.ndarray) -> float:
        return y[ia]

    ma_negative.terminal = True
    ma_negative.direction = -1
    off_opts = dict(method=method, rtol=rtol, atol=atol, events=ma_negative)
    if method in ("Radau", "BDF", "LSODA"):
        off_opts["jac"] = J_off
    cycle = _Cycle(model, TL, d, float(cycle_s), f_on, opts, f_off, off_opts, ia, ir)
    return cycle.run(y, float(t_max), steady_stop, int(max_cycles), as_reporter(progress))


@dataclass
class _Cycle:
    """One cycle of an intermittent task: "on" at ``TL`` for ``d * T`` s, then a rest; ``run``
    repeats it (see :func:`endurance_time`)."""

    model: FatigueModel
    TL: float
    d: float
    T: float
    f_on: object
    opts: dict
    f_off: object
    off_opts: dict
    ia: int
    ir: int

    def run(self, y: np.ndarray, t_max: float, steady_stop: bool, max_cycles: int, report) -> float:
        TL, T = self.TL, self.T
        t0 = 0.0
        margins: list[float] = []
        while t0 < t_max:
            if len(margins) >= max_cycles:
                raise ParameterError(
                    f"endurance_time: max_cycles = {max_cycles} cycles of {T:g} s ({max_cycles * T:g} s) simulated at TL = {TL:g} "
                    f"without failure or a steady state (margin ma + mr - TL = {margins[-1]:.3g}); expected a task that fails "
                    "or settles within max_cycles: raise max_cycles (--max-cycles) or lengthen the cycle"
                )
            if margins and len(margins) % PROGRESS_EVERY == 0:
                report.line(f"  TL = {TL:g}: cycle {len(margins)} of at most {max_cycles} (t = {t0:g} s), "
                            f"margin ma + mr - TL = {margins[-1]:.4g}")
            t_on_end = min(t0 + self.d * T, t_max)
            out = _solve_ivp(self.f_on, (t0, t_on_end), y, **self.opts)
            _check_solve(out, self.model, TL)
            if out.t_events[0].size:
                return float(out.t_events[0][0])
            y = out.y[:, -1]
            if t_on_end >= t_max:
                break
            margins.append(float(y[self.ia] + y[self.ir] - TL))
            if steady_stop and _settles_above(margins):
                return math.inf
            y = _rest(self.f_off, self.off_opts, y, t_on_end, t0 + T, self.ia, self.model)
            t0 += T
        return math.inf


def _rest(f_off, off_opts: dict, y: np.ndarray, t_a: float, t_b: float, ia: int, model: FatigueModel) -> np.ndarray:
    """Integrate a rest (TL = 0) from ``t_a`` to ``t_b``. ``ma`` decays to 0 and never crosses it in
    the exact solution; when the integrator's round-off takes it below 0, it is set to 0 (a change
    below ``atol``), where it stays exactly. Without this, Xia's 3CC-r switch ``R' = r R while
    ma >= TL`` would flicker between ``r R`` and ``R`` with the sign of the round-off."""
    out = _solve_ivp(f_off, (t_a, t_b), y, **off_opts)
    _check_solve(out, model, 0.0)
    if not out.t_events[0].size or out.t_events[0][0] >= t_b:
        return out.y[:, -1].copy()
    # ma = 0 with TL = 0 is an equilibrium of ma (C = 0, F ma = 0): integrate the rest of the phase
    # from there without the event (a zero-to-zero "crossing" would fire it again at once).
    y = out.y_events[0][0].copy()
    y[ia] = 0.0
    t_a = float(out.t_events[0][0])
    opts = {k: v for k, v in off_opts.items() if k != "events"}
    out = _solve_ivp(f_off, (t_a, t_b), y, **opts)
    _check_solve(out, model, 0.0)
    return out.y[:, -1].copy()


def _settles_above(margins: list[float], tol: float = 1e-4) -> bool:
    """Whether the end-of-"on" margins ``ma + mr - TL`` of successive cycles converge (geometrically,
    Aitken's extrapolation agreeing over two consecutive estimates) to a limit above ``tol``."""
    if len(margins) < 5:
        return False
    limits = []
    for k in (len(margins) - 1, len(margins) - 2):
        d1, d0 = margins[k] - margins[k - 1], margins[k - 1] - margins[k - 2]
        if abs(d1) < 1e-13 and abs(d0) < 1e-13:
            limits.append(margins[k])
            continue
        if d0 == 0.0:
            return False
        q = d1 / d0
        if not 0.0 < q < 0.999:
            return False
        limits.append(margins[k] + d1 * q / (1.0 - q))
    return min(limits) > tol and abs(limits[0] - limits[1]) < 0.1 * tol


def _check_solve(out, model: FatigueModel, TL: float) -> None:
    if not out.success:
        raise FatiguePinError(f"endurance simulation of {model!r} at TL = {TL} failed: {out.message}")


# -- tables -------------------------------------------------------------------------------------------


@dataclass
class EnduranceTable:
    """Endurance times of one model over target loads.

    Attributes:
        name: a label (e.g. the preset name).
        model: the fatigue model simulated.
        loads: target loads, shape (n,).
        et_sim: simulated endurance times (s), shape (n,) (``inf``: none before ``t_max``).
        et_closed: closed form of Xia's 3CC-r with instant activation and the model's F, R, r
            (s), shape (n,); NaN for models without a closed form.
        joint: the joint whose Frey-Law & Avin (2010) power model is compared, or None.
        et_power: that power model's endurance times (s), shape (n,), NaN without a joint.
        duty_cycle, cycle_s: the task (1, None: sustained).
        source: where the parameters come from.
    """

    name: str
    model: FatigueModel
    loads: np.ndarray
    et_sim: np.ndarray
    et_closed: np.ndarray
    joint: str | None = None
    et_power: np.ndarray = field(default_factory=lambda: np.array([]))
    duty_cycle: float = 1.0
    cycle_s: float | None = None
    source: str = ""

    @property
    def rel_error_closed(self) -> np.ndarray:
        """``et_sim / et_closed - 1`` (NaN where either is infinite or missing)."""
        return _rel(self.et_sim, self.et_closed)

    @property
    def rel_error_power(self) -> np.ndarray:
        """``et_closed / et_power - 1`` (model's closed form vs the empirical curve), NaN without a joint."""
        ref = self.et_closed if np.isfinite(self.et_closed).any() else self.et_sim
        return _rel(ref, self.et_power) if self.et_power.size else np.full(self.loads.shape, np.nan)


def _rel(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.asarray(a, float) / np.asarray(b, float) - 1.0
    return np.where(np.isfinite(a) & np.isfinite(b), out, np.nan)


def endurance_table(
    model: FatigueModel,
    loads: Sequence[float] = DEFAULT_LOADS,
    duty_cycle: float = 1.0,
    cycle_s: float | None = None,
    name: str = "",
    joint: str | None = None,
    source: str = "",
    **simulate_options: object,
) -> EnduranceTable:
    """Simulated and closed-form endurance times of ``model`` at each load (see :func:`endurance_time`)."""
    if len(loads) == 0:
        raise ParameterError("endurance_table: loads = []: expected at least one target load, a fraction in (0, 1]")
    tl = np.array([_check_load(x, "endurance_table") for x in loads])
    et_sim = np.array([endurance_time(model, x, duty_cycle, cycle_s, **simulate_options) for x in tl])
    if isinstance(model, XiaFatigue):
        et_closed = np.array([intermittent_et_closed_form(model.F, model.R, x, duty_cycle, cycle_s, model.r) for x in tl])
    else:
        et_closed = np.full(tl.shape, np.nan)
    et_power = power_model_et(joint, tl) if joint is not None and duty_cycle == 1.0 else np.array([])
    return EnduranceTable(name or model.kind, model, tl, et_sim, et_closed, joint, np.asarray(et_power, float),
                          float(duty_cycle), None if cycle_s is None else float(cycle_s), source)


def compare_frey_law_avin(loads: Sequence[float] = DEFAULT_LOADS, simulate: bool = False) -> list[EnduranceTable]:
    """For every joint of Frey-Law, Looft & Heitsman (2012): the 3CC endurance times with the joint's
    F and R beside Frey-Law & Avin (2010)'s power model (sustained tasks). ``simulate=True`` also
    runs the ODE (LD = LR = 10); otherwise ``et_sim`` holds the closed form."""
    from fatigue_pin.fatigue.presets import FREY_LAW_2012_JOINTS, preset, preset_source

    out = []
    for joint in FREY_LAW_2012_JOINTS:
        name = f"frey-law-2012/{joint}"
        model = preset(name)
        tl = np.asarray(loads, dtype=float)
        if simulate:
            tab = endurance_table(model, tl, name=name, joint=joint, source=preset_source(name))
        else:
            closed = sustained_et_closed_form(model.F, model.R, tl)
            tab = EnduranceTable(name, model, tl, closed.copy(), closed, joint, power_model_et(joint, tl), 1.0, None,
                                 preset_source(name))
        out.append(tab)
    return out
