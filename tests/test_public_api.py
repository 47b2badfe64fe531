"""The public API of fatigue_pin/__init__.py: every name in ``_API`` is the object its module
owns, and ``import fatigue_pin`` loads none of them (nor CasADi) until one is used."""

from __future__ import annotations

import importlib
import subprocess
import sys

import fatigue_pin


def test_every_public_name_is_its_modules_object():
    for name, module in fatigue_pin._API.items():
        assert getattr(fatigue_pin, name) is getattr(importlib.import_module(module), name), name
    assert set(fatigue_pin.__all__) == set(fatigue_pin._API) | {"__version__"}


def test_import_is_lazy():
    code = ("import sys, fatigue_pin; assert 'casadi' not in sys.modules, 'casadi'; "
            "fatigue_pin.preset; assert 'fatigue_pin.fatigue.presets' in sys.modules")
    subprocess.run([sys.executable, "-c", code], check=True)
