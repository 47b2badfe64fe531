"""The tables of a study file: :func:`normalise` validates a parsed study and fills every default,
:func:`to_toml` writes a normalised study back (docs/studies.md lists every key).

``[model]``, ``[actuators]``, ``[task]``, ``[transcription]``, ``[horizon]`` and ``[solver]`` are read by the classes
they configure (:mod:`fatigue_pin.io.schema`, :data:`SECTIONS`); the arrays of ``[task]`` by the
task items of :mod:`fatigue_pin.ocp.task`. ``[fatigue]`` is checked against the fatigue models'
parameter names, ``[costs]`` against the cost kinds.
"""

from __future__ import annotations

import math
import re
from typing import Any

from fatigue_pin.drivers.horizon import Horizon
from fatigue_pin.io.schema import StudyError, build, fill, is_toml_number, read_table, table_keys
from fatigue_pin.ocp.actuators import Actuation
from fatigue_pin.ocp.solver import SolverOptions
from fatigue_pin.ocp.task import FrameOrientation, FramePlane, FrameTarget, JointRange, JointTarget, StateTarget, Task
from fatigue_pin.ocp.transcription import Transcription
from fatigue_pin.robot.model import ModelSource
from fatigue_pin.core.errors import FatiguePinError
from fatigue_pin.core.text import plain, shown

#: The tables read by the class they configure (``[task]``: :func:`task_table`).
SECTIONS: dict[str, type] = {"model": ModelSource, "actuators": Actuation, "transcription": Transcription, "horizon": Horizon,
                             "solver": SolverOptions}
#: The keys at the top of a study.
TOP_KEYS = ("name", "model", "actuators", "fatigue", "motors", "task", "costs", "transcription", "horizon", "solver", "labels")
#: The arrays of tables of ``[task]``, after Task's own keys (its ``items`` field, built from them).
TASK_ARRAYS = ("targets", "ranges", "planes")
#: A frame target table names FrameOrientation's fields thus (beside FrameTarget's own keys).
ORIENTATION_RENAMES = {"rotation": "rpy", "tolerance": "angle_tolerance"}


# -- [task] -------------------------------------------------------------------------------------------


def _frame_target(t: dict[str, Any], where: str) -> tuple[dict[str, Any], list[Any]]:
    """A target table with ``frame``: a FrameTarget (with ``position``) and/or a FrameOrientation
    (with ``rpy``)."""
    parts = ((FrameTarget, {}, "position"), (FrameOrientation, ORIENTATION_RENAMES, "rpy"))
    known = set().union(*(table_keys(cls, renames=renames) for cls, renames, _ in parts))
    unknown = sorted(set(t) - known)
    if unknown:
        raise StudyError(f"unknown key {where}.{unknown[0]}; expected one of {sorted(known)}")
    if not any(needed in t for *_, needed in parts):
        raise StudyError(f"missing key {where}.position: a frame target needs a position (3 numbers, m) and/or rpy (rad)")
    out: dict[str, Any] = {}
    items = []
    for cls, renames, needed in parts:
        keys = table_keys(cls, renames=renames)
        values = fill(cls, {k: v for k, v in t.items() if k in keys}, where, renames=renames, optional=(needed,), drop_none=True)
        out.update(values)
        if needed in t:
            items.append(build(cls, values, where, renames=renames))
    return out, items


def _item_tables(kind: str, tables: Any) -> tuple[list[dict[str, Any]], list[Any]]:
    """The normalised tables of the array ``task.<kind>`` and the task items they build."""
    if not isinstance(tables, list) or not all(isinstance(t, dict) for t in tables):
        raise StudyError(f"task.{kind} = {shown(tables)}: expected an array of tables [[task.{kind}]]")
    out, items = [], []
    for i, t in enumerate(tables):
        where = f"task.{kind}[{i}]"
        if kind == "targets" and "frame" in t:
            values, built = _frame_target(t, where)
        elif kind == "targets" and "joint" not in t and "state" not in t:
            raise StudyError(f"{where}: expected either joint + value and/or velocity (a joint target), frame + position (a frame "
                             "target) or state + value (a state target)")
        else:
            cls = {"targets": StateTarget if "state" in t and "joint" not in t else JointTarget, "ranges": JointRange,
                   "planes": FramePlane}[kind]
            values, item = read_table(cls, t, where, drop_none=True)
            built = [item]
        out.append(values)
        items += built
    return out, items


