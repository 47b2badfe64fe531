"""The bad-input catalogue (docs/errors.md): every kind of bad input, on the command line, in
study files, URDFs, result files and the Python API, is refused with one line naming the bad
value, exit code 2, no traceback (``--debug`` shows it), and an existing result file left byte
for byte as it was.

``python tests/test_errors.py`` prints the catalogue's table with the messages as they are now
(paths shortened to ``TMP/``), the source of docs/errors.md.
"""

from __future__ import annotations

import copy
import re
import subprocess
import sys
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fatigue_pin.cli.main import main  # noqa: E402
from fatigue_pin.core.errors import FatiguePinError  # noqa: E402
from fatigue_pin.io.results import write_run, write_search  # noqa: E402
from fatigue_pin.io.study import to_toml  # noqa: E402
from conftest import make_run  # noqa: E402


def _base_study() -> dict[str, Any]:
    """The small curl (10 intervals, 2 substeps, uncompiled) as a parsed study file."""
    from fatigue_pin.paper.curl import curl_study

    study = curl_study("full", intervals_per_cycle=10, substeps=2, solver={"compile": False})
    return tomllib.loads(study.to_toml())


BASE = _base_study()


class Env:
    """Files of one case: a folder, an existing result file, and makers of bad inputs."""

    def __init__(self, tmp: Path):
        self.tmp = tmp
        self.existing = tmp / "existing.h5"  # every command that writes is pointed at it
        write_run(self.existing, make_run("full/a"))
        write_run(self.existing, make_run("full/b"))
        self.watched = [self.existing]

    def path(self, name: str) -> str:
        return str(self.tmp / name)

    def write(self, name: str, data: bytes | str) -> str:
        p = self.tmp / name
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(data if isinstance(data, bytes) else data.encode())
        return str(p)

    def study(self, mutate: Callable[[dict], Any] | None = None, extra: str = "", name: str = "study.toml") -> str:
        data = copy.deepcopy(BASE)
        if mutate is not None:
            mutate(data)
        return self.write(name, to_toml(data) + extra)

    def urdf(self, change: Callable[[str], str], name: str = "robot.urdf") -> str:
        from fatigue_pin.robot.model import bundled_urdf

        return self.write(name, change(bundled_urdf().read_text()))

    def osim(self, change: Callable[[str], str] | None = None, name: str = "arm26.osim") -> str:
        """tests/data/arm26.osim, with ``change(text) -> text`` applied, written in the case's folder."""
        text = (Path(__file__).resolve().parents[1] / "data" / "arm26.osim").read_text()
        return self.write(name, change(text) if change is not None else text)

    def sweep(self) -> str:
        """A sweep file of two jobs over the small curl."""
        self.write("base.toml", to_toml(BASE))
        return self.write("sweep.toml", 'base = "base.toml"\n[grid]\n"fatigue.S" = [0.0, 10.0]\n')

    def empty_result(self) -> str:
        import h5py

        p = self.tmp / "empty.h5"
        with h5py.File(p, "w") as h5:
            h5.attrs["format"] = "fatigue_pin.results/2"
        return str(p)

    def result_without_cycles(self) -> str:
        p = self.tmp / "failed.h5"
        write_run(p, make_run("sliding/x", cycles=0))
        return str(p)

    def result_cut_q(self) -> str:
        import h5py

        p = self.tmp / "cut_q.h5"
        write_run(p, make_run("full/a"))
        with h5py.File(p, "a") as h5:
            q = h5["full/a/q"][()]
            joints = h5["full/a/q"].attrs["joints"]
            del h5["full/a/q"]
            h5["full/a"].create_dataset("q", data=q[:-1]).attrs["joints"] = joints
        self.watched.append(p)
        return str(p)

    def result(self, name: str, layout: int | None = None, truncate: bool = False) -> str:
        import h5py

        p = self.tmp / name
        write_run(p, make_run("full/a"))
        write_search(p, "s", [{"n_cycles": 1, "converged": True, "status": "ok", "iterations": 3, "wall_time_s": 0.1}])
        if layout is not None:
            with h5py.File(p, "a") as h5:
                h5.attrs["format"] = f"fatigue_pin.results/{layout}"
        if truncate:
            data = p.read_bytes()
            p.write_bytes(data[: len(data) // 2])
        self.watched.append(p)
        return str(p)


def _banner_server() -> str:
    """The address of a server on 127.0.0.1 that sends an SSH banner to its one connection."""
    import socket
    import threading

    listener = socket.create_server(("127.0.0.1", 0))
    listener.settimeout(30)

    def serve() -> None:
        with listener:
            try:
                conn, _ = listener.accept()
            except OSError:
                return
            with conn:
                conn.sendall(b"SSH-2.0-OpenSSH_9.2p1\r\n")

    threading.Thread(target=serve, daemon=True).start()
    return f"tcp://127.0.0.1:{listener.getsockname()[1]}"


def _set(*keys_value):
    *keys, value = keys_value

    def mutate(data: dict) -> None:
        node = data
        for k in keys[:-1]:
            node = node[k]
        node[keys[-1]] = value

    return mutate


def _delete(*keys):
    def mutate(data: dict) -> None:
        node = data
        for k in keys[:-1]:
            node = node[k]
        del node[keys[-1]]

    return mutate


def _osim_muscles(path: str, ignore_wraps: bool = False):
    """The base study driven by the muscles of the OpenSim model ``path`` (its skeleton too)."""
    def mutate(data: dict) -> None:
        data["model"] = {"osim": path, "ignore_wraps": ignore_wraps}
        data["actuators"] = {"kind": "muscles", "residuals": 50.0}
        data["task"]["targets"] = [{**t, "joint": "r_elbow_flex", "value": min(t["value"], 2.0)} for t in data["task"]["targets"]]
        data["costs"] = {"activation": 1.0, "residual": 1.0}
        data.get("fatigue", {}).pop("joints", None)

    return mutate


def _sliding(window: int, max_cycles: int):
    def mutate(data: dict) -> None:
        data["horizon"].update(kind="sliding", cycles=window, max_cycles=max_cycles)

    return mutate


_ELBOW_LIMIT = '<limit lower="0.0" upper="3.141592653589793" effort="50.0" velocity="31.41592653589793"/>'


def _zero_mass(text: str) -> str:
    text = re.sub(r'<mass value="[0-9.eE+-]+"\s*/>', '<mass value="0"/>', text)
    return re.sub(r"<inertia [^/]*/>", '<inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/>', text)


@dataclass
class Case:
    """One kind of bad input.

    Attributes:
        id: short name; group: where the input enters; what: the input, for the catalogue.
        argv: the command line (from the case's Env), or None for a Python API case.
        api: for a Python API case, a call that must raise.
        message: a regular expression the error line must match (it names the bad value).
    """

    id: str
    group: str
    what: str
    message: str
    argv: Callable[[Env], list[str]] | None = None
    api: Callable[[Env], Any] | None = None


def _motors(**fields: Any) -> Callable[[dict], None]:
    """The study's joints driven by maxon RE 30 motors, with ``fields`` in [motors]."""
    def mutate(data: dict) -> None:
        data["actuators"]["kind"] = "motors"
        data["motors"] = {"preset": "maxon-re30", **fields}

    return mutate


def _run(study: Callable[[Env], str]) -> Callable[[Env], list[str]]:
    return lambda e: ["run", study(e), "--out", str(e.existing)]


CLI, PATHS, URDF, STUDY, API, FILES = "command line", "paths", "URDF", "study file", "Python API", "result files"
FATIGUE, SWEEP, OSIM = "fatigue data", "sweeps", "OpenSim models"

CASES: list[Case] = [
    # -- the command line ----------------------------------------------------------------------
    Case("unknown-command", CLI, "an unknown command", r"invalid choice: 'frobnicate'", lambda e: ["frobnicate"]),
    Case("not-an-integer", CLI, "`solve full --cycles abc`", r"argument --cycles: invalid int value: 'abc'",
         lambda e: ["solve", "full", "--cycles", "abc", "--out", str(e.existing)]),
    Case("bad-choice", CLI, "`--cost speed`", r"argument --cost: invalid choice: 'speed'",
         lambda e: ["solve", "full", "--cost", "speed", "--out", str(e.existing)]),
    Case("missing-option", CLI, "`solve full` without `--out`", r"required: --out", lambda e: ["solve", "full"]),
    Case("zero-cycles", CLI, "`solve full --cycles 0`", r"--cycles 0: expected an integer number of cycles >= 1",
         lambda e: ["solve", "full", "--cycles", "0", "--no-compile", "--out", str(e.existing)]),
    Case("negative-stabiliser", CLI, "`--stabilization -1`", r"S = -1.0: expected a finite rate >= 0",
         lambda e: ["solve", "full", "-S", "-1", "--out", str(e.existing)]),
    Case("nan-stabiliser", CLI, "`--stabilization nan`", r"S = nan: expected a finite rate >= 0",
         lambda e: ["solve", "full", "-S", "nan", "--out", str(e.existing)]),
    Case("window-longer-than-run", CLI, "`solve sliding --window 4 --max-cycles 2`",
         r"horizon.max_cycles = 2: expected at least the window, cycles = 4",
         lambda e: ["solve", "sliding", "--window", "4", "--max-cycles", "2", "--out", str(e.existing)]),
    Case("advance-beyond-window", CLI, "`solve sliding --window 2 --advance 3`", r"horizon.advance = 3",
         lambda e: ["solve", "sliding", "--window", "2", "--advance", "3", "--out", str(e.existing)]),
    Case("unknown-linear-solver", CLI, "`solve full --linear-solver foo`",
         r"solver.linear_solver = 'foo': not a valid IPOPT setting; expected one of \['ma27', 'ma57'",
         lambda e: ["solve", "full", "--linear-solver", "foo", "--no-compile", "--out", str(e.existing)]),
    Case("n-max-zero", CLI, "`max-cycles --n-max 0`", r"--n-max 0: expected an integer number of cycles >= 1",
         lambda e: ["max-cycles", "--n-max", "0", "--out", str(e.existing)]),
    Case("negative-max-iter", CLI, "`--max-iter -1`", r"solver.max_iter = -1: expected an integer >= 0",
         lambda e: ["solve", "full", "--max-iter", "-1", "--out", str(e.existing)]),
    Case("set-without-value", CLI, "`run --set fatigue.S`", r"--set 'fatigue.S': expected KEY=VALUE",
         lambda e: ["run", e.study(), "--set", "fatigue.S", "--out", str(e.existing)]),
    Case("set-unknown-key", CLI, "`run --set nosuch.key=1`", r"study key 'nosuch.key' does not exist",
         lambda e: ["run", e.study(), "--set", "nosuch.key=1", "--out", str(e.existing)]),
    Case("set-index-out-of-range", CLI, "`run --set task.targets[9].value=1` (a study with 2 targets)",
         r"study key 'task.targets\[9\].value': index \[9\] is out of range; task.targets has 2 elements, \[0\] to \[1\]",
         lambda e: ["run", e.study(), "--set", "task.targets[9].value=1", "--out", str(e.existing)]),
    Case("cycle-out-of-range", CLI, "`replay --cycle 99` of a 2-cycle run", r"--cycle 99: run 'full/a' has cycles 1 to 2",
         lambda e: ["replay", str(e.existing), "--run", "full/a", "--cycle", "99", "--html", e.path("r.html")]),
    Case("zero-jobs", CLI, "`reproduce --jobs 0`", r"--jobs 0: expected a number of worker processes >= 1",
         lambda e: ["reproduce", "--jobs", "0", "--out", e.path("reproduce")]),
    # -- paths -----------------------------------------------------------------------------------
    Case("out-unwritable", PATHS, "`--out /proc/x.h5` (a folder nobody can write to)", r"output folder '/proc' is not writable",
         lambda e: ["solve", "sliding", "--out", "/proc/x.h5"]),
    Case("out-is-folder", PATHS, "`--out` an existing folder", r"output '.*' is a folder; expected the path of an HDF5 result file",
         lambda e: ["solve", "full", "--out", str(e.tmp)]),
    Case("out-not-hdf5", PATHS, "`--out` an existing file that is not HDF5", r"exists and is not an HDF5 file",
         lambda e: ["solve", "full", "--out", e.write("notes.txt", "my notes")]),
    Case("out-parent-is-file", PATHS, "`--out` below a file (`notes.txt/x.h5`)", r"cannot be created: '.*notes.txt' is not a folder",
         lambda e: ["solve", "full", "--out", str(Path(e.write("notes.txt", "x")) / "x.h5")]),
    Case("out-truncated", PATHS, "`--out` a truncated result file", r"truncated or damaged",
         lambda e: ["solve", "full", "--out", e.result("cut.h5", truncate=True)]),
    Case("out-newer-layout", PATHS, "`--out` a result file of a newer layout",
         r"was written by a newer fatigue_pin \(layout 4\); this version reads layouts up to 3",
         lambda e: ["solve", "full", "--out", e.result("new.h5", layout=4)]),
    Case("out-full-disk", PATHS, "`--out` on a full disk", r"full", lambda e: ["solve", "full", "--out", e.full_disk()]),
    Case("folder-out-is-file", PATHS, "`plot --out` an existing file", r"output '.*' is a file; expected a folder",
         lambda e: ["plot", str(e.existing), "--out", e.write("notes.txt", "x")]),
    Case("folder-out-unwritable", PATHS, "`forward --out /proc/fp`", r"output folder '/proc/fp' is not writable",
         lambda e: ["forward", "--out", "/proc/fp"]),
    Case("demo-out-is-file", PATHS, "`demo --out` an existing file", r"is a file; expected a folder",
         lambda e: ["demo", "--out", e.write("notes.txt", "x")]),
    Case("html-is-folder", PATHS, "`replay --html` an existing folder", r"--html '.*' is a folder",
         lambda e: ["replay", str(e.existing), "--run", "full/a", "--html", str(e.tmp)]),
    Case("study-missing", PATHS, "a study file that does not exist", r"study file not found: '.*nope.toml'",
         lambda e: ["run", e.path("nope.toml"), "--out", str(e.existing)]),
    Case("study-is-folder", PATHS, "a study path that is a folder", r"study file '.*' is a folder",
         lambda e: ["run", str(e.tmp), "--out", str(e.existing)]),
    # -- URDFs -------------------------------------------------------------------------------------
    Case("urdf-missing", URDF, "a URDF path that does not exist", r"URDF file not found: '.*nope.urdf'",
         lambda e: ["info", "--urdf", e.path("nope.urdf")]),
    Case("urdf-unparsable", URDF, "a URDF that is not XML", r"does not parse",
         lambda e: ["info", "--urdf", e.write("bad.urdf", "<robot name='x'><link name='a'></robot")]),
    Case("urdf-floating-base", URDF, "a floating base", r"joint 'world_to_thorax' is a floating base",
         lambda e: ["info", "--urdf", e.urdf(lambda t: t.replace('name="world_to_thorax" type="fixed"',
                                                                   'name="world_to_thorax" type="floating"'))]),
    Case("urdf-continuous-joint", URDF, "a continuous joint", r"joint 'elbow' is of unsupported type",
         lambda e: ["info", "--urdf", e.urdf(lambda t: t.replace('name="elbow" type="revolute"', 'name="elbow" type="continuous"'))]),
    Case("urdf-no-effort", URDF, "a joint `<limit>` without `effort`", r"does not parse: joint \[shoulder\]: limit has no effort",
         lambda e: ["info", "--urdf", e.urdf(lambda t: t.replace('effort="50.0"', "", 1))]),
    Case("urdf-negative-effort", URDF, 'a joint with `effort="-1"` (0 is a passive joint)',
         r"joint 'elbow' has effort limit -1.0; expected a finite effort >= 0",
         lambda e: ["info", "--urdf", e.urdf(lambda t: t.replace(
             'lower="0.0" upper="3.141592653589793" effort="50.0"', 'lower="0.0" upper="3.141592653589793" effort="-1"'))]),
    Case("urdf-zero-mass", URDF, "links of zero mass (in a study's `model.urdf`)", r"joint 'shoulder' moves no mass",
         _run(lambda e: e.study(_set("model", "urdf", e.urdf(_zero_mass, "massless.urdf"))))),
    Case("urdf-is-folder", URDF, "a URDF path that is a folder", r"URDF path '.*' is a folder; expected the path of a .urdf file",
         lambda e: ["info", "--urdf", str(e.tmp)]),
    Case("urdf-empty-path", URDF, "`run --set model.urdf=` (empty)", r"model.urdf = '': expected a bundled model name",
         lambda e: ["run", e.study(), "--set", "model.urdf=", "--out", str(e.existing)]),
    Case("urdf-negative-mass", URDF, "a link of negative mass", r"link 'humerus' has mass -1.86457; expected a mass >= 0",
         lambda e: ["info", "--urdf", e.urdf(lambda t: t.replace('<mass value="1.864572"/>', '<mass value="-1.864572"/>'))]),
    Case("urdf-negative-inertia", URDF, "a link with a negative moment of inertia", r"link 'humerus' has ixx = -0.01481; expected moments",
         lambda e: ["info", "--urdf", e.urdf(lambda t: t.replace('ixx="0.01481"', 'ixx="-0.01481"'))]),
    Case("urdf-lower-above-upper", URDF, "a lower limit above the upper limit", r"joint 'elbow' has lower limit 2 above its upper limit 1",
         lambda e: ["info", "--urdf", e.urdf(lambda t: t.replace('lower="0.0" upper="3.141592653589793"', 'lower="2" upper="1"'))]),
    Case("urdf-mimic-joint", URDF, "a joint that mimics another (a mimic tag), not locked", r"joint 'elbow' mimics 'shoulder' \(<mimic>\).*locked_joints",
         lambda e: ["info", "--urdf", e.urdf(lambda t: t.replace('lower="0.0" upper="3.141592653589793" effort="50.0" velocity="31.41592653589793"/>',
                                                                 'lower="0.0" upper="3.141592653589793" effort="50.0" velocity="31.41592653589793"/><mimic joint="shoulder"/>'))]),
    Case("urdf-nan-limit", URDF, "a NaN limit", r"joint \[elbow\]: <limit upper='nan'>: expected a finite number",
         lambda e: ["info", "--urdf", e.urdf(lambda t: t.replace('lower="0.0" upper="3.141592653589793"', 'lower="0.0" upper="nan"'))]),
    Case("urdf-word-for-number", URDF, "a word where a number belongs", r"joint \[elbow\]: <limit lower='zero'>: expected a finite number",
         lambda e: ["info", "--urdf", e.urdf(lambda t: t.replace('lower="0.0" upper="3.141592653589793"', 'lower="zero" upper="3"'))]),
    Case("urdf-vector-size", URDF, "an `<origin xyz>` of two numbers", r"<origin xyz='0.0061 -0.2904'>: expected 3 finite numbers",
         lambda e: ["info", "--urdf", e.urdf(lambda t: t.replace('xyz="0.0061 -0.2904 -0.0123"', 'xyz="0.0061 -0.2904"'))]),
    Case("urdf-zero-axis", URDF, "a joint axis `0 0 0`", r"joint 'elbow' has axis xyz = '0 0 0'; expected a non-zero axis",
         lambda e: ["info", "--urdf", e.urdf(lambda t: t.replace('<axis xyz="0.049400012 0.036600009 0.998108250"/>', '<axis xyz="0 0 0"/>'))]),
    Case("urdf-mass-without-value", URDF, "a `<mass/>` without its value (read as 0 by the parser)",
         r"link \[humerus\]: <mass> has no value; expected <mass value=",
         lambda e: ["info", "--urdf", e.urdf(lambda t: t.replace('<mass value="1.864572"/>', "<mass/>"))]),
    Case("urdf-duplicate-joint", URDF, "two joints of the same name", r"two joints are named 'shoulder'; expected unique joint names",
         lambda e: ["info", "--urdf", e.urdf(lambda t: t.replace('name="elbow" type="revolute"', 'name="shoulder" type="revolute"'))]),
    Case("urdf-unknown-joint-type", URDF, "a joint of an unknown type (the parser's own message, on one line)",
         r"does not parse: Joint \[elbow\] has no known type \[weird\]",
         lambda e: ["info", "--urdf", e.urdf(lambda t: t.replace('name="elbow" type="revolute"', 'name="elbow" type="weird"'))]),
    # -- OpenSim models ----------------------------------------------------------------------------
    Case("osim-ellipsoid-wrap", OSIM, "a muscle study on an OpenSim model whose muscle wraps round an ellipsoid, without `ignore_wraps`",
         r"model.osim = '.*arm26.osim': OpenSim model .*Thelen2003Muscle 'TRIlong', path wrap 'TRIlonghh' is a WrapEllipsoid",
         _run(lambda e: e.study(_osim_muscles(e.osim())))),
    Case("osim-joint-kind", OSIM, "`info --osim` a model with a `BallJoint`",
         r"BallJoint 'r_elbow' is of a joint kind fatigue_pin does not read",
         lambda e: ["info", "--osim", e.osim(lambda t: t.replace('<CustomJoint name="r_elbow">', '<BallJoint name="r_elbow">')
                                             .replace("</SpatialTransform>\n        </CustomJoint>\n      </objects>",
                                                      "</SpatialTransform>\n        </BallJoint>\n      </objects>"))]),
    Case("osim-coupled", OSIM, "`info --osim` a `CustomJoint` axis driven by two coordinates",
         r"CustomJoint 'r_elbow', transform axis 'rotation1' is driven by the coordinates \['r_elbow_flex', 'r_shoulder_elev'\] together",
         lambda e: ["info", "--osim", e.osim(lambda t: t.replace("<coordinates>r_elbow_flex</coordinates>",
                                                                 "<coordinates>r_elbow_flex r_shoulder_elev</coordinates>"))]),
    Case("osim-moving-point", OSIM, "`info --osim` a muscle with a `MovingPathPoint`",
         r"Thelen2003Muscle 'BRA', path point 'BRA-P2' is a MovingPathPoint; expected fixed PathPoints",
         lambda e: ["info", "--osim", e.osim(lambda t: re.sub(r'<PathPoint name="BRA-P2">(.*?)</PathPoint>',
                                                              r'<MovingPathPoint name="BRA-P2">\1</MovingPathPoint>', t, flags=re.S)),
                    "--ignore-wraps"]),
    Case("osim-unknown-body", OSIM, "`info --osim` a path point on a body the model does not have",
         r"path point 'BRA-P1' refers to frame '/bodyset/scapula', which is no body or offset frame of the model",
         lambda e: ["info", "--osim", e.osim(lambda t: t.replace("/bodyset/r_humerus</socket_parent_frame>\n"
                                                                 "                  <location>0.0068",
                                                                 "/bodyset/scapula</socket_parent_frame>\n"
                                                                 "                  <location>0.0068")), "--ignore-wraps"]),
    Case("osim-max-force", OSIM, "a muscle study on an OpenSim model with `max_isometric_force` 0 (or < 0)",
         r"Thelen2003Muscle 'BRA' has max_isometric_force 0; expected a force > 0 \(N\)",
         _run(lambda e: e.study(_osim_muscles(e.osim(lambda t: t.replace("<max_isometric_force>987.26", "<max_isometric_force>0")),
                                              ignore_wraps=True)))),
    Case("osim-optimal-length", OSIM, "`info --osim` a muscle with `optimal_fiber_length` 0 (or < 0)",
         r"Thelen2003Muscle 'BRA' has optimal_fiber_length 0; expected a length > 0 \(m\)",
         lambda e: ["info", "--osim", e.osim(lambda t: t.replace("<optimal_fiber_length>0.0858", "<optimal_fiber_length>0")),
                    "--ignore-wraps"]),
    Case("osim-no-joint-crossed", OSIM, "`info --osim` a muscle whose points are all on one body",
         r"Thelen2003Muscle 'BRA' crosses no joint: its points are all on \['r_humerus'\]",
         lambda e: ["info", "--osim", e.osim(lambda t: t.replace("/bodyset/r_ulna_radius_hand</socket_parent_frame>\n"
                                                                 "                  <location>-0.0032",
                                                                 "/bodyset/r_humerus</socket_parent_frame>\n"
                                                                 "                  <location>-0.0032")), "--ignore-wraps"]),
    Case("osim-wrap-radius", OSIM, "`info --osim` a wrap cylinder of radius 0 (or < 0)",
         r"WrapCylinder 'TRI' on body 'r_humerus' has radius 0; expected a cylinder radius > 0 \(m\)",
         lambda e: ["info", "--osim", e.osim(lambda t: t.replace("<radius>0.016</radius>", "<radius>0</radius>")), "--ignore-wraps"]),
    Case("osim-with-urdf", OSIM, "a study with both `model.osim` and `model.urdf`",
         r"model.urdf = 'arm26' beside osim = '.*arm26.osim': an OpenSim model brings its skeleton and its muscles",
         _run(lambda e: e.study(_set("model", "osim", e.osim())))),
    # -- study files -------------------------------------------------------------------------------
    Case("study-not-toml", STUDY, "a study file that is not TOML", r"is not valid TOML",
         lambda e: ["run", e.write("bad.toml", "name = \n[model"), "--out", str(e.existing)]),
    Case("study-binary", STUDY, "a binary file as study", r"is neither a TOML study nor an HDF5 result file",
         lambda e: ["run", e.write("bin.toml", b"\xff\xfe\x00\x01"), "--out", str(e.existing)]),
    Case("negative-rate", STUDY, "`fatigue.F = -1.0`", r"fatigue.F = -1.0: expected a finite rate >= 0",
         _run(lambda e: e.study(_set("fatigue", "F", -1.0)))),
    Case("infinite-rate", STUDY, "`fatigue.R = inf`", r"fatigue.R = inf: expected a finite rate >= 0",
         _run(lambda e: e.study(_set("fatigue", "R", float("inf"))))),
    Case("nan-rate", STUDY, "`fatigue.LD = nan`", r"fatigue.LD = nan: expected a finite rate >= 0",
         _run(lambda e: e.study(_set("fatigue", "LD", float("nan"))))),
    Case("passive-unknown-joint", STUDY, "`actuators.passive = [\"wrist\"]` on arm26",
         r"actuators.passive = \['wrist'\]: joint 'wrist' is not in model 'arm26'; its joints are \['shoulder', 'elbow'\]",
         _run(lambda e: e.study(_set("actuators", "passive", ["wrist"])))),
    Case("coupling-unknown", STUDY, "`actuators.coupling = \"tl+mf<=2\"`",
         r"actuators.coupling = 'tl\+mf<=2': expected one of \['tl\+mf<=1', 'observed', 'active'\]",
         _run(lambda e: e.study(_set("actuators", "coupling", "tl+mf<=2")))),
    Case("negative-weight", STUDY, "`costs.torque = -1.0`", r"costs.torque.weight = -1.0: expected a finite weight >= 0",
         _run(lambda e: e.study(_set("costs", "torque", -1.0)))),
    Case("nan-weight", STUDY, "`costs.fatigue = nan`", r"costs.fatigue.weight = nan: expected a finite weight >= 0",
         _run(lambda e: e.study(_set("costs", "fatigue", float("nan"))))),
    Case("negative-duration", STUDY, "`task.cycle_duration = -1.0`", r"task.cycle_duration = -1.0: expected a duration in seconds > 0",
         _run(lambda e: e.study(_set("task", "cycle_duration", -1.0)))),
    Case("infinite-duration", STUDY, "`task.cycle_duration = inf`", r"task.cycle_duration = inf: expected a finite number",
         _run(lambda e: e.study(_set("task", "cycle_duration", float("inf"))))),
    Case("zero-intervals", STUDY, "`task.intervals_per_cycle = 0`", r"task.intervals_per_cycle = 0: expected an integer >= 1",
         _run(lambda e: e.study(_set("task", "intervals_per_cycle", 0)))),
    Case("negative-tolerance", STUDY, "`solver.tol = -1e-6`", r"solver.tol = -1e-06: expected a tolerance > 0",
         _run(lambda e: e.study(_set("solver", "tol", -1e-6)))),
    Case("negative-target-tolerance", STUDY, "a target with `tolerance = -0.1`",
         r"task.targets\[1\].tolerance = -0.1: expected a tolerance >= 0",
         _run(lambda e: e.study(lambda d: d["task"]["targets"][1].update(tolerance=-0.1)))),
    Case("end-tolerance", STUDY, "`horizon.end_tolerance = 1.5`", r"horizon.end_tolerance = 1.5: expected a fraction in \[0, 1\)",
         _run(lambda e: e.study(_set("horizon", "end_tolerance", 1.5)))),
    Case("wrong-type", STUDY, '`task.intervals_per_cycle = "ten"`', r"task.intervals_per_cycle = 'ten': expected an integer >= 1",
         _run(lambda e: e.study(_set("task", "intervals_per_cycle", "ten")))),
    Case("wrong-type-table", STUDY, "`horizon = 3` (not a table)", r"horizon = 3: expected a table",
         _run(lambda e: e.write("t.toml", re.sub(r"\[horizon\]\n(.+\n)+\n", "", to_toml(BASE)).replace("\n", "\nhorizon = 3\n", 1)))),
    Case("unknown-key", STUDY, "`horizon.windw = 3` (a misspelt key)", r"unknown key horizon.windw",
         _run(lambda e: e.study(_set("horizon", "windw", 3)))),
    Case("unknown-table", STUDY, "a `[solvr]` table", r"unknown key 'solvr'",
         _run(lambda e: e.study(extra="\n[solvr]\ntol = 1e-6\n"))),
    Case("missing-key", STUDY, "no `task.cycle_duration`", r"missing key task.cycle_duration",
         _run(lambda e: e.study(_delete("task", "cycle_duration")))),
    Case("bad-name", STUDY, '`name = "a/b"`', r"name = 'a/b': expected a non-empty string without '/'",
         _run(lambda e: e.study(_set("name", "a/b")))),
    Case("unknown-joint", STUDY, 'a target on joint `"knee"`', r"task joint 'knee' is not in model 'arm26'",
         _run(lambda e: e.study(lambda d: d["task"]["targets"][1].update(joint="knee")))),
    Case("target-out-of-range", STUDY, "an elbow target at 4.0 rad", r"task target 4.0 of joint 'elbow' is outside its range",
         _run(lambda e: e.study(lambda d: d["task"]["targets"][1].update(value=4.0)))),
    Case("end-target-out-of-range", STUDY, 'an elbow target at 9.0 rad at `"end"`',
         r"task target 9.0 of joint 'elbow' is outside its range .* \(at the end\)",
         _run(lambda e: e.study(lambda d: d["task"]["targets"].append({"joint": "elbow", "value": 9.0, "at": "end"})))),
    Case("terminal-cost-unknown-state", STUDY, 'a terminal cost on state `"elbow_qddot"`',
         r"cost term 'end': state 'elbow_qddot' is not a state of the problem",
         _run(lambda e: e.study(lambda d: d["costs"].update(end={"kind": "state", "weight": 1.0, "states": ["elbow_qddot"],
                                                                 "at": "end"})))),
    Case("terminal-cost-of-controls", STUDY, '`costs.torque.at = "end"` (a term of the controls)',
         r"unknown key costs.torque.at; .* a terminal cost .* is a term of the state",
         _run(lambda e: e.study(lambda d: d["costs"]["torque"].update(at="end")))),
    Case("target-not-a-node", STUDY, "a target at phase 0.33 with 10 intervals", r"task phase at = 0.33 is not a node",
         _run(lambda e: e.study(lambda d: d["task"]["targets"][1].update(at=0.33)))),
    Case("q-init-out-of-bounds", STUDY, "`task.q_init = [0.07, -1.0]` (elbow below its range)",
         r"q_init = \[0.07, -1.0\] is outside the range of joints \['elbow'\]",
         _run(lambda e: e.study(_set("task", "q_init", [0.07, -1.0])))),
    Case("q-init-wrong-length", STUDY, "`task.q_init = [0.07]`", r"task q_init has 1 entries; model 'arm26' has nq = 2",
         _run(lambda e: e.study(_set("task", "q_init", [0.07])))),
    Case("two-targets-one-phase", STUDY, "two elbow targets at phase 0.5 with different values",
         r"task targets 2.617\d* \(\+- 0\) and 1.0 \(\+- 0\) of joint 'elbow' at phase 0.5: expected one target per joint and phase",
         _run(lambda e: e.study(lambda d: d["task"]["targets"].append({"joint": "elbow", "value": 1.0, "at": 0.5})))),
    Case("q-init-off-target", STUDY, "`task.q_init` with the elbow at 0.5 rad, its phase-0 target at 15 deg",
         r"task q_init = \[0.07, 0.5\] puts joint 'elbow' at 0.5, but its target at phase 0 is 0.261\d* \(\+- 0\)",
         _run(lambda e: e.study(_set("task", "q_init", [0.07, 0.5])))),
    Case("absurd-cycles", STUDY, "`horizon.cycles = 100000000000000000000`",
         r"cycles = 100000000000000000000: .* shooting intervals; expected at most 1000000 in one OCP",
         _run(lambda e: e.study(_set("horizon", "cycles", 10**20)))),
    Case("absurd-intervals", STUDY, "`task.intervals_per_cycle = 1000000000000`",
         r"intervals_per_cycle = 1000000000000: expected an integer in \[1, 1000000\]",
         _run(lambda e: e.study(_set("task", "intervals_per_cycle", 10**12)))),
    Case("absurd-substeps", STUDY, "`transcription.substeps = 1000000000`", r"substeps = 1000000000: expected an integer in \[1, 1000\]",
         _run(lambda e: e.study(_set("transcription", "substeps", 10**9)))),
    Case("ipopt-unknown-option", STUDY, "`solver.ipopt.nosuch = 3`", r"solver.ipopt.nosuch: IPOPT has no option 'nosuch'",
         _run(lambda e: e.study(lambda d: d["solver"].update(ipopt={"nosuch": 3})))),
    Case("ipopt-bad-setting", STUDY, '`solver.ipopt.mu_strategy = "weird"`',
         r"solver.ipopt.mu_strategy = 'weird': not a valid IPOPT setting; expected one of \['monotone', 'adaptive'\]",
         _run(lambda e: e.study(lambda d: d["solver"].update(ipopt={"mu_strategy": "weird"})))),
    Case("window-longer-than-run-file", STUDY, "a sliding window of 4 cycles with `max_cycles = 2`",
         r"horizon.max_cycles = 2: expected at least the window",
         _run(lambda e: e.study(_sliding(4, 2)))),
    Case("unknown-fatigue-model", STUDY, '`fatigue.model = "hill"`', r"fatigue.model = 'hill': expected one of",
         _run(lambda e: e.study(_set("fatigue", "model", "hill")))),
    Case("unknown-cost", STUDY, "`costs.speed = 1.0`", r"costs.speed: cost kind 'speed' is unknown",
         _run(lambda e: e.study(_set("costs", "speed", 1.0)))),
    Case("fatigue-unknown-joint", STUDY, "`[fatigue.joints.knee]`", r"fatigue.joints.knee: joint 'knee' is not in model 'arm26'",
         _run(lambda e: e.study(lambda d: d["fatigue"].update(joints={"knee": {"F": 0.1}})))),
    # -- result files ------------------------------------------------------------------------------
    Case("file-missing", FILES, "`replay` a file that does not exist", r"result file not found: '.*nope.h5'",
         lambda e: ["replay", e.path("nope.h5"), "--html", e.path("r.html")]),
    Case("file-not-hdf5", FILES, "`plot` a file that is not HDF5", r"lacks the HDF5 signature",
         lambda e: ["plot", e.write("notes.h5", "my notes"), "--out", e.path("figures")]),
    Case("file-truncated", FILES, "`replay` a truncated result file", r"'.*cut.h5' is not a readable HDF5 file: it is truncated or damaged",
         lambda e: ["replay", e.result("cut.h5", truncate=True), "--html", e.path("r.html")]),
    Case("file-newer-layout", FILES, "`plot` a file of a newer layout", r"newer fatigue_pin \(layout 4\); this version reads layouts up to 3",
         lambda e: ["plot", e.result("new.h5", layout=4), "--out", e.path("figures")]),
    Case("file-unknown-run", FILES, "`replay --run nope`", r"run 'nope' is not in '.*existing.h5'; it holds \['full/a', 'full/b'\]",
         lambda e: ["replay", str(e.existing), "--run", "nope", "--html", e.path("r.html")]),
    Case("file-several-runs", FILES, "`replay` a file of several runs without `--run`", r"holds 2 runs \['full/a', 'full/b'\]; choose one",
         lambda e: ["replay", str(e.existing), "--html", e.path("r.html")]),
    Case("file-empty", FILES, "`replay` a result file that holds no run", r"'.*empty.h5' holds no run; expected a result file with a run",
         lambda e: ["replay", e.empty_result(), "--html", e.path("r.html")]),
    Case("run-file-several-runs", FILES, "`run FILE.h5` of a file of several runs, without `--run`",
         r"holds 2 runs \['full/a', 'full/b'\]; choose one by name \(--run NAME\)",
         lambda e: ["run", str(e.existing), "--out", e.path("new.h5")]),
    Case("run-without-cycles", FILES, "`plot` a sliding run whose first window failed (no cycle)",
         r"run 'sliding/x' has no cycle to plot: no window converged .*'sliding/x_failed_window'",
         lambda e: ["plot", e.result_without_cycles(), "--out", e.path("figures")]),
    Case("datasets-disagree", FILES, "`replay` a run whose datasets disagree in length (q has a row too few)",
         r"run 'full/a': t has 21 nodes and cycle_costs 2 cycles, but the rows of \{'q': 20\} disagree",
         lambda e: ["replay", e.result_cut_q(), "--run", "full/a", "--html", e.path("r.html")]),
    Case("rerun-without-study", FILES, "`rerun` a run built in Python (no stored study)", r"holds no run with a stored study",
         lambda e: ["rerun", str(e.existing), "--out", str(e.existing)]),
    # -- run names ---------------------------------------------------------------------------------
    Case("run-name-parent-group", FILES, "`run --name full` where the file holds full/a and full/b",
         r"run name 'full' is the group of \['full/a', 'full/b'\] in '.*existing.h5'; a run replaces only a run of the same name",
         lambda e: ["run", e.study(), "--name", "full", "--out", str(e.existing)]),
    Case("run-name-inside-run", FILES, "`run --name full/a/x` (inside run full/a)", r"run name 'full/a/x' lies inside run 'full/a'",
         lambda e: ["run", e.study(), "--name", "full/a/x", "--out", str(e.existing)]),
    Case("run-name-grammar", FILES, "`run --name a//b` (an empty segment; also `.`, `/`, `search/...`)",
         r"run name 'a//b': expected segments of letters and digits of any script and _ - . \+ = , separated by '/'",
         lambda e: ["run", e.study(), "--name", "a//b", "--out", str(e.existing)]),
    Case("run-name-character", FILES, "`run --name 'bïcèps_💪 run'` (letters of any script are letters; an emoji and a space are not)",
         r"run name 'bïcèps_💪 run': holds '💪' \(U\+1F4AA\), which is not allowed; expected segments of letters and digits",
         lambda e: ["run", e.study(), "--name", "bïcèps_💪 run", "--out", str(e.existing)]),
    # -- fatigue data: presets, endurance CSVs, endurance tasks ------------------------------------
    Case("preset-json-shape", FATIGUE, "a preset JSON whose `model` is a list", r"model = \['3cc'\]: expected one of",
         lambda e: ["endurance", "--preset", e.write("p.json", '{"model": ["3cc"], "F": 0.01, "R": 0.001, "LD": 10, "LR": 10}'),
                    "--loads", "0.5", "--no-compare", "--out", e.path("endurance")]),
    Case("csv-duplicated-column", FATIGUE, "an endurance CSV with a column twice",
         r"column\(s\) \['target_load'\] appear more than once",
         lambda e: ["calibrate", e.write("d.csv", "target_load,endurance_time_s,target_load\n0.5,100,0.6\n0.3,300,0.4\n"),
                    "--out", e.path("p.json")]),
    Case("csv-tiny-times", FATIGUE, "endurance times of 1e-300 s (the fit would overflow)",
         r"endurance_time_s = 1e-300: expected a time in \[0.001, 1e\+09\) s",
         lambda e: ["calibrate", e.write("d.csv", "target_load,endurance_time_s\n0.5,1e-300\n0.3,2e-300\n"), "--out", e.path("p.json")]),
    Case("thermal-csv-constant", FATIGUE, "a thermal log whose temperature never changes (`calibrate-thermal`)",
         r"log.csv: winding_C never changes \(all 40.0 deg C\): expected a temperature that rises or falls",
         lambda e: ["calibrate-thermal", e.write("log.csv", "time_s,current_A,winding_C\n" + "".join(f"{k},1,40\n" for k in range(6))),
                    "--motor", "maxon-re30", "--out", e.path("fit.json")]),
    Case("motor-gear-ratio", STUDY, "`[motors] gear_ratio = 0` (the curl's joints driven by motors)",
         r"motors: joint 'shoulder': MotorParameters.gear_ratio = 0: expected a gear ratio > 0",
         _run(lambda e: e.study(_motors(gear_ratio=0)))),
    Case("motor-t-max-below-ambient", STUDY, "`[motors] preset = \"maxon-re30\"`, `T_ambient = 130` (T_max 125 deg C)",
         r"MotorParameters.T_max = 125.0: expected above T_ambient \+ margin = 130 \+ 10.0",
         _run(lambda e: e.study(_motors(T_ambient=130)))),
    Case("motor-thermal-resistance", STUDY, "`[motors] R_ha = -1`",
         r"MotorParameters.R_ha = -1: expected a thermal resistance > 0 \(K/W\)",
         _run(lambda e: e.study(_motors(R_ha=-1)))),
    Case("motor-unknown-joint", STUDY, "`[motors.joints.knee]` on arm26 (no knee)",
         r"motors.joints.knee: motor on joint 'knee': expected a joint of the model \['shoulder', 'elbow'\]",
         _run(lambda e: e.study(_motors(joints={"knee": {"gear_ratio": 50.0}})))),
    Case("motor-derate", STUDY, "`[motors] derate = \"yes\"`", r"motors.derate = 'yes': expected true or false",
         _run(lambda e: e.study(_motors(derate="yes")))),
    Case("heat-budget-without-motors", STUDY, "`[horizon] heat_budget = true` on torque halves (sliding, `max_cycles = 4`)",
         r"horizon.heat_budget = true: expected motors \(actuators.kind = \"motors\"\); the actuators are 'torque'",
         _run(lambda e: e.study(lambda d: d["horizon"].update(kind="sliding", cycles=2, max_cycles=4, heat_budget=True)))),
    Case("motor-preset-api", API, "`motor_preset(\"maxon-re30\", gear_ratio=0)`",
         r"MotorParameters.gear_ratio = 0: expected a gear ratio > 0",
         api=lambda e: __import__("fatigue_pin.motors.presets", fromlist=["x"]).motor_preset("maxon-re30", gear_ratio=0)),
    Case("empty-loads", FATIGUE, "`endurance --loads ,` (no load)", r"--loads ',': expected comma-separated fractions",
         lambda e: ["endurance", "--loads", ",", "--out", e.path("endurance")]),
    Case("endurance-too-many-cycles", FATIGUE, "an intermittent task of 0.01 s cycles beyond `--max-cycles 20`",
         r"max_cycles = 20 cycles of 0.01 s \(0.2 s\) simulated at TL = 0.5 without failure",
         lambda e: ["endurance", "--loads", "0.5", "--duty-cycle", "0.5", "--cycle-s", "0.01", "--max-cycles", "20",
                    "--no-compare", "--out", e.path("endurance")]),
    # -- sweeps on an existing Dask scheduler -----------------------------------------------------
    Case("scheduler-malformed", SWEEP, "`sweep --scheduler tcp://127.0.0.1:http`", r"--scheduler 'tcp://127.0.0.1:http': expected tcp://HOST:PORT",
         lambda e: ["sweep", e.sweep(), "--scheduler", "tcp://127.0.0.1:http", "--out", e.path("sweep")]),
    Case("scheduler-other-protocol", SWEEP, "`sweep --scheduler` a port that answers with an SSH banner",
         r"--scheduler 'tcp://127.0.0.1:\d+' answered 'SSH-2.0-OpenSSH_9.2p1', another protocol; expected a Dask scheduler",
         lambda e: ["sweep", e.sweep(), "--scheduler", _banner_server(), "--out", e.path("sweep")]),
    # -- the Python API ----------------------------------------------------------------------------
    Case("x-init-sum", API, "`Problem(..., x_init)` with ma + mr + mf = 1.5 on a half",
         r"x_init of actuator half 'shoulder_plus': ma = 0.5, mr = 1, mf = 0; ma \+ mr \+ mf = 1.5, expected 1",
         api=lambda e: _problem(fatigue=[0.5, 1.0, 0.0])),
    Case("x-init-fraction", API, "`Problem(..., x_init)` with mf = -0.2", r"mf = -0.2; expected fractions in \[0, 1\]",
         api=lambda e: _problem(fatigue=[0.2, 1.0, -0.2])),
    Case("x-init-q-bounds", API, "`Problem(..., x_init)` with the elbow at -1 rad", r"x_init: q = \[0.07, -1.0\] is outside the bounds of joints \['elbow'\]",
         api=lambda e: _problem(q=[0.07, -1.0])),
    Case("x-init-size", API, "`Problem(..., x_init)` of the wrong size", r"x_init has 3 entries; expected nx = 16",
         api=lambda e: _problem(size=3)),
    Case("fatigue-params", API, "`XiaFatigue(F=-1, ...)`", r"XiaFatigue.F = -1.0: expected a finite rate >= 0",
         api=lambda e: __import__("fatigue_pin.fatigue.models", fromlist=["x"]).XiaFatigue(LD=10, LR=10, F=-1, R=0.1)),
    Case("task-duration", API, "`Task(cycle_duration=0, ...)`", r"Task.cycle_duration = 0: expected a duration in seconds > 0",
         api=lambda e: __import__("fatigue_pin.ocp.task", fromlist=["x"]).Task(0, 10)),
    Case("sliding-settings", API, "`SlidingSettings(window=3, advance=4)`", r"SlidingSettings.advance = 4: expected an integer in \[1, window = 3\]",
         api=lambda e: __import__("fatigue_pin.drivers.sliding", fromlist=["x"]).SlidingSettings(window=3, advance=4)),
    Case("read-unknown-run", API, "`read_run(path, 'nope')`", r"run 'nope' is not in",
         api=lambda e: __import__("fatigue_pin.io.results", fromlist=["x"]).read_run(e.existing, "nope")),
]


def _problem(fatigue=None, q=None, size=None):
    from fatigue_pin.paper.curl import curl_study

    study = curl_study("full", intervals_per_cycle=10, substeps=2, solver={"compile": False})
    problem = study.problem(_model())
    x = problem.initial_state()
    if size is not None:
        x = x[:size]
    if q is not None:
        x[:2] = q
    if fatigue is not None:
        x[4:7] = fatigue
    return problem.with_x_init(x)


_MODEL: list = []


def _model():
    if not _MODEL:
        from fatigue_pin.robot.model import load_model

        _MODEL.append(load_model())
    return _MODEL[0]


# -- a full disk -------------------------------------------------------------------------------


class _FullDisk:
    """``Env.full_disk()``: a result file on a full tmpfs (or, where mounting is not allowed, on a
    disk whose ``statvfs`` reports no free space)."""

    def __init__(self, monkeypatch):
        self.monkeypatch = monkeypatch
        self.mounts: list[Path] = []

    def __call__(self, env: Env) -> str:
        disk = env.tmp / "disk"
        disk.mkdir()
        if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=256k", "tmpfs", str(disk)], capture_output=True).returncode == 0:
            self.mounts.append(disk)
            path = disk / "existing.h5"
            write_run(path, make_run("full/a"))
            import os

            st = os.statvfs(disk)
            with open(disk / "filler", "wb") as fh:
                fh.write(b"\0" * max(st.f_bavail * st.f_frsize - 16384, 0))
        else:
            import os
            from collections import namedtuple

            path = disk / "existing.h5"
            write_run(path, make_run("full/a"))
            real = os.statvfs
            Stat = namedtuple("Stat", "f_bavail f_frsize")
            self.monkeypatch.setattr(os, "statvfs", lambda p: Stat(0, 4096) if str(p).startswith(str(disk)) else real(p))
        env.watched.append(path)
        return str(path)

    def close(self) -> None:
        for disk in self.mounts:
            subprocess.run(["umount", "-l", str(disk)], check=False)


@pytest.fixture
def env(tmp_path, monkeypatch):
    e = Env(tmp_path)
    disk = _FullDisk(monkeypatch)
    e.full_disk = lambda: disk(e)  # type: ignore[attr-defined]
    yield e
    disk.close()


CLI_CASES = [c for c in CASES if c.argv is not None]
API_CASES = [c for c in CASES if c.api is not None]


#: Reprs of numpy values that a message must never show (it writes plain numbers and lists).
NUMPY_REPRS = ("np.float64(", "np.int64(", "np.bool", "array(")


def _no_numpy_repr(message: str) -> None:
    shown = [r for r in NUMPY_REPRS if r in message]
    assert not shown, f"message shows the numpy repr {shown[0]!r}: {message}"


def _snapshot(e: Env) -> dict[Path, bytes]:
    return {p: p.read_bytes() for p in e.watched if p.exists()}


@pytest.mark.parametrize("case", CLI_CASES, ids=[c.id for c in CLI_CASES])
def test_cli_refuses_with_one_line(case, env, capsys):
    argv = case.argv(env)
    before = _snapshot(env)
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.endswith("\n") and err.count("\n") == 1, err  # exactly one line
    assert err.startswith("fatigue-pin: error: ") and "Traceback" not in err
    assert re.search(case.message, err), err
    _no_numpy_repr(err)
    assert _snapshot(env) == before  # existing result files are byte-for-byte unchanged
    assert not list(env.tmp.glob("**/*.h5.tmp"))


@pytest.mark.parametrize("case", CLI_CASES[::4], ids=[c.id for c in CLI_CASES[::4]])
def test_debug_shows_the_traceback(case, env):
    with pytest.raises((FatiguePinError, OSError)) as err:
        main(case.argv(env) + ["--debug"])
    assert re.search(case.message, " ".join(str(err.value).split()))


@pytest.mark.parametrize("case", API_CASES, ids=[c.id for c in API_CASES])
def test_python_api_refuses(case, env):
    with pytest.raises(FatiguePinError) as err:
        case.api(env)
    assert re.search(case.message, str(err.value)), str(err.value)
    assert "\n" not in str(err.value)
    _no_numpy_repr(str(err.value))


def test_the_catalogue_has_every_case():
    doc = (Path(__file__).resolve().parents[2] / "docs" / "errors.md").read_text()
    assert len(CASES) >= 30
    missing = [c.id for c in CASES if f"`{c.id}`" not in doc]
    assert not missing, f"docs/errors.md lacks {missing}"


# -- the catalogue's table (python tests/test_errors.py) --------------------------------------------


def _catalogue() -> str:
    import io
    import tempfile
    from contextlib import redirect_stderr, redirect_stdout

    class _MP:  # a minimal monkeypatch for the full-disk case outside pytest
        def __init__(self):
            self.undo_list = []

        def setattr(self, obj, name, value):
            self.undo_list.append((obj, name, getattr(obj, name)))
            setattr(obj, name, value)

        def undo(self):
            for obj, name, value in reversed(self.undo_list):
                setattr(obj, name, value)

    lines = ["| group | case | input | message | exit code |", "|---|---|---|---|---|"]
    for case in CASES:
        with tempfile.TemporaryDirectory() as tmp:
            mp = _MP()
            e = Env(Path(tmp))
            disk = _FullDisk(mp)
            e.full_disk = lambda: disk(e)  # type: ignore[attr-defined]
            try:
                if case.argv is not None:
                    err = io.StringIO()
                    with redirect_stderr(err), redirect_stdout(io.StringIO()):
                        code = main(case.argv(e))
                    message = err.getvalue().strip()
                    exit_code = str(code)
                else:
                    try:
                        case.api(e)
                        message, exit_code = "(no error)", "-"
                    except FatiguePinError as exc:
                        message, exit_code = f"{type(exc).__name__}: {exc}", "(exception)"
            finally:
                disk.close()
                mp.undo()
            message = message.replace(str(Path(tmp).resolve()), "TMP").replace(tmp, "TMP").replace("|", "\\|")
        lines.append(f"| {case.group} | `{case.id}` | {case.what.replace('|', chr(92) + '|')} | `{message}` | {exit_code} |")
    return "\n".join(lines)


if __name__ == "__main__":
    print(_catalogue())
