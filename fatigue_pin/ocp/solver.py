"""How an optimal control problem is solved: from a CasADi Opti formulation to IPOPT.

The problem is written with ``casadi.Opti`` (see :mod:`fatigue_pin.ocp.transcription`); this module turns it
into an ``nlpsol`` once and re-solves it with new parameter values as often as needed:

1. ``opti.x, opti.p, opti.f, opti.g`` and the parametric ``opti.lbg, opti.ubg`` are taken from
   the Opti stack, and ``casadi.detect_simple_bounds`` moves every constraint that bounds one
   decision variable (state boxes, fixed initial state, task angles, end-of-window bounds) into
   IPOPT's variable bounds ``lbx, ubx``; only dynamics gaps and coupling constraints stay in ``g``.
2. With ``compile=True`` the NLP functions IPOPT needs (objective, constraints, gradient,
   Jacobian, Hessian of the Lagrangian) are generated as C, compiled with the system C compiler
   and loaded back. The shared library is cached on disk under a hash of the generated source, so
   the compile cost is paid once per model and discretisation, not per solve or per process.
3. A failed solve is a result, not an exception: the status, iteration count and last iterate
   are returned.
"""

from __future__ import annotations

import hashlib
import os
import sys
import tempfile
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Callable, Sequence

import casadi as ca
import numpy as np

from fatigue_pin.core.settings import check_fields, is_bool, is_int, is_number, is_str, is_strs, setting
from fatigue_pin.core.progress import Progress, as_reporter
from fatigue_pin.core.signals import watch
from fatigue_pin.core.streams import captured
from fatigue_pin.ocp.compiled import BuildOptions, cache_folder, cached_build, compile_shared, host_key, verify_entry
from fatigue_pin.ocp.ipopt_process import check_ipopt_options, limit_blas_threads
from fatigue_pin.ocp.riccati import RICCATI_AUTO_MAX_BLOCK, linear_solver_options, riccati_library, riccati_releaser, riccati_structure

#: How a compiled NLP is built (see :class:`SolverOptions`).
COMPILE_MODES = ("library", "nlp")
#: Lagrangian Hessians of :attr:`SolverOptions.hessian`.
HESSIANS = ("exact", "gauss-newton", "one-step", "euler-step")
#: How the rigid body's Jacobian block is taken (:attr:`SolverOptions.dynamics_jacobian`).
DYNAMICS_JACOBIANS = ("analytical", "automatic")
#: What a build does when the model's library is not cached yet (:attr:`SolverOptions.first_compile`).
FIRST_COMPILES = ("auto", "wait", "background")
#: ``first_compile = "auto"`` compiles in the background for full-horizon solves of at most this
#: many intervals (see :func:`resolve_first_compile`).
BACKGROUND_MAX_INTERVALS = 60
#: IPOPT options of a warm-started solve (:meth:`NlpSolver.solve` with ``warm_start``): start
#: from the given primal and dual point, pushed 1e-3 off the bounds, with barrier 1e-2 (on the small
#: curl: 30 % fewer iterations than cold windows; 1e-4 and 1e-6 gave 10-20 %).
WARM_START_OPTIONS = {"warm_start_init_point": "yes", "warm_start_bound_push": 1e-3, "warm_start_slack_bound_push": 1e-3,
                      "warm_start_mult_bound_push": 1e-3, "mu_init": 1e-2}
#: ``nlpsol`` options of every solve: no multipliers of the parameters (nothing uses them), and
#: so no ``nlp_grad`` function, whose reverse sweep through the rigid-body step would make the
#: compiled library carry that step's adjoint code although the derivative blocks give IPOPT
#: every derivative it needs (818 kB of C and about 22 s of compiler time on the UR5).
NLPSOL_OPTIONS = {"calc_lam_p": False, "no_nlp_grad": True}
#: IPOPT statuses counted as converged.
CONVERGED_STATUSES = ("Solve_Succeeded",)

