"""Named cost terms: the objective is a weighted sum of integrals over the horizon.

Each :class:`CostTerm` has a name, a weight and an integrand: an expression of one shooting
interval's state x_k, control u_k and previous control u_{k-1} (on CasADi SX symbols). The
objective is::

    J = sum_k dt * sum_i w_i * L_i(x_k, u_k, u_{k-1})          (rectangle rule, k = 0..N-1)

with u_{-1} := u_0. The weights are parameters of the NLP, so one compiled NLP serves every
choice of weights, and per-cycle costs are reported per term name.

Built-in terms (:data:`COST_KINDS`), each over the joints ``joints`` (default: every joint;
``posture``: none) with per-joint weights ``joint_weights`` (default 1)::

    posture      sum_j c_j q_j^2                          (rad^2 or m^2)
    velocity     sum_j c_j qdot_j^2                       ((rad/s)^2 or (m/s)^2)
    torque_rate  sum_j c_j sum_{h of j} (u_h,k - u_h,k-1)^2  (N^2 m^2 or N^2)
    fatigue      sum_j c_j sum_{h of j} m_fatigued,h^2       (1)
    torque       sum_j c_j sum_{h of j} u_h,k^2              (N^2 m^2 or N^2)
    activation   sum_i a_i,k^2 over the muscles              (1; muscle actuators only)
    residual     sum_h u_h,k^2 over the residual torques     (N^2 m^2; muscles with residual torques only)
    state        sum_i c_i (x_{s_i} - target_i)^2         states by name (StateLayout.state_names)
    frame        |p_frame(q) - position|^2                (m^2)

A term at ``at = "end"`` is a terminal cost: ``w * L(x)`` on the state at the last node of every
phase (nodes n, 2n, ..., N), not integrated; only terms of the state may be terminal (``posture``,
``velocity``, ``fatigue``, ``state``, ``frame``, or a term of your own that reads no control)::

    J = sum_k dt * sum_{i running} w_i L_i(x_k, u_k, u_{k-1}) + sum_{e in ends} sum_{i terminal} w_i L_i(x_e)

A term of your own needs no change to the package::

    CostTerm("elbow_velocity", 1.0, lambda v: v.qdot("elbow") ** 2)
"""

from __future__ import annotations

import inspect
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
        return self.actuators.joint_torque(self.u, self.x[self.layout.m], self.x[: self.layout.nq + self.layout.nv])

    def tau_halves(self, joints: str | Sequence[str] | None = None) -> ca.SX:
        """Torques of the halves of ``joints`` (N m or N): ``(plus of each, minus of each)``, (2 len(joints),)."""
        rows = self._joint_rows(joints)
        return ca.vertcat(self.tau_plus[rows], self.tau_minus[rows]) if rows else ca.SX(0, 1)

    def tau_halves_prev(self, joints: str | Sequence[str] | None = None) -> ca.SX:
        """:meth:`tau_halves` of the previous interval's control."""
        rows = self._joint_rows(joints)
        nv = self.layout.nv
        return ca.vertcat(self.u_prev[:nv][rows], self.u_prev[nv:][rows]) if rows else ca.SX(0, 1)

    def fatigued_of(self, joints: str | Sequence[str] | None = None) -> ca.SX:
        """Fatigued fraction of the halves of ``joints``, (halves of those joints,)."""
        names = self.actuators.half_names
        rows = [names.index(f"{self.model.joint_names[j]}_{side}") for j in self._joint_rows(joints) for side in ("plus", "minus")
                if f"{self.model.joint_names[j]}_{side}" in names]
        return self.fatigued[rows] if rows else ca.SX(0, 1)

    def state(self, name: str) -> ca.SX:
        """The state named ``name`` (:attr:`~fatigue_pin.ocp.problem.StateLayout.state_names`)."""
        return self.x[self.layout.state_row(name)]

    def frame_position(self, frame: str) -> ca.SX:
        """World position (m) of frame ``frame``'s origin, (3,)."""
        return self.model.frame_position(frame)(self.x[self.layout.q])

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


