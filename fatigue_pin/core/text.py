"""Values as messages and files show them: plain Python numbers and lists, never numpy reprs.

A numpy scalar's repr is ``np.float64(0.5)`` (numpy >= 2) and an array's is ``array([...])``;
neither belongs in an error line, a report or a TOML file. :func:`plain` turns numpy scalars and
arrays (nested in tables, lists and tuples) into Python numbers and lists; :func:`shown` is the
repr of the plain value, for ``f"... = {shown(value)}: expected ..."``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["plain", "shown"]


def plain(value: Any) -> Any:
    """A copy of ``value`` made of plain Python values: numpy scalars as Python numbers (bools,
    strings), numpy arrays and tuples as (nested) lists; tables and lists copied item by item;
    anything else as it is."""
    if isinstance(value, dict):
        return {k: plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return plain(value.tolist())  # a 0-d array gives its scalar
    if isinstance(value, np.generic):
        return value.item()
    return value


def shown(value: Any) -> str:
    """``repr`` of ``value`` made plain (:func:`plain`): ``np.float64(0.5)`` -> ``0.5``,
    ``np.array([1, 2])`` -> ``[1, 2]``, ``(np.int64(1), 2)`` -> ``[1, 2]``; strings keep their quotes."""
    return repr(plain(value))
