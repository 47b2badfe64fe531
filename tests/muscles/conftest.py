"""Shared builders of the muscle tests: the bundled arm26 muscles and their geometry."""

from __future__ import annotations

import pytest

from fatigue_pin.muscles.files import load_muscles
from fatigue_pin.muscles.geometry import MuscleGeometry


@pytest.fixture(scope="session")
def arm26_muscles():
    return load_muscles("arm26")


@pytest.fixture(scope="session")
def arm26_geometry(arm26, arm26_muscles):
    """Paths with the humeral cylinder TRI."""
    return MuscleGeometry(arm26.pin_model, arm26_muscles)


@pytest.fixture(scope="session")
def arm26_geometry_unwrapped(arm26, arm26_muscles):
    """Straight segments between the path points."""
    return MuscleGeometry(arm26.pin_model, arm26_muscles.without_wraps())
