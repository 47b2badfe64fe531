"""Derivative blocks (fatigue_pin.ocp.blocks): nlpsol's own constraint Jacobian and Lagrangian Hessian,
assembled from per-interval blocks, equal CasADi's automatic ones (random x, multipliers and
parameters) for the arm26 curl and for the UR5 carry task (frame targets, a plane at every node,
the torque-rate cost, 3CC-S fatigue, an end box); a solve with them takes the same iterations to
the same optimum. Uncompiled: the blocks are the same functions the library compiles."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from conftest import small_curl
from fatigue_pin.ocp.guesses import rest_guess
from fatigue_pin.ocp.blocks import MappedCall, block_functions, nlp_derivatives
from fatigue_pin.io.study import Study
from fatigue_pin.core.errors import ParameterError
from fatigue_pin.ocp.transcription import Ocp

UR5_STUDY = Path(__file__).resolve().parents[2] / "studies" / "ur5_carry.toml"


def _ocp(study: Study, model, cycles: int, blocks: bool, end_tolerance: float | None = None) -> Ocp:
    solver = dataclasses.replace(study.solver(), compile=False, derivative_blocks=blocks)
    return Ocp(study.problem(model), cycles, study.transcription(), solver, end_tolerance=end_tolerance)


@pytest.fixture(scope="module")
def ur5_study() -> Study:
    return Study.from_file(UR5_STUDY).replace({"task.intervals_per_cycle": 6, "solver.compile": False})


def _compare(ocp: Ocp, seed: int = 0) -> None:
    """The block Jacobian and Hessian against nlpsol's own at random points."""
    derivatives = ocp.nlp.derivatives
    assert set(derivatives) == {"jac_g", "hess_lag"}
    reference = ca.nlpsol("reference", "ipopt", ocp.nlp.problem, {"print_time": False})
    jac_ref, hess_ref = reference.get_function("nlp_jac_g"), reference.get_function("nlp_hess_l")
    rng = np.random.default_rng(seed)
    p0 = ocp.parameter_vector()
    z0 = ocp.flatten(*rest_guess(ocp))
    for _ in range(3):
        x = z0 + 0.3 * rng.normal(size=z0.size)
        p = p0 * (1 + 0.1 * rng.normal(size=p0.size))
        lam_f, lam_g = rng.normal(), rng.normal(size=ocp.nlp.n_g)
        g, jac = derivatives["jac_g"](x, p)
        g0, jac0 = jac_ref(x, p)
        hess, hess0 = derivatives["hess_lag"](x, p, lam_f, lam_g), hess_ref(x, p, lam_f, lam_g)
        # (the analytical Jacobian block computes ddq by Pinocchio's derivative pass: other
        # operations than ABA's, the same values to rounding)
        assert np.abs(np.asarray(g) - np.asarray(g0)).max() <= 1e-10 * max(1.0, float(ca.norm_inf(g0)))
        for mine, theirs in ((jac, jac0), (hess, hess0)):
            scale = max(1.0, float(ca.norm_inf(theirs)))
            assert float(ca.norm_inf(ca.densify(mine) - ca.densify(theirs))) <= 1e-10 * scale
        assert hess.sparsity().is_triu()  # the upper triangle, as IPOPT reads it


def test_arm26_blocks_equal_casadis_derivatives(arm26):
    ocp = _ocp(small_curl(), arm26, 2, blocks=True)
    assert {c.function.name() for c in ocp.mapped_calls} == {"F_rb", "F_fatigue_xia", "coupling", "terms"}
    _compare(ocp)


def test_ur5_frame_targets_and_torque_rate_blocks_equal_casadis(ur5_study):
    ocp = _ocp(ur5_study, ur5_study.model(), 1, blocks=True, end_tolerance=0.1)
    assert "torque_rate" in ocp.cost_terms and ocp._state_constraints  # a cost of u_prev; frame rows
    _compare(ocp, seed=1)


