"""Rigid-body models: load a fixed-base URDF with Pinocchio and expose its CasADi dynamics.

``load_model()`` returns the bundled arm26 (two revolute joints, 3.6 kg dumbbell in the hand);
``load_model(path)`` loads any fixed-base robot whose joints are all revolute or prismatic
(one position and one velocity per joint).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping

import casadi as ca
import numpy as np
import pinocchio as pin

from fatigue_pin.robot.dynamics import casadi_aba_derivatives, casadi_dynamics
from fatigue_pin.robot.units import JointUnits, units_of_kind
from fatigue_pin.robot.urdf import check_urdf_text, quiet_stderr
from fatigue_pin.core.errors import DimensionError, ModelError
from fatigue_pin.core.settings import check_fields, setting
from fatigue_pin.core.text import shown

#: Joint model short names Pinocchio uses for one-DoF revolute joints, then prismatic ones.
_REVOLUTE_JOINTS = ("JointModelRX", "JointModelRY", "JointModelRZ", "JointModelRevoluteUnaligned")
_PRISMATIC_JOINTS = ("JointModelPX", "JointModelPY", "JointModelPZ", "JointModelPrismaticUnaligned")
_SUPPORTED_JOINTS = _REVOLUTE_JOINTS + _PRISMATIC_JOINTS


def joint_kind(joint: pin.JointModel) -> str:
    """``"revolute"`` or ``"prismatic"`` for a one-DoF Pinocchio joint model (``JointModelR*``,
    ``JointModelP*``); ModelError for any other joint type."""
    short = joint.shortname()
    if short in _REVOLUTE_JOINTS:
        return "revolute"
    if short in _PRISMATIC_JOINTS:
        return "prismatic"
    raise ModelError(f"joint type {short}: expected a revolute or prismatic joint with one position and one velocity")


def joint_kinds_of_urdf(urdf: str) -> dict[str, str]:
    """Joint name -> kind (``revolute``, ``prismatic``) of every movable joint of a URDF text,
    from Pinocchio's parse (no dynamics built); ModelError if it does not parse or holds another
    joint type. Result files that predate the stored kinds get them from their URDF this way."""
    try:
        with quiet_stderr():
            model = pin.buildModelFromXML(urdf)
    except Exception as exc:  # Pinocchio raises ValueError/RuntimeError with the parser's message
        raise ModelError(f"the URDF text does not parse ({' '.join(str(exc).split())})") from None
    return {model.names[i]: joint_kind(model.joints[i]) for i in range(1, model.njoints)}


def bundled_file(filename: str) -> Path | None:
    """Path of a model file shipped with fatigue_pin (a URDF, a muscle file), or None: the
    package's ``urdf`` folder (an installed wheel), then the source tree's."""
    here = Path(__file__).resolve().parents[1]  # the package folder
    for folder in (here / "urdf", here.parent / "urdf"):
        if (folder / filename).is_file():
            return folder / filename
    return None


def bundled_urdf(name: str = "arm26") -> Path:
    """Path of a URDF shipped with fatigue_pin (``arm26``)."""
    path = bundled_file(f"{name}.urdf")
    if path is None:
        raise ModelError(f"bundled URDF {name!r} not found next to the package ({Path(__file__).resolve().parents[1]}); "
                         "reinstall fatigue_pin")
    return path


#: URDFs of example-robot-data known by short name (paths below its ``robots`` folder).
EXAMPLE_ROBOTS = {
    "ur5": "ur_description/urdf/ur5_robot.urdf",
    "panda": "panda_description/urdf/panda.urdf",
}


def example_robot_urdf(name: str) -> Path:
    """Path of a URDF shipped by the ``example-robot-data`` wheel.

    Args:
        name: a short name of :data:`EXAMPLE_ROBOTS` (``ur5``, ``panda``) or a path below the
            package's ``robots`` folder (e.g. ``"ur_description/urdf/ur5_robot.urdf"``).
    """
    from importlib import metadata

    relative = EXAMPLE_ROBOTS.get(name, name)
    try:
        files = metadata.files("example-robot-data") or []
    except metadata.PackageNotFoundError as exc:
        raise ModelError("example-robot-data is not installed (pip install example-robot-data)") from exc
    for f in files:
        if str(f).endswith("example-robot-data/robots/" + relative):
            return Path(f.locate()).resolve()
    raise ModelError(f"example-robot-data has no URDF {name!r}; known names: {sorted(EXAMPLE_ROBOTS)}")


def package_dirs() -> list[str]:
    """Folders in which ``package://`` mesh paths of URDFs are resolved: the one holding
    example-robot-data's packages (``.../share``), when installed."""
    try:
        share = example_robot_urdf("ur5").parents[4]
    except (ModelError, IndexError):
        return []
    return [str(share)]


