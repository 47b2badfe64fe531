"""The problem: a model, its actuators with their fatigue models, a task, cost terms and an
initial state. Nothing here says how the problem is transcribed or solved.

State of the OCPs (:class:`StateLayout`)::

    x = [q (nq), qdot (nv), states of half 0, states of half 1, ...]

where each half contributes the states its fatigue model declares (Xia's 3CC: ma, mr, mf), and
the control is ``u = [tau_plus (na), tau_minus (na)]`` of the na actuated joints (passive joints
have no control and no fatigue state; the joint torque is the actuators' to say,
:meth:`SignedTorqueActuators.joint_torque`). Every quantity is addressed by name.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Mapping, Sequence

import numpy as np

from fatigue_pin.ocp.actuators import Actuation, ParamsSpec, SignedTorqueActuators
from fatigue_pin.ocp.costs import CostTerm, check_costs
from fatigue_pin.core.errors import ParameterError, TaskError
from fatigue_pin.robot.model import RobotModel
from fatigue_pin.ocp.task import Task


@dataclass(frozen=True)
class StateLayout:
    """Where each quantity sits in the state x and the control u.

    The fatigue states follow q and qdot, half after half; where each half's states start and
    which row holds a named state are the actuators' to say
    (:meth:`SignedTorqueActuators.state_rows`, :meth:`~SignedTorqueActuators.fatigued_rows`);
    this layout only adds the offset nq + nv.

    Attributes:
        nq, nv: configuration and velocity sizes.
        actuators: the actuator halves with their fatigue models.
        joints: the model's joint names (those of q and qdot).
    """

    nq: int
    nv: int
    actuators: SignedTorqueActuators
    joints: tuple[str, ...] = ()

    @classmethod
    def of(cls, model: RobotModel, actuators: SignedTorqueActuators) -> StateLayout:
        return cls(model.nq, model.nv, actuators, tuple(model.joint_names))

    @property
    def half_names(self) -> tuple[str, ...]:
        """Actuator halves in order (``shoulder_plus``, ...)."""
        return tuple(self.actuators.half_names)

    @property
    def half_states(self) -> tuple[tuple[str, ...], ...]:
        """The state names of each half's fatigue model."""
        return tuple(tuple(h.params.state_names) for h in self.actuators.halves)

    @property
    def n_halves(self) -> int:
        return len(self.half_names)

    @property
    def n_fatigue(self) -> int:
        """Number of fatigue states of all halves."""
        return self.actuators.n_states

    @property
    def nx(self) -> int:
        return self.nq + self.nv + self.n_fatigue

    @property
    def nu(self) -> int:
        """Number of controls: two halves per actuated joint (:attr:`SignedTorqueActuators.nu`)."""
        return self.actuators.nu

    @property
    def joint_names(self) -> tuple[str, ...]:
        """The joints the layout's q and qdot rows belong to (model order)."""
        return self.joints

    @property
    def state_names(self) -> tuple[str, ...]:
        """A name for every row of x: ``"<joint>_q"`` (rad or m), ``"<joint>_qdot"`` (rad/s or
        m/s), then the fatigue states ``"<half>_<state>"`` (:attr:`SignedTorqueActuators.state_names`),
        shape (nx,). :class:`~fatigue_pin.ocp.task.StateTarget` and the ``state`` cost address
        states by these names."""
        joints = self.joint_names
        return (*(f"{j}_q" for j in joints), *(f"{j}_qdot" for j in joints), *self.actuators.state_names)

    def state_row(self, name: str) -> int:
        """Row in x of the state named ``name`` (:attr:`state_names`)."""
        names = self.state_names
        if name not in names:
            raise ParameterError(f"state {name!r} is not a state of the problem; its states are {list(names)}")
        return names.index(name)

    @property
    def q(self) -> slice:
        return slice(0, self.nq)

    @property
    def v(self) -> slice:
        return slice(self.nq, self.nq + self.nv)

    @property
    def m(self) -> slice:
        return slice(self.nq + self.nv, self.nx)

    @property
    def state_kinds(self) -> tuple[str, ...]:
        """Every fatigue state name, in first-seen order (``ma, mr, mf`` for Xia's model)."""
        return self.actuators.fatigue_state_kinds

    def rows(self, state: str) -> list[int | None]:
        """Row in x of fatigue state ``state`` of every half (``None`` where a half's model has no
        such state), length n_halves."""
        m0 = self.nq + self.nv
        return [None if r is None else m0 + r for r in self.actuators.state_rows(state)]

    def fatigued_rows(self) -> list[int]:
        """Row in x of every half's fatigued fraction (its model's ``fatigued_state``), length n_halves."""
        return [self.nq + self.nv + r for r in self.actuators.fatigued_rows()]

    def fatigued(self, x: np.ndarray) -> np.ndarray:
        """The fatigued fraction of every half from states x (nodes, nx): (nodes, n_halves)."""
        return np.asarray(x)[..., self.fatigued_rows()]

    def fatigue_index(self, state: str) -> list[int]:
        """Rows in x of fatigue state ``state`` of every half; every half must have it."""
        rows = self.rows(state)
        if any(r is None for r in rows):
            missing = [h for h, r in zip(self.half_names, rows) if r is None]
            raise ParameterError(f"fatigue state {state!r} is not a state of halves {missing}")
        return [int(r) for r in rows]  # type: ignore[arg-type]

    def fatigue_columns(self, x: np.ndarray, state: str) -> np.ndarray:
        """State ``state`` of every half from states x (nodes, nx), shape (nodes, n_halves); NaN
        in the columns of halves whose model has no such state."""
        rows = self.rows(state)
        out = np.full((x.shape[0], len(rows)), np.nan)
        for h, r in enumerate(rows):
            if r is not None:
                out[:, h] = x[:, r]
        return out

    def assemble(self, q: np.ndarray, qdot: np.ndarray, fatigue: Mapping[str, np.ndarray]) -> np.ndarray:
        """States (nodes, nx) from q (nodes, nq), qdot (nodes, nv) and fatigue states by name
        (each (nodes, n_halves)); the inverse of reading them back by name."""
        x = np.zeros((q.shape[0], self.nx))
        x[:, self.q], x[:, self.v] = q, qdot
        for state in self.state_kinds:
            data = np.asarray(fatigue[state])
            for h, r in enumerate(self.rows(state)):
                if r is not None:
                    x[:, r] = data[:, h]
        return x


