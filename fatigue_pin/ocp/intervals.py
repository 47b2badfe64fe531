"""The interval functions of a problem: what happens over one shooting interval.

:class:`IntervalFunctions` builds, once per problem, the rigid-body step (RK4 with substeps of
Pinocchio's ABA on SX, called from MX), the fatigue step (RK4 of one actuator half per group of
halves with the same fatigue equations, mapped over the halves), the coupling rows and the cost
terms of one interval, and their derivative blocks; :mod:`fatigue_pin.ocp.transcription` maps
them over a horizon.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Callable, Mapping

import casadi as ca
import numpy as np

from fatigue_pin.ocp.blocks import HESS_BLOCK, JAC_BLOCK, BlockPair, block_functions
from fatigue_pin.ocp.sensitivities import rk4_adjoint_hessian, rk4_sensitivities
from fatigue_pin.ocp.costs import IntervalVariables
from fatigue_pin.ocp.problem import Problem

if TYPE_CHECKING:
    from fatigue_pin.ocp.transcription import Transcription

#: Name prefix of the fatigue step of one half of a group (``F_fatigue_<label>``).
FATIGUE_STEP = "F_fatigue_"


def rk4(f: ca.Function, x: ca.MX | ca.SX, args: tuple, h: float, steps: int) -> ca.MX | ca.SX:
    """``steps`` classical Runge-Kutta steps of length ``h`` of ``xdot = f(x, *args)``."""
    for _ in range(steps):
        k1 = f(x, *args)
        k2 = f(x + h / 2 * k1, *args)
        k3 = f(x + h / 2 * k2, *args)
        k4 = f(x + h * k3, *args)
        x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return x


class IntervalFunctions:
    """The functions of one shooting interval, built once per problem structure and dt.

    With piecewise-constant controls the rigid-body states (q, qdot) and the fatigue states m
    evolve independently over an interval, so RK4 on the whole state equals RK4 on each part;
    integrating them separately keeps the derivatives (and the exact Hessian) small. (Under the
    ``active`` coupling the torque is the halves' active fraction times their limit, so the rigid
    body depends on m within the interval: :attr:`F_rb_active` integrates both; m still does not
    depend on the rigid body, so :attr:`F_fatigue` is unchanged.) For the same
    reason the fatigue step is built for one half (the halves are independent: a half's states
    depend on its own torque and parameters only) and mapped over the halves.

    Attributes:
        f_rb: ``f_rb(y, tau) -> ydot`` with y = (q, qdot): Pinocchio's ABA (SX).
        f_fatigue: ``f_fatigue(m, u, p) -> mdot`` of all actuator halves (SX).
        F_rb: ``F_rb(y, tau) -> y_next``, RK4 over one interval.
        F_fatigue: ``F_fatigue(m, u, p) -> m_next``, RK4 over one interval of all halves: one SX
            function, or with ``fatigue_calls`` the maps of :attr:`fatigue_steps` (MX,
            :meth:`fatigue_by_groups`). The same values either way, to rounding.
        fatigue_groups: the halves grouped by fatigue equations
            (:meth:`~fatigue_pin.ocp.actuators.SignedTorqueActuators.fatigue_groups`).
        fatigue_steps: per group, ``F_fatigue_<label>(m_h, TL_h, p_h) -> m_h_next``: the RK4 of one
            half over one interval (the library compiles these, not F_fatigue).
        coupling: ``coupling(x, u) -> TL + m_fatigued`` of every half.
        F_rb_active: ``F_rb_active(y, m, u, p) -> y_next`` under the ``active`` coupling, else None.
        terms: running cost integrands of one interval times dt, ``terms(x, u, u_prev) -> (n_running,)``.
        terminal: terminal cost terms on an end state, ``terminal(x) -> (n_terminal,)``, or None.
    """

    def __init__(self, problem: Problem, transcription: Transcription, fatigue_calls: bool = False) -> None:
        """``fatigue_calls`` (for a compiled library): integrate the fatigue states as MX calls of
        the SX right-hand side of one half, mapped over the halves (derivative code of one half
        instead of all, same values) instead of one SX function of all halves; and differentiate
        a rigid body whose torque follows the state one direction at a time (:attr:`F_rb_active`:
        smaller code, slower in CasADi's virtual machine)."""
        model, actuators, task = problem.model, problem.actuators, problem.task
        layout = problem.layout
        self.layout = layout
        nx, nu, nv, nq = layout.nx, layout.nu, layout.nv, layout.nq
        substeps = transcription.substeps
        h = task.dt / substeps

        y = ca.SX.sym("y", nq + nv)
        tau = ca.SX.sym("tau", nv)
        self.f_rb = ca.Function("f_rb", [y, tau], [ca.vertcat(y[nq:], model.aba(y[:nq], y[nq:], tau))], ["y", "tau"], ["ydot"])
        # expanded: one SX function; else RK4 as MX calls of the SX f_rb (small derivative code,
        # fast to compile)
        ys, taus = (y, tau) if transcription.expand else (ca.MX.sym("y", nq + nv), ca.MX.sym("tau", nv))
        self.F_rb = ca.Function("F_rb", [ys, taus], [rk4(self.f_rb, ys, (taus,), h, substeps)], ["y", "tau"], ["y_next"])
        # one RK4 step over the whole interval: the rigid body's approximate Hessian of ``one-step``
        self.F_rb_one_step = ca.Function("F_rb_one_step", [ys, taus], [rk4(self.f_rb, ys, (taus,), task.dt, 1)], ["y", "tau"], ["y_next"])
        # one explicit Euler step: the rigid body's approximate Hessian of ``euler-step``
        self.F_rb_euler_step = ca.Function("F_rb_euler_step", [ys, taus], [ys + task.dt * self.f_rb(ys, taus)], ["y", "tau"], ["y_next"])
        derivatives = model.aba_derivatives()
        #: ``(y, tau) -> (ydot, ddq_dq, ddq_dv, Minv)`` from Pinocchio's analytical derivatives
        #: of ABA (SX), or None (nq != nv)
        self.f_rb_derivatives = None
        if derivatives is not None:
            ddq, ddq_dq, ddq_dv, minv = derivatives(y[:nq], y[nq:], tau)  # one pass: ddq shares its terms
            self.f_rb_derivatives = ca.Function("f_rb_derivatives", [y, tau], [ca.vertcat(y[nq:], ddq), ddq_dq, ddq_dv, minv],
                                                ["y", "tau"], ["ydot", "ddq_dq", "ddq_dv", "Minv"])
        self._h = h
        self.substeps = substeps


        self.actuators = actuators
        m = ca.SX.sym("m", actuators.n_states)
        u = ca.SX.sym("u", nu)
        p = ca.SX.sym("p_fatigue", actuators.n_params)
        self.f_fatigue = ca.Function("f_fatigue", [m, u, p], [actuators.fatigue_rates(m, u, p)], ["m", "u", "p"], ["mdot"])
        # per group of halves with the same equations, the RK4 of one half (SX, or with
        # fatigue_calls MX calls of the model's SX right-hand side: less derivative code)
        self.fatigue_groups = actuators.fatigue_groups()
        self.fatigue_steps: dict[str, ca.Function] = {}
        kind = ca.MX if fatigue_calls else ca.SX
        for group in self.fatigue_groups:
            half = group.model
            mh, tl, ph = kind.sym("m", half.n_states()), kind.sym("TL"), kind.sym("p", half.n_params())
            name = FATIGUE_STEP + group.label
            self.fatigue_steps[name] = ca.Function(name, [mh, tl, ph], [rk4(half.rhs(), mh, (tl, ph), h, substeps)],
                                                   ["m", "TL", "p"], ["m_next"])
        self._fatigue_calls = fatigue_calls
        if fatigue_calls:
            self.F_fatigue = self._mapped_fatigue_step()
        else:
            self.F_fatigue = ca.Function("F_fatigue", [m, u, p], [rk4(self.f_fatigue, m, (u, p), h, substeps)], ["m", "u", "p"], ["m_next"])
        self.library = None  # the compiled library once :meth:`use` has swapped the functions
        #: the Hessian the rigid body's block was built for (:meth:`build_blocks`)
        self.blocks_hessian = "exact"
        #: derivative blocks per interval function (:mod:`fatigue_pin.ocp.blocks`), once built
        self.blocks: dict[str, BlockPair] = {}

        x = ca.SX.sym("x", nx)
        u_prev = ca.SX.sym("u_prev", nu)
        self.coupling = ca.Function("coupling", [x, u], [actuators.coupling(x[layout.m], u)], ["x", "u"], ["TL_plus_mf"])
        #: where the torque follows the state through the interval (the ``active`` coupling: the
        #: halves' active fractions; muscles: q and qdot too), the rigid body is integrated with it:
        #: ``F_rb_active(y, m, u, p) -> y_next``, the y part of RK4 of (y, m) (its m part is
        #: :attr:`F_fatigue`'s, m not depending on y); None otherwise
        #: (:attr:`~fatigue_pin.ocp.actuation_layer.ActuationLayer.torque_follows_state`)
        self.F_rb_active = self._active_rigid_body(h, substeps, fatigue_calls) if actuators.torque_follows_state else None
        v = IntervalVariables(x, u, u_prev, layout, model, actuators)
        integrands = [term.expression(v) for term in problem.costs if not term.terminal]
        terms = (ca.vertcat(*integrands) if integrands else ca.SX(0, 1)) * task.dt
        self.terms = ca.Function("terms", [x, u, u_prev], [terms], ["x", "u", "u_prev"], ["terms"])
        ends = [term.expression(v) for term in problem.costs if term.terminal]
        #: the terminal cost terms on one end state, ``terminal(x) -> (n_terminal,)`` (not times dt), or None
        self.terminal = ca.Function("terminal", [x], [ca.vertcat(*ends)], ["x"], ["terminal"]) if ends else None

    def analytical_rb_jacobian(self) -> ca.Function | None:
        """``jblk_F_rb(w) -> (y_next, J)`` with w = (y, tau) (18 rows for nv = 6): the RK4 of
        :attr:`F_rb` and its Jacobian by forward sensitivities, from Pinocchio's analytical
        derivatives of ABA (:attr:`f_rb_derivatives`) instead of automatic differentiation of
        ABA. Each stage k = f(y_s, tau) adds ``dk/dw = A dy_s/dw + [0 | B]`` with
        A = [[0, I], [ddq_dq, ddq_dv]] and B = [0; Minv]; the stages combine as the RK4 step
        does. The same values as ``ca.jacobian`` of :attr:`F_rb` to rounding. None without
        analytical derivatives."""
        if self.f_rb_derivatives is None:
            return None
        nq, nv = self.layout.nq, self.layout.nv
        ny = nq + nv
        w = ca.MX.sym("w", ny + nv)
        y, tau = w[:ny], w[ny:]
        S = ca.MX(ca.DM.eye(ny + nv)[:ny, :])  # dy/dw
        control = ca.MX(nv, ny)  # zeros beside Minv: d(ddq)/dtau acts on the tau columns only

        def stage(ys: ca.MX, Ss: ca.MX) -> tuple[ca.MX, ca.MX]:
            ydot, dq, dv, minv = self.f_rb_derivatives(ys, tau)
            return ydot, ca.vertcat(Ss[nq:, :], ca.mtimes(dq, Ss[:nq, :]) + ca.mtimes(dv, Ss[nq:, :]) + ca.horzcat(control, minv))

        y, S = rk4_sensitivities(stage, y, S, self._h, self.substeps)
        return ca.Function(JAC_BLOCK + "F_rb", [w], [y, S], ["w"], ["y", "J"])

    def rb_adjoint_hessian(self) -> ca.Function | None:
        """``hblk_F_rb(w, mu) -> tril(H)`` with w = (y, tau): the exact Hessian block of
        :attr:`F_rb` (H = d2/dw2 mu' y_next) by the second-order adjoint rule of
        :func:`~fatigue_pin.ocp.sensitivities.rk4_adjoint_hessian`: each RK4 stage's curvature of
        ABA in (q, qdot, tau) weighed by the stage's adjoint and carried by
        its forward sensitivities (Pinocchio's analytical first derivatives where the model has
        them). The same values as CasADi's Hessian of the flow to rounding. None where nq != nv."""
        nq, nv = self.layout.nq, self.layout.nv
        if nq != nv:
            return None
        ny = nq + nv
        ys, taus, lam = ca.SX.sym("y", ny), ca.SX.sym("tau", nv), ca.SX.sym("lam", nv)
        ddq = self.f_rb(ys, taus)[nq:]
        curvature = ca.Function("f_rb_curvature", [ys, taus, lam], [ca.hessian(ca.dot(lam, ddq), ca.vertcat(ys, taus))[0]],
                                ["y", "tau", "lam"], ["H"])
        w, mu = ca.MX.sym("w", ny + nv), ca.MX.sym("mu", ny)
        y, tau = w[:ny], w[ny:]
        eye = ca.DM.eye(ny + nv)
        if self.f_rb_derivatives is not None:
            stage = self.f_rb_derivatives
        else:
            stage = ca.Function("f_rb_first", [ys, taus], [self.f_rb(ys, taus), ca.jacobian(ddq, ys[:nq]), ca.jacobian(ddq, ys[nq:]),
                                                             ca.jacobian(ddq, taus)])

        def first(Z: ca.MX) -> tuple[ca.MX, ca.MX, ca.MX]:
            ydot, dq, dv, minv = stage(Z, tau)
            gz = ca.vertcat(ca.horzcat(ca.MX(nq, nq), ca.MX(ca.DM.eye(nq))), ca.horzcat(dq, dv))
            return ydot, gz, ca.vertcat(ca.MX(nq, nv), minv)

        H = rk4_adjoint_hessian(first, lambda Z, lam: curvature(Z, tau, lam[nq:]), y, ca.MX(eye[:ny, :]), ca.MX(eye[ny:, :]),
                                mu, self._h, self.substeps)
        return ca.Function(HESS_BLOCK + "F_rb", [w, mu], [ca.tril(H)], ["w", "mu"], ["H"])

    #: library functions that only the transcription's constraints evaluate (no other NLP, such
    #: as the moving-horizon estimator's, differentiates them): with derivative blocks they are
    #: compiled without derivative functions. (Not the fatigue steps: :attr:`F_fatigue`, which
    #: the estimator differentiates, is assembled around them.)
    blocks_only = ("F_rb",)

    def _mapped_fatigue_step(self) -> ca.Function:
        """``F_fatigue(m, u, p) -> m_next`` of all halves as maps of :attr:`fatigue_steps` (MX;
        around the compiled steps once :meth:`use` has swapped them, so a library holds the
        fatigue step once, for one half per group)."""
        A = self.actuators
        m, u, p = ca.MX.sym("m", A.n_states), ca.MX.sym("u", A.nu), ca.MX.sym("p_fatigue", A.n_params)
        return ca.Function("F_fatigue", [m, u, p], [self.fatigue_by_groups(m, u, p)], ["m", "u", "p"], ["m_next"])

    def fatigue_by_groups(self, m: ca.MX, u: ca.MX, p: ca.MX, call: Callable[..., ca.MX] | None = None) -> ca.MX:
        """The fatigue states after one interval, (n_states, K), from states ``m`` (n_states, K),
        controls ``u`` (nu, K) and parameters ``p`` (n_params, 1) or (n_params, K): per group of
        halves (:attr:`fatigue_groups`) one ``map`` of its one-half step over its halves and the
        K columns. Column ``k * n_g + i`` of a group's map is its half i in column k. ``call(f,
        n, *args)`` maps ``f`` over ``n`` columns (default ``f.map(n)(*args)``; the transcription
        records its maps). Every operation around the maps is a selection, a reshape or the
        division of a torque by its limit, so the maps' inputs are affine in (m, u) and the
        states linear in their outputs, as the derivative blocks need
        (:mod:`fatigue_pin.ocp.blocks`). The same values as the RK4 of all halves at once
        (:attr:`f_fatigue`) to rounding: the halves are independent."""
        call = call or (lambda f, n, *args: f.map(n)(*args))
        K = m.size2()
        TL = self.actuators.control_target_loads(u)
        parts, rows = [], []
        for group in self.fatigue_groups:
            f = self.fatigue_steps[FATIGUE_STEP + group.label]
            ns, npar, nh = group.model.n_states(), group.model.n_params(), len(group.halves)
            Pg = p[list(group.param_rows), :]
            Pg = ca.reshape(Pg, npar, nh * K) if p.size2() == K else ca.repmat(ca.reshape(Pg, npar, nh), 1, K)
            out = call(f, nh * K, ca.reshape(m[list(group.state_rows), :], ns, nh * K),
                       ca.reshape(TL[list(group.halves), :], 1, nh * K), Pg)
            parts.append(ca.reshape(out, ns * nh, K))
            rows += group.state_rows
        stacked = ca.vertcat(*parts)
        if rows == list(range(len(rows))):
            return stacked
        return stacked[np.argsort(rows).tolist(), :]  # back to the halves' order

    def _active_rigid_body(self, h: float, substeps: int, one_direction: bool = False) -> ca.Function:
        """``F_rb_active(y, m, u, p) -> y_next``: RK4 of ``(y, m)`` with the joint torque of the
        halves' active fractions (``active`` coupling) or of the muscles, its y part (RK4 of y
        alone where that torque does not depend on m: the same y part). MX calls of the SX
        right-hand sides, as :attr:`F_rb`; ``one_direction``: their derivatives one direction at
        a time (for compiled code), except in the Jacobian block (:attr:`_F_rb_active_jacobian`)."""
        A, L = self.actuators, self.layout
        ny = L.nq + L.nv
        y, m = ca.MX.sym("y", ny), ca.MX.sym("m", A.n_states)
        u, p = ca.MX.sym("u", A.nu), ca.MX.sym("p_fatigue", A.n_params)
        z = ca.SX.sym("z", ny + A.n_states)
        us, ps = ca.SX.sym("u", A.nu), ca.SX.sym("p", A.n_params)
        tau = A.joint_torque(us, z[ny:], z[:ny])  # muscles: on (q, qdot) too
        #: ``(y, u, p) -> (ydot, d(ddq)/d(y, u))`` of a torque of (q, qdot, u) alone, for
        #: :meth:`active_sensitivity_jacobian`; None where the torque depends on m
        self._active_stage = None
        #: ``(y, u, p, lam) -> d2/d(y, u)2 (lam' ddq)`` of that torque, for :meth:`active_adjoint_hessian`
        self._active_curvature = None
        if ca.depends_on(tau, z[ny:]):
            zs, rates, z0 = z, ca.vertcat(self.f_rb(z[:ny], tau), self.f_fatigue(z[ny:], us, ps)), ca.vertcat(y, m)
        else:
            # a torque of (q, qdot, u) alone (muscles whose force the fatigue states do not scale):
            # RK4 of y alone has the same y part, without the fatigue states' stages, which the
            # derivative calls of compiled code would carry
            zs, rates, z0 = z[:ny], self.f_rb(z[:ny], tau), y
            if L.nq == L.nv and not ca.depends_on(rates, ps):
                self._active_stage = ca.Function("f_active_stage", [zs, us, ps], [rates, ca.jacobian(rates[L.nq:], ca.vertcat(zs, us))],
                                                 ["y", "u", "p"], ["ydot", "dddq"])
                lam = ca.SX.sym("lam", L.nv)  # the qdot rows are linear: only ddq's curvature
                self._active_curvature = ca.Function("f_active_curvature", [zs, us, ps, lam],
                                                     [ca.hessian(ca.dot(lam, rates[L.nq:]), ca.vertcat(zs, us))[0]],
                                                     ["y", "u", "p", "lam"], ["H"])

        def flow(options: dict) -> tuple[ca.Function, ca.Function]:
            f = ca.Function("f_active", [zs, us, ps], [rates], options)
            return f, ca.Function("F_rb_active", [y, m, u, p], [rk4(f, z0, (u, p), h, substeps)[:ny]], ["y", "m", "u", "p"], ["y_next"])

        # compiled, the second derivatives one direction at a time: the Hessian block of the muscle
        # curl (arm26, polynomial paths) is 2.0 MB of C against 11.7 MB with CasADi's bundled
        # directions (docs/muscles.md, "Compiled muscle problems"); uncompiled, the bundled
        # directions are five times faster in CasADi's virtual machine. The Jacobian block takes
        # its ny adjoint directions together (one forward pass per stage instead of ny): 40 % less
        # CPU for the muscle curl's Jacobian (docs/muscles.md, "To exhaustion").
        #: the flow whose Jacobian block :meth:`build_blocks` takes (bundled directions), or None
        self._F_rb_active_jacobian = flow({"max_num_dir": ny})[1] if one_direction else None
        f, F = flow({"max_num_dir": 1} if one_direction else {})
        dt = h * substeps
        # the approximate Hessians' flows (solver.hessian): one RK4 step, one explicit Euler step
        self.F_rb_active_one_step = ca.Function("F_rb_active_one_step", [y, m, u, p], [rk4(f, z0, (u, p), dt, 1)[:ny]],
                                                ["y", "m", "u", "p"], ["y_next"])
        self.F_rb_active_euler_step = ca.Function("F_rb_active_euler_step", [y, m, u, p], [(z0 + dt * f(z0, u, p))[:ny]],
                                                  ["y", "m", "u", "p"], ["y_next"])
        return F

    def _active_block_inputs(self, diff: tuple[int, ...]) -> tuple[list[int], ca.MX, list[ca.MX], tuple[ca.MX, ca.MX, ca.MX]]:
        """The inputs of a block of :attr:`F_rb_active` for the differentiated inputs ``diff``:
        the sizes of those inputs, w (their concatenation), the other inputs' symbols, and
        (y, u, p) as pieces of w or as those symbols."""
        F = self.F_rb_active
        sizes = [F.size1_in(i) for i in diff]
        w = ca.MX.sym("w", sum(sizes))
        pieces = dict(zip(diff, ca.vertsplit(w, list(np.cumsum([0, *sizes])))))
        others = [ca.MX.sym(F.name_in(i), F.sparsity_in(i)) for i in range(F.n_in()) if i not in diff]
        given = dict(zip([i for i in range(F.n_in()) if i not in diff], others))
        return sizes, w, others, (pieces[0], pieces.get(2, given.get(2)), given[3])

    def active_sensitivity_jacobian(self, diff: tuple[int, ...]) -> ca.Function | None:
        """``jblk_F_rb_active(w, *others) -> (y_next, J)``: the RK4 of :attr:`F_rb_active` and its
        Jacobian by forward sensitivities, for a torque of (q, qdot, u) alone (the muscles'), else
        None. Each RK4 stage needs the Jacobian of its right-hand side, whose qdot rows are
        ``[0, I | 0]`` and whose ddq rows take two reverse sweeps (nv of them) of one stage
        (:attr:`_active_stage`); the sensitivities S = dy/d(y, u) then combine as the RK4 step
        does. CasADi's Jacobian of the flow takes ny reverse sweeps through every stage instead:
        the muscle curl's Jacobian block, 0.75 M operations against 1.40 M (docs/muscles.md, "To
        exhaustion"). The same values as ``ca.jacobian`` to rounding; the columns of m (the flow
        does not depend on it) are structural zeros. ``diff``: the differentiated inputs of
        ``F_rb_active(y, m, u, p)``, as :meth:`build_blocks` has them."""
        stage = self._active_stage
        F = self.F_rb_active
        if stage is None or F is None or 3 in diff or 0 not in diff:
            return None
        nq, ny, nu = self.layout.nq, self.layout.nq + self.layout.nv, F.size1_in(2)
        sizes, w, others, (y, u, p) = self._active_block_inputs(diff)
        S = ca.MX(ca.DM.eye(ny + nu)[:ny, :])  # dy/d(y, u)
        tail = ca.MX(ca.DM.eye(ny + nu)[ny:, :])  # du/d(y, u)

        def rates(ys: ca.MX, Ss: ca.MX) -> tuple[ca.MX, ca.MX]:
            ydot, dddq = stage(ys, u, p)
            return ydot, ca.vertcat(Ss[nq:, :], ca.mtimes(dddq[:, :ny], Ss) + ca.mtimes(dddq[:, ny:], tail))

        y, S = rk4_sensitivities(rates, y, S, self._h, self.substeps)
        columns = {0: S[:, :ny], 1: ca.MX(ny, F.size1_in(1)), 2: S[:, ny:]}
        J = ca.horzcat(*[columns[i] for i in diff])
        names = ["w", *[F.name_in(i) for i in range(F.n_in()) if i not in diff]]
        return ca.Function(JAC_BLOCK + F.name(), [w, *others], [y, J], names, ["y", "J"])

    def active_adjoint_hessian(self, diff: tuple[int, ...]) -> ca.Function | None:
        """``hblk_F_rb_active(w, *others, mu) -> tril(H)``: the exact Hessian block of
        :attr:`F_rb_active` (H = d2/dw2 mu' y_next) by the second-order adjoint rule of
        :func:`~fatigue_pin.ocp.sensitivities.rk4_adjoint_hessian`, for a torque of (q, qdot, u)
        alone (the muscles'), else None: each RK4 stage's curvature of ddq (a Hessian in (q, qdot,
        u) of one stage, :attr:`_active_curvature`) weighed by the stage's adjoint and carried by
        its forward sensitivities. The same values as CasADi's Hessian of the flow to rounding,
        with a fraction of its work and code (docs/ocp.md, "What makes a robot window
        faster"). ``diff`` as for :meth:`active_sensitivity_jacobian`. The fatigue states' rows
        and columns are structural zeros."""
        stage, curvature, F = self._active_stage, self._active_curvature, self.F_rb_active
        if stage is None or curvature is None or F is None or 3 in diff or 0 not in diff:
            return None
        nq, ny, nu = self.layout.nq, self.layout.nq + self.layout.nv, F.size1_in(2)
        sizes, w, others, (y, u, p) = self._active_block_inputs(diff)
        mu = ca.MX.sym("mu", ny)
        nr = ny + (nu if 2 in diff else 0)  # the differentiated (y, u)
        eye = ca.DM.eye(nr)
        S, C = ca.MX(eye[:ny, :]), (ca.MX(eye[ny:, :]) if 2 in diff else ca.MX(nu, nr))

        def first(Z: ca.MX) -> tuple[ca.MX, ca.MX, ca.MX]:
            ydot, dddq = stage(Z, u, p)
            gz = ca.vertcat(ca.horzcat(ca.MX(nq, nq), ca.MX(ca.DM.eye(nq))), dddq[:, :ny])
            return ydot, gz, ca.vertcat(ca.MX(nq, nu), dddq[:, ny:])

        H = rk4_adjoint_hessian(first, lambda Z, lam: curvature(Z, u, p, lam[nq:]), y, S, C, mu, self._h, self.substeps)
        # into the rows and columns of w: m's are structural zeros (the flow does not depend on it)
        rows = {0: list(range(ny)), 2: list(range(ny, nr))}
        place, offset = [], 0
        for i, n in zip(diff, sizes):
            if i in rows:
                place += list(range(offset, offset + n))
            offset += n
        full = ca.MX(offset, offset)
        full[place, place] = H
        out = ca.tril(full)
        names = ["w", *[F.name_in(i) for i in range(F.n_in()) if i not in diff], "mu"]
        return ca.Function(HESS_BLOCK + F.name(), [w, *others, mu], [out], names, ["H"])

    def rigid_body_step(self, y: ca.MX, m: ca.MX, u: ca.MX, p: ca.MX, T: ca.MX | None = None,
                        call: Callable[..., ca.MX] | None = None) -> ca.MX:
        """(q, qdot) after every interval, (nq + nv, K), from y (nq + nv, K), fatigue states m
        (n_states, K), controls u (nu, K), fatigue parameters p (n_params, 1) and, if given, the
        joint torques T (nv, K) (else the actuators' :meth:`joint_torque` of u; under the
        ``active`` coupling T is not used: the torque follows m within the interval). ``call(f, n,
        *args)`` maps ``f`` over ``n`` columns (default ``f.map(n)(*args)``)."""
        call = call or (lambda f, n, *args: f.map(n)(*args))
        K = y.size2()
        if self.F_rb_active is not None:
            return call(self.F_rb_active, K, y, m, u, ca.repmat(p, 1, K) if p.size2() == 1 else p)
        return call(self.F_rb, K, y, self.actuators.joint_torque(u) if T is None else T)

    def library_functions(self) -> list[ca.Function]:
        """The functions a compiled library holds (:mod:`fatigue_pin.ocp.compiled`)."""
        rb = self.F_rb if self.F_rb_active is None else self.F_rb_active
        return [rb, *self.fatigue_steps.values(), self.coupling, self.terms]

    def build_blocks(self, diffs: Mapping[str, tuple[int, ...]], hessian: str = "exact", jacobian: str = "automatic") -> None:
        """Build the derivative blocks (:func:`fatigue_pin.ocp.blocks.block_functions`) of the
        library functions named in ``diffs``, for the inputs given there (those that depend on
        the decision variables), from the original functions. ``hessian``
        (:attr:`SolverOptions.hessian <fatigue_pin.ocp.solver.SolverOptions.hessian>`) says what
        the rigid body's Hessian block holds: ``exact``, nothing (``gauss-newton``), or the
        second derivatives of one RK4 step (``one-step``) or one explicit Euler step
        (``euler-step``) over the interval. ``jacobian``
        (:attr:`SolverOptions.dynamics_jacobian <fatigue_pin.ocp.solver.SolverOptions.dynamics_jacobian>`):
        ``analytical`` takes the rigid body's Jacobian block from :meth:`analytical_rb_jacobian`
        where the model has one and both y and tau are differentiated."""
        approximations = {"F_rb": {"one-step": self.F_rb_one_step, "euler-step": self.F_rb_euler_step}}
        if self.F_rb_active is not None:
            approximations["F_rb_active"] = {"one-step": self.F_rb_active_one_step, "euler-step": self.F_rb_active_euler_step}
        for f in self.library_functions():
            if f.name() not in diffs:
                continue
            rb = f.name() == "F_rb"
            diff = tuple(int(i) for i in diffs[f.name()])
            ready = self.analytical_rb_jacobian() if rb and jacobian == "analytical" and diff == (0, 1) else None
            if f.name() == "F_rb_active" and self._F_rb_active_jacobian is not None:
                ready = self.active_sensitivity_jacobian(diff) or block_functions(self._F_rb_active_jacobian, diff, hessian=False).jac
            # gauss-newton drops the rigid body's second derivatives, with a state-dependent torque too
            exact = not (f.name() in ("F_rb", "F_rb_active") and hessian == "gauss-newton")
            # the muscles' exact Hessian block by the stages' adjoints (active_adjoint_hessian)
            curvature = None
            if hessian == "exact" and f.name() == "F_rb_active":
                curvature = self.active_adjoint_hessian(diff)
            elif hessian == "exact" and rb and diff == (0, 1):
                curvature = self.rb_adjoint_hessian()
            self.blocks[f.name()] = block_functions(f, diff, hessian=exact,
                                                    hessian_of=approximations.get(f.name(), {}).get(hessian), jacobian=ready,
                                                    hessian_block=curvature)
        self.blocks_hessian = hessian

    def block_functions(self) -> list[ca.Function]:
        """The block functions of :attr:`blocks` (compiled without derivatives)."""
        return [g for pair in self.blocks.values() for g in (pair.jac, pair.hess) if g is not None]

    def use(self, library) -> None:
        """Replace :meth:`library_functions` (and the block functions) by their compiled
        externals from ``library``."""
        functions = library.functions()
        for f in self.library_functions():
            if f.name() in self.fatigue_steps:
                self.fatigue_steps[f.name()] = functions[f.name()]
            else:
                setattr(self, f.name(), functions[f.name()])
        if self._fatigue_calls:
            self.F_fatigue = self._mapped_fatigue_step()
        self.blocks = {name: BlockPair(pair.diff, functions[pair.jac.name()], None if pair.hess is None else functions[pair.hess.name()])
                       for name, pair in self.blocks.items() if pair.jac.name() in functions}
        self.library = library

    def fatigue_rollout(self, n: int) -> ca.Function:
        """``fatigue_rollout(m0, U, P) -> M``: :attr:`F_fatigue` over ``n`` intervals in one call,
        each step's states clipped to [0, 1]; m0 (n_states,), U (nu, n), P (n_params, n), M
        (n_states, n) the states at nodes 1..n. Built once per ``n`` and per :attr:`F_fatigue`
        (a compiled library swaps it); a Python loop of ``F_fatigue`` calls gives the same values."""
        key = (int(n), id(self.F_fatigue))
        cache = self.__dict__.setdefault("_fatigue_rollouts", {})
        if key not in cache:
            F = self.F_fatigue
            m, u, p = ca.MX.sym("m", F.size1_in(0)), ca.MX.sym("u", F.size1_in(1)), ca.MX.sym("p", F.size1_in(2))
            clipped = ca.Function("fatigue_step_clipped", [m, u, p], [ca.fmin(ca.fmax(F(m, u, p), 0.0), 1.0)])
            cache[key] = clipped.mapaccum("fatigue_rollout", int(n), [0], [0])
        return cache[key]

    def step(self, x: np.ndarray, u: np.ndarray, p: np.ndarray) -> np.ndarray:
        """Numeric state after one interval, shape (nx,)."""
        L = self.layout
        ny = L.nq + L.nv
        if self.F_rb_active is not None:
            y = np.asarray(self.F_rb_active(x[:ny], x[L.m], u, p)).reshape(-1)
        else:
            y = np.asarray(self.F_rb(x[:ny], self.actuators.joint_torque(np.asarray(u, dtype=float)))).reshape(-1)
        m = np.asarray(self.F_fatigue(x[L.m], u, p)).reshape(-1)
        return np.concatenate([y, m])
