"""Shared fixtures: the arm26 model and small versions of the paper's curl."""

from __future__ import annotations

import pytest

from fatigue_pin.full import OcpBuilder
from fatigue_pin.model import load_model
from fatigue_pin.paper import curl_study


def small_curl(horizon: str = "full", cost: str = "fatigue-torque", preset: str = "paper", S: float = 10.0, **kwargs):
    """The paper's curl with 10 intervals per cycle and 2 RK4 substeps, evaluated without
    compiling: solves in about a second."""
    kwargs.setdefault("solver", {"compile": False})
    kwargs.setdefault("intervals_per_cycle", 10)
    kwargs.setdefault("substeps", 2)
    return curl_study(horizon, cost, preset, S, **kwargs)


@pytest.fixture(scope="session")
def arm26():
    return load_model()


@pytest.fixture(scope="session")
def small_study():
    return small_curl()


@pytest.fixture(scope="session")
def small_problem(arm26, small_study):
    return small_study.problem(arm26)


@pytest.fixture(scope="session")
def build(small_problem, small_study):
    """``build(n_cycles, **changes)``: an Ocp of the small curl (interval functions shared)."""
    builder = OcpBuilder(small_problem, small_study.transcription(), small_study.solver())
    return builder
