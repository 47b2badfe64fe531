"""Tests of the named fatigue presets and calibrated parameter files (fatigue_pin.fatigue.presets)."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.fatigue.models import MichaudFatigue, XiaFatigue
from fatigue_pin.paper.curl import ocp_params
from fatigue_pin.fatigue.presets import FREY_LAW_2012_JOINTS, PRESETS, PresetFileError, load_preset_json, preset, preset_source

DOCS = Path(__file__).resolve().parents[2] / "docs" / "fatigue.md"

TABLE_1 = {  # Frey-Law, Looft & Heitsman (2012) Table 1, F and R (1/s)
    "ankle": (0.00589, 0.00058), "knee": (0.01500, 0.00149), "trunk": (0.00755, 0.00075),
    "shoulder": (0.01820, 0.00168), "elbow": (0.00912, 0.00094), "hand": (0.00980, 0.00064),
    "general": (0.00970, 0.00091),
}


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_every_preset_loads_has_a_source_and_a_docs_line(name):
    kind, values, source = PRESETS[name]
    model = preset(name)
    assert model.kind == kind and model.as_dict() == pytest.approx(values)
    assert len(source) > 40 and preset_source(name) == source
    assert f"`{name}`" in DOCS.read_text(), f"docs/fatigue.md has no line for preset {name}"


@pytest.mark.parametrize("joint", sorted(TABLE_1))
def test_frey_law_2012_values(joint):
    m = preset(f"frey-law-2012/{joint}")
    assert isinstance(m, XiaFatigue)
    assert (m.F, m.R) == TABLE_1[joint]
    assert (m.LD, m.LR, m.S, m.r) == (10.0, 10.0, 0.0, 1.0)
    assert FREY_LAW_2012_JOINTS[joint] == TABLE_1[joint]
    assert "doi:10.1016/j.jbiomech.2012.04.018" in preset_source(f"frey-law-2012/{joint}")


def test_grip_is_hand():
    assert preset("frey-law-2012/grip") == preset("frey-law-2012/hand")


def test_puchaud_presets_match_paper_module():
    assert preset("puchaud-2023/authors-code") == ocp_params("authors-code", S=10.0)
    assert preset("puchaud-2023/paper") == ocp_params("paper", S=10.0)
    assert preset("puchaud-2023/paper").R == 0.00094 and preset("puchaud-2023/authors-code").R == 0.0094


def test_michaud_preset():
    m = preset("bioptim/michaud-pendulum")
    assert isinstance(m, MichaudFatigue) and m.effort_threshold == 0.2 and m.stabilization_factor == 10.0


def test_overrides_and_errors():
    assert preset("frey-law-2012/elbow", S=10.0).S == 10.0
    with pytest.raises(ParameterError, match=re.escape("has no parameter(s) ['X']")):
        preset("frey-law-2012/elbow", X=1.0)
    with pytest.raises(ParameterError, match="F = -1.0"):
        preset("frey-law-2012/elbow", F=-1.0)
    with pytest.raises(ParameterError, match="'frey-law-2012/wrist' is unknown"):
        preset("frey-law-2012/wrist")


def test_json_preset(tmp_path):
    path = tmp_path / "params.json"
    path.write_text(json.dumps({"model": "3cc-r", "F": 0.01, "R": 0.001, "r": 12.0, "LD": 10, "LR": 10,
                                "confidence_intervals": {"F": [0.009, 0.011]}, "source": "my lab"}))
    m = preset(str(path))
    assert m == XiaFatigue(LD=10, LR=10, F=0.01, R=0.001, S=0.0, r=12.0)
    assert preset(str(path), S=5.0).S == 5.0
    assert preset_source(str(path)) == "my lab"
    path.write_text(json.dumps({"model": "3cc", "F": 0.01, "R": 0.001, "LD": 10, "LR": 10}))
    assert load_preset_json(path).r == 1.0


@pytest.mark.parametrize(
    "content, message",
    [
        ("not json", "not readable JSON"),
        ("[1, 2]", "holds a list"),
        ('{"model": ["3cc"], "F": 0.01, "R": 0.001, "LD": 10, "LR": 10}', "model = ['3cc']: expected one of"),
        ('{"model": {"kind": "3cc"}, "F": 0.01}', "model = {'kind': '3cc'}: expected one of"),
        ('{"model": "hill", "F": 1}', "model = 'hill'"),
        ('{"model": "3cc", "F": 0.01, "LD": 10, "LR": 10}', "has no 'R'"),
        ('{"model": "3cc", "F": "fast", "R": 0.001, "LD": 10, "LR": 10}', "F = 'fast': expected a finite number"),
        ('{"model": "3cc", "F": -0.01, "R": 0.001, "LD": 10, "LR": 10}', "F = -0.01"),
    ],
)
def test_bad_json_files(tmp_path, content, message):
    path = tmp_path / "p.json"
    path.write_text(content)
    with pytest.raises(PresetFileError, match=re.escape(message)):
        preset(str(path))


def test_missing_json_file(tmp_path):
    with pytest.raises(PresetFileError, match="does not exist"):
        preset(str(tmp_path / "nope.json"))


def test_the_physiological_curl_study_uses_frey_law_rates_per_joint():
    """studies/curl_physiological.toml: the elbow halves carry Frey-Law 2012's elbow rates, the
    shoulder halves the shoulder's, all with S = 10; the dumbbell weighs 10 kg; cycles last 2 s;
    and a short full horizon of it (10 intervals per cycle) converges."""
    from pathlib import Path

    from fatigue_pin.drivers.full import solve_full
    from fatigue_pin.fatigue.presets import FREY_LAW_2012_JOINTS
    from fatigue_pin.io.study import Study

    study = Study.from_file(Path(__file__).resolve().parents[2] / "studies" / "curl_physiological.toml")
    problem = study.problem()
    for half in problem.actuators._halves:
        assert (half.params.F, half.params.R) == FREY_LAW_2012_JOINTS[half.joint] and half.params.S == 10.0
    light = Study.from_dict({**study.data, "model": {"urdf": "arm26"}}).problem().model
    assert problem.model.body_masses()["elbow"] - light.body_masses()["elbow"] == pytest.approx(6.4)
    assert problem.task.cycle_duration == 2.0
    small = study.replace({"task.intervals_per_cycle": 10})
    ocp, sol = solve_full(small.problem(), 2, small.transcription(), small.solver())
    assert sol.success
    assert np.nanmax(sol.fatigue("mf")) > 0  # the load tires the arm
