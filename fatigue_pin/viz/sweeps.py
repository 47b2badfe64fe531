"""Figures of a sweep's output folder: repetitions against each swept key (``fatigue-pin plot DIR``).

One figure per swept key (:func:`independent_keys`): repetitions of every job against that key's
values, one line per combination of the other swept keys. Jobs that
ended in an error are left out; jobs that did not converge are drawn with open markers.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.ticker import MaxNLocator  # noqa: E402

from fatigue_pin.sweep.summary import read_summary  # noqa: E402

DPI = 150


def _label(value: Any) -> str:
    return f"{value:g}" if isinstance(value, float) else str(value)


def _key(value: Any) -> Any:
    """A hashable form of a summary value (lists and tables as text)."""
    return value if isinstance(value, (str, int, float, bool, type(None))) else repr(value)


def _save(fig: Any, out_dir: Path, stem: str) -> list[Path]:
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = [out_dir / f"{stem}.png", out_dir / f"{stem}.pdf"]
    fig.savefig(paths[0], dpi=DPI)
    fig.savefig(paths[1])
    plt.close(fig)
    return paths


def _determined(key: str, by: list[str], rows: list[dict[str, Any]]) -> bool:
    """Whether the value of ``key`` is the same in every row with the same values of ``by``."""
    seen: dict[tuple, Any] = {}
    for r in rows:
        combo = tuple(_key(r.get(k)) for k in by)
        if seen.setdefault(combo, _key(r.get(key))) != _key(r.get(key)):
            return False
    return True


def independent_keys(keys: list[str], rows: list[dict[str, Any]]) -> list[str]:
    """The swept keys to draw against: grid keys (those that vary within a case) first, then the
    case keys, leaving out constants and keys that follow from the keys kept before them (e.g. a
    label set together with a cost weight in each case)."""
    varying = [k for k in keys if len({_key(r.get(k)) for r in rows}) > 1]
    in_case = [k for k in varying if not _determined(k, ["case"], rows)]
    kept: list[str] = []
    for key in in_case + [k for k in varying if k not in in_case]:
        if not _determined(key, kept, rows):
            kept.append(key)
    return kept


def plot_sweep(folder: str | Path, out_dir: str | Path) -> list[Path]:
    """Write ``sweep_<key>.png`` / ``.pdf`` for every swept key of the sweep in ``folder``."""
    folder, out_dir = Path(folder), Path(out_dir)
    keys, _, rows = read_summary(folder)
    rows = [r for r in rows if r.get("status") in ("converged", "not converged")]
    swept = independent_keys(keys, rows)
    paths: list[Path] = []
    if not swept:  # one job, or every job the same on the swept keys: one bar per job
        fig, ax = plt.subplots(figsize=(6, 4), layout="constrained")
        ax.bar(range(len(rows)), [r.get("repetitions") or 0 for r in rows])
        ax.set_xticks(range(len(rows)), [str(r.get("job")) for r in rows], rotation=45, ha="right", fontsize=7)
        ax.set_ylabel("repetitions")
        ax.set_title(f"sweep {folder.name}")
        return _save(fig, out_dir, "sweep_jobs")
    for key in swept:
        others = [k for k in swept if k != key]
        values = [r.get(key) for r in rows]
        numeric = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)
        order = sorted({_key(v) for v in values}) if numeric else list(dict.fromkeys(_key(v) for v in values))
        position = {v: (float(v) if numeric else i) for i, v in enumerate(order)}
        groups: dict[tuple, list[dict[str, Any]]] = {}
        for r in rows:
            groups.setdefault(tuple(_key(r.get(k)) for k in others), []).append(r)
        fig, ax = plt.subplots(figsize=(7, 4.5), layout="constrained")
        for combo, members in groups.items():
            members = sorted(members, key=lambda r: position[_key(r.get(key))])
            x = [position[_key(r.get(key))] for r in members]
            y = [r.get("repetitions") for r in members]
            label = ", ".join(f"{k} = {_label(v)}" for k, v in zip(others, combo)) or None
            (line,) = ax.plot(x, y, "-", label=label)
            ok = [(a, b) for a, b, r in zip(x, y, members) if r.get("status") == "converged"]
            bad = [(a, b) for a, b, r in zip(x, y, members) if r.get("status") != "converged"]
            if ok:
                ax.plot(*zip(*ok), "o", color=line.get_color())
            if bad:
                ax.plot(*zip(*bad), "o", mfc="none", color=line.get_color())
        if not numeric:
            ax.set_xticks(range(len(order)), [_label(v) for v in order])
        ax.set_xlabel(key)
        ax.set_ylabel("repetitions")
        ax.yaxis.set_major_locator(MaxNLocator(integer=True))
        ax.set_title(f"repetitions against {key} (open markers: not converged)", fontsize=9)
        if len(groups) > 1:
            ax.legend(fontsize=7)
        paths += _save(fig, out_dir, f"sweep_{key.replace('.', '_').replace('/', '_')}")
    return paths
