"""Forward studies of the 3CC / 3CC-S fatigue model (paper section 2).

Writes ``forward_studies.h5`` and three PNG figures into ``--out`` and prints our numbers beside
the paper's. Usage::

    python experiments/forward_studies.py --out results/forward
"""

from __future__ import annotations

import argparse
from pathlib import Path

from fatigue_pin.paper.forward import run_forward_studies


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("results/forward"), help="output directory (default: results/forward)")
    args = parser.parse_args(argv)
    result = run_forward_studies(args.out)
    print(result.table)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
