"""Studies as data: one TOML file says the model, the fatigue models, the task, the costs, the
transcription, the horizon and the solver (``docs/studies.md`` lists every key).

``Study.from_toml(text)`` / ``Study.from_file(path)`` read and validate a study (a ``.toml``
file, or an HDF5 result file whose run stores the study that produced it); ``study.to_toml()``
writes it back with every default made explicit; ``study.problem()``, ``study.transcription()``,
``study.solver()`` and ``study.horizon_settings()`` build the objects of the API; :func:`run_study`
runs it and returns a :class:`StudyResult`, whatever the horizon kind. Unknown keys, wrong types
and missing required keys are :class:`StudyError` naming the key and what was expected; the keys,
their defaults and their checks come from the classes each table configures
(:mod:`fatigue_pin.io.tables`, :mod:`fatigue_pin.io.schema`).
"""

from __future__ import annotations

import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any


from fatigue_pin.core.errors import FatiguePinError
from fatigue_pin.core.text import plain, shown
from fatigue_pin.io.schema import StudyError, build
from fatigue_pin.io.tables import SECTIONS, TASK_ARRAYS, fill_placeholders, normalise, task_table, to_toml

__all__ = ["Study", "StudyError", "StudyResult", "key_steps", "normalise", "parse_changes", "run_study", "set_key", "to_toml"]


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


#: One step of a dotted key: a name, then any indices (``targets[1]``, ``q_init[0]``).
_STEP = re.compile(r"([^.\[\]]+)((?:\[[^\[\]]*\])*)")


def key_steps(dotted: str) -> list[str | int]:
    """The steps of a dotted study key, names and array indices (from 0, as messages name the
    elements): ``"task.targets[1].tolerance"`` -> ``["task", "targets", 1, "tolerance"]``."""
    steps: list[str | int] = []
    for part in dotted.split("."):
        m = _STEP.fullmatch(part)
        if m is None:
            raise StudyError(f"study key {dotted!r} does not exist")
        steps.append(m.group(1))
        for index in re.findall(r"\[([^\[\]]*)\]", m.group(2)):
            if not re.fullmatch(r"[0-9]+", index):
                raise StudyError(f"study key {dotted!r}: index [{index}] is not an integer >= 0 (elements count from 0)")
            steps.append(int(index))
    return steps


def set_key(data: dict[str, Any], dotted: str, value: Any) -> None:
    """Set the dotted key ``dotted`` (:func:`key_steps`) of the study table ``data`` in place; every
    table and element on the way must exist (the last name may be new: the study's check names
    it if it is unknown)."""
    steps = key_steps(dotted)
    node: Any = data
    where = ""  # the key walked so far, as messages name it
    for i, step in enumerate(steps):
        last = i == len(steps) - 1
        if isinstance(step, int):
            if not isinstance(node, list):
                raise StudyError(f"study key {dotted!r}: {where} is not an array; it has no elements to index")
            if step >= len(node):
                count = {0: "no elements", 1: "1 element, [0]"}.get(len(node), f"{len(node)} elements, [0] to [{len(node) - 1}]")
                raise StudyError(f"study key {dotted!r}: index [{step}] is out of range; {where} has {count}")
            where += f"[{step}]"
        else:
            if not isinstance(node, dict) or (not last and step not in node):
                raise StudyError(f"study key {dotted!r} does not exist")
            where += f".{step}" if where else step
        if last:
            node[step] = value
        else:
            node = node[step]


# -- the study object ------------------------------------------------------------------------------


