"""The reference re-integration of ``fatigue-pin verify``: numeric ``pinocchio.aba`` and the numpy
fatigue right-hand sides, integrated with ``scipy.integrate.solve_ivp`` over each interval with the
stored piecewise-constant control.

* :func:`gap_checks`: the multiple-shooting gaps ``|Phi(x_k, u_k, dt) - x_{k+1}|`` and, with the
  stored substeps, the transcription's RK4 written again in numpy (its residual and its distance to
  the exact flow);
* :func:`single_shooting`: the stored controls over the whole horizon from the stored x_0.

No integration can run for ever: the tolerances are validated (:class:`ReferenceIntegration`), an
interval whose stored values are not finite is not integrated, a right-hand side that turns
non-finite or an interval that needs more than :data:`MAX_EVALUATIONS` evaluations of it stops
the integration (:class:`IntegrationFailed`), which is reported as an infinite gap on that
interval; after :data:`MAX_FAILED_INTERVALS` such intervals the others are not integrated.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from fatigue_pin.verify.report import ReferenceIntegration, VerifyCheck, VerifyReport, VerifyTolerances, worst
from fatigue_pin.verify.stored import Stored

__all__ = ["Dynamics", "IntegrationFailed", "integrate", "rk4", "gap_checks", "GapResult", "single_shooting"]

Rhs = Callable[[float, np.ndarray], np.ndarray]

#: Right-hand-side evaluations allowed per interval: a smooth interval takes tens of DOP853 steps
#: of 12 evaluations at rtol 1e-10; a stiff or absurd one (a dt of 1e9 s, huge torques) is stopped.
MAX_EVALUATIONS = 20_000
#: Intervals whose integration may fail before the gap check stops integrating the others.
MAX_FAILED_INTERVALS = 3


class IntegrationFailed(Exception):
    """The reference integration of one interval failed (solver failure or a non-finite rate)."""


class Dynamics:
    """Numeric right-hand sides of the rigid body (``pin.aba``) and of the fatigue states."""

    def __init__(self, stored: Stored) -> None:
        import pinocchio as pin

        self.pin = pin
        self.model = stored.robot.pin_model
        self.data = self.model.createData()
        self.nq = self.model.nq
        self.halves = stored.halves
        self.offsets = stored.offsets
        self.stored = stored

    def rigid(self, k: int) -> Rhs:
        """d(q, qdot)/dt on interval ``k``: its stored joint torques held, plus for a muscle run
        the muscles' torque at its activations and the current (q, qdot)."""
        nq, pin, model, data = self.nq, self.pin, self.model, self.data
        s = self.stored
        tau = s.tau[k]
        if s.muscles is None:
            def f(_t: float, y: np.ndarray) -> np.ndarray:
                return np.concatenate([y[nq:], pin.aba(model, data, y[:nq], y[nq:], tau)])
            return f
        muscles, a = s.muscles, s.activations[k]

        def g(_t: float, y: np.ndarray) -> np.ndarray:
            return np.concatenate([y[nq:], pin.aba(model, data, y[:nq], y[nq:], tau + muscles.torque(y[:nq], y[nq:], a))])

        return g

    def joint(self, k: int) -> Rhs:
        """d(q, qdot, m)/dt on interval ``k`` of a muscle run of the ``active`` coupling: each
        muscle's activation is its active fraction, a state, so the rigid body and the fatigue
        states are integrated together."""
        nq, pin, model, data = self.nq, self.pin, self.model, self.data
        s = self.stored
        tau, muscles, rows, fm = s.tau[k], s.muscles, s.active, self.fatigue(s.TL[k])
        ny = 2 * nq

        def f(t: float, z: np.ndarray) -> np.ndarray:
            y, m = z[:ny], z[ny:]
            torque = tau + muscles.torque(y[:nq], y[nq:], m[rows])
            return np.concatenate([y[nq:], pin.aba(model, data, y[:nq], y[nq:], torque), fm(t, m)])

        return f

    def fatigue(self, TL: np.ndarray) -> Rhs:
        """dm/dt of every half's states with the target loads ``TL`` (halves,) held."""
        halves, off = self.halves, self.offsets

        def f(_t: float, m: np.ndarray) -> np.ndarray:
            return np.concatenate([h.rhs(m[off[i]:off[i + 1]], TL[i]) for i, h in enumerate(halves)])

        return f


