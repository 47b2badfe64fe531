"""``fatigue-pin mpc``: a closed-loop run of a study against its plant (:mod:`fatigue_pin.io.mpc_study`).

``cli.build_parser`` adds it with ``cli.mpc.register(sub)``. The output location is checked
before any work; bad input is a :class:`~fatigue_pin.core.errors.FatiguePinError`, which
``cli.main`` prints as one line (exit code 2).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

__all__ = ["register", "run_closed_loop_study"]


def report_path(out: Path) -> Path:
    """Where the report of the run written to ``out`` goes: ``<out stem>_report.md`` beside it."""
    return out.with_name(f"{out.stem}_report.md")


def run_closed_loop_study(args: argparse.Namespace) -> int:
    """``fatigue-pin mpc`` (and ``fatigue-pin run`` of a closed-loop study): the closed loop, its
    report beside the result file, one line of outcome."""
    from fatigue_pin.core.progress import Reporter
    from fatigue_pin.drivers.mpc_run import estimation_error, report
    from fatigue_pin.io.mpc_study import MpcStudy, run_mpc
    from fatigue_pin.io.results import check_output
    from fatigue_pin.io.study import parse_changes

    check_output(args.out)
    study = MpcStudy.from_file(args.study, parse_changes(args.set))
    run = run_mpc(study, args.out, name=args.name, resume=args.resume, progress=Reporter.for_stream(sys.stdout),
                  cache_dir=args.cache)
    path = report_path(args.out)
    path.write_text(report(run))
    a = run.attrs
    print(f"{a['repetitions']} repetitions achieved by the plant ({run.n_cycles} whole cycles; estimator {a['estimator']}; "
          f"max |mf error| {abs(estimation_error(run)).max():.3f}; real-time factor median {a['real_time_factor_median']:.2f}, "
          f"max {a['real_time_factor_max']:.2f}); wrote {args.out} [{run.name}] and {path}")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``mpc`` sub-command to the parser's sub-commands ``sub``."""
    p = sub.add_parser("mpc", help="closed loop: re-plan the sliding window against a plant ([plant], [mpc] study tables); "
                                   "HDF5 after every re-plan, and a Markdown report")
    p.add_argument("study", type=Path, help="study file (.toml) with optional [plant], [plant.noise], [plant.disturbance], "
                                            "seed and [mpc] tables (docs/mpc.md)")
    p.add_argument("--out", type=Path, required=True, help="HDF5 result file (the report goes beside it, <stem>_report.md)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="change a key of the study, e.g. --set mpc.replan_every=5 --set plant.fatigue.F=0.9 (repeatable)")
    p.add_argument("--resume", action="store_true", help="continue the run stored in --out from its last re-plan")
    p.add_argument("--name", default=None, help="run name in the file (default: mpc/<study name>)")
    p.add_argument("--cache", type=Path, default=None, help="folder of compiled code (default ~/.cache/fatigue_pin)")
    p.set_defaults(func=run_closed_loop_study)
