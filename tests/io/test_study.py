"""Study files: the format of docs/studies.md, clear errors, round trips, rerun from a result."""

from __future__ import annotations

import math
import textwrap
import tomllib

import numpy as np
import pytest

from conftest import small_curl
from fatigue_pin.cli.main import main
from fatigue_pin.io.results import read_run
from fatigue_pin.io.study import Study, StudyError

#: The example of the issue that introduced study files, verbatim.
EXAMPLE = textwrap.dedent(
    """
    [model]
    urdf = "arm26"                      # a bundled model, an example-robot-data name, or a path
    [fatigue]                           # every actuator half, unless overridden per joint
    model = "xia"                       # 3CC; S > 0 gives 3CC-S, r != 1 gives 3CC-r
    LD = 10.0
    LR = 10.0
    F = 0.456
    R = 0.0094
    S = 10.0
    [fatigue.joints.elbow]              # optional per-joint overrides (both halves)
    F = 0.3
    [task]
    cycle_duration = 1.0
    intervals_per_cycle = 50
    q_init = [0.07, 0.2618]             # optional
    [[task.targets]]
    joint = "elbow"
    value = 0.2618                      # rad
    at = 0.0                            # phase of the cycle in [0, 1); repeated every cycle
    [[task.targets]]
    joint = "elbow"
    value = 2.618
    at = 0.5
    [costs]                             # name = weight, or a table with options
    posture = { weight = 1e4, joints = ["shoulder"] }
    torque_rate = 0.1
    fatigue = 1e3
    torque = 1.0
    [horizon]
    kind = "sliding"                    # "full", "sliding" or "max-cycles"
    cycles = 3                          # full: the horizon; sliding: the window
    advance = 1                         # sliding only
    max_cycles = 30                     # sliding: stop after; max-cycles: search bound
    [solver]
    linear_solver = "mumps"
    """
)


#: The example as the table tomllib reads.
EXAMPLE_DICT = tomllib.loads(EXAMPLE)


def test_the_documented_example_builds_its_problem(arm26):
    study = Study.from_toml(EXAMPLE)
    problem = study.problem(arm26)
    assert problem.cost_names == ("posture", "torque_rate", "fatigue", "torque")
    assert list(problem.weights) == [1e4, 0.1, 1e3, 1.0]
    params = {h.name: h.params for h in problem.actuators.halves}
    assert params["elbow_plus"].F == params["elbow_minus"].F == 0.3
    assert params["shoulder_plus"].F == 0.456 and params["shoulder_minus"].R == 0.0094
    assert params["elbow_plus"].S == 10.0
    task = problem.task
    assert task.intervals_per_cycle == 50 and [t.value for t in task.joint_targets] == [0.2618, 2.618]
    assert np.allclose(problem.initial_state()[:2], [0.07, 0.2618])
    assert study.horizon["kind"] == "sliding" and study.horizon["max_cycles"] == 30


def test_round_trip_through_toml_keeps_every_value():
    study = Study.from_toml(EXAMPLE)
    again = Study.from_toml(study.to_toml())
    assert again.data == study.data


@pytest.mark.parametrize("changes, plain", [
    ({"fatigue.F": np.float64(0.9)}, {"fatigue.F": 0.9}),
    ({"fatigue.R": np.float32(0.5)}, {"fatigue.R": 0.5}),
    ({"horizon.cycles": np.int64(2), "solver.compile": np.bool_(False)}, {"horizon.cycles": 2, "solver.compile": False}),
    ({"task.q_init": np.array([0.1, 0.25])}, {"task.q_init": [0.1, 0.25]}),
    ({"task.cycle_duration": np.array(2.0), "task.q_init": (np.float64(0.1), 0.25)}, {"task.cycle_duration": 2.0, "task.q_init": [0.1, 0.25]}),
])
def test_numpy_values_enter_a_study_as_plain_numbers(changes, plain):
    """A study changed with numpy scalars or arrays is the study changed with the same plain
    values: its TOML reads back to it, and its text (the job id of a sweep) is the same."""
    from fatigue_pin.sweep.plan import study_id

    study = Study.from_toml(EXAMPLE)
    changed = study.replace(changes)
    expected = study.replace(plain)
    assert Study.from_toml(changed.to_toml()) == changed
    assert changed == expected and changed.to_toml() == expected.to_toml()
    assert study_id(changed.to_toml()) == study_id(expected.to_toml())
    assert "np." not in changed.to_toml() and "array" not in changed.to_toml()
    assert Study.from_dict({**EXAMPLE_DICT, "task": {**EXAMPLE_DICT["task"], "q_init": np.array([0.1, 0.25])}}) == study.replace({"task.q_init": [0.1, 0.25]})


