"""Tests of endurance times (fatigue_pin.fatigue.endurance) and the ``fatigue-pin endurance`` command."""

from __future__ import annotations

import argparse
import math

import h5py
import numpy as np
import pytest

from fatigue_pin.cli import fatigue as cli_fatigue
from fatigue_pin.fatigue.endurance import (
    FREY_LAW_AVIN_2010,
    OutputLocationError,
    compare_frey_law_avin,
    endurance_table,
    endurance_time,
    intermittent_et_closed_form,
    power_model_et,
    sustained_et_closed_form,
)
from fatigue_pin.fatigue.endurance_report import format_comparison, run_endurance
from fatigue_pin.core.errors import ParameterError
from fatigue_pin.fatigue.michaud import MichaudFatigue
from fatigue_pin.fatigue.models import XiaFatigue

ELBOW = XiaFatigue(LD=10, LR=10, F=0.00912, R=0.00094)


def test_closed_form_by_hand():
    # TL = 0.5: ln(1 - 0.00094 * 0.5 / (0.00912 * 0.5)) / -0.00094
    assert sustained_et_closed_form(0.00912, 0.00094, 0.5) == pytest.approx(-math.log(1 - 0.00094 / 0.00912) / 0.00094)
    # R = 0: no recovery, mf = F TL t reaches 1 - TL.
    assert sustained_et_closed_form(0.01, 0.0, 0.25) == pytest.approx(0.75 / 0.0025)
    # R (1 - TL) >= F TL: the fatigued fraction settles below 1 - TL.
    assert sustained_et_closed_form(0.001, 0.001, 0.5) == math.inf
    assert sustained_et_closed_form(0.001, 0.001, 0.4) == math.inf
    np.testing.assert_array_equal(sustained_et_closed_form(0.01, 0.001, np.array([0.05, 0.5]))[0], np.inf)


def test_power_model():
    assert power_model_et("elbow", 0.5) == pytest.approx(17.98 * 0.5**-2.21)
    assert FREY_LAW_AVIN_2010["grip"] == FREY_LAW_AVIN_2010["hand"] == (33.55, -1.61)
    with pytest.raises(ParameterError, match="'wrist'"):
        power_model_et("wrist", 0.5)


@pytest.mark.parametrize("TL", [0.2, 0.35, 0.5, 0.65, 0.8, 0.9])
def test_simulation_matches_closed_form_with_large_LD(TL):
    model = ELBOW.with_(LD=1000.0, LR=1000.0)
    sim = endurance_time(model, TL)
    closed = sustained_et_closed_form(model.F, model.R, TL)
    assert sim == pytest.approx(closed, rel=2e-3)  # well inside the 2 % required


@pytest.mark.parametrize("TL", [0.2, 0.5, 0.9])
def test_finite_LD_delay_is_first_order_in_1_over_LD(TL):
    # LD = 10: ma holds at TL LD / (LD + F), i.e. F acts as F LD / (LD + F), and the ramp-up takes
    # about 1 / LD: ET grows by 1/LD + (F/LD) ET |d ln ET / d ln F| to first order.
    sim, closed = endurance_time(ELBOW, TL), sustained_et_closed_form(ELBOW.F, ELBOW.R, TL)
    x = ELBOW.R * (1 - TL) / (ELBOW.F * TL)
    elasticity = x / ((1 - x) * -math.log(1 - x))
    predicted = 1 / ELBOW.LD + ELBOW.F / ELBOW.LD * closed * elasticity
    assert sim - closed == pytest.approx(predicted, rel=0.2)
    assert sim == pytest.approx(closed, rel=0.01)


def test_no_failure_within_t_max():
    model = XiaFatigue(LD=10, LR=10, F=0.001, R=0.001)
    assert endurance_time(model, 0.4, t_max=2000.0) == math.inf


def test_definition_is_capacity_below_target():
    # At ET, ma + mr = TL exactly; just before, the actuator still holds TL.
    from fatigue_pin.fatigue.simulation import simulate

    TL = 0.7
    et = endurance_time(ELBOW, TL)
    tr = simulate(ELBOW, TL, (0, 1, 0), et, t_eval=[et - 1.0, et], method="LSODA", rtol=1e-10, atol=1e-12)
    cap = tr.ma + tr.mr
    assert cap[1] == pytest.approx(TL, abs=1e-6) and cap[0] > TL
    assert tr.ma[0] == pytest.approx(TL, rel=2e-3)


@pytest.mark.parametrize("TL, d, T, r", [(0.6, 0.5, 20.0, 1.0), (0.9, 0.5, 20.0, 15.0), (0.6, 0.8, 10.0, 15.0), (0.3, 0.3, 60.0, 1.0)])
def test_intermittent_simulation_matches_cycle_closed_form(TL, d, T, r):
    model = ELBOW.with_(LD=1000.0, LR=1000.0, r=r)
    sim = endurance_time(model, TL, d, T)
    closed = intermittent_et_closed_form(model.F, model.R, TL, d, T, r)
    assert sim == pytest.approx(closed, rel=2e-3)


