"""``fatigue-pin endurance`` and ``fatigue-pin calibrate``: sub-commands over
:mod:`fatigue_pin.fatigue.endurance` and :mod:`fatigue_pin.fatigue.calibration`.

``cli.build_parser`` adds them with ``cli_fatigue.register(sub)``. Handlers check their output
location before any work and raise :class:`~fatigue_pin.core.errors.FatiguePinError` subclasses on bad
input, which ``cli.main`` prints as one line (exit code 2).
"""

from __future__ import annotations

import argparse
from pathlib import Path

__all__ = ["register"]


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
    from fatigue_pin.core.progress import Reporter
    from fatigue_pin.fatigue.endurance import DEFAULT_LOADS
    from fatigue_pin.core.files import check_output_dir
    from fatigue_pin.fatigue.endurance_report import format_comparison, format_table, run_endurance

    check_output_dir(args.out)
    if args.duty_cycle < 1.0 and args.cycle_s is None:
        raise ParameterError(f"--duty-cycle {args.duty_cycle}: expected --cycle-s (the cycle length, s) as well")
    tab, comparison, paths = run_endurance(
        args.out, args.preset, DEFAULT_LOADS if args.loads is None else args.loads, args.duty_cycle, args.cycle_s,
        compare=not args.no_compare, max_cycles=args.max_cycles, progress=Reporter.for_stream(),
    )
    print(format_table(tab))
    if comparison:
        print()
        print(format_comparison(comparison))
    for p in paths.values():
        print(f"wrote {p}")
    return 0


def _cmd_calibrate(args: argparse.Namespace) -> int:
    from fatigue_pin.fatigue.calibration import check_output_file, run_calibrate

    check_output_file(args.out, ".json")
    result, paths = run_calibrate(args.data, args.out, model=args.model, LD=args.ld, LR=args.lr,
                                  confidence=args.confidence, intermittent=args.intermittent)
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
    p = subparsers.add_parser("endurance", help="endurance times of isometric tasks for a fatigue preset, vs closed form and Frey-Law & Avin (2010)")
    p.add_argument("--preset", default="frey-law-2012/elbow",
                   help="preset name (see fatigue_pin.fatigue.presets.PRESETS) or a calibrated .json file (default frey-law-2012/elbow)")
    p.add_argument("--out", type=Path, required=True, help="output folder (endurance.h5, endurance.png)")
    p.add_argument("--loads", type=_loads, default=None, help="target loads, comma-separated (default 0.1,...,0.9)")
    p.add_argument("--duty-cycle", type=float, default=1.0, help="fraction of each cycle at the target load (default 1: sustained)")
    p.add_argument("--cycle-s", type=float, default=None, help="cycle length (s) of an intermittent task")
    p.add_argument("--max-cycles", type=_cycles, default=10_000,
                   help="most cycles simulated per load of an intermittent task (default 10000; a progress line every 1000)")
    p.add_argument("--no-compare", action="store_true", help="skip the per-joint comparison with Frey-Law & Avin (2010)")
    p.set_defaults(func=_cmd_endurance)

    p = subparsers.add_parser("calibrate", help="fit 3CC (F, R) or 3CC-r (F, R, r) to endurance data (CSV); write a JSON preset")
    p.add_argument("data", type=Path, help="CSV with target_load, endurance_time_s [, duty_cycle, cycle_s]")
    p.add_argument("--out", type=Path, required=True, help="output parameter file (.json); a .png figure is written beside it")
    p.add_argument("--model", default="3cc", choices=["3cc", "3cc-r"], help="model to fit (default 3cc)")
    p.add_argument("--ld", type=float, default=10.0, help="LD written with the result, used by --intermittent ode (1/s, default 10)")
    p.add_argument("--lr", type=float, default=10.0, help="LR written with the result, used by --intermittent ode (1/s, default 10)")
    p.add_argument("--confidence", type=float, default=0.95, help="confidence level of the intervals (default 0.95)")
    p.add_argument("--intermittent", default="closed-form", choices=["closed-form", "ode"],
                   help="how intermittent rows are predicted: exact instant-activation cycles (default) or the ODE with LD, LR")
    p.set_defaults(func=_cmd_calibrate)