def test_a_solve_with_blocks_takes_the_same_path(arm26):
    study = small_curl()
    with_blocks = _ocp(study, arm26, 2, blocks=True).solve()
    without = _ocp(study, arm26, 2, blocks=False).solve()
    assert with_blocks.success and without.success
    assert with_blocks.iterations == without.iterations
    assert with_blocks.objective == pytest.approx(without.objective, rel=1e-8, abs=1e-8)
    assert np.allclose(with_blocks.x, without.x, atol=1e-7)


def test_nonlinear_use_of_a_map_output_keeps_casadis_derivatives():
    """A map output entering the NLP nonlinearly (here squared in the objective) is detected."""
    a = ca.SX.sym("a", 2)
    f = ca.Function("f", [a], [ca.sin(a)])
    X = ca.MX.sym("X", 2, 4)
    out = f.map(4)(X)
    nlp = {"x": ca.vec(X), "p": ca.MX.sym("p", 0), "f": ca.sumsqr(out), "g": ca.vec(out)}
    blocks = {"f": block_functions(f, (0,))}
    assert nlp_derivatives(nlp, [MappedCall(f, (X,), out, 4)], blocks) is None
    linear = {**nlp, "f": ca.sum1(ca.sum2(out))}
    assert nlp_derivatives(linear, [MappedCall(f, (X,), out, 4)], blocks) is not None


def test_gauss_newton_hessian_drops_only_the_rigid_body_curvature(arm26):
    """``hessian = "gauss-newton"``: the block Hessian equals CasADi's exact Hessian of the
    Lagrangian with the rigid-body gap multipliers set to zero (only their second derivatives
    leave), and the Jacobian is unchanged."""
    study = small_curl()
    exact = _ocp(study, arm26, 1, blocks=True)
    solver = dataclasses.replace(study.solver(), compile=False, derivative_blocks=True, hessian="gauss-newton")
    gn = Ocp(study.problem(arm26), 1, study.transcription(), solver)
    assert gn.functions.blocks["F_rb"].hess is None and gn.functions.blocks["F_fatigue_xia"].hess is not None
    reference = ca.nlpsol("reference", "ipopt", gn.nlp.problem, {"print_time": False})
    hess_ref = reference.get_function("nlp_hess_l")
    # the rigid-body gap rows of g: those that depend on the output of the mapped F_rb
    g = gn.nlp.problem["g"]
    call = next(c for c in gn.mapped_calls if c.function.name() == "F_rb")
    S = ca.MX.sym("S", call.out.sparsity())
    rb_rows = np.flatnonzero(np.asarray(ca.DM(ca.jacobian(ca.graph_substitute(g, [call.out], [S]), S).sparsity(), 1)).sum(axis=1))
    assert rb_rows.size == call.out.numel()
    rng = np.random.default_rng(3)
    z = gn.flatten(*rest_guess(gn)) + 0.3 * rng.normal(size=gn.nlp.n_x)
    p, lam_f, lam_g = gn.parameter_vector(), 0.7, rng.normal(size=gn.nlp.n_g)
    kept = lam_g.copy()
    kept[rb_rows] = 0.0
    mine = np.asarray(ca.densify(gn.nlp.derivatives["hess_lag"](z, p, lam_f, lam_g)))
    assert np.allclose(mine, np.triu(np.asarray(ca.densify(hess_ref(z, p, lam_f, kept)))), rtol=1e-11, atol=1e-10)
    full = np.triu(np.asarray(ca.densify(hess_ref(z, p, lam_f, lam_g))))
    assert np.abs(mine - full).max() > 1e-3  # the rigid body's curvature did go
    jac_gn, jac_exact = gn.nlp.derivatives["jac_g"](z, p)[1], exact.nlp.derivatives["jac_g"](z, p)[1]
    assert float(ca.norm_inf(ca.densify(jac_gn - jac_exact))) == 0.0