#: IPOPT statuses that certify (locally) that the constraints cannot be met.
INFEASIBLE_STATUSES = ("Infeasible_Problem_Detected", "Restoration_Failed")
#: IPOPT statuses of a solve stopped by a limit before it converged or failed.
LIMIT_STATUSES = ("Maximum_Iterations_Exceeded", "Maximum_WallTime_Exceeded", "Maximum_CpuTime_Exceeded")


def failure_kind(status: str, constraint_violation: Sequence[float], tol: float) -> str:
    """Why a solve ended, from IPOPT's status and its primal infeasibility per iteration.

    Returns one of:
        ``converged``;
        ``infeasible``: IPOPT's infeasibility certificate (``Infeasible_Problem_Detected``) or a
            restoration phase that could not reduce the constraint violation (``Restoration_Failed``
            with the last iterate's violation above ``tol``);
        ``infeasible-growing``: stopped by a limit with the constraint violation above ``tol`` and
            larger at the end than at its lowest point by 10x (the iterates move away from
            feasibility);
        ``not-converged``: stopped by the iteration or time limit otherwise (feasible or
            approaching it, so more iterations or another start might converge), or a
            ``Restoration_Failed`` whose last iterate meets ``tol``: the line search stalled at a
            feasible point (an approximate Hessian's tail can), which is no verdict of infeasibility;
        ``numerical``: any other status (``Error_In_Step_Computation``,
            ``Search_Direction_Becomes_Too_Small``, ...): the step computation broke down.

    Args:
        status: IPOPT's ``return_status``.
        constraint_violation: inf_pr of every iteration (IPOPT's scaled primal infeasibility).
        tol: the acceptable constraint violation (``constr_viol_tol``).
    """
    if status in CONVERGED_STATUSES:
        return "converged"
    viol = np.asarray(constraint_violation, dtype=float)
    if status == "Restoration_Failed" and viol.size and viol[-1] <= tol:
        return "not-converged"
    if status in INFEASIBLE_STATUSES:
        return "infeasible"
    if status in LIMIT_STATUSES:
        if viol.size and viol[-1] > tol and viol[-1] > 10 * np.min(viol):
            return "infeasible-growing"
        return "not-converged"
    return "numerical"


