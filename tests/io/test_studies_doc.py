"""docs/studies.md lists exactly the keys the study tables take from their classes, with their
defaults: a field added to a settings class fails here until the doc has its row."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import pytest

from fatigue_pin.core.settings import REQUIRED
from fatigue_pin.io.tables import key_tables

DOC = Path(__file__).resolve().parents[2] / "docs" / "studies.md"

#: the heading of each table in the doc -> the table of key_tables()
HEADINGS = {
    "## `[model]` (required)": "model",
    "### `model.payload`": "model.payload",
    "## `[actuators]`": "actuators",
    "## `[task]` (required)": "task",
    "### `[[task.targets]]`: joint targets": "task.targets (joint)",
    "### `[[task.targets]]`: frame targets": "task.targets (frame)",
    "### `[[task.targets]]`: state targets": "task.targets (state)",
    "### `[[task.ranges]]`": "task.ranges",
    "### `[[task.planes]]`": "task.planes",
    "## `[transcription]`": "transcription",
    "## `[horizon]`": "horizon",
    "## `[solver]`": "solver",
}


def doc_tables(text: str) -> dict[str, dict[str, str]]:
    """key -> default cell of the first Markdown table after each heading of HEADINGS."""
    out: dict[str, dict[str, str]] = {}
    lines = text.splitlines()
    for i, line in enumerate(lines):
        if line.strip() not in HEADINGS:
            continue
        rows: dict[str, str] = {}
        j = i + 1
        while j < len(lines) and not lines[j].startswith("|"):
            j += 1
        for row in lines[j + 2:]:  # after the header and the |---| line
            if not row.startswith("|"):
                break
            cells = [c.strip() for c in row.strip("|").split("|")]
            rows[cells[0].strip("`")] = cells[2]
        out[HEADINGS[line.strip()]] = rows
    return out


def _default(cell: str):
    """A default cell's value: REQUIRED, None, or the TOML value in backticks."""
    if cell.startswith("required"):
        return REQUIRED
    if cell == "none":
        return None
    match = re.fullmatch(r"`(.*)`", cell)
    assert match, f"default cell {cell!r}: expected required, none or a TOML value in backticks"
    return tomllib.loads(f"v = {match.group(1)}")["v"]


def test_every_table_of_the_schema_is_in_the_doc():
    assert set(doc_tables(DOC.read_text())) == set(key_tables()) == set(HEADINGS.values())


@pytest.mark.parametrize("table", sorted(HEADINGS.values()))
def test_the_doc_lists_the_keys_and_defaults_of_the_classes(table):
    documented = doc_tables(DOC.read_text())[table]
    keys = key_tables()[table]
    assert sorted(documented) == sorted(keys), f"[{table}]: keys only in the doc {sorted(set(documented) - set(keys))}, " \
                                               f"only in the classes {sorted(set(keys) - set(documented))}"
    for name, key in keys.items():
        assert _default(documented[name]) == key.default, f"{table}.{name}: the doc says {documented[name]}, the class {key.default!r}"


def test_the_checker_sees_a_missing_key_and_a_wrong_default():
    text = DOC.read_text()
    without = re.sub(r"\n\| `warmup` \|[^\n]*", "", text)
    assert "warmup" not in doc_tables(without)["horizon"] and "warmup" in key_tables()["horizon"]
    wrong = text.replace("| `substeps` | integer | `5` |", "| `substeps` | integer | `4` |")
    assert _default(doc_tables(wrong)["transcription"]["substeps"]) != key_tables()["transcription"]["substeps"].default