@dataclass(frozen=True)
class Study:
    """A validated study (the normalised table of a study file).

    Attributes:
        data: the normalised table (every default filled in).
        given: the dotted keys of the tables its source set before the defaults were filled in
            (``"solver"``, ``"solver.mu_init"``, ...; a study read from a result file stored
            every key), and those :meth:`replace` changed. Not part of the study's value: two
            studies of the same data are equal.
        stored: for a study of an OpenSim model (``model.osim``) read from a result file, the
            URDF text and the muscle file text its run stores (written from the model when it
            ran): :meth:`model` and :meth:`muscles` read them, not the ``.osim`` file, so that
            ``fatigue-pin rerun`` solves the run's model again, with or without the file. A change
            of a ``model`` key drops them. None otherwise.
    """

    data: dict
    given: frozenset[str] = field(default=frozenset(), compare=False, repr=False)
    stored: tuple[str, str] | None = field(default=None, compare=False, repr=False)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Study:
        """A study from a table (validated, every default filled). The one place values enter a
        study: numpy scalars and arrays become plain Python numbers and lists here, so that the
        study, its TOML and its job id are the same whichever type the caller passed."""
        return cls(normalise(plain(data)), _given_keys(data))

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

            stored_run = read_run(path, run)
            text = stored_run.study
            if not text:
                raise StudyError(f"run {run!r} of {str(path)!r} stores no study (it was built in Python, not from a study)")
            study = cls.from_toml(text, f"the study stored in {path}")
            if study.data["model"].get("osim") and stored_run.urdf:  # the model as it was read when the run was solved
                return cls(study.data, study.given, (stored_run.urdf, stored_run.muscles))
            return study
        try:
            text = path.read_text()
        except UnicodeDecodeError:
            raise StudyError(f"{str(path)!r} is neither a TOML study nor an HDF5 result file") from None
        return cls.from_toml(text, repr(str(path)))

    def to_toml(self) -> str:
        return to_toml(self.data)

    def replace(self, changes: dict[str, Any]) -> Study:
        """A copy with dotted keys changed, e.g. ``{"fatigue.S": 0.0, "horizon.kind": "full"}``;
        an element of an array is reached by its index from 0, as messages name it:
        ``{"task.targets[1].tolerance": 0.1}`` (:func:`set_key`)."""
        data = plain(self.data)  # a copy
        for dotted, value in changes.items():
            set_key(data, dotted, value)
        changed = {".".join(dotted.split(".")[:n]) for dotted in changes for n in range(1, dotted.count(".") + 2)}
        stored = None if "model" in changed else self.stored
        return Study(normalise(plain(data)), self.given | changed | _given_keys(plain(changes)), stored)

    def solver_defaults(self) -> str:
        """One line naming the settings in force that differ from IPOPT's defaults and that the
        study does not set (:func:`~fatigue_pin.ocp.solver.departures_in_force`), or ""."""
        from fatigue_pin.ocp.ipopt_defaults import departures_in_force, departures_line

        given = {key.split(".", 1)[1] for key in self.given if key.startswith("solver.")}
        warm = self.horizon["kind"] == "sliding" and bool(self.horizon.get("warm_start"))  # only windows warm-start
        return departures_line(departures_in_force(self.solver(), given, warm_start=warm))

    @property
    def name(self) -> str:
        """The study's name with its ``{dotted.key}`` placeholders filled from the study, e.g.
        ``"curl_S{fatigue.S}"`` -> ``"curl_S10"`` (numbers written with ``%g``)."""
        return fill_placeholders(self.data["name"], self.data)

    @property
    def horizon(self) -> dict[str, Any]:
        return self.data["horizon"]

    @property
    def labels(self) -> dict[str, Any]:
        return self.data["labels"]

    def run_name(self) -> str:
        """Default run name in result files: ``<horizon kind>/<name>`` (``full``, ``sliding``)."""
        return f"{self.horizon_settings().run_prefix}/{self.name}"

    # -- building the API objects -------------------------------------------------------------

    def model(self):
        """The :class:`~fatigue_pin.robot.model.RobotModel` of ``[model]`` (of the stored URDF
        text of an OpenSim model's run, :attr:`stored`)."""
        source = build(SECTIONS["model"], self.data["model"], "model")
        if self.stored is not None:
            from fatigue_pin.robot.model import load_model

            return load_model(Path(source.osim), source.gravity, source.payload, source.locked_joints, text=self.stored[0])
        return source.load()

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
        """The :class:`~fatigue_pin.ocp.task.Task` of ``[task]`` (its items built by :func:`~fatigue_pin.io.tables.task_table`)."""
        from fatigue_pin.ocp.task import Task

        values, items = task_table(self.data["task"])  # its own keys and the items, each checked
        return Task(**{k: v for k, v in values.items() if k not in TASK_ARRAYS}, items=items)  # TaskError: items against the intervals

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
        return Problem(model, self.actuators(model), self.task(), tuple(self.costs()))

    def actuation(self):
        """The :class:`~fatigue_pin.ocp.actuators.Actuation` of ``[actuators]``."""
        return build(SECTIONS["actuators"], self.data["actuators"], "actuators")

    def actuators(self, model):
        """The actuation layer of ``model`` (``[actuators] kind``): the
        :class:`~fatigue_pin.ocp.actuators.SignedTorqueActuators` with the fatigue models of
        ``[fatigue]`` and the passive joints and coupling of ``[actuators]``, or the
        :class:`~fatigue_pin.ocp.muscle_actuators.MuscleActuators` of ``[model] muscles``
        (:meth:`muscle_actuators`)."""
        from fatigue_pin.ocp.actuators import SignedTorqueActuators

        actuation = self.actuation()
        unknown = [j for j in actuation.passive if j not in model.joint_names]
        if unknown:
            raise StudyError(f"actuators.passive = {shown(list(actuation.passive))}: joint {unknown[0]!r} is not in model "
                             f"{model.name!r}; its joints are {list(model.joint_names)}")
        if actuation.kind == "muscles":
            return self.muscle_actuators(model)
        if actuation.kind == "motors":
            return self.motor_actuators(model)
        if self.data["fatigue"].get("muscles"):
            raise StudyError("fatigue.muscles: per-muscle fatigue models need muscles; expected [actuators] kind = \"muscles\"")
        return SignedTorqueActuators.from_model(model, self.fatigue_spec(model), actuation)

    def motor_actuators(self, model):
        """The :class:`~fatigue_pin.ocp.motor_actuators.MotorActuators` of ``model``: a motor on
        every joint but the passive ones (``actuators.passive``, or a zero effort limit), chosen by
        ``[motors]`` (:func:`~fatigue_pin.motors.study_table.motors_of`; without the table, the
        model's stand-ins)."""
        from fatigue_pin.motors.study_table import motors_of
        from fatigue_pin.ocp.motor_actuators import MotorActuators

        passive = set(self.actuation().passive)
        actuated = [j for j, hi in zip(model.joint_names, model.tau_upper) if j not in passive and hi > 0]
        try:
            table = self.data.get("motors", {})
            return MotorActuators.from_model(model, motors_of(table, model.joint_names, actuated, model.name),
                                             derate=bool(table.get("derate", False)))
        except FatiguePinError as exc:
            raise StudyError(str(exc)) from None

    def muscles(self):
        """The :class:`~fatigue_pin.muscles.muscle_set.MuscleSet` of ``[model] muscles``, or of the
        OpenSim model ``[model] osim`` (its muscles, written as a muscle file's text:
        :mod:`fatigue_pin.robot.osim`)."""
        from fatigue_pin.muscles.files import load_muscles, read_muscles

        key, source = self._muscle_source()
        if not source:
            raise StudyError('actuators.kind = "muscles": the model has no muscles; expected [model] muscles = a bundled muscle file '
                             '("arm26") or a muscle file path, or [model] osim = an OpenSim model with muscles')
        try:
            if key == "model.osim" and self.stored is not None and self.stored[1]:
                return read_muscles(self.stored[1], f"the muscles stored with the run of {source}")
            if key == "model.osim":
                imported = build(SECTIONS["model"], self.data["model"], "model").read_osim()
                if not imported.muscles:
                    raise StudyError(f'model.osim = {source!r}: actuators.kind = "muscles", but the OpenSim model has no muscles')
                return read_muscles(imported.muscles, str(imported.path))
            return load_muscles(source)
        except StudyError:
            raise
        except FatiguePinError as exc:
            raise StudyError(f"{key} = {source!r}: {exc}") from None

    def _muscle_source(self) -> tuple[str, str]:
        """The key that gives the muscles (``model.muscles`` or ``model.osim``) and its value."""
        model = self.data["model"]
        if model.get("osim"):
            return "model.osim", str(model["osim"])
        return "model.muscles", str(model.get("muscles", ""))

    def muscle_actuators(self, model):
        """The :class:`~fatigue_pin.ocp.muscle_actuators.MuscleActuators` of ``model``: the muscles
        of ``[model] muscles`` on its frames (:class:`~fatigue_pin.muscles.geometry.MuscleGeometry`),
        each with the fatigue model of ``[fatigue]`` (or of ``[fatigue.muscles.<muscle or group>]``),
        and residual torques of +-``actuators.residuals`` N m on every joint but the passive ones,
        fatigable with ``actuators.residual_fatigue``. Under the ``active`` coupling, residual
        torques that do not tire deliver their control (coupling ``observed``): only the muscles'
        force follows their active fraction."""
        import dataclasses

        import numpy as np

        from fatigue_pin.muscles.geometry import MuscleGeometry
        from fatigue_pin.muscles.polynomial_paths import PolynomialPaths
        from fatigue_pin.ocp.actuators import SignedTorqueActuators
        from fatigue_pin.ocp.muscle_actuators import MuscleActuators

        actuation = self.actuation()
        muscles = self.muscles()
        fat = self.data["fatigue"]
        base = _fatigue_model(fat, None)
        names = set(muscles.names) | {m.group for m in muscles.muscles if m.group}
        overrides = fat.get("muscles", {})
        unknown = [key for key in overrides if key not in names]
        if unknown:
            raise StudyError(f"fatigue.muscles.{unknown[0]}: {unknown[0]!r} is neither a muscle nor a group of "
                             f"{self._muscle_source()[1]!r}; its muscles are {list(muscles.names)}")
        # by muscle or group name, as MuscleActuators resolves them (a muscle's own wins over its group's)
        params = {**{m.name: base for m in muscles.muscles if m.name not in overrides and m.group not in overrides},
                  **{key: _fatigue_model(sub, fat) for key, sub in overrides.items()}}
        if fat.get("joints") and not (actuation.residuals > 0 and actuation.residual_fatigue):
            raise StudyError("fatigue.joints: with muscles, per-joint fatigue models are those of the residual torques; expected "
                             "actuators.residuals > 0 and actuators.residual_fatigue = true, or fatigue.muscles for the muscles")
        residuals = None
        if actuation.residuals > 0:
            n = len(model.joint_names)
            spec = self.fatigue_spec(model) if actuation.residual_fatigue else base.with_(F=0.0, R=0.0)
            own = actuation  # torques that never tire deliver their control beside 'active' muscles
            if actuation.coupling == "active" and not actuation.residual_fatigue:
                own = dataclasses.replace(actuation, coupling="observed")
            residuals = SignedTorqueActuators.from_limits(model.joint_names, -actuation.residuals * np.ones(n),
                                                          actuation.residuals * np.ones(n), spec, own)
        try:
            geometry = MuscleGeometry(model.pin_model, muscles)
            if actuation.paths == "polynomial":
                geometry = PolynomialPaths(geometry, tolerance=actuation.path_tolerance)
            return MuscleActuators(model.joint_names, muscles, geometry, params, actuation.coupling, residuals,
                                   actuation.activation_dynamics)
        except FatiguePinError as exc:
            key, source = self._muscle_source()
            raise StudyError(f"{key} = {source!r}: {exc}") from None

    def transcription(self):
        """The :class:`~fatigue_pin.ocp.transcription.Transcription` of ``[transcription]``."""
        return build(SECTIONS["transcription"], self.data["transcription"], "transcription")

    def solver(self, cache_dir: str | Path | None = None):
        """The :class:`~fatigue_pin.ocp.solver.SolverOptions` of ``[solver]``; ``cache_dir``: where
        compiled code is kept on this machine (not a key of the study)."""
        return build(SECTIONS["solver"], self.data["solver"], "solver", cache_dir=Path(cache_dir) if cache_dir else None)

    def horizon_settings(self):
        """The :class:`~fatigue_pin.drivers.horizon.Horizon` of ``[horizon]``."""
        return build(SECTIONS["horizon"], self.data["horizon"], "horizon")


