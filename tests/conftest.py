"""Shared fixtures: the arm26 model and small versions of the curl OCP."""

from __future__ import annotations

import pytest

from fatigue_pin.model import load_model
from fatigue_pin.ocp import CyclicTask, OcpSettings
from fatigue_pin.solver import SolverOptions


@pytest.fixture(scope="session")
def arm26():
    return load_model()


@pytest.fixture(scope="session")
def small_settings() -> OcpSettings:
    """The paper's curl with 10 intervals per cycle and 2 RK4 substeps, evaluated without
    compiling: solves in about a second."""
    return OcpSettings(task=CyclicTask(intervals_per_cycle=10), substeps=2, solver=SolverOptions(compile=False))
