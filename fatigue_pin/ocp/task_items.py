"""The items of a task (:mod:`fatigue_pin.ocp.task`): what the body must do at a phase of every
cycle, or at every node, each a frozen dataclass checked when it is made.

* :class:`JointTarget` (a joint's value and/or velocity at a phase), :class:`JointRange`,
  :class:`StateTarget` (any state by its layout name), :class:`StateConstraint` (any expression of
  the state, a ``casadi.Function`` the caller builds);
* the Cartesian items :class:`FrameTarget`, :class:`FrameOrientation`, :class:`FramePlane`, each
  building its :class:`StateConstraint` from the model's frame kinematics.

Phases are fractions of the cycle in [0, 1), or :data:`END` (the last node of every phase of a
non-cyclic task), given as ``"end"`` or 1.0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence, Union

import casadi as ca
import numpy as np

from fatigue_pin.core.errors import TaskError
from fatigue_pin.core.text import shown

__all__ = ["END", "FRAME_AXES", "FRAME_TARGET_SHAPES", "FrameOrientation", "FramePlane", "FrameTarget", "JointRange", "JointTarget", "Phase",
           "StateConstraint", "StateTarget", "TaskItem", "phase_label", "phase_value"]


def _finite(owner: str, name: str, value: object, what: str = "a finite number") -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)) or not math.isfinite(float(value)):
        raise TaskError(f"{owner}.{name} = {shown(value)}: expected {what}")
    return float(value)


#: The phase of an item at the end of every cycle (phase) of a non-cyclic task: its last node.
END = "end"
#: A phase: a fraction of the cycle in [0, 1), or :data:`END`.
Phase = Union[float, str]


def _phase(owner: str, at: object, end: bool = True) -> Phase:
    """A phase in [0, 1); or, where ``end``, :data:`END` (given as ``"end"`` or as 1.0)."""
    what = 'a phase of the cycle in [0, 1) or "end"' if end else "a phase of the cycle in [0, 1)"
    if end and (at == END or (isinstance(at, (int, float, np.floating, np.integer)) and not isinstance(at, bool) and at == 1.0)):
        return END
    if isinstance(at, str):
        raise TaskError(f"{owner}.at = {shown(at)}: expected {what}")
    x = _finite(owner, "at", at, what)
    if not 0.0 <= x < 1.0:
        raise TaskError(f"{owner}.at = {shown(at)}: expected {what}")
    return x


def phase_value(at: Phase) -> float:
    """A phase as a number for ordering and timing: :data:`END` is 1.0."""
    return 1.0 if at == END else float(at)


def phase_label(at: Phase) -> str:
    """A phase as messages write it: ``0.5``, ``end``."""
    return END if at == END else f"{at:g}"


def _target_text(t: "JointTarget") -> str:
    """A joint target's values as messages write them: ``3.14 (+- 0)``, ``velocity 0 (+- 0)``."""
    parts = [] if t.value is None else [f"{shown(t.value)} (+- {t.tolerance:g})"]
    if t.velocity is not None:
        parts.append(f"velocity {shown(t.velocity)} (+- {t.velocity_tolerance:g})")
    return ", ".join(parts)


def _item_label(item: object) -> str:
    """An item as messages name it: ``JointTarget('pendulum')``, ``FrameTarget('tool0')``."""
    name = next((getattr(item, a) for a in ("joint", "state", "frame", "name") if isinstance(getattr(item, a, None), str)), "")
    return f"{type(item).__name__}({name!r})"


def _tolerance(owner: str, name: str, value: object) -> float:
    tol = _finite(owner, name, value, "a finite tolerance >= 0")
    if tol < 0:
        raise TaskError(f"{owner}.{name} = {shown(value)}: expected a tolerance >= 0")
    return tol