def test_rest_multiplier_matters_for_intermittent_tasks():
    et = {r: intermittent_et_closed_form(0.00912, 0.00094, 0.6, 0.8, 10.0, r) for r in (1.0, 5.0, 15.0)}
    assert et[1.0] < et[5.0] < et[15.0] < math.inf
    assert intermittent_et_closed_form(0.00912, 0.00094, 0.6, 0.5, 20.0, 15.0) == math.inf
    # The simulation agrees that r = 15 never fails there (stopped once the cycles settle).
    assert endurance_time(ELBOW.with_(r=15.0), 0.6, 0.5, 20.0) == math.inf
    # Sustained: r plays no part, duty cycle 1 is the sustained closed form.
    assert intermittent_et_closed_form(0.00912, 0.00094, 0.6, 1.0, None, 15.0) == sustained_et_closed_form(0.00912, 0.00094, 0.6)


def test_intermittent_no_recovery_by_hand():
    # R = 0: mf grows by F TL d T = 0.01 * 0.5 * 5 = 0.025 per 10 s cycle and fails at mf = 0.5:
    # 20 full "on" parts, i.e. failure at the end of the 20th on part = 19 cycles + 5 s.
    assert intermittent_et_closed_form(0.01, 0.0, 0.5, 0.5, 10.0) == pytest.approx(195.0)


def test_michaud_endurance_shorter_than_xia_with_same_rates():
    mich = MichaudFatigue(LD=10, LR=10, F=0.00912, R=0.00094, effort_threshold=0.2, effort_factor=0.01,
                          stabilization_factor=0.0)
    et_m, et_x = endurance_time(mich, 0.5), endurance_time(ELBOW, 0.5)
    assert et_m < et_x  # effort takes capacity away from ma + mr


def test_bad_inputs():
    with pytest.raises(ParameterError, match="TL = 1.5"):
        endurance_time(ELBOW, 1.5)
    with pytest.raises(ParameterError, match="cycle_s = None"):
        endurance_time(ELBOW, 0.5, 0.5)
    with pytest.raises(ParameterError, match="duty_cycle = 0.0"):
        intermittent_et_closed_form(0.01, 0.001, 0.5, 0.0, 10.0)


def test_comparison_with_frey_law_avin_is_reported_not_tuned():
    tabs = compare_frey_law_avin()
    assert [t.joint for t in tabs] == ["ankle", "knee", "trunk", "shoulder", "elbow", "hand", "general"]
    elbow = tabs[4]
    np.testing.assert_allclose(elbow.et_power, 17.98 * elbow.loads**-2.21)
    np.testing.assert_allclose(elbow.et_closed, sustained_et_closed_form(0.00912, 0.00094, elbow.loads))
    # The 3CC fit does not reproduce the power curve: at TL = 0.9 it predicts about half the time.
    assert elbow.rel_error_power[-1] == pytest.approx(12.28 / 22.74 - 1, abs=0.01)
    assert "RMS log error" in format_comparison(tabs)


def test_run_endurance_writes_table_h5_and_figure(tmp_path):
    tab, comparison, paths = run_endurance(tmp_path / "out", preset="frey-law-2012/elbow", loads=(0.3, 0.8))
    assert paths["png"].stat().st_size > 10_000
    with h5py.File(paths["h5"]) as h5:
        g = h5["endurance/0"]
        np.testing.assert_allclose(g["TL"][()], [0.3, 0.8])
        np.testing.assert_allclose(g["et_sim_s"][()], tab.et_sim)
        np.testing.assert_allclose(g["et_closed_form_s"][()], sustained_et_closed_form(0.00912, 0.00094, np.array([0.3, 0.8])))
        assert g.attrs["joint"] == "elbow" and "Frey-Law" in g.attrs["source"]
        assert set(h5["frey_law_avin"]) == {"ankle", "knee", "trunk", "shoulder", "elbow", "hand", "general"}
    assert np.all(np.abs(tab.rel_error_closed) < 0.02)


def _parser():
    parser = argparse.ArgumentParser(prog="fatigue-pin")
    cli_fatigue.register(parser.add_subparsers(dest="command", required=True))
    return parser


def test_cli_endurance(tmp_path, capsys):
    args = _parser().parse_args(["endurance", "--preset", "frey-law-2012/knee", "--out", str(tmp_path / "e"),
                                 "--loads", "0.5,0.9", "--no-compare"])
    assert args.func(args) == 0
    out = capsys.readouterr().out
    assert "| 0.50 |" in out and "Frey-Law & Avin knee" in out and "endurance.h5" in out