@dataclass(frozen=True)
class SolverOptions:
    """IPOPT settings and how the NLP functions are evaluated.

    Attributes:
        linear_solver: IPOPT's linear solver (``mumps`` ships with CasADi; ``ma57``, ``ma27``,
            ... need HSL libraries on the machine); ``riccati``: this package's stage-wise solver
            of IPOPT's augmented system (:func:`~fatigue_pin.ocp.riccati.riccati_library`), loaded by IPOPT in place of
            HSL's MA27, so IPOPT's algorithm and iterates stay; a problem whose stages it cannot
            take falls back to ``mumps`` with one line saying why (:func:`~fatigue_pin.ocp.riccati.riccati_structure`).
            ``auto`` (the default): ``riccati`` where its library is installed and the NLP's
            stages are at most :data:`~fatigue_pin.ocp.riccati.RICCATI_AUTO_MAX_BLOCK` rows, where it is measured faster
            than MUMPS with the same iterations; ``mumps`` otherwise, without a message.
        tol: IPOPT ``tol`` (overall convergence tolerance; 1e-6, IPOPT's default 1e-8:
            :data:`fatigue_pin.ocp.ipopt_defaults.DEPARTURES` lists every setting unlike IPOPT's).
        constr_viol_tol: IPOPT ``constr_viol_tol``.
        max_iter: IPOPT iteration limit.
        max_wall_time: IPOPT wall-time limit per solve (s); ``None`` for none.
        print_level: IPOPT verbosity (0 silent, 5 IPOPT's default).
        compile: generate C for the NLP functions and compile it (cached on disk).
        compiler: C compiler command.
        compiler_flags: flags of the compile step. Measured per IPOPT iteration on the 16-cycle
            curl (2 cores): -O1 124 ms, -O2 115, -O3 116, -O2 -march=native 109, -O3
            -march=native 100 ms; -O0 was 10x slower than -O1. Compiling takes 70-80 s at -O2/-O3
            against 50-60 s at -O1. Code built for the native CPU is cached under a key that
            includes the CPU, so a shared cache never serves it to another machine.
        cache_dir: where compiled NLPs are kept (default ``$FATIGUE_PIN_CACHE`` or
            ``~/.cache/fatigue_pin``).
        mu_init: IPOPT's initial barrier parameter. 1 (IPOPT's default is 0.1): the first
            barrier problems keep the torque halves away from their zero bound while the
            trajectory is still far from feasible; 16-cycle curl from rest 98 iterations
            against 119, and 10-20 % fewer across costs and horizons (docs/ocp.md).
        perturb_dec_fact: how fast IPOPT lowers the Hessian regularisation after an
            indefinite iteration. 0.6 (default 1/3) keeps it near the last working value, so
            fewer extra factorisations are needed (16 cycles: 108 iterations at 90 ms against
            119 at 95 ms). Both together: 16 cycles from rest 101 iterations, 10.1 s against
            119, 11.9 s; 32 cycles 212, 44 s against 232, 54 s.
        ipopt: further IPOPT options, passed as they are (they override the fields above).
        compile_mode: with ``compile``: ``library`` (default) compiles the interval functions and
            the derivatives IPOPT needs of them once per model (:mod:`fatigue_pin.ocp.compiled`,
            cached under a key without the horizon) and lets CasADi's virtual machine assemble
            any horizon around them: a new horizon builds in seconds. ``nlp`` generates and
            compiles the whole NLP of each horizon (about a minute each on arm26); measured slower
            per iteration than ``library`` at 4, 16 and 32 cycles (docs/ocp.md, "Compiled code").
        compile_jobs: compiler processes for a library (default: every core this process may use).
        accept_acceptable: count IPOPT's ``Solved_To_Acceptable_Level`` as converged, as CasADi's
            ``success`` flag does (and so the authors' code, docs/authors-code.md D11). Default
            False: only ``Solve_Succeeded`` converges.
        derivative_blocks: give IPOPT the constraint Jacobian and the Lagrangian's Hessian
            assembled from per-interval blocks (:mod:`fatigue_pin.ocp.blocks`, compiled in the
            library) instead of CasADi's assembly around the maps: the same values, far fewer
            operations of the virtual machine per iteration. ``None`` (default): in ``library``
            mode; ``True``: also without compiling (blocks evaluated by CasADi); ``False``: never.
            Not used in ``nlp`` mode.
        hessian: the Lagrangian's Hessian IPOPT gets: ``exact``, or ``gauss-newton``: without the
            second derivatives of the rigid-body dynamics (the RK4 of ABA, with a torque that
            depends on the state, such as the muscles', inside it: Gauss-Newton for the
            rigid-body gaps), the exact Hessian of the costs, the fatigue dynamics, the coupling
            and the task's constraints kept. The same KKT point; only IPOPT's path differs, and
            each iteration and the compile skip the largest derivative (needs the derivative
            blocks, docs/ocp.md "Robot-scale speed"). ``one-step``: the rigid body's second
            derivatives from one RK4 step over each interval instead of ``substeps`` steps (an
            approximation of the same flow's curvature; the constraints, their Jacobian and so
            the optimum stay those of the transcription; with a torque that follows the state,
            one RK4 step of the rigid body with it, the muscles' included). ``euler-step``: the same from one
            explicit Euler step, ``dt`` times the Hessian of ABA (a tenth of the cost of
            ``one-step``'s on the UR5, docs/ocp.md "Robot-scale speed").
        dynamics_jacobian: how the Jacobian of the rigid body's RK4 (the derivative block
            ``jblk_F_rb``) is taken: ``analytical``: forward sensitivities through the RK4 stages
            from Pinocchio's analytical derivatives of ABA (``computeABADerivatives`` on SX;
            :meth:`IntervalFunctions.analytical_rb_jacobian
            <fatigue_pin.ocp.intervals.IntervalFunctions.analytical_rb_jacobian>`); ``automatic``:
            CasADi's automatic differentiation through ABA. The same values to rounding. Models
            with nq != nv (continuous joints) always use ``automatic``.
        blas_threads: threads of the BLAS under IPOPT's linear solver (the OpenBLAS that ships
            with CasADi, :func:`~fatigue_pin.ocp.ipopt_process.limit_blas_threads`); 0 leaves it as it is (the
            ``OPENBLAS_NUM_THREADS`` environment variable, else every core). 1 (default): the
            KKT systems of these problems are too small for threaded BLAS, whose idle threads
            spin against the ``thread`` maps of the interval functions: the UR5 window of
            docs/ocp.md "Robot-scale speed" took 130 against 177 ms per iteration, with a third of
            its CPU time spent in the kernel before.
        first_compile: what a library-mode build does when the model's library is not in the
            cache yet: ``wait`` compiles it, then solves; ``background`` starts the compile in a
            detached process (:mod:`fatigue_pin.ocp.background`) and solves this run with the
            uncompiled functions, so the next run finds the library; ``auto`` (default) is
            ``background`` for a full-horizon solve of at most :data:`BACKGROUND_MAX_INTERVALS`
            intervals (:func:`resolve_first_compile`) and ``wait`` otherwise (sliding windows,
            searches and longer horizons use the library many times over). The pendulum study's
            first run on 2 cores: 3.2 s against 22.7-26 s (docs/ocp.md, "Compiled code").
    """

    linear_solver: str = setting("auto", "'auto', 'riccati' or an IPOPT linear solver name (e.g. 'mumps')", is_str)
    tol: float = setting(1e-6, "a tolerance > 0", lambda v: is_number(v) and v > 0)
    constr_viol_tol: float = setting(1e-4, "a tolerance > 0", lambda v: is_number(v) and v > 0)
    max_iter: int = setting(3000, "an integer >= 0", lambda v: int(v) == v and v >= 0)
    max_wall_time: float | None = setting(None, "seconds > 0", lambda v: is_number(v) and v > 0)
    print_level: int = setting(0, "an integer 0..12", lambda v: is_int(v) and 0 <= v <= 12)
    compile: bool = setting(True, "true or false", is_bool)
    compiler: str = setting("gcc", "a C compiler command", is_str)
    compiler_flags: tuple[str, ...] = setting(("-O3", "-march=native"), "a list of strings", is_strs)
    cache_dir: Path | None = setting(None, "a folder", study=False)
    mu_init: float = setting(1.0, "a barrier parameter > 0", lambda v: is_number(v) and v > 0)
    perturb_dec_fact: float = setting(0.6, "a factor in (0, 1)", lambda v: is_number(v) and 0 < v < 1)
    ipopt: dict[str, Any] = setting(default_factory=dict, expected="a table of IPOPT options", check=lambda v: isinstance(v, dict))
    compile_mode: str = setting("library", "'library' (once per model) or 'nlp' (once per horizon)", lambda v: v in COMPILE_MODES)
    compile_jobs: int | None = setting(None, "a number of compiler processes >= 1", lambda v: is_int(v) and v >= 1)
    accept_acceptable: bool = setting(False, "true or false", is_bool)
    derivative_blocks: bool | None = setting(None, "true or false (none: in library mode)", is_bool)
    hessian: str = setting("exact", "'exact', 'one-step', 'euler-step' or 'gauss-newton'", lambda v: v in HESSIANS)
    dynamics_jacobian: str = setting("analytical", "'analytical' or 'automatic'", lambda v: v in DYNAMICS_JACOBIANS)
    blas_threads: int = setting(1, "a number of threads >= 1, or 0 (as the environment sets it)", lambda v: is_int(v) and v >= 0)
    first_compile: str = setting("auto", "'auto', 'wait' or 'background'", lambda v: v in FIRST_COMPILES)

    def __post_init__(self) -> None:
        check_fields(self)

    @property
    def library_mode(self) -> bool:
        """Whether the interval functions run from a per-model compiled library."""
        return self.compile and self.compile_mode == "library"

    def build_options(self):
        """Compiler, flags and cache folder for :mod:`fatigue_pin.ocp.compiled`."""
        return BuildOptions(compiler=self.compiler, flags=tuple(self.compiler_flags), cache_dir=self.resolved_cache_dir(),
                            jobs=self.compile_jobs)

    def ipopt_options(self) -> dict[str, Any]:
        """The option dictionary passed to ``nlpsol('ipopt')``."""
        ipopt: dict[str, Any] = {
            **linear_solver_options(self.linear_solver),
            "tol": self.tol,
            "constr_viol_tol": self.constr_viol_tol,
            "max_iter": int(self.max_iter),
            "print_level": int(self.print_level),
            "hessian_approximation": "exact",
            "mu_init": float(self.mu_init),
            "perturb_dec_fact": float(self.perturb_dec_fact),
            "sb": "yes",
        }
        if self.max_wall_time is not None:
            ipopt["max_wall_time"] = float(self.max_wall_time)
        ipopt.update(self.ipopt)
        return {"ipopt": ipopt, "print_time": False, "error_on_fail": False, **NLPSOL_OPTIONS}

    def check_ipopt(self) -> None:
        """Refuse, before any work, IPOPT options that IPOPT would reject or that cannot work on
        this machine (:func:`~fatigue_pin.ocp.ipopt_process.check_ipopt_options`: unknown options, values of the wrong type or
        out of range, a linear solver IPOPT does not know or cannot load)."""
        check_ipopt_options(tuple(sorted((k, repr(v)) for k, v in self.ipopt_options()["ipopt"].items())))

    def resolved_cache_dir(self) -> Path:
        """Directory of the compiled-code cache (:func:`fatigue_pin.ocp.compiled.cache_folder`)."""
        return cache_folder(self.cache_dir)


