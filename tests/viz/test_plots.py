"""Figures from result files: every figure is a non-empty PNG (more than one colour) and PDF."""

from __future__ import annotations

from pathlib import Path

import matplotlib.image
import numpy as np
import pytest

from fatigue_pin.viz import plots
from fatigue_pin.io.results import ResultFileError, read_run, write_run, write_search
from conftest import make_curl_run


def _check(paths: list[Path], stems: set[str] | None = None) -> None:
    assert paths, "no figure written"
    for p in paths:
        assert p.is_file() and p.stat().st_size > 0, p
    pngs = [p for p in paths if p.suffix == ".png"]
    assert {p.with_suffix(".pdf") for p in pngs} == {p for p in paths if p.suffix == ".pdf"}
    for png in pngs:
        img = matplotlib.image.imread(png)
        assert (img != img[0, 0]).any(), f"{png} has a single colour"
    for pdf in (p for p in paths if p.suffix == ".pdf"):
        assert pdf.read_bytes().startswith(b"%PDF"), pdf
    if stems is not None:
        assert {p.stem for p in pngs} == stems


@pytest.mark.parametrize("horizon", ["full", "sliding"])
@pytest.mark.parametrize("plot", [plots.plot_joint_angles, plots.plot_fatigue_states, plots.plot_torque_limits,
                                  plots.plot_cycle_costs, plots.plot_solve_time])
def test_each_run_figure(plot, horizon: str, tmp_path: Path) -> None:
    path = write_run(tmp_path / "runs.h5", make_curl_run(name=f"{horizon}/fatigue_torque", n_cycles=3, horizon=horizon))
    run = read_run(path)
    paths = plot(run, tmp_path / "fig")
    _check(paths)
    assert all(p.name.startswith(f"{horizon}_fatigue_torque_") for p in paths)


def test_capacity_figure_and_peak_torques(tmp_path: Path) -> None:
    run = make_curl_run(name="full/fatigue_torque", n_cycles=3)
    peak = plots.peak_torques(run)
    per = run.tau_plus.shape[0] // 3
    assert peak.shape == (3, 4)
    np.testing.assert_allclose(peak[1, 0], np.abs(run.tau_plus[per:2 * per, 0]).max())
    np.testing.assert_allclose(peak[2, 3], np.abs(run.tau_minus[2 * per:, 1]).max())
    paths = plots.plot_capacity(run, tmp_path / "fig", holding={"elbow": 4.0})
    _check(paths, {"full_fatigue_torque_capacity"})


def test_target_loads_come_from_the_stored_limits() -> None:
    run = make_curl_run()
    tl = run.target_loads()
    np.testing.assert_allclose(tl[:, 0], run.tau_plus[:, 0] / 50.0)
    np.testing.assert_allclose(tl[:, 3], run.tau_minus[:, 1] / -50.0)
    assert (tl >= 0).all()
    run.attrs["tau_limits"] = np.array([40.0, -30.0, 20.0, -10.0])
    np.testing.assert_allclose(run.target_loads()[:, 1], run.tau_minus[:, 0] / -30.0)
    del run.attrs["tau_limits"]  # no guessed limits: a run without them says so
    with pytest.raises(ResultFileError, match="tau_limits"):
        run.target_loads()


def test_plot_file_with_several_runs(tmp_path: Path) -> None:
    h5 = tmp_path / "runs.h5"
    write_run(h5, make_curl_run(name="full/fatigue_torque", n_cycles=2))
    write_run(h5, make_curl_run(name="sliding/torque", n_cycles=4, horizon="sliding"))
    write_search(h5, "full_fatigue_torque", [
        {"n_cycles": n, "converged": n < 4, "status": "ok" if n < 4 else "fail", "iterations": 10 * n,
         "wall_time_s": 1.5 * n} for n in (1, 2, 3, 4)])
    paths = plots.plot_file(h5, tmp_path / "out")
    per_run = ("joint_angles", "fatigue_states", "torque_limits", "cycle_costs", "solve_time")
    expected = {f"{r}_{f}" for r in ("full_fatigue_torque", "sliding_torque") for f in per_run}
    _check(paths, expected | {"runs_comparison", "search_full_fatigue_torque"})