class _NonFinite(Exception):
    pass


def integrate(f: Rhs, y0: np.ndarray, dt: float, ref: ReferenceIntegration) -> np.ndarray:
    """``y(dt)`` from ``y(0) = y0`` with ``solve_ivp`` (raises :class:`IntegrationFailed`)."""
    from scipy.integrate import solve_ivp

    if not np.all(np.isfinite(y0)):
        raise IntegrationFailed("a non-finite initial state")

    count = [0]

    def guarded(t: float, y: np.ndarray) -> np.ndarray:
        count[0] += 1
        if count[0] > MAX_EVALUATIONS:
            raise _NonFinite(f"more than {MAX_EVALUATIONS} evaluations of the rates (stiff, or an absurd step)")
        d = f(t, y)
        if not np.all(np.isfinite(d)):
            raise _NonFinite(f"a non-finite rate at t = {t:g} s")
        return d

    try:
        with np.errstate(all="ignore"):
            sol = solve_ivp(guarded, (0.0, dt), y0, method=ref.method, rtol=ref.rtol, atol=ref.atol)
    except _NonFinite as exc:
        raise IntegrationFailed(str(exc)) from None
    if not sol.success:
        raise IntegrationFailed(str(sol.message))
    return sol.y[:, -1]


def rk4(f: Rhs, y: np.ndarray, dt: float, steps: int) -> np.ndarray:
    """``steps`` classical Runge-Kutta steps over ``dt`` (the transcription's scheme, written again)."""
    h = dt / steps
    with np.errstate(all="ignore"):
        for _ in range(steps):
            k1 = f(0.0, y)
            k2 = f(0.0, y + h / 2 * k1)
            k3 = f(0.0, y + h / 2 * k2)
            k4 = f(0.0, y + h * k3)
            y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return y


def finite_intervals(s: Stored) -> np.ndarray:
    """Intervals whose two nodes and control are finite, (N,) bool."""
    node = np.all(np.isfinite(s.Y), axis=1) & np.all(np.isfinite(s.M), axis=1)
    ctrl = np.all(np.isfinite(s.tau), axis=1) & np.all(np.isfinite(s.TL), axis=1)
    if s.activations is not None:
        ctrl &= np.all(np.isfinite(s.activations), axis=1)
    return node[:-1] & node[1:] & ctrl


@dataclass
class GapResult:
    """The gap lines and the figures the report keeps."""

    checks: list[VerifyCheck]
    gap_q: float
    gap_qdot: float
    gap_fatigue: float
    rk4_residual: float
    rk4_truncation: float
    rk4_where: str


def _no_progress(_n: int) -> None:
    pass


def _interval_gaps(s: Stored, dyn: Dynamics, ref: ReferenceIntegration, k: int, gy: np.ndarray, gm: np.ndarray,
                   res: np.ndarray, trunc: np.ndarray, failed: list[str]) -> None:
    """Fill row ``k`` of the gaps ``gy`` (q, qdot), ``gm`` (fatigue) and, with substeps, of the RK4
    residual ``res`` and truncation ``trunc``; a failed integration is an infinite gap, named in ``failed``."""
    nm = s.M.shape[1]
    if s.active is not None:  # the rigid body reads the fatigue states: one integration of both
        _joint_interval_gaps(s, dyn, ref, k, gy, gm, res, trunc, failed)
        return
    fy, fm = dyn.rigid(k), dyn.fatigue(s.TL[k])
    try:
        ey = integrate(fy, s.Y[k], s.dt, ref)
        em = integrate(fm, s.M[k], s.dt, ref) if nm else s.M[k]
    except IntegrationFailed as exc:
        gy[k], gm[k] = np.inf, np.inf
        failed.append(f"interval {k} ({exc})")
        return
    gy[k], gm[k] = np.abs(ey - s.Y[k + 1]), np.abs(em - s.M[k + 1])
    if s.substeps:
        ry = rk4(fy, s.Y[k], s.dt, s.substeps)
        rm = rk4(fm, s.M[k], s.dt, s.substeps) if nm else s.M[k]
        res[k] = np.abs(np.concatenate([ry - s.Y[k + 1], rm - s.M[k + 1]]))
        trunc[k] = np.abs(np.concatenate([ry - ey, rm - em]))