def test_per_half_overrides_and_name_placeholders(arm26):
    study = Study.from_toml(EXAMPLE.replace("F = 0.3", "F = 0.3\nminus = { F = 0.2 }"))
    params = {h.name: h.params for h in study.problem(arm26).actuators.halves}
    assert params["elbow_plus"].F == 0.3 and params["elbow_minus"].F == 0.2
    named = study.replace({"name": "curl_S{fatigue.S}_F{fatigue.F}"})
    assert named.name == "curl_S10_F0.456" and named.run_name() == "sliding/curl_S10_F0.456"


@pytest.mark.parametrize(
    "change, message",
    [
        (("[solver]", "[solver]\nspeed = 3"), "unknown key solver.speed"),
        (("[horizon]", "[horizon]\nwindow = 3"), "unknown key horizon.window"),
        (("cycle_duration = 1.0", 'cycle_duration = "1 s"'), "task.cycle_duration = '1 s': expected a duration"),
        (("intervals_per_cycle = 50", "intervals_per_cycle = 50.5"), "task.intervals_per_cycle = 50.5"),
        (("cycle_duration = 1.0\n", ""), "missing key task.cycle_duration"),
        (('kind = "sliding" ', 'kind = "circular" '), "horizon.kind = 'circular'"),
        (("torque = 1.0", "torque = -1.0"), "costs.torque.weight = -1.0"),
        (("torque = 1.0", "speed = 1.0"), "cost kind 'speed' is unknown"),
        (('model = "xia" ', 'model = "hill" '), "fatigue.model = 'hill'"),
        (("LD = 10.0", "LD = 10.0\nQ = 1.0"), "unknown key fatigue.Q"),
        (("F = 0.456", "F = nan"), "fatigue.F = nan"),
        (("[fatigue.joints.elbow]", "[fatigue.joints.wrist]"), "joint 'wrist' is not in model"),
        (('joint = "elbow"\nvalue = 2.618', 'joint = "knee"\nvalue = 2.618'), "task joint 'knee' is not in model"),
        (("value = 2.618", "value = 4.0"), "outside its range"),
        (("at = 0.5", "at = 1.5"), "at = 1.5: expected a phase"),
        (("advance = 1 ", "advance = 4 "), "horizon.advance = 4"),
        (("max_cycles = 30", "max_cycles = 2"), "horizon.max_cycles = 2"),
        (("R = 0.0094", "R = -0.0094"), "R = -0.0094: expected a finite rate"),
    ],
)
def test_bad_study_files_name_the_key(arm26, change, message):
    old, new = change
    assert old in EXAMPLE
    with pytest.raises(Exception) as info:
        Study.from_toml(EXAMPLE.replace(old, new, 1)).problem(arm26)
    assert message in str(info.value)
    assert "\n" not in str(info.value)