def task_table(table: Any) -> tuple[dict[str, Any], tuple[Any, ...]]:
    """The normalised ``[task]`` table and its items, in the order of :class:`~fatigue_pin.ocp.task.Task`.

    Task's own keys are checked by Task (the phases of the items against the intervals when the
    whole task is built, :meth:`~fatigue_pin.io.study.Study.task`)."""
    if not isinstance(table, dict):
        raise StudyError(f"task = {shown(table)}: expected a table")
    own = table_keys(Task, skip=("items",))
    unknown = sorted(set(table) - set(own) - set(TASK_ARRAYS))
    if unknown:
        raise StudyError(f"unknown key task.{unknown[0]}; expected one of {sorted([*own, *TASK_ARRAYS])}")
    values = fill(Task, {k: v for k, v in table.items() if k in own}, "task", skip=("items",))
    build(Task, values, "task", skip=("items",))
    items: list[Any] = []
    for kind in TASK_ARRAYS:
        values[kind], built = _item_tables(kind, table.get(kind, []))
        items += built
    return values, tuple(items)


def key_tables() -> dict[str, dict[str, Any]]:
    """The keys of every table a study file may hold but ``[fatigue]``, ``[costs]`` and
    ``[labels]``, by table (``"task.targets (frame)"``, ...): docs/studies.md lists them (a test
    holds it to this)."""
    from fatigue_pin.robot.model import Payload

    frame = {**table_keys(FrameTarget), **table_keys(FrameOrientation, renames=ORIENTATION_RENAMES)}
    return {
        "model": table_keys(ModelSource), "model.payload": table_keys(Payload),
        "task": table_keys(Task, skip=("items",)), "task.targets (joint)": table_keys(JointTarget),
        "task.targets (frame)": frame, "task.targets (state)": table_keys(StateTarget), "task.ranges": table_keys(JointRange), "task.planes": table_keys(FramePlane),
        **{section: table_keys(SECTIONS[section]) for section in ("actuators", "transcription", "horizon", "solver")},
    }


# -- [fatigue] and [costs] --------------------------------------------------------------------------


def _fatigue_table(table: Any, where: str = "fatigue") -> dict[str, Any]:
    """Validate a ``[fatigue]`` table (model kind, preset, parameters, per-joint overrides)."""
    from fatigue_pin.fatigue.models import FATIGUE_MODELS

    if not isinstance(table, dict):
        raise StudyError(f"{where} = {shown(table)}: expected a table")
    out = dict(table)
    kind = out.get("model", "xia")
    if not isinstance(kind, str) or kind not in FATIGUE_MODELS:
        raise StudyError(f"{where}.model = {kind!r}: expected one of {sorted(FATIGUE_MODELS)}")
    out["model"] = kind
    params = FATIGUE_MODELS[kind].param_names
    allowed = set(params) | set(FATIGUE_MODELS[kind].option_names) | {"model", "preset", "joints", "muscles", "plus", "minus"}
    for key, value in out.items():
        if key not in allowed:
            raise StudyError(f"unknown key {where}.{key}; expected 'model', 'preset', 'joints', 'muscles' or a parameter of {kind!r}: "
                             f"{list(params)}")
        if key in params and (not is_toml_number(value) or not math.isfinite(float(value)) or value < 0):
            unit = FATIGUE_MODELS[kind].param_units[params.index(key)]
            raise StudyError(f"{where}.{key} = {shown(value)}: expected " + ("a finite rate >= 0 (1/s)" if unit == "1/s" else "a finite number >= 0"))
        if key in FATIGUE_MODELS[kind].option_names and not is_toml_number(value):
            raise StudyError(f"{where}.{key} = {shown(value)}: expected a number")
        if key == "preset" and not isinstance(value, str):
            raise StudyError(f"{where}.preset = {shown(value)}: expected a preset name or a JSON file path")
    if "joints" in out:
        if where != "fatigue":
            raise StudyError(f"{where}.joints: per-joint overrides only in [fatigue]")
        if not isinstance(out["joints"], dict):
            raise StudyError(f"fatigue.joints = {shown(out['joints'])}: expected a table of joint names")
        out["joints"] = {j: _fatigue_table(t, f"fatigue.joints.{j}") for j, t in out["joints"].items()}
    if "muscles" in out:  # per muscle or muscle group (names checked against the model's muscles, later)
        if where != "fatigue":
            raise StudyError(f"{where}.muscles: per-muscle overrides only in [fatigue]")
        if not isinstance(out["muscles"], dict):
            raise StudyError(f"fatigue.muscles = {shown(out['muscles'])}: expected a table of muscle or group names")
        out["muscles"] = {m: _fatigue_table(t, f"fatigue.muscles.{m}") for m, t in out["muscles"].items()}
    for half in ("plus", "minus"):
        if half in out:
            if where == "fatigue":
                raise StudyError(f"fatigue.{half}: per-half values only in [fatigue.joints.<joint>]")
            out[half] = _fatigue_table(out[half], f"{where}.{half}")
    return out


