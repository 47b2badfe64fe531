"""The settings and the outcome of ``fatigue-pin verify``: tolerances, the reference integration's
settings, one line per check, and the report.

:class:`VerifyTolerances` decide ``passed``; :class:`ReferenceIntegration` holds the settings of
``scipy.integrate.solve_ivp`` (both validated in ``__post_init__``: a non-finite or negative value
is refused before any integration, since a NaN tolerance would make ``solve_ivp`` loop for ever);
:class:`VerifyCheck` is one line of the table; :class:`VerifyReport` gathers them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from fatigue_pin.core.accuracy import GAP_TOLERANCE, GAP_TOLERANCE_FATIGUE, REFERENCE_ATOL, REFERENCE_METHOD, REFERENCE_RTOL
from fatigue_pin.core.errors import ParameterError
from fatigue_pin.core.text import shown

__all__ = ["DEFAULT_RTOL", "DEFAULT_ATOL", "DEFAULT_METHOD", "METHODS", "VerifyTolerances", "ReferenceIntegration",
           "VerifyCheck", "VerifyReport", "worst"]

#: Default tolerances and method of the reference integration.
DEFAULT_RTOL = REFERENCE_RTOL
DEFAULT_ATOL = REFERENCE_ATOL
DEFAULT_METHOD = REFERENCE_METHOD
#: The ``solve_ivp`` methods verify accepts.
METHODS = ("DOP853", "RK45", "RK23", "Radau", "BDF", "LSODA")


def _is_real(value: object) -> bool:
    return not isinstance(value, bool) and isinstance(value, (int, float, np.integer, np.floating))


@dataclass(frozen=True)
class VerifyTolerances:
    """Tolerances of the checks that decide ``passed`` (absolute, in the unit of each check).

    Attributes:
        gap: multiple-shooting gap of q (rad or m) and qdot (rad/s or m/s). It must admit the
            transcription's own RK4 error: about 1e-4 on the test discretisation (10 intervals per
            cycle, 2 substeps), 1e-8 on the paper's (50 intervals, 5 substeps).
        gap_fatigue: multiple-shooting gap of the fatigue states (dimensionless).
        task: every task item (joint targets and ranges in rad or m, frame targets and planes in
            m, frame orientations in rad, beyond the item's own tolerance) and the initial state.
        coupling: ``TL + m_fatigued`` outside [0, 1] (IPOPT's ``constr_viol_tol`` is 1e-4).
        bound: q, qdot, torques (N m) and fatigue states outside their bounds.
    """

    gap: float = GAP_TOLERANCE
    gap_fatigue: float = GAP_TOLERANCE_FATIGUE
    task: float = 1e-4
    coupling: float = 1e-4
    bound: float = 1e-4

    def __post_init__(self) -> None:
        for name in ("gap", "gap_fatigue", "task", "coupling", "bound"):
            value = getattr(self, name)
            if not _is_real(value) or not math.isfinite(value) or value < 0:
                raise ParameterError(f"VerifyTolerances.{name} = {shown(value)}: expected a finite tolerance >= 0")


@dataclass(frozen=True)
class ReferenceIntegration:
    """Settings of the reference integration (``scipy.integrate.solve_ivp``).

    Attributes:
        rtol: relative tolerance, finite and > 0.
        atol: absolute tolerance (in the unit of each state), finite and >= 0.
        method: one of :data:`METHODS` (DOP853 by default; the paper's single shooting: RK45 with
            rtol 1e-3, atol 1e-6).
    """

    rtol: float = DEFAULT_RTOL
    atol: float = DEFAULT_ATOL
    method: str = DEFAULT_METHOD

    def __post_init__(self) -> None:
        if not _is_real(self.rtol) or not math.isfinite(self.rtol) or self.rtol <= 0:
            raise ParameterError(f"rtol = {shown(self.rtol)}: expected a finite relative tolerance > 0 of the reference integration (verify --rtol)")
        if not _is_real(self.atol) or not math.isfinite(self.atol) or self.atol < 0:
            raise ParameterError(f"atol = {shown(self.atol)}: expected a finite absolute tolerance >= 0 of the reference integration (verify --atol)")
        if self.method not in METHODS:
            raise ParameterError(f"method = {self.method!r}: expected one of {list(METHODS)} (verify --method)")
        object.__setattr__(self, "rtol", float(self.rtol))
        object.__setattr__(self, "atol", float(self.atol))


@dataclass(frozen=True)
class VerifyCheck:
    """One line of the report.

    Attributes:
        name: what is checked (e.g. ``gap qdot``).
        value: the worst violation or error (NaN when not checked).
        unit: the unit of ``value``.
        tolerance: the limit that decides pass/fail, or None (reported only).
        where: where the worst value is (e.g. ``interval 13, elbow``).
    """

    name: str
    value: float
    unit: str
    tolerance: float | None = None
    where: str = ""

    @property
    def checked(self) -> bool:
        return not math.isnan(self.value)

    @property
    def passed(self) -> bool:
        return self.tolerance is None or not self.checked or self.value <= self.tolerance

    @property
    def verdict(self) -> str:
        if not self.checked:
            return "not checked"
        if self.tolerance is None:
            return "reported"
        return "ok" if self.passed else "FAIL"


@dataclass
class VerifyReport:
    """The outcome of :func:`fatigue_pin.verify.verifier.verify_run`.

    Attributes:
        run: run name; horizon: ``full`` or ``sliding``.
        n_intervals, dt, substeps: the run's grid (substeps: of the stored transcription, 0 if unknown).
        checks: every check, in table order (:class:`VerifyCheck`).
        gap_q, gap_qdot, gap_fatigue: worst multiple-shooting gaps (rad, rad/s, 1).
        task: worst task violation over every checked task line and the initial state (NaN when
            the run stores no study).
        coupling: worst coupling violation (TL + fatigued fraction outside [0, 1]).
        bound: worst bound violation (q, qdot, torques, fatigue states).
        invariant: worst |1 - sum of states| over nodes and halves; invariant_final: at the last node.
        invariant_sum: the sum used per model kind (e.g. ``xia: ma + mr + mf``).
        rhs_check: worst |numpy rhs - model rates| over the nodes (NaN without a numpy transcription).
        rk4_residual: worst |RK4(x_k, u_k) - x_{k+1}| with the stored substeps, RK4 written again in
            numpy (the NLP's own gaps: small when it was solved); NaN when substeps are unknown.
        rk4_truncation: worst |RK4(x_k, u_k) - exact flow(x_k, u_k)|: how coarse the grid is.
        drift_q, drift_qdot, drift_fatigue, drift_invariant: single-shooting drift (NaN unless asked).
        single_shooting_invariant, single_shooting_invariant_final: |1 - sum| of the
            single-shooting states, worst over nodes and at the last node (NaN unless asked).
        notes: what was not checked and why.
        tolerances: the tolerances used; rtol, atol, method: of the reference integration.
    """

    run: str
    horizon: str
    n_intervals: int
    dt: float
    substeps: int
    checks: list[VerifyCheck]
    gap_q: float
    gap_qdot: float
    gap_fatigue: float
    task: float
    coupling: float
    bound: float
    invariant: float
    invariant_final: float
    invariant_sum: str
    rhs_check: float
    rk4_residual: float
    rk4_truncation: float
    tolerances: VerifyTolerances
    rtol: float
    atol: float
    method: str = DEFAULT_METHOD
    drift_q: float = float("nan")
    drift_qdot: float = float("nan")
    drift_fatigue: float = float("nan")
    drift_invariant: float = float("nan")
    single_shooting_invariant: float = float("nan")
    single_shooting_invariant_final: float = float("nan")
    notes: list[str] = field(default_factory=list)

    @property
    def gap(self) -> float:
        """Worst gap of q and qdot."""
        return max(self.gap_q, self.gap_qdot)

    @property
    def failures(self) -> list[VerifyCheck]:
        return [c for c in self.checks if not c.passed]

    @property
    def not_checked(self) -> list[VerifyCheck]:
        """The lines that could not be checked (each has a note saying why)."""
        return [c for c in self.checks if not c.checked]

    @property
    def passed(self) -> bool:
        return not self.failures

    def check(self, name: str) -> VerifyCheck:
        """The line called ``name`` (KeyError naming the lines if there is none)."""
        for c in self.checks:
            if c.name == name:
                return c
        raise KeyError(f"no check {name!r}; the report has {[c.name for c in self.checks]}")

    def table(self) -> str:
        """The report as text: one line per check, notes, and the verdict."""
        head = (f"verify {self.run} ({self.horizon}, {self.n_intervals} intervals of {self.dt:g} s"
                f"{f', {self.substeps} RK4 substeps' if self.substeps else ''}; reference {self.method} rtol {self.rtol:g} atol {self.atol:g})")
        w = max([7, *(len(c.unit) + 1 for c in self.checks)])  # "rad/s or m/s" for a model with both joint kinds
        lines = [head, f"  {'check':<36}{'worst':>11}  {'unit':<{w}}{'tolerance':>10}  {'result':<12}where"]
        for c in self.checks:
            value = "-" if not c.checked else f"{c.value:.3e}"
            tol = "-" if c.tolerance is None else f"{c.tolerance:.0e}"
            lines.append(f"  {c.name:<36}{value:>11}  {c.unit:<{w}}{tol:>10}  {c.verdict:<12}{c.where}")
        for note in self.notes:
            lines.append(f"  note: {note}")
        if self.passed:
            lines.append("  PASSED")
        else:
            lines.append("  FAILED: " + "; ".join(f"{c.name} {c.value:.3e} > {c.tolerance:g} ({c.where})" for c in self.failures))
        return "\n".join(lines)


def worst(values: np.ndarray, labels: Sequence[str], what: str, offset: int = 0) -> tuple[float, str]:
    """The largest entry of a (rows, columns) array of violations and where it is, e.g.
    ``(0.01, "interval 12, elbow")`` (row ``k + offset`` named by ``what``, column by ``labels``).
    NaN entries (values that were not computed) count as 0; +inf is kept (a failed integration)."""
    values = np.asarray(values, dtype=float)
    if values.size == 0:
        return 0.0, ""
    flat = np.nan_to_num(values, nan=0.0, posinf=np.inf)
    k, j = np.unravel_index(int(np.argmax(flat)), flat.shape)
    if not flat[k, j] > 0:
        return 0.0, ""
    label = labels[j] if len(labels) > j else ""
    return float(flat[k, j]), f"{what} {int(k) + offset}" + (f", {label}" if label else "")
