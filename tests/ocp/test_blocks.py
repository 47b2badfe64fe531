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
        assert np.allclose(np.asarray(g), np.asarray(g0), rtol=1e-12, atol=1e-12)
        for mine, theirs in ((jac, jac0), (hess, hess0)):
            scale = max(1.0, float(ca.norm_inf(theirs)))
            assert float(ca.norm_inf(ca.densify(mine) - ca.densify(theirs))) <= 1e-11 * scale
        assert hess.sparsity().is_triu()  # the upper triangle, as IPOPT reads it


def test_arm26_blocks_equal_casadis_derivatives(arm26):
    ocp = _ocp(small_curl(), arm26, 2, blocks=True)
    assert {c.function.name() for c in ocp.mapped_calls} == {"F_rb", "F_fatigue", "coupling", "terms"}
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
