"""usable_cores: the process's affinity mask, not the machine's core count."""

from __future__ import annotations

import dataclasses
import os

import pytest

from fatigue_pin.core.cores import usable_cores
from fatigue_pin.drivers.full import OcpBuilder


def test_usable_cores_follow_the_affinity_mask(monkeypatch):
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {3, 5}, raising=False)
    monkeypatch.setattr(os, "cpu_count", lambda: 64)
    assert usable_cores() == 2


def test_without_affinity_masks_the_machine_count_is_used(monkeypatch):
    monkeypatch.delattr(os, "sched_getaffinity", raising=False)
    monkeypatch.setattr(os, "cpu_count", lambda: 12)
    assert usable_cores() == 12
    monkeypatch.setattr(os, "cpu_count", lambda: None)
    assert usable_cores() == 1


@pytest.mark.skipif(not hasattr(os, "sched_getaffinity"), reason="the system has no affinity masks")
def test_a_thread_map_starts_a_thread_per_granted_core(monkeypatch, small_problem, small_study):
    """A process granted one core of the machine maps its intervals on one thread."""
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0}, raising=False)
    monkeypatch.setattr(os, "cpu_count", lambda: 64)
    transcription = dataclasses.replace(small_study.transcription(), parallel="thread")
    ocp = OcpBuilder(small_problem, transcription, small_study.solver())(1)
    assert ocp._map_args == ("thread", 1)
