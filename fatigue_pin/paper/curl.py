"""The reference study's numbers: Puchaud, Michaud & Begon (2023); docs/reproduction.md and docs/authors-code.md.

Every value that belongs to the paper (the curl task, its fatigue rates, weights, the values on
which its text and its authors' code differ, and its published tables) lives here and in the
study files under ``studies/``, never as a default of a general class.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.fatigue.models import XiaFatigue
from fatigue_pin.fatigue.presets import PRESETS, preset

#: The paper's three costs and the cost terms each one uses (weights of the others are 0).
COSTS: dict[str, tuple[str, ...]] = {
    "fatigue-torque": ("posture", "torque_rate", "fatigue", "torque"),
    "fatigue": ("posture", "torque_rate", "fatigue"),
    "torque": ("posture", "torque_rate", "torque"),
}

#: Weights of the cost terms before a cost zeroes the ones it does not use (posture: preset's).
WEIGHTS: dict[str, float] = {"torque_rate": 0.1, "fatigue": 1e3, "torque": 1.0}

#: The curl: elbow between 15 and 150 deg, one round trip per 1 s cycle, 50 intervals.
TASK_JOINT = "elbow"
LOW = math.radians(15.0)
HIGH = math.radians(150.0)
Q_INIT = (0.07, math.radians(15.0))
PENALISED_JOINTS = ("shoulder",)
CYCLE_DURATION = 1.0
INTERVALS_PER_CYCLE = 50
SUBSTEPS = 5
#: The sliding horizon's window K (cycles).
WINDOW = 3


@dataclass(frozen=True)
class Variant:
    """Values on which the paper text and the authors' code differ (docs/authors-code.md).

    Attributes:
        name: ``paper`` (the text) or ``authors-code`` (the code that produced the published results).
        R: recovery rate of every actuator half (1/s).
        posture_weight: weight of the shoulder penalty.
        last_node_offset: where the last ``low`` angle is imposed relative to the final node
            (0: node 50 n; -1: node 50 n - 1 as in the authors' code).
    """

    name: str
    R: float
    posture_weight: float
    last_node_offset: int


#: The paper's two variants (the study files' ``preset`` label): the text and the authors' code.
VARIANTS: dict[str, Variant] = {
    "paper": Variant("paper", R=PRESETS["puchaud-2023/paper"].values["R"], posture_weight=1e5, last_node_offset=0),
    "authors-code": Variant("authors-code", R=PRESETS["puchaud-2023/authors-code"].values["R"], posture_weight=1e4,
                            last_node_offset=-1),
}


def paper_variant(name: str) -> Variant:
    """The variant ``name`` (``paper`` or ``authors-code``)."""
    if name not in VARIANTS:
        raise ParameterError(f"preset = {name!r}: expected one of {list(VARIANTS)}")
    return VARIANTS[name]


def elbow_params(S: float = 0.0) -> XiaFatigue:
    """Elbow values of Looft et al. (2018) used in the forward studies (paper section 2).

    LD = LR = 10, F = 0.00912, R = 0.00094 (1/s), stabiliser ``S`` (1/s), no rest multiplier.
    """
    return XiaFatigue(LD=10.0, LR=10.0, F=0.00912, R=0.00094, S=S)


def ocp_params(variant: str = "authors-code", S: float = 10.0) -> XiaFatigue:
    """Fatigue values of the optimal control problems (paper section 3).

    LD = LR = 10, F = 0.456, S = 10 (1/s). ``R`` depends on the source: ``"paper"`` (the text)
    gives 0.00094, ``"authors-code"`` (the code that produced the published results) 0.0094.
    """
    paper_variant(variant)  # a known variant
    return preset(f"puchaud-2023/{variant}", S=S)


#: The paper's repetitions (with S = 10, without stabiliser S = 0).
PAPER_REPETITIONS = {
    ("full", 10.0): {"fatigue-torque": 32, "fatigue": 32, "torque": 32},
    ("full", 0.0): {"fatigue-torque": 20, "fatigue": 18, "torque": 14},
    ("sliding", 10.0): {"fatigue-torque": 21, "fatigue": 20, "torque": 20},
    ("sliding", 0.0): {"fatigue-torque": 21, "fatigue": 20, "torque": 9},
}
#: The paper's solve times (minutes) with S = 0.
PAPER_MINUTES_S0 = {("full", c): v for c, v in zip(COSTS, (41.8, 11.7, 1.70))} | {
    ("sliding", c): v for c, v in zip(COSTS, (10.0, 9.9, 0.39))
}


def curl_study_dict(
    horizon: str = "sliding",
    cost: str = "fatigue-torque",
    preset_name: str = "paper",
    S: float = 10.0,
    cycles: int | None = None,
    max_cycles: int | None = None,
    guess: str = "rest",
    solver: dict | None = None,
    transcription: dict | None = None,
    intervals_per_cycle: int = INTERVALS_PER_CYCLE,
    substeps: int = SUBSTEPS,
) -> dict:
    """The paper's curl as a study table (the form of ``studies/*.toml``).

    Args:
        horizon: ``full``, ``sliding`` or ``max-cycles``.
        cost: ``fatigue-torque``, ``fatigue`` or ``torque`` (:data:`COSTS`).
        preset_name: ``paper`` or ``authors-code`` (:data:`VARIANTS`).
        S: stabiliser of every half (1/s).
        cycles: the full horizon (default: the horizon's, 1), or the window (default :data:`WINDOW`).
        max_cycles: sliding: stop after; max-cycles: search bound.
        guess: the ``horizon.guess`` setting.
        solver: optional ``[solver]`` settings.
        transcription: optional ``[transcription]`` settings.
        intervals_per_cycle: intervals per cycle (the paper's 50; tests use less).
        substeps: RK4 substeps per interval (the paper's 5).
    """
    if cost not in COSTS:
        raise ParameterError(f"cost = {cost!r}: expected one of {list(COSTS)}")
    p = paper_variant(preset_name)
    weights = {"posture": p.posture_weight, **WEIGHTS}
    costs = {
        "posture": {"weight": weights["posture"] if "posture" in COSTS[cost] else 0.0, "joints": list(PENALISED_JOINTS)},
        **{term: (weights[term] if term in COSTS[cost] else 0.0) for term in ("torque_rate", "fatigue", "torque")},
    }
    horizon_table: dict = {"kind": horizon, "guess": guess}
    if horizon == "sliding":
        horizon_table.update(cycles=cycles or WINDOW, advance=1, end_tolerance=0.01)
    elif horizon == "full" and cycles is not None:
        horizon_table.update(cycles=cycles)
    if max_cycles is not None:
        horizon_table["max_cycles"] = max_cycles
    params = ocp_params(preset_name, S)
    return {
        "name": f"{cost}_S{{fatigue.S}}",
        "model": {"urdf": "arm26"},
        "fatigue": {"model": "xia", **params.as_dict()},
        "task": {
            "cycle_duration": CYCLE_DURATION,
            "intervals_per_cycle": intervals_per_cycle,
            "q_init": list(Q_INIT),
            "final_node_offset": p.last_node_offset,
            "targets": [
                {"joint": TASK_JOINT, "value": LOW, "at": 0.0},
                {"joint": TASK_JOINT, "value": HIGH, "at": 0.5},
            ],
        },
        "costs": costs,
        "transcription": {"substeps": substeps, **(transcription or {})},
        "horizon": horizon_table,
        # MUMPS, with which the reproduced counts were measured: the stage-wise solver (the default
        # "auto" picks it on arm26) gives the same iterates, but near exhaustion a window at the
        # edge of IPOPT's iteration limit can go either way (docs/ocp.md, "The KKT solve by stages")
        "solver": {"linear_solver": "mumps", **(solver or {})},
        "labels": {"cost": cost, "preset": preset_name},
    }


def curl_study(*args, **kwargs):
    """The paper's curl as a :class:`~fatigue_pin.io.study.Study` (arguments of :func:`curl_study_dict`)."""
    from fatigue_pin.io.study import Study

    return Study.from_dict(curl_study_dict(*args, **kwargs))


#: The authors' full-horizon settings that a study can state (docs/authors-code.md, D1, D3, D4,
#: D9, D10, D11, D12): end box, task targets as constraint rows, no joint-torque variable, rest
#: guess per N, IPOPT's own mu_init and perturb_dec_fact, no scaling, Solved_To_Acceptable_Level
#: accepted.
AUTHORS_VARIANT = {
    "horizon": {"cyclic_end": True, "end_tolerance": 0.01, "guess": "rest"},
    "solver": {"mu_init": 0.1, "perturb_dec_fact": 1.0 / 3.0, "accept_acceptable": True},
    "transcription": {"scaling": False, "target_rows": True, "torque_variable": False},
}


def authors_variant_dict(cost: str = "fatigue-torque", S: float = 10.0, cycles: int = 33, **kwargs) -> dict:
    """The full-horizon curl as the authors' code states it, as far as a study can
    (``studies/curl_full_authors-variant.toml``): the ``authors-code`` values with
    :data:`AUTHORS_VARIANT`. ``kwargs`` go to :func:`curl_study_dict`."""
    data = curl_study_dict("full", cost, "authors-code", S, cycles=cycles, **kwargs)
    for table, values in AUTHORS_VARIANT.items():
        data[table] = {**data.get(table, {}), **values}
    data["name"] = "authors-variant_{labels.cost}_S{fatigue.S}"
    data["labels"]["preset"] = "authors-variant"
    return data
