"""Tests of the calibration of 3CC / 3CC-r to endurance data (fatigue_pin.fatigue.calibration)."""

from __future__ import annotations

import argparse
import json
import re

import numpy as np
import pytest

from fatigue_pin.cli import fatigue as cli_fatigue
from fatigue_pin.fatigue.calibration import CalibrationDataError, EnduranceData, calibrate, read_endurance_csv, run_calibrate
from fatigue_pin.core.errors import OutputLocationError
from fatigue_pin.fatigue.endurance import intermittent_et_closed_form, sustained_et_closed_form
from fatigue_pin.core.errors import FatiguePinError, ParameterError
from fatigue_pin.fatigue.models import XiaFatigue
from fatigue_pin.fatigue.presets import preset

F, R = 0.00912, 0.00094
LOADS = np.linspace(0.2, 0.9, 8)


def write_csv(path, rows, header="target_load,endurance_time_s"):
    path.write_text(header + "\n" + "\n".join(",".join(str(v) for v in row) for row in rows) + "\n")
    return path


@pytest.mark.parametrize("F_true, R_true", [(0.00912, 0.00094), (0.0182, 0.00168), (0.00589, 0.00058), (0.05, 0.002)])
def test_recovers_F_and_R_from_noise_free_data(F_true, R_true):
    data = EnduranceData.from_arrays(LOADS, sustained_et_closed_form(F_true, R_true, LOADS))
    res = calibrate(data)
    assert res.success
    assert res.params["F"] == pytest.approx(F_true, rel=0.02)
    assert res.params["R"] == pytest.approx(R_true, rel=0.02)
    assert res.rms_log < 1e-6


def test_noisy_data_true_values_inside_the_confidence_intervals():
    # One draw (seed 0); a 95 % interval misses for about 1 seed in 20 (seed 7 misses F), which
    # test_ci_coverage_over_seeds checks statistically.
    rng = np.random.default_rng(0)
    tl = np.repeat(LOADS, 3)
    et = sustained_et_closed_form(F, R, tl) * np.exp(rng.normal(0.0, 0.1, tl.size))
    res = calibrate(EnduranceData.from_arrays(tl, et))
    for name, true in (("F", F), ("R", R)):
        lo, hi = res.ci[name]
        assert lo < res.params[name] < hi
        assert lo <= true <= hi
    # The residual scale estimates the noise (sigma 0.1 in log ET).
    assert 0.05 < res.rms_log < 0.15
    # Wider intervals at a lower confidence level would be a bug.
    res90 = calibrate(EnduranceData.from_arrays(tl, et), confidence=0.9)
    assert res90.ci["F"][1] - res90.ci["F"][0] < res.ci["F"][1] - res.ci["F"][0]


def test_ci_coverage_over_seeds():
    # 95 % intervals: with 20 noisy data sets, F should be covered at least 16 times.
    tl = np.repeat(LOADS, 2)
    covered = 0
    for seed in range(20):
        et = sustained_et_closed_form(F, R, tl) * np.exp(np.random.default_rng(seed).normal(0.0, 0.1, tl.size))
        lo, hi = calibrate(EnduranceData.from_arrays(tl, et)).ci["F"]
        covered += lo <= F <= hi
    assert covered >= 16


def test_recovers_F_R_and_r_from_intermittent_data():
    r = 15.0
    tl = np.array([0.2, 0.4, 0.6, 0.8, 0.7, 0.75, 0.8, 0.9, 0.6, 0.8])
    dc = np.array([1, 1, 1, 1, 0.5, 0.5, 0.5, 0.5, 0.8, 0.8])
    cs = np.array([np.nan] * 4 + [20.0] * 4 + [10.0, 10.0])
    et = np.array([intermittent_et_closed_form(F, R, a, b, c, r) for a, b, c in zip(tl, dc, cs)])
    res = calibrate(EnduranceData.from_arrays(tl, et, dc, cs), model="3cc-r")
    assert res.params["F"] == pytest.approx(F, rel=0.02)
    assert res.params["R"] == pytest.approx(R, rel=0.02)
    assert res.params["r"] == pytest.approx(r, rel=0.02)
    # Fitting 3cc (r = 1) to the same data cannot explain the intermittent rows.
    res1 = calibrate(EnduranceData.from_arrays(tl, et, dc, cs), model="3cc")
    assert res1.rms_log > 0.05


