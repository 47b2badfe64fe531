"""``fatigue-pin endurance`` and ``fatigue-pin calibrate``: sub-commands over
:mod:`fatigue_pin.fatigue.endurance` and :mod:`fatigue_pin.fatigue.calibration`.

``cli.build_parser`` adds them with ``cli_fatigue.register(sub)``. Their options are None unless
given: the defaults, shown in the help, are the fields of
:class:`~fatigue_pin.fatigue.endurance_report.EnduranceSettings` and
:class:`~fatigue_pin.fatigue.calibration.CalibrationSettings` (:mod:`fatigue_pin.cli.options`).
Handlers check their output location before any work and raise :class:`~fatigue_pin.core.errors.FatiguePinError` subclasses on bad
input, which ``cli.main`` prints as one line (exit code 2).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from fatigue_pin.cli.options import check_options, given, option

__all__ = ["register"]

#: Where the options' defaults are: the settings classes of the two commands.
_ENDURANCE = "fatigue_pin.fatigue.endurance_report:EnduranceSettings"
_CALIBRATE = "fatigue_pin.fatigue.calibration:CalibrationSettings"


def _loads(text: str) -> list[float]:
    try:
        loads = [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        loads = []
    if not loads:
        raise argparse.ArgumentTypeError(f"--loads {text!r}: expected comma-separated fractions, e.g. 0.2,0.5,0.8")
    return loads


def _cycles(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        n = 0
    if n < 1:
        raise argparse.ArgumentTypeError(f"--max-cycles {text!r}: expected an integer number of cycles >= 1")
    return n


def _cmd_endurance(args: argparse.Namespace) -> int:
    from fatigue_pin.core.errors import ParameterError
    from fatigue_pin.core.files import check_output_dir
    from fatigue_pin.core.progress import Reporter
    from fatigue_pin.fatigue.endurance_report import EnduranceSettings, format_comparison, format_table, run_endurance

    check_output_dir(args.out)
    check_options(args, {k: (_ENDURANCE, k) for k in ("duty_cycle", "cycle_s")})
    settings = EnduranceSettings(**given(args, preset="preset", loads="loads", duty_cycle="duty_cycle", cycle_s="cycle_s",
                                         max_cycles="max_cycles"), **({"compare": False} if args.no_compare else {}))
    if settings.duty_cycle < 1.0 and settings.cycle_s is None:
        raise ParameterError(f"--duty-cycle {settings.duty_cycle}: expected --cycle-s (the cycle length, s) as well")
    tab, comparison, paths = run_endurance(args.out, settings, progress=Reporter.for_stream())
    print(format_table(tab))
    if comparison:
        print()
        print(format_comparison(comparison))
    for p in paths.values():
        print(f"wrote {p}")
    return 0


def _cmd_calibrate(args: argparse.Namespace) -> int:
    from fatigue_pin.fatigue.calibration import CalibrationSettings, check_output_file, run_calibrate

    check_output_file(args.out, ".json")
    check_options(args, {"ld": (_CALIBRATE, "LD"), "lr": (_CALIBRATE, "LR"), "confidence": (_CALIBRATE, "confidence")})
    settings = CalibrationSettings(**given(args, model="model", LD="ld", LR="lr", confidence="confidence", intermittent="intermittent"))
    result, paths = run_calibrate(args.data, args.out, settings)
    level = int(round(100 * result.confidence))
    for k, v in result.params.items():
        ci = result.ci[k]
        ci_text = "no CI" if ci is None else f"{level} % CI [{ci[0]:.6g}, {ci[1]:.6g}]"
        print(f"{k} = {v:.6g}  ({ci_text})")
    print(f"{result.data.n} rows, RMS log residual {result.rms_log:.4g}; {result.message}")
    for note in result.notes:
        print(f"note: {note}")
    for p in paths.values():
        print(f"wrote {p}")
    return 0 if result.success else 1


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``endurance`` and ``calibrate`` sub-commands to ``fatigue-pin``'s sub-parsers."""
    from fatigue_pin.fatigue.calibration import INTERMITTENT, MODELS
    from fatigue_pin.fatigue.endurance import PROGRESS_EVERY

    p = subparsers.add_parser("endurance", help="endurance times of isometric tasks for a fatigue preset, vs closed form and Frey-Law & Avin (2010)")
    option(p, "--preset", default_from=(_ENDURANCE, "preset"),
           help="preset name (see fatigue_pin.fatigue.presets.PRESETS) or a calibrated .json file")
    p.add_argument("--out", type=Path, required=True, help="output folder (endurance.h5, endurance.png)")
    option(p, "--loads", type=_loads, default_from=(_ENDURANCE, "loads"), help="target loads, comma-separated")
    option(p, "--duty-cycle", type=float, default_from=(_ENDURANCE, "duty_cycle"),
           help="fraction of each cycle at the target load (1: sustained)")
    option(p, "--cycle-s", type=float, default_from=(_ENDURANCE, "cycle_s"), help="cycle length (s) of an intermittent task")
    option(p, "--max-cycles", type=_cycles, default_from=(_ENDURANCE, "max_cycles"),
           help=f"most cycles simulated per load of an intermittent task (a progress line every {PROGRESS_EVERY})")
    p.add_argument("--no-compare", action="store_true", help="skip the per-joint comparison with Frey-Law & Avin (2010)")
    p.set_defaults(func=_cmd_endurance)

    p = subparsers.add_parser("calibrate", help="fit 3CC (F, R) or 3CC-r (F, R, r) to endurance data (CSV); write a JSON preset")
    p.add_argument("data", type=Path, help="CSV with target_load, endurance_time_s [, duty_cycle, cycle_s]")
    p.add_argument("--out", type=Path, required=True, help="output parameter file (.json); a .png figure is written beside it")
    option(p, "--model", default_from=(_CALIBRATE, "model"), choices=list(MODELS), help="model to fit")
    option(p, "--ld", type=float, default_from=(_CALIBRATE, "LD"), help="LD written with the result, used by --intermittent ode (1/s)")
    option(p, "--lr", type=float, default_from=(_CALIBRATE, "LR"), help="LR written with the result, used by --intermittent ode (1/s)")
    option(p, "--confidence", type=float, default_from=(_CALIBRATE, "confidence"), help="confidence level of the intervals")
    option(p, "--intermittent", default_from=(_CALIBRATE, "intermittent"), choices=list(INTERMITTENT),
           help="how intermittent rows are predicted: exact instant-activation cycles (closed-form) or the ODE with LD, LR (ode)")
    p.set_defaults(func=_cmd_calibrate)
