"""The actuation layer: controls -> joint torques, and the capacity states it carries.

:class:`ActuationLayer` is what every kind of actuator shares: a sequence of *units* (the halves of
the signed torque actuators, :class:`~fatigue_pin.ocp.actuators.SignedTorqueActuators`; the
muscles, :class:`~fatigue_pin.ocp.muscle_actuators.MuscleActuators`), each with its fatigue model
(any :class:`~fatigue_pin.fatigue.interface.FatigueModel`) and target load. It owns where each
unit's fatigue states sit (the states of each unit consecutively, units in order), their names,
their parameters, their right-hand sides and the coupling rows ``TL + m_fatigued``. A kind adds
its controls, their bounds and scales, its target loads and its joint torque.

Drivers, costs, verify, plots and replay ask the layer (these methods), never a kind. (For the
signed torque actuators, "unit" and "half" are the same: the names below keep ``half`` for them.)
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Union

import casadi as ca
import numpy as np

from fatigue_pin.core.errors import DimensionError, ParameterError
from fatigue_pin.core.text import shown
from fatigue_pin.fatigue.interface import FatigueModel
from fatigue_pin.ocp.actuation import COUPLINGS
from fatigue_pin.ocp.halves import FatigueGroup

__all__ = ["ActuationLayer", "column", "unit_model"]

Expr = Union[ca.SX, ca.MX, ca.DM, np.ndarray]


def column(x: Expr, n: int, what: str) -> Expr:
    """Return ``x`` as a CasADi column of length ``n`` (numpy -> DM)."""
    if isinstance(x, (ca.SX, ca.MX, ca.DM)):
        if x.shape not in ((n, 1), (1, n)) and not (n == 1 and x.numel() == 1):
            raise DimensionError(f"{what} of shape {x.shape}: expected {n} entries")
        return x if x.shape[1] == 1 else x.T
    a = np.asarray(x, dtype=float).reshape(-1)
    if a.shape != (n,):
        raise DimensionError(f"{what} of shape {np.shape(x)}: expected {n} entries")
    return ca.DM(a)


def unit_model(kind: str, **params: float) -> FatigueModel:
    """The model of a unit from the kind and parameters a run stores of it (``fatigue_params``,
    :func:`~fatigue_pin.drivers.run.fatigue_parameters`): a fatigue model
    (:func:`~fatigue_pin.fatigue.models.fatigue_model`), one with the activation dynamics in
    front (kind ``<model>+activation``, :func:`~fatigue_pin.muscles.activation.activated`), or a
    motor's temperatures (:class:`~fatigue_pin.motors.thermal_states.MotorThermal`).

    Raises:
        ParameterError: an unknown kind, unknown or missing parameters, bad values.
    """
    from fatigue_pin.fatigue.models import FATIGUE_MODELS, model_of_class
    from fatigue_pin.motors.thermal_states import MotorThermal
    from fatigue_pin.muscles.activation import SUFFIX, activated

    base = kind.removesuffix(SUFFIX)
    classes = {MotorThermal.kind: MotorThermal, **FATIGUE_MODELS}
    if base not in classes or (base != kind and base not in FATIGUE_MODELS):
        raise ParameterError(f"fatigue model {kind!r} is unknown; expected one of {sorted(classes)} "
                             f"(muscles with activation dynamics: {SUFFIX!r} after one of {sorted(FATIGUE_MODELS)})")
    return model_of_class(activated(classes[base]) if base != kind else classes[base], **params)


@dataclass(frozen=True)
class RunRecord:
    """What a kind adds to the record of a run (:func:`fatigue_pin.drivers.run.to_run_result`).

    Attributes:
        unit_controls: the control of every unit, (intervals, units), or None where the run's
            ``tau_plus`` and ``tau_minus`` are the units' controls (torque halves).
        muscles: the muscle file's text, or "".
        extras: further arrays by name (:attr:`RunResult.extras`).
    """

    unit_controls: np.ndarray | None = None
    muscles: str = ""
    extras: dict = field(default_factory=dict)


class ActuationLayer:
    """The units of an actuation kind, each with its fatigue model (module docstring).

    A kind calls :meth:`_set_units` (its units: objects with ``name`` and ``params``, a
    FatigueModel; every joint of the model; the coupling), and defines ``nu``,
    :meth:`target_loads`, :meth:`joint_torque`, :meth:`control_bounds`, :meth:`control_scales`,
    :meth:`structure_key` and :attr:`torque_follows_state`.
    """

    _halves: tuple
    _joint_names: tuple[str, ...]
    _coupling: str

    #: whether the units are a plus and a minus half per joint (per-joint cost terms select them)
    units_per_joint = True
    #: the actuator kind, one of :data:`~fatigue_pin.ocp.actuation.ACTUATOR_KINDS` (run records name it)
    kind = "torque"
    #: whether a unit's load is limited by what is not fatigued (a tired half or muscle delivers
    #: at most ``1 - m_fatigued`` of its limit: a closed loop's plant caps it there); False for a
    #: motor, whose temperature bounds its state, not its torque
    capacity_limits_load = True
    #: whether :meth:`window_budget` gives a sliding window's budget (``heat_budget``)
    has_window_budget = False

    def _set_units(self, units: tuple, joint_names: tuple[str, ...], coupling: str, words: tuple[str, str]) -> None:
        """Check the coupling against the units' fatigue models and keep the three: ``words`` are
        the singular and plural of a unit in messages (``("half", "halves")``)."""
        if coupling not in COUPLINGS:
            raise ParameterError(f"coupling = {shown(coupling)}: expected one of {list(COUPLINGS)}")
        if coupling == "active":
            lacking = [u.name for u in units if u.params.active_state not in u.params.state_names]
            if lacking:
                raise ParameterError(f"coupling 'active' needs an active state in every {words[0]}'s fatigue model; "
                                     f"{words[1]} {lacking} have none")
        self._halves, self._joint_names, self._coupling = tuple(units), tuple(joint_names), coupling

    @property
    def torque_follows_state(self) -> bool:
        """Whether the joint torque depends on the state (q, qdot or the fatigue states) within an
        interval, so that the interval functions integrate the rigid body with it: under the
        ``active`` coupling (the torque follows m_active)."""
        return self._coupling == "active"

    def target_loads(self, u: Expr) -> Expr:
        """Target loads (dimensionless) of every unit, (n_units, K), from controls (nu, K)."""
        raise NotImplementedError

    @property
    def n_window_budget(self) -> int:
        """Rows of a window's budget (:meth:`window_budget`); 0 for kinds without one."""
        return 0

    def window_budget(self, cycle_s: float, after: int) -> tuple[np.ndarray, np.ndarray]:
        """A sliding window's budget: rows ``(E_last, E_before)``, each (n_window_budget,
        n_states), such that the window keeps ``E_last m(T) + E_before m(T - cycle_s) <= 1``,
        ``m`` the capacity states at the end and the start of its last cycle, so that ``after``
        more cycles like it stay within the capacity (motors: the heat budget).

        Only kinds with :attr:`has_window_budget` define it.
        """
        raise ParameterError(f"a window budget (horizon.heat_budget) needs an actuation kind with one (motors); "
                             f"this one is {self.kind!r}")

    def activation_rows(self) -> list[int]:
        """Rows of the controls that are muscle activations (the ``activation`` cost term); none
        for torque halves."""
        return []

    def residual_rows(self) -> list[int]:
        """Rows of the controls that are residual torques beside muscles (the ``residual`` cost
        term); none for torque halves (their torques are the actuators)."""
        return []

    def run_record(self, q: np.ndarray, qdot: np.ndarray, u: np.ndarray, m: np.ndarray) -> RunRecord:
        """What a run of this kind stores beside its states and ``tau_plus``/``tau_minus``, from
        the state at the start of every interval (q, qdot (N, nv), m (N, n_states)) and its
        controls u (N, nu): nothing for torque halves."""
        return RunRecord()

    def run_record_attributes(self) -> dict[str, object]:
        """Run attributes of this kind: none for torque halves (a run without ``actuation`` is
        one of torque halves); ``actuation`` and the kind's own for the others."""
        return {}

    def control_target_loads(self, u: Expr) -> Expr:
        """:meth:`target_loads` (the name the interval functions use)."""
        return self.target_loads(u)

    @property
    def halves(self) -> tuple:
        """The units: for the signed torque actuators the halves ``(j0_plus, j0_minus, j1_plus,
        ...)`` (actuated joints only), for muscles the muscles in order."""
        return self._halves

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Every joint of the model in model order (length nv), passive ones included."""
        return self._joint_names

    @property
    def coupling_kind(self) -> str:
        """How torque and fatigue are coupled, one of :data:`~fatigue_pin.ocp.actuation.COUPLINGS`."""
        return self._coupling

    @property
    def nv(self) -> int:
        """Number of joints (passive ones included)."""
        return len(self._joint_names)

    @property
    def n_halves(self) -> int:
        """Number of units (signed torque halves: ``2 * na``; muscles: nm, then residual halves)."""
        return len(self._halves)

    @property
    def n_states(self) -> int:
        """Number of fatigue states (the sum over halves of their model's states)."""
        return sum(h.params.n_states() for h in self._halves)

    @property
    def n_params(self) -> int:
        """Length of :meth:`param_vector` (the sum over halves of their model's parameters)."""
        return sum(h.params.n_params() for h in self._halves)

    @property
    def half_names(self) -> tuple[str, ...]:
        """``("j0_plus", "j0_minus", ...)``."""
        return tuple(h.name for h in self._halves)

    @property
    def state_names(self) -> tuple[str, ...]:
        """Fatigue state names ``("j0_plus_ma", "j0_plus_mr", "j0_plus_mf", "j0_minus_ma", ...)`` (dimensionless)."""
        return tuple(f"{h.name}_{s}" for h in self._halves for s in h.params.state_names)

    @property
    def fatigue_state_kinds(self) -> tuple[str, ...]:
        """Every state name declared by the halves' models, in first-seen order (e.g. ``ma, mr, mf``)."""
        return tuple(dict.fromkeys(s for h in self._halves for s in h.params.state_names))

    def state_offsets(self) -> list[int]:
        """Offset of each half's states in the fatigue state vector, length n_halves."""
        return np.cumsum([0] + [h.params.n_states() for h in self._halves[:-1]]).tolist()

    def param_offsets(self) -> list[int]:
        """Offset of each half's parameters in :meth:`param_vector`, length n_halves."""
        return np.cumsum([0] + [h.params.n_params() for h in self._halves[:-1]]).tolist()

    def state_rows(self, state: str) -> list[int | None]:
        """Row of state ``state`` of each half in the fatigue state vector (``None`` for a half whose
        model has no such state), length n_halves."""
        return [off + h.params.state_names.index(state) if state in h.params.state_names else None
                for h, off in zip(self._halves, self.state_offsets())]

    def fatigued_rows(self) -> list[int]:
        """Row of each half's fatigued fraction (its model's ``fatigued_state``), length n_halves."""
        return [off + h.params.state_index(h.params.fatigued_state) for h, off in zip(self._halves, self.state_offsets())]

    def measured_rows(self) -> list[int]:
        """Row of the state a capacity probe of each unit measures (a closed loop's
        :meth:`Plant.probe <fatigue_pin.drivers.plant.Plant.probe>` gives ``1 -`` it): the
        fatigued fraction (an MVC test), length n_halves."""
        return self.fatigued_rows()

    def active_rows(self) -> list[int]:
        """Row of each half's active fraction (its model's ``active_state``), length n_halves."""
        return [off + h.params.state_index(h.params.active_state) for h, off in zip(self._halves, self.state_offsets())]

    def fatigue_groups(self) -> tuple[FatigueGroup, ...]:
        """The halves grouped by fatigue equations (the same model kind and :meth:`structure_key
        <fatigue_pin.fatigue.interface.FatigueModel.structure_key>`; parameter values may differ),
        groups in the order of their first half. A group's halves share one state step of one
        half, mapped over them (:mod:`fatigue_pin.ocp.intervals`)."""
        keys: dict[str, list[int]] = {}
        for i, h in enumerate(self._halves):
            keys.setdefault(h.params.structure_key(), []).append(i)
        offsets, param_offsets = self.state_offsets(), self.param_offsets()
        groups, seen = [], {}
        for halves in keys.values():
            model = self._halves[halves[0]].params
            kind = "_".join(re.findall(r"[A-Za-z0-9]+", model.kind)) or "model"  # a name CasADi accepts
            seen[kind] = seen.get(kind, 0) + 1
            label = kind if seen[kind] == 1 else f"{kind}_{seen[kind]}"
            ns, npar = model.n_states(), model.n_params()
            groups.append(FatigueGroup(
                label, model, tuple(halves),
                tuple(offsets[i] + s for i in halves for s in range(ns)),
                tuple(param_offsets[i] + k for i in halves for k in range(npar))))
        return tuple(groups)

    def params_of(self, name: str) -> FatigueModel:
        """Fatigue parameters of the half ``name`` (e.g. ``"elbow_minus"``)."""
        for h in self._halves:
            if h.name == name:
                return h.params
        raise ParameterError(f"unknown actuator half {name!r}; the halves are {list(self.half_names)}")

    def param_vector(self) -> np.ndarray:
        """Stacked fatigue parameters of each half (e.g. ``[LD, LR, F, R, S, r]`` for Xia's model),
        shape (n_params,)."""
        return np.concatenate([h.params.as_vector() for h in self._halves])

    def initial_state(self) -> np.ndarray:
        """The rested state of every half (Xia: ``(ma, mr, mf) = (0, 1, 0)``), shape (n_states,)."""
        return np.concatenate([h.params.rest_state() for h in self._halves])

    def check_stabiliser(self, dt: float, method: str = "rk4") -> None:
        """Check every half's model for a stable explicit step ``dt`` (raises ParameterError)."""
        for h in self._halves:
            try:
                h.params.check_step(dt, method)
            except ParameterError as exc:
                raise ParameterError(f"actuator half {h.name!r}: {exc}") from None

    def state(self, m: Expr, state: str) -> Expr:
        """State ``state`` (e.g. ``"mf"``) of every half, shape (n_halves,), from ``m`` of shape
        (n_states,). Every half's model must have that state."""
        m = column(m, self.n_states, "fatigue states m")
        rows = self.state_rows(state)
        missing = [h.name for h, r in zip(self._halves, rows) if r is None]
        if missing:
            raise ParameterError(f"fatigue state {state!r} is not a state of the models of halves {missing}")
        return ca.vertcat(*[m[r] for r in rows])

    def split_states(self, m: Expr) -> tuple[Expr, ...]:
        """Every state kind of :attr:`fatigue_state_kinds` of all halves, each shape (n_halves,)."""
        return tuple(self.state(m, s) for s in self.fatigue_state_kinds)

    def fatigued(self, m: Expr) -> Expr:
        """Fatigued fraction of every half (its model's ``fatigued_state``), shape (n_halves,)."""
        m = column(m, self.n_states, "fatigue states m")
        return ca.vertcat(*[m[r] for r in self.fatigued_rows()])

    def fatigue_rates(self, m: Expr, u: Expr, p: Expr | None = None) -> Expr:
        """``dm/dt`` (1/s), shape (n_states,), same layout as ``m``.

        Args:
            m: fatigue states, shape (n_states,).
            u: controls ``(tau_plus, tau_minus)`` (N m), shape (nu,).
            p: optional parameter vector, shape (n_params,), e.g. a symbol; default
                :meth:`param_vector`.
        """
        m = column(m, self.n_states, "fatigue states m")
        TL = self.target_loads(u)
        p = ca.DM(self.param_vector()) if p is None else column(p, self.n_params, "fatigue parameter vector p")
        out = []
        for i, (h, so, po) in enumerate(zip(self._halves, self.state_offsets(), self.param_offsets())):
            ns, npar = h.params.n_states(), h.params.n_params()
            out.append(h.params.rhs()(m[so : so + ns], TL[i], p[po : po + npar]))
        return ca.vertcat(*out)

    def delivered_loads(self, TL: np.ndarray, capacity: np.ndarray) -> np.ndarray:
        """The target loads a plant delivers for the commanded ``TL`` of units whose capacity is
        ``capacity`` (``1 - m_fatigued``), both (nu,) in control order: each capped at its
        capacity (a tired half or muscle). Motors say otherwise."""
        return np.minimum(np.asarray(TL, dtype=float), np.maximum(np.asarray(capacity, dtype=float), 0.0))

    def coupling(self, m: Expr, u: Expr) -> Expr:
        """Torque/fatigue coupling ``TL + fatigued fraction`` per half (dimensionless), shape
        (n_halves,); under the ``tl+mf<=1`` coupling the OCPs bound it to [0, 1]."""
        return self.target_loads(u) + self.fatigued(m)

    @property
    def coupling_rows(self) -> bool:
        """Whether the OCPs hold ``0 <= TL + m_fatigued <= 1`` (the ``tl+mf<=1`` coupling)."""
        return self._coupling == "tl+mf<=1"