@dataclass(frozen=True)
class Payload:
    """A rigid load held at a frame of the model (a tool, a carried box).

    Attributes:
        frame: the frame it is fixed to (a link or tool frame of the URDF).
        mass: kg, >= 0.
        com: centre of mass in the frame's axes, from its origin (m), 3 numbers.
        inertia: rotational inertia about the centre of mass, in the frame's axes (kg m^2), as
            (ixx, ixy, ixz, iyy, iyz, izz); None: a point mass.
    """

    frame: str
    mass: float
    com: tuple[float, float, float] = (0.0, 0.0, 0.0)
    inertia: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        m = self.mass
        if isinstance(m, bool) or not isinstance(m, (int, float, np.floating, np.integer)) or not math.isfinite(m) or m < 0:
            raise ModelError(f"payload mass = {shown(m)}: expected a finite mass >= 0 (kg)")
        object.__setattr__(self, "mass", float(m))
        c = np.asarray(self.com, dtype=float).reshape(-1)
        if c.size != 3 or not np.all(np.isfinite(c)):
            raise ModelError(f"payload com = {shown(list(np.ravel(self.com)))}: expected 3 finite numbers (m, in the frame's axes)")
        object.__setattr__(self, "com", tuple(float(x) for x in c))
        if self.inertia is not None:
            i = np.asarray(self.inertia, dtype=float).reshape(-1)
            if i.size != 6 or not np.all(np.isfinite(i)) or np.linalg.eigvalsh(self.inertia_matrix(i)).min() < -1e-12:
                raise ModelError(f"payload inertia = {shown(list(np.ravel(self.inertia)))}: expected (ixx, ixy, ixz, iyy, iyz, izz), "
                                 "kg m^2, a positive semi-definite matrix")
            object.__setattr__(self, "inertia", tuple(float(x) for x in i))

    @staticmethod
    def inertia_matrix(i: np.ndarray | tuple | None) -> np.ndarray:
        if i is None:
            return np.zeros((3, 3))
        ixx, ixy, ixz, iyy, iyz, izz = i
        return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])

    def apply(self, model: pin.Model, owner: str = "model") -> None:
        """Add the load to the body of the frame's parent joint of ``model`` (in place)."""
        if not model.existFrame(self.frame):
            names = [f.name for f in model.frames if f.type in (pin.FrameType.BODY, pin.FrameType.OP_FRAME)]
            raise ModelError(f"payload frame {self.frame!r} is not in {owner} {model.name!r}; its link and tool frames are {names}")
        f = model.frames[model.getFrameId(self.frame)]
        if f.parentJoint == 0:
            raise ModelError(f"payload frame {self.frame!r} is fixed to the base of {owner} {model.name!r}; it would move no joint")
        Y = pin.Inertia(self.mass, np.array(self.com), self.inertia_matrix(self.inertia))
        model.appendBodyToJoint(f.parentJoint, Y, f.placement)


