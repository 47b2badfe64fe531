"""How a problem becomes an NLP: direct multiple shooting with RK4, on a grid of nodes.

For a :class:`~fatigue_pin.ocp.problem.Problem` and a horizon of ``n_cycles`` cycles (N = n_cycles *
intervals_per_cycle intervals of length dt), :class:`Ocp` builds::

    x_{k+1} = F(x_k, u_k)                         gaps, k = 0..N-1 (rigid body and fatigue
                                                  integrated by separate RK4 functions)
    T_k = B u_k                                   auxiliary joint torque (0 on passive joints)
    0 <= TL_h(u_k) + m_fatigued,h(x_k) <= 1       every half h, every node (u_N := u_{N-1}), under
                                                  the `tl+mf<=1` coupling only (docs/model.md)
    X_lb <= x_k <= X_ub                            model bounds, [0, 1] on fatigue states, the
                                                  initial state at node 0, joint targets at
                                                  their nodes, joint ranges, and (sliding
                                                  windows) the cyclic end box at node N
    lower <= h(x_k) <= upper                       state constraints of the task at their nodes
                                                  (at node 0 widened to h(x_init))
    u in the halves' torque ranges
    J = sum_k dt * sum_i w_i L_i(x_k, u_k, u_{k-1})

Every weight, fatigue parameter, bound and the initial state is a *parameter* of the NLP, so
one NLP (and one compiled library) per horizon serves every cost, stabiliser, window and
initial state. Parameters are addressed by name (:class:`~fatigue_pin.ocp.solution.ParameterLayout`). The
interval functions are in :mod:`fatigue_pin.ocp.intervals`, the solution in
:mod:`fatigue_pin.ocp.solution`; ``IntervalFunctions``, ``rk4`` and ``OcpSolution`` are importable
from here too.

Design notes (measured on arm26, docs/ocp.md): the rigid-body RK4 is built from MX calls of the
SX dynamics (fast to compile), the fatigue RK4 is SX; IPOPT sees scaled variables (velocities
divided by their bound, torques by their limit). The interval functions are ``map``-ped and the
maps recorded (:class:`~fatigue_pin.ocp.blocks.MappedCall`), so that in library mode IPOPT's
Jacobian and Hessian are assembled from their per-interval derivative blocks.
"""

from __future__ import annotations

__all__ = ["GUESSES", "INTEGRATORS", "MAP_MODES", "IntervalFunctions", "Ocp", "OcpSolution", "ParameterLayout", "Transcription", "rk4"]

import time
from dataclasses import dataclass
from typing import Callable, Mapping

import casadi as ca
import numpy as np

from fatigue_pin.core.cores import usable_cores
from fatigue_pin.ocp import bounds
from fatigue_pin.ocp.blocks import MappedCall, differentiated_inputs, nlp_derivatives
from fatigue_pin.ocp.guesses import GUESSES, initial_guess
from fatigue_pin.core.errors import ParameterError
from fatigue_pin.core.settings import check_fields, is_bool, is_int, setting
from fatigue_pin.ocp.intervals import IntervalFunctions, rk4
from fatigue_pin.ocp.problem import Problem
from fatigue_pin.core.progress import Progress
from fatigue_pin.ocp.solution import OcpSolution, ParameterLayout
from fatigue_pin.ocp.solver import NLPSOL_OPTIONS, NlpResult, NlpSolver, SolverOptions, simple_bounds
from fatigue_pin.ocp.task import check_horizon, joint_target_pairs
from fatigue_pin.ocp.window_budget import WindowBudget, add_budget_rows, budget_values, require_window_budget
from fatigue_pin.core.text import shown

#: Integrators of the shooting intervals.
INTEGRATORS = ("rk4",)
#: How interval functions are mapped over the horizon.
MAP_MODES = ("auto", "serial", "openmp", "thread")


#: Most integrator steps per shooting interval (each is unrolled in the interval's expression).
MAX_SUBSTEPS = 1000


