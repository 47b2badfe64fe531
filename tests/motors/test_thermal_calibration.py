"""The thermal calibration: recovers known parameters from noise-free series; bad logs are one line."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from fatigue_pin.cli.main import main
from fatigue_pin.core.errors import ParameterError
from fatigue_pin.motors.calibration import ThermalLog, calibrate_thermal, read_thermal_csv, simulate
from fatigue_pin.motors.presets import motor_preset

from conftest import integrate, step_from_ambient

TRUTH = {"R_wh": 2.3, "R_ha": 4.5, "tau_w": 25.0, "tau_m": 800.0}  # the RE 30 preset: 1.7, 6.0, 16.9, 593


def _write(path, header, rows):
    path.write_text(header + "\n" + "\n".join(",".join(repr(float(v)) for v in r) for r in rows) + "\n")
    return path


def test_recovers_the_four_parameters_from_the_closed_form_step():
    """A step of current from ambient with alpha = 0 and no no-load loss: the winding's rise is the
    reference's two-exponential closed form."""
    t = np.arange(0.0, 2400.0, 4.0)
    i = 2.0
    R25 = motor_preset("maxon-re30").R25
    T = 25.0 + step_from_ambient(*TRUTH.values(), R25 * i * i, t)[:, 0]
    fit = calibrate_thermal(ThermalLog(t, np.full_like(t, i), T, "winding"), motor="maxon-re30", alpha=0.0,
                            no_load_loss=0.0, T_ambient=25.0)
    assert fit.success
    assert fit.params == pytest.approx(TRUTH, rel=1e-6)
    assert fit.rms_K < 1e-8


def test_recovers_three_from_a_housing_log_with_resistance_rising(tmp_path):
    """Heating then cooling with R(T_w) and the no-load loss, integrated by solve_ivp; the housing
    temperature, logged as a joint torque, fits R_wh, R_ha, tau_m with tau_w held at the preset's."""
    base = motor_preset("maxon-re30")
    truth = dataclasses.replace(base, R_wh=2.3, R_ha=4.5, tau_m=800.0)
    t = np.arange(0.0, 3600.0, 5.0)
    tau = np.where(t < 1800.0, 2.0 * base.k_t * base.gear_ratio, 0.0)
    T = np.empty((t.size, 2))
    T[0] = 25.0
    for k in range(t.size - 1):  # piecewise constant current, row by row
        i = truth.current(tau[k], 0.0)
        T[k + 1] = integrate(lambda s, y: list(truth.derivative(y[0], y[1], i)), np.array([0.0, t[k + 1] - t[k]]), T[k])[-1]
    path = _write(tmp_path / "log.csv", "time_s,torque_Nm,housing_C", zip(t, tau, T[:, 1]))
    log = read_thermal_csv(path, base)
    assert simulate(truth, log.time_s, log.current_A, (25.0, 25.0)) == pytest.approx(T, abs=1e-7)
    fit = calibrate_thermal(log, motor="maxon-re30")
    assert fit.fitted == ("R_wh", "R_ha", "tau_m")
    assert fit.params == pytest.approx({"R_wh": 2.3, "R_ha": 4.5, "tau_m": 800.0}, rel=1e-5)


def test_all_four_from_a_housing_log_is_refused():
    t = np.arange(0.0, 50.0, 5.0)
    log = ThermalLog(t, np.ones_like(t), 25.0 + t / 10, "housing")
    with pytest.raises(ParameterError, match=r"^ThermalCalibrationSettings\.fit = all four from a housing"):
        calibrate_thermal(log, motor="maxon-re30", fit=("R_wh", "R_ha", "tau_w", "tau_m"))


def test_cli_writes_the_fit(tmp_path, capsys):
    t = np.arange(0.0, 2400.0, 4.0)
    R25 = motor_preset("maxon-re30").R25
    T = 25.0 + step_from_ambient(*TRUTH.values(), R25 * 4.0, t)[:, 0]
    path = _write(tmp_path / "log.csv", "time_s,current_A,winding_C", zip(t, np.full_like(t, 2.0), T))
    out = tmp_path / "fit.json"
    assert main(["calibrate-thermal", str(path), "--motor", "maxon-re30", "--out", str(out), "--alpha", "0",
                 "--no-load-loss", "0"]) == 0
    assert "R_wh = 2.3" in capsys.readouterr().out and out.is_file()


@pytest.mark.parametrize("text, match", [
    ("time_s,current_A,winding_C\n" + "".join(f"{k},1.0,40.0\n" for k in range(8)),
     r"log\.csv: winding_C never changes \(all 40\.0 deg C\): expected a temperature that rises or falls"),
    ("time_s,current_A,winding_C\n" + "".join(f"{k % 3},1.0,{40 + k}\n" for k in range(8)),
     r"log\.csv: row 4: time_s = 0\.0: expected times strictly increasing"),
    ("time_s,current_A\n0,1\n", r"log\.csv: columns \['time_s', 'current_A'\]: expected time_s, one of"),
    ("time_s,current_A,housing_C\n0,x,3\n", r"log\.csv: row 1: current_A = 'x': expected a number"),
])
def test_bad_csv_is_exit_2_and_one_line(tmp_path, capsys, text, match):
    (tmp_path / "log.csv").write_text(text)
    assert main(["calibrate-thermal", str(tmp_path / "log.csv"), "--motor", "maxon-re30", "--out", str(tmp_path / "f.json")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("fatigue-pin: error: ")
    import re
    assert re.search(match, err)


def test_bad_motor_on_the_line_is_exit_2(tmp_path, capsys):
    (tmp_path / "log.csv").write_text("time_s,current_A,winding_C\n0,1,2\n")
    assert main(["calibrate-thermal", str(tmp_path / "log.csv"), "--motor", "maxon-re99", "--out", str(tmp_path / "f.json")]) == 2
    assert "ThermalCalibrationSettings.motor = 'maxon-re99': expected a motor preset name" in capsys.readouterr().err


def test_a_fit_is_a_motor_preset(tmp_path):
    t = np.arange(0.0, 2400.0, 4.0)
    R25 = motor_preset("maxon-re30").R25
    T = 25.0 + step_from_ambient(*TRUTH.values(), R25 * 4.0, t)[:, 0]
    fit = calibrate_thermal(ThermalLog(t, np.full_like(t, 2.0), T, "winding"), motor="maxon-re30", alpha=0.0, no_load_loss=0.0)
    path = fit.write_json(tmp_path / "fit.json")
    motor = motor_preset(str(path), gear_ratio=101.0)
    assert motor == dataclasses.replace(fit.motor, gear_ratio=101.0)
    (tmp_path / "bad.json").write_text('{"rms_K": 1}')
    with pytest.raises(ParameterError, match=r"bad\.json' has no 'motor' table: expected the output of"):
        motor_preset(str(tmp_path / "bad.json"))
