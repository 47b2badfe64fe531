"""Cost terms: the built-in kinds, and a term of one's own through the public API only."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from conftest import small_curl
from fatigue_pin.ocp.costs import CostTerm, IntervalVariables, cost_term
from fatigue_pin.core.errors import ParameterError
from fatigue_pin.drivers.full import OcpBuilder
from fatigue_pin.ocp.problem import Problem


def _elbow_speed_integral(sol, problem) -> float:
    j = problem.model.joint_names.index("elbow")
    return float(np.sum(sol.qdot[:-1, j] ** 2) * problem.task.dt)


def test_a_cost_term_of_ones_own_changes_the_solution_in_the_expected_direction(arm26):
    """Add elbow velocity squared as a new term: the optimum moves the elbow more slowly (a
    smaller integral of qdot^2), and the term is reported per cycle under its name."""
    study = small_curl("full", cycles=1)
    base = study.problem(arm26)
    mine = CostTerm("elbow_velocity", 5.0, lambda v: v.qdot("elbow") ** 2)
    with_term = Problem(base.model, base.actuators, base.task, (*base.costs, mine))
    plain = OcpBuilder(base, study.transcription(), study.solver())(1).solve()
    ocp = OcpBuilder(with_term, study.transcription(), study.solver())(1)
    sol = ocp.solve()
    assert plain.success and sol.success
    assert _elbow_speed_integral(sol, base) < 0.95 * _elbow_speed_integral(plain, base)
    assert sol.cost_terms[-1] == "elbow_velocity" and sol.cycle_costs.shape == (1, 5)
    assert sol.cycle_costs[0, -1] == pytest.approx(5.0 * _elbow_speed_integral(sol, base), rel=1e-9)
    assert sol.cycle_costs.sum() == pytest.approx(sol.objective, rel=1e-8)
    # the weight is a parameter: zero it and the NLP gives back the plain solution
    zero = ocp.solve(weights={"elbow_velocity": 0.0})
    assert zero.objective == pytest.approx(plain.objective, rel=1e-6)


def test_builtin_kinds_evaluate_their_formulas(arm26):
    problem = small_curl().problem(arm26)
    L = problem.layout
    x, u, up = ca.SX.sym("x", L.nx), ca.SX.sym("u", L.nu), ca.SX.sym("up", L.nu)
    v = IntervalVariables(x, u, up, L, problem.model, problem.actuators)
    rng = np.random.default_rng(1)
    xv, uv, upv = rng.normal(size=L.nx), rng.normal(size=L.nu), rng.normal(size=L.nu)

    def value(term: CostTerm) -> float:
        return float(ca.Function("f", [x, u, up], [term.expression(v)])(xv, uv, upv))

    assert value(cost_term("posture", 1.0, joints=["shoulder"])) == pytest.approx(xv[0] ** 2)
    assert value(cost_term("velocity", 1.0, joints=["elbow"])) == pytest.approx(xv[L.nq + 1] ** 2)
    assert value(cost_term("torque_rate", 1.0)) == pytest.approx(np.sum((uv - upv) ** 2))
    assert value(cost_term("torque", 1.0)) == pytest.approx(np.sum(uv**2))
    assert value(cost_term("fatigue", 1.0)) == pytest.approx(np.sum(xv[L.fatigue_index("mf")] ** 2))


def test_bad_cost_terms(arm26):
    with pytest.raises(ParameterError, match="weight = -1"):
        CostTerm("x", -1.0, lambda v: v.q() ** 2)
    with pytest.raises(ParameterError, match="identifier"):
        CostTerm("my term", 1.0, lambda v: v.q() ** 2)
    with pytest.raises(ParameterError, match="unknown"):
        cost_term("jerk", 1.0)
    with pytest.raises(ParameterError, match="appears twice"):
        base = small_curl().problem(arm26)
        Problem(base.model, base.actuators, base.task, (cost_term("torque", 1.0), cost_term("torque", 2.0)))