@dataclass(frozen=True)
class Transcription:
    """How the problem is discretised (not what it is, nor how it is solved).

    Attributes:
        substeps: integrator steps per shooting interval.
        integrator: ``rk4``.
        scaling: IPOPT works on scaled variables (velocities / their bound, torques / their
            limit): fewer iterations, same solution.
        parallel: how interval functions are mapped: ``serial``, ``thread`` (CasADi's VM on every
            core), ``openmp`` (generated C built with ``-fopenmp``), ``auto`` (``openmp`` in
            ``nlp`` mode, ``serial`` uncompiled; library mode: :attr:`Ocp.map_mode`).
        expand: integrate the rigid body as one expanded SX function per interval (slow to
            compile; kept for comparisons).
        torque_variable: the joint torque T = tau_plus + tau_minus (nv, N) is a decision variable
            of its own, tied by an equality row, and the rigid body takes T; ``False`` puts the
            sum of the halves into the rigid body directly (how the paper's code does it). Not
            used under the ``active`` coupling (:attr:`Ocp.torque_is_variable`).
        target_rows: joint targets as equality rows in g instead of fixed variables (bounds
            lb = ub); a target at node 0 then duplicates the fixed initial state (how the paper's
            code does it; its bounds are widened to that state where it misses the target by more
            than ``constr_viol_tol``, as :meth:`Ocp.state_bounds` lets the start state win). Same feasible set, other KKT
            systems: for comparisons.
    """

    substeps: int = setting(5, f"an integer in [1, {MAX_SUBSTEPS}]", lambda v: is_int(v) and 1 <= v <= MAX_SUBSTEPS)
    integrator: str = setting("rk4", f"one of {list(INTEGRATORS)}", lambda v: v in INTEGRATORS)
    scaling: bool = setting(True, "true or false", is_bool)
    parallel: str = setting("auto", f"one of {list(MAP_MODES)}", lambda v: v in MAP_MODES)
    expand: bool = setting(False, "true or false", is_bool)
    torque_variable: bool = setting(True, "true or false", is_bool)
    target_rows: bool = setting(False, "true or false", is_bool)

    def __post_init__(self) -> None:
        check_fields(self)

    def map_mode(self, compiled: bool) -> str:
        if self.parallel == "auto":
            return "openmp" if compiled else "serial"
        return self.parallel