def _joint_interval_gaps(s: Stored, dyn: Dynamics, ref: ReferenceIntegration, k: int, gy: np.ndarray, gm: np.ndarray,
                         res: np.ndarray, trunc: np.ndarray, failed: list[str]) -> None:
    """:func:`_interval_gaps` of a run whose rigid body reads the fatigue states (:meth:`Dynamics.joint`)."""
    ny = s.Y.shape[1]
    f, z0, z1 = dyn.joint(k), np.concatenate([s.Y[k], s.M[k]]), np.concatenate([s.Y[k + 1], s.M[k + 1]])
    try:
        e = integrate(f, z0, s.dt, ref)
    except IntegrationFailed as exc:
        gy[k], gm[k] = np.inf, np.inf
        failed.append(f"interval {k} ({exc})")
        return
    gy[k], gm[k] = np.abs(e[:ny] - s.Y[k + 1]), np.abs(e[ny:] - s.M[k + 1])
    if s.substeps:
        r = rk4(f, z0, s.dt, s.substeps)
        res[k], trunc[k] = np.abs(r - z1), np.abs(r - e)


def gap_checks(s: Stored, dyn: Dynamics, tol: VerifyTolerances, ref: ReferenceIntegration, notes: list[str],
               advance: Callable[[int], None] = _no_progress) -> GapResult:
    """Multiple-shooting gaps: each interval integrated from its stored node with its stored control
    held; with the stored substeps, the transcription's RK4 too (its residual says whether the NLP
    was solved, its distance to the exact flow how coarse the grid is). ``advance(n)`` is told of
    every interval done (N in all: those not integrated count too)."""
    N, nq, nm = s.N, s.nq, s.M.shape[1]
    gy, gm = np.full((N, 2 * nq), np.nan), np.full((N, nm), np.nan)
    res, trunc = np.full((N, 2 * nq + nm), np.nan), np.full((N, 2 * nq + nm), np.nan)
    ok = finite_intervals(s)
    failed: list[str] = []
    stopped = False
    for k in range(N):
        if ok[k] and not stopped and len(failed) >= MAX_FAILED_INTERVALS:
            notes.append(f"the gaps of intervals {k} to {N - 1} were not computed: the reference integration failed "
                         f"on {MAX_FAILED_INTERVALS} intervals already")
            stopped = True
        if ok[k] and not stopped:
            _interval_gaps(s, dyn, ref, k, gy, gm, res, trunc, failed)
        advance(1)
    if not ok.all():
        notes.append(f"{int((~ok).sum())} of {N} intervals not re-integrated: their stored values are not finite")
    if failed:
        notes.append(f"the reference integration failed on {len(failed)} interval(s), counted as infinite gaps: "
                     + "; ".join(failed[:3]) + ("; ..." if len(failed) > 3 else ""))
    gap_q, at_q = worst(gy[:, :nq], s.joints, "interval")
    gap_v, at_v = worst(gy[:, nq:], s.joints, "interval")
    gap_m, at_m = worst(gm, s.state_labels, "interval")
    rk4_res = rk4_trunc = float("nan")
    at_res = at_trunc = ""
    if s.substeps:
        rk4_res, at_res = worst(res, s.x_labels, "interval")
        rk4_trunc, at_trunc = worst(trunc, s.x_labels, "interval")
    checks = [
        VerifyCheck("gap q", gap_q, s.units("position"), tol.gap, at_q),
        VerifyCheck("gap qdot", gap_v, s.units("velocity"), tol.gap, at_v),
        VerifyCheck("gap fatigue states", gap_m, "1", tol.gap_fatigue, at_m),
    ]
    rk4_lines = [
        VerifyCheck(f"RK4 residual ({s.substeps} substeps, numpy)", rk4_res, "state", None, at_res),
        VerifyCheck("RK4 truncation (RK4 - exact flow)", rk4_trunc, "state", None, at_trunc),
    ]
    return GapResult(checks + rk4_lines, gap_q, gap_v, gap_m, rk4_res, rk4_trunc, at_trunc)


