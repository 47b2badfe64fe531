"""The settings and the report of verify (fatigue_pin.verify.report): tolerances are validated
before any integration, and the report's lines and verdicts."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.verify.report import ReferenceIntegration, VerifyCheck, VerifyTolerances, worst


@pytest.mark.parametrize("changes, message", [
    ({"rtol": math.nan}, r"rtol = nan: expected a finite relative tolerance > 0"),
    ({"rtol": 0.0}, r"rtol = 0.0: expected a finite relative tolerance > 0"),
    ({"rtol": math.inf}, r"rtol = inf"),
    ({"atol": -1.0}, r"atol = -1.0: expected a finite absolute tolerance >= 0"),
    ({"atol": math.nan}, r"atol = nan"),
    ({"atol": "1e-6"}, r"atol = '1e-6'"),
    ({"method": "Euler"}, r"method = 'Euler': expected one of \['DOP853'"),
])
def test_reference_integration_refuses_bad_settings(changes, message):
    with pytest.raises(ParameterError, match=message):
        ReferenceIntegration(**changes)


def test_reference_integration_accepts_zero_atol():
    ref = ReferenceIntegration(rtol=1e-3, atol=0, method="RK45")
    assert ref.atol == 0.0 and isinstance(ref.atol, float)


@pytest.mark.parametrize("name", ["gap", "gap_fatigue", "task", "coupling", "bound"])
@pytest.mark.parametrize("value", [math.nan, -1e-9, math.inf, True])
def test_tolerances_refuse_bad_values(name, value):
    with pytest.raises(ParameterError, match=rf"VerifyTolerances.{name} = "):
        VerifyTolerances(**{name: value})


def test_verdicts():
    assert VerifyCheck("a", 2e-4, "rad", 1e-4).verdict == "FAIL"
    assert VerifyCheck("a", 1e-4, "rad", 1e-4).verdict == "ok"
    assert VerifyCheck("a", math.nan, "rad", 1e-4).verdict == "not checked" and VerifyCheck("a", math.nan, "", 1e-4).passed
    assert VerifyCheck("a", math.inf, "rad", None).verdict == "reported"
    assert VerifyCheck("a", math.inf, "rad", 1.0).verdict == "FAIL"


def test_worst_names_the_place_and_keeps_infinity():
    v = np.array([[0.0, 1e-3], [np.nan, 2e-3], [np.inf, 0.0]])
    assert worst(v, ["a", "b"], "interval", offset=10) == (math.inf, "interval 12, a")
    assert worst(v[:2], ["a", "b"], "node") == (2e-3, "node 1, b")
    assert worst(np.full((2, 2), np.nan), ["a", "b"], "node") == (0.0, "")
    assert worst(-np.ones((2, 2)), ["a", "b"], "node") == (0.0, "")