class Ocp:
    """The multiple-shooting NLP of a problem over ``n_cycles`` cycles, ready to solve.

    Build once (symbolic functions, NLP, IPOPT instance, compiled code), then :meth:`solve` any
    number of times with other initial states, end boxes, weights, fatigue parameters or guesses.

    Args:
        problem: the problem.
        n_cycles: cycles in the horizon (fixes the structure).
        transcription: discretisation settings.
        solver: IPOPT settings.
        end_tolerance: if set, q and qdot at the last node are bounded to a reference state
            +- end_tolerance * (their bound range): the cyclic end condition of a window.
        guess: the default initial guess, ``rest``, ``physical`` or ``ik``.
        functions: interval functions to reuse (built from ``problem`` and ``transcription`` if
            None); pass the ones of another Ocp of the same problem to skip rebuilding them.
        progress: where a compile reports itself (a Reporter or a line callback; default quiet).
        window_budget: add the rows of a window budget (:mod:`fatigue_pin.ocp.window_budget`),
            their coefficients parameters of each solve (``budget``; none by default): a sliding
            run's ``heat_budget``.
    """

    def __init__(
        self,
        problem: Problem,
        n_cycles: int,
        transcription: Transcription | None = None,
        solver: SolverOptions | None = None,
        end_tolerance: float | None = None,
        guess: str = "rest",
        functions: IntervalFunctions | None = None,
        progress: Progress = None,
        window_budget: bool = False,
    ) -> None:
        t0 = time.perf_counter()
        check_horizon(problem.task, n_cycles, "n_cycles")
        (solver or SolverOptions()).check_ipopt()  # before anything is built or compiled
        if end_tolerance is not None and not (0 <= end_tolerance < 1):
            raise ParameterError(f"end_tolerance = {shown(end_tolerance)}: expected a fraction in [0, 1) or None")
        if guess not in GUESSES:
            raise ParameterError(f"guess = {guess!r}: expected one of {list(GUESSES)}")
        self.problem = problem
        self.model, self.actuators, self.task = problem.model, problem.actuators, problem.task
        self.n_cycles = int(n_cycles)
        self.transcription = transcription or Transcription()
        self.solver_options = solver or SolverOptions()
        self.end_tolerance = end_tolerance
        self.guess = guess
        if window_budget:
            require_window_budget(self.actuators)
        self.window_budget = bool(window_budget)
        self.actuators.check_stabiliser(self.task.dt / self.transcription.substeps, self.transcription.integrator)
        self.n_intervals = N = self.n_cycles * self.task.intervals_per_cycle
        library_mode = self.solver_options.library_mode
        self.functions = functions or IntervalFunctions(problem, self.transcription, fatigue_calls=library_mode)
        self.layout = self.functions.layout
        self.cost_terms = problem.cost_names
        self._check_hessian()
        library_compile_s = 0.0
        if library_mode and self.functions.library is None:
            self._build_library(progress)
            library_compile_s = self.functions.library.compile_time_s if self.functions.library else 0.0
        opti = self._formulate()
        if self._uses_blocks and self.functions.library is None and not self.functions.blocks:  # uncompiled
            self.functions.build_blocks(self._differentiated_inputs(opti.x), self.solver_options.hessian,
                                             self.solver_options.dynamics_jacobian)
        blocks = self._block_derivatives if self._uses_blocks else None
        self.nlp = NlpSolver(opti, self.solver_options, name=f"fatigue_ocp_{self.model.name}_{N}", progress=progress,
                             label=f"the {self.model.name} NLP of {self.n_cycles} cycles", derivatives=blocks,
                             kept_rows=self.kept_rows, calls=[c.out for c in self._mapped])
        #: compile time paid by this build (s): the library (once per model) or the whole NLP
        self.compile_time_s = self.nlp.compile_time_s + library_compile_s
        self.build_time_s = time.perf_counter() - t0
        self.t = np.linspace(0.0, N * self.task.dt, N + 1)

    @property
    def torque_is_variable(self) -> bool:
        """:attr:`Transcription.torque_variable`, but never where the torque follows the state
        within the interval (the ``active`` coupling, muscles)."""
        return self.transcription.torque_variable and not self.actuators.torque_follows_state

    @property
    def map_mode(self) -> str:
        """How the interval functions (and their derivative blocks) are mapped. In library mode
        with ``parallel="auto"``: ``thread`` (on an idle 2-core machine 10-17 % less time per
        iteration than ``serial`` from 4 to 32 cycles, sliding window 0.49 s against 0.60 s; on
        cores shared with other solver processes ``serial`` was 15-30 % faster, so set
        ``Transcription(parallel="serial")`` there; docs/ocp.md)."""
        if self.transcription.parallel == "auto" and self.solver_options.library_mode:
            # CasADi's virtual machine evaluates the maps of the compiled externals
            return "thread"
        return self.transcription.map_mode(self.solver_options.compile)

    @property
    def _map_args(self) -> tuple:
        """Arguments of ``Function.map`` after the count: :attr:`map_mode`, and the thread count
        with ``thread``."""
        mode = self.map_mode
        return (mode, usable_cores()) if mode == "thread" else (mode,)

    @property
    def mapped_calls(self) -> tuple[MappedCall, ...]:
        """The interval functions as mapped in the NLP (:class:`fatigue_pin.ocp.blocks.MappedCall`)."""
        return tuple(self._mapped)

    @property
    def library(self):
        """The per-model compiled library of the interval functions (library mode), or None."""
        return self.functions.library

    def _build_library(self, progress: Progress) -> None:
        """Compile (or find in the cache) the interval functions and the derivatives of them that
        this NLP evaluates, and use them. The derivative set is probed on a one-cycle NLP built
        with the original functions (it depends on the problem's structure, not on the horizon)."""
        import re

        from fatigue_pin.ocp.compiled import FunctionLibrary, requested_derivatives

        saved = self.n_intervals
        self.n_intervals = self.task.intervals_per_cycle
        try:
            probe = self._formulate()
            x, p, f, g = probe.x, probe.p, probe.f, probe.g
            gi, *_ = simple_bounds(x, p, g, probe.lbg, probe.ubg, self.kept_rows, [c.out for c in self._mapped])
            nlp = {"x": x, "p": p, "f": f, "g": g[gi]}
            opts: dict = {"print_time": False, **NLPSOL_OPTIONS}  # the derivatives the solves will request
            if self._uses_blocks:
                self.functions.build_blocks(self._differentiated_inputs(x), self.solver_options.hessian,
                                             self.solver_options.dynamics_jacobian)
                opts.update(self._block_derivatives(nlp) or {})
                if not opts.keys() & {"jac_g", "hess_lag"}:
                    self.functions.blocks = {}  # not usable for this problem: CasADi's own derivatives
            solver = ca.nlpsol("probe", "ipopt", nlp, opts)
        finally:
            self.n_intervals = saved
        functions = self.functions.library_functions()
        # with the blocks, only the gradients (adj1_) are evaluated of the interval functions
        derivatives = requested_derivatives(solver, [fn.name() for fn in functions])
        # a function only this NLP evaluates, whose derivatives all come from its blocks, is
        # compiled without derivative code (the UR5's rigid body: a quarter of the library's C)
        plain = [fn for fn in functions if fn.name() in self.functions.blocks_only and fn.name() in self.functions.blocks
                 and not derivatives[fn.name()]]
        functions = [fn for fn in functions if fn not in plain]
        derivatives = {fn.name(): derivatives[fn.name()] for fn in functions}
        name = re.sub(r"[^A-Za-z0-9_]", "_", f"{self.model.name}_intervals")
        library = FunctionLibrary.build(functions, name, self.solver_options.build_options(), derivatives=derivatives,
                                        progress=progress, description=f"the {self.model.name} interval functions",
                                        plain=plain + self.functions.block_functions(),
                                        background=self.solver_options.first_compile == "background")
        if library is not None:  # else compiling in the background: this build stays uncompiled
            self.functions.use(library)

    def _block_derivatives(self, nlp: Mapping[str, ca.MX]) -> dict[str, ca.Function] | None:
        """nlpsol's ``jac_g`` and ``hess_lag`` from the interval functions' derivative blocks
        (:func:`fatigue_pin.ocp.blocks.nlp_derivatives`), or None without usable blocks."""
        if not self.functions.blocks:
            return None
        return nlp_derivatives(nlp, self._mapped, self.functions.blocks, self._map_args)

    def _formulate(self) -> ca.Opti:
        """The NLP as a ``casadi.Opti`` problem; sets ``X, U, T``, the parameters and the
        cost-term function."""
        fn, layout, N = self.functions, self.layout, self.n_intervals
        nx, nu = layout.nx, layout.nu
        opti = ca.Opti()
        self.opti = opti
        self.x_scale, self.u_scale, self.t_scale = self._variable_scales()
        Xs = opti.variable(nx, N + 1)
        Us = opti.variable(nu, N)
        X = ca.diag(ca.DM(self.x_scale)) @ Xs
        U = ca.diag(ca.DM(self.u_scale)) @ Us
        if self.torque_is_variable:
            # joint torque tau_plus + tau_minus as its own variable: the rigid-body dynamics then
            # depend on nv torques instead of 2 na halves, which halves the exact Hessian's cost
            Ts = opti.variable(layout.nv, N)
            T = ca.diag(ca.DM(self.t_scale)) @ Ts
        else:  # the torque the actuators deliver (under the `active` coupling: from the states)
            T = self.actuators.joint_torque(U, X[layout.m, :N], X[: layout.nq + layout.nv, :N])
        self.X, self.U, self.T = X, U, T
        params = ParameterLayout(opti)
        P_fatigue = params.add("fatigue", self.actuators.n_params)
        P_weights = params.add("weights", len(self.cost_terms))
        X_lb, X_ub = params.add("X_lb", nx, N + 1), params.add("X_ub", nx, N + 1)
        U_lb, U_ub = params.add("U_lb", nu, N), params.add("U_ub", nu, N)
        self.params = params

        ny = layout.nq + layout.nv
        par = self._map_args
        #: the mapped interval functions (for the derivative blocks, :mod:`fatigue_pin.ocp.blocks`)
        self._mapped: list[MappedCall] = []

        def mapped(f: ca.Function, n: int, *args: ca.MX, how: tuple = par) -> ca.MX:
            out = f.map(n, *how)(*args)
            self._mapped.append(MappedCall(f, tuple(args), out, n))
            return out

        if self.torque_is_variable:
            opti.subject_to(T == self.actuators.joint_torque(U))
        opti.subject_to(X[:ny, 1:] == fn.rigid_body_step(X[:ny, :N], X[ny:, :N], U, P_fatigue, T, call=mapped))
        opti.subject_to(X[ny:, 1:] == self._fatigue_step(X[ny:, :N], U, P_fatigue, mapped))
        if self.actuators.coupling_rows:  # the `tl+mf<=1` coupling (docs/model.md)
            opti.subject_to(opti.bounded(0, mapped(fn.coupling, N + 1, X, ca.horzcat(U, U[:, N - 1]), how=()), 1))
        opti.subject_to(opti.bounded(X_lb, X, X_ub))
        opti.subject_to(opti.bounded(U_lb, U, U_ub))
        self._task_rows(opti, X, params)
        if self.window_budget:  # the cycle ending at every node, repeated to the task's end, stays within the capacity
            add_budget_rows(opti, params, X[layout.m, :], self.task.intervals_per_cycle, self.actuators.n_window_budget)
        opti.minimize(self._objective(X, U, P_weights, mapped))
        return opti

    def _task_rows(self, opti: ca.Opti, X: ca.MX, params: ParameterLayout) -> None:
        """The task's rows of g: joint targets as rows (``target_rows``; node 0 with parametric
        bounds) and the state constraints (StateConstraints, frame targets, planes) with
        parametric bounds at their nodes. Sets :attr:`kept_rows` and the state constraints."""
        N, nx = self.n_intervals, self.layout.nx
        #: rows of g that stay constraints although they bound one variable (``target_rows``)
        self.kept_rows: tuple[int, ...] = ()
        if self.transcription.target_rows:
            first = opti.g.numel()
            pairs = joint_target_pairs(self.task, self.model, N, self.layout)
            starts = [(j, a, b) for node, j, a, b in pairs if node == 0]
            if starts:  # bounds of the node-0 rows: the targets widened to the start (parameter_vector)
                S_lb, S_ub = params.add("start_targets_lb", len(starts)), params.add("start_targets_ub", len(starts))
            for i, (node, j, a, b) in enumerate(pairs):  # node 0 first (sorted by node)
                opti.subject_to(opti.bounded(S_lb[i], X[j, 0], S_ub[i]) if node == 0 else opti.bounded(a, X[j, node], b))
            self.kept_rows = tuple(range(first, opti.g.numel()))
        # state constraints of the task: expression rows with parametric bounds
        self._state_constraints = []
        for sc in self.task.expression_constraints(self.model, self.layout):  # StateConstraints, frame targets, planes
            if sc.expression.size1_in(0) != nx:
                raise ParameterError(f"task state constraint {sc.name!r} takes {sc.expression.size1_in(0)} inputs; expected nx = {nx}")
            nodes = self.task.nodes(sc.at, N)
            m = sc.expression.size1_out(0)
            lb = params.add(f"{sc.name}_lb", m, len(nodes))
            ub = params.add(f"{sc.name}_ub", m, len(nodes))
            values = sc.expression.map(len(nodes))(X[:, nodes])
            opti.subject_to(opti.bounded(lb, values, ub))
            self._state_constraints.append((sc, nodes))

    def _objective(self, X: ca.MX, U: ca.MX, P_weights: ca.MX, mapped: Callable[..., ca.MX]) -> ca.MX:
        """The objective from X (nx, N+1), U (nu, N) and the weights; sets the cost-term
        functions of :meth:`cycle_costs`."""
        fn, N, nx, nu = self.functions, self.n_intervals, self.layout.nx, self.layout.nu
        # objective: weighted named terms summed over intervals (running) and over the ends of
        # the phases (terminal); the same functions of (X, U) give the per-cycle costs
        running, terminal = self._running_rows, self._terminal_rows
        n_terms = len(running)
        Xn, Un = ca.MX.sym("X", nx, N + 1), ca.MX.sym("U", nu, N)
        terms = fn.terms.map(N)(Xn[:, :N], Un, ca.horzcat(Un[:, 0], Un[:, : N - 1])) if n_terms else ca.MX(0, N)
        self._terms_fn = ca.Function("interval_terms", [Xn, Un], [terms])
        W_running = P_weights[running] if running else ca.MX(0, 1)
        if n_terms and self._uses_blocks:  # the map itself in the graph, where the blocks find it
            objective = ca.dot(W_running, ca.sum2(mapped(fn.terms, N, X[:, :N], U, ca.horzcat(U[:, 0], U[:, : N - 1]), how=())))
        else:  # as before the blocks (the same generated code, so `nlp` mode keeps its cache entries)
            objective = ca.dot(W_running, ca.sum2(self._terms_fn(X, U))) if n_terms else ca.MX(0)
        if terminal:
            ends = self.end_nodes
            self._terminal_fn = ca.Function("end_terms", [Xn], [fn.terminal.map(len(ends))(Xn[:, ends])])
            objective = objective + ca.dot(P_weights[terminal], ca.sum2(fn.terminal.map(len(ends))(X[:, ends])))
        return objective

    @property
    def _running_rows(self) -> list[int]:
        """Positions in :attr:`cost_terms` of the running terms (integrated over the intervals)."""
        return [i for i, t in enumerate(self.problem.costs) if not t.terminal]

    @property
    def _terminal_rows(self) -> list[int]:
        """Positions in :attr:`cost_terms` of the terminal terms (on the ends of the phases)."""
        return [i for i, t in enumerate(self.problem.costs) if t.terminal]

    @property
    def end_nodes(self) -> list[int]:
        """The last node of every phase (cycle): n, 2n, ..., N, where terminal costs apply."""
        return list(range(self.task.intervals_per_cycle, self.n_intervals + 1, self.task.intervals_per_cycle))

    def _fatigue_step(self, M: ca.MX, U: ca.MX, P: ca.MX, mapped: Callable[..., ca.MX]) -> ca.MX:
        """The fatigue states after every interval, (n_states, N), from M (n_states, N), U (nu, N)
        and the fatigue parameters P, through ``mapped(f, n, *args)``. With the derivative blocks,
        one map per group of halves of its one-half step
        (:meth:`~fatigue_pin.ocp.intervals.IntervalFunctions.fatigue_by_groups`), so that a block
        differentiates one half, not all; otherwise one map of the all-halves ``F_fatigue`` as
        before the blocks (the same generated code, so ``nlp`` mode keeps its cache entries)."""
        if self._uses_blocks:
            return self.functions.fatigue_by_groups(M, U, P, call=mapped)
        return mapped(self.functions.F_fatigue, M.size2(), M, U, P)

    @property
    def _uses_blocks(self) -> bool:
        """Whether IPOPT gets the derivative-block Jacobian and Hessian
        (:attr:`SolverOptions.derivative_blocks`: by default in library mode)."""
        options = self.solver_options
        if options.derivative_blocks is None:
            return options.library_mode
        return bool(options.derivative_blocks) and (options.library_mode or not options.compile)

    def _check_hessian(self) -> None:
        """An approximate Hessian exists only as derivative blocks; and blocks reused from
        another Ocp must have been built for this one's Hessian."""
        hessian = self.solver_options.hessian
        if hessian != "exact" and not self._uses_blocks:
            raise ParameterError(f"SolverOptions.hessian = {hessian!r} needs the derivative blocks: "
                                 "expected compile_mode = 'library' (or derivative_blocks = true without compiling)")
        if self.functions.blocks and self.functions.blocks_hessian != hessian:
            raise ParameterError(f"the interval functions were built for SolverOptions.hessian = {self.functions.blocks_hessian!r}, "
                                 f"not {hessian!r}; build them again (functions=None)")

    def _differentiated_inputs(self, x: ca.MX) -> dict[str, tuple[int, ...]]:
        """Per mapped interval function, the inputs that depend on the decision variables ``x``."""
        return {c.function.name(): differentiated_inputs(c, x) for c in self._mapped}

    # -- parameters and bounds -------------------------------------------------------------------

    def _variable_scales(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Scales of the decision variables (state, control, joint torque): IPOPT solves for
        value / scale. Velocities are scaled by their bound, torques by their limit."""
        L = self.layout
        x, u, t = np.ones(L.nx), np.ones(L.nu), np.ones(L.nv)
        if self.transcription.scaling:

            def magnitude(lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
                """Largest |bound| per joint; 1 where it is infinite or zero."""
                m = np.maximum(np.abs(lower), np.abs(upper))
                return np.where(np.isfinite(m) & (m > 0), m, 1.0)

            x[L.v] = magnitude(self.model.v_lower, self.model.v_upper)
            tmax = magnitude(self.model.tau_lower, self.model.tau_upper)
            u = self.actuators.control_scales(tmax)  # each half by its joint's limit
            t = tmax  # 1 on a passive joint (its torque is 0)
        return x, u, t

    def initial_state(self) -> np.ndarray:
        """The problem's initial state (nx,)."""
        return self.problem.initial_state()

    def start_state(self, x_init: np.ndarray | None = None) -> np.ndarray:
        """``x_init`` (nx,) checked for size, or the problem's initial state when None."""
        if x_init is None:
            return self.initial_state()
        x_init = np.asarray(x_init, dtype=float).reshape(-1)
        if x_init.size != self.layout.nx:
            raise ParameterError(f"x_init has {x_init.size} entries; expected nx = {self.layout.nx}")
        return x_init

    def state_bounds(self, x_init: np.ndarray, x_end: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Node-wise state bounds, each (nx, N+1): :func:`fatigue_pin.ocp.bounds.state_bounds`
        with this Ocp's model, task, grid, ``target_rows`` and ``end_tolerance``."""
        return bounds.state_bounds(self.model, self.task, self.layout, self.n_intervals, x_init, x_end,
                                   target_rows=self.transcription.target_rows, end_tolerance=self.end_tolerance)

    def control_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounds of the actuator halves, each of shape (nu, N)."""
        N = self.n_intervals
        lo, hi = self.actuators.control_bounds()
        return np.tile(lo[:, None], (1, N)), np.tile(hi[:, None], (1, N))

    def parameter_vector(
        self,
        x_init: np.ndarray | None = None,
        x_end: np.ndarray | None = None,
        weights: Mapping[str, float] | np.ndarray | None = None,
        fatigue: np.ndarray | None = None,
        budget: WindowBudget | None = None,
    ) -> np.ndarray:
        """The NLP parameter vector of one solve.

        Args:
            x_init: initial state (nx,); default the problem's.
            x_end: reference of the end box (nx,), used when ``end_tolerance`` is set; default
                ``x_init`` (the box around the horizon's initial state).
            weights: cost weights, by name (others keep the problem's) or as a full vector.
            fatigue: stacked fatigue parameters (n_params,); default the actuators'.
            budget: the window budget of this solve (with ``window_budget``); default none.
        """
        x_init = self.start_state(x_init)
        X_lb, X_ub = self.state_bounds(x_init, x_init if x_end is None else x_end)
        U_lb, U_ub = self.control_bounds()
        values: dict[str, np.ndarray] = {
            "fatigue": self.actuators.param_vector() if fatigue is None else np.asarray(fatigue, dtype=float).reshape(-1),
            "weights": self.weight_vector(weights),
            "X_lb": X_lb, "X_ub": X_ub, "U_lb": U_lb, "U_ub": U_ub,
        }
        if "start_targets_lb" in self.params.names:
            values["start_targets_lb"], values["start_targets_ub"] = bounds.start_target_bounds(
                self.task, self.model, self.n_intervals, self.layout, x_init, self.solver_options.constr_viol_tol)
        for sc, nodes in self._state_constraints:
            values[f"{sc.name}_lb"], values[f"{sc.name}_ub"] = bounds.constraint_bounds(sc, nodes, x_init)
        if self.window_budget:
            values.update(budget_values(budget, self.task.intervals_per_cycle, self.n_intervals,
                                        self.actuators.n_window_budget, self.layout.n_fatigue))
        elif budget is not None:
            raise ParameterError("budget given to an Ocp built without window_budget")
        return self.params.vector(values)

    def weight_vector(self, weights: Mapping[str, float] | np.ndarray | None = None) -> np.ndarray:
        """Cost weights in :attr:`cost_terms` order from a mapping by name (or a full vector)."""
        if weights is None or isinstance(weights, Mapping):
            return self.problem.weight_vector(weights)
        w = np.asarray(weights, dtype=float).reshape(-1)
        if w.size != len(self.cost_terms):
            raise ParameterError(f"weights have {w.size} entries; expected one per cost term {list(self.cost_terms)}")
        return w

    # -- initial guess ------------------------------------------------------------------------------

    def initial_guess(self, x_init: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The initial guess named by ``guess`` (:mod:`fatigue_pin.ocp.guesses`): states (N+1, nx),
        controls (N, nu)."""
        return initial_guess(self, self.guess, x_init)

    def flatten(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Decision vector in the NLP's order (X, U[, T]) from states (N+1, nx) and controls (N, nu)."""
        x, u = np.asarray(x, dtype=float), np.asarray(u, dtype=float)
        xs, us = x / self.x_scale, u / self.u_scale
        parts = [xs.T.reshape(-1, order="F"), us.T.reshape(-1, order="F")]
        if self.torque_is_variable:
            parts.append((self.actuators.joint_torque(u) / self.t_scale).T.reshape(-1, order="F"))
        return np.concatenate(parts)

    def unflatten(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """States (N+1, nx) and controls (N, nu) from a decision vector."""
        N, L = self.n_intervals, self.layout
        nX, nU = L.nx * (N + 1), L.nu * N
        x = z[:nX].reshape((L.nx, N + 1), order="F").T * self.x_scale
        u = z[nX : nX + nU].reshape((L.nu, N), order="F").T * self.u_scale
        return x, u

    def cycle_costs(self, x: np.ndarray, u: np.ndarray, weights: np.ndarray) -> np.ndarray:
        """Weighted cost terms per cycle, shape (n_cycles, n_terms): the running terms summed over
        the cycle's intervals, the terminal ones at its last node."""
        out = np.zeros((self.n_cycles, len(self.cost_terms)))
        running, terminal = self._running_rows, self._terminal_rows
        if running:
            terms = np.asarray(self._terms_fn(x.T, u.T))  # (n_running, N)
            out[:, running] = terms.reshape(len(running), self.n_cycles, self.task.intervals_per_cycle).sum(axis=2).T
        if terminal:
            out[:, terminal] = np.asarray(self._terminal_fn(x.T)).T  # (n_cycles, n_terminal)
        return out * np.asarray(weights, dtype=float)

    # -- solving ----------------------------------------------------------------------------------

    def solve(
        self,
        x_init: np.ndarray | None = None,
        guess: tuple[np.ndarray, np.ndarray] | None = None,
        x_end: np.ndarray | None = None,
        warm: NlpResult | None = None,
        weights: Mapping[str, float] | np.ndarray | None = None,
        max_iter: int | None = None,
        fatigue: np.ndarray | None = None,
        warm_start: bool = False,
        budget: WindowBudget | None = None,
    ) -> OcpSolution:
        """Solve the OCP.

        Args:
            x_init: fixed initial state (nx,); default the problem's.
            guess: initial guess (states (N+1, nx), controls (N, nu)); default :meth:`initial_guess`.
            x_end: reference state of the end box (with ``end_tolerance`` set); default ``x_init``.
            warm: a previous result of the same NLP whose multipliers start this solve.
            weights: cost weights of this solve, by name or as a vector (default: the problem's).
            max_iter: IPOPT iteration limit of this solve (default: the solver options').
            fatigue: fatigue parameters of this solve (n_params,) (default: the actuators').
            warm_start: IPOPT starts from ``guess`` and ``warm``'s multipliers
                (:data:`~fatigue_pin.ocp.solver.WARM_START_OPTIONS`; :mod:`fatigue_pin.ocp.warm`).
            budget: the window budget's rows of this solve (:meth:`parameter_vector`).

        Returns:
            An :class:`OcpSolution`; check ``success`` before using it as optimal.
        """
        x_init = self.start_state(x_init)
        if guess is None:
            guess = self.initial_guess(x_init)
        w = self.weight_vector(weights)
        p = self.parameter_vector(x_init, x_end, w, fatigue, budget)
        z0 = self.flatten(*guess)
        res = self.nlp.solve(p, z0, warm.lam_x if warm else None, warm.lam_g if warm else None, max_iter=max_iter,
                             warm_start=warm_start)
        x, u = self.unflatten(res.x)
        return OcpSolution(
            t=self.t.copy(), x=x, u=u, layout=self.layout, actuator_names=self.actuators.half_names,
            status=res.status, success=res.success, iterations=res.iterations, wall_time_s=res.wall_time_s,
            nlp=res, cycle_costs=self.cycle_costs(x, u, w), objective=res.f, cost_terms=self.cost_terms,
        )

