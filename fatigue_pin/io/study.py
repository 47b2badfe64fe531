"""Studies as data: one TOML file says the model, the fatigue models, the task, the costs, the
transcription, the horizon and the solver (``docs/studies.md`` lists every key).

``Study.from_toml(text)`` / ``Study.from_file(path)`` read and validate a study (a ``.toml``
file, or an HDF5 result file whose run stores the study that produced it); ``study.to_toml()``
writes it back with every default made explicit; ``study.problem()``, ``study.transcription()``
and ``study.solver()`` build the objects of the API; :func:`run_study` runs it. Unknown keys,
wrong types and missing required keys are :class:`StudyError` naming the key and what was
expected.
"""

from __future__ import annotations

import copy
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from fatigue_pin.core.errors import FatiguePinError

HORIZONS = ("full", "sliding", "max-cycles")


class StudyError(FatiguePinError, ValueError):
    """A study file or table that cannot be used (unknown key, wrong type, missing key, ...)."""


# -- a small schema: key -> (type check, description, default or REQUIRED) -----------------------

REQUIRED = object()


def parse_changes(pairs: list[str]) -> dict[str, Any]:
    """Dotted ``KEY=VALUE`` pairs (``--set``) as :meth:`Study.replace` changes; values are read
    as TOML (numbers, booleans, strings, lists), and kept as text where they are not TOML."""
    out: dict[str, Any] = {}
    for pair in pairs:
        if "=" not in pair:
            raise StudyError(f"--set {pair!r}: expected KEY=VALUE, e.g. fatigue.S=0")
        key, text = pair.split("=", 1)
        try:
            out[key.strip()] = tomllib.loads(f"v = {text}")["v"]
        except tomllib.TOMLDecodeError:
            out[key.strip()] = text
    return out


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _is_int(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _is_str(v: Any) -> bool:
    return isinstance(v, str)


def _is_bool(v: Any) -> bool:
    return isinstance(v, bool)


def _is_numbers(v: Any) -> bool:
    return isinstance(v, list) and all(_is_number(x) for x in v)


def _is_strs(v: Any) -> bool:
    return isinstance(v, list) and all(_is_str(x) for x in v)


def _is_table(v: Any) -> bool:
    return isinstance(v, dict)


Check = tuple[Callable[[Any], bool], str, Any]

SCHEMA: dict[str, dict[str, Check]] = {
    "model": {
        "urdf": (_is_str, "a bundled model name, an example-robot-data name or a URDF path", REQUIRED),
        "gravity": (_is_numbers, "a list of 3 numbers (m/s^2)", None),
        "payload": (_is_table, "a table { frame, mass (kg), com (m), inertia (kg m^2) }", None),
    },
    "task": {
        "cycle_duration": (_is_number, "a duration in seconds > 0", REQUIRED),
        "intervals_per_cycle": (_is_int, "an integer >= 1", REQUIRED),
        "q_init": (_is_numbers, "a list of joint positions (rad or m), one per joint", None),
        "final_node_offset": (_is_int, "0 or -1", 0),
        "targets": (lambda v: isinstance(v, list) and all(_is_table(x) for x in v), "an array of tables [[task.targets]]", []),
        "ranges": (lambda v: isinstance(v, list) and all(_is_table(x) for x in v), "an array of tables [[task.ranges]]", []),
        "planes": (lambda v: isinstance(v, list) and all(_is_table(x) for x in v), "an array of tables [[task.planes]]", []),
    },
    "transcription": {
        "substeps": (_is_int, "an integer >= 1", 5),
        "integrator": (_is_str, "'rk4'", "rk4"),
        "scaling": (_is_bool, "true or false", True),
        "parallel": (_is_str, "'auto', 'serial', 'openmp' or 'thread'", "auto"),
        "expand": (_is_bool, "true or false", False),
        "torque_variable": (_is_bool, "true or false", True),
        "target_rows": (_is_bool, "true or false", False),
    },
    "horizon": {
        "kind": (_is_str, "'full', 'sliding' or 'max-cycles'", "full"),
        "cycles": (_is_int, "an integer number of cycles >= 1", 1),
        "advance": (_is_int, "an integer number of cycles >= 1", 1),
        "max_cycles": (_is_int, "an integer number of cycles >= 1", None),
        "end_tolerance": (_is_number, "a fraction of the joint ranges in [0, 1)", 0.01),
        "cyclic_end": (_is_bool, "true or false", False),
        "guess": (_is_str, "'rest', 'physical' or 'ik'", "rest"),
        "failure_iterations": (_is_number, "a multiple of the median window iterations >= 1", 10.0),
        "min_iterations": (_is_int, "an integer >= 0", 200),
        "warmup": (_is_int, "an integer >= 0", 3),
        "guess_fatigue": (_is_str, "'integrate' or 'copy'", "integrate"),
    },
    "solver": {
        "linear_solver": (_is_str, "an IPOPT linear solver name (e.g. 'mumps')", "mumps"),
        "tol": (_is_number, "a tolerance > 0", 1e-6),
        "constr_viol_tol": (_is_number, "a tolerance > 0", 1e-4),
        "max_iter": (_is_int, "an integer >= 0", 3000),
        "max_wall_time": (_is_number, "seconds > 0", None),
        "print_level": (_is_int, "an integer 0..12", 0),
        "compile": (_is_bool, "true or false", True),
        "compiler": (_is_str, "a C compiler command", "gcc"),
        "compiler_flags": (_is_strs, "a list of strings", ["-O3", "-march=native"]),
        "mu_init": (_is_number, "a barrier parameter > 0", 1.0),
        "perturb_dec_fact": (_is_number, "a factor in (0, 1)", 0.6),
        "ipopt": (_is_table, "a table of IPOPT options", {}),
        "compile_mode": (_is_str, "'library' (once per model) or 'nlp' (once per horizon)", "library"),
        "compile_jobs": (_is_int, "a number of compiler processes >= 1", None),
        "accept_acceptable": (_is_bool, "true or false", False),
    },
}
TARGET_KEYS: dict[str, Check] = {
    "joint": (_is_str, "a joint name", REQUIRED),
    "value": (_is_number, "a joint position (rad or m)", REQUIRED),
    "at": (_is_number, "a phase of the cycle in [0, 1)", 0.0),
    "tolerance": (_is_number, "a tolerance >= 0", 0.0),
}
FRAME_TARGET_KEYS: dict[str, Check] = {  # a target with `frame` (issue 13: Cartesian tasks)
    "frame": (_is_str, "a frame name of the model (a link or tool frame)", REQUIRED),
    "position": (_is_numbers, "3 numbers (m, world frame)", None),
    "rpy": (_is_numbers, "3 roll-pitch-yaw angles (rad, world frame)", None),
    "at": (_is_number, "a phase of the cycle in [0, 1)", 0.0),
    "tolerance": (_is_number, "a tolerance >= 0 (m)", 0.0),
    "shape": (_is_str, "'ball' or 'box'", "ball"),
    "angle_tolerance": (_is_number, "an angle in (0, pi] (rad)", 0.05),
}
PLANE_KEYS: dict[str, Check] = {
    "frame": (_is_str, "a frame name of the model (a link or tool frame)", REQUIRED),
    "normal": (_is_numbers, "3 numbers, not all 0 (world frame)", REQUIRED),
    "offset": (_is_number, "a distance (m): normal . p >= offset", REQUIRED),
    "at": (_is_number, "a phase of the cycle in [0, 1) (default: every node)", None),
}
PAYLOAD_KEYS: dict[str, Check] = {
    "frame": (_is_str, "a frame name of the model (a link or tool frame)", REQUIRED),
    "mass": (_is_number, "a mass >= 0 (kg)", REQUIRED),
    "com": (_is_numbers, "3 numbers (m, in the frame's axes)", [0.0, 0.0, 0.0]),
    "inertia": (_is_numbers, "6 numbers ixx, ixy, ixz, iyy, iyz, izz (kg m^2, about the com, frame axes)", None),
}


def _cartesian_tables(out: dict[str, Any]) -> None:
    """Fill and check the tables of Cartesian tasks and payloads (frame targets, planes,
    model.payload); a target table has either joint + value or frame + position / rpy."""
    targets = []
    for i, t in enumerate(out["task"]["targets"]):
        where = f"task.targets[{i}]"
        if isinstance(t, dict) and "frame" in t:
            t = {k: v for k, v in _fill(t, FRAME_TARGET_KEYS, where).items() if v is not None}
            if "position" not in t and "rpy" not in t:
                raise StudyError(f"missing key {where}.position: a frame target needs a position (3 numbers, m) and/or rpy (rad)")
            for key in ("position", "rpy"):
                if key in t and len(t[key]) != 3:
                    raise StudyError(f"{where}.{key} = {t[key]!r}: expected {FRAME_TARGET_KEYS[key][1]}")
            if t["shape"] not in ("ball", "box"):
                raise StudyError(f"{where}.shape = {t['shape']!r}: expected 'ball' or 'box'")
            if not 0 < t["angle_tolerance"] <= math.pi:
                raise StudyError(f"{where}.angle_tolerance = {t['angle_tolerance']!r}: expected an angle in (0, pi] (rad)")
        elif isinstance(t, dict) and "joint" not in t:
            raise StudyError(f"{where}: expected either joint + value (a joint target) or frame + position (a frame target)")
        else:
            t = _fill(t, TARGET_KEYS, where)
        targets.append(t)
    out["task"]["targets"] = targets
    planes = []
    for i, t in enumerate(out["task"]["planes"]):
        t = {k: v for k, v in _fill(t, PLANE_KEYS, f"task.planes[{i}]").items() if v is not None}
        if len(t["normal"]) != 3 or not any(t["normal"]):
            raise StudyError(f"task.planes[{i}].normal = {t['normal']!r}: expected {PLANE_KEYS['normal'][1]}")
        if "at" in t and not 0 <= t["at"] < 1:
            raise StudyError(f"task.planes[{i}].at = {t['at']!r}: expected a phase of the cycle in [0, 1)")
        planes.append(t)
    out["task"]["planes"] = planes
    if out["model"].get("payload") is not None:
        p = {k: v for k, v in _fill(out["model"]["payload"], PAYLOAD_KEYS, "model.payload").items() if v is not None}
        if p["mass"] < 0:
            raise StudyError(f"model.payload.mass = {p['mass']!r}: expected a mass >= 0 (kg)")
        if len(p["com"]) != 3:
            raise StudyError(f"model.payload.com = {p['com']!r}: expected {PAYLOAD_KEYS['com'][1]}")
        if "inertia" in p and len(p["inertia"]) != 6:
            raise StudyError(f"model.payload.inertia = {p['inertia']!r}: expected {PAYLOAD_KEYS['inertia'][1]}")
        out["model"]["payload"] = p


RANGE_KEYS: dict[str, Check] = {
    "joint": (_is_str, "a joint name", REQUIRED),
    "lower": (_is_number, "a joint position (rad or m)", REQUIRED),
    "upper": (_is_number, "a joint position (rad or m)", REQUIRED),
}
#: Values a key must take beyond its type (the message is the schema's description).
RANGES: dict[str, Callable[[Any], bool]] = {
    "model.gravity": lambda v: len(v) == 3,
    "task.cycle_duration": lambda v: v > 0,
    "task.intervals_per_cycle": lambda v: v >= 1,
    "task.final_node_offset": lambda v: v in (0, -1),
    "transcription.substeps": lambda v: v >= 1,
    "transcription.integrator": lambda v: v == "rk4",
    "transcription.parallel": lambda v: v in ("auto", "serial", "openmp", "thread"),
    "horizon.advance": lambda v: v >= 1,
    "horizon.guess": lambda v: v in ("rest", "physical", "ik"),
    "horizon.failure_iterations": lambda v: v >= 1,
    "horizon.min_iterations": lambda v: v >= 0,
    "horizon.warmup": lambda v: v >= 0,
    "horizon.guess_fatigue": lambda v: v in ("integrate", "copy"),
    "solver.tol": lambda v: v > 0,
    "solver.constr_viol_tol": lambda v: v > 0,
    "solver.max_iter": lambda v: v >= 0,
    "solver.max_wall_time": lambda v: v > 0,
    "solver.print_level": lambda v: 0 <= v <= 12,
    "solver.mu_init": lambda v: v > 0,
    "solver.perturb_dec_fact": lambda v: 0 < v < 1,
}
TARGET_RANGES: dict[str, Callable[[Any], bool]] = {"at": lambda v: 0 <= v < 1, "tolerance": lambda v: v >= 0}


def _check_ranges(out: dict[str, Any]) -> None:
    """Refuse values of the right type outside their range (a negative duration, a zero
    tolerance, ...), naming the key and what was expected."""
    for dotted, ok in RANGES.items():
        section, key = dotted.split(".")
        value = out[section].get(key)
        if value is not None and not ok(value):
            raise StudyError(f"{dotted} = {value!r}: expected {SCHEMA[section][key][1]}")
    for i, target in enumerate(out["task"]["targets"]):
        for key, ok in TARGET_RANGES.items():
            if not ok(target[key]):
                raise StudyError(f"task.targets[{i}].{key} = {target[key]!r}: expected {TARGET_KEYS[key][1]}")
    for i, rng in enumerate(out["task"]["ranges"]):
        if rng["lower"] > rng["upper"]:
            raise StudyError(f"task.ranges[{i}]: lower = {rng['lower']!r} > upper = {rng['upper']!r}; expected lower <= upper")


TOP_KEYS = ("name", "model", "fatigue", "task", "costs", "transcription", "horizon", "solver", "labels")


def _fill(table: Any, schema: dict[str, Check], where: str) -> dict[str, Any]:
    """Validate ``table`` against ``schema`` and return it with defaults filled in."""
    if not isinstance(table, dict):
        raise StudyError(f"{where} = {table!r}: expected a table")
    unknown = sorted(set(table) - set(schema))
    if unknown:
        raise StudyError(f"unknown key {where}.{unknown[0]}; expected one of {sorted(schema)}")
    out: dict[str, Any] = {}
    for key, (check, what, default) in schema.items():
        if key in table and table[key] is not None:  # None (Python only; TOML has no null): not given
            value = table[key]
            if value is not None and not check(value):
                raise StudyError(f"{where}.{key} = {value!r}: expected {what}")
            if _is_number(value) and not math.isfinite(float(value)):
                raise StudyError(f"{where}.{key} = {value!r}: expected a finite number ({what})")
            out[key] = value
        elif default is REQUIRED:
            raise StudyError(f"missing key {where}.{key}: expected {what}")
        else:
            out[key] = copy.deepcopy(default)
    return out


def _fatigue_table(table: Any, where: str = "fatigue") -> dict[str, Any]:
    """Validate a ``[fatigue]`` table (model kind, preset, parameters, per-joint overrides)."""
    from fatigue_pin.fatigue.models import FATIGUE_MODELS

    if not isinstance(table, dict):
        raise StudyError(f"{where} = {table!r}: expected a table")
    out = dict(table)
    kind = out.get("model", "xia")
    if not isinstance(kind, str) or kind not in FATIGUE_MODELS:
        raise StudyError(f"{where}.model = {kind!r}: expected one of {sorted(FATIGUE_MODELS)}")
    out["model"] = kind
    params = FATIGUE_MODELS[kind].param_names
    allowed = set(params) | {"model", "preset", "joints", "plus", "minus"}
    for key, value in out.items():
        if key not in allowed:
            raise StudyError(f"unknown key {where}.{key}; expected 'model', 'preset', 'joints' or a parameter of {kind!r}: {list(params)}")
        if key in params and (not _is_number(value) or not math.isfinite(float(value)) or value < 0):
            unit = FATIGUE_MODELS[kind].param_units[params.index(key)]
            raise StudyError(f"{where}.{key} = {value!r}: expected " + ("a finite rate >= 0 (1/s)" if unit == "1/s" else "a finite number >= 0"))
        if key == "preset" and not isinstance(value, str):
            raise StudyError(f"{where}.preset = {value!r}: expected a preset name or a JSON file path")
    if "joints" in out:
        if where != "fatigue":
            raise StudyError(f"{where}.joints: per-joint overrides only in [fatigue]")
        if not isinstance(out["joints"], dict):
            raise StudyError(f"fatigue.joints = {out['joints']!r}: expected a table of joint names")
        out["joints"] = {j: _fatigue_table(t, f"fatigue.joints.{j}") for j, t in out["joints"].items()}
    for half in ("plus", "minus"):
        if half in out:
            if where == "fatigue":
                raise StudyError(f"fatigue.{half}: per-half values only in [fatigue.joints.<joint>]")
            out[half] = _fatigue_table(out[half], f"{where}.{half}")
    return out


def _costs_table(table: Any) -> dict[str, Any]:
    from fatigue_pin.ocp.costs import COST_KINDS

    if not isinstance(table, dict):
        raise StudyError(f"costs = {table!r}: expected a table of name = weight")
    out: dict[str, Any] = {}
    for name, spec in table.items():
        if _is_number(spec):
            spec = {"weight": spec}
        if not isinstance(spec, dict):
            raise StudyError(f"costs.{name} = {spec!r}: expected a weight or a table {{ weight = ..., ... }}")
        spec = dict(spec)
        kind = spec.setdefault("kind", name)
        if not isinstance(kind, str) or kind not in COST_KINDS:
            raise StudyError(f"costs.{name}: cost kind {kind!r} is unknown; expected one of {sorted(COST_KINDS)}")
        if "weight" not in spec:
            raise StudyError(f"missing key costs.{name}.weight: expected a weight >= 0")
        w = spec["weight"]
        if not _is_number(w) or not math.isfinite(float(w)) or w < 0:
            raise StudyError(f"costs.{name}.weight = {w!r}: expected a finite weight >= 0")
        for key in spec:
            if key not in ("weight", "kind", "joints"):
                raise StudyError(f"unknown key costs.{name}.{key}; expected 'weight', 'kind' or 'joints'")
        if "joints" in spec and not _is_strs(spec["joints"]):
            raise StudyError(f"costs.{name}.joints = {spec['joints']!r}: expected a list of joint names")
        out[name] = spec
    return out


def normalise(data: dict[str, Any]) -> dict[str, Any]:
    """Validate a parsed study and fill every default (the form stored in result files)."""
    if not isinstance(data, dict):
        raise StudyError(f"study = {data!r}: expected a table")
    unknown = sorted(set(data) - set(TOP_KEYS))
    if unknown:
        raise StudyError(f"unknown key {unknown[0]!r}; a study has the tables {list(TOP_KEYS[1:])} and a 'name'")
    out: dict[str, Any] = {}
    name = data.get("name", "study")
    if not isinstance(name, str) or not name or "/" in name:
        raise StudyError(f"name = {name!r}: expected a non-empty string without '/'")
    out["name"] = name
    for section in ("model", "task", "transcription", "horizon", "solver"):
        if section not in data and section in ("model", "task"):
            raise StudyError(f"missing table [{section}]")
        out[section] = _fill(data.get(section, {}), SCHEMA[section], section)
    if "fatigue" not in data:
        raise StudyError("missing table [fatigue]: expected a fatigue model and its parameters (or a preset)")
    out["fatigue"] = _fatigue_table(data["fatigue"])
    out["costs"] = _costs_table(data.get("costs", {}))
    _cartesian_tables(out)  # joint and frame targets, planes, model.payload
    out["task"]["ranges"] = [_fill(t, RANGE_KEYS, f"task.ranges[{i}]") for i, t in enumerate(out["task"]["ranges"])]
    labels = data.get("labels", {})
    if not isinstance(labels, dict) or not all(isinstance(v, (str, int, float, bool)) for v in labels.values()):
        raise StudyError(f"labels = {labels!r}: expected a table of strings and numbers")
    out["labels"] = dict(labels)
    h = out["horizon"]
    if h["kind"] not in HORIZONS:
        raise StudyError(f"horizon.kind = {h['kind']!r}: expected one of {list(HORIZONS)}")
    if h["cycles"] < 1:
        raise StudyError(f"horizon.cycles = {h['cycles']!r}: expected an integer number of cycles >= 1")
    if h["max_cycles"] is not None and h["max_cycles"] < 1:
        raise StudyError(f"horizon.max_cycles = {h['max_cycles']!r}: expected an integer number of cycles >= 1")
    if h["kind"] == "sliding":
        if not 1 <= h["advance"] <= h["cycles"]:
            raise StudyError(f"horizon.advance = {h['advance']!r}: expected an integer in [1, cycles = {h['cycles']}]")
        if h["max_cycles"] is not None and h["max_cycles"] < h["cycles"]:
            raise StudyError(f"horizon.max_cycles = {h['max_cycles']!r}: expected at least the window, cycles = {h['cycles']}")
    if not 0 <= h["end_tolerance"] < 1:
        raise StudyError(f"horizon.end_tolerance = {h['end_tolerance']!r}: expected a fraction in [0, 1)")
    _check_ranges(out)
    _fill_placeholders(name, out)  # every placeholder names a key
    return out


# -- TOML output (the subset studies use) ---------------------------------------------------------


def _toml_value(v: Any) -> str:
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
    raise StudyError(f"cannot write {v!r} to TOML")


def _toml_key(k: str) -> str:
    return k if k.replace("_", "").replace("-", "").isalnum() else _toml_value(k)


def to_toml(data: dict[str, Any]) -> str:
    """TOML text of a normalised study (None values are left out)."""
    lines = [f"name = {_toml_value(data['name'])}", ""]

    def table(header: str, values: dict[str, Any]) -> None:
        lines.append(f"[{header}]")
        for k, v in values.items():
            if v is None or (isinstance(v, (list, dict)) and k in ("targets", "ranges", "planes", "joints")):
                continue
            lines.append(f"{_toml_key(k)} = {_toml_value(v)}")
        lines.append("")

    table("model", data["model"])
    fat = data["fatigue"]
    table("fatigue", {k: v for k, v in fat.items() if k != "joints"})
    for joint, sub in fat.get("joints", {}).items():
        table(f"fatigue.joints.{_toml_key(joint)}", sub)
    table("task", data["task"])
    for kind in ("targets", "ranges", "planes"):
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


# -- the study object ------------------------------------------------------------------------------


@dataclass(frozen=True)
class Study:
    """A validated study (the normalised table of a study file)."""

    data: dict

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Study:
        return cls(normalise(copy.deepcopy(data)))

    @classmethod
    def from_toml(cls, text: str, source: str = "study") -> Study:
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise StudyError(f"{source} is not valid TOML: {exc}") from None
        return cls.from_dict(data)

    @classmethod
    def from_file(cls, path: str | Path, run: str | None = None) -> Study:
        """A study from a ``.toml`` file, or from the run ``run`` of an HDF5 result file."""
        path = Path(path)
        if path.is_dir():
            raise StudyError(f"study file {str(path)!r} is a folder; expected a .toml study file or an HDF5 result file")
        if not path.exists():
            raise StudyError(f"study file not found: {str(path)!r}; expected a .toml study file or an HDF5 result file")
        if not path.is_file():  # a pipe (/dev/stdin, <(...)): read it once, as TOML
            try:
                data = path.read_bytes()
            except OSError as exc:
                raise StudyError(f"study file {str(path)!r} cannot be read ({exc.strerror}); expected a .toml study file") from None
            if data.startswith(b"\x89HDF"):
                raise StudyError(f"study {str(path)!r} is an HDF5 file read from a pipe; expected it as a file path")
            try:
                return cls.from_toml(data.decode(), repr(str(path)))
            except UnicodeDecodeError:
                raise StudyError(f"{str(path)!r} is neither a TOML study nor an HDF5 result file") from None
        head = path.read_bytes()[:8]
        if run is not None and not head.startswith(b"\x89HDF"):
            raise StudyError(f"run {run!r}: {str(path)!r} is a study file, not an HDF5 result file; a run is named only in a result file")
        if head.startswith(b"\x89HDF"):
            from fatigue_pin.io.results import read_run

            text = read_run(path, run).study
            if not text:
                raise StudyError(f"run {run!r} of {str(path)!r} stores no study (it was built in Python, not from a study)")
            return cls.from_toml(text, f"the study stored in {path}")
        try:
            text = path.read_text()
        except UnicodeDecodeError:
            raise StudyError(f"{str(path)!r} is neither a TOML study nor an HDF5 result file") from None
        return cls.from_toml(text, repr(str(path)))

    def to_toml(self) -> str:
        return to_toml(self.data)

    def replace(self, changes: dict[str, Any]) -> Study:
        """A copy with dotted keys changed, e.g. ``{"fatigue.S": 0.0, "horizon.kind": "full"}``."""
        data = copy.deepcopy(self.data)
        for dotted, value in changes.items():
            parts = dotted.split(".")
            node = data
            for p in parts[:-1]:
                if not isinstance(node, dict) or p not in node:
                    raise StudyError(f"study key {dotted!r} does not exist")
                node = node[p]
            node[parts[-1]] = value
        return Study.from_dict(data)

    @property
    def name(self) -> str:
        """The study's name with its ``{dotted.key}`` placeholders filled from the study, e.g.
        ``"curl_S{fatigue.S}"`` -> ``"curl_S10"`` (numbers written with ``%g``)."""
        return _fill_placeholders(self.data["name"], self.data)

    @property
    def horizon(self) -> dict[str, Any]:
        return self.data["horizon"]

    @property
    def labels(self) -> dict[str, Any]:
        return self.data["labels"]

    def run_name(self) -> str:
        """Default run name in result files: ``<horizon kind>/<name>`` (``full``, ``sliding``)."""
        kind = self.horizon["kind"]
        return f"{'full' if kind == 'max-cycles' else kind}/{self.name}"

    # -- building the API objects -------------------------------------------------------------

    def model(self):
        from fatigue_pin.robot.model import resolve_model

        m = self.data["model"]
        payload = None
        if m.get("payload") is not None:
            from fatigue_pin.robot.model import Payload

            p = m["payload"]
            payload = Payload(p["frame"], p["mass"], tuple(p.get("com", (0.0, 0.0, 0.0))), p.get("inertia"))
        return resolve_model(m["urdf"], gravity=m.get("gravity"), payload=payload)

    def fatigue_spec(self, model):
        """Fatigue models of every half, as :meth:`SignedTorqueActuators.from_model` takes them."""
        fat = self.data["fatigue"]
        base = _fatigue_model(fat, None)
        joints = fat.get("joints", {})
        unknown = [j for j in joints if j not in model.joint_names]
        if unknown:
            raise StudyError(f"fatigue.joints.{unknown[0]}: joint {unknown[0]!r} is not in model {model.name!r}; its joints are {list(model.joint_names)}")
        if not joints:
            return base
        spec = {}
        for j in model.joint_names:
            sub = joints.get(j)
            if sub is None:
                spec[j] = base
                continue
            both = _fatigue_model(sub, fat)
            plus = _fatigue_model(sub["plus"], {**fat, **{k: v for k, v in sub.items() if k not in ("plus", "minus")}}) if "plus" in sub else both
            minus = _fatigue_model(sub["minus"], {**fat, **{k: v for k, v in sub.items() if k not in ("plus", "minus")}}) if "minus" in sub else both
            spec[j] = (plus, minus)
        return spec

    def task(self):
        from fatigue_pin.ocp.task import FrameOrientation, FramePlane, FrameTarget, JointRange, JointTarget, Task

        t = self.data["task"]
        items = []
        for x in t["targets"]:
            if "frame" not in x:
                items.append(JointTarget(x["joint"], x["value"], x["at"], x["tolerance"]))
                continue
            if "position" in x:
                items.append(FrameTarget(x["frame"], x["position"], x["at"], x["tolerance"], x["shape"]))
            if "rpy" in x:
                items.append(FrameOrientation(x["frame"], x["rpy"], x["at"], x["angle_tolerance"]))
        items += [JointRange(x["joint"], x["lower"], x["upper"]) for x in t["ranges"]]
        items += [FramePlane(x["frame"], x["normal"], x["offset"], x.get("at")) for x in t.get("planes", [])]
        return Task(t["cycle_duration"], t["intervals_per_cycle"], tuple(items),
                    None if t.get("q_init") is None else tuple(t["q_init"]), t["final_node_offset"])

    def costs(self):
        from fatigue_pin.ocp.costs import cost_term
        from fatigue_pin.core.errors import ParameterError

        out = []
        for name, spec in self.data["costs"].items():
            options = {k: v for k, v in spec.items() if k not in ("weight", "kind")}
            try:
                out.append(cost_term(spec["kind"], float(spec["weight"]), name=name, **options))
            except ParameterError as exc:
                raise StudyError(f"costs.{name}: {exc}") from None
        return out

    def problem(self, model=None):
        """The :class:`~fatigue_pin.ocp.problem.Problem` of this study."""
        from fatigue_pin.ocp.problem import Problem

        model = model or self.model()
        return Problem.build(model, self.fatigue_spec(model), self.task(), self.costs())

    def transcription(self):
        from fatigue_pin.ocp.transcription import Transcription

        return Transcription(**self.data["transcription"])

    def solver(self, cache_dir: str | Path | None = None):
        from fatigue_pin.ocp.solver import SolverOptions

        s = dict(self.data["solver"])
        s["compiler_flags"] = tuple(s["compiler_flags"])
        return SolverOptions(**s, cache_dir=Path(cache_dir) if cache_dir else None)


def _fill_placeholders(text: str, data: dict[str, Any]) -> str:
    """``text`` with every ``{a.b}`` replaced by the study's value at dotted key ``a.b``."""
    import re

    def value(match: re.Match) -> str:
        node: Any = data
        for part in match.group(1).split("."):
            if not isinstance(node, dict) or part not in node:
                raise StudyError(f"name {text!r}: placeholder {{{match.group(1)}}} is not a key of the study")
            node = node[part]
        return f"{node:g}" if _is_number(node) else str(node)

    return re.sub(r"\{([A-Za-z0-9_.\-]+)\}", value, text)


def _fatigue_model(table: dict[str, Any], parent: dict[str, Any] | None):
    """A FatigueModel from a fatigue table: preset values, then the parent's and the table's own
    parameters (later wins)."""
    from fatigue_pin.core.errors import ParameterError
    from fatigue_pin.fatigue.models import FATIGUE_MODELS, fatigue_model

    kind = table.get("model", (parent or {}).get("model", "xia"))
    names = FATIGUE_MODELS[kind].param_names
    values: dict[str, float] = {}
    for source in (parent, table):
        if not source:
            continue
        if "preset" in source:
            values.update(_preset_values(source["preset"], kind))
        values.update({k: float(v) for k, v in source.items() if k in names})
    try:
        return fatigue_model(kind, **values)
    except ParameterError as exc:
        raise StudyError(f"fatigue: {exc}") from None


def _preset_values(name: str, kind: str) -> dict[str, float]:
    """Parameter values of a named preset or a calibrated JSON file (issue: presets)."""
    try:
        from fatigue_pin.fatigue import presets
    except ImportError:  # pragma: no cover - presets module not installed
        raise StudyError(f"fatigue.preset = {name!r}: no parameter presets are available") from None
    try:
        model = presets.preset(name)
    except FatiguePinError as exc:
        raise StudyError(f"fatigue.preset = {name!r}: {exc}") from None
    if model.kind != kind:
        raise StudyError(f"fatigue.preset = {name!r} is a {model.kind!r} preset; the study's fatigue model is {kind!r}")
    return model.as_dict()


def run_study(study: Study, out: str | Path | None = None, name: str | None = None, resume: bool = False,
              progress=None, cache_dir: str | Path | None = None):
    """Run a study with its horizon driver and write its run(s) to ``out``.

    ``progress`` is a :class:`~fatigue_pin.core.progress.Reporter` or a line callback (default quiet).
    Returns the driver's result: a :class:`~fatigue_pin.io.results.RunResult` (full, sliding) or a
    :class:`~fatigue_pin.drivers.search.SearchResult` (max-cycles).
    """
    from fatigue_pin.core.progress import as_reporter

    from fatigue_pin.drivers.full import solve_full
    from fatigue_pin.drivers.run import solution_to_run
    from fatigue_pin.drivers.search import max_repetitions
    from fatigue_pin.drivers.sliding import SlidingHorizon, SlidingSettings
    from fatigue_pin.io.results import ResultFile

    say = as_reporter(progress)
    if out is not None:  # before any work: a bad output path fails now, not after the solve
        from fatigue_pin.io.results import check_output

        check_output(out)
    name = study.run_name() if name is None else name
    from fatigue_pin.io.results import check_run_slot
    from fatigue_pin.drivers.run import check_run_name

    check_run_slot(out, name) if out is not None else check_run_name(name)  # nothing but a run of that name in its place
    problem = study.problem()
    tr, sol_opts, h = study.transcription(), study.solver(cache_dir), study.horizon
    text = study.to_toml()
    end = h["end_tolerance"] if h["cyclic_end"] else None  # the full horizons' end box
    if h["kind"] == "full":
        ocp, sol = solve_full(problem, h["cycles"], tr, sol_opts, guess=h["guess"], progress=say, end_tolerance=end)
        run = solution_to_run(ocp, sol, name, study=text, labels=study.labels)
        if out is not None:
            ResultFile(out).write(run)
        return run
    if h["kind"] == "sliding":
        sliding = SlidingSettings(window=h["cycles"], advance=h["advance"], max_cycles=h["max_cycles"],
                                  end_tolerance=h["end_tolerance"], failure_iterations=h["failure_iterations"],
                                  min_iterations=h["min_iterations"], warmup=h["warmup"], guess_fatigue=h["guess_fatigue"])
        runner = SlidingHorizon(problem, sliding, tr, sol_opts, guess=h["guess"], study=text, labels=study.labels, progress=say)
        return runner.run(ResultFile(out) if out is not None else None, name=name, resume=resume, progress=say)
    return max_repetitions(problem, tr, sol_opts, n_max=h["max_cycles"], guess=h["guess"], progress=say,
                           store=ResultFile(out) if out is not None else None,
                           name=name, study=text, labels=study.labels, resume=resume,
                           end_tolerance=end)