@pytest.mark.parametrize("hessian, intervals", [("gauss-newton", 10), ("one-step", 20), ("euler-step", 20)])
def test_approximate_hessians_reach_the_exact_hessians_optimum(arm26, hessian, intervals):
    """Same KKT point (solved to tol 1e-9): objective within 1e-6 relative, states within 1e-4.
    (``one-step`` on 20 intervals per cycle: one RK4 step of 0.1 s, the 10-interval grid, is
    too coarse an approximation of arm26's curvature and IPOPT does not converge.)"""
    study = small_curl(intervals_per_cycle=intervals)
    sols = {}
    for h in ("exact", hessian):
        solver = dataclasses.replace(study.solver(), compile=False, derivative_blocks=True, hessian=h, tol=1e-9)
        sols[h] = Ocp(study.problem(arm26), 2, study.transcription(), solver).solve()
    exact, approximate = sols["exact"], sols[hessian]
    assert exact.success and approximate.success
    assert approximate.objective == pytest.approx(exact.objective, rel=1e-6)
    assert np.abs(approximate.x - exact.x).max() < 1e-4


def test_one_step_hessian_block_is_the_second_derivative_of_one_rk4_step(arm26):
    """``one-step``: the rigid body's Hessian block equals CasADi's Hessian of mu' RK4(dt, 1
    step) at a random point, and differs from the exact block of RK4(dt / substeps, substeps)
    by little (the same flow's curvature)."""
    from fatigue_pin.ocp.transcription import rk4

    study = small_curl(intervals_per_cycle=20)
    solver = dataclasses.replace(study.solver(), compile=False, derivative_blocks=True, hessian="one-step")
    ocp = Ocp(study.problem(arm26), 1, study.transcription(), solver)
    fn = ocp.functions
    hblk = fn.blocks["F_rb"].hess
    y, tau, mu = ca.SX.sym("y", 4), ca.SX.sym("tau", 2), ca.SX.sym("mu", 4)
    w = ca.vertcat(y, tau)
    one = ca.Function("h1", [w, mu], [ca.hessian(ca.dot(mu, rk4(fn.f_rb, y, (tau,), ocp.task.dt, 1)), w)[0]])
    exact = ca.Function("h5", [w, mu], [ca.hessian(ca.dot(mu, rk4(fn.f_rb, y, (tau,), ocp.task.dt / 2, 2)), w)[0]])
    rng = np.random.default_rng(4)
    wv = np.r_[ocp.initial_state()[:4] + 0.1 * rng.normal(size=4), rng.normal(size=2)]
    mv = rng.normal(size=4)
    mine = np.asarray(ca.densify(hblk(wv, mv)))
    h1, h5 = np.asarray(one(wv, mv)), np.asarray(exact(wv, mv))
    assert np.allclose(mine, np.tril(h1), rtol=1e-10, atol=1e-12)
    assert 0 < np.abs(h1 - h5).max() < 0.1 * np.abs(h5).max()


def test_gauss_newton_needs_the_blocks(arm26):
    study = small_curl()
    solver = dataclasses.replace(study.solver(), compile=False, derivative_blocks=False, hessian="gauss-newton")
    with pytest.raises(ParameterError, match="hessian = 'gauss-newton' needs the derivative blocks"):
        Ocp(study.problem(arm26), 1, study.transcription(), solver)
    with pytest.raises(ParameterError, match="SolverOptions.hessian = 'newton'"):
        dataclasses.replace(study.solver(), hessian="newton")


@pytest.mark.parametrize("which", ["arm26", "ur5"])
def test_analytical_rigid_body_jacobian_equals_automatic_differentiation(arm26, ur5_study, which):
    """``dynamics_jacobian = "analytical"``: the RK4's Jacobian block from forward sensitivities
    of Pinocchio's analytical ABA derivatives equals CasADi's automatic Jacobian of the same RK4
    (values and states), at random points; the block replaces only F_rb's Jacobian."""
    study = small_curl() if which == "arm26" else ur5_study
    model = arm26 if which == "arm26" else ur5_study.model()
    solver = dataclasses.replace(study.solver(), compile=False, derivative_blocks=True, dynamics_jacobian="analytical")
    ocp = Ocp(study.problem(model), 1, study.transcription(), solver, end_tolerance=0.1)
    fn = ocp.functions
    mine = fn.blocks["F_rb"].jac
    automatic = block_functions(fn.F_rb, (0, 1), hessian=False).jac
    assert mine.name() == automatic.name() == "jblk_F_rb"
    rng = np.random.default_rng(5)
    nw = mine.size1_in(0)
    for _ in range(5):
        w = rng.uniform(-1.0, 1.0, nw)
        (y, J), (y0, J0) = mine(w), automatic(w)
        assert np.abs(np.asarray(y) - np.asarray(y0)).max() <= 1e-12 * max(1.0, float(ca.norm_inf(y0)))
        assert np.abs(np.asarray(ca.densify(J)) - np.asarray(ca.densify(J0))).max() <= 1e-11 * max(1.0, float(ca.norm_inf(J0)))
    assert fn.blocks["F_fatigue_xia"].jac.name() == "jblk_F_fatigue_xia"  # the others stay automatic


