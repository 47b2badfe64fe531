"""Problems: state layouts addressed by name, and a fatigue model of one's own next to Xia's."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import casadi as ca
import numpy as np
import pytest

from conftest import small_curl
from fatigue_pin.core.errors import ParameterError
from fatigue_pin.fatigue.interface import FatigueModel
from fatigue_pin.drivers.full import OcpBuilder
from fatigue_pin.drivers.run import solution_to_run
from fatigue_pin.paper.curl import ocp_params
from fatigue_pin.ocp.problem import Problem
from fatigue_pin.io.results import read_run, write_run


@dataclass(frozen=True)
class TwoCompartment(FatigueModel):
    """A model of one's own (the worked example of docs/fatigue.md): active ma and fatigued mf,
    dma/dt = L (TL - ma) - F ma, dmf/dt = F ma - R mf."""

    kind: ClassVar[str] = "two-compartment"
    state_names: ClassVar[tuple[str, ...]] = ("ma", "mf")
    param_names: ClassVar[tuple[str, ...]] = ("L", "F", "R")
    param_units: ClassVar[tuple[str, ...]] = ("1/s", "1/s", "1/s")
    fatigued_state: ClassVar[str] = "mf"

    L: float
    F: float
    R: float

    @classmethod
    def rhs(cls) -> ca.Function:
        m, TL, p = ca.SX.sym("m", 2), ca.SX.sym("TL"), ca.SX.sym("p", 3)
        dma = p[0] * (TL - m[0]) - p[1] * m[0]
        dmf = p[1] * m[0] - p[2] * m[1]
        return ca.Function("two_compartment", [m, TL, p], [ca.vertcat(dma, dmf)])

    @classmethod
    def rest_state(cls) -> np.ndarray:
        return np.zeros(2)


@pytest.fixture(scope="module")
def mixed(arm26):
    """Shoulder halves with the two-compartment model, elbow halves with Xia's 3CC-S."""
    study = small_curl("full", cycles=1)
    base = study.problem(arm26)
    problem = Problem.build(arm26, {"shoulder": TwoCompartment(L=10.0, F=0.3, R=0.01), "elbow": ocp_params("paper")},
                            base.task, base.costs)
    return study, problem


def test_layout_addresses_states_by_name(mixed):
    _, problem = mixed
    L = problem.layout
    assert L.nx == 2 + 2 + 2 * 2 + 2 * 3
    assert L.state_kinds == ("ma", "mf", "mr")
    assert L.rows("mf") == [5, 7, 10, 13]
    assert L.rows("mr") == [None, None, 9, 12]
    with pytest.raises(ParameterError, match="'mr' is not a state of halves"):
        L.fatigue_index("mr")
    assert list(problem.actuators.initial_state()) == [0, 0, 0, 0, 0, 1, 0, 0, 1, 0]
    assert problem.actuators.n_params == 3 + 3 + 6 + 6


def test_an_ocp_with_a_model_of_ones_own(mixed, tmp_path):
    study, problem = mixed
    ocp = OcpBuilder(problem, study.transcription(), study.solver())(1)
    sol = ocp.solve()
    assert sol.success
    # the shoulder halves follow the two-compartment equations: re-integrate one interval
    p = ocp.actuators.param_vector()
    nxt = np.asarray(ocp.functions.F_fatigue(sol.x[3, ocp.layout.m], sol.u[3], p)).ravel()
    assert np.allclose(nxt, sol.x[4, ocp.layout.m], atol=1e-6)
    # coupling with each half's own fatigued state
    TL = np.abs(np.column_stack([sol.tau_plus[:, 0], sol.tau_minus[:, 0]])) / 50.0
    mf = sol.x[:-1, [5, 7]]
    assert np.all(TL + mf <= 1 + 1e-6)
    # result files and readers take whatever states the models declare
    path = tmp_path / "mixed.h5"
    write_run(path, solution_to_run(ocp, sol, "full/mixed"))
    run = read_run(path, "full/mixed")
    assert run.fatigue_states == ("ma", "mf", "mr")
    assert np.all(np.isnan(run.fatigue["mr"][:, :2])) and np.all(np.isfinite(run.fatigue["mr"][:, 2:]))
    assert np.allclose(run.fatigued, sol.x[:, [5, 7, 10, 13]])


def test_problem_refuses_mismatched_parts(arm26):
    base = small_curl().problem(arm26)
    with pytest.raises(ParameterError, match="x_init has 3 entries"):
        Problem(base.model, base.actuators, base.task, base.costs, x_init=np.zeros(3))
    with pytest.raises(ParameterError, match="not in the problem"):
        base.weight_vector({"jerk": 1.0})