def coarse_grid_note(s: Stored, gaps: GapResult) -> str | None:
    """Why the gaps fail when the nodes solve their own discretisation (a small RK4 residual)."""
    failing = [c for c in gaps.checks if c.name.startswith("gap") and not c.passed]
    if failing and s.substeps and gaps.rk4_residual <= 0.1 * min(c.tolerance for c in failing):
        return (f"the gaps are the transcription's own RK4 error ({gaps.rk4_truncation:.2e} at {gaps.rk4_where}): the nodes "
                f"solve the discretised problem (RK4 residual {gaps.rk4_residual:.1e}) but the grid ({s.substeps} substeps "
                f"of {s.dt / s.substeps:g} s) is too coarse for the gap tolerance")
    return None



def single_shooting(s: Stored, dyn: Dynamics, ref: ReferenceIntegration, report: VerifyReport,
                    advance: Callable[[int], None] = _no_progress) -> None:
    """Integrate the stored controls over the whole horizon from the stored x_0 and add the drift
    of the states and of the invariant to ``report`` (reported only). The rigid body's open-loop
    integration can blow up over long horizons: it is then reported as an infinite drift with a
    note, and the fatigue states (which depend on the controls only) are integrated to the end.
    ``advance(n)`` is told of every interval done (N in all)."""
    N, nq, Y, M = s.N, s.nq, s.Y, s.M
    ys, ms = np.full_like(Y, np.nan), np.full_like(M, np.nan)
    ys[0], ms[0] = Y[0], M[0]
    diverged = stopped = None
    ny = Y.shape[1]
    for k in range(N):
        if diverged is None and s.active is not None:  # the rigid body reads the fatigue states: both at once
            try:
                z = integrate(dyn.joint(k), np.concatenate([ys[k], ms[k]]), s.dt, ref)
                ys[k + 1], ms[k + 1] = z[:ny], z[ny:]
                advance(1)
                continue
            except IntegrationFailed:
                diverged = k
        if diverged is None:
            try:
                ys[k + 1] = integrate(dyn.rigid(k), ys[k], s.dt, ref)
            except IntegrationFailed:
                diverged = k
        if M.shape[1] and stopped is None:
            try:
                ms[k + 1] = integrate(dyn.fatigue(s.TL[k]), ms[k], s.dt, ref)
            except IntegrationFailed:
                stopped = k
        advance(1)
    dq, at_dq = worst(np.abs(ys[:, :nq] - Y[:, :nq]), s.joints, "node")
    dv, at_dv = worst(np.abs(ys[:, nq:] - Y[:, nq:]), s.joints, "node")
    if diverged is not None:
        dq = dv = float("inf")
        at_dq = at_dv = f"diverged on interval {diverged} (open-loop integration of the rigid body)"
        report.notes.append(f"single shooting: the rigid body's integration failed on interval {diverged} of {N}: "
                            "an open-loop swing amplifies small differences; the fatigue states were integrated to the end")
    dm, at_dm = worst(np.abs(ms - M), s.state_labels, "node")
    if stopped is not None:
        dm, at_dm = float("inf"), f"failed on interval {stopped}"
    inv_ss, inv = s.invariant(ms), s.invariant(M)
    d_inv, at_di = worst(np.abs(inv_ss - inv), [h.name for h in s.halves], "node")
    report.drift_q, report.drift_qdot, report.drift_fatigue, report.drift_invariant = dq, dv, dm, d_inv
    top = float(np.nanmax(inv_ss)) if inv_ss.size and np.isfinite(inv_ss).any() else 0.0
    last = float(np.nanmax(inv_ss[-1])) if inv_ss.size and np.isfinite(inv_ss[-1]).any() else float("nan")
    if inv_ss.size:
        report.single_shooting_invariant, report.single_shooting_invariant_final = top, last
    report.checks += [
        VerifyCheck("single shooting: drift q", dq, s.units("position"), None, at_dq),
        VerifyCheck("single shooting: drift qdot", dv, s.units("velocity"), None, at_dv),
        VerifyCheck("single shooting: drift fatigue", dm, "1", None, at_dm),
        VerifyCheck("single shooting: invariant there", top, "1", None, f"max over nodes; {last:.3e} at node {N}"),
        VerifyCheck("single shooting: invariant drift", d_inv, "1", None, at_di),
    ]
