"""Solver plumbing: compile flags, modes and generated code."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.ocp.solver import SolverOptions, _host_key, simple_bounds


def test_cache_key_names_the_cpu_only_for_native_code():
    assert _host_key(SolverOptions(compiler_flags=("-O1",))) == b""
    assert _host_key(SolverOptions(compiler_flags=("-O3", "-march=native"))) != b""


def test_barrier_and_regularisation_defaults_reach_ipopt_and_can_be_overridden():
    ipopt = SolverOptions().ipopt_options()["ipopt"]
    assert ipopt["mu_init"] == 1.0 and ipopt["perturb_dec_fact"] == 0.6
    ipopt = SolverOptions(mu_init=0.1, ipopt={"perturb_dec_fact": 1 / 3}).ipopt_options()["ipopt"]
    assert ipopt["mu_init"] == 0.1 and ipopt["perturb_dec_fact"] == 1 / 3


def test_bad_barrier_settings_are_named():
    with pytest.raises(ParameterError, match="mu_init = -1"):
        SolverOptions(mu_init=-1)
    with pytest.raises(ParameterError, match="perturb_dec_fact = 1.5"):
        SolverOptions(perturb_dec_fact=1.5)


def test_generated_nlp_source_needs_no_change_of_directory(tmp_path):
    """The C written into a folder is what CasADi's generate_dependencies writes into the
    working directory, and the working directory is left alone."""
    import os

    import casadi as ca

    from fatigue_pin.ocp.solver import generate_nlp_source

    x, p = ca.SX.sym("x", 2), ca.SX.sym("p")
    nlp = ca.nlpsol("s", "ipopt", {"x": x, "p": p, "f": (x[0] - p) ** 2 + x[1] ** 2, "g": x[0] * x[1]},
                    {"print_time": False, "ipopt": {"print_level": 0}})
    cwd = os.getcwd()
    path = generate_nlp_source(nlp, "nlp_a", tmp_path)
    assert os.getcwd() == cwd and path == tmp_path / "nlp_a.c"
    reference = tmp_path / "ref"
    reference.mkdir()
    os.chdir(reference)
    try:
        nlp.generate_dependencies("nlp_a.c")
    finally:
        os.chdir(cwd)
    assert path.read_bytes() == (reference / "nlp_a.c").read_bytes()


def test_compile_mode_is_validated_and_the_compiler_checked_only_when_compiling(tmp_path):
    with pytest.raises(ParameterError, match="compile_mode = 'fast'"):
        SolverOptions(compile_mode="fast")
    options = SolverOptions(compiler="no-such-cc")  # exists without a compiler on PATH
    assert options.library_mode and options.build_options().compiler == "no-such-cc"


def test_acceptable_level_counts_only_when_asked():
    import types

    from fatigue_pin.ocp.solver import NlpSolver, SolverOptions

    strict = types.SimpleNamespace(options=SolverOptions())
    lenient = types.SimpleNamespace(options=SolverOptions(accept_acceptable=True))
    assert NlpSolver.converged(strict, "Solve_Succeeded") and NlpSolver.converged(lenient, "Solve_Succeeded")
    assert not NlpSolver.converged(strict, "Solved_To_Acceptable_Level")
    assert NlpSolver.converged(lenient, "Solved_To_Acceptable_Level")
    assert not NlpSolver.converged(lenient, "Maximum_Iterations_Exceeded")


def test_failure_kinds_tell_infeasibility_from_limits():
    from fatigue_pin.ocp.solver import failure_kind

    assert failure_kind("Solve_Succeeded", [1.0, 1e-8], 1e-4) == "converged"
    assert failure_kind("Infeasible_Problem_Detected", [1.0], 1e-4) == "infeasible"
    assert failure_kind("Restoration_Failed", [1.0], 1e-4) == "infeasible"
    # a restoration phase entered at a feasible point (the line search stalled there) is no verdict
    assert failure_kind("Restoration_Failed", [1.0, 1e-3, 1e-9], 1e-4) == "not-converged"
    # stopped by a limit while the violation grew from its lowest point: moving away from feasibility
    assert failure_kind("Maximum_Iterations_Exceeded", [1.0, 1e-3, 0.5], 1e-4) == "infeasible-growing"
    # stopped by a limit while (nearly) feasible, or still decreasing: just not converged
    assert failure_kind("Maximum_Iterations_Exceeded", [1.0, 1e-3, 1e-6], 1e-4) == "not-converged"
    assert failure_kind("Maximum_WallTime_Exceeded", [1.0, 0.5, 0.4], 1e-4) == "not-converged"
    assert failure_kind("Error_In_Step_Computation", [1e-9], 1e-4) == "numerical"


@pytest.mark.parametrize("options, message", [
    (dict(ipopt={"nosuchoption": 3}), r"solver.ipopt.nosuchoption: IPOPT has no option 'nosuchoption'"),
    (dict(linear_solver="foo"), r"solver.linear_solver = 'foo': not a valid IPOPT setting; expected one of \['ma27', .*'mumps'"),
    (dict(ipopt={"mu_strategy": "weird"}), r"solver.ipopt.mu_strategy = 'weird': .* expected one of \['monotone', 'adaptive'\]"),
    (dict(ipopt={"acceptable_tol": -1.0}), r"solver.ipopt.acceptable_tol = -1.0: not a valid IPOPT setting; expected a value in 0 <"),
    (dict(ipopt={"tol": "abc"}), r"solver.ipopt.tol = 'abc': IPOPT expects another type of value"),
])
def test_ipopt_options_are_checked_before_any_work(options, message, capfd):
    with pytest.raises(ParameterError, match=message) as err:
        SolverOptions(**options).check_ipopt()
    assert "\n" not in str(err.value)
    assert capfd.readouterr().out == ""  # IPOPT's option documentation is kept out of the terminal


def test_valid_ipopt_options_pass(capfd):
    SolverOptions().check_ipopt()
    SolverOptions(linear_solver="mumps", ipopt={"mu_strategy": "adaptive", "hessian_approximation": "limited-memory"}).check_ipopt()
    assert capfd.readouterr().out == ""


@pytest.mark.parametrize("linear_solver", ["ma27", "ma57", "pardiso"])
def test_a_linear_solver_that_cannot_be_loaded_is_an_error_not_a_failed_solve(linear_solver):
    """Where the library of an HSL or Pardiso solver is missing, the check names it (a search
    used to report "0 repetitions"); where it is installed, a solve with it converges."""
    import casadi as ca

    try:
        SolverOptions(linear_solver=linear_solver).check_ipopt()
    except ParameterError as exc:
        assert f"solver.linear_solver = {linear_solver!r} cannot be used on this machine (" in str(exc)
        assert "expected an installed linear solver, e.g. 'mumps'" in str(exc)
    else:
        x = ca.SX.sym("x")
        solver = ca.nlpsol("s", "ipopt", {"x": x, "f": (x - 1) ** 2}, SolverOptions(linear_solver=linear_solver).ipopt_options())
        assert float(solver(x0=0.0)["x"]) == pytest.approx(1.0) and solver.stats()["success"]


def test_blas_threads_set_the_openblas_that_mumps_uses():
    """``blas_threads``: the thread count of the OpenBLAS copy IPOPT's MUMPS loaded (read back
    from that copy); 0 leaves it alone; a negative count is refused."""
    import ctypes

    import casadi as ca

    from fatigue_pin.ocp.solver import NlpSolver

    opti = ca.Opti()
    x = opti.variable(2)
    opti.minimize(ca.sumsqr(x - 1))
    opti.subject_to(x[0] ** 2 + x[1] == 1)
    opti.subject_to(opti.bounded(-5, x, 5))

    def threads() -> int:
        paths = {line.split()[-1] for line in open("/proc/self/maps") if "libcasadi-tp-openblas" in line}
        assert len(paths) == 1, paths  # the one copy MUMPS uses, never a second one of ours
        return ctypes.CDLL(paths.pop()).openblas_get_num_threads()

    for n in (2, 1):
        NlpSolver(opti, SolverOptions(compile=False, blas_threads=n))
        assert threads() == n
    NlpSolver(opti, SolverOptions(compile=False, blas_threads=0))
    assert threads() == 1
    with pytest.raises(ParameterError, match="blas_threads = -1"):
        SolverOptions(blas_threads=-1)


def test_simple_bounds_leave_rows_with_calls_out_of_the_detection():
    """A row that uses a call is a constraint; the detection does not differentiate it, so a call
    without derivatives (a step compiled without derivative code) does not stop it; the rows and
    the bounds are those of CasADi's detection on the same NLP with a differentiable call."""
    x, p = ca.MX.sym("x", 4), ca.MX.sym("p", 2)
    a = ca.MX.sym("a")
    opts = {"enable_forward": False, "enable_reverse": False, "enable_jacobian": False, "enable_fd": False}
    plain, opaque = (ca.Function("step", [a], [ca.sin(a)], *([opts] if o else [])) for o in (False, True))

    def nlp(step):
        out = step.map(2)(ca.horzcat(x[0], x[1]))
        g = ca.vertcat(x[2] - out[0], 2 * x[1], x[3] - out[1], x[0] + x[3], 3 * x[2] - p[0])
        return g, out

    g, _ = nlp(plain)
    lbg, ubg = ca.vertcat(0, -1, 0, -p[1], 0), ca.vertcat(0, 1, 0, p[1], 0)
    gi, lbx, ubx, _, _ = ca.detect_simple_bounds(x, p, g, lbg, ubg)
    g_opaque, out = nlp(opaque)
    with pytest.raises(RuntimeError):
        ca.detect_simple_bounds(x, p, g_opaque, lbg, ubg)
    rows, lo, hi = simple_bounds(x, p, g_opaque, lbg, ubg, calls=[out])
    assert rows == [int(i) for i in gi] == [0, 2, 3]
    bounds = [ca.Function("b", [p], [lo, hi]), ca.Function("b", [p], [lbx, ubx])]
    for pv in ([0.3, 2.0], [-1.5, 0.5]):
        assert np.allclose(np.hstack(bounds[0](pv)), np.hstack(bounds[1](pv)))
