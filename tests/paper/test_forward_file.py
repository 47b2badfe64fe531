"""The forward studies' file read back, and its figures."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from fatigue_pin.paper.forward_file import is_forward_file, plot_forward_file, read_forward_studies


def test_plot_file_forward_studies(tmp_path: Path) -> None:
    from fatigue_pin.paper.forward import ForwardStudyConfig, run_forward_studies

    cfg = ForwardStudyConfig(t_end=3.0, n_eval=301)
    res = run_forward_studies(tmp_path / "fwd", progress=None, config=cfg)
    back = read_forward_studies(res.h5_path)
    assert [(r.S, r.mr0) for r in back.study2] == [(r.S, r.mr0) for r in res.study2]
    np.testing.assert_array_equal(back.study2[-1].trajectory.mf, res.study2[-1].trajectory.mf)
    assert is_forward_file(res.h5_path) and not is_forward_file(tmp_path / "missing.h5")
    paths = plot_forward_file(res.h5_path, tmp_path / "figs")
    assert {p.stem for p in paths if p.suffix == ".png"} == {"study1_states", "study2_states", "study2_invariant_error"}
    assert all(p.stat().st_size > 1000 for p in paths)
