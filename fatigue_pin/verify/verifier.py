"""An independent check of a stored result: ``fatigue-pin verify FILE.h5 [RUN]``.

Everything is rebuilt from what the run stores (:mod:`fatigue_pin.verify.stored`), without the
package's interval functions (``F_rb``, ``F_fatigue``, ``IntervalFunctions.step``) or its CasADi
dynamics:

* the rigid body the run was solved on (its URDF text, with the stored study's gravity and
  payload), its accelerations from numeric ``pinocchio.aba``;
* the fatigue models from the ``fatigue_params`` attribute, their right-hand side from a numpy
  transcription of the equations (:mod:`fatigue_pin.verify.fatigue_rhs`), cross-checked against the
  model's own ``rates`` on every stored node;
* the integration with ``scipy.integrate.solve_ivp`` over each interval, with the stored
  piecewise-constant control (:mod:`fatigue_pin.verify.dynamics`);
* the task from the stored study (:meth:`Study.task`), every item kind evaluated with numeric
  Pinocchio kinematics (:mod:`fatigue_pin.verify.task_checks`).

Checked (``docs/verify.md`` gives the equations): the stored numbers are finite,
multiple-shooting gaps (q, qdot, fatigue states), the task, the coupling
``0 <= TL + m_fatigued <= 1`` at every node (``u_N := u_{N-1}``), bounds (q, qdot, torques,
fatigue states in [0, 1]) (:mod:`fatigue_pin.verify.constraints`), the invariant
``|1 - sum of states|`` and, on request, the single-shooting drift over the whole horizon.
"""

from __future__ import annotations

from typing import Callable

from fatigue_pin.core.progress import Progress, as_reporter
from fatigue_pin.drivers.run import RunResult
from fatigue_pin.verify.constraints import bound_checks, coupling_check, finite_check, invariant_checks, rhs_check
from fatigue_pin.verify.dynamics import Dynamics, coarse_grid_note, gap_checks
from fatigue_pin.verify.dynamics import single_shooting as _single_shooting
from fatigue_pin.verify.report import DEFAULT_ATOL, DEFAULT_METHOD, DEFAULT_RTOL, ReferenceIntegration, VerifyReport, VerifyTolerances
from fatigue_pin.verify.stored import Stored, rebuild
from fatigue_pin.verify.task_checks import task_checks

__all__ = ["verify_run"]


def verify_run(run: RunResult, tolerances: VerifyTolerances | None = None, single_shooting: bool = False,
               rtol: float = DEFAULT_RTOL, atol: float = DEFAULT_ATOL, method: str = DEFAULT_METHOD,
               progress: Progress = None) -> VerifyReport:
    """Check a stored run independently of the package's transcription.

    Args:
        run: a run read with :func:`fatigue_pin.io.results.read_run`.
        tolerances: the limits that decide ``passed`` (default :class:`VerifyTolerances`).
        single_shooting: also integrate the stored controls over the whole horizon from the
            stored initial state and report the drift of the states and of the invariant.
        rtol: relative tolerance of ``solve_ivp`` (finite, > 0; ``RK45`` with rtol 1e-3, atol 1e-6
            is the paper's single shooting). The tolerances and the method apply to the gap check
            too, so loose values loosen its reference.
        atol: absolute tolerance of ``solve_ivp`` (finite, >= 0).
        method: method of ``solve_ivp`` (DOP853 by default).
        progress: a :class:`~fatigue_pin.core.progress.Reporter` (a bar over the intervals
            re-integrated: N for the gaps, N more with ``single_shooting``), or a line callback
            (no bar); default quiet.

    Returns:
        A :class:`VerifyReport`; non-finite stored values fail its "finite stored values" line.

    Raises:
        ParameterError: a tolerance or method that is not valid (before any work).
        ResultFileError: the run lacks what is needed (URDF, fatigue parameters, a study that
            loads) or is inconsistent (joints, sizes, a non-finite gravity, limits or dt).
    """
    tol = tolerances if tolerances is not None else VerifyTolerances()
    ref = ReferenceIntegration(rtol, atol, method)
    s = rebuild(run)
    dyn = Dynamics(s)
    bar = as_reporter(progress).bar(s.N * (2 if single_shooting else 1), f"verify {run.name}", "interval")
    try:
        report = _checks(s, run, tol, ref, dyn, bar.update)
        if single_shooting:
            _single_shooting(s, dyn, ref, report, bar.update)
    finally:
        bar.close()
    return report


def _checks(s: Stored, run: RunResult, tol: VerifyTolerances, ref: ReferenceIntegration, dyn: Dynamics,
            advance: Callable[[int], None]) -> VerifyReport:
    """Every check but single shooting; ``advance(n)`` counts the intervals re-integrated."""
    notes = s.notes
    finite = finite_check(s)
    rhs, rhs_err = rhs_check(s, notes)
    gaps = gap_checks(s, dyn, tol, ref, notes, advance)
    if s.horizon == "sliding":
        notes.append("sliding horizon: each window's cyclic end condition is not checked (its end nodes are not kept); "
                     "the stitched trajectory's gaps are, joins included")
    task = task_checks(s, tol.task, notes)
    coupling, coupling_value = coupling_check(s, tol)
    bounds, bound_value = bound_checks(s, tol)
    invariant, inv_value, inv_final, inv_sum = invariant_checks(s)
    checks = [finite, *gaps.checks[:3], *task, coupling, *bounds, *invariant, rhs, *gaps.checks[3:]]
    note = coarse_grid_note(s, gaps)
    if note:
        notes.append(note)
    if ";" in inv_sum:
        notes.append(f"invariant sums: {inv_sum}")
    task_values = [c.value for c in task if c.checked]
    return VerifyReport(
        run=run.name, horizon=s.horizon, n_intervals=s.N, dt=s.dt, substeps=s.substeps, checks=checks,
        gap_q=gaps.gap_q, gap_qdot=gaps.gap_qdot, gap_fatigue=gaps.gap_fatigue,
        task=max(task_values) if task_values else float("nan"), coupling=coupling_value, bound=bound_value,
        invariant=inv_value, invariant_final=inv_final, invariant_sum=inv_sum, rhs_check=rhs_err,
        rk4_residual=gaps.rk4_residual, rk4_truncation=gaps.rk4_truncation, tolerances=tol,
        rtol=ref.rtol, atol=ref.atol, method=ref.method, notes=notes,
    )
