"""The reference integration of verify (fatigue_pin.verify.dynamics): a right-hand side that turns
non-finite stops it at once (a NaN gravity or state used to make solve_ivp loop for ever), and it
agrees with a closed form."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from fatigue_pin.verify.dynamics import IntegrationFailed, integrate, rk4
from fatigue_pin.verify.report import ReferenceIntegration

REF = ReferenceIntegration()


def test_integrate_matches_a_closed_form():
    y = integrate(lambda t, y: np.array([y[1], -4.0 * y[0]]), np.array([1.0, 0.0]), 0.3, REF)
    assert y == pytest.approx([math.cos(0.6), -2 * math.sin(0.6)], abs=1e-10)


@pytest.mark.parametrize("rhs, y0", [
    (lambda t, y: y * np.nan, np.array([1.0])),  # a NaN gravity: every rate NaN
    (lambda t, y: -y, np.array([np.nan])),  # a NaN stored state
    (lambda t, y: np.array([1.0 / (0.1 - t)]) if t < 0.1 else np.array([np.inf]), np.array([0.0])),  # a blow-up
])
def test_non_finite_rates_stop_the_integration(rhs, y0):
    start = time.monotonic()
    with pytest.raises(IntegrationFailed):
        integrate(rhs, y0, 0.2, REF)
    assert time.monotonic() - start < 5.0


def test_rk4_is_fourth_order():
    f = lambda t, y: -y  # noqa: E731
    errors = [abs(rk4(f, np.array([1.0]), 1.0, s)[0] - math.exp(-1.0)) for s in (4, 8)]
    assert 14 < errors[0] / errors[1] < 18