def test_cli_endurance_rakshit_elbow(tmp_path, capsys):
    """``fatigue-pin endurance --preset rakshit-2021/elbow``: Rakshit et al.'s elbow row (F = 0.01086,
    R = 0.00225), beside the elbow power curve; the sustained ET is the 3CC closed form (r acts at
    rest only, so not here), written out by hand."""
    out_dir = tmp_path / "e"
    args = _parser().parse_args(["endurance", "--preset", "rakshit-2021/elbow", "--out", str(out_dir),
                                 "--loads", "0.5", "--no-compare"])
    assert args.func(args) == 0
    out = capsys.readouterr().out
    assert "F = 0.01086, R = 0.00225" in out and "r = 4.93, rest_load = 0" in out and "Frey-Law & Avin elbow" in out
    F, R, TL = 0.01086, 0.00225, 0.5
    closed = -math.log(1 - R * (1 - TL) / (F * TL)) / R  # 103.2 s
    with h5py.File(out_dir / "endurance.h5") as f:
        g = f["endurance/0"]
        assert g["et_closed_form_s"][0] == pytest.approx(closed, rel=1e-12)
        assert g["et_sim_s"][0] == pytest.approx(closed, rel=5e-3)  # LD = 10: ET grows by about F / LD
        assert g["et_power_model_s"][0] == pytest.approx(17.98 * TL ** -2.21, rel=1e-12)


def test_cli_endurance_checks_output_first(tmp_path):
    target = tmp_path / "file"
    target.write_text("x")
    args = _parser().parse_args(["endurance", "--out", str(target)])
    with pytest.raises(OutputLocationError, match="is a file; expected a folder"):
        args.func(args)
    args = _parser().parse_args(["endurance", "--out", str(tmp_path / "e"), "--duty-cycle", "0.5"])
    with pytest.raises(ParameterError, match="--cycle-s"):
        args.func(args)


def test_intermittent_task_is_bounded_and_shows_progress(monkeypatch):
    """A very frequent intermittent task simulates at most max_cycles cycles, with a progress
    line every PROGRESS_EVERY cycles, then stops with one line naming the bound."""
    import fatigue_pin.fatigue.endurance as endurance

    monkeypatch.setattr(endurance, "PROGRESS_EVERY", 10)
    lines: list[str] = []
    with pytest.raises(ParameterError, match=r"max_cycles = 35 cycles of 0.01 s \(0.35 s\) simulated at TL = 0.5") as err:
        endurance_time(ELBOW, 0.5, 0.5, 0.01, max_cycles=35, progress=lines.append)
    assert "\n" not in str(err.value)
    assert [line.split(":")[1].split("(")[0].strip() for line in lines] == [f"cycle {k} of at most 35" for k in (10, 20, 30)]
    # A bound that the task stays within changes nothing: 10 s cycles at TL = 0.5 fail in cycle 25.
    et = endurance_time(ELBOW, 0.5, 0.5, 10.0)
    assert endurance_time(ELBOW, 0.5, 0.5, 10.0, max_cycles=25) == et
    assert et == pytest.approx(intermittent_et_closed_form(ELBOW.F, ELBOW.R, 0.5, 0.5, 10.0), rel=2e-3)
    with pytest.raises(ParameterError, match="max_cycles = 0: expected an integer"):
        endurance_time(ELBOW, 0.5, 0.5, 10.0, max_cycles=0)


def test_cli_endurance_max_cycles_and_empty_loads(tmp_path, capsys):
    args = _parser().parse_args(["endurance", "--out", str(tmp_path / "e"), "--loads", "0.5", "--duty-cycle", "0.5",
                                 "--cycle-s", "0.01", "--max-cycles", "20", "--no-compare"])
    with pytest.raises(ParameterError, match="max_cycles = 20 cycles of 0.01 s"):
        args.func(args)
    for loads in (",", "", " , "):
        with pytest.raises(SystemExit):
            _parser().parse_args(["endurance", "--out", str(tmp_path / "e"), "--loads", loads])
        assert f"--loads {loads!r}: expected comma-separated fractions" in capsys.readouterr().err
    with pytest.raises(ParameterError, match=r"loads = \[\]: expected at least one target load"):
        endurance_table(ELBOW, [])


def test_closed_form_when_the_on_part_saturates():
    """R d T so large that exp(-R d T) underflows to 0: each "on" part reaches F TL / R, and the
    first one fails as a sustained task would (was a division by zero)."""
    et = intermittent_et_closed_form(2e3, 1e3, 0.5, 0.5, 10.0)
    assert et == pytest.approx(sustained_et_closed_form(2e3, 1e3, 0.5)) and et == pytest.approx(math.log(2) / 1e3)
