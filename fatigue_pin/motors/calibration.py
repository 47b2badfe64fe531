"""Fit a motor's thermal network (R_wh, R_ha, tau_w, tau_m) to a logged current and temperature.

Data: a CSV file (UTF-8, a byte-order mark allowed; separated by commas, or by ``;`` with decimal
commas, or by tabs) with columns

* ``time_s``: time (s), strictly increasing;
* ``current_A`` (motor current, A) or ``torque_Nm`` (joint torque, N m, turned into a current by
  the motor's gear and torque constant, :meth:`MotorParameters.current` at rest);
* ``winding_C`` or ``housing_C``: the logged temperature (deg C) of that node (a UR's RTDE
  ``joint_temperatures`` is likely a housing-like one).

Model of the log: the current of a row holds until the next row (zero-order hold); the log starts in
thermal equilibrium, both nodes at the first logged temperature; the motor's ``R25``, ``alpha``,
``no_load_loss`` and ambient temperature are known (the preset's, or given). Between rows the
network with ``R(T_w)`` is linear in the temperatures, so each step is exact: the matrix
exponential of the affine system (:func:`simulate`).

Fit: ``scipy.optimize.least_squares`` on the temperature residuals (K) over the logarithms of the
fitted parameters, from the preset's values. A housing temperature determines only three
combinations of the four parameters (its transfer function from the copper loss has three
coefficients), so a housing log fits ``R_wh``, ``R_ha``, ``tau_m`` with ``tau_w`` held at the
preset's, unless ``fit`` says otherwise (asking for all four from a housing log is an error).
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy.linalg import expm
from scipy.optimize import least_squares

from fatigue_pin.core.errors import CalibrationDataError, ParameterError
from fatigue_pin.core.files import atomic_write_bytes, check_output_file, csv_number, read_csv_table
from fatigue_pin.core.settings import check_fields, check_values, is_number, is_str, is_strs, replaced, setting
from fatigue_pin.motors.motor import REFERENCE_C, MotorParameters
from fatigue_pin.motors.presets import MOTOR_PRESETS, motor_preset

__all__ = ["ThermalLog", "ThermalCalibrationSettings", "ThermalFit", "THERMAL_PARAMETERS", "read_thermal_csv",
           "simulate", "calibrate_thermal", "run_calibrate_thermal"]

#: The parameters a fit can adjust.
THERMAL_PARAMETERS = ("R_wh", "R_ha", "tau_w", "tau_m")
#: Logged node -> its CSV column.
NODES = {"winding": "winding_C", "housing": "housing_C"}
_LOADS = ("current_A", "torque_Nm")


@dataclass(frozen=True)
class ThermalLog:
    """A logged series, one entry per row.

    Attributes:
        time_s: times (s), shape (n,), strictly increasing.
        current_A: motor current (A), shape (n,), held until the next row.
        temperature_C: the logged node's temperature (deg C), shape (n,).
        node: ``"winding"`` or ``"housing"``.
        source: where the data come from (a file name).
    """

    time_s: np.ndarray
    current_A: np.ndarray
    temperature_C: np.ndarray
    node: str
    source: str = ""

    def __post_init__(self) -> None:
        where = self.source or "thermal log"
        t, i, T = (np.asarray(x, dtype=float) for x in (self.time_s, self.current_A, self.temperature_C))
        if self.node not in NODES:
            raise CalibrationDataError(f"{where}: node {self.node!r}: expected one of {sorted(NODES)}")
        if not (t.ndim == 1 and t.shape == i.shape == T.shape and t.size >= 5):
            raise CalibrationDataError(f"{where}: {t.size} rows: expected at least 5 rows of time, current, temperature")
        for name, x in (("time_s", t), ("current", i), (NODES[self.node], T)):
            if not np.all(np.isfinite(x)):
                raise CalibrationDataError(f"{where}: {name} has a value that is not a finite number: expected numbers")
        if np.any(np.diff(t) <= 0):
            k = int(np.argmax(np.diff(t) <= 0)) + 2
            raise CalibrationDataError(f"{where}: row {k}: time_s = {float(t[k - 1])!r}: expected times strictly increasing")
        if np.ptp(T) <= 1e-9 * max(1.0, abs(T[0])):
            raise CalibrationDataError(f"{where}: {NODES[self.node]} never changes (all {float(T[0])!r} deg C): "
                                       "expected a temperature that rises or falls with the current")
        for name, x in (("time_s", t), ("current_A", i), ("temperature_C", T)):
            object.__setattr__(self, name, x)


def _one_of(header: list[str], names: tuple[str, ...], name: str) -> str:
    present = [h for h in names if h in header]
    if len(present) != 1:
        raise CalibrationDataError(f"{name}: columns {header}: expected time_s, one of {list(_LOADS)} and one of "
                                   f"{list(NODES.values())}")
    return present[0]


def read_thermal_csv(path: str | Path, motor: MotorParameters) -> ThermalLog:
    """Read and validate a thermal log (see the module docstring); ``motor`` turns a
    ``torque_Nm`` column into a current.

    Raises:
        CalibrationDataError: missing file or column, a bad value (naming the row and the column),
            times not increasing, a temperature that never changes.
    """
    p = Path(path)
    header, rows, delimiter = read_csv_table(p, "thermal data")
    if "time_s" not in header:
        raise CalibrationDataError(f"{p.name}: columns {header}: expected time_s, one of {list(_LOADS)} and one of "
                                   f"{list(NODES.values())}")
    load = _one_of(header, _LOADS, p.name)
    temp = _one_of(header, tuple(NODES.values()), p.name)
    columns: dict[str, list[float]] = {c: [] for c in ("time_s", load, temp)}
    for k, row in enumerate(rows, start=1):
        for c in columns:
            columns[c].append(csv_number(row.get(c, ""), delimiter, f"{p.name}: row {k}: {c}"))
    current = np.asarray(columns[load], dtype=float)
    if load == "torque_Nm":
        current = motor.current(current, 0.0)
    node = next(n for n, c in NODES.items() if c == temp)
    return ThermalLog(np.asarray(columns["time_s"]), current, np.asarray(columns[temp]), node, source=p.name)


def simulate(motor: MotorParameters, time_s: np.ndarray, current_A: np.ndarray,
             T0: tuple[float, float]) -> np.ndarray:
    """Temperatures ``(T_w, T_h)`` (deg C), shape (n, 2), at the times ``time_s`` (s, shape (n,))
    from ``T0`` at the first time, the current of each row (A) held until the next: exact steps of
    the network with ``R(T_w)`` (linear in the temperatures for a constant current)."""
    net = motor.network
    a, b, c = net.rates
    i2 = np.asarray(current_A, dtype=float)[:-1] ** 2
    h = np.diff(np.asarray(time_s, dtype=float))
    n = h.size
    M = np.zeros((n, 3, 3))
    M[:, 0, 0] = -a + motor.R25 * motor.alpha * i2 / net.C_w
    M[:, 0, 1] = a
    M[:, 1, 0] = b
    M[:, 1, 1] = -(b + c)
    M[:, 0, 2] = motor.R25 * (1.0 - motor.alpha * REFERENCE_C) * i2 / net.C_w
    M[:, 1, 2] = (motor.no_load_loss + motor.T_ambient / motor.R_ha) / net.C_h
    # logs hold few distinct (step, current) pairs: one matrix exponential per pair
    pairs, which = np.unique(np.column_stack([h, i2]), axis=0, return_inverse=True)
    first = np.array([int(np.argmax(which.ravel() == k)) for k in range(len(pairs))])
    E = expm(M[first] * h[first, None, None])[which.ravel()]
    out = np.empty((n + 1, 2))
    x = np.array([T0[0], T0[1], 1.0])
    out[0] = x[:2]
    for k in range(n):
        x = E[k] @ x
        out[k + 1] = x[:2]
    return out


def _fit_names(fit: tuple[str, ...] | None, node: str) -> tuple[str, ...]:
    if fit is None:
        return THERMAL_PARAMETERS if node == "winding" else ("R_wh", "R_ha", "tau_m")
    if node == "housing" and set(fit) == set(THERMAL_PARAMETERS):
        raise ParameterError("ThermalCalibrationSettings.fit = all four from a housing temperature: expected at most "
                             "three (a housing log determines three combinations; hold tau_w or R_wh)")
    return tuple(fit)


@dataclass(frozen=True)
class ThermalCalibrationSettings:
    """How :func:`calibrate_thermal` fits (the options of ``fatigue-pin calibrate-thermal``).

    Attributes:
        motor: the motor preset (a key of ``MOTOR_PRESETS``) that gives the known values and the start.
        fit: the parameters fitted (some of :data:`THERMAL_PARAMETERS`); None: all four from a
            winding log, ``R_wh, R_ha, tau_m`` from a housing log.
        T_ambient: ambient temperature during the log (deg C); None: the preset's.
        alpha: temperature coefficient of the resistance (1/K); None: the preset's.
        no_load_loss: no-load loss at the housing during the log (W); None: the preset's.
    """

    motor: str = setting(expected="a motor preset name (fatigue_pin.motors.presets.MOTOR_PRESETS)",
                         check=lambda v: is_str(v) and v in MOTOR_PRESETS)
    fit: tuple[str, ...] | None = setting(None, f"a non-empty list of some of {list(THERMAL_PARAMETERS)}, each once",
                                          lambda v: is_strs(v) and 0 < len(v) == len(set(v)) and set(v) <= set(THERMAL_PARAMETERS))
    T_ambient: float | None = setting(None, "a temperature (deg C)", is_number)
    alpha: float | None = setting(None, "a coefficient >= 0 (1/K)", lambda v: is_number(v) and v >= 0)
    no_load_loss: float | None = setting(None, "a power >= 0 (W)", lambda v: is_number(v) and v >= 0)

    def __post_init__(self) -> None:
        check_fields(self)


def _settings(settings: ThermalCalibrationSettings | None, changes: dict[str, Any]) -> ThermalCalibrationSettings:
    if settings is None:  # ``motor`` has no default
        check_values(ThermalCalibrationSettings, changes)
        if "motor" not in changes:
            raise ParameterError("ThermalCalibrationSettings.motor missing: expected a motor preset name")
        return ThermalCalibrationSettings(**changes)
    return replaced(ThermalCalibrationSettings, settings, changes)


@dataclass(frozen=True)
class ThermalFit:
    """The result of :func:`calibrate_thermal`.

    Attributes:
        motor: the motor with the fitted values.
        fitted: the names of the fitted parameters.
        rms_K: RMS temperature residual (K).
        node: the logged node.
        n: number of rows.
        success: whether the least-squares solver converged.
        message: the solver's message.
        source: the data's file name.
    """

    motor: MotorParameters
    fitted: tuple[str, ...]
    rms_K: float
    node: str
    n: int
    success: bool
    message: str
    source: str

    @property
    def params(self) -> dict[str, float]:
        """The fitted values by name."""
        return {k: getattr(self.motor, k) for k in self.fitted}

    def to_dict(self) -> dict[str, Any]:
        return {"motor": dataclasses.asdict(self.motor), "fitted": list(self.fitted), "rms_K": self.rms_K,
                "node": self.node, "rows": self.n, "success": self.success, "message": self.message,
                "source": f"fatigue_pin thermal calibration to {self.source or 'a thermal log'} ({self.node} temperature)",
                "method": "scipy.optimize.least_squares on the temperature (K) over log-parameters; exact zero-order-hold "
                          "steps of the two-node network with R(T_w); equilibrium at the first row"}

    def write_json(self, path: str | Path) -> Path:
        return atomic_write_bytes(Path(path), (json.dumps(self.to_dict(), indent=2) + "\n").encode())


def calibrate_thermal(log: ThermalLog, settings: ThermalCalibrationSettings | None = None, **changes: Any) -> ThermalFit:
    """Fit the thermal network of ``settings.motor`` to ``log`` (see the module docstring).

    Raises:
        ParameterError: bad settings, or all four parameters from a housing log.
    """
    settings = _settings(settings, changes)
    known = {k: getattr(settings, k) for k in ("T_ambient", "alpha", "no_load_loss") if getattr(settings, k) is not None}
    base = motor_preset(settings.motor, **known)
    names = _fit_names(settings.fit, log.node)
    col = 0 if log.node == "winding" else 1
    T0 = (float(log.temperature_C[0]),) * 2
    scale = float(np.ptp(log.temperature_C))

    def model(x: np.ndarray) -> MotorParameters:
        return dataclasses.replace(base, **{k: float(math.exp(v)) for k, v in zip(names, x)})

    def residuals(x: np.ndarray) -> np.ndarray:
        return (simulate(model(x), log.time_s, log.current_A, T0)[:, col] - log.temperature_C) / scale

    x0 = np.log([getattr(base, k) for k in names])
    sol = least_squares(residuals, x0, method="trf", xtol=1e-14, ftol=1e-14, gtol=1e-14, max_nfev=400)
    rms = float(np.sqrt(np.mean(sol.fun ** 2)) * scale)
    return ThermalFit(model(sol.x), names, rms, log.node, log.time_s.size, bool(sol.success), str(sol.message), log.source)


def run_calibrate_thermal(data_csv: str | Path, out_json: str | Path, settings: ThermalCalibrationSettings | None = None,
                          **changes: Any) -> tuple[ThermalFit, Path]:
    """Read ``data_csv``, fit (:func:`calibrate_thermal`), write ``out_json`` (settings and output
    checked first)."""
    settings = _settings(settings, changes)
    out = check_output_file(out_json, ".json")
    motor = motor_preset(settings.motor)
    log = read_thermal_csv(data_csv, motor)
    fit = calibrate_thermal(log, settings)
    return fit, fit.write_json(out)