@dataclass(frozen=True)
class JointTarget:
    """Joint ``joint`` at ``value`` (rad, or m for a prismatic joint) within ``+- tolerance``,
    and/or moving at ``velocity`` (rad/s or m/s) within ``+- velocity_tolerance``, at phase ``at``
    of every cycle (``"end"``: the last node of every phase of a non-cyclic task). A target needs
    a value, a velocity or both."""

    joint: str
    value: float | None = None
    at: Phase = 0.0
    tolerance: float = 0.0
    velocity: float | None = None
    velocity_tolerance: float = 0.0

    def __post_init__(self) -> None:
        owner = f"JointTarget({self.joint!r})"
        if self.value is None and self.velocity is None:
            raise TaskError(f"{owner}: expected a value (rad or m), a velocity (rad/s or m/s) or both")
        if self.value is not None:
            object.__setattr__(self, "value", _finite(owner, "value", self.value))
        if self.velocity is not None:
            object.__setattr__(self, "velocity", _finite(owner, "velocity", self.velocity))
        object.__setattr__(self, "at", _phase(owner, self.at))
        object.__setattr__(self, "tolerance", _tolerance(owner, "tolerance", self.tolerance))
        object.__setattr__(self, "velocity_tolerance", _tolerance(owner, "velocity_tolerance", self.velocity_tolerance))


@dataclass(frozen=True)
class StateTarget:
    """State ``state`` (a name of the problem's state layout,
    :meth:`~fatigue_pin.ocp.problem.StateLayout.state_names`: ``"<joint>_q"``, ``"<joint>_qdot"``
    or a fatigue state ``"<half>_<state>"`` such as ``"elbow_plus_mf"``) at ``value`` within
    ``+- tolerance`` at phase ``at`` (``"end"`` by default: the end state of every phase)."""

    state: str
    value: float
    at: Phase = END
    tolerance: float = 0.0

    def __post_init__(self) -> None:
        owner = f"StateTarget({self.state!r})"
        if not isinstance(self.state, str) or not self.state:
            raise TaskError(f"{owner}.state: expected the name of a state")
        object.__setattr__(self, "value", _finite(owner, "value", self.value))
        object.__setattr__(self, "at", _phase(owner, self.at))
        object.__setattr__(self, "tolerance", _tolerance(owner, "tolerance", self.tolerance))


@dataclass(frozen=True)
class JointRange:
    """Joint ``joint`` within ``[lower, upper]`` (rad or m) at every node."""

    joint: str
    lower: float
    upper: float

    def __post_init__(self) -> None:
        owner = f"JointRange({self.joint!r})"
        lo = _finite(owner, "lower", self.lower)
        hi = _finite(owner, "upper", self.upper)
        if lo > hi:
            raise TaskError(f"{owner}: lower = {shown(lo)} > upper = {shown(hi)}; expected lower <= upper")
        object.__setattr__(self, "lower", lo)
        object.__setattr__(self, "upper", hi)


@dataclass(frozen=True)
class StateConstraint:
    """``lower <= expression(x) <= upper`` at phase ``at`` of every cycle, or at every node
    (``at = None``).

    Attributes:
        name: a label (used in messages and results).
        expression: a ``casadi.Function`` of the state x (nx,) with one output (m,); build it from
            the model (e.g. a frame position from :mod:`fatigue_pin.robot.model`'s kinematics).
        lower, upper: bounds, shape (m,) (use +-inf for one-sided bounds).
        at: phase in [0, 1), or None for every node.
    """

    name: str
    expression: ca.Function
    lower: Sequence[float]
    upper: Sequence[float]
    at: float | None = None

    def __post_init__(self) -> None:
        owner = f"StateConstraint({self.name!r})"
        if not isinstance(self.expression, ca.Function) or self.expression.n_in() != 1 or self.expression.n_out() != 1:
            raise TaskError(f"{owner}.expression: expected a casadi.Function of the state x with one output")
        m = self.expression.size1_out(0) * self.expression.size2_out(0)
        lo = np.broadcast_to(np.asarray(self.lower, dtype=float), (m,)).copy()
        hi = np.broadcast_to(np.asarray(self.upper, dtype=float), (m,)).copy()
        if np.any(np.isnan(lo)) or np.any(np.isnan(hi)) or np.any(lo > hi):
            raise TaskError(f"{owner}: bounds {lo.tolist()}, {hi.tolist()}: expected lower <= upper, no NaN")
        object.__setattr__(self, "lower", tuple(lo))
        object.__setattr__(self, "upper", tuple(hi))
        if self.at is not None:
            object.__setattr__(self, "at", _phase(owner, self.at))