def _given_keys(table: Any, prefix: str = "") -> frozenset[str]:
    """The dotted keys of ``table`` and of its tables within (not into arrays)."""
    if not isinstance(table, dict):
        return frozenset()
    keys: set[str] = set()
    for k, v in table.items():
        keys.add(f"{prefix}{k}")
        keys |= _given_keys(v, f"{prefix}{k}.")
    return frozenset(keys)


def _fatigue_model(table: dict[str, Any], parent: dict[str, Any] | None):
    """A FatigueModel from a fatigue table: preset values, then the parent's and the table's own
    parameters (later wins)."""
    from fatigue_pin.core.errors import ParameterError
    from fatigue_pin.fatigue.models import FATIGUE_MODELS, fatigue_model

    kind = table.get("model", (parent or {}).get("model", "xia"))
    names = FATIGUE_MODELS[kind].param_names + FATIGUE_MODELS[kind].option_names
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


@dataclass(frozen=True)
class StudyResult:
    """What running a study gives, whatever its horizon kind.

    Attributes:
        kind: the horizon kind that ran (``full``, ``sliding``, ``max-cycles``).
        run: the run, as stored in the output file: full: the solution (converged or not);
            sliding: the stitched run; max-cycles: the best converged run (None when no N
            converged, or when the search ran without an output file).
        repetitions: cycles achieved: full: the cycles of the horizon (see ``converged``);
            sliding: the cycles kept; max-cycles: the largest N that converged.
        converged: full: the solve converged; sliding: at least one window converged;
            max-cycles: some N converged.
        answered: the run reached its answer: a full horizon that converged; a sliding run and
            a search always do (their count of repetitions, 0 included, is the answer).
        objective: the run's objective (sliding: the sum of its cycle costs); NaN without a run.
        iterations: IPOPT iterations (sliding: as its run stores them, -1 if not; max-cycles:
            of every solve of the search).
        solve_time_s: IPOPT wall time (s) of the run (max-cycles: of every solve of the search).
        outcome: the outcome in one line (what ``fatigue-pin run`` prints).
        search: the search of max-cycles (every N tried, how each failure ended); None otherwise.
    """

    kind: str
    run: Any
    repetitions: int
    converged: bool
    answered: bool
    objective: float
    iterations: int
    solve_time_s: float
    outcome: str
    search: Any = None


