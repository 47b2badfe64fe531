"""Values in messages and TOML files are plain numbers and lists, never numpy reprs."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest

from fatigue_pin.core.errors import FatiguePinError
from fatigue_pin.core.text import plain, shown

#: Reprs of numpy values that no message or file may show.
NUMPY_REPRS = ("np.float64(", "np.float32(", "np.int64(", "np.bool", "array(")


def test_plain_and_shown():
    assert plain({"a": np.float64(0.5), "b": (np.int64(1), np.array([2.0, 3.0])), "c": np.bool_(True)}) == \
        {"a": 0.5, "b": [1, [2.0, 3.0]], "c": True}
    assert type(plain(np.float64(0.5))) is float and type(plain(np.int64(2))) is int
    assert shown(np.float64(0.5)) == "0.5" and shown(np.array([1, 2])) == "[1, 2]" and shown(np.array(2.0)) == "2.0"
    assert shown([np.float64(0.0), np.float64(1.0)]) == "[0.0, 1.0]" and shown("x") == "'x'"


def test_the_toml_writer_writes_numpy_values_as_numbers():
    """io.tables.to_toml is given numpy values (a table built in Python): its TOML parses."""
    import copy

    from fatigue_pin.io.study import Study, to_toml
    from fatigue_pin.paper.curl import curl_study

    study = curl_study("full", intervals_per_cycle=10, substeps=2, solver={"compile": False})
    data = copy.deepcopy(study.data)
    data["fatigue"]["F"] = np.float64(data["fatigue"]["F"])
    data["horizon"]["cycles"] = np.int64(data["horizon"]["cycles"])
    data["task"]["q_init"] = np.asarray(data["task"]["q_init"])
    text = to_toml(data)
    assert not any(r in text for r in NUMPY_REPRS), text
    assert Study.from_dict(tomllib.loads(text)) == study


def test_a_closed_loop_study_with_numpy_changes_writes_valid_toml():
    from pathlib import Path

    from fatigue_pin.io.mpc_study import MpcStudy

    path = Path(__file__).resolve().parents[2] / "studies" / "curl_mpc.toml"
    changed = MpcStudy.from_file(path, {"mpc.replan_every": np.int64(2), "plant.noise.q": np.float64(0.001),
                                        "fatigue.F": np.float64(0.5)})
    expected = MpcStudy.from_file(path, {"mpc.replan_every": 2, "plant.noise.q": 0.001, "fatigue.F": 0.5})
    text = changed.to_toml()
    assert not any(r in text for r in NUMPY_REPRS), text
    assert text == expected.to_toml()
    assert MpcStudy.from_toml(text).to_toml() == text


def _calls():
    """Python API calls given bad numpy values (each must raise, naming the value plainly)."""
    from fatigue_pin.fatigue.models import XiaFatigue
    from fatigue_pin.ocp.costs import cost_term
    from fatigue_pin.ocp.task import FramePlane, FrameTarget, JointTarget, Task
    from fatigue_pin.ocp.transcription import Transcription
    from fatigue_pin.robot.model import Payload

    return {
        "settings field": (lambda: Transcription(substeps=np.int64(0)), "= 0:"),
        "task duration": (lambda: Task(cycle_duration=np.float64(-1.0), intervals_per_cycle=10, items=()), "= -1.0:"),
        "joint target": (lambda: JointTarget("elbow", np.float64(np.nan), at=0.0), "= nan:"),
        "plane normal": (lambda: FramePlane("hand", np.zeros(3), 0.0), "[0.0, 0.0, 0.0]"),
        "frame target tolerance": (lambda: FrameTarget("hand", (0.0, 0.0, 0.0), at=0.0, tolerance=np.float64(-1.0)), "= -1.0:"),
        "fatigue parameter": (lambda: XiaFatigue(F=np.float64(-0.5), R=0.02, LD=10.0, LR=10.0), "= -0.5:"),
        "cost weight": (lambda: cost_term("torque", np.float64(-2.0)), "= -2.0:"),
        "payload com": (lambda: Payload("hand", mass=1.0, com=np.array([0.0, np.nan, 0.0])), "[0.0, nan, 0.0]"),
    }


@pytest.mark.parametrize("name", list(_calls()))
def test_messages_show_numpy_values_plainly(name):
    call, plain_text = _calls()[name]
    with pytest.raises(FatiguePinError) as err:
        call()
    message = str(err.value)
    assert not any(r in message for r in NUMPY_REPRS), message
    assert plain_text in message, message
