"""Named fatigue parameter sets, each with its source, and calibrated parameter files.

``preset(name, **overrides)`` returns a :class:`~fatigue_pin.fatigue.models.FatigueModel`;
``PRESETS`` maps every name to ``(model kind, values, source text)``. A name that ends in
``.json`` (or any path to an existing file) is read with :func:`load_preset_json`, so a study can
write ``preset = "path/to/params.json"`` for the output of ``fatigue-pin calibrate``.

Sources of the shipped numbers (see ``docs/fatigue.md``):

* ``frey-law-2012/<joint>``: Frey-Law, Looft & Heitsman (2012), J Biomech 45:1803-1808,
  doi:10.1016/j.jbiomech.2012.04.018, Table 1: F and R (1/s) of Xia's 3CC per joint, fitted to the
  pooled intensity-endurance curves of Frey-Law & Avin (2010). The paper's fit uses the endurance
  time, which does not depend on LD and LR; we set LD = LR = 10 1/s as in the forward studies of
  Puchaud, Michaud & Begon (2023). No stabiliser (S = 0), no rest multiplier (r = 1).
* ``puchaud-2023/authors-code`` and ``puchaud-2023/paper``: the OCP values of Puchaud, Michaud &
  Begon (2023) (``fatigue_pin.paper.curl.ocp_params``).
* ``bioptim/michaud-pendulum``: the values of bioptim's pendulum example for Michaud's model
  (toy values for a demonstration, not physiological).

Not shipped: Rakshit et al. (2021) per-joint and per-muscle-group 3CC-r values. The only machine-
readable transcription found (a MyoSuite fork's ``MUSCLE_FATIGUE_PARAMS``) is not in the
official MyoSuite repository and could not be checked against the paper; see docs/fatigue.md.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from types import MappingProxyType

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.fatigue.models import FATIGUE_MODELS, FatigueModel, fatigue_model

__all__ = ["PRESETS", "FREY_LAW_2012_JOINTS", "preset", "load_preset_json", "preset_source", "PresetFileError"]


class PresetFileError(ParameterError):
    """A parameter file (JSON) that cannot be used as a preset."""


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


def _build() -> dict[str, tuple[str, dict[str, float], str]]:
    out: dict[str, tuple[str, dict[str, float], str]] = {}
    for joint, (F, R) in FREY_LAW_2012_JOINTS.items():
        label = "hand/grip" if joint == "hand" else joint
        out[f"frey-law-2012/{joint}"] = (
            "xia", {"LD": 10.0, "LR": 10.0, "F": F, "R": R, "S": 0.0, "r": 1.0}, _FL2012.format(joint=label)
        )
    out["frey-law-2012/grip"] = out["frey-law-2012/hand"]
    out["puchaud-2023/authors-code"] = (
        "xia",
        {"LD": 10.0, "LR": 10.0, "F": 0.456, "R": 0.0094, "S": 10.0, "r": 1.0},
        "Puchaud, Michaud & Begon (2023), OCPs, values of the authors' code that produced the published "
        "results (s2mLab/dumbbell_lifting; docs/authors-code.md): R = 0.0094",
    )
    out["puchaud-2023/paper"] = (
        "xia",
        {"LD": 10.0, "LR": 10.0, "F": 0.456, "R": 0.00094, "S": 10.0, "r": 1.0},
        "Puchaud, Michaud & Begon (2023), OCPs, values printed in the paper text (section 3): R = 0.00094",
    )
    out["bioptim/michaud-pendulum"] = (
        "michaud",
        {"LD": 100.0, "LR": 100.0, "F": 0.005, "R": 0.005, "effort_threshold": 0.2, "effort_factor": 0.001,
         "stabilization_factor": 10.0},
        "pyomeca/bioptim, bioptim/examples/toy_examples/fatigue/pendulum_with_fatigue.py (fatigue_type 'michaud'), "
        "commit e8fbc72971387be3c193364f712fbc55a225f32f: demonstration values, not physiological",
    )
    return out


#: name -> (model kind, parameter values, source text). Read-only.
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
    for Xia's model; missing ``S`` is 0 and missing ``r`` is 1). Other entries (confidence
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
            raise PresetFileError(f"parameter file {str(p)!r}: {name} = {v!r}: expected a finite number")
        values[name] = float(v)
    try:
        return fatigue_model(kind, **values)
    except ParameterError as exc:
        raise PresetFileError(f"parameter file {str(p)!r}: {exc}") from None
