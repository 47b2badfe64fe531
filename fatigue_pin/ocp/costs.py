"""Named cost terms: the objective is a weighted sum of integrals over the horizon.

Each :class:`CostTerm` has a name, a weight and an integrand: an expression of one shooting
interval's state x_k, control u_k and previous control u_{k-1} (on CasADi SX symbols). The
objective is::

    J = sum_k dt * sum_i w_i * L_i(x_k, u_k, u_{k-1})          (rectangle rule, k = 0..N-1)

with u_{-1} := u_0. The weights are parameters of the NLP, so one compiled NLP serves every
choice of weights, and per-cycle costs are reported per term name.

Built-in terms (:data:`COST_KINDS`)::

    posture      sum_{j in joints} q_j^2                 (rad^2)
    velocity     sum_{j in joints} qdot_j^2              ((rad/s)^2)
    torque_rate  |u_k - u_{k-1}|^2   all halves           (N^2 m^2)
    fatigue      sum_h m_fatigued,h^2                     (1)
    torque       |u_k|^2             all halves           (N^2 m^2)

A term of your own needs no change to the package::

    CostTerm("elbow_velocity", 1.0, lambda v: v.qdot("elbow") ** 2)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Sequence

import casadi as ca

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.core.text import shown


@dataclass(frozen=True)
class IntervalVariables:
    """The symbols of one shooting interval, addressed by name, for cost integrands.

    Attributes:
        x: state (nx,) at the start of the interval; u: control (nu,) = (tau_plus, tau_minus) of
            the actuated joints;
        u_prev: the previous interval's control (nu,).
        layout: the :class:`~fatigue_pin.ocp.transcription.StateLayout`; model: the RobotModel;
        actuators: the :class:`~fatigue_pin.ocp.actuators.SignedTorqueActuators`.
    """

    x: ca.SX
    u: ca.SX
    u_prev: ca.SX
    layout: object
    model: object
    actuators: object

    def _joint_rows(self, joints: str | Sequence[str] | None) -> list[int]:
        names = self.model.joint_names
        if joints is None:
            return list(range(len(names)))
        joints = [joints] if isinstance(joints, str) else list(joints)
        for j in joints:
            if j not in names:
                raise ParameterError(f"cost term joint {j!r} is not in model {self.model.name!r}; its joints are {list(names)}")
        return [names.index(j) for j in joints]

    def q(self, joints: str | Sequence[str] | None = None) -> ca.SX:
        """Joint positions (rad or m) of ``joints`` (a name, names, or all)."""
        rows = self._joint_rows(joints)
        return self.x[self.layout.q][rows] if rows else ca.SX(0, 1)

    def qdot(self, joints: str | Sequence[str] | None = None) -> ca.SX:
        """Joint velocities (rad/s or m/s) of ``joints``."""
        rows = self._joint_rows(joints)
        return self.x[self.layout.v][rows] if rows else ca.SX(0, 1)

    @property
    def tau_plus(self) -> ca.SX:
        """Flexion-half torques of the actuated joints (N m), (na,)."""
        return self.u[: self.actuators.n_actuated]

    @property
    def tau_minus(self) -> ca.SX:
        """Extension-half torques of the actuated joints (N m), (na,)."""
        return self.u[self.actuators.n_actuated :]

    @property
    def tau(self) -> ca.SX:
        """Joint torques (N m), (nv,), as the actuators deliver them
        (:meth:`~fatigue_pin.ocp.actuators.SignedTorqueActuators.joint_torque`: 0 on passive joints)."""
        return self.actuators.joint_torque(self.u, self.x[self.layout.m])

    def fatigue(self, state: str) -> ca.SX:
        """Fatigue state ``state`` (e.g. ``"mf"``) of every half, (n_halves,)."""
        return self.actuators.state(self.x[self.layout.m], state)

    @property
    def fatigued(self) -> ca.SX:
        """Fatigued fraction of every half (each model's ``fatigued_state``), (n_halves,)."""
        return self.actuators.fatigued(self.x[self.layout.m])


Integrand = Callable[[IntervalVariables], ca.SX]


def _check_weight(owner: str, weight: object) -> float:
    if isinstance(weight, bool) or not isinstance(weight, (int, float)) or not math.isfinite(float(weight)) or float(weight) < 0:
        raise ParameterError(f"{owner}.weight = {shown(weight)}: expected a finite weight >= 0")
    return float(weight)


@dataclass(frozen=True)
class CostTerm:
    """One named term of the objective.

    Attributes:
        name: the term's name (a key of per-cycle costs, result files and plots).
        weight: its weight (>= 0); a parameter of the NLP.
        integrand: ``integrand(v: IntervalVariables) -> SX`` scalar (or a vector, whose squares
            are NOT taken: return the scalar you want integrated).
        options: what the term was built from (e.g. ``{"joints": ["shoulder"]}``), for study files.
        kind: the built-in kind it came from, or ``""`` for a user's own term.
    """

    name: str
    weight: float
    integrand: Integrand = field(compare=False)
    options: dict = field(default_factory=dict, compare=False)
    kind: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise ParameterError(f"cost term name {self.name!r}: expected an identifier (letters, digits, _)")
        object.__setattr__(self, "weight", _check_weight(f"CostTerm({self.name!r})", self.weight))
        if not callable(self.integrand):
            raise ParameterError(f"CostTerm({self.name!r}).integrand: expected a function of IntervalVariables")

    def with_weight(self, weight: float) -> CostTerm:
        return CostTerm(self.name, weight, self.integrand, dict(self.options), self.kind)

    def expression(self, v: IntervalVariables) -> ca.SX:
        """The integrand on ``v``, checked to be a scalar."""
        e = self.integrand(v)
        e = ca.SX(e) if not isinstance(e, ca.SX) else e
        if e.numel() != 1:
            raise ParameterError(f"cost term {self.name!r} integrand has shape {e.shape}: expected a scalar")
        return e


def posture(weight: float, joints: Sequence[str] = (), name: str = "posture") -> CostTerm:
    """``sum_{j in joints} q_j^2`` (rad^2): keeps the named joints near 0."""
    joints = tuple(joints)
    return CostTerm(name, weight, lambda v: ca.sumsqr(v.q(joints)) if joints else ca.SX(0), {"joints": list(joints)}, "posture")


def velocity(weight: float, joints: Sequence[str] | None = None, name: str = "velocity") -> CostTerm:
    """``sum_{j in joints} qdot_j^2`` ((rad/s)^2); every joint by default."""
    js = None if joints is None else tuple(joints)
    return CostTerm(name, weight, lambda v: ca.sumsqr(v.qdot(js)), {} if js is None else {"joints": list(js)}, "velocity")


def torque_rate(weight: float, name: str = "torque_rate") -> CostTerm:
    """``|u_k - u_{k-1}|^2`` over every actuator half (N^2 m^2)."""
    return CostTerm(name, weight, lambda v: ca.sumsqr(v.u - v.u_prev), {}, "torque_rate")


def fatigue(weight: float, name: str = "fatigue") -> CostTerm:
    """``sum_h mf_h^2``: the fatigued fraction of every half squared."""
    return CostTerm(name, weight, lambda v: ca.sumsqr(v.fatigued), {}, "fatigue")


def torque(weight: float, name: str = "torque") -> CostTerm:
    """``|u_k|^2`` over every actuator half (N^2 m^2)."""
    return CostTerm(name, weight, lambda v: ca.sumsqr(v.u), {}, "torque")


#: Built-in cost kinds by name: ``kind(weight, **options) -> CostTerm``.
COST_KINDS: dict[str, Callable[..., CostTerm]] = {
    "posture": posture,
    "velocity": velocity,
    "torque_rate": torque_rate,
    "fatigue": fatigue,
    "torque": torque,
}


def cost_term(kind: str, weight: float, name: str | None = None, **options: object) -> CostTerm:
    """A built-in term by kind, e.g. ``cost_term("posture", 1e4, joints=["shoulder"])``."""
    if kind not in COST_KINDS:
        raise ParameterError(f"cost kind {kind!r} is unknown; expected one of {sorted(COST_KINDS)} (or a CostTerm of your own)")
    try:
        return COST_KINDS[kind](weight, name=name or kind, **options)
    except TypeError as exc:
        raise ParameterError(f"cost {name or kind!r}: bad options {sorted(options)} for kind {kind!r} ({exc})") from None


def check_costs(terms: Sequence[CostTerm]) -> tuple[CostTerm, ...]:
    """The terms as a tuple, refusing duplicates and non-terms."""
    out = tuple(terms)
    seen: set[str] = set()
    for t in out:
        if not isinstance(t, CostTerm):
            raise ParameterError(f"cost term {t!r}: expected a CostTerm")
        if t.name in seen:
            raise ParameterError(f"cost term {t.name!r} appears twice; expected unique names")
        seen.add(t.name)
    return out