def resolve_first_compile(options: SolverOptions, n_intervals: int) -> SolverOptions:
    """``options`` for a full-horizon solve of ``n_intervals`` intervals, with ``first_compile =
    "auto"`` made ``background`` (at most :data:`BACKGROUND_MAX_INTERVALS` intervals) or ``wait``."""
    if options.first_compile != "auto":
        return options
    return replace(options, first_compile="background" if n_intervals <= BACKGROUND_MAX_INTERVALS else "wait")


@dataclass
class NlpResult:
    """Outcome of one NLP solve (flat vectors in the reduced NLP's ordering).

    Attributes:
        x: last iterate, shape (n_x,).
        lam_x, lam_g: multipliers of the variable bounds and of ``g``.
        f: objective value.
        status: IPOPT's return status (e.g. ``Solve_Succeeded``, ``Maximum_Iterations_Exceeded``).
        success: whether ``status`` counts as converged.
        iterations: IPOPT iterations.
        wall_time_s: wall time of the solve call (s).
        constraint_violation: IPOPT's primal infeasibility (inf_pr) at the last iterate.
        kind: :func:`failure_kind` of the solve (``converged``, ``infeasible``, ...).
    """

    x: np.ndarray
    lam_x: np.ndarray
    lam_g: np.ndarray
    f: float
    status: str
    success: bool
    iterations: int
    wall_time_s: float
    constraint_violation: float = float("nan")
    kind: str = ""


