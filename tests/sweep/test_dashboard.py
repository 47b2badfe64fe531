"""The sweep's dashboard line (fatigue_pin.sweep.cluster.dashboard): its address, or that it is off
and why (Dask's dashboard needs bokeh, the ``dashboard`` extra)."""

from __future__ import annotations

import importlib.util
from types import SimpleNamespace

from fatigue_pin.sweep import cluster


def _client(services):
    return SimpleNamespace(scheduler_info=lambda: {"services": services}, dashboard_link="http://127.0.0.1:8787/status")


def test_dashboard_address_when_the_scheduler_serves_one():
    assert cluster.dashboard(_client({"dashboard": 8787})) == "dashboard: http://127.0.0.1:8787/status"


def test_dashboard_off_says_it_needs_bokeh(monkeypatch):
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "bokeh" else real(name, *a))
    line = cluster.dashboard(_client({}))
    assert line.startswith("dashboard: off") and "bokeh" in line and "fatigue_pin[dashboard]" in line


def test_dashboard_off_with_bokeh_installed(monkeypatch):
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: object())
    assert cluster.dashboard(_client({})) == "dashboard: off (the scheduler serves none)"
