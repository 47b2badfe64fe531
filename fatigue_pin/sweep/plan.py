"""Parameter sweeps: many studies from one base study, run on Dask (``docs/sweeps.md``).

This module reads sweep files into jobs; :mod:`~fatigue_pin.sweep.jobs` runs one job on a worker,
:mod:`~fatigue_pin.sweep.summary` writes and reads the summary, :mod:`~fatigue_pin.sweep.runner`
runs a sweep and :mod:`~fatigue_pin.sweep.cluster` starts or reaches the Dask cluster.

A sweep file (TOML) names a base study (``base = "studies/x.toml"``, relative to the sweep file,
or an inline ``[base]`` table) and the changes to make to it: a ``[grid]`` of dotted keys to
lists of values (every combination is a job) and/or ``[[cases]]`` (each a table of dotted keys to
values; with a grid too, every case is combined with every grid point)::

    base = "curl.toml"

    [grid]
    "fatigue.S" = [10.0, 0.0]
    "horizon.kind" = ["sliding", "max-cycles"]

    [[cases]]
    "labels.cost" = "fatigue-torque"

    [[cases]]
    "labels.cost" = "torque"
    "costs.fatigue.weight" = 0.0

:meth:`Sweep.jobs` resolves every job to a validated :class:`~fatigue_pin.io.study.Study` whose id is
a hash of its TOML text. :func:`run_sweep` runs the jobs that have no complete result file in the
output folder on a Dask client, one file ``<id>.h5`` per job written atomically by the worker, and
writes ``summary.csv`` and ``summary.h5`` (one row per job). :func:`sweep_command` is the
``fatigue-pin sweep`` command: a local cluster (one single-threaded worker process per core), an
existing scheduler, or SLURM through dask-jobqueue.
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Union

from fatigue_pin.core.errors import FatiguePinError, SweepError
from fatigue_pin.io.mpc_study import MpcStudy, is_closed_loop, is_closed_loop_table
from fatigue_pin.io.study import Study

#: A sweep's base and its jobs: a study, or a closed-loop study (its [plant], [mpc] tables and
#: seed are keys like the others, e.g. ``"plant.fatigue.F"``; :mod:`fatigue_pin.io.mpc_study`).
AnyStudy = Union[Study, MpcStudy]

#: Keys a sweep file may hold at its top level.
SWEEP_KEYS = ("base", "grid", "cases", "description")


# -- sweep files -----------------------------------------------------------------------------------


def _flatten(table: dict[str, Any], base: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """Dotted keys of a (nested) table: ``{"fatigue": {"S": 1}}`` -> ``{"fatigue.S": 1}``.

    TOML reads a bare dotted key ``fatigue.S = 1`` as nested tables and a quoted one
    ``"fatigue.S" = 1`` as one key; both end up as ``"fatigue.S"``. A table is split into its
    keys (merged into the base's table) where the base study has a table at that key; elsewhere
    it is one value (e.g. ``"fatigue.joints" = { elbow = { S = 0.0 } }`` adds a table).
    """
    out: dict[str, Any] = {}
    for key, value in table.items():
        dotted = f"{prefix}.{key}" if prefix else str(key)
        node: Any = base
        for part in dotted.split("."):
            node = node.get(part) if isinstance(node, dict) else None
        if isinstance(value, dict) and value and isinstance(node, dict):
            out.update(_flatten(value, base, dotted))
        else:
            out[dotted] = value
    return out


def study_id(text: str) -> str:
    """The id of a resolved study: the first 16 hex digits of the SHA-256 of its TOML text."""
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _show(values: dict[str, Any]) -> str:
    return ", ".join(f"{k} = {v!r}" for k, v in values.items()) or "the base study"


@dataclass(frozen=True)
class Job:
    """One study of a sweep.

    Attributes:
        index: position in the sweep (0-based; the order of :meth:`Sweep.jobs`).
        study: the resolved, validated study (a closed-loop one when the base is).
        values: the swept keys and their values for this job (case keys, then grid keys).
        case: index of the job's ``[[cases]]`` table (None in a sweep without cases).
        text: the study's TOML text (what the result file stores).
        id: :func:`study_id` of ``text``; the result file is ``<id>.h5``.
    """

    index: int
    study: AnyStudy
    values: dict[str, Any]
    text: str
    id: str
    case: int | None = None

    @property
    def file(self) -> str:
        return f"{self.id}.h5"


@dataclass
class Sweep:
    """A base study (or closed-loop study) and the changes that make its jobs."""

    base: AnyStudy
    grid: dict[str, list[Any]] = field(default_factory=dict)
    cases: list[dict[str, Any]] = field(default_factory=list)
    source: str = "sweep"
    description: str = ""

    @classmethod
    def from_file(cls, path: str | Path) -> Sweep:
        """Read a sweep file; a relative ``base`` path is taken from the sweep file's folder."""
        path = Path(path)
        if not path.is_file():
            raise SweepError(f"sweep file not found: {str(path)!r}")
        try:
            data = tomllib.loads(path.read_text())
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
            raise SweepError(f"{path}: not valid TOML: {exc}") from None
        return cls.from_dict(data, root=path.parent, source=str(path))

    @classmethod
    def from_toml(cls, text: str, root: str | Path = ".", source: str = "sweep") -> Sweep:
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise SweepError(f"{source}: not valid TOML: {exc}") from None
        return cls.from_dict(data, root=root, source=source)

    @classmethod
    def from_dict(cls, data: dict[str, Any], root: str | Path = ".", source: str = "sweep") -> Sweep:
        """A sweep from its parsed table; errors are :class:`SweepError` naming the file and key."""
        if not isinstance(data, dict):
            raise SweepError(f"{source}: expected a table")
        unknown = sorted(set(data) - set(SWEEP_KEYS))
        if unknown:
            raise SweepError(f"{source}: unknown key {unknown[0]!r}; a sweep file has {list(SWEEP_KEYS)}")
        base = cls._base(data.get("base"), Path(root), source)
        grid_table = data.get("grid", {})
        if not isinstance(grid_table, dict):
            raise SweepError(f"{source}: grid = {grid_table!r}: expected a table of dotted keys to lists of values")
        grid = _flatten(grid_table, base.data)
        for key, values in grid.items():
            if not isinstance(values, list):
                raise SweepError(f"{source}: [grid] {key} = {values!r}: expected a list of values")
            if not values:
                raise SweepError(f"{source}: [grid] {key} is an empty list; expected at least one value")
            for value in values:  # each value alone, so the message names it
                try:
                    base.replace({key: value})
                except FatiguePinError as exc:
                    raise SweepError(f"{source}: [grid] {key} = {value!r}: {exc}") from None
        raw_cases = data.get("cases", None)
        cases: list[dict[str, Any]] = []
        if raw_cases is not None:
            if not isinstance(raw_cases, list) or not all(isinstance(c, dict) for c in raw_cases):
                raise SweepError(f"{source}: cases must be an array of tables [[cases]]")
            if not raw_cases:
                raise SweepError(f"{source}: cases is an empty list; expected at least one [[cases]] table")
            for i, case in enumerate(raw_cases):
                flat = _flatten(case, base.data)
                if not flat:
                    raise SweepError(f"{source}: cases[{i}] is empty; expected dotted keys and values")
                both = sorted(set(flat) & set(grid))
                if both:
                    raise SweepError(f"{source}: cases[{i}] and [grid] both set {both[0]!r}")
                try:
                    base.replace(flat)
                except FatiguePinError as exc:
                    raise SweepError(f"{source}: cases[{i}]: {exc}") from None
                cases.append(flat)
        description = data.get("description", "")
        if not isinstance(description, str):
            raise SweepError(f"{source}: description = {description!r}: expected a string")
        sweep = cls(base, grid, cases, source, description)
        sweep.jobs()  # every combination must be a valid study, and no two the same
        return sweep

    @staticmethod
    def _base(base: Any, root: Path, source: str) -> AnyStudy:
        if base is None:
            raise SweepError(f"{source}: missing key 'base': expected a study file path or a [base] table")
        if isinstance(base, str):
            path = Path(base) if Path(base).is_absolute() else root / base
            if not path.is_file():
                raise SweepError(f"{source}: base study not found: {base!r} (looked for {str(path)!r})")
            try:
                return MpcStudy.from_file(path) if is_closed_loop(path) else Study.from_file(path)
            except FatiguePinError as exc:
                raise SweepError(f"{source}: base study {base!r}: {exc}") from None
        if isinstance(base, dict):
            try:
                return MpcStudy.from_dict(base) if is_closed_loop_table(base) else Study.from_dict(base)
            except FatiguePinError as exc:
                raise SweepError(f"{source}: [base]: {exc}") from None
        raise SweepError(f"{source}: base = {base!r}: expected a study file path or a [base] table")

    @property
    def keys(self) -> list[str]:
        """Every swept key: the cases' (in order of appearance), then the grid's."""
        keys: list[str] = []
        for case in self.cases:
            keys += [k for k in case if k not in keys]
        return keys + [k for k in self.grid if k not in keys]

    def jobs(self) -> list[Job]:
        """Every job: each case combined with each grid point (cases outer, grid in file order)."""
        points = [dict(zip(self.grid, combo)) for combo in itertools.product(*self.grid.values())]
        jobs: list[Job] = []
        seen: dict[str, Job] = {}
        for c, case in enumerate(self.cases or [{}]):
            for point in points:
                values = {**copy.deepcopy(case), **copy.deepcopy(point)}
                try:
                    study = self.base.replace(values) if values else self.base
                except FatiguePinError as exc:
                    raise SweepError(f"{self.source}: job {_show(values)}: {exc}") from None
                text = study.to_toml()
                job = Job(len(jobs), study, values, text, study_id(text), c if self.cases else None)
                if job.id in seen:
                    raise SweepError(f"{self.source}: jobs {_show(seen[job.id].values)} and {_show(values)} are the same study")
                seen[job.id] = job
                jobs.append(job)
        return jobs
