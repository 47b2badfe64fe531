"""Tests of the forward studies (fatigue_pin.paper.forward): file layout and the paper's numbers."""

from __future__ import annotations

import math

import h5py
import numpy as np
import pytest

from fatigue_pin.paper.forward import PAPER_STUDY2, ForwardStudiesResult, run_forward_studies

PRECISIONS_CHECKED = 3  # 1e-5, 1e-6, 1e-7


@pytest.fixture(scope="module")
def result(tmp_path_factory) -> ForwardStudiesResult:
    return run_forward_studies(tmp_path_factory.mktemp("forward"), progress=None)


def test_h5_layout(result):
    assert result.h5_path.name == "forward_studies.h5"
    assert not result.h5_path.with_name("forward_studies.h5.tmp").exists()
    with h5py.File(result.h5_path, "r") as h5:
        assert set(h5["study1"]) == {"3cc", "3cc_s"}
        expected = {f"S{S}_mr{mr}" for S in (0, 5, 10, 20) for mr in ("1.0001", "0.9999", "1.0")}
        assert set(h5["study2"]) == expected
        for name in ["study1/3cc", "study1/3cc_s"] + [f"study2/{g}" for g in expected]:
            g = h5[name]
            n = g["t"].shape[0]
            assert n >= 6000
            for key in ("ma", "mr", "mf"):
                assert g[key].shape == (n,)
            for key in ("S", "TL", "LD", "LR", "F", "R", "rtol", "atol"):
                assert key in g.attrs, (name, key)
            assert g.attrs["m0"].shape == (3,)
            assert g.attrs["TL"] == 0.8 and g.attrs["rtol"] == 1e-3 and g.attrs["atol"] == 1e-6
            assert (g.attrs["LD"], g.attrs["LR"], g.attrs["F"], g.attrs["R"]) == (10.0, 10.0, 0.00912, 0.00094)
            np.testing.assert_allclose(g["t"][[0, -1]], [0.0, 60.0])
        g = h5["study2/S5_mr1.0001"]
        assert g.attrs["S"] == 5.0
        np.testing.assert_array_equal(g.attrs["m0"], [0.0, 1.0001, 0.0])
        assert g.attrs["time_to_precision"].shape == (4,) and g.attrs["final_abs_error"].shape == (3,)
        assert h5["study1/3cc"].attrs["S"] == 0.0 and h5["study1/3cc_s"].attrs["S"] == 10.0
        for key in ("3cc", "3cc_s"):
            assert h5[f"study1/{key}"].attrs["rmse"].shape == (3,)
            assert h5[f"study1/{key}"].attrs["final_abs_error"].shape == (3,)


def test_study1_models_agree(result):
    assert np.all(result.study1_rmse < 1e-12)
    assert np.all(result.study1_final_abs_error < 1e-12)


@pytest.mark.parametrize("key", sorted(PAPER_STUDY2))
def test_study2_times_match_paper(result, key):
    S, mr0 = key
    ours = result.run(S, mr0).time_to_precision
    paper = PAPER_STUDY2[key][0]
    for k in range(PRECISIONS_CHECKED):
        assert abs(ours[k] - paper[k]) <= 0.05, (S, mr0, k, ours, paper)


def test_study2_final_errors_order_of_paper(result):
    for run in result.study2:
        if run.S in (5.0, 10.0):
            assert run.final_abs_error[0] < 1e-4 and run.final_abs_error[1] < 1e-6 and run.final_abs_error[2] < 1e-4


def test_study2_without_and_with_too_large_stabiliser(result):
    for mr0 in (1.0001, 0.9999):
        s0 = result.run(0, mr0)
        assert all(math.isnan(x) for x in s0.time_to_precision)  # the initial error stays
        assert s0.trajectory.invariant_error[-1] == pytest.approx(1e-4, rel=1e-6)
        s20 = result.run(20, mr0)
        assert all(math.isnan(x) for x in s20.time_to_precision)
        late = s20.trajectory.t > 50.0
        assert np.max(s20.trajectory.invariant_error[late]) > 1e-4  # keeps coming back above 1e-4


def test_table_and_figures(result):
    table = result.table
    assert "paper" in table and "Study 1" in table and "Study 2" in table
    assert set(result.figures) == {"study1_states", "study2_states", "study2_invariant_error"}
    for path in result.figures.values():
        assert path.suffix == ".png" and path.stat().st_size > 1000
