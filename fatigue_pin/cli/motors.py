"""``fatigue-pin calibrate-thermal``: a sub-command over :mod:`fatigue_pin.motors.calibration`.

``cli.build_parser`` adds it with ``register(sub)``. Its options are None unless given: the
defaults, shown in the help, are the fields of
:class:`~fatigue_pin.motors.calibration.ThermalCalibrationSettings`. Bad input raises a
:class:`~fatigue_pin.core.errors.FatiguePinError` subclass, which ``cli.main`` prints as one line
(exit code 2).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from fatigue_pin.cli.options import given, option

__all__ = ["register"]

_SETTINGS = "fatigue_pin.motors.calibration:ThermalCalibrationSettings"


def _names(text: str) -> tuple[str, ...]:
    return tuple(x.strip() for x in text.split(",") if x.strip())


def _cmd_calibrate_thermal(args: argparse.Namespace) -> int:
    from fatigue_pin.motors.calibration import run_calibrate_thermal

    fit, path = run_calibrate_thermal(args.data, args.out, **given(args, motor="motor", fit="fit", T_ambient="ambient",
                                                                   alpha="alpha", no_load_loss="no_load_loss"))
    for k, v in fit.params.items():
        print(f"{k} = {v:.6g}")
    print(f"{fit.n} rows ({fit.node} temperature), RMS residual {fit.rms_K:.4g} K; {fit.message}")
    print(f"wrote {path}")
    return 0 if fit.success else 1


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``calibrate-thermal`` sub-command to ``fatigue-pin``'s sub-parsers."""
    p = subparsers.add_parser("calibrate-thermal",
                              help="fit a motor's R_wh, R_ha, tau_w, tau_m to a logged current and temperature (CSV); write JSON")
    p.add_argument("data", type=Path, help="CSV with time_s, current_A or torque_Nm, winding_C or housing_C")
    p.add_argument("--motor", required=True, help="motor preset (fatigue_pin.motors.presets.MOTOR_PRESETS): known values and start")
    p.add_argument("--out", type=Path, required=True, help="output parameter file (.json)")
    option(p, "--fit", type=_names, default_from=(_SETTINGS, "fit"),
           help="parameters fitted, comma-separated (default: all four from a winding log, R_wh,R_ha,tau_m from a housing log)")
    option(p, "--ambient", type=float, default_from=(_SETTINGS, "T_ambient"), help="ambient temperature (deg C; default the preset's)")
    option(p, "--alpha", type=float, default_from=(_SETTINGS, "alpha"), help="resistance temperature coefficient (1/K; default the preset's)")
    option(p, "--no-load-loss", type=float, default_from=(_SETTINGS, "no_load_loss"), help="no-load loss at the housing (W; default the preset's)")
    p.set_defaults(func=_cmd_calibrate_thermal)
