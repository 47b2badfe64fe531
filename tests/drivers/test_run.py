"""The run record: every attribute, limits at cycle ends, labels, the URDF text."""

from __future__ import annotations

import numpy as np

from fatigue_pin.drivers.run import RUN_ATTRIBUTES, solution_to_run
from fatigue_pin.io.results import read_run, write_run


def test_run_record_has_every_attribute(build, tmp_path):
    ocp = build(2)
    sol = ocp.solve()
    run = solution_to_run(ocp, sol, "full/test")
    write_run(tmp_path / "r.h5", run)
    back = read_run(tmp_path / "r.h5", "full/test")
    for key in RUN_ATTRIBUTES:
        assert key in back.attrs, key
    assert back.attrs["horizon"] == "full" and bool(back.attrs["converged"]) is True
    assert back.torque_limits.shape == (2, 4)
    assert np.allclose(back.torque_limits[:, 0], 50 * (1 - back.mf[[10, 20], 0]))
    assert back.actuator_names == ("shoulder_plus", "shoulder_minus", "elbow_plus", "elbow_minus")
    assert back.fatigue_states == ("ma", "mr", "mf")
    assert "<robot" in back.urdf