def _vector(owner: str, name: str, value: object, n: int = 3, what: str = "3 finite numbers") -> tuple[float, ...]:
    try:
        a = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise TaskError(f"{owner}.{name} = {shown(value)}: expected {what}") from None
    if a.size != n or not np.all(np.isfinite(a)):
        raise TaskError(f"{owner}.{name} = {shown(value)}: expected {what}")
    return tuple(float(x) for x in a)


def _function_name(text: str) -> str:
    """A valid casadi.Function name from a label (letters, digits, single underscores)."""
    import re

    name = re.sub(r"_+", "_", re.sub(r"[^A-Za-z0-9]", "_", text)).strip("_")
    return name if name[:1].isalpha() else f"f_{name}"


def _check_frame(owner: str, model, frame: str) -> None:
    from fatigue_pin.core.errors import ModelError
    from fatigue_pin.robot.kinematics import frame_id

    try:
        frame_id(model.pin_model, frame)
    except ModelError as exc:
        raise TaskError(f"{owner}: {exc}") from None


#: shapes of the tolerance region of a :class:`FrameTarget`
FRAME_TARGET_SHAPES = ("ball", "box")
#: the world axes a :class:`FrameTarget` may hold
FRAME_AXES = ("x", "y", "z")


@dataclass(frozen=True)
class FrameTarget:
    """The origin of frame ``frame`` at ``position`` (m, world frame) at phase ``at`` of every
    cycle, within ``tolerance`` (m): a ball of that radius (``shape = "ball"``) or a box of that
    half-width (``"box"``). A zero tolerance pins the point (an equality row per axis).
    ``axes`` names the world axes held (``"x"``, ``"y"``, ``"z"``; default all three): with fewer,
    the point is held on those coordinates only (``["x", "z"]`` leaves its ``y`` free), and the
    ball or the box is of those axes.

    It becomes a :class:`StateConstraint` (:meth:`constraint`) on the frame position from
    Pinocchio's kinematics on CasADi symbols (:meth:`RobotModel.frame_position`). The ball is the
    row ``(|p - position|^2 - tolerance^2) / (2 tolerance) <= 0``, about ``|p - position| -
    tolerance`` near its surface, so the solver's constraint tolerance is in metres.
    """

    frame: str
    position: tuple[float, float, float]
    at: Phase = 0.0
    tolerance: float = 0.0
    shape: str = "ball"
    axes: tuple[str, ...] = FRAME_AXES

    def __post_init__(self) -> None:
        owner = f"FrameTarget({self.frame!r})"
        axes = tuple(self.axes) if isinstance(self.axes, (list, tuple)) else None
        if not axes or not all(a in FRAME_AXES for a in axes) or len(set(axes)) != len(axes):
            raise TaskError(f"{owner}.axes = {shown(self.axes)}: expected some of {list(FRAME_AXES)}, each once (world axes)")
        object.__setattr__(self, "axes", tuple(a for a in FRAME_AXES if a in axes))
        object.__setattr__(self, "position", _vector(owner, "position", self.position, what="3 finite numbers (m, world frame)"))
        object.__setattr__(self, "at", _phase(owner, self.at))
        tol = _finite(owner, "tolerance", self.tolerance, "a finite tolerance >= 0 (m)")
        if tol < 0:
            raise TaskError(f"{owner}.tolerance = {shown(self.tolerance)}: expected a tolerance >= 0 (m)")
        object.__setattr__(self, "tolerance", tol)
        if self.shape not in FRAME_TARGET_SHAPES:
            raise TaskError(f"{owner}.shape = {shown(self.shape)}: expected one of {list(FRAME_TARGET_SHAPES)}")

    @property
    def name(self) -> str:
        return f"{self.frame}_position_at_{phase_label(self.at)}"

    @property
    def rows(self) -> list[int]:
        """The rows of :attr:`axes` in a position (3,)."""
        return [FRAME_AXES.index(a) for a in self.axes]

    def distance(self, p: np.ndarray) -> float:
        """How far ``p`` (3,) is outside the tolerance region (m; <= 0 inside)."""
        d = (np.asarray(p, dtype=float) - np.asarray(self.position))[self.rows]
        if self.shape == "box" or self.tolerance == 0.0:
            return float(np.max(np.abs(d)) - self.tolerance)
        return float(np.linalg.norm(d) - self.tolerance)

    def constraint(self, model, layout) -> StateConstraint:
        x = ca.SX.sym("x", layout.nx)
        d = (model.frame_position(self.frame)(x[layout.q]) - ca.DM(self.position))[self.rows]
        tol = self.tolerance
        if self.shape == "box" or tol == 0.0:
            expr, lower, upper = d, -tol, tol
        else:
            expr, lower, upper = (ca.dot(d, d) - tol * tol) / (2 * tol), -np.inf, 0.0
        return StateConstraint(self.name, ca.Function(_function_name(self.name), [x], [expr]), lower, upper, self.at)

    def check(self, model, q_init: np.ndarray | None = None) -> None:
        """Unknown frame, or a target out of the frame's reach (:func:`fatigue_pin.robot.kinematics.reach`)."""
        from fatigue_pin.robot.kinematics import reach

        owner = f"task frame target of {self.frame!r}"
        _check_frame(owner, model, self.frame)
        centre, radius = reach(model.pin_model, self.frame)
        distance = float(np.linalg.norm((np.asarray(self.position) - centre)[self.rows]))  # to the nearest point of the held axes
        if distance - self.tolerance * math.sqrt(3) > radius:
            raise TaskError(
                f"{owner}: position {shown(self.position)} m is out of reach: {distance:.3f} m from the base of its chain at "
                f"{np.round(centre, 3).tolist()}, which reaches at most {radius:.3f} m (the sum of its link lengths)"
            )
        if q_init is not None and self.at == 0.0:  # node 0 is the initial state: it must meet the target
            from fatigue_pin.robot.kinematics import frame_placement

            off = self.distance(frame_placement(model.pin_model, self.frame, q_init).translation)
            if off > 1e-9:
                raise TaskError(
                    f"{owner}: the initial configuration puts the frame {off:.4f} m outside its phase-0 target "
                    f"{shown(self.position)} +- {self.tolerance:g} m; set task.q_init to a posture that meets it "
                    "(fatigue_pin.robot.ik.solve_ik finds one)"
                )