@dataclass(frozen=True)
class _Job:
    """A study ready to run: its problem and settings, where and under which name it is written."""

    study: Study
    problem: Any
    horizon: Any
    transcription: Any
    solver: Any
    store: Any  # where the runs are written (a ResultFile), or None
    name: str
    resume: bool
    say: Any


def _run_full(job: _Job) -> StudyResult:
    from fatigue_pin.drivers.full import solve_full
    from fatigue_pin.drivers.run import solution_to_run

    h = job.horizon
    ocp, sol = solve_full(job.problem, h.cycles, job.transcription, job.solver, guess=h.guess, progress=job.say,
                          end_tolerance=h.end_box)
    run = solution_to_run(ocp, sol, job.name, study=job.study.to_toml(), labels=job.study.labels)
    if job.store is not None:
        job.store.write(run)
    outcome = "converged" if run.converged else f"NOT CONVERGED ({run.attrs['status']})"
    return StudyResult("full", run, run.n_cycles, run.converged, run.converged, float(run.attrs.get("objective", math.nan)),
                       int(run.attrs.get("iterations", -1)), float(run.attrs["wall_time_s"]), outcome)


def _run_sliding(job: _Job) -> StudyResult:
    from fatigue_pin.drivers.sliding import SlidingHorizon, ending

    runner = SlidingHorizon(job.problem, job.horizon.sliding_settings(), job.transcription, job.solver, guess=job.horizon.guess,
                            study=job.study.to_toml(), labels=job.study.labels, progress=job.say)
    run = runner.run(job.store, name=job.name, resume=job.resume, progress=job.say)
    a = run.attrs
    objective = float(run.cycle_costs.sum()) if run.cycle_costs.size else math.nan
    outcome = (f"{a['repetitions']} repetitions: {ending(run)} ({a['converged_windows']} windows converged, {a['wall_time_s']:.1f} s solving, "
               f"median real-time factor {a.get('median_real_time_factor', float('nan')):.2f})")
    return StudyResult("sliding", run, int(a["repetitions"]), run.converged, True, objective, int(a.get("iterations", -1)),
                       float(a["wall_time_s"]), outcome)