def _costs_table(table: Any) -> dict[str, Any]:
    from fatigue_pin.core.errors import ParameterError
    from fatigue_pin.ocp.costs import COST_KINDS, cost_term, kind_options

    if not isinstance(table, dict):
        raise StudyError(f"costs = {shown(table)}: expected a table of name = weight")
    out: dict[str, Any] = {}
    for name, spec in table.items():
        if is_toml_number(spec):
            spec = {"weight": spec}
        if not isinstance(spec, dict):
            raise StudyError(f"costs.{name} = {shown(spec)}: expected a weight or a table {{ weight = ..., ... }}")
        spec = dict(spec)
        kind = spec.setdefault("kind", name)
        if not isinstance(kind, str) or kind not in COST_KINDS:
            raise StudyError(f"costs.{name}: cost kind {kind!r} is unknown; expected one of {sorted(COST_KINDS)}")
        if "weight" not in spec:
            raise StudyError(f"missing key costs.{name}.weight: expected a weight >= 0")
        w = spec["weight"]
        if not is_toml_number(w) or not math.isfinite(float(w)) or w < 0:
            raise StudyError(f"costs.{name}.weight = {shown(w)}: expected a finite weight >= 0")
        options = kind_options(kind)
        for key in spec:
            if key not in ("weight", "kind", *options):
                terminal = ("; a terminal cost (at = \"end\") is a term of the state: posture, velocity, fatigue, state or frame"
                            if key == "at" else "")
                raise StudyError(f"unknown key costs.{name}.{key}; expected 'weight', 'kind' or an option of kind {kind!r}: "
                                 f"{list(options)}{terminal}")
        try:  # the options' values, checked by the kind itself (joint and state names: against the model, later)
            cost_term(kind, float(w), name=name if name.isidentifier() else None,
                      **{k: v for k, v in spec.items() if k not in ("weight", "kind")})
        except ParameterError as exc:
            raise StudyError(f"costs.{name}: {exc}") from None
        out[name] = spec
    return out


# -- the whole study --------------------------------------------------------------------------------