def test_not_toml_is_a_clear_error(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text("[model\nurdf = 1")
    with pytest.raises(StudyError, match="is not valid TOML"):
        Study.from_file(path)
    with pytest.raises(StudyError, match="not found"):
        Study.from_file(tmp_path / "missing.toml")


def test_run_stores_its_study_and_rerun_reproduces_it(tmp_path, capsys):
    """`fatigue-pin run` stores the study in the run; `fatigue-pin rerun` rebuilds it from the
    file alone and solves it again: same iterations, same objective."""
    study = small_curl("full", cycles=2)
    path = tmp_path / "curl.toml"
    path.write_text(study.to_toml())
    out = tmp_path / "first.h5"
    assert main(["run", str(path), "--out", str(out)]) == 0
    first = read_run(out)
    assert Study.from_toml(first.study).data == study.data
    again = tmp_path / "again.h5"
    assert main(["rerun", str(out), "--out", str(again)]) == 0
    second = read_run(again)
    assert second.attrs["iterations"] == first.attrs["iterations"]
    assert second.attrs["objective"] == pytest.approx(first.attrs["objective"], rel=1e-8)
    assert Study.from_file(again).data == study.data
    assert "converged" in capsys.readouterr().out


def test_set_changes_a_key_of_the_study(tmp_path):
    path = tmp_path / "curl.toml"
    path.write_text(small_curl("full").to_toml())
    out = tmp_path / "r.h5"
    assert main(["run", str(path), "--out", str(out), "--set", "fatigue.S=0", "--set", "costs.torque.weight=0"]) == 0
    run = read_run(out, "full/fatigue-torque_S0")
    stored = Study.from_toml(run.study)
    assert stored.data["fatigue"]["S"] == 0 and stored.data["costs"]["torque"]["weight"] == 0
    assert run.attrs["S"] == 0.0 and math.isfinite(run.attrs["objective"])


def test_model_locked_joints_key_reduces_the_model():
    """``[model] locked_joints = { name = value }`` reaches the model, survives the TOML round
    trip, and a bad joint name is one ModelError line."""
    from pathlib import Path

    from fatigue_pin.core.errors import ModelError

    path = Path(__file__).resolve().parents[2] / "benchmarks" / "studies" / "panda_scale.toml"
    study = Study.from_file(path)
    assert study.model().nv == 7
    assert Study.from_toml(study.to_toml()).data["model"]["locked_joints"] == study.data["model"]["locked_joints"]
    bad = study.replace({"model.locked_joints": {"panda_finger_joint2": 0.0, "panda_finger_joint9": 0.0}})
    with pytest.raises(ModelError, match="joint 'panda_finger_joint9' is not in panda.urdf"):
        bad.model()


def test_a_study_read_from_a_pipe(tmp_path):
    """``fatigue-pin run /dev/stdin`` (a pipe, not a regular file) reads the study; a pipe that
    carries no TOML gets the usual one-line error."""
    import os
    import threading

    text = small_curl("full").to_toml()
    for payload, expected in ((text, None), ("name = \n[model", "is not valid TOML")):
        fifo = tmp_path / "pipe"
        if fifo.exists():
            fifo.unlink()
        os.mkfifo(fifo)
        writer = threading.Thread(target=lambda p=payload: fifo.write_text(p), daemon=True)
        writer.start()
        if expected is None:
            assert Study.from_file(fifo).to_toml() == text
        else:
            with pytest.raises(StudyError, match=expected):
                Study.from_file(fifo)
        writer.join(5)


def test_run_names_the_run_of_a_result_file_whose_study_to_use(tmp_path, capsys):
    """``fatigue-pin run FILE.h5 --run NAME``: a file of several runs needs the name (before, it
    had no way to name one); ``--run`` with a TOML study is refused."""
    import dataclasses

    from conftest import make_run
    from fatigue_pin.io.results import write_run

    path = tmp_path / "runs.h5"
    for name, S in (("full/a", 0.0), ("full/b", 10.0)):
        write_run(path, dataclasses.replace(make_run(name), study=small_curl("full", S=S).to_toml()))
    assert Study.from_file(path, "full/a").data["fatigue"]["S"] == 0.0
    assert Study.from_file(path, "full/b").data["fatigue"]["S"] == 10.0
    assert main(["run", str(path), "--out", str(tmp_path / "new.h5")]) == 2
    assert "choose one by name (--run NAME)" in capsys.readouterr().err
    assert main(["run", str(path), "--run", "full/c", "--out", str(tmp_path / "new.h5")]) == 2
    assert "run 'full/c' is not in" in capsys.readouterr().err
    toml = tmp_path / "s.toml"
    toml.write_text(small_curl("full").to_toml())
    with pytest.raises(StudyError, match="is a study file, not an HDF5 result file"):
        Study.from_file(toml, "full/a")


def test_run_study_returns_one_result_type_for_every_horizon_kind(tmp_path):
    """Full, sliding and max-cycles all give a StudyResult: the run, the repetitions, whether it
    converged, the search table when there is one, and a one-line outcome."""
    from fatigue_pin.io.results import list_runs
    from fatigue_pin.io.study import StudyResult, run_study

    files = {kind: tmp_path / f"{kind}.h5" for kind in ("full", "sliding", "max-cycles")}
    full = run_study(small_curl("full", cycles=1), files["full"])
    sliding = run_study(small_curl("sliding", max_cycles=3), files["sliding"])
    search = run_study(small_curl("max-cycles", max_cycles=2), files["max-cycles"])
    for result in (full, sliding, search):
        assert isinstance(result, StudyResult) and result.converged and result.answered
        assert result.run.name in list_runs(files[result.kind])
    assert (full.kind, full.repetitions, full.search) == ("full", 1, None)
    assert full.iterations == full.run.attrs["iterations"] and full.objective == full.run.attrs["objective"]
    assert full.outcome == "converged"
    assert (sliding.kind, sliding.repetitions, sliding.search) == ("sliding", 3, None)
    assert sliding.repetitions == sliding.run.attrs["repetitions"] == sliding.run.n_cycles
    assert sliding.outcome.startswith("3 repetitions: stopped at the cap of 3 cycles (horizon.max_cycles), not by fatigue (1 windows converged")
    assert search.kind == "max-cycles" and search.repetitions == search.search.max_cycles == 2 == search.run.n_cycles
    assert search.iterations == sum(r["iterations"] for r in search.search.tried)
    assert search.outcome.startswith("maximum repetitions: 2 (tried N = [1, 2]; failed: none)")


def test_a_key_given_as_none_is_a_key_not_given():
    """TOML has no None: a table given ``at = None`` from Python normalises as one without ``at``
    (its default filled in), so the study reads back from its TOML to the same table (found by
    hypothesis: the None was dropped without its default)."""
    from conftest import small_curl

    data = small_curl("full").data
    given = [dict(t) for t in data["task"]["targets"]]
    data["task"]["targets"][0]["at"] = None
    study = Study.from_dict(data)
    assert study.data["task"]["targets"] == given
    assert Study.from_toml(study.to_toml()).data == study.data


#: The example with a frame target holding an orientation (its tolerance key: angle_tolerance).
WITH_ORIENTATION = EXAMPLE.replace('[costs]', '[[task.targets]]\nframe = "r_ulna_radius_hand"\nrpy = [0.0, 0.0, 0.5]\n'
                                             'angle_tolerance = 0.2\nat = 0.5\n[costs]', 1)


@pytest.mark.parametrize("dotted, old, new", [
    ("task.targets[1].tolerance", "value = 2.618\nat = 0.5", "value = 2.618\nat = 0.5\ntolerance = 0.1"),
    ("task.targets[0].value", "value = 0.2618 ", "value = 0.1 "),
    ("task.targets[2].angle_tolerance", "angle_tolerance = 0.2", "angle_tolerance = 0.1"),
    ("task.q_init[1]", "q_init = [0.07, 0.2618]", "q_init = [0.07, 0.1]"),
])
def test_set_reaches_elements_of_arrays_as_messages_name_them(dotted, old, new):
    """``task.targets[1].tolerance`` is the second target's tolerance: the name an error message
    gives it (indices from 0), and the same study as the TOML edited by hand."""
    text = WITH_ORIENTATION.replace("\n    ", "\n")
    assert old in text
    by_key = Study.from_toml(text).replace({dotted: 0.1})
    by_hand = Study.from_toml(text.replace(old, new, 1))
    assert by_key == by_hand and by_key != Study.from_toml(text)
    bad = {"tolerance": -0.1, "angle_tolerance": 9.0}.get(dotted.rsplit(".", 1)[-1])
    if bad is not None:  # the message names the key the way --set takes it
        with pytest.raises(StudyError) as err:
            Study.from_toml(text).replace({dotted: bad}).problem()
        assert dotted in str(err.value)


def test_set_of_an_element_through_the_command_line(tmp_path):
    from fatigue_pin.io.study import parse_changes

    study = small_curl("full")
    changed = study.replace(parse_changes(["task.targets[1].tolerance=0.05"]))
    data = study.data
    data["task"]["targets"][1]["tolerance"] = 0.05
    assert changed == Study.from_dict(data) and changed.to_toml().count("tolerance = 0.05") == 1


@pytest.mark.parametrize("dotted, message", [
    ("task.targets[9].x", r"^study key 'task.targets\[9\].x': index \[9\] is out of range; task.targets has 2 elements, \[0\] to \[1\]$"),
    ("task.ranges[0].lower", r"index \[0\] is out of range; task.ranges has no elements$"),
    ("task.targets[-1].value", r"index \[-1\] is not an integer >= 0"),
    ("task.cycle_duration[0]", r"task.cycle_duration is not an array"),
    ("fatigue.S.x", r"^study key 'fatigue.S.x' does not exist$"),
    ("task.targets[1]x.value", r"does not exist"),
])
def test_set_of_a_missing_element_is_one_line(dotted, message):
    with pytest.raises(StudyError, match=message):
        Study.from_toml(EXAMPLE).replace({dotted: 1.0})
