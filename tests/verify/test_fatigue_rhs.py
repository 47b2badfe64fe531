"""The numpy transcriptions of the fatigue models (fatigue_pin.verify.fatigue_rhs) against the
models' own rates, on every branch of their piecewise right-hand sides."""

from __future__ import annotations

import numpy as np

from fatigue_pin.fatigue.michaud import MichaudFatigue
from fatigue_pin.fatigue.models import XiaFatigue
from fatigue_pin.verify.fatigue_rhs import numpy_rhs


def test_numpy_rhs_matches_the_models_rates_on_every_branch():
    rng = np.random.default_rng(0)
    models = [XiaFatigue(10, 10, 0.456, 0.0094, 10.0, 3.0), XiaFatigue(10, 10, 0.456, 0.0094, 10.0, 3.0, rest_load=0.3),
              MichaudFatigue(10, 10, 0.456, 0.0094, effort_threshold=0.2, effort_factor=0.1, stabilization_factor=1.0)]
    for model in models:
        f, p = numpy_rhs(model.kind), model.as_dict()
        for _ in range(300):
            m = rng.uniform(0, 1, model.n_states())
            TL = float(rng.choice([rng.uniform(0, 1), p.get("effort_threshold", 0.5), m[0]]))
            assert np.allclose(f(m, TL, p), model.rates(m, TL), rtol=1e-13, atol=1e-14)


def test_unknown_kind_has_no_numpy_transcription():
    assert numpy_rhs("hill") is None