def test_plot_file_rejects_other_files(tmp_path: Path) -> None:
    import h5py

    with h5py.File(tmp_path / "other.h5", "w") as h5:
        h5["x"] = np.zeros(3)
    with pytest.raises(ResultFileError, match="neither"):
        plots.plot_file(tmp_path / "other.h5", tmp_path / "out")
    with pytest.raises(ResultFileError, match="not found"):
        plots.plot_file(tmp_path / "missing.h5", tmp_path / "out")


def _drawn(monkeypatch) -> list:
    """Capture the figures the plot functions save (their lines hold the data drawn)."""
    figures: list = []
    save = plots._save
    monkeypatch.setattr(plots, "_save", lambda fig, out, stem: figures.append(fig) or save(fig, out, stem))
    return figures


def test_figures_draw_the_run_s_data(monkeypatch, tmp_path: Path) -> None:
    """What is drawn is the run: each cycle's joint angles (deg), each half's mf, the stored
    torque limits at the cycle ends; not just a file that exists."""
    run = make_curl_run(n_cycles=3)
    figures = _drawn(monkeypatch)
    plots.plot_joint_angles(run, tmp_path)
    elbow = figures[-1].axes[1]
    assert elbow.get_title() == "elbow"
    lines = elbow.get_lines()
    assert len(lines) == 3
    for c, line in enumerate(lines):
        s = run.cycle_slice(c)
        np.testing.assert_allclose(line.get_ydata(), np.degrees(run.q[s, 1]))
        np.testing.assert_allclose(line.get_xdata(), run.t[s] - run.t[s.start])
    plots.plot_fatigue_states(run, tmp_path)
    elbow_plus = figures[-1].axes[2]
    assert elbow_plus.get_title() == "elbow_plus (limit +50 N m)"
    (tl,) = [ln for ln in elbow_plus.get_lines() if ln.get_drawstyle() == "steps-post"]  # the target load; states: bands
    np.testing.assert_allclose(tl.get_ydata(), run.tau_plus[:, 1] / 50.0)
    top = elbow_plus.collections[-1].get_paths()[0].vertices[:, 1].max()  # the mf band reaches ma + mr + mf
    assert top == pytest.approx((run.ma[:, 2] + run.mr[:, 2] + run.mf[:, 2]).max())
    plots.plot_torque_limits(run, tmp_path)
    drawn = [np.asarray(line.get_ydata()) for ax in figures[-1].axes for line in ax.get_lines()]
    expected = np.concatenate([[50.0 * (1 - run.fatigued[0, 2])], run.torque_limits[:, 2]])
    assert any(d.shape == expected.shape and np.allclose(d, expected) for d in drawn)


def test_a_prismatic_joint_is_plotted_in_metres(monkeypatch, tmp_path: Path) -> None:
    """The slider's positions are drawn as stored (m), the pendulum's in deg; its halves' limits in N."""
    from conftest import make_pendulum_run

    run = read_run(write_run(tmp_path / "p.h5", make_pendulum_run(cycles=3)))
    figures = _drawn(monkeypatch)
    plots.plot_joint_angles(run, tmp_path)
    slider, pendulum = figures[-1].axes[:2]
    assert (slider.get_title(), slider.get_ylabel()) == ("slider", "position (m)")
    assert (pendulum.get_title(), pendulum.get_ylabel()) == ("pendulum", "angle (deg)")
    for c in range(3):
        s = run.cycle_slice(c)
        np.testing.assert_array_equal(slider.get_lines()[c].get_ydata(), run.q[s, 0])
        np.testing.assert_allclose(pendulum.get_lines()[c].get_ydata(), np.degrees(run.q[s, 1]))
    plots.plot_fatigue_states(run, tmp_path)
    titles = [ax.get_title() for ax in figures[-1].axes[:4]]
    assert titles == ["slider_plus (limit +50 N)", "slider_minus (limit -50 N)", "pendulum_plus (limit +50 N m)",
                      "pendulum_minus (limit -50 N m)"]
    plots.plot_torque_limits(run, tmp_path)
    assert {ax.get_ylabel() for ax in figures[-1].axes} == {"torque limit (N or N m)"}
    legend = [t.get_text() for t in figures[-1].axes[0].get_legend().get_texts()]
    assert legend[0].startswith("slider_plus: 50 -> ") and " N (" in legend[0] and " N m (" in legend[1]
    plots.plot_capacity(run, tmp_path, holding={"slider": 2.0})
    assert [ax.get_ylabel() for ax in figures[-1].axes[:2]] == ["force (N)", "force (N)"]
    assert "holding force 2.00 N" in [t.get_text() for t in figures[-1].axes[0].get_legend().get_texts()]
    plots.plot_comparison([run, run], tmp_path)
    comparison = figures[-1].axes[1]
    assert comparison.get_ylabel() == "position (m)"
    np.testing.assert_array_equal(comparison.get_lines()[0].get_ydata(), run.q[run.cycle_slice(2), 0])


