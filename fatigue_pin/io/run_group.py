"""One run's group in an HDF5 result file: :func:`write_run_group` writes a :class:`RunResult` into a
group, :func:`read_run_group` reads it back (the layout: :mod:`fatigue_pin.io.results`, docs/results.md).
:mod:`fatigue_pin.io.results` owns the files (atomic rewrites, locks, layouts); this module the
datasets and attributes of one run."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from fatigue_pin.core.errors import ModelError, ResultFileError
from fatigue_pin.drivers.run import WINDOW_DTYPE, RunResult, joint_columns

#: Fatigue states of files written before the layout named them (Xia's model).
LEGACY_FATIGUE_STATES = ("ma", "mr", "mf")


def attr_value(value: Any) -> Any:
    """An HDF5 attribute as Python reads it back: text as str, a numpy scalar as a Python one."""
    value = value.decode() if isinstance(value, bytes) else value
    return value.item() if isinstance(value, np.generic) else value


def as_attr(value: Any) -> Any:
    if value is None:
        return "none"
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, Path):
        return str(value)
    return value


def write_run_group(group: h5py.Group, run: RunResult) -> None:
    for key, value in run.attrs.items():
        group.attrs[key] = as_attr(value)
    group.attrs["urdf"] = run.urdf
    group.attrs["study"] = run.study
    group.attrs["fatigue_states"] = list(run.fatigue)
    if run.muscles:
        group.attrs["muscles"] = run.muscles
    controls = "tau_halves" if run.unit_controls is None else "unit_controls"  # torque halves, or another kind's units
    units = {"t": "s", "q": "rad", "qdot": "rad/s", controls: "N m", "cycle_costs": "cost", "torque_limits": "N m", "cycle_wall_time_s": "s"}
    arrays = {n: getattr(run, n) for n in units if n != controls} | {controls: run.half_torques()} | dict(run.fatigue) | {"fatigued": run.fatigued}
    units |= {name: "1" for name in run.fatigue} | {"fatigued": "1"}
    for name, unit in units.items():
        data = np.asarray(arrays[name], dtype=float)
        ds = group.create_dataset(name, data=data, compression="gzip" if data.size > 1000 else None)
        ds.attrs["unit"] = unit
    joint_units = [run.joint_units(j) for j in range(len(run.joint_names))]
    for name, unit_of in (("q", "position"), ("qdot", "velocity")):
        group[name].attrs["joints"] = list(run.joint_names)
        _column_units(group[name], [getattr(u, unit_of) for u in joint_units])
    group["q"].attrs["joint_kinds"] = list(run.joint_kinds)
    for name in (*run.fatigue, "fatigued", "torque_limits", controls):
        group[name].attrs["actuators"] = list(run.actuator_names)
    for name in ("torque_limits", controls):
        _column_units(group[name], [run.unit_effort(h) for h in range(len(run.actuator_names))])
    group["cycle_costs"].attrs["terms"] = list(run.cost_terms)
    if run.windows is not None:
        group.create_dataset("windows", data=np.asarray(run.windows, dtype=WINDOW_DTYPE))
    if run.extras:
        extras = group.create_group("extras")
        for name, value in run.extras.items():
            data = np.asarray(value)
            extras.create_dataset(name, data=data, compression="gzip" if data.size > 1000 else None)


def _column_units(ds: h5py.Dataset, units: list[str]) -> None:
    """The per-column ``units`` attribute of ``ds`` (one per joint or half), and its ``unit``: the
    columns' common unit, or ``mixed`` when they differ."""
    ds.attrs["units"] = units
    ds.attrs["unit"] = units[0] if len(set(units)) == 1 else "mixed"


def _joint_kinds(group: h5py.Group, joints: tuple[str, ...]) -> tuple[str, ...]:
    """The kind of every joint of a stored run: the ``joint_kinds`` attribute of ``q``; for runs
    written before it, from the stored URDF (joints matched by name), else every joint revolute
    (all the models of those versions' studies but a hand-made URDF were)."""
    if "joint_kinds" in group["q"].attrs:
        return _str_list(group["q"].attrs["joint_kinds"])
    urdf = text_of(group.attrs.get("urdf", ""))
    if urdf.strip():
        from fatigue_pin.robot.model import joint_kinds_of_urdf

        try:
            kinds = joint_kinds_of_urdf(urdf)
        except ModelError:
            kinds = {}
        if all(j in kinds for j in joints):
            return tuple(kinds[j] for j in joints)
    return ("revolute",) * len(joints)


def _str_list(values: Any) -> tuple[str, ...]:
    return tuple(v.decode() if isinstance(v, bytes) else str(v) for v in values)


def read_run_group(group: h5py.Group, name: str) -> RunResult:
    states = _str_list(group.attrs["fatigue_states"]) if "fatigue_states" in group.attrs else LEGACY_FATIGUE_STATES
    controls = next((k for k in ("tau_halves", "unit_controls") if k in group), None)  # layouts 1-2: tau_plus, tau_minus
    missing = [k for k in ("t", "q", "qdot", *((controls,) if controls else ("tau_plus", "tau_minus")), *states, "cycle_costs",
                           "torque_limits") if k not in group]
    if missing:
        raise ResultFileError(f"run {name!r} lacks datasets {missing}; is it an OCP run written by fatigue_pin?")
    attrs = {k: attr_value(v) for k, v in group.attrs.items() if k not in ("urdf", "study", "fatigue_states", "muscles")}
    joints = _str_list(group["q"].attrs["joints"])
    if controls is None:
        tau_plus, tau_minus = group["tau_plus"][()], group["tau_minus"][()]
    else:  # a muscle run's residual halves follow its muscles
        muscles = json.loads(text_of(group.attrs.get("muscle_names", "")) or "[]")
        tau_plus, tau_minus = joint_columns(joints, _str_list(group[controls].attrs["actuators"]), group[controls][()], skip=muscles)
    unit_controls = group[controls][()] if controls == "unit_controls" else None
    run = RunResult(
        name=name,
        attrs=attrs,
        t=group["t"][()],
        q=group["q"][()],
        qdot=group["qdot"][()],
        tau_plus=tau_plus,
        tau_minus=tau_minus,
        fatigue={s: group[s][()] for s in states},
        cycle_costs=group["cycle_costs"][()],
        torque_limits=group["torque_limits"][()],
        joint_names=joints,
        joint_kinds=_joint_kinds(group, joints),
        actuator_names=_str_list(group[states[0]].attrs["actuators"]),
        cost_terms=_str_list(group["cycle_costs"].attrs["terms"]),
        cycle_wall_time_s=group["cycle_wall_time_s"][()] if "cycle_wall_time_s" in group else np.zeros(0),
        windows=group["windows"][()] if "windows" in group else None,
        urdf=str(group.attrs.get("urdf", "")),
        study=text_of(group.attrs.get("study", "")),
        fatigued=group["fatigued"][()] if "fatigued" in group else group["mf"][()],  # before "fatigued": Xia's mf
        extras={k: v[()] for k, v in group["extras"].items()} if "extras" in group else {},
        unit_controls=unit_controls,
        muscles=text_of(group.attrs.get("muscles", "")),
    )
    run.check_shapes()
    return run


def text_of(value: Any) -> str:
    return value.decode() if isinstance(value, bytes) else str(value)
