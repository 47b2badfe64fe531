"""The summary of a sweep: ``summary.csv`` and ``summary.h5``, one row per job (``docs/sweeps.md``)."""

from __future__ import annotations

import csv
import json
import math
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterable

if TYPE_CHECKING:
    from fatigue_pin.sweep.plan import Job

#: Columns of the summary after the swept keys (``docs/sweeps.md``).
SUMMARY_COLUMNS = ("case", "job", "status", "repetitions", "objective", "iterations", "wall_time_s", "worker", "file", "run",
                   "reused", "error")
STATUSES = ("converged", "not converged", "error")
SUMMARY_FORMAT = "fatigue_pin.sweep/1"

# -- the summary -----------------------------------------------------------------------------------


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return "" if math.isnan(value) else repr(value)
    if isinstance(value, (list, dict)):
        return json.dumps(value)
    return str(value)


def summary_rows(jobs: Iterable[Job], rows: dict[str, dict[str, Any]]) -> tuple[list[str], list[dict[str, Any]]]:
    """Columns and rows of the summary (a job without a row yet has status ``pending``)."""
    jobs = list(jobs)
    keys: list[str] = []
    for job in jobs:
        keys += [k for k in job.values if k not in keys]
    table = []
    for job in jobs:
        row = {**rows.get(job.id, {"job": job.id, "status": "pending", "file": job.file}), "case": job.case}
        table.append({**{k: job.values.get(k) for k in keys}, **{c: row.get(c) for c in SUMMARY_COLUMNS}})
    return keys + list(SUMMARY_COLUMNS), table


def write_summary(out: str | Path, jobs: Iterable[Job], rows: dict[str, dict[str, Any]]) -> tuple[Path, Path]:
    """Write ``summary.csv`` and ``summary.h5`` (the same table; each written atomically)."""
    import h5py
    import numpy as np

    out = Path(out)
    columns, table = summary_rows(jobs, rows)
    csv_path, h5_path = out / "summary.csv", out / "summary.h5"
    tmp = out / ".summary.csv.tmp"
    with open(tmp, "w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(columns)
        for row in table:
            writer.writerow([_cell(row[c]) for c in columns])
    os.replace(tmp, csv_path)

    fields, data = [], []
    for c in columns:
        values = [row[c] for row in table]
        present = [v for v in values if v is not None]
        if present and all(isinstance(v, bool) for v in present) and len(present) == len(values):
            fields.append((c, "?"))
            data.append(values)
        elif present and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in present):
            fields.append((c, "f8"))
            data.append([math.nan if v is None else float(v) for v in values])
        else:
            fields.append((c, h5py.string_dtype()))
            data.append([_cell(v) for v in values])
    array = np.empty(len(table), dtype=np.dtype(fields))
    for (name, _), values in zip(fields, data):
        array[name] = values
    tmp = out / ".summary.h5.tmp"
    with h5py.File(tmp, "w") as h5:
        ds = h5.create_dataset("summary", data=array)
        ds.attrs["columns"] = columns
        ds.attrs["swept"] = columns[: len(columns) - len(SUMMARY_COLUMNS)]
        h5.attrs["format"] = SUMMARY_FORMAT
    os.replace(tmp, h5_path)
    return csv_path, h5_path


def _parse(text: str) -> Any:
    if text == "":
        return None
    if text in ("true", "false"):
        return text == "true"
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    if text[:1] in "[{":
        try:
            return json.loads(text)
        except ValueError:
            pass
    return text


def read_summary(out: str | Path) -> tuple[list[str], list[str], list[dict[str, Any]]]:
    """``(swept keys, columns, rows)`` of ``out/summary.csv`` (values typed back)."""
    path = Path(out) / "summary.csv"
    if not path.is_file():
        from fatigue_pin.sweep.plan import SweepError

        raise SweepError(f"{str(out)!r} holds no sweep summary (summary.csv)")
    with open(path, newline="") as fh:
        reader = csv.reader(fh)
        columns = next(reader, [])
        rows = [dict(zip(columns, (_parse(v) for v in line))) for line in reader]
    if SUMMARY_COLUMNS[0] not in columns:
        from fatigue_pin.sweep.plan import SweepError

        raise SweepError(f"{str(path)!r} is not a sweep summary: it has no {SUMMARY_COLUMNS[0]!r} column")
    return columns[: columns.index(SUMMARY_COLUMNS[0])], columns, rows