#: The phase of a terminal cost term: the end of every phase.
END = "end"


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
        at: ``None``: integrated over every interval (a running cost); ``"end"``: a terminal
            cost on the state at the end of every phase (its integrand may read no control).
    """

    name: str
    weight: float
    integrand: Integrand = field(compare=False)
    options: dict = field(default_factory=dict, compare=False)
    kind: str = ""
    at: str | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise ParameterError(f"cost term name {self.name!r}: expected an identifier (letters, digits, _)")
        object.__setattr__(self, "weight", _check_weight(f"CostTerm({self.name!r})", self.weight))
        if not callable(self.integrand):
            raise ParameterError(f"CostTerm({self.name!r}).integrand: expected a function of IntervalVariables")
        if self.at is not None and self.at != END:
            raise ParameterError(f"CostTerm({self.name!r}).at = {shown(self.at)}: expected \"end\" (a terminal cost) or none (a running cost)")

    @property
    def terminal(self) -> bool:
        """A terminal cost (``at = "end"``)."""
        return self.at == END

    def with_weight(self, weight: float) -> CostTerm:
        return CostTerm(self.name, weight, self.integrand, dict(self.options), self.kind, self.at)

    def expression(self, v: IntervalVariables) -> ca.SX:
        """The integrand on ``v``, checked to be a scalar (and, terminal, free of the controls)."""
        e = self.integrand(v)
        e = ca.SX(e) if not isinstance(e, ca.SX) else e
        if e.numel() != 1:
            raise ParameterError(f"cost term {self.name!r} integrand has shape {e.shape}: expected a scalar")
        if self.terminal and (ca.depends_on(e, v.u) or ca.depends_on(e, v.u_prev)):
            raise ParameterError(f"cost term {self.name!r} at the end reads the controls: expected a term of the state "
                                 "(a terminal cost is evaluated on the end state, where no control acts)")
        return e


def _weights(owner: str, joints: Sequence[str] | None, joint_weights: Sequence[float] | None) -> tuple[float, ...] | None:
    """Per-joint weights, one per joint of ``joints`` (finite, >= 0), or None (all 1)."""
    if joint_weights is None:
        return None
    w = tuple(joint_weights) if isinstance(joint_weights, (list, tuple)) else None
    if w is None or not all(isinstance(c, (int, float)) and not isinstance(c, bool) and math.isfinite(c) and c >= 0 for c in w):
        raise ParameterError(f"{owner}.joint_weights = {shown(joint_weights)}: expected a list of finite weights >= 0, one per joint")
    if joints is None:
        raise ParameterError(f"{owner}.joint_weights: expected joints too (the weights are one per joint of joints)")
    if len(w) != len(joints):
        raise ParameterError(f"{owner}.joint_weights has {len(w)} entries; expected one per joint of joints {list(joints)}")
    return tuple(float(c) for c in w)


def _joints(owner: str, joints: object) -> tuple[str, ...] | None:
    if joints is None:
        return None
    if isinstance(joints, str):
        joints = [joints]
    if not isinstance(joints, (list, tuple)) or not all(isinstance(j, str) for j in joints):
        raise ParameterError(f"{owner}.joints = {shown(joints)}: expected a list of joint names")
    return tuple(joints)


def _per_joint(v: IntervalVariables, joints: tuple[str, ...] | None, weights: tuple[float, ...] | None,
               values: Callable[[str | Sequence[str] | None], ca.SX]) -> ca.SX:
    """``sum_j c_j |values(j)|^2`` over ``joints`` (all when None), with weights c (1 when None)."""
    if weights is None:
        return ca.sumsqr(values(joints))
    return sum((c * ca.sumsqr(values(j)) for j, c in zip(joints, weights)), ca.SX(0))


def _options(joints: tuple[str, ...] | None, weights: tuple[float, ...] | None, at: str | None, **more: object) -> dict:
    out = {} if joints is None else {"joints": list(joints)}
    if weights is not None:
        out["joint_weights"] = list(weights)
    if at is not None:
        out["at"] = at
    return {**out, **more}


def posture(weight: float, joints: Sequence[str] = (), name: str = "posture", joint_weights: Sequence[float] | None = None,
            at: str | None = None) -> CostTerm:
    """``sum_{j in joints} c_j q_j^2`` (rad^2 or m^2): keeps the named joints near 0."""
    js = _joints(name, tuple(joints))
    w = _weights(name, js, joint_weights)
    return CostTerm(name, weight, lambda v: _per_joint(v, js, w, v.q) if js else ca.SX(0), {**_options(js, w, at)}, "posture", at)


def velocity(weight: float, joints: Sequence[str] | None = None, name: str = "velocity", joint_weights: Sequence[float] | None = None,
             at: str | None = None) -> CostTerm:
    """``sum_{j in joints} c_j qdot_j^2`` ((rad/s)^2 or (m/s)^2); every joint by default."""
    js = _joints(name, joints)
    w = _weights(name, js, joint_weights)
    return CostTerm(name, weight, lambda v: _per_joint(v, js, w, v.qdot), _options(js, w, at), "velocity", at)


def _halves_term(kind: str, weight: float, name: str, joints: Sequence[str] | None, joint_weights: Sequence[float] | None,
                 every: Callable, of_joint: Callable, at: str | None = None) -> CostTerm:
    """A term over actuator halves: ``every(v)`` over all of them, or with ``joints``
    ``sum_j c_j |of_joint(v)(j)|^2`` over the named joints' halves."""
    js = _joints(name, joints)
    w = _weights(name, js, joint_weights)
    value = every if js is None else (lambda v: _per_joint(v, js, w, of_joint(v)))
    return CostTerm(name, weight, value, _options(js, w, at), kind, at)


