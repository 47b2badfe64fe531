"""HDF5 result files: round trip, atomic writes, clear errors."""

from __future__ import annotations

import h5py
import numpy as np
import pytest

from conftest import make_run
from fatigue_pin.io.results import (
    ResultFileError,
    list_runs,
    read_run,
    read_search,
    write_run,
    write_search,
)


def test_round_trip(tmp_path):
    run = make_run()
    write_run(tmp_path / "a.h5", run)
    back = read_run(tmp_path / "a.h5")
    for name in ("t", "q", "qdot", "tau_plus", "tau_minus", "ma", "mr", "mf", "cycle_costs", "torque_limits"):
        assert np.array_equal(getattr(back, name), getattr(run, name)), name
    assert back.actuator_names == run.actuator_names and back.joint_names == run.joint_names
    assert back.attrs["cost"] == "torque" and back.urdf == run.urdf
    assert back.torque_limits.shape == (2, 4) and np.allclose(back.torque_limits[:, 1], -50 * (1 - run.mf[[10, 20], 1]))


def test_several_runs_and_replacing_one(tmp_path):
    path = tmp_path / "b.h5"
    write_run(path, make_run("full/torque_S10"))
    write_run(path, make_run("sliding/torque_S10", cycles=3))
    write_run(path, make_run("full/torque_S10", cycles=4))
    assert list_runs(path) == ["full/torque_S10", "sliding/torque_S10"]
    assert read_run(path, "full/torque_S10").n_cycles == 4
    assert read_run(path, "sliding/torque_S10").n_cycles == 3


def test_crash_during_write_leaves_the_old_file(tmp_path, monkeypatch):
    import fatigue_pin.io.results as results

    path = tmp_path / "c.h5"
    write_run(path, make_run())

    def boom(group, run):
        group.create_dataset("t", data=[1.0])
        raise RuntimeError("killed")

    monkeypatch.setattr(results, "write_run_group", boom)
    with pytest.raises(RuntimeError):
        write_run(path, make_run("full/other"))
    monkeypatch.undo()
    assert list_runs(path) == ["full/torque_S10"]
    assert not (tmp_path / "c.h5.tmp").exists()
    with h5py.File(path, "r") as h5:
        assert "full/torque_S10/q" in h5


def test_search_table(tmp_path):
    path = tmp_path / "s.h5"
    rows = [{"n_cycles": 1, "converged": True, "status": "Solve_Succeeded", "iterations": 12, "wall_time_s": 0.5}]
    write_search(path, "torque_S10", rows, {"max_cycles": 1})
    table = read_search(path)["torque_S10"]
    assert table["n_cycles"][0] == 1 and table["converged"][0]


def test_clear_errors(tmp_path):
    with pytest.raises(ResultFileError, match="not found"):
        read_run(tmp_path / "missing.h5")
    (tmp_path / "junk.h5").write_text("not hdf5")
    with pytest.raises(ResultFileError, match="not a readable HDF5"):
        read_run(tmp_path / "junk.h5")
    write_run(tmp_path / "d.h5", make_run("a"))
    write_run(tmp_path / "d.h5", make_run("b"))
    with pytest.raises(ResultFileError, match="holds 2 runs"):
        read_run(tmp_path / "d.h5")
    with pytest.raises(ResultFileError, match="'c' is not in"):
        read_run(tmp_path / "d.h5", "c")


def _strings(values) -> list[str]:
    return [v.decode() if isinstance(v, bytes) else str(v) for v in values]


def test_joint_kinds_and_units_round_trip(tmp_path):
    from conftest import make_pendulum_run

    run = make_pendulum_run()
    path = write_run(tmp_path / "p.h5", run)
    with h5py.File(path) as h5:
        g = h5[run.name]
        assert _strings(g["q"].attrs["joint_kinds"]) == ["prismatic", "revolute"]
        assert _strings(g["q"].attrs["units"]) == ["m", "rad"] and g["q"].attrs["unit"] == "mixed"
        assert _strings(g["qdot"].attrs["units"]) == ["m/s", "rad/s"]
        assert _strings(g["tau_halves"].attrs["units"]) == ["N", "N", "N m", "N m"] == _strings(g["torque_limits"].attrs["units"])
    back = read_run(path)
    assert back.joint_kinds == ("prismatic", "revolute")
    assert back.joint_units("slider").effort == "N" and back.half_units("pendulum_minus").effort == "N m"
    write_run(tmp_path / "a.h5", make_run())  # every joint revolute: one unit per dataset, as before
    with h5py.File(tmp_path / "a.h5") as h5:
        assert h5["full/torque_S10/q"].attrs["unit"] == "rad" and h5["full/torque_S10/tau_halves"].attrs["unit"] == "N m"


@pytest.mark.parametrize("urdf, kinds", [(None, ("prismatic", "revolute")),  # from the stored URDF
                                         ("", ("revolute", "revolute")),  # none stored: revolute
                                         ("<robot name='x'/>", ("revolute", "revolute"))])  # the URDF lacks the joints
def test_files_without_joint_kinds_still_read(tmp_path, urdf, kinds):
    """Runs written before the kinds were stored: kinds from the run's URDF, else revolute."""
    from conftest import make_pendulum_run

    run = make_pendulum_run(urdf=urdf)
    path = write_run(tmp_path / "old.h5", run)
    with h5py.File(path, "a") as h5:
        for name in ("q", "qdot", "tau_halves", "torque_limits"):
            del h5[run.name][name].attrs["units"]
        del h5[run.name]["q"].attrs["joint_kinds"]
    back = read_run(path)
    assert back.joint_kinds == kinds
    np.testing.assert_array_equal(back.q, run.q)


def test_a_stored_unknown_joint_kind_is_refused(tmp_path):
    path = write_run(tmp_path / "bad.h5", make_run())
    with h5py.File(path, "a") as h5:
        h5["full/torque_S10/q"].attrs["joint_kinds"] = ["revolute", "spherical"]
    with pytest.raises(ResultFileError, match=r"joint kinds \['revolute', 'spherical'\]: expected one of"):
        read_run(path)
