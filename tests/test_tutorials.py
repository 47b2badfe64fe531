"""The tutorial notebooks (docs/tutorials/*.ipynb) run top to bottom in a fresh kernel, on the
small settings they take from ``FATIGUE_PIN_TUTORIAL_QUICK=1``, and print what they teach."""

from __future__ import annotations

import json
from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

TUTORIALS = Path(__file__).resolve().parents[1] / "docs" / "tutorials"
NOTEBOOKS = sorted(TUTORIALS.glob("*.ipynb"))

# what each notebook's outputs must show (a finished solve, a fit, a sweep ...)
EXPECTED = {
    "01_curl_in_five_minutes": ["window   0 (cycles 1-3): converged", "sliding/fatigue-torque_S10 4 cycles",
                                "replay.html", "gap fatigue states"],
    "02_your_robot_and_task": ["with tool_speed  Solve_Succeeded", "without          Solve_Succeeded",
                               "integral of the squared tool speed"],
    "03_fatigue_models": ["'rakshit-2021': 28", "r=4.93, rest_load=0.0", "95 % interval", "LoadDependentFatigue"],
    "04_sweeps": ["2 jobs run, 0 errors", "0 jobs run the second time", "'not converged'"],
}


def test_there_are_four_tutorials_committed_without_outputs():
    assert [p.stem for p in NOTEBOOKS] == sorted(EXPECTED)
    for path in NOTEBOOKS:
        nb = nbformat.read(path, as_version=4)
        nbformat.validate(nb)
        code = [c for c in nb.cells if c.cell_type == "code"]
        assert code and all(not c.outputs and c.execution_count is None for c in code), f"{path.name} has outputs"
        imports = "\n".join(c.source for c in code)
        assert "from fatigue_pin import" in imports and "fatigue_pin." not in imports.replace("from fatigue_pin import", "")


def _text(nb) -> str:
    parts = []
    for cell in nb.cells:
        for output in cell.get("outputs", []):
            if output.get("output_type") == "stream":
                parts.append(output["text"])
            elif "data" in output:
                parts.append(output["data"].get("text/plain", ""))
    return "\n".join(parts)


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_tutorial_runs_top_to_bottom(path, tmp_path, monkeypatch):
    monkeypatch.setenv("FATIGUE_PIN_TUTORIAL_QUICK", "1")
    monkeypatch.setenv("MPLBACKEND", "module://matplotlib_inline.backend_inline")
    nb = nbformat.read(path, as_version=4)
    NotebookClient(nb, timeout=600, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}}).execute()
    text = _text(nb)
    for expected in EXPECTED[path.stem]:
        assert expected in text, f"{path.name}: {expected!r} not in its outputs:\n{text[-3000:]}"
    images = sum("image/png" in o.get("data", {}) for c in nb.cells for o in c.get("outputs", []))
    assert images >= 1, f"{path.name} shows no figure"
    json.dumps(nb)  # the executed notebook is still plain JSON