@dataclass(frozen=True)
class RobotModel:
    """A fixed-base rigid-body model with its bounds and CasADi dynamics.

    Attributes:
        name: model name from the URDF.
        urdf_path: the URDF file the model was built from.
        pin_model: the Pinocchio model (gravity (0, 0, -9.81) m/s^2 unless changed).
        joint_names: names of the actuated joints, in Pinocchio order (length nv).
        q_lower, q_upper: position bounds, shape (nq,), rad or m.
        v_lower, v_upper: velocity bounds, shape (nv,), rad/s or m/s.
        tau_lower, tau_upper: torque/force bounds, shape (nv,), N m or N (tau_lower < 0 < tau_upper, or
            both 0: a passive joint, no actuator; :mod:`fatigue_pin.ocp.actuators`).
        aba: ``casadi.Function`` (q[nq], v[nv], tau[nv]) -> ddq[nv], Pinocchio's ABA on SX.
        rnea: ``casadi.Function`` (q[nq], v[nv], a[nv]) -> tau[nv], Pinocchio's RNEA on SX.
        payload: the :class:`Payload` added to ``pin_model`` (and so to ``aba``, ``rnea``), or None.
        locked_joints: joints of the URDF held fixed (``(name, value)`` pairs, rad or m), removed
            from ``pin_model`` by Pinocchio's ``buildReducedModel``; empty: none.
        urdf_text: the URDF text the model was built from (runs store it): the file's, or the
            text written from an OpenSim model (:mod:`fatigue_pin.robot.osim`; ``urdf_path`` is
            then the ``.osim`` file).
    """

    name: str
    urdf_path: Path
    pin_model: pin.Model = field(repr=False)
    joint_names: tuple[str, ...]
    q_lower: np.ndarray = field(repr=False)
    q_upper: np.ndarray = field(repr=False)
    v_lower: np.ndarray = field(repr=False)
    v_upper: np.ndarray = field(repr=False)
    tau_lower: np.ndarray = field(repr=False)
    tau_upper: np.ndarray = field(repr=False)
    aba: ca.Function = field(repr=False)
    rnea: ca.Function = field(repr=False)
    payload: Payload | None = None
    locked_joints: tuple[tuple[str, float], ...] = ()
    urdf_text: str = field(default="", repr=False, compare=False)
    _frames: dict = field(default_factory=dict, init=False, repr=False, compare=False)
    _derivatives: list = field(default_factory=list, init=False, repr=False, compare=False)

    def aba_derivatives(self) -> ca.Function | None:
        """Pinocchio's analytical derivatives of ABA on SX (built once, then cached):
        ``(q, v, tau) -> (ddq, ddq_dq, ddq_dv, Minv)``
        (:func:`~fatigue_pin.robot.dynamics.casadi_aba_derivatives`), or None when nq != nv."""
        if not self._derivatives:
            self._derivatives.append(casadi_aba_derivatives(self.pin_model))
        return self._derivatives[0]

    # -- frame kinematics on CasADi symbols (fatigue_pin.robot.kinematics), cached per frame ----------

    def frame(self, frame: str):
        """:class:`~fatigue_pin.robot.kinematics.FrameFunctions` of ``frame`` (built once, then cached)."""
        from fatigue_pin.robot.kinematics import frame_functions, frame_id

        fid = frame_id(self.pin_model, frame)
        if fid not in self._frames:
            self._frames[fid] = frame_functions(self.pin_model, fid)
        return self._frames[fid]

    def frame_position(self, frame: str) -> ca.Function:
        """``casadi.Function`` q (nq) -> p (3): world position of ``frame``'s origin (m)."""
        return self.frame(frame).position

    def frame_rotation(self, frame: str) -> ca.Function:
        """``casadi.Function`` q (nq) -> R (3 x 3): world orientation of ``frame``."""
        return self.frame(frame).rotation

    def frame_velocity(self, frame: str) -> ca.Function:
        """``casadi.Function`` (q (nq), v (nv)) -> pdot (3): linear velocity of ``frame``'s origin,
        world axes (m/s)."""
        return self.frame(frame).velocity

    @property
    def joint_kinds(self) -> tuple[str, ...]:
        """Kind of every joint of :attr:`joint_names`: ``"revolute"`` (Pinocchio's
        ``JointModelR*``) or ``"prismatic"`` (``JointModelP*``)."""
        return tuple(joint_kind(self.pin_model.joints[i]) for i in range(1, self.pin_model.njoints))

    def joint_units(self, joint: int | str) -> JointUnits:
        """The :class:`JointUnits` of joint ``joint`` (its index in q, v, tau, or its name): rad,
        rad/s, N m for a revolute joint; m, m/s, N for a prismatic one."""
        j = self.joint_index(joint) if isinstance(joint, str) else int(joint)
        if not 0 <= j < self.nv:
            raise ModelError(f"joint index {j} is not in model {self.name!r}; expected 0 to {self.nv - 1}")
        return units_of_kind(self.joint_kinds[j])

    @property
    def nq(self) -> int:
        """Number of configuration variables."""
        return self.pin_model.nq

    @property
    def nv(self) -> int:
        """Number of velocity variables (= number of actuated joints)."""
        return self.pin_model.nv

    def joint_index(self, joint: str) -> int:
        """Index of ``joint`` in q, v and tau. Raises ModelError naming the known joints."""
        if joint not in self.joint_names:
            raise ModelError(f"joint {joint!r} is not in model {self.name!r}; its joints are {list(self.joint_names)}")
        return self.joint_names.index(joint)

    def check_state(self, q: np.ndarray, v: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Return q, v as float arrays of shapes (nq,), (nv,); raise DimensionError otherwise."""
        q = np.asarray(q, dtype=float).reshape(-1)
        v = np.zeros(self.nv) if v is None else np.asarray(v, dtype=float).reshape(-1)
        if q.size != self.nq:
            raise DimensionError(f"q has {q.size} entries; model {self.name!r} expects nq = {self.nq}")
        if v.size != self.nv:
            raise DimensionError(f"v has {v.size} entries; model {self.name!r} expects nv = {self.nv}")
        return q, v

    def gravity_torque(self, q: np.ndarray) -> np.ndarray:
        """Static holding torques g(q), shape (nv,), N m (torque that keeps the model still at q)."""
        q, v = self.check_state(q)
        return np.asarray(self.rnea(q, v, np.zeros(self.nv))).reshape(-1)

    def forward_dynamics(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """Joint accelerations from the CasADi ABA, shape (nv,)."""
        q, v = self.check_state(q, v)
        tau = np.asarray(tau, dtype=float).reshape(-1)
        if tau.size != self.nv:
            raise DimensionError(f"tau has {tau.size} entries; model {self.name!r} expects nv = {self.nv}")
        return np.asarray(self.aba(q, v, tau)).reshape(-1)

    def body_masses(self) -> dict[str, float]:
        """Mass carried by each joint's subtree body (kg), fixed bodies merged in, by joint name."""
        return {self.pin_model.names[i]: float(self.pin_model.inertias[i].mass) for i in range(1, self.pin_model.njoints)}

    def summary(self, q: np.ndarray | None = None) -> str:
        """Human-readable summary: joints, their kinds, masses, bounds and holding efforts at ``q``,
        each value in its joint's units (:meth:`joint_units`: rad, rad/s, N m for a revolute joint;
        m, m/s, N for a prismatic one).

        The default ``q`` of arm26 is (0.07 rad, 15 deg), the initial posture of the curl task;
        for other models it is the middle of the joint ranges.
        """
        if q is None:
            q = np.array([0.07, math.radians(15.0)]) if self.name == "arm26" else 0.5 * (self.q_lower + self.q_upper)
        q = self.check_state(q)[0]
        g = self.gravity_torque(q)
        masses = self.body_masses()
        units = [self.joint_units(j) for j in range(self.nv)]
        efforts = " and ".join(f"{e}s" for e in dict.fromkeys(u.effort_name for u in units))  # "torques", "forces and torques"
        w = max([14] + [len(n) + 2 for n in self.joint_names])  # the joint column
        lines = [
            f"model {self.name} ({self.urdf_path})",
            f"  nq = {self.nq}, nv = {self.nv}, total mass {sum(masses.values()):.4f} kg, "
            f"gravity {tuple(float(x) for x in self.pin_model.gravity.linear)} m/s^2",
            f"  {'joint':<{w}}{'kind':<11}{'mass (kg)':>10}{'q range':>26}{'|v| max':>18}{'effort range':>22}{'g(q)':>15}",
        ]
        for i, (name, u) in enumerate(zip(self.joint_names, units)):
            lines.append(
                f"  {name:<{w}}{u.kind:<11}{masses[name]:>10.4f}{f'[{self.q_lower[i]:.4f}, {self.q_upper[i]:.4f}] {u.position:<3}':>26}"
                f"{f'{self.v_upper[i]:.4f} {u.velocity:<5}':>18}{f'[{self.tau_lower[i]:.1f}, {self.tau_upper[i]:.1f}] {u.effort:<3}':>22}"
                f"{f'{g[i]:.4f} {u.effort:<3}':>15}".rstrip()
            )
        at = ", ".join(f"{v:.4g} {u.position}" for v, u in zip(q, units))
        held = ", ".join(f"{v:.4g} {u.effort}" for v, u in zip(g, units))
        lines.append(f"  holding {efforts} at q = ({at}): ({held})")
        return "\n".join(lines)


def _validate_joints(model: pin.Model, path: Path) -> None:
    """Reject floating bases and joints other than one-DoF revolute/prismatic, naming them."""
    for i in range(1, model.njoints):
        joint = model.joints[i]
        short = joint.shortname()
        if short == "JointModelFreeFlyer":
            raise ModelError(f"{path}: joint {model.names[i]!r} is a floating base; only fixed-base models are supported")
        if short not in _SUPPORTED_JOINTS:
            raise ModelError(
                f"{path}: joint {model.names[i]!r} is of unsupported type {short} (nq={joint.nq}, nv={joint.nv}); "
                "expected revolute or prismatic joints with one position and one velocity"
            )


def _urdf_path(urdf: str | Path | None) -> Path:
    """The path of an existing URDF file (the bundled arm26 for None); ModelError otherwise."""
    if urdf is None:
        return bundled_urdf("arm26")
    if not str(urdf).strip():
        raise ModelError("URDF path '' is empty; expected the path of an existing .urdf file")
    path = Path(urdf).expanduser()
    if path.is_dir():
        raise ModelError(f"URDF path {str(path)!r} is a folder; expected the path of a .urdf file")
    if not path.exists():
        raise ModelError(f"URDF file not found: {str(path)!r} (expected the path of an existing .urdf file)")
    return path


def resolve_model(name: str | Path | None = None, gravity: object = None, payload: Payload | None = None,
                  locked_joints: Mapping[str, float] | None = None) -> RobotModel:
    """Load a model by name or path: a bundled model (``arm26``), an example-robot-data name
    (``ur5``, ``panda``), or the path of a URDF file; ``payload`` adds a load at a frame and
    ``locked_joints`` holds joints fixed (:func:`load_model`).

    Raises:
        ModelError: a name that is none of these, or a file that cannot be loaded.
    """
    g = None if gravity is None else np.asarray(gravity, dtype=float)
    if name is None:
        return load_model(None, g, payload, locked_joints)
    text = str(name)
    if not text.strip():
        raise ModelError(f"model {text!r} is empty; expected a bundled model (arm26), an example-robot-data name "
                         f"{sorted(EXAMPLE_ROBOTS)} or the path of a URDF file")
    here = Path(__file__).resolve().parents[1]  # the package folder
    if text.isidentifier() and any((folder / f"{text}.urdf").is_file() for folder in (here / "urdf", here.parent / "urdf")):
        return load_model(bundled_urdf(text), g, payload, locked_joints)
    if text in EXAMPLE_ROBOTS:
        return load_model(example_robot_urdf(text), g, payload, locked_joints)
    path = Path(text).expanduser()
    if not path.suffix and not path.exists():
        raise ModelError(
            f"model {text!r} is not a bundled model (arm26), an example-robot-data name {sorted(EXAMPLE_ROBOTS)} or an existing URDF path"
        )
    return load_model(path, g, payload, locked_joints)


def lock_joints(model: pin.Model, locked: Mapping[str, float], path: Path) -> pin.Model:
    """``model`` with the joints of ``locked`` (name -> position, rad or m) held fixed at their
    values: Pinocchio's ``buildReducedModel`` merges the bodies they carry into their parents.

    Raises:
        ModelError: a name that is no joint of the model, a value that is not a finite number
            within the joint's position limits, or every joint locked.
    """
    q_ref = pin.neutral(model)
    ids = []
    movable = [model.names[i] for i in range(1, model.njoints)]
    for name, value in locked.items():
        if name not in movable:
            raise ModelError(f"model.locked_joints: joint {name!r} is not in {path.name}; its joints are {movable}")
        if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)) or not math.isfinite(value):
            raise ModelError(f"model.locked_joints.{name} = {shown(value)}: expected a finite joint position (rad or m)")
        j = model.getJointId(name)
        i = model.joints[j].idx_q
        lo, hi = float(model.lowerPositionLimit[i]), float(model.upperPositionLimit[i])
        if not lo - 1e-12 <= value <= hi + 1e-12:
            raise ModelError(f"model.locked_joints.{name} = {shown(value)}: expected a position within the joint's limits [{lo:g}, {hi:g}]")
        q_ref[i] = float(value)
        ids.append(j)
    if len(ids) == len(movable):
        raise ModelError(f"model.locked_joints locks every joint of {path.name}; expected at least one joint left to move")
    reduced = pin.buildReducedModel(model, sorted(ids), q_ref)
    reduced.name = model.name
    return reduced