@dataclass(frozen=True)
class FrameOrientation:
    """Frame ``frame`` oriented as ``rotation`` (3 x 3, world frame; or 3 roll-pitch-yaw angles,
    rad) within ``tolerance`` (rad, > 0) at phase ``at`` of every cycle: the row
    ``cos(angle(R, rotation)) - cos(tolerance) >= 0``."""

    frame: str
    rotation: tuple[float, ...]
    at: float = 0.0
    tolerance: float = 0.05

    def __post_init__(self) -> None:
        owner = f"FrameOrientation({self.frame!r})"
        a = np.asarray(self.rotation, dtype=float)
        if a.size == 3:
            import pinocchio as pin

            a = pin.rpy.rpyToMatrix(*_vector(owner, "rotation", a))
        R = np.asarray(_vector(owner, "rotation", a, 9, "a rotation matrix (3 x 3) or 3 roll-pitch-yaw angles (rad)")).reshape(3, 3)
        if not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
            raise TaskError(f"{owner}.rotation = {shown(self.rotation)}: expected a rotation matrix (orthonormal, det 1)")
        object.__setattr__(self, "rotation", tuple(R.reshape(-1)))
        object.__setattr__(self, "at", _phase(owner, self.at))
        tol = _finite(owner, "tolerance", self.tolerance, "an angle in (0, pi] (rad)")
        if not 0 < tol <= math.pi:
            raise TaskError(f"{owner}.tolerance = {shown(self.tolerance)}: expected an angle in (0, pi] (rad)")
        object.__setattr__(self, "tolerance", tol)

    @property
    def name(self) -> str:
        return f"{self.frame}_orientation_at_{phase_label(self.at)}"

    @property
    def matrix(self) -> np.ndarray:
        return np.asarray(self.rotation).reshape(3, 3)

    def constraint(self, model, layout) -> StateConstraint:
        x = ca.SX.sym("x", layout.nx)
        R = model.frame_rotation(self.frame)(x[layout.q])
        cos_angle = (ca.trace(ca.DM(self.matrix).T @ R) - 1) / 2
        return StateConstraint(self.name, ca.Function(_function_name(self.name), [x], [cos_angle - math.cos(self.tolerance)]), 0.0, np.inf, self.at)

    def check(self, model, q_init: np.ndarray | None = None) -> None:
        _check_frame(f"task orientation target of {self.frame!r}", model, self.frame)


