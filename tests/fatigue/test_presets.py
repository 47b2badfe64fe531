"""Tests of the named fatigue presets and calibrated parameter files (fatigue_pin.fatigue.presets)."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.fatigue.michaud import MichaudFatigue
from fatigue_pin.fatigue.models import XiaFatigue
from fatigue_pin.fatigue.presets import (
    FREY_LAW_2012_JOINTS,
    LOOFT_2018_R,
    PRESETS,
    PresetFileError,
    load_preset_json,
    preset,
    preset_source,
)

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


def test_the_paper_reads_its_presets_from_the_one_registry():
    from fatigue_pin.paper import curl

    assert preset("puchaud-2023/authors-code") == curl.ocp_params("authors-code", S=10.0)
    assert curl.ocp_params("paper", S=0.0).S == 0.0 and curl.paper_variant("paper").R == PRESETS["puchaud-2023/paper"].values["R"]
    # the published OCP values (paper section 3; R of the text and of the authors' code)
    assert preset("puchaud-2023/paper").R == 0.00094 and preset("puchaud-2023/authors-code").R == 0.0094
    assert preset("puchaud-2023/paper").F == 0.456 and preset("puchaud-2023/paper").S == 10.0
    # the fatigue layer never loads the paper module
    code = ("import sys; from fatigue_pin.fatigue import presets; presets.preset('puchaud-2023/paper'); "
            "assert not any(m.startswith('fatigue_pin.paper') for m in sys.modules)")
    subprocess.run([sys.executable, "-c", code], check=True)


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


# Rakshit, Xiang & Yang (2021) Table 2 as transcribed in MyoSuite (myosuite/core/muscle_conditions.py):
# MyoSuite row -> (F, R, r), F and R in 1/s; None: no r in the table.
TABLE_2 = {
    "Ankle": (0.01485, 0.00333, 9.31), "Elbow": (0.01086, 0.00225, 4.93),
    "Hand": (0.01227, 0.00134, 9.10), "Knee": (0.00825, 0.00076, 14.85),
    "Ankle-Dorsiflexor": (0.00828, 0.00204, 7.07), "Ankle-Dorsiflexor-F": (0.00746, 0.00081, 4.97),
    "Ankle-Dorsiflexor-M": (0.00725, 0.00096, 10.36), "Ankle-Plantarflexor": (0.00695, 0.00096, None),
    "Ankle-Plantarflexor-F": (0.00702, 0.00098, None), "Ankle-Plantarflexor-M": (0.00683, 0.00093, None),
    "Elbow-Extensor": (0.01559, 0.00125, 25.52), "Elbow-Extensor-F": (0.01874, 0.00206, 21.22),
    "Elbow-Extensor-M": (0.01269, 0.00085, 30.21), "Elbow-Flexor": (0.01703, 0.00494, 4.68),
    "Elbow-Flexor-F": (0.00965, 0.00197, 6.22), "Elbow-Flexor-M": (0.01302, 0.00188, 8.99),
    "Hand-Adductor-Pollicis": (0.00558, 0.00283, 1.00), "Hand-Adductor-Pollicis-F": (0.00476, 0.00093, 6.62),
    "Hand-Adductor-Pollicis-M": (0.00586, 0.00202, 1.00), "Hand-First-Dorsal-Interossei": (0.02686, 0.00656, 3.41),
    "Hand-First-Dorsal-Interossei-F": (0.03999, 0.03983, None), "Hand-First-Dorsal-Interossei-M": (0.01637, 0.00360, 3.66),
    "Wrist-Flexor": (0.01235, 0.00135, 12.51), "Wrist-Flexor-F": (0.01159, 0.00217, 7.39),
    "Wrist-Flexor-M": (0.01238, 0.00178, 8.00), "Knee-Extensor": (0.00825, 0.00076, 14.85),
    "Knee-Extensor-F": (0.01407, 0.00185, 6.32), "Knee-Extensor-M": (0.01420, 0.00153, 10.96),
}


def _rakshit_name(row: str) -> str:
    name = row.lower().replace("wrist-flexor", "hand-grip")
    return "rakshit-2021/" + re.sub(r"-f$", "-female", re.sub(r"-m$", "-male", name))


@pytest.mark.parametrize("row", sorted(TABLE_2))
def test_rakshit_2021_values_are_table_2(row):
    F, R, r = TABLE_2[row]
    name = _rakshit_name(row)
    m = preset(name)
    assert isinstance(m, XiaFatigue) and (m.F, m.R) == (F, R)
    assert m.r == (1.0 if r is None else r)
    assert (m.rest_load, m.S, m.LD, m.LR) == (0.0, 0.0, 10.0, 10.0)  # r at rest only (Eq. 7)
    source = preset_source(name)
    assert "doi:10.1016/j.jbiomech.2021.110695" in source and "single transcription" in source
    assert ("gives no r" in source) == (r is None)


def test_every_rakshit_preset_is_a_row_of_the_table():
    names = {n for n in PRESETS if n.startswith("rakshit-2021/")}
    assert names == {_rakshit_name(row) for row in TABLE_2}


def test_looft_2018_r():
    assert LOOFT_2018_R == {"ankle": 15.0, "knee": 15.0, "elbow": 15.0, "grip": 30.0}
    assert preset("rakshit-2021/elbow", r=LOOFT_2018_R["elbow"]).r == 15.0


def _rakshit_rhs(F, R, r, LD, LR):
    """Rakshit et al. (2021) Eqs. 1-7 in numpy, written from the paper's form: Xia's controller,
    recovery r R while TL = 0 and R otherwise."""
    def f(t, m, TL):
        ma, mr, mf = m
        if ma < TL:
            C = LD * (TL - ma) if mr >= TL - ma else LD * mr
        else:
            C = LR * (TL - ma)
        Rr = r * R if TL == 0.0 else R
        return [C - F * ma, -C + Rr * mf, F * ma - Rr * mf]
    return f


def test_rakshit_r_acts_only_at_rest():
    """Loads 0.5, 0.2 (relaxing from 0.5: ma > TL for ~10 s with LR = 0.1), 0 (rest), 0.4: the
    package's model with rest_load = 0 against an independent scipy integration of the 3CC-r
    equations; the model with r on the whole relaxation branch (rest_load = 1) differs."""
    from scipy.integrate import solve_ivp

    from fatigue_pin.fatigue.simulation import simulate

    model = preset("rakshit-2021/elbow", LR=0.1)
    everywhere = model.with_(rest_load=1.0)
    ref_rhs = _rakshit_rhs(model.F, model.R, model.r, model.LD, model.LR)
    phases = [(0.5, 60.0), (0.2, 40.0), (0.0, 60.0), (0.4, 30.0)]
    m_ref = m_pkg = m_all = np.array([0.0, 1.0, 0.0])
    for TL, duration in phases:
        out = solve_ivp(ref_rhs, (0.0, duration), m_ref, args=(TL,), method="LSODA", rtol=1e-10, atol=1e-12)
        assert out.success
        m_ref = out.y[:, -1]
        tol = dict(method="LSODA", rtol=1e-10, atol=1e-12)
        m_pkg = simulate(model, TL, m_pkg, duration, **tol).m[:, -1]
        m_all = simulate(everywhere, TL, m_all, duration, **tol).m[:, -1]
        np.testing.assert_allclose(m_pkg, m_ref, atol=1e-7)
        if TL == 0.2:  # after the relaxation at a load: r must not have acted
            assert abs(m_all[2] - m_ref[2]) > 1e-3
    # at rest the fatigued fraction decays like exp(-r R t) once ma has relaxed to 0
    mf = simulate(model, 0.0, [0.0, 0.7, 0.3], 50.0, t_eval=[20.0, 50.0], method="LSODA", rtol=1e-10, atol=1e-12).mf
    assert mf[1] / mf[0] == pytest.approx(np.exp(-model.r * model.R * 30.0), rel=1e-6)