def _is_vector3(v: object) -> bool:
    a = np.asarray(v, dtype=float).reshape(-1)
    return a.size == 3 and bool(np.all(np.isfinite(a)))


@dataclass(frozen=True)
class ModelSource:
    """Which model a study runs on (its ``[model]`` table): :meth:`load` gives the RobotModel.

    Attributes:
        urdf: a bundled model (``arm26``), an example-robot-data name (``ur5``, ``panda``) or the
            path of a URDF file (:func:`resolve_model`); "" with ``osim``.
        gravity: gravity (3,) in the world frame, m/s^2; None: the OpenSim model's (``osim``),
            else (0, 0, -9.81).
        payload: a rigid load fixed to a frame (:class:`Payload`), part of the dynamics; None: none.
        locked_joints: joints held fixed, name -> position (rad or m) within the joint's limits
            (:func:`lock_joints`, e.g. the Panda's fingers); None: none.
        muscles: the model's muscles: a bundled muscle file (``arm26``) or the path of a muscle
            file (docs/muscles.md); "": none. They drive the joints under ``[actuators] kind =
            "muscles"``.
        osim: the path of an OpenSim model (``.osim``, :mod:`fatigue_pin.robot.osim`): its skeleton
            and its muscles, instead of ``urdf`` and ``muscles``; "": none.
        ignore_wraps: with ``osim``, the wrap objects left out of the muscle paths: ``true``, every
            one fatigue_pin cannot model (ellipsoids, spheres, tori, a cylinder of one quadrant or
            over part of a path; otherwise each is refused in one line), or a list of wrap names.
        osim_effort: with ``osim``, the torque (N m) or force (N) limit of every joint (an OpenSim
            coordinate has none), > 0.
    """

    urdf: str = setting("", "a bundled model name, an example-robot-data name or a URDF path",
                        check=lambda v: isinstance(v, (str, Path)))
    gravity: tuple[float, float, float] | None = setting(None, "3 finite numbers (m/s^2, world frame)", _is_vector3)
    payload: Payload | None = setting(None, "a table { frame, mass (kg), com (m), inertia (kg m^2) }",
                                      lambda v: isinstance(v, Payload))
    locked_joints: dict[str, float] | None = setting(None, "a table { joint name = position (rad or m), ... }",
                                                     lambda v: isinstance(v, dict))
    muscles: str = setting("", "a bundled muscle file name (arm26) or a muscle file path", lambda v: isinstance(v, (str, Path)))
    osim: str = setting("", "the path of an OpenSim model (.osim)", lambda v: isinstance(v, (str, Path)))
    ignore_wraps: bool | tuple[str, ...] = setting(False, "true, false or a list of wrap object names",
                                                   lambda v: isinstance(v, bool) or (isinstance(v, (list, tuple))
                                                                                     and all(isinstance(x, str) for x in v)))
    osim_effort: float = setting(50.0, "a finite torque or force limit > 0 (N m or N)",
                                 lambda v: not isinstance(v, bool) and isinstance(v, (int, float)) and math.isfinite(v) and v > 0)

    def __post_init__(self) -> None:
        check_fields(self, ModelError)
        if isinstance(self.ignore_wraps, list):
            object.__setattr__(self, "ignore_wraps", tuple(self.ignore_wraps))
        if str(self.osim):
            for key in ("urdf", "muscles"):
                if str(getattr(self, key)):
                    raise ModelError(f"ModelSource.{key} = {str(getattr(self, key))!r} beside osim = {str(self.osim)!r}: an OpenSim "
                                     f"model brings its skeleton and its muscles; expected {key} left out")
        elif not str(self.urdf):
            raise ModelError("ModelSource.urdf = '': expected a bundled model name, an example-robot-data name or a URDF path "
                             "(or osim, the path of an OpenSim model)")
        else:
            for key, default in (("ignore_wraps", False), ("osim_effort", 50.0)):
                if getattr(self, key) != default:
                    raise ModelError(f"ModelSource.{key} = {shown(getattr(self, key))}: a setting of an OpenSim model; expected "
                                     "it with osim, or left out")

    def read_osim(self, muscles: bool = True):
        """The :class:`~fatigue_pin.robot.osim.OsimModel` of ``osim`` (ModelError without one);
        ``muscles`` False: its skeleton only."""
        from fatigue_pin.robot.osim import read_osim

        if not str(self.osim):
            raise ModelError("ModelSource.osim = '': no OpenSim model")
        return read_osim(self.osim, self.ignore_wraps, self.osim_effort, muscles)

    def load(self) -> RobotModel:
        """The RobotModel: of ``urdf`` (:func:`resolve_model`), or of the skeleton of ``osim``."""
        if str(self.osim):
            imported = self.read_osim(muscles=False)
            return load_model(imported.path, self.gravity, self.payload, self.locked_joints, text=imported.urdf)
        return resolve_model(self.urdf, gravity=self.gravity, payload=self.payload, locked_joints=self.locked_joints)