def _run_search(job: _Job) -> StudyResult:
    from fatigue_pin.drivers.search import max_repetitions

    h = job.horizon
    search = max_repetitions(job.problem, job.transcription, job.solver, n_max=h.max_cycles, guess=h.guess, progress=job.say,
                             store=job.store, name=job.name, study=job.study.to_toml(), labels=job.study.labels, resume=job.resume,
                             end_tolerance=h.end_box)
    run = search.run
    failed = ", ".join(f"{n}: {k}" for n, k in search.failures.items()) or "none"
    outcome = f"maximum repetitions: {search.max_cycles} (tried N = {shown([r['n_cycles'] for r in search.tried])}; failed: {failed})"
    return StudyResult("max-cycles", run, int(search.max_cycles), search.max_cycles > 0, True,
                       float(run.attrs.get("objective", math.nan)) if run is not None else math.nan,
                       int(sum(int(r["iterations"]) for r in search.tried)), float(sum(float(r["wall_time_s"]) for r in search.tried)),
                       outcome, search)


#: The driver of each horizon kind.
_RUNNERS = {"full": _run_full, "sliding": _run_sliding, "max-cycles": _run_search}


def run_study(study: Study, out: str | Path | None = None, name: str | None = None, resume: bool = False,
              progress=None, cache_dir: str | Path | None = None) -> StudyResult:
    """Run a study with its horizon driver and write its run(s) to ``out``.

    ``progress`` is a :class:`~fatigue_pin.core.progress.Reporter` or a line callback (default
    quiet); ``resume`` continues the sliding run or the search stored in ``out``; ``cache_dir``:
    where compiled code is kept. Before the solve, ``progress`` gets one line naming the solver
    settings in force that are not IPOPT's defaults and that the study does not set
    (:meth:`Study.solver_defaults`). Returns a :class:`StudyResult`, the same type for every kind.
    """
    from fatigue_pin.core.progress import as_reporter

    from fatigue_pin.io.results import ResultFile

    if out is not None:  # before any work: a bad output path fails now, not after the solve
        from fatigue_pin.io.results import check_output

        check_output(out)
    name = study.run_name() if name is None else name
    from fatigue_pin.drivers.run import check_run_name
    from fatigue_pin.io.results import check_run_slot

    check_run_slot(out, name) if out is not None else check_run_name(name)  # nothing but a run of that name in its place
    horizon = study.horizon_settings()
    job = _Job(study, study.problem(), horizon, study.transcription(), study.solver(cache_dir),
               ResultFile(out) if out is not None else None, name, resume, as_reporter(progress))
    defaults = study.solver_defaults()  # the study is valid: say which settings IPOPT would not have chosen
    if defaults:
        job.say(defaults)
    return _RUNNERS[horizon.kind](job)
