"""The interval functions (fatigue_pin.ocp.intervals): the fatigue step built per half (one RK4
of one half per group of halves with the same equations, mapped over the halves) gives the
values, Jacobian and Hessian of the RK4 of all halves at once, on arm26 and on arm26 with mixed
fatigue models (two Xia variants and Michaud's model in one actuator set); the NLP built with it
(derivative blocks) has the derivatives of the NLP built with the all-halves step."""

from __future__ import annotations

import dataclasses

import casadi as ca
import numpy as np
import pytest

from conftest import small_curl
from fatigue_pin.fatigue.michaud import MichaudFatigue
from fatigue_pin.fatigue.models import XiaFatigue
from fatigue_pin.ocp.guesses import rest_guess
from fatigue_pin.ocp.intervals import IntervalFunctions, rk4
from fatigue_pin.ocp.problem import Problem
from fatigue_pin.ocp.transcription import Ocp

XIA = XiaFatigue(LD=10.0, LR=10.0, F=0.456, R=0.0094, S=10.0)
#: arm26's halves: Xia, Xia at rest_load 0 (other equations: a second Xia group), Michaud, Xia
MIXED = {"shoulder": (XIA, XIA.with_(rest_load=0.0, r=15.0)),
         "elbow": (MichaudFatigue(LD=10.0, LR=10.0, F=0.456, R=0.0094, effort_threshold=0.2, effort_factor=0.1), XIA)}


def _problem(arm26, which: str) -> Problem:
    study = small_curl()
    problem = study.problem(arm26)
    if which == "mixed":
        problem = Problem.build(arm26, MIXED, problem.task, problem.costs)
    return problem


def _all_halves_rk4(fn: IntervalFunctions, problem: Problem, substeps: int) -> tuple[ca.Function, ca.SX, ca.SX, ca.SX]:
    """The plain RK4 of every half at once (one SX system of all fatigue states), as the fatigue
    step was built before the per-half steps: the reference."""
    A = problem.actuators
    m, u, p = ca.SX.sym("m", A.n_states), ca.SX.sym("u", 2 * A.nv), ca.SX.sym("p", A.n_params)
    y = rk4(fn.f_fatigue, m, (u, p), problem.task.dt / substeps, substeps)
    return ca.Function("reference", [m, u, p], [y]), m, u, p