def _parse_urdf(text: str, path: Path) -> pin.Model:
    """Pinocchio's model of a URDF text (``path`` names it), its joints checked (:func:`_validate_joints`)."""
    with quiet_stderr() as parser_lines:
        try:
            model = pin.buildModelFromXML(text)
        except Exception as exc:  # Pinocchio raises ValueError/RuntimeError with the parser's message
            failure = exc
        else:
            failure = None
    if failure is not None:  # the parser's own lines (urdfdom) say what is wrong; Pinocchio's message does not
        said = [line.removeprefix("Error:").strip() for line in parser_lines if not line.startswith("at line")]
        raise ModelError(f"URDF file {str(path)!r} does not parse: {'; '.join(said + [' '.join(str(failure).split())])}") from failure
    _validate_joints(model, path)
    return model


def load_model(urdf: str | Path | None = None, gravity: np.ndarray | None = None, payload: Payload | None = None,
               locked_joints: Mapping[str, float] | None = None, *, text: str | None = None) -> RobotModel:
    """Load a fixed-base robot from a URDF file and build its CasADi dynamics.

    Args:
        urdf: URDF file; default the bundled arm26 (``urdf/arm26.urdf``). With ``text``, the
            file the text comes from (it names the model in messages and in ``urdf_path``).
        gravity: optional gravity vector (3,) in the world frame, m/s^2; default the URDF's own
            top-level ``<gravity xyz="..."/>`` (an OpenSim model's, :mod:`fatigue_pin.robot.osim`),
            else Pinocchio's (0, 0, -9.81).
        payload: an optional :class:`Payload` fixed to one of the model's frames; it is part of
            ``pin_model`` and of the CasADi dynamics (the URDF file is left as it is).
        locked_joints: joints held fixed, name -> position (rad or m) within the joint's limits
            (:func:`lock_joints`; e.g. the Panda's fingers): they leave q, v and tau.
        text: the URDF's text, instead of reading the file ``urdf``.

    Returns:
        A :class:`RobotModel`. Bounds come from the URDF ``<limit>`` tags; a missing or infinite
        velocity limit becomes +-10*pi rad/s, and a missing effort limit raises ModelError.

    Raises:
        ModelError: the file is missing or does not parse, the base floats, a joint is unsupported,
            a joint has no effort limit, or a joint moves no mass (zero mass and inertia).
    """
    path = _urdf_path(urdf) if text is None else Path(urdf if urdf is not None else "model.urdf")
    own_gravity = check_urdf_text(path, locked_joints or {}, text)
    if text is None:
        text = path.read_text()
    model = _parse_urdf(text, path)
    if locked_joints:
        model = lock_joints(model, dict(locked_joints), path)
    locked = tuple((str(k), float(v)) for k, v in (locked_joints or {}).items())
    if model.nv == 0:
        raise ModelError(f"{path}: the model has no movable joint")
    if gravity is None and own_gravity is not None:
        gravity = np.array(own_gravity)
    if gravity is not None:
        g = np.asarray(gravity, dtype=float).reshape(-1)
        if g.size != 3:
            raise DimensionError(f"gravity has {g.size} entries; expected 3 (m/s^2, world frame)")
        model.gravity.linear = g
    if payload is not None:
        payload.apply(model, "model")

    names = tuple(model.names[i] for i in range(1, model.njoints))
    q_lower, q_upper = np.array(model.lowerPositionLimit, dtype=float), np.array(model.upperPositionLimit, dtype=float)
    v_max = np.array(model.velocityLimit, dtype=float)
    v_max = np.where(np.isfinite(v_max) & (v_max > 0), v_max, 10 * math.pi)
    effort = np.array(model.effortLimit, dtype=float)
    for name, e in zip(names, effort):
        if not (np.isfinite(e) and e >= 0):
            raise ModelError(f"{path}: joint {name!r} has effort limit {e}; expected a finite effort >= 0 in its <limit> tag "
                             "(0: a passive joint)")
    inertia = np.diag(pin.crba(model, model.createData(), pin.neutral(model)))
    for name, m in zip(names, inertia):
        if not (np.isfinite(m) and m > 1e-12):
            raise ModelError(f"{path}: joint {name!r} moves no mass (inertia {m:g} about its axis); "
                             "expected the links it moves to have an <inertial> with mass > 0")
    aba, rnea = casadi_dynamics(model)
    return RobotModel(
        name=model.name,
        urdf_path=path.resolve(),
        pin_model=model,
        joint_names=names,
        q_lower=q_lower,
        q_upper=q_upper,
        v_lower=-v_max,
        v_upper=v_max,
        tau_lower=-effort,
        tau_upper=effort.copy(),
        aba=aba,
        rnea=rnea,
        payload=payload,
        locked_joints=locked,
        urdf_text=text,
    )
