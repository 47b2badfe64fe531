"""The public API: every name exported by ``fatigue_pin`` resolves to the module docs/api.md
names, and docs/api.md lists exactly the exported names and every error class."""

from __future__ import annotations

import importlib
import inspect
import re
from pathlib import Path

import fatigue_pin
import fatigue_pin.core.errors as errors

API_DOC = Path(__file__).resolve().parents[1] / "docs" / "api.md"


def _table(heading: str) -> list[list[str]]:
    """Rows of the Markdown table under ``## heading`` of docs/api.md, cells without backticks."""
    text = API_DOC.read_text().split(f"## {heading}\n", 1)[1].split("\n## ", 1)[0]
    rows = [line for line in text.splitlines() if line.startswith("| ") and not line.startswith("| name") and not line.startswith("| class")]
    return [[c.strip().strip("`") for c in row.strip("|").split("|")] for row in rows if not set(row) <= set("|- ")]


def test_every_exported_name_resolves_to_its_module():
    for name in fatigue_pin.__all__:
        value = getattr(fatigue_pin, name)
        if name == "__version__":
            continue
        module = fatigue_pin._API[name]
        assert getattr(importlib.import_module(module), name) is value
        owner = getattr(value, "__module__", module)
        assert owner == module, f"{name} is defined in {owner}, exported as {module}"


def test_the_api_page_lists_exactly_the_exported_names():
    listed = {row[0]: row[1] for row in _table("The public names")}
    assert listed == fatigue_pin._API


def test_the_api_page_lists_every_error_class():
    classes = {n for n, c in inspect.getmembers(errors, inspect.isclass) if issubclass(c, errors.FatiguePinError)}
    listed = {row[0] for row in _table("Errors")}
    assert listed == classes
    for row in _table("Errors")[1:]:
        bases = {b.strip() for b in row[1].replace("`", "").split(",")}
        assert bases == {b.__name__ for b in getattr(errors, row[0]).__bases__}, row


def test_unknown_names_are_an_attribute_error():
    try:
        fatigue_pin.no_such_name  # noqa: B018
    except AttributeError as exc:
        assert re.search("no_such_name", str(exc))
    else:
        raise AssertionError("no AttributeError")


def test_import_is_lazy():
    """``import fatigue_pin`` loads no public name (nor CasADi) until one is used."""
    import subprocess
    import sys

    code = ("import sys, fatigue_pin; assert 'casadi' not in sys.modules, 'casadi'; "
            "fatigue_pin.preset; assert 'fatigue_pin.fatigue.presets' in sys.modules")
    subprocess.run([sys.executable, "-c", code], check=True)