@dataclass(frozen=True)
class FramePlane:
    """The origin of frame ``frame`` on the positive side of a plane: ``normal . p(q) >= offset``
    (m, world frame; ``normal`` is made unit) at every node (``at = None``), e.g. "the hand
    stays above the table", or at phase ``at`` only."""

    frame: str
    normal: tuple[float, float, float]
    offset: float
    at: float | None = None

    def __post_init__(self) -> None:
        owner = f"FramePlane({self.frame!r})"
        n = np.asarray(_vector(owner, "normal", self.normal, what="3 finite numbers, not all 0"))
        if np.linalg.norm(n) < 1e-12:
            raise TaskError(f"{owner}.normal = {shown(self.normal)}: expected 3 finite numbers, not all 0")
        object.__setattr__(self, "normal", tuple(float(v) for v in n / np.linalg.norm(n)))
        object.__setattr__(self, "offset", _finite(owner, "offset", self.offset, "a finite distance (m)"))
        if self.at is not None:
            object.__setattr__(self, "at", _phase(owner, self.at))

    @property
    def name(self) -> str:
        return f"{self.frame}_plane" + ("" if self.at is None else f"_at_{phase_label(self.at)}")

    def height(self, p: np.ndarray) -> float:
        """Signed distance of ``p`` (3,) above the plane (m)."""
        return float(np.dot(self.normal, p) - self.offset)

    def constraint(self, model, layout) -> StateConstraint:
        x = ca.SX.sym("x", layout.nx)
        p = model.frame_position(self.frame)(x[layout.q])
        return StateConstraint(self.name, ca.Function(_function_name(self.name), [x], [ca.dot(ca.DM(self.normal), p)]), self.offset, np.inf, self.at)

    def check(self, model, q_init: np.ndarray | None = None) -> None:
        """Unknown frame, or an initial configuration below the plane (a bound over every node)."""
        owner = f"task plane of {self.frame!r}"
        _check_frame(owner, model, self.frame)
        if q_init is not None and self.at is None:
            from fatigue_pin.robot.kinematics import frame_placement

            h = self.height(frame_placement(model.pin_model, self.frame, q_init).translation)
            if h < -1e-9:
                raise TaskError(f"{owner}: the initial configuration puts the frame {-h:.4f} m below the plane "
                                f"normal {shown(self.normal)} . p >= {self.offset:g}; expected q_init on its positive side")


TaskItem = Union[JointTarget, JointRange, StateTarget, StateConstraint, FrameTarget, FrameOrientation, FramePlane]