def test_euler_step_hessian_block_is_dt_times_the_hessian_of_aba(arm26):
    """``euler-step``: the rigid body's Hessian block is the Hessian of mu' (y + dt f(y, tau))."""
    study = small_curl(intervals_per_cycle=20)
    solver = dataclasses.replace(study.solver(), compile=False, derivative_blocks=True, hessian="euler-step")
    ocp = Ocp(study.problem(arm26), 1, study.transcription(), solver)
    fn = ocp.functions
    y, tau, mu = ca.SX.sym("y", 4), ca.SX.sym("tau", 2), ca.SX.sym("mu", 4)
    w = ca.vertcat(y, tau)
    ref = ca.Function("h", [w, mu], [ca.hessian(ocp.task.dt * ca.dot(mu, fn.f_rb(y, tau)), w)[0]])
    rng = np.random.default_rng(6)
    wv = np.r_[ocp.initial_state()[:4] + 0.1 * rng.normal(size=4), rng.normal(size=2)]
    mv = rng.normal(size=4)
    assert np.allclose(np.asarray(ca.densify(fn.blocks["F_rb"].hess(wv, mv))), np.tril(np.asarray(ref(wv, mv))), rtol=1e-10, atol=1e-12)


def test_one_step_hessian_of_a_torque_that_follows_the_state(tmp_path):
    """Muscles (their torque follows q, qdot): the ``one-step`` Hessian block of ``F_rb_active`` is
    CasADi's Hessian of mu' (one RK4 step over the interval) at a random point, and close to the
    exact block of the study's substeps."""
    from conftest import muscle_curl, two_muscle_file

    study = muscle_curl(two_muscle_file(tmp_path), **{"task.intervals_per_cycle": 20})
    solver = dataclasses.replace(study.solver(), compile=False, derivative_blocks=True, hessian="one-step")
    ocp = Ocp(study.problem(), 1, study.transcription(), solver)
    fn = ocp.functions
    pair = fn.blocks["F_rb_active"]
    one, exact = fn.F_rb_active_one_step, fn.F_rb_active
    sizes = [one.sparsity_in(i).numel() for i in pair.diff]
    w, mu = ca.MX.sym("w", sum(sizes)), ca.MX.sym("mu", 4)
    others = [ca.MX.sym(one.name_in(i), one.sparsity_in(i)) for i in range(one.n_in()) if i not in pair.diff]
    pieces, rest, args = iter(ca.vertsplit(w, list(np.cumsum([0, *sizes])))), iter(others), []
    for i in range(one.n_in()):
        args.append(next(pieces) if i in pair.diff else next(rest))
    H = {name: ca.Function(name, [w, *others, mu], [ca.hessian(ca.dot(mu, f(*args)), w)[0]]) for name, f in
         (("one", one), ("exact", exact))}
    rng = np.random.default_rng(5)
    assert pair.diff == (0, 1, 2)  # y, the fatigue states, the controls; the fatigue parameters are not differentiated
    x0 = ocp.initial_state()
    wv = np.r_[x0[:4] + 0.1 * rng.normal(size=4), x0[4:4 + sizes[1]], rng.uniform(0, 1, sizes[2])]
    ov = [rng.uniform(0.5, 2.0, o.numel()) for o in others]
    mv = rng.normal(size=4)
    mine = np.asarray(ca.densify(pair.hess(wv, *ov, mv)))
    h1, hN = np.asarray(H["one"](wv, *ov, mv)), np.asarray(H["exact"](wv, *ov, mv))
    assert np.allclose(mine, np.tril(h1), rtol=1e-9, atol=1e-10)
    assert 0 < np.abs(h1 - hN).max() < 0.2 * np.abs(hN).max()


