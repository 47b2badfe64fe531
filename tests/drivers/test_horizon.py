"""Horizon: the [horizon] table's settings, one owner for the keys every kind reads, the sliding
driver's settings for the rest."""

from __future__ import annotations

import pytest

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.drivers.horizon import Horizon, sliding_defaults
from fatigue_pin.drivers.sliding import SlidingSettings
from fatigue_pin.core.settings import default_of


def test_the_sliding_settings_take_the_window_from_cycles():
    h = Horizon(kind="sliding", cycles=4, sliding={"advance": 2, "max_cycles": 9})
    assert h.sliding_settings() == SlidingSettings(window=4, advance=2, max_cycles=9)
    assert h.max_cycles == 9 and h.end_tolerance == default_of(SlidingSettings, "end_tolerance")
    assert h.run_prefix == "sliding" and h.end_box is None


def test_missing_sliding_keys_take_the_sliding_defaults():
    h = Horizon()
    assert h.sliding == sliding_defaults() and "window" not in h.sliding
    assert h.sliding["warmup"] == default_of(SlidingSettings, "warmup")


def test_every_kind_checks_each_sliding_key_alone():
    for kind in ("full", "sliding", "max-cycles"):
        with pytest.raises(ParameterError, match=r"SlidingSettings.min_iterations = -1: expected an integer >= 0"):
            Horizon(kind=kind, cycles=3, sliding={"min_iterations": -1})
    with pytest.raises(ParameterError, match=r"unknown setting 'window'"):
        Horizon(sliding={"window": 3})


def test_only_sliding_relates_the_sliding_keys_to_the_window():
    with pytest.raises(ParameterError, match=r"SlidingSettings.advance = 4: expected an integer in \[1, window = 3\]"):
        Horizon(kind="sliding", cycles=3, sliding={"advance": 4})
    search = Horizon(kind="max-cycles", cycles=3, sliding={"max_cycles": 2})  # cycles is not a window here
    assert search.max_cycles == 2 and search.run_prefix == "full"
    full = Horizon(kind="full", cycles=2, cyclic_end=True, sliding={"end_tolerance": 0.02})
    assert full.end_box == 0.02


def test_bad_horizon_keys():
    with pytest.raises(ParameterError, match=r"Horizon.kind = 'circular': expected 'full', 'sliding' or 'max-cycles'"):
        Horizon(kind="circular")
    with pytest.raises(ParameterError, match=r"Horizon.guess = 'zero'"):
        Horizon(guess="zero")
    with pytest.raises(ParameterError, match=r"Horizon.cycles = 0"):
        Horizon(cycles=0)