def test_csv_json_preset_round_trip(tmp_path):
    rows = [(tl, et) for tl, et in zip(LOADS, sustained_et_closed_form(F, R, LOADS))]
    csv_path = write_csv(tmp_path / "data.csv", rows)
    res, paths = run_calibrate(csv_path, tmp_path / "params.json")
    d = json.loads(paths["json"].read_text())
    assert d["model"] == "3cc" and d["F"] == pytest.approx(F, rel=1e-6) and d["LD"] == 10.0
    assert set(d["confidence_intervals"]) == {"F", "R"} and len(d["residuals_log"]) == 8
    assert paths["png"].stat().st_size > 10_000
    model = preset(str(paths["json"]))
    assert isinstance(model, XiaFatigue) and model.F == pytest.approx(F, rel=1e-6) and model.r == 1.0


def test_exactly_as_many_rows_as_parameters_fits_without_cis():
    tl = np.array([0.3, 0.7])
    res = calibrate(EnduranceData.from_arrays(tl, sustained_et_closed_form(F, R, tl)))
    assert res.params["F"] == pytest.approx(F, rel=1e-3) and res.ci == {"F": None, "R": None}
    assert "no CIs" in res.notes[0]


@pytest.mark.parametrize(
    "rows, header, message",
    [
        ([(0.5, 100.0)], "target_load,endurance_time_s", "1 data row(s) for the 3cc model: expected at least 2"),
        ([(0.5, -3.0), (0.6, 50.0)], "target_load,endurance_time_s", "row 1: endurance_time_s = -3.0: expected a time in [0.001, 1e+09) s"),
        ([(0.5, 1e-300), (0.6, 2e-300)], "target_load,endurance_time_s", "row 1: endurance_time_s = 1e-300: expected a time in [0.001"),
        ([(0.5, 100.0, 0.7), (0.6, 50.0, 0.8)], "target_load,endurance_time_s,target_load", "column(s) ['target_load'] appear more than once"),
        ([(0.5, "nan"), (0.6, 50.0)], "target_load,endurance_time_s", "endurance_time_s = nan"),
        ([(0.5, "inf"), (0.6, 50.0)], "target_load,endurance_time_s", "endurance_time_s = inf"),
        ([(0.5, 100.0), (1.2, 50.0)], "target_load,endurance_time_s", "row 2: target_load = 1.2: expected a fraction of maximum in (0, 1]"),
        ([(0.0, 100.0), (0.5, 50.0)], "target_load,endurance_time_s", "row 1: target_load = 0.0"),
        ([(1.0, 100.0), (0.5, 50.0)], "target_load,endurance_time_s", "target_load = 1.0: the 3CC with instant activation predicts ET = 0"),
        ([(0.5,), (0.6,)], "target_load", "missing column 'endurance_time_s'"),
        ([(0.5, "long"), (0.6, 50.0)], "target_load,endurance_time_s", "row 1: endurance_time_s = 'long': expected a number"),
        ([(0.5, 100.0, 0.5, ""), (0.6, 50.0, 1, "")], "target_load,endurance_time_s,duty_cycle,cycle_s", "cycle_s = nan with duty_cycle 0.5"),
        ([(0.5, 100.0, 1.5, 10)], "target_load,endurance_time_s,duty_cycle,cycle_s", "duty_cycle = 1.5"),
        ([(0.5, 100.0, 1, 10, 3)], "target_load,endurance_time_s,duty_cycle,cycle_s,subject", "unknown column(s) ['subject']"),
        ([], "target_load,endurance_time_s", "no data rows"),
    ],
)
def test_bad_data_is_refused_with_one_clear_line(tmp_path, rows, header, message):
    path = write_csv(tmp_path / "bad.csv", rows, header)
    with pytest.raises(CalibrationDataError, match=re.escape(message)) as info:
        calibrate(read_endurance_csv(path))
    assert "\n" not in str(info.value)
    assert isinstance(info.value, ParameterError) and isinstance(info.value, FatiguePinError)