def test_the_muscle_flows_sensitivity_jacobian_is_casadis(tmp_path):
    """Muscles, compiled layout: the Jacobian block of ``F_rb_active`` by forward sensitivities
    (IntervalFunctions.active_sensitivity_jacobian) has the flow's value and CasADi's Jacobian of
    the flow at a random point, and the fatigue states' columns are zero (the flow does not
    depend on them)."""
    from conftest import muscle_curl, two_muscle_file

    from fatigue_pin.ocp.intervals import IntervalFunctions

    study = muscle_curl(two_muscle_file(tmp_path), **{"task.intervals_per_cycle": 20})
    fn = IntervalFunctions(study.problem(), study.transcription(), fatigue_calls=True)
    F = fn.F_rb_active
    diff = (0, 1, 2)
    jac = fn.active_sensitivity_jacobian(diff)
    assert jac is not None and fn.active_sensitivity_jacobian((1, 2)) is None  # y must be differentiated
    sizes = [F.size1_in(i) for i in diff]
    w, p = ca.MX.sym("w", sum(sizes)), ca.MX.sym("p", F.sparsity_in(3))
    y, m, u = ca.vertsplit(w, list(np.cumsum([0, *sizes])))
    ref = ca.Function("ref", [w, p], [F(y, m, u, p), ca.jacobian(F(y, m, u, p), w)])
    rng = np.random.default_rng(7)
    x0 = study.problem().initial_state()
    wv = np.r_[x0[:4] + 0.1 * rng.normal(size=4), x0[4:4 + sizes[1]], rng.uniform(0, 1, sizes[2])]
    pv = rng.uniform(0.5, 2.0, F.sparsity_in(3).numel())
    y_ref, J_ref = (np.asarray(ca.densify(v)) for v in ref(wv, pv))
    y_sens, J_sens = (np.asarray(ca.densify(v)) for v in jac(wv, pv))
    assert np.allclose(y_sens, y_ref, rtol=0, atol=1e-13)
    assert np.abs(J_ref).max() > 1.0 and np.allclose(J_sens, J_ref, rtol=1e-11, atol=1e-11 * np.abs(J_ref).max())
    assert not J_sens[:, sizes[0]:sizes[0] + sizes[1]].any()


def test_a_block_whose_calls_are_too_large_is_kept_as_mx_without_expanding():
    """_maybe_expanded: small MX functions become SX; one whose calls alone hold over 10x the
    limit stays MX, judged by counting its callees' instructions (no expansion: the muscle
    curl's exact Hessian block would take seconds to expand only to be dropped)."""
    from fatigue_pin.ocp import blocks

    x = ca.SX.sym("x", 4)
    g = ca.Function("g", [x], [ca.sin(x) * ca.cos(x) + x])
    small_n = blocks.EXPAND_MAX_INSTRUCTIONS // (4 * g.n_instructions())
    X = ca.MX.sym("X", 4)
    y = X
    for _ in range(small_n):
        y = g(y)
    small = ca.Function("small", [X], [y])
    assert small.expand().n_instructions() <= blocks._called_instructions(small, 10**9) <= blocks.EXPAND_MAX_INSTRUCTIONS
    assert blocks._maybe_expanded(small).is_a("SXFunction")
    big = ca.Function("big", [X], [ca.vertcat(*[small(X + k) for k in range(60)])])  # 60 nested calls of `small`
    assert blocks._called_instructions(big, 10**9) > 10 * blocks.EXPAND_MAX_INSTRUCTIONS
    kept = blocks._maybe_expanded(big)
    assert kept is big and not kept.is_a("SXFunction")
    assert np.allclose(np.asarray(kept(np.arange(4.0))), np.asarray(big.expand()(np.arange(4.0))))