def generate_nlp_source(solver: ca.Function, name: str, folder: Path) -> Path:
    """Write the C of an ``nlpsol``'s NLP functions to ``folder/<name>.c`` and return its path.

    The same code as ``solver.generate_dependencies(name + ".c")`` (the oracle, then every NLP
    function IPOPT calls, in name order), written into ``folder`` without changing the process's
    working directory.
    """
    gen = ca.CodeGenerator(f"{name}.c")
    gen.add(solver.oracle())
    for fname in solver.get_function():
        gen.add(solver.get_function(fname))
    gen.generate(str(folder) + os.sep)
    return folder / f"{name}.c"


def _host_key(options: SolverOptions) -> bytes:
    """What the cache key adds for code tuned to this CPU (``-march=native``): its model and
    instruction-set flags (:func:`fatigue_pin.ocp.compiled.host_key`), so a cache shared between
    machines never hands one machine's library to another."""
    return host_key(options.compiler_flags)


def simple_bounds(x: ca.MX, p: ca.MX, g: ca.MX, lbg: ca.MX, ubg: ca.MX, kept_rows: Sequence[int] = (),
                  calls: Sequence[ca.MX] = ()) -> tuple[list[int], ca.MX, ca.MX]:
    """``casadi.detect_simple_bounds`` that leaves ``kept_rows`` of ``g`` in ``g``.

    ``calls``: outputs of the function calls in ``g`` (the mapped interval functions). A row that
    uses one is a constraint, never a simple bound, and is left out of the detection, which
    differentiates the rows it examines: a call compiled without derivative code (the rigid
    body's step with derivative blocks) has none.

    Returns:
        The rows of ``g`` that stay constraints (in their order, those of ``kept_rows`` last), and
        the variable bounds ``lbx, ubx`` (n_x,) as expressions of the parameters ``p``.
    """
    kept = sorted({int(i) for i in kept_rows})
    with_calls: set[int] = set()
    p_all = p
    if calls:  # each call output as a parameter of the detection: its rows are then not simple
        symbols = [ca.MX.sym(f"call_{i}", c.nnz()) for i, c in enumerate(calls)]
        g = ca.graph_substitute([g], list(calls), [ca.sparsity_cast(s, c.sparsity()) for s, c in zip(symbols, calls)])[0]
        for s in symbols:
            with_calls.update(int(r) for r in ca.jacobian_sparsity(g, s).get_triplet()[0])
        p_all = ca.vertcat(p, *symbols)
    skipped = with_calls | set(kept)
    candidates = [i for i in range(g.numel()) if i not in skipped]
    if len(candidates) == g.numel():
        gi, lbx, ubx, _, _ = ca.detect_simple_bounds(x, p, g, lbg, ubg)
        return [int(i) for i in gi], lbx, ubx
    gi, lbx, ubx, _, _ = ca.detect_simple_bounds(x, p_all, g[candidates], lbg[candidates], ubg[candidates])
    if calls:  # the bounds come from rows without calls: the call parameters only appear structurally
        lbx, ubx = ca.graph_substitute([lbx, ubx], symbols, [ca.MX.zeros(s.sparsity()) for s in symbols])
    return sorted(with_calls | {candidates[int(i)] for i in gi}) + kept, lbx, ubx


