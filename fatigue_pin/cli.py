"""The ``fatigue-pin`` command: a thin layer over the Python API.

Each sub-command parses its arguments and calls one function of the package; no modelling or
solving happens here.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def _cmd_info(args: argparse.Namespace) -> int:
    from fatigue_pin.model import load_model

    model = load_model(args.urdf)
    print(model.summary())
    return 0


def _cmd_forward(args: argparse.Namespace) -> int:
    from fatigue_pin.forward import run_forward_studies

    result = run_forward_studies(args.out)
    print(result.table)
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="fatigue-pin",
        description="Predictive simulation of motion with actuator fatigue (Pinocchio + 3CC-S + CasADi).",
    )
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("info", help="print the model summary: joints, masses, bounds, holding torques")
    p.add_argument("--urdf", type=Path, default=None, help="URDF file (default: bundled arm26)")
    p.set_defaults(func=_cmd_info)

    p = sub.add_parser("forward", help="forward studies of the 3CC / 3CC-S fatigue model (paper section 2)")
    p.add_argument("--out", type=Path, required=True, help="output directory")
    p.set_defaults(func=_cmd_forward)

    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``fatigue-pin`` command."""
    from fatigue_pin.errors import FatiguePinError

    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except FatiguePinError as exc:
        print(f"fatigue-pin: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