@dataclass(frozen=True)
class Problem:
    """What is to be optimised: model, actuators (each half with its fatigue model), task, named
    cost terms and the initial state.

    Attributes:
        model: the rigid-body model.
        actuators: one plus and one minus half per actuated joint of ``model`` (its ``joint_names``
            are the model's).
        task: the cyclic task.
        costs: the cost terms (unique names).
        x_init: initial state (nx,); ``None``: the task's q_init and qdot_init (default at rest),
            rested fatigue.
    """

    model: RobotModel
    actuators: SignedTorqueActuators
    task: Task
    costs: tuple[CostTerm, ...]
    x_init: np.ndarray | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "costs", check_costs(self.costs))
        if tuple(self.actuators.joint_names) != tuple(self.model.joint_names):
            raise ParameterError(
                f"actuators drive joints {list(self.actuators.joint_names)}; model {self.model.name!r} has {list(self.model.joint_names)}"
            )
        self.task.check(self.model)
        self.task.check_states(self.layout.state_names)
        self._check_cost_names()
        if self.x_init is not None:
            x = np.asarray(self.x_init, dtype=float).reshape(-1)
            if x.size != self.layout.nx:
                raise ParameterError(f"x_init has {x.size} entries; expected nx = {self.layout.nx}")
            self._check_x_init(x)
            object.__setattr__(self, "x_init", x)

    def _check_cost_names(self) -> None:
        """Refuse a built-in cost term whose options name a joint, a state or a frame the problem
        does not have (before anything is built)."""
        from fatigue_pin.core.errors import ModelError
        from fatigue_pin.robot.kinematics import frame_id

        states, joints = self.layout.state_names, self.model.joint_names
        for t in self.costs:
            if t.options.get("joints") and t.kind in ("torque", "torque_rate", "fatigue") and not self.actuators.units_per_joint:
                raise ParameterError(f"cost term {t.name!r}: a {t.kind} term per joint selects torque halves; these actuators "
                                     "are muscles: expected the term over every unit (no joints)")
            for kind, rows, needs in (("an activation", self.actuators.activation_rows(), "muscles"),
                                      ("a residual", self.actuators.residual_rows(), "residual torques beside muscles")):
                if t.kind == kind.split()[1] and not rows:
                    raise ParameterError(f"cost term {t.name!r}: {kind} term needs {needs}; expected [actuators] kind = "
                                         f"\"muscles\"{' with residuals > 0' if kind == 'a residual' else ''}, or another term")
            for j in t.options.get("joints", []):
                if j not in joints:
                    raise ParameterError(f"cost term {t.name!r}: joint {j!r} is not in model {self.model.name!r}; its joints are {list(joints)}")
            for s in t.options.get("states", []):
                if s not in states:
                    raise ParameterError(f"cost term {t.name!r}: state {s!r} is not a state of the problem; its states are {list(states)}")
            if t.kind == "frame":
                try:
                    frame_id(self.model.pin_model, t.options["frame"])
                except ModelError as exc:
                    raise ParameterError(f"cost term {t.name!r}: {exc}") from None

    def _check_x_init(self, x: np.ndarray) -> None:
        """Refuse an initial state with q or qdot outside the model's bounds, q off a target at
        phase 0 (:meth:`Task.check_start`), or fatigue states that are not a valid state of their
        half's model (fractions in [0, 1], Xia: summing to 1)."""
        L, m = self.layout, self.model
        for label, values, lo, hi in (("q", x[L.q], m.q_lower, m.q_upper), ("qdot", x[L.v], m.v_lower, m.v_upper)):
            bad = [m.joint_names[j] for j in range(values.size) if not (lo[j] <= values[j] <= hi[j])]
            if bad:
                raise ParameterError(f"x_init: {label} = {values.tolist()} is outside the bounds of joints {bad} "
                                     f"({lo.tolist()} to {hi.tolist()})")
        try:
            self.task.check_start(m, x[L.q], "x_init's q")
        except TaskError as exc:
            raise ParameterError(str(exc)) from None
        k0 = L.nq + L.nv
        for half, off in zip(self.actuators.halves, self.actuators.state_offsets()):
            start = k0 + off
            half.params.check_state(x[start : start + half.params.n_states()], f"x_init of actuator half {half.name!r}")

    @classmethod
    def build(cls, model: RobotModel, fatigue: ParamsSpec, task: Task, costs: Sequence[CostTerm],
              x_init: np.ndarray | None = None, actuation: Actuation | None = None) -> Problem:
        """A problem whose actuators come from ``model``'s torque limits with fatigue models
        ``fatigue`` (one for every half, or per joint: see
        :meth:`SignedTorqueActuators.from_model`), passive joints and coupling ``actuation``."""
        return cls(model, SignedTorqueActuators.from_model(model, fatigue, actuation), task, tuple(costs), x_init)

    @property
    def layout(self) -> StateLayout:
        return StateLayout.of(self.model, self.actuators)

    @property
    def cost_names(self) -> tuple[str, ...]:
        return tuple(t.name for t in self.costs)

    @property
    def weights(self) -> np.ndarray:
        """Weights of the cost terms in :attr:`cost_names` order, shape (n_terms,)."""
        return np.array([t.weight for t in self.costs], dtype=float)

    def weight_vector(self, weights: Mapping[str, float] | None = None) -> np.ndarray:
        """The weights with some replaced by name (unknown names are refused)."""
        w = self.weights
        for name, value in (weights or {}).items():
            if name not in self.cost_names:
                raise ParameterError(f"cost term {name!r} is not in the problem; its terms are {list(self.cost_names)}")
            w[self.cost_names.index(name)] = CostTerm(name, value, lambda v: 0).weight
        return w

    def with_weights(self, **weights: float) -> Problem:
        """A copy with some cost weights changed by name."""
        w = self.weight_vector(weights)
        return replace(self, costs=tuple(t.with_weight(float(x)) for t, x in zip(self.costs, w)))

    def with_x_init(self, x_init: np.ndarray | None) -> Problem:
        return replace(self, x_init=x_init)

    def initial_state(self) -> np.ndarray:
        """The initial state (nx,): ``x_init``, or q_init, zero velocity and rested fatigue."""
        if self.x_init is not None:
            return np.asarray(self.x_init, dtype=float).copy()
        L = self.layout
        x0 = np.zeros(L.nx)
        x0[L.q] = self.task.initial_configuration(self.model)
        x0[L.v] = self.task.initial_velocity(self.model)
        x0[L.m] = self.actuators.initial_state()
        return x0

    def structure_key(self) -> str:
        """Text identifying everything compiled interval functions depend on (the model, the
        actuators and their fatigue equations, the interval length and the cost integrands'
        names); weights and parameter values are not part of it."""
        return "|".join([
            self.model.name,
            self.model.pin_model.saveToString() if hasattr(self.model.pin_model, "saveToString") else "",
            self.actuators.structure_key(),
            repr(self.task.dt),
            ",".join(f"{t.name}:{t.kind}:{sorted(t.options.items())}" for t in self.costs),
        ])
