"""Closed-loop studies: [plant] overrides, [plant.noise], [plant.disturbance], seed, [mpc]."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from conftest import small_mpc_study
from fatigue_pin.core.errors import FatiguePinError
from fatigue_pin.io.mpc_study import MpcStudy

STUDIES = Path(__file__).resolve().parents[2] / "studies"

TABLES = """
[plant.fatigue]
F = 0.912

[plant.model.payload]
frame = "dumbbell"
mass = 5.0

[plant.noise]
q = 0.001
qdot = 0.01
capacity = 0.02

[plant.disturbance]
constant = [0.0, 0.5]
std = 0.1

[mpc]
replan_every = 5
estimator = "mhe"
probe_every = 2

[mpc.mhe]
params = ["F"]
cycles = 2
"""


def test_the_plant_overrides_the_study_with_the_same_keys():
    s = MpcStudy.from_toml(small_mpc_study(TABLES, seed=9))
    assert s.study.data["fatigue"]["F"] == 0.456 and s.plant_study.data["fatigue"]["F"] == 0.912
    model, plant = s.study.problem().model, s.plant_study.problem().model
    assert model.payload is None and plant.payload.mass == 5.0
    masses = model.body_masses(), plant.body_masses()
    assert masses[1]["elbow"] == pytest.approx(masses[0]["elbow"] + 5.0)  # the load rides on the forearm
    assert s.plant.noise.q == 0.001 and s.plant.noise.capacity == 0.02 and s.plant.seed == 9
    assert s.plant.disturbance.constant == (0.0, 0.5) and s.plant.disturbance.std == 0.1
    assert s.mpc.replan_every == 5 and s.mpc.estimator == "mhe" and s.mpc.probe_every == 2
    assert s.mpc.mhe.params == ("F",) and s.mpc.mhe.cycles == 2
    again = MpcStudy.from_toml(s.to_toml())  # the stored text reads back to the same study
    assert (again.plant, again.mpc, again.plant_study.data, again.study.data) == (s.plant, s.mpc, s.plant_study.data, s.study.data)


def test_without_a_plant_table_the_plant_is_the_model():
    s = MpcStudy.from_toml(small_mpc_study())
    assert s.plant_study is s.study
    assert not s.plant.noisy and s.mpc.estimator == "open-loop" and s.mpc.replan_every is None


def test_set_changes_reach_every_table():
    s = MpcStudy.from_toml(small_mpc_study(), changes={"mpc.replan_every": 2, "plant.fatigue.F": 1.0, "seed": 3,
                                                        "horizon.max_cycles": 4, "plant.noise.q": 0.01})
    assert s.mpc.replan_every == 2 and s.plant_study.data["fatigue"]["F"] == 1.0 and s.plant.seed == 3
    assert s.study.horizon["max_cycles"] == 4 and s.plant_study.horizon["max_cycles"] == 4 and s.plant.noise.q == 0.01
    np.testing.assert_array_equal(s.sliding().window, 3)


@pytest.mark.parametrize("changes, message", [
    ({"plant.fatigue.G": 1.0}, "unknown key plant.fatigue.G;"),
    ({"plant.model.colour": "red"}, "unknown key plant.model.colour;"),
    ({"plant.task.cycle_duration": 2.0}, "unknown key plant.task;"),
    ({"plant.fatigue.F": -1.0}, "plant.fatigue.F = -1.0: expected"),
    ({"plant.model.payload.mass": 5.0}, "missing key plant.model.payload.frame"),
    ({"plant.noise.q": -0.1}, "plant.noise.q = -0.1: expected a standard deviation >= 0"),
    ({"plant.noise.speed": 0.1}, "unknown key plant.noise.speed;"),
    ({"plant.disturbance.std": [0.1, -0.2]}, "plant.disturbance.std = "),
    ({"mpc.replan_every": 0}, "mpc.replan_every = 0: expected an integer number of intervals >= 1"),
    ({"mpc.estimator": "ekf"}, "mpc.estimator = 'ekf'"),
    ({"mpc.window": 3}, "unknown key mpc.window;"),
    ({"mpc.mhe.cycles": 0}, "mpc.mhe.cycles = 0"),
    ({"seed": -1}, "seed = -1"),
])
def test_bad_closed_loop_keys_are_one_line_errors(changes, message):
    with pytest.raises(FatiguePinError) as err:
        MpcStudy.from_toml(small_mpc_study(), changes=changes)
    assert str(err.value).startswith(message) and "\n" not in str(err.value)


def test_the_ur5_study_parses_and_builds():
    s = MpcStudy.from_file(STUDIES / "ur5_mpc.toml")
    plant, model = s.plant_study.problem(), s.study.problem()
    assert plant.model.payload.mass > model.model.payload.mass  # the plant carries more than the model thinks
    assert s.mpc.estimator == "mhe" and s.mpc.replan_every >= 1 and s.plant.noisy
    assert plant.model.nv == 6 and plant.layout.n_halves == 12