def _drawn_lines(monkeypatch, suffix: str) -> dict:
    """``{"lines": {y label: [each line's y data]}}`` of the figure saved with a stem ending in
    ``suffix``, once it is saved."""
    drawn: dict = {}
    original = plots._save

    def keep(fig, out_dir, stem):
        if stem.endswith(suffix):
            drawn["lines"] = {ax.get_ylabel(): [ln.get_ydata() for ln in ax.lines] for ax in fig.axes}
        return original(fig, out_dir, stem)

    monkeypatch.setattr(plots, "_save", keep)
    return drawn


def test_a_muscle_run_gets_its_muscles_figure(two_muscle_run, monkeypatch, tmp_path: Path) -> None:
    """Each muscle's fatigued fraction, its force and the joint torques it gives are what the run stores."""
    _, _, run = two_muscle_run
    drawn = _drawn_lines(monkeypatch, "_muscles")
    paths = plots.plot_run(run, tmp_path)
    assert any(p.name.endswith("_muscles.png") for p in paths)
    lines = drawn["lines"]
    assert np.array_equal(lines["fatigued fraction (-)"][0], run.fatigued[:, 0])  # TRIlat over the run
    assert np.array_equal(lines["tendon force (N)"][1][:-1], run.extras["muscle_force"][:, 1][: len(lines["tendon force (N)"][1]) - 1])
    # the muscles' share of the elbow torque, and the residual at the elbow
    elbow_muscles = run.extras["joint_torque"][:, 1] - (run.tau_plus + run.tau_minus)[:, 1]
    assert np.allclose(lines["joint torque (N m)"][2], elbow_muscles)


def test_a_motor_run_gets_its_heat_figure(monkeypatch, tmp_path: Path) -> None:
    """A motor run's figure draws each winding's stored temperature, its limit T_max - margin and
    each joint's RMS torque per cycle, computed here again from the stored torques."""
    from conftest import small_curl
    from fatigue_pin.io.study import run_study

    study = small_curl("full").replace({"actuators.kind": "motors", "horizon.cycles": 2,
                                        "motors": {"preset": "maxon-re40", "gear_ratio": 20.0, "T_max": 120.0}})
    run_study(study, out=tmp_path / "m.h5", name="full/motors")
    run = read_run(tmp_path / "m.h5", "full/motors")
    drawn = _drawn_lines(monkeypatch, "_motors")
    paths = plots.plot_run(run, tmp_path / "fig")
    _check([p for p in paths if "_motors" in p.name])
    heat, torque = drawn["lines"]["winding (solid), housing (dotted) (deg C)"], drawn["lines"]["RMS torque in the cycle (N m)"]
    assert np.array_equal(heat[0], run.extras["winding_C"][:, 0]) and np.allclose(heat[2], 120.0 - 10.0)  # the default margin
    tau, n = run.half_torques(), 10
    rms = [np.sqrt(np.mean(tau[c * n:(c + 1) * n, 1] ** 2)) for c in range(2)]
    assert np.allclose(torque[1], rms)  # the elbow's
