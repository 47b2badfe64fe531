"""The study tables taken from the settings classes read every shipped study as the hand-written
schema did: tests/io/normalised_studies.json holds, for every study of studies/, every job of its
sweep and every paper curl study of ``curl_study_dict``, the input and the normalised form and
TOML text computed by the code before the rework (commit 5bbba9f, io/study.py's SCHEMA)."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import pytest

from fatigue_pin.io.study import Study, normalise, to_toml
from fatigue_pin.io.tables import TASK_ARRAYS, key_tables

FIXTURE = json.loads((Path(__file__).with_name("normalised_studies.json")).read_text())
#: defaults changed on purpose since the fixture, (section, key) -> (old, new): a study that does
#: not set the key reads the new default; one stored with the old (every key written) keeps it
CHANGED_DEFAULTS = {("solver", "linear_solver"): ("mumps", "auto")}  # the stage-wise solver where it wins (docs/ocp.md)


def _as_before(new: dict, given: dict) -> dict:
    """``new`` (a normalised study) with each changed default that ``given`` (its input) did not
    set back at its old value."""
    out = json.loads(json.dumps(new))
    for (section, key), (old, now) in CHANGED_DEFAULTS.items():
        if out.get(section, {}).get(key) == now and key not in given.get(section, {}):
            out[section][key] = old
    return out


def _new_keys_at_default(new: dict, old: dict) -> dict:
    """``new`` without the keys (and tables) the old schema did not have, each checked to be at its
    class's default (a setting added since reads every old study as before)."""
    tables = key_tables()
    out = {}
    for section, values in new.items():
        if section in tables and section not in old:  # a table added since ([actuators]): every key at its default
            for key, value in values.items():
                assert value == tables[section][key].default, f"{section}.{key} = {value!r} in a study that did not set it"
            continue
        if not isinstance(values, dict) or section not in old or section not in tables:
            out[section] = values
            continue
        kept = {}
        for key, value in values.items():
            if key in old[section]:
                kept[key] = value
                if section == "task" and key in TASK_ARRAYS:  # the items' own new keys, at their defaults
                    kept[key] = [_item_at_default(f"task.{key}", item, before) for item, before in zip(value, old[section][key])]
            else:
                assert value == tables[section][key].default, f"{section}.{key} = {value!r} in a study that did not set it"
        out[section] = kept
    return out


def _item_at_default(where: str, item: dict, old: dict) -> dict:
    """An item table of a task array without the keys the old schema did not have, each at the
    default of its class's field (``velocity_tolerance`` of a joint target)."""
    tables = key_tables()
    kinds = [k for k in tables if k == where or k.startswith(where + " (")]
    defaults = {name: key.default for kind in kinds for name, key in tables[kind].items()}
    for key, value in item.items():
        if key not in old:
            assert value == defaults[key], f"{where}.{key} = {value!r} in a study that did not set it"
    return {k: v for k, v in item.items() if k in old}


def test_the_fixture_covers_every_shipped_study():
    closed_loop = ("plant", "mpc", "seed")  # closed-loop studies (io/mpc_study.py) are newer than the fixture
    # studies with keys the old schema lacked ([actuators], targets at "end", muscles, motors)
    newer = {"bioptim_pendulum_xia.toml", "bioptim_static_arm_xia.toml", "curl_muscles_exhaustion.toml", "curl_muscles_sliding.toml",
             "ur5_motors_lift.toml", "ur5_motors_paced.toml"}
    shipped = {p.name for p in (Path(__file__).resolve().parents[2] / "studies").glob("*.toml")
               if not set(tomllib.loads(p.read_text())) & set(closed_loop)} - newer
    assert shipped <= {name.split("#")[0] for name in FIXTURE}
    assert len(FIXTURE) == 47


@pytest.mark.parametrize("name", sorted(FIXTURE))
def test_every_study_normalises_to_the_same_values(name):
    case = FIXTURE[name]
    new = _as_before(normalise(case["input"]), case["input"])
    assert _new_keys_at_default(new, case["normalised"]) == case["normalised"]
    old_text = tomllib.loads(case["toml"])
    assert _new_keys_at_default(tomllib.loads(to_toml(new)), old_text) == old_text
    assert Study.from_toml(case["toml"]).data == new  # a study stored by the old code reads the same


def test_the_comparison_sees_a_changed_default():
    case = FIXTURE["curl_full_fatigue_paper.toml"]
    changed = json.loads(json.dumps(case["input"]))
    changed.setdefault("solver", {})["tol"] = 1e-7
    assert _new_keys_at_default(normalise(changed), case["normalised"]) != case["normalised"]