def test_the_muscle_flows_adjoint_hessian_is_casadis(tmp_path):
    """Muscles: the exact Hessian block of ``F_rb_active`` by the stages' adjoints
    (IntervalFunctions.active_adjoint_hessian, ocp/sensitivities.py) equals CasADi's Hessian of
    mu' F_rb_active at a random point, with the fatigue states' rows and columns structurally
    zero; the exact Hessian's blocks take it."""
    from conftest import muscle_curl, two_muscle_file

    from fatigue_pin.ocp.intervals import IntervalFunctions

    study = muscle_curl(two_muscle_file(tmp_path), **{"task.intervals_per_cycle": 20})
    fn = IntervalFunctions(study.problem(), study.transcription(), fatigue_calls=True)
    F = fn.F_rb_active
    diff = (0, 1, 2)
    hess = fn.active_adjoint_hessian(diff)
    assert hess is not None and fn.active_adjoint_hessian((1, 2)) is None
    sizes = [F.size1_in(i) for i in diff]
    w, p, mu = ca.MX.sym("w", sum(sizes)), ca.MX.sym("p", F.sparsity_in(3)), ca.MX.sym("mu", 4)
    y, m, u = ca.vertsplit(w, list(np.cumsum([0, *sizes])))
    ref = ca.Function("ref", [w, p, mu], [ca.hessian(ca.dot(mu, F(y, m, u, p)), w)[0]])
    rng = np.random.default_rng(8)
    x0 = study.problem().initial_state()
    wv = np.r_[x0[:4] + 0.1 * rng.normal(size=4), x0[4:4 + sizes[1]], rng.uniform(0, 1, sizes[2])]
    pv, mv = rng.uniform(0.5, 2.0, F.sparsity_in(3).numel()), rng.normal(size=4)
    R = np.tril(np.asarray(ca.densify(ref(wv, pv, mv))))
    M = np.asarray(ca.densify(hess(wv, pv, mv)))
    assert np.abs(R).max() > 1.0 and np.allclose(M, R, rtol=1e-10, atol=1e-11 * np.abs(R).max())
    m_rows = slice(sizes[0], sizes[0] + sizes[1])
    pattern = np.zeros(M.shape, bool)
    sp = hess.sparsity_out(0)
    pattern[sp.row(), sp.get_col()] = True
    assert not pattern[m_rows, :].any() and not pattern[:, m_rows].any()
    fn.build_blocks({"F_rb_active": diff}, "exact")
    assert fn.blocks["F_rb_active"].hess.name() == "hblk_F_rb_active"
    assert np.allclose(np.asarray(ca.densify(fn.blocks["F_rb_active"].hess(wv, pv, mv))), M, rtol=0, atol=0)


def test_the_rigid_bodys_adjoint_hessian_is_casadis(arm26):
    """Torque halves: the exact Hessian block of ``F_rb`` by the stages' adjoints
    (IntervalFunctions.rb_adjoint_hessian) equals CasADi's Hessian of mu' F_rb at a random point
    (arm26, Pinocchio's analytical first derivatives), and the exact blocks take it."""
    study = small_curl(intervals_per_cycle=20)
    solver = dataclasses.replace(study.solver(), compile=False, derivative_blocks=True, hessian="exact")
    fn = Ocp(study.problem(arm26), 1, study.transcription(), solver).functions
    hess = fn.rb_adjoint_hessian()
    assert fn.blocks["F_rb"].hess.name() == "hblk_F_rb" and fn.blocks["F_rb"].hess.n_instructions() == hess.n_instructions()
    w, mu = ca.MX.sym("w", 6), ca.MX.sym("mu", 4)
    ref = ca.Function("ref", [w, mu], [ca.tril(ca.hessian(ca.dot(mu, fn.F_rb(w[:4], w[4:])), w)[0])])
    rng = np.random.default_rng(9)
    wv = np.r_[np.array([0.3, 1.2, 0.5, -0.8]) + 0.1 * rng.normal(size=4), 10 * rng.normal(size=2)]
    mv = rng.normal(size=4)
    R, M = (np.asarray(ca.densify(f(wv, mv))) for f in (ref, hess))
    assert np.abs(R).max() > 0.1 and np.allclose(M, R, rtol=1e-10, atol=1e-12 * np.abs(R).max())