def torque_rate(weight: float, name: str = "torque_rate", joints: Sequence[str] | None = None,
                joint_weights: Sequence[float] | None = None) -> CostTerm:
    """``|u_k - u_{k-1}|^2`` over the halves of ``joints`` (every half by default; N^2 m^2 or N^2)."""
    return _halves_term("torque_rate", weight, name, joints, joint_weights, lambda v: ca.sumsqr(v.u - v.u_prev),
                        lambda v: lambda j: v.tau_halves(j) - v.tau_halves_prev(j))


def fatigue(weight: float, name: str = "fatigue", joints: Sequence[str] | None = None, joint_weights: Sequence[float] | None = None,
            at: str | None = None) -> CostTerm:
    """``sum_h mf_h^2``: the fatigued fraction of every half (of ``joints``) squared."""
    return _halves_term("fatigue", weight, name, joints, joint_weights, lambda v: ca.sumsqr(v.fatigued), lambda v: v.fatigued_of, at)


def torque(weight: float, name: str = "torque", joints: Sequence[str] | None = None,
           joint_weights: Sequence[float] | None = None) -> CostTerm:
    """``|u_k|^2`` over the halves of ``joints`` (every half by default; N^2 m^2 or N^2)."""
    return _halves_term("torque", weight, name, joints, joint_weights, lambda v: ca.sumsqr(v.u), lambda v: v.tau_halves)


def activation(weight: float, name: str = "activation") -> CostTerm:
    """``sum_i a_i^2``: every muscle's activation squared (dimensionless; the rows of
    :meth:`~fatigue_pin.ocp.actuation_layer.ActuationLayer.activation_rows`)."""
    return CostTerm(name, weight, lambda v: ca.sumsqr(v.u[v.actuators.activation_rows()]), {}, "activation")


def residual(weight: float, name: str = "residual") -> CostTerm:
    """``sum_h u_h^2``: every residual torque half squared (N^2 m^2; the rows of
    :meth:`~fatigue_pin.ocp.actuation_layer.ActuationLayer.residual_rows`)."""
    return CostTerm(name, weight, lambda v: ca.sumsqr(v.u[v.actuators.residual_rows()]), {}, "residual")