class NlpSolver:
    """An Opti formulation turned into a reusable IPOPT solver.

    Build it once per problem structure; call :meth:`solve` with new parameter values, initial
    guesses and multipliers as often as needed. Nothing symbolic is rebuilt between solves.

    Args:
        opti: the formulated problem (variables, parameters, objective and constraints set).
        options: solver settings.
        name: a name for the generated code (the cache key also hashes the code itself).
        derivatives: in library mode, called with the reduced NLP (:attr:`problem`); returns
            nlpsol's own ``jac_g`` and ``hess_lag`` (:func:`fatigue_pin.ocp.blocks.nlp_derivatives`)
            or None for CasADi's.
        kept_rows: rows of ``opti.g`` kept as constraints even where they bound one variable.
        calls: outputs of the function calls in ``opti.g`` (:func:`simple_bounds`).
    """

    def __init__(self, opti: ca.Opti, options: SolverOptions, name: str = "fatigue_ocp", progress: Progress = None,
                 label: str = "the NLP", derivatives: Callable[[dict[str, ca.MX]], dict[str, ca.Function] | None] | None = None,
                 kept_rows: Sequence[int] = (), calls: Sequence[ca.MX] = ()) -> None:
        t0 = time.perf_counter()
        self._progress = as_reporter(progress)
        self._label = label
        self.options = options
        self.opti = opti
        x, p, f, g = opti.x, opti.p, opti.f, opti.g
        lbg, ubg = opti.lbg, opti.ubg
        gi, lbx, ubx = simple_bounds(x, p, g, lbg, ubg, kept_rows, calls)
        self.n_x = x.numel()
        self.n_p = p.numel()
        self.n_g = len(gi)
        #: bounds of the reduced NLP as a function of the parameters
        self._bounds = ca.Function("bounds", [p], [lbx, ubx, lbg[gi], ubg[gi]])
        nlp = {"x": x, "p": p, "f": f, "g": g[gi]}
        self._name = name
        #: the reduced NLP given to nlpsol: ``{"x", "p", "f", "g"}`` (g without the simple bounds)
        self.problem = nlp
        self.compile_time_s = 0.0
        self.compiled_path: Path | None = None
        opts = options.ipopt_options()
        #: nlpsol's own derivative functions (``jac_g``, ``hess_lag``), if ``derivatives`` gave them
        self.derivatives: dict[str, ca.Function] = {}
        if options.compile and options.compile_mode == "nlp":
            self._source: dict[str, Any] | str = self._compiled(ca.nlpsol(name, "ipopt", nlp, opts), name)
        else:  # library mode: the interval functions in the graph are already compiled externals
            self._source = nlp
            self.derivatives = (derivatives(nlp) if derivatives is not None else None) or {}
        #: one IPOPT instance per iteration limit and warm start (IPOPT options are fixed per instance)
        self._solvers: dict[tuple[int, bool], ca.Function] = {}
        #: per iteration limit, the instance of the last solve (warm-started or not)
        self._last: dict[int, ca.Function] = {}
        self._solver()
        if options.linear_solver in ("riccati", "auto"):
            self._check_riccati()
        #: frees the stage-wise solver's factors once a solve has returned (None on other solvers)
        self._release_factors = riccati_releaser() if self.options.linear_solver == "riccati" else None
        self.build_time_s = time.perf_counter() - t0

    def _check_riccati(self) -> None:
        """Fall back to MUMPS, with one line on stderr saying why, where the stage-wise solver
        cannot take this NLP (:func:`~fatigue_pin.ocp.riccati.riccati_structure`, on the patterns IPOPT will see); under
        ``auto``, choose it or MUMPS (:data:`~fatigue_pin.ocp.riccati.RICCATI_AUTO_MAX_BLOCK`) without a message. The
        options then name the solver chosen."""
        auto = self.options.linear_solver == "auto"
        solver = next(iter(self._solvers.values()))
        why = riccati_structure(solver.get_function("nlp_hess_l").sparsity_out(0), solver.get_function("nlp_jac_g").sparsity_out(1),
                                RICCATI_AUTO_MAX_BLOCK if auto else None)
        if why is None:
            self.options = replace(self.options, linear_solver="riccati")
            return
        if not auto:
            print(f"solver.linear_solver = 'riccati': {self._label} is solved with MUMPS instead ({why})", file=sys.stderr)
        self.options = replace(self.options, linear_solver="mumps")
        if riccati_library() is not None:  # else linear_solver_options gave MUMPS already
            self._solvers.clear()
            self._solver()

    def stats(self, max_iter: int | None = None) -> dict[str, Any]:
        """CasADi's statistics of the last solve with this iteration limit: IPOPT's per-iteration
        record (``stats()["iterations"]``: inf_pr, inf_du, mu, regularization_size, alpha_pr, ...)
        and the timings (``t_wall_nlp_hess_l``, ...)."""
        key = int(self.options.max_iter if max_iter is None else max_iter)
        return self._last.get(key, self._solver(max_iter)).stats()

    def converged(self, status: str) -> bool:
        """Whether IPOPT's ``status`` counts as converged under these options."""
        return status in CONVERGED_STATUSES or (self.options.accept_acceptable and status == "Solved_To_Acceptable_Level")

    def _solver(self, max_iter: int | None = None, warm_start: bool = False) -> ca.Function:
        """The IPOPT instance with iteration limit ``max_iter`` (default: the options'), with
        :data:`WARM_START_OPTIONS` if ``warm_start``."""
        key = (int(self.options.max_iter if max_iter is None else max_iter), bool(warm_start))
        if key not in self._solvers:
            opts = self.options.ipopt_options()
            opts["ipopt"]["max_iter"] = key[0]
            if warm_start:
                opts["ipopt"].update(WARM_START_OPTIONS)
            self._solvers[key] = ca.nlpsol(self._name, "ipopt", self._source, {**opts, **self.derivatives})
            if self.options.blas_threads:
                limit_blas_threads(self.options.blas_threads)
        return self._solvers[key]

    def _compiled(self, solver: ca.Function, name: str) -> str:
        """Generate C for ``solver``'s NLP functions, compile it (or find it in the cache) and
        return the shared library's path."""
        t0 = time.perf_counter()
        with tempfile.TemporaryDirectory() as tmp:
            source = generate_nlp_source(solver, name, Path(tmp))
            code = source.read_bytes()
            key = code + " ".join(self.options.compiler_flags).encode() + _host_key(self.options)
            digest = hashlib.sha256(key).hexdigest()[:20]
            target = self.options.resolved_cache_dir() / f"{name}_{digest}.so"
            if not verify_entry(target):  # the compile cache's lock, checksum and atomic rename
                with self._progress.task(f"compiling {self._label} (once per machine)", expected_s=len(code) / 100_000):
                    built = cached_build(target, lambda tmp_so: compile_shared([source], tmp_so, self.options.build_options()))
                if built:
                    self.compile_time_s = time.perf_counter() - t0
        self.compiled_path = target
        return str(target)

    def bounds(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Numeric ``lbx, ubx, lbg, ubg`` of the reduced NLP for parameter vector ``p``."""
        return tuple(np.asarray(v, dtype=float).reshape(-1) for v in self._bounds(p))  # type: ignore[return-value]

    def solve(
        self,
        p: np.ndarray,
        x0: np.ndarray,
        lam_x0: np.ndarray | None = None,
        lam_g0: np.ndarray | None = None,
        max_iter: int | None = None,
        warm_start: bool = False,
    ) -> NlpResult:
        """Solve with parameters ``p`` from the initial guess ``x0`` (and multipliers, if given).

        Args:
            p: parameter vector, shape (n_p,) in Opti's parameter order.
            x0: initial guess, shape (n_x,) in Opti's variable order.
            lam_x0: initial multipliers of the variable bounds (e.g. from a previous solve), for warm starts.
            lam_g0: initial multipliers of ``g``, for warm starts.
            max_iter: iteration limit of this solve (default: the options').
            warm_start: IPOPT starts from ``x0`` and the multipliers (:data:`WARM_START_OPTIONS`);
                without it IPOPT uses only ``x0``.
        """
        lbx, ubx, lbg, ubg = self.bounds(p)
        x0 = np.clip(np.asarray(x0, dtype=float).reshape(-1), lbx, ubx)
        args: dict[str, Any] = {"x0": x0, "p": p, "lbx": lbx, "ubx": ubx, "lbg": lbg, "ubg": ubg}
        if lam_x0 is not None:
            args["lam_x0"] = lam_x0
        if lam_g0 is not None:
            args["lam_g0"] = lam_g0
        t0 = time.perf_counter()
        solver = self._solver(max_iter, warm_start and lam_x0 is not None and lam_g0 is not None)
        self._last[int(self.options.max_iter if max_iter is None else max_iter)] = solver
        try:
            with captured(2) as said, watch():  # Ctrl-C / SIGTERM: IPOPT stops, Interrupted is raised (no failed solve)
                sol = solver(**args)
        finally:
            if self._release_factors is not None:
                self._release_factors()
        if said:  # what CasADi and IPOPT wrote on standard error, once the solve was not interrupted
            print("\n".join(said), file=sys.stderr)
        wall = time.perf_counter() - t0
        stats = solver.stats()
        status = str(stats.get("return_status", "unknown"))
        inf_pr = list(stats.get("iterations", {}).get("inf_pr", []))
        return NlpResult(
            x=np.asarray(sol["x"], dtype=float).reshape(-1),
            lam_x=np.asarray(sol["lam_x"], dtype=float).reshape(-1),
            lam_g=np.asarray(sol["lam_g"], dtype=float).reshape(-1),
            f=float(sol["f"]),
            status=status,
            success=self.converged(status),
            iterations=int(stats.get("iter_count", -1)),
            wall_time_s=wall,
            constraint_violation=float(inf_pr[-1]) if inf_pr else float("nan"),
            kind="converged" if self.converged(status) else failure_kind(status, inf_pr, self.options.constr_viol_tol),
        )