def normalise(data: dict[str, Any]) -> dict[str, Any]:
    """Validate a parsed study and fill every default (the form stored in result files)."""
    if not isinstance(data, dict):
        raise StudyError(f"study = {shown(data)}: expected a table")
    unknown = sorted(set(data) - set(TOP_KEYS))
    if unknown:
        raise StudyError(f"unknown key {unknown[0]!r}; a study has the tables {list(TOP_KEYS[1:])} and a 'name'")
    out: dict[str, Any] = {}
    name = data.get("name", "study")
    if not isinstance(name, str) or not name or "/" in name:
        raise StudyError(f"name = {name!r}: expected a non-empty string without '/'")
    out["name"] = name
    for section in ("model", "task"):
        if section not in data:
            raise StudyError(f"missing table [{section}]")
    out["model"] = read_table(ModelSource, data["model"], "model")[0]
    out["task"] = task_table(data["task"])[0]
    for section in ("actuators", "transcription", "horizon", "solver"):
        out[section] = read_table(SECTIONS[section], data.get(section, {}), section)[0]
    motors = out["actuators"]["kind"] == "motors"
    if "fatigue" not in data and not motors:  # a motor's capacity is its temperatures: [motors]
        raise StudyError("missing table [fatigue]: expected a fatigue model and its parameters (or a preset)")
    out["fatigue"] = _fatigue_table(data.get("fatigue", {}))
    if "motors" in data:
        from fatigue_pin.motors.study_table import check_motors_table

        if not motors:
            raise StudyError('[motors]: motors are an actuator kind; expected [actuators] kind = "motors", or no [motors] table')
        try:
            out["motors"] = check_motors_table(data["motors"])
        except FatiguePinError as exc:
            raise StudyError(str(exc)) from None
    out["costs"] = _costs_table(data.get("costs", {}))
    labels = data.get("labels", {})
    if not isinstance(labels, dict) or not all(isinstance(v, (str, int, float, bool)) for v in labels.values()):
        raise StudyError(f"labels = {shown(labels)}: expected a table of strings and numbers")
    out["labels"] = dict(labels)
    fill_placeholders(name, out)  # every placeholder names a key
    return out


def fill_placeholders(text: str, data: dict[str, Any]) -> str:
    """``text`` with every ``{a.b}`` replaced by the study's value at dotted key ``a.b`` (numbers
    written with ``%g``)."""

    def value(match: re.Match) -> str:
        node: Any = data
        for part in match.group(1).split("."):
            if not isinstance(node, dict) or part not in node:
                raise StudyError(f"name {text!r}: placeholder {{{match.group(1)}}} is not a key of the study")
            node = node[part]
        return f"{node:g}" if is_toml_number(node) else str(node)

    return re.sub(r"\{([A-Za-z0-9_.\-]+)\}", value, text)


# -- TOML output (the subset studies use) ---------------------------------------------------------


def _toml_value(v: Any) -> str:
    v = plain(v)  # numpy scalars and arrays as Python numbers and lists (never 'np.float64(...)')
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):  # a TOML basic string: backslash, quote and control characters escaped
        return '"' + "".join(c if c not in '\\"' and 31 < ord(c) != 127 else f"\\u{ord(c):04x}" for c in v) + '"'
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{_toml_key(k)} = {_toml_value(x)}" for k, x in v.items()) + " }"
    raise StudyError(f"cannot write {shown(v)} to TOML")


def _toml_key(k: str) -> str:
    return k if k.replace("_", "").replace("-", "").isalnum() else _toml_value(k)


def to_toml(data: dict[str, Any]) -> str:
    """TOML text of a normalised study (None values are left out)."""
    lines = [f"name = {_toml_value(data['name'])}", ""]

    def table(header: str, values: dict[str, Any]) -> None:
        lines.append(f"[{header}]")
        for k, v in values.items():
            if v is None or (isinstance(v, (list, dict)) and k in (*TASK_ARRAYS, "joints")):
                continue
            lines.append(f"{_toml_key(k)} = {_toml_value(v)}")
        lines.append("")

    table("model", data["model"])
    if "actuators" in data:
        table("actuators", data["actuators"])
    fat = data["fatigue"]
    table("fatigue", {k: v for k, v in fat.items() if k != "joints"})
    for joint, sub in fat.get("joints", {}).items():
        table(f"fatigue.joints.{_toml_key(joint)}", sub)
    if "motors" in data:
        table("motors", {k: v for k, v in data["motors"].items() if k != "joints"})
        for joint, sub in data["motors"].get("joints", {}).items():
            table(f"motors.joints.{_toml_key(joint)}", sub)
    table("task", data["task"])
    for kind in TASK_ARRAYS:
        for item in data["task"].get(kind, []):
            lines.append(f"[[task.{kind}]]")
            lines += [f"{k} = {_toml_value(v)}" for k, v in item.items()]
            lines.append("")
    table("costs", data["costs"])
    for section in ("transcription", "horizon", "solver"):
        table(section, data[section])
    if data.get("labels"):
        table("labels", data["labels"])
    return "\n".join(lines)