def state(weight: float, states: Sequence[str] = (), targets: Sequence[float] | None = None, name: str = "state",
          state_weights: Sequence[float] | None = None, at: str | None = None) -> CostTerm:
    """``sum_i c_i (x_{s_i} - target_i)^2`` over the states named ``states``
    (:attr:`~fatigue_pin.ocp.problem.StateLayout.state_names`, e.g. ``"pendulum_qdot"``,
    ``"elbow_plus_mf"``); targets default 0, weights ``state_weights`` default 1."""
    if isinstance(states, str):
        states = [states]
    if not isinstance(states, (list, tuple)) or not states or not all(isinstance(x, str) for x in states):
        raise ParameterError(f"{name}.states = {shown(states)}: expected a list of state names")
    n = len(states)

    def numbers(key: str, values: object, default: float, at_least: float = -math.inf) -> tuple[float, ...]:
        if values is None:
            return (default,) * n
        ok = isinstance(values, (list, tuple)) and len(values) == n and all(
            isinstance(c, (int, float)) and not isinstance(c, bool) and math.isfinite(c) and c >= at_least for c in values)
        if not ok:
            raise ParameterError(f"{name}.{key} = {shown(values)}: expected {n} finite numbers" + (" >= 0" if at_least == 0 else "")
                                 + f", one per state of {list(states)}")
        return tuple(float(c) for c in values)

    tg, cw = numbers("targets", targets, 0.0), numbers("state_weights", state_weights, 1.0, 0.0)
    options = {"states": list(states), "targets": list(tg), "state_weights": list(cw), **({"at": at} if at else {})}
    return CostTerm(name, weight, lambda v: sum((c * (v.state(s) - t) ** 2 for s, t, c in zip(states, tg, cw)), ca.SX(0)),
                    options, "state", at)


def frame(weight: float, frame: str = "", position: Sequence[float] = (0.0, 0.0, 0.0), name: str = "frame",
          at: str | None = None) -> CostTerm:
    """``|p_frame(q) - position|^2`` (m^2): frame ``frame``'s origin near ``position`` (m, world frame)."""
    if not isinstance(frame, str) or not frame:
        raise ParameterError(f"{name}.frame = {shown(frame)}: expected the name of a frame of the model")
    p = tuple(position) if isinstance(position, (list, tuple)) else ()
    if len(p) != 3 or not all(isinstance(c, (int, float)) and not isinstance(c, bool) and math.isfinite(c) for c in p):
        raise ParameterError(f"{name}.position = {shown(position)}: expected 3 finite numbers (m, world frame)")
    target = ca.DM([float(c) for c in p])
    return CostTerm(name, weight, lambda v: ca.sumsqr(v.frame_position(frame) - target),
                    {"frame": frame, "position": [float(c) for c in p], **({"at": at} if at else {})}, "frame", at)


#: Built-in cost kinds by name: ``kind(weight, **options) -> CostTerm``.
COST_KINDS: dict[str, Callable[..., CostTerm]] = {
    "posture": posture,
    "velocity": velocity,
    "torque_rate": torque_rate,
    "fatigue": fatigue,
    "torque": torque,
    "activation": activation,
    "residual": residual,
    "state": state,
    "frame": frame,
}


def kind_options(kind: str) -> tuple[str, ...]:
    """The options a built-in kind takes (its keyword arguments but ``weight`` and ``name``)."""
    return tuple(p for p in inspect.signature(COST_KINDS[kind]).parameters if p not in ("weight", "name"))


def cost_term(kind: str, weight: float, name: str | None = None, **options: object) -> CostTerm:
    """A built-in term by kind, e.g. ``cost_term("posture", 1e4, joints=["shoulder"])``."""
    if kind not in COST_KINDS:
        raise ParameterError(f"cost kind {kind!r} is unknown; expected one of {sorted(COST_KINDS)} (or a CostTerm of your own)")
    known = kind_options(kind)
    for key in options:
        if key not in known:
            terminal = " (a terminal cost is a term of the state: posture, velocity, fatigue, state or frame)" if key == "at" else ""
            raise ParameterError(f"cost {name or kind!r}: option {key!r} is not an option of kind {kind!r}; its options are "
                                 f"{list(known)}{terminal}")
    return COST_KINDS[kind](weight, name=name or kind, **options)


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