def test_a_byte_order_mark_is_read(tmp_path):
    """Excel writes UTF-8 CSV files with a byte-order mark before the first column's name."""
    rows = [(tl, et) for tl, et in zip(LOADS, sustained_et_closed_form(F, R, LOADS))]
    plain = write_csv(tmp_path / "plain.csv", rows)
    marked = tmp_path / "excel.csv"
    marked.write_bytes(b"\xef\xbb\xbf" + plain.read_bytes())
    a, b = read_endurance_csv(plain), read_endurance_csv(marked)
    np.testing.assert_array_equal(a.target_load, b.target_load)
    np.testing.assert_array_equal(a.endurance_time_s, b.endurance_time_s)
    assert calibrate(b).params["F"] == pytest.approx(F, rel=1e-6)


@pytest.mark.parametrize("scale", [1e-3, 2e-3, 1e8])
def test_extreme_but_accepted_times_fit_or_fail_with_one_line(scale):
    """Times at the ends of the accepted range, with intermittent rows of very short cycles: the
    fit ends at finite parameters or raises the project's error, never an overflow."""
    tl = np.array([0.2, 0.5, 0.8])
    data = EnduranceData.from_arrays(tl, scale * np.array([3.0, 2.0, 1.0]), [0.5, 1.0, 0.5], [1e-3, np.nan, 1e-3])
    try:
        res = calibrate(data, model="3cc-r")
    except CalibrationDataError as exc:
        assert "\n" not in str(exc)
    else:
        assert all(np.isfinite(v) and v > 0 for v in res.params.values())


def test_3cc_r_needs_intermittent_rows():
    data = EnduranceData.from_arrays(LOADS, sustained_et_closed_form(F, R, LOADS))
    with pytest.raises(CalibrationDataError, match="r acts during rests"):
        calibrate(data, model="3cc-r")
    with pytest.raises(CalibrationDataError, match="does not exist"):
        read_endurance_csv("/nonexistent/data.csv")


def _parser():
    parser = argparse.ArgumentParser(prog="fatigue-pin")
    cli_fatigue.register(parser.add_subparsers(dest="command", required=True))
    return parser


def test_cli_calibrate(tmp_path, capsys):
    rows = [(tl, et) for tl, et in zip(LOADS, sustained_et_closed_form(F, R, LOADS))]
    csv_path = write_csv(tmp_path / "data.csv", rows)
    args = _parser().parse_args(["calibrate", str(csv_path), "--out", str(tmp_path / "p.json")])
    assert args.func(args) == 0
    out = capsys.readouterr().out
    assert "F = 0.00912" in out and "95 % CI" in out and (tmp_path / "p.json").is_file() and (tmp_path / "p.png").is_file()


@pytest.mark.parametrize("out, message", [("file/p.json", "is not a folder"), ("p.txt", "expected a .json file name")])
def test_cli_calibrate_checks_output_before_reading(tmp_path, out, message):
    (tmp_path / "file").write_text("a file where the folder should be")
    args = _parser().parse_args(["calibrate", str(tmp_path / "absent.csv"), "--out", str(tmp_path / out)])
    with pytest.raises(OutputLocationError, match=re.escape(message)):
        args.func(args)


@pytest.mark.parametrize("text", ["target_load;endurance_time_s\n0,5;100\n0,3;300\n", "target_load\tendurance_time_s\n0.5\t100\n0.3\t300\n",
                                  "target_load,endurance_time_s\r\n0.5,100\r\n0.3,300\r\n"])
def test_excel_separators_and_decimal_commas_are_read(tmp_path, text):
    """Excel writes ';' with decimal commas where the comma is the decimal mark; tabs and
    Windows line ends are common too: all read as the same data."""
    path = tmp_path / "data.csv"
    path.write_text(text)
    data = read_endurance_csv(path)
    np.testing.assert_array_equal(data.target_load, [0.5, 0.3])
    np.testing.assert_array_equal(data.endurance_time_s, [100.0, 300.0])