def _random_point(problem: Problem, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Fatigue states (fractions), controls within the halves' ranges, parameters scattered
    around the actuators' (a half's parameters differ from its neighbour's)."""
    A = problem.actuators
    m = rng.uniform(0.0, 1.0, A.n_states)
    u = np.concatenate([rng.uniform(0, 1, A.n_actuated) * A.tau_plus_limits, rng.uniform(0, 1, A.n_actuated) * A.tau_minus_limits])
    p = A.param_vector() * rng.uniform(0.5, 1.5, A.n_params)
    return m, u, p


@pytest.mark.parametrize("which", ["arm26", "mixed"])
def test_fatigue_groups_follow_the_halves_equations(arm26, which):
    groups = _problem(arm26, which).actuators.fatigue_groups()
    if which == "arm26":
        assert [(g.label, g.halves) for g in groups] == [("xia", (0, 1, 2, 3))]
        assert groups[0].state_rows == tuple(range(12)) and groups[0].param_rows == tuple(range(24))
    else:  # state offsets 0, 3, 6, 10 (Michaud has 4 states); parameter offsets 0, 6, 12, 19
        assert [(g.label, g.halves) for g in groups] == [("xia", (0, 3)), ("xia_2", (1,)), ("michaud", (2,))]
        assert groups[0].state_rows == (0, 1, 2, 10, 11, 12) and groups[2].state_rows == (6, 7, 8, 9)
        assert groups[0].param_rows == (*range(6), *range(19, 25)) and groups[2].param_rows == tuple(range(12, 19))


@pytest.mark.parametrize("which", ["arm26", "mixed"])
@pytest.mark.parametrize("calls", [False, True])
def test_per_half_fatigue_step_equals_the_rk4_of_all_halves(arm26, which, calls):
    """F_fatigue (calls: the maps of the per-half steps) and the per-half maps over K columns
    (as the transcription uses them) against the plain all-halves RK4: values and the Jacobian
    in (m, u, p) (what the moving-horizon estimator differentiates) to rounding."""
    problem = _problem(arm26, which)
    transcription = small_curl().transcription()
    fn = IntervalFunctions(problem, transcription, fatigue_calls=calls)
    ref, m, u, p = _all_halves_rk4(fn, problem, transcription.substeps)
    assert fn.F_fatigue.is_a("MXFunction") == calls
    rng = np.random.default_rng(1)
    ref_jac = ca.Function("J", [m, u, p], [ca.jacobian(ref(m, u, p), ca.vertcat(m, u, p))])
    mx = [ca.MX.sym(n, s.numel()) for n, s in (("m", m), ("u", u), ("p", p))]
    mine_jac = ca.Function("J", mx, [ca.jacobian(fn.F_fatigue(*mx), ca.vertcat(*mx))])
    K = 3
    M, U, P = (ca.MX.sym("M", m.numel(), K), ca.MX.sym("U", u.numel(), K), ca.MX.sym("P", p.numel()))
    by_columns = ca.Function("columns", [M, U, P], [fn.fatigue_by_groups(M, U, P)])
    for _ in range(4):
        point = _random_point(problem, rng)
        y0 = np.asarray(ref(*point)).ravel()
        assert np.abs(np.asarray(fn.F_fatigue(*point)).ravel() - y0).max() <= 1e-14
        J0 = np.asarray(ref_jac(*point))
        assert np.abs(np.asarray(mine_jac(*point)) - J0).max() <= 1e-12 * max(1.0, np.abs(J0).max())
        cols = [_random_point(problem, rng) for _ in range(K)]
        Mv, Uv = np.column_stack([c[0] for c in cols]), np.column_stack([c[1] for c in cols])
        out = np.asarray(by_columns(Mv, Uv, point[2]))
        expected = np.column_stack([np.asarray(ref(Mv[:, k], Uv[:, k], point[2])).ravel() for k in range(K)])
        assert np.abs(out - expected).max() <= 1e-14


@pytest.mark.parametrize("which", ["arm26", "mixed"])
def test_per_half_blocks_equal_the_derivatives_of_the_all_halves_rk4(arm26, which):
    """The derivative blocks of the per-half steps (one half, w = (m_h, TL_h)), placed by hand
    with TL_h = u_row(h) / signed limit, give ``ca.jacobian`` and ``ca.hessian`` of mu' RK4 of
    all halves in (m, u)."""
    problem = _problem(arm26, which)
    transcription = small_curl().transcription()
    fn = IntervalFunctions(problem, transcription, fatigue_calls=True)
    fn.build_blocks({name: (0, 1) for name in fn.fatigue_steps})
    ref, m, u, p = _all_halves_rk4(fn, problem, transcription.substeps)
    A = problem.actuators
    mu = ca.SX.sym("mu", A.n_states)
    w = ca.vertcat(m, u)
    y = ref(m, u, p)
    derivatives = ca.Function("d", [m, u, p, mu], [ca.jacobian(y, w), ca.hessian(ca.dot(mu, y), w)[0]])
    rows, limits = A.control_rows(), A.signed_limits
    rng = np.random.default_rng(2)
    for _ in range(3):
        mv, uv, pv = _random_point(problem, rng)
        muv = rng.normal(size=A.n_states)
        J0, H0 = (np.asarray(d) for d in derivatives(mv, uv, pv, muv))
        J, H = np.zeros_like(J0), np.zeros_like(H0)
        for group in fn.fatigue_groups:
            pair = fn.blocks[f"F_fatigue_{group.label}"]
            ns, npar = group.model.n_states(), group.model.n_params()
            for i, half in enumerate(group.halves):
                srows = list(group.state_rows[i * ns : (i + 1) * ns])
                ph = pv[list(group.param_rows[i * npar : (i + 1) * npar])]
                wh = np.r_[mv[srows], uv[rows[half]] / limits[half]]
                Jh = np.asarray(ca.densify(pair.jac(wh, ph)[1]))
                Hh = np.asarray(ca.densify(pair.hess(wh, ph, muv[srows])))
                Hh = Hh + np.tril(Hh, -1).T  # the block holds the lower triangle
                # dw_h/dw: identity on the half's states, 1 / limit on its control
                D = np.zeros((ns + 1, J0.shape[1]))
                D[np.arange(ns), srows] = 1.0
                D[ns, A.n_states + rows[half]] = 1.0 / limits[half]
                J[srows, :] += Jh @ D
                H += D.T @ Hh @ D
        assert np.abs(J - J0).max() <= 1e-12 * max(1.0, np.abs(J0).max())
        assert np.abs(H - H0).max() <= 1e-12 * max(1.0, np.abs(H0).max())


@pytest.mark.parametrize("which", ["arm26", "mixed"])
def test_nlp_derivatives_with_per_half_blocks_equal_the_all_halves_nlps(arm26, which):
    """The NLP with derivative blocks (the fatigue gaps as maps of the per-half steps) against
    the NLP without (one map of the all-halves step, CasADi's own derivatives): the same
    constraints, Jacobian and Lagrangian Hessian at random points, row for row."""
    problem = _problem(arm26, which)
    study = small_curl()
    ocps = {blocks: Ocp(problem, 1, study.transcription(), dataclasses.replace(study.solver(), compile=False, derivative_blocks=blocks))
            for blocks in (True, False)}
    mine, theirs = ocps[True], ocps[False]
    assert "F_fatigue" in {c.function.name() for c in theirs.mapped_calls}
    assert {f"F_fatigue_{g.label}" for g in mine.functions.fatigue_groups} <= {c.function.name() for c in mine.mapped_calls}
    reference = ca.nlpsol("reference", "ipopt", theirs.nlp.problem, {"print_time": False})
    jac_ref, hess_ref = reference.get_function("nlp_jac_g"), reference.get_function("nlp_hess_l")
    rng = np.random.default_rng(3)
    z0, p0 = mine.flatten(*rest_guess(mine)), mine.parameter_vector()
    for _ in range(2):
        z = z0 + 0.2 * rng.normal(size=z0.size)
        p = p0 * (1 + 0.1 * rng.normal(size=p0.size))
        lam_f, lam_g = rng.normal(), rng.normal(size=mine.nlp.n_g)
        (g, jac), (g0, jac0) = mine.nlp.derivatives["jac_g"](z, p), jac_ref(z, p)
        hess, hess0 = mine.nlp.derivatives["hess_lag"](z, p, lam_f, lam_g), hess_ref(z, p, lam_f, lam_g)
        assert np.abs(np.asarray(g) - np.asarray(g0)).max() <= 1e-12
        for a, b in ((jac, jac0), (hess, hess0)):
            scale = max(1.0, float(ca.norm_inf(b)))
            assert float(ca.norm_inf(ca.densify(a) - ca.densify(b))) <= 1e-11 * scale


def test_mixed_models_solve_with_the_per_half_blocks_as_without(arm26):
    """Mixed fatigue models: a solve with the per-half blocks takes the all-halves NLP's path."""
    problem = _problem(arm26, "mixed")
    study = small_curl()
    sols = [Ocp(problem, 1, study.transcription(), dataclasses.replace(study.solver(), compile=False, derivative_blocks=b)).solve()
            for b in (True, False)]
    assert sols[0].success and sols[1].success and sols[0].iterations == sols[1].iterations
    assert sols[0].objective == pytest.approx(sols[1].objective, rel=1e-9)
    assert np.abs(sols[0].x - sols[1].x).max() < 1e-8
