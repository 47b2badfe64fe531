"""Named fatigue parameter sets, each with its source, and calibrated parameter files.

``preset(name, **overrides)`` returns a :class:`~fatigue_pin.fatigue.interface.FatigueModel`;
``PRESETS`` maps every name to a :class:`Preset` ``(model kind, values, source text)``. A name that
ends in ``.json`` (or any path to an existing file) is read with :func:`load_preset_json`, so a
study can write ``preset = "path/to/params.json"`` for the output of ``fatigue-pin calibrate``.

This is the one registry of named parameter sets, all from the literature; the paper module
(:mod:`fatigue_pin.paper.curl`) reads its OCPs' sets, ``puchaud-2023/*``, from here.

Sources of the numbers defined here (see ``docs/fatigue.md``):

* ``frey-law-2012/<joint>``: Frey-Law, Looft & Heitsman (2012), J Biomech 45:1803-1808,
  doi:10.1016/j.jbiomech.2012.04.018, Table 1: F and R (1/s) of Xia's 3CC per joint, fitted to the
  pooled intensity-endurance curves of Frey-Law & Avin (2010). The values agree with two
  independent transcriptions of Table 1, one of them MyoSuite's
  (``docs/source/fatigue_validation.rst``, MyoHub/myosuite at commit
  416c185ebc7ee3504500f70d1e8f2d2428c38a6d). The paper's fit uses the endurance time, which does
  not depend on LD and LR; we set LD = LR = 10 1/s as in the forward studies of Puchaud, Michaud &
  Begon (2023). No stabiliser (S = 0), no rest multiplier (r = 1).
* ``rakshit-2021/<region>``: Rakshit, Xiang & Yang (2021), J Biomech 127:110695,
  doi:10.1016/j.jbiomech.2021.110695, Table 2: F, R (1/s) and r of the 3CC-r model per joint
  (ankle, elbow, hand, knee) and per functional muscle group, for both sexes and per sex. **A single
  transcription**: MyoSuite's ``MUSCLE_FATIGUE_PARAMS`` (``myosuite/core/muscle_conditions.py``,
  MyoHub/myosuite at commit 02218868f82d6cfaba1bc8d7ad17a9bc143f7372), whose documentation
  (``docs/source/fatigue_validation.rst``) states that every value matches the published table;
  the paper itself was not opened here. Their ``r`` acts only at rest (Eq. 7: ``r`` when
  ``TL = 0``), so these presets set ``rest_load = 0`` (MyoSuite counts ``TL <= 0.01`` as rest). Rows
  for which the table gives no ``r`` (ankle plantarflexors, female first dorsal interosseous)
  have ``r = 1`` (MyoSuite falls back to its default r = 15 there). LD = LR = 10 1/s and S = 0 as
  for the Frey-Law presets (our choice).
* :data:`LOOFT_2018_R`: the rest multipliers recommended by Looft, Herkert & Frey-Law (2018),
  J Biomech 77:16-25, doi:10.1016/j.jbiomech.2018.06.005 (15 for the ankle, knee and elbow, 30 for
  grip), documented alternatives to Rakshit's r: ``preset("rakshit-2021/elbow", r=LOOFT_2018_R["elbow"])``.
* ``puchaud-2023/paper`` and ``puchaud-2023/authors-code``: Puchaud, Michaud & Begon (2023), the
  values of their optimal control problems (section 3): LD = LR = 10, F = 0.456, S = 10 (1/s);
  R = 0.00094 1/s as printed in the text, 0.0094 1/s in the authors' code that produced the
  published results (s2mLab/dumbbell_lifting; docs/authors-code.md).
* ``bioptim/michaud-pendulum``: the values of bioptim's pendulum example for Michaud's model
  (toy values for a demonstration, not physiological).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from types import MappingProxyType
from pathlib import Path
from typing import NamedTuple

from fatigue_pin.core.errors import ParameterError, PresetFileError
from fatigue_pin.fatigue.interface import FatigueModel
from fatigue_pin.fatigue.models import FATIGUE_MODELS, fatigue_model
from fatigue_pin.core.text import shown

__all__ = [
    "Preset",
    "PRESETS",
    "FREY_LAW_2012_JOINTS",
    "RAKSHIT_2021_TABLE_2",
    "LOOFT_2018_R",
    "preset",
    "load_preset_json",
    "preset_source",
    "PresetFileError",
]


class Preset(NamedTuple):
    """A named parameter set.

    Attributes:
        kind: the fatigue model kind (a key of ``FATIGUE_MODELS``).
        values: the model's parameters (and options) by name.
        source: where the values come from (citation, table, transcription).
    """

    kind: str
    values: Mapping[str, float]
    source: str


_FL2012 = (
    "Frey-Law, Looft & Heitsman (2012), J Biomech 45:1803-1808, doi:10.1016/j.jbiomech.2012.04.018, "
    "Table 1 ({joint}); LD = LR = 10 1/s as in Puchaud et al. (2023)'s forward studies (the endurance time "
    "the values were fitted to does not depend on LD, LR); S = 0, r = 1"
)

#: Frey-Law, Looft & Heitsman (2012) Table 1: joint -> (F, R) (1/s) of Xia's 3CC.
FREY_LAW_2012_JOINTS: dict[str, tuple[float, float]] = {
    "ankle": (0.00589, 0.00058),
    "knee": (0.01500, 0.00149),
    "trunk": (0.00755, 0.00075),
    "shoulder": (0.01820, 0.00168),
    "elbow": (0.00912, 0.00094),
    "hand": (0.00980, 0.00064),
    "general": (0.00970, 0.00091),
}

_RAKSHIT = (
    "Rakshit, Xiang & Yang (2021), J Biomech 127:110695, doi:10.1016/j.jbiomech.2021.110695, Table 2 ({row}), "
    "as transcribed in MyoSuite (MyoHub/myosuite, myosuite/core/muscle_conditions.py, MUSCLE_FATIGUE_PARAMS, "
    "commit 02218868f82d6cfaba1bc8d7ad17a9bc143f7372): a single transcription, not checked against the paper; "
    "r at rest only (rest_load = 0, their Eq. 7){no_r}; LD = LR = 10 1/s, S = 0 (our choice)"
)

#: Rakshit, Xiang & Yang (2021) Table 2, as transcribed in MyoSuite: region -> (F, R, r), F and R
#: in 1/s, r dimensionless or None where the table gives none. ``-female`` / ``-male``: the
#: sex-specific rows; ``hand-grip``: MyoSuite's ``Wrist-Flexor`` rows ("Hand G/Grip group").
RAKSHIT_2021_TABLE_2: dict[str, tuple[float, float, float | None]] = {
    # joints
    "ankle": (0.01485, 0.00333, 9.31),
    "elbow": (0.01086, 0.00225, 4.93),
    "hand": (0.01227, 0.00134, 9.10),
    "knee": (0.00825, 0.00076, 14.85),
    # functional muscle groups: both sexes, female, male
    "ankle-dorsiflexor": (0.00828, 0.00204, 7.07),
    "ankle-dorsiflexor-female": (0.00746, 0.00081, 4.97),
    "ankle-dorsiflexor-male": (0.00725, 0.00096, 10.36),
    "ankle-plantarflexor": (0.00695, 0.00096, None),
    "ankle-plantarflexor-female": (0.00702, 0.00098, None),
    "ankle-plantarflexor-male": (0.00683, 0.00093, None),
    "elbow-extensor": (0.01559, 0.00125, 25.52),
    "elbow-extensor-female": (0.01874, 0.00206, 21.22),
    "elbow-extensor-male": (0.01269, 0.00085, 30.21),
    "elbow-flexor": (0.01703, 0.00494, 4.68),
    "elbow-flexor-female": (0.00965, 0.00197, 6.22),
    "elbow-flexor-male": (0.01302, 0.00188, 8.99),
    "hand-adductor-pollicis": (0.00558, 0.00283, 1.00),
    "hand-adductor-pollicis-female": (0.00476, 0.00093, 6.62),
    "hand-adductor-pollicis-male": (0.00586, 0.00202, 1.00),
    "hand-first-dorsal-interossei": (0.02686, 0.00656, 3.41),
    "hand-first-dorsal-interossei-female": (0.03999, 0.03983, None),
    "hand-first-dorsal-interossei-male": (0.01637, 0.00360, 3.66),
    "hand-grip": (0.01235, 0.00135, 12.51),
    "hand-grip-female": (0.01159, 0.00217, 7.39),
    "hand-grip-male": (0.01238, 0.00178, 8.00),
    "knee-extensor": (0.00825, 0.00076, 14.85),
    "knee-extensor-female": (0.01407, 0.00185, 6.32),
    "knee-extensor-male": (0.01420, 0.00153, 10.96),
}

#: Looft, Herkert & Frey-Law (2018): recommended rest multipliers r per joint (dimensionless).
LOOFT_2018_R: dict[str, float] = {"ankle": 15.0, "knee": 15.0, "elbow": 15.0, "grip": 30.0}

def _build() -> dict[str, Preset]:
    out: dict[str, Preset] = {}
    for joint, (F, R) in FREY_LAW_2012_JOINTS.items():
        label = "hand/grip" if joint == "hand" else joint
        out[f"frey-law-2012/{joint}"] = Preset(
            "xia", {"LD": 10.0, "LR": 10.0, "F": F, "R": R, "S": 0.0, "r": 1.0}, _FL2012.format(joint=label)
        )
    out["frey-law-2012/grip"] = out["frey-law-2012/hand"]
    for region, (F, R, r) in RAKSHIT_2021_TABLE_2.items():
        no_r = "" if r is not None else "; the table gives no r for this row: r = 1 here"
        out[f"rakshit-2021/{region}"] = Preset(
            "xia",
            {"LD": 10.0, "LR": 10.0, "F": F, "R": R, "S": 0.0, "r": 1.0 if r is None else r, "rest_load": 0.0},
            _RAKSHIT.format(row=region, no_r=no_r),
        )
    for variant, R, where in (("paper", 0.00094, "printed in the paper text (section 3)"),
                              ("authors-code", 0.0094, "of the authors' code that produced the published results "
                                                       "(s2mLab/dumbbell_lifting; docs/authors-code.md)")):
        out[f"puchaud-2023/{variant}"] = Preset(
            "xia", {"LD": 10.0, "LR": 10.0, "F": 0.456, "R": R, "S": 10.0, "r": 1.0},
            f"Puchaud, Michaud & Begon (2023), OCPs, values {where}: R = {R:g}")
    out["bioptim/michaud-pendulum"] = Preset(
        "michaud",
        {"LD": 100.0, "LR": 100.0, "F": 0.005, "R": 0.005, "effort_threshold": 0.2, "effort_factor": 0.001,
         "stabilization_factor": 10.0},
        "pyomeca/bioptim, bioptim/examples/toy_examples/fatigue/pendulum_with_fatigue.py (fatigue_type 'michaud'), "
        "commit e8fbc72971387be3c193364f712fbc55a225f32f: demonstration values, not physiological",
    )
    return out


#: name -> :class:`Preset` (model kind, parameter values, source text). Read-only.
PRESETS = MappingProxyType(_build())


def _is_file_name(name: str) -> bool:
    return name.endswith(".json") or "/" in name and Path(name).is_file()


def preset(name: str, **overrides: float) -> FatigueModel:
    """The fatigue model of preset ``name`` with some parameters overridden.

    Args:
        name: a key of :data:`PRESETS` (e.g. ``"frey-law-2012/elbow"``) or the path of a JSON
            parameter file (see :func:`load_preset_json`).
        **overrides: parameter values that replace the preset's (e.g. ``S=10``).

    Raises:
        ParameterError: unknown name, unknown parameter in ``overrides`` or a bad value.
    """
    if not isinstance(name, str):
        raise ParameterError(f"preset name {name!r}: expected a string, one of {sorted(PRESETS)} or a .json path")
    if name in PRESETS:
        kind, values, _ = PRESETS[name]
        return fatigue_model(kind, **(values | overrides))
    if _is_file_name(name):
        model = load_preset_json(name)
        return model.with_(**overrides) if overrides else model
    raise ParameterError(f"fatigue preset {name!r} is unknown; expected one of {sorted(PRESETS)} or a path to a .json file")


def preset_source(name: str) -> str:
    """The source text of preset ``name`` (for a JSON file: its ``source`` entry or its path)."""
    if name in PRESETS:
        return PRESETS[name][2]
    if _is_file_name(name):
        data = _read_json(Path(name))
        return str(data.get("source", f"calibrated parameter file {name}"))
    raise ParameterError(f"fatigue preset {name!r} is unknown; expected one of {sorted(PRESETS)} or a path to a .json file")


def _read_json(path: Path) -> dict:
    if not path.is_file():
        raise PresetFileError(f"parameter file {str(path)!r} does not exist (or is not a file): expected a JSON file")
    try:
        data = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise PresetFileError(f"parameter file {str(path)!r} is not readable JSON ({exc}): expected a JSON object") from None
    if not isinstance(data, dict):
        raise PresetFileError(f"parameter file {str(path)!r} holds a {type(data).__name__}: expected a JSON object")
    return data


#: ``model`` entries of calibration files -> fatigue model kind.
_MODEL_ALIASES = {"3cc": "xia", "3cc-r": "xia", "3cc-s": "xia", "xia": "xia", "michaud": "michaud"}


def load_preset_json(path: str | Path) -> FatigueModel:
    """A fatigue model from a JSON parameter file, e.g. the output of ``fatigue-pin calibrate``.

    The file is a JSON object with ``model`` (``"3cc"``, ``"3cc-r"``, ``"xia"`` or ``"michaud"``) and
    the model's parameters as numbers at the top level (``F``, ``R``, ``LD``, ``LR``, and ``S``, ``r``
    for Xia's model; missing ``S`` is 0 and missing ``r`` is 1), and the model's options when
    given (Xia's ``rest_load``, default 1). Other entries (confidence
    intervals, residuals, source) are ignored here.

    Raises:
        PresetFileError: missing or unreadable file, unknown model, a missing or non-numeric parameter.
    """
    p = Path(path)
    data = _read_json(p)
    model = data.get("model")
    if not isinstance(model, str) or model not in _MODEL_ALIASES:
        raise PresetFileError(f"parameter file {str(p)!r}: model = {model!r}: expected one of {sorted(_MODEL_ALIASES)}")
    kind = _MODEL_ALIASES[model]
    cls = FATIGUE_MODELS[kind]
    defaults = {"S": 0.0, "r": 1.0} if kind == "xia" else {}
    values: dict[str, float] = {}
    for name in cls.param_names:
        if name not in data:
            if name in defaults:
                values[name] = defaults[name]
                continue
            raise PresetFileError(f"parameter file {str(p)!r} has no {name!r}: expected the {model!r} parameters {list(cls.param_names)}")
        v = data[name]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(float(v)):
            raise PresetFileError(f"parameter file {str(p)!r}: {name} = {shown(v)}: expected a finite number")
        values[name] = float(v)
    for name in cls.option_names:
        if name in data:
            v = data[name]
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(float(v)):
                raise PresetFileError(f"parameter file {str(p)!r}: {name} = {shown(v)}: expected a finite number")
            values[name] = float(v)
    try:
        return fatigue_model(kind, **values)
    except ParameterError as exc:
        raise PresetFileError(f"parameter file {str(p)!r}: {exc}") from None
