"""The plant of a closed-loop run: the simulated body that the controller's plan meets.

The plant is a problem of its own (its model, payload included, and its actuators with their
true fatigue parameters); it never shares state with the controller. Over every interval of
length dt it

1. limits each half's commanded torque to what its true fatigue state allows at the interval's
   start, ``TL_h <= 1 - mf_h`` (a tired plant cannot deliver what a fresh model plans), and
   holds the delivered torques constant over the interval (zero-order hold);
2. adds the torque disturbance ``d_k`` (N m per joint: a constant plus, with ``std`` > 0, a
   normal draw per interval);
3. integrates ``qddot = ABA(q, qdot, tau + d)``, tau the actuators' joint torque (the halves'
   sum, 0 on passive joints, or under the ``active`` coupling ``sum ma * limit``; numeric Pinocchio on the
   plant's model) and ``dm/dt`` of every half (its fatigue model's right-hand side, evaluated
   by :meth:`~fatigue_pin.ocp.actuation_layer.ActuationLayer.fatigue_rates`) with scipy's adaptive ``solve_ivp``
   (``integrator = "rk45"``, the default, with ``rtol`` and ``atol``: the plant stands for
   reality, so it follows the exact flow), or with ``substeps`` classical RK4 steps
   (``integrator = "rk4"``: with the controller's substeps a plant equal to the model integrates
   exactly as the plan does, also where the plan's grid is too coarse for its motion).

:meth:`Plant.flow_gap` re-integrates an interval the plant did with the reference integration of
:mod:`fatigue_pin.core.accuracy` (that of ``fatigue-pin verify``): the closed loop credits a
repetition only where every interval of the cycle is within verify's gap tolerances of it.

What the controller sees (:meth:`Plant.measure`, :meth:`Plant.probe`): q and qdot with normal
noise of std ``noise.q`` (rad) and ``noise.qdot`` (rad/s), and the capacity ``1 - mf`` of every
half with noise of std ``noise.capacity``. Every draw comes from a generator seeded with
``(seed, node, channel)``, so a run is reproducible bit for bit and a resumed run draws what an
uninterrupted one would.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import casadi as ca
import numpy as np
import pinocchio as pin
from scipy.integrate import solve_ivp

from fatigue_pin.core.accuracy import REFERENCE_ATOL, REFERENCE_METHOD, REFERENCE_RTOL
from fatigue_pin.core.errors import ParameterError
from fatigue_pin.ocp.problem import Problem
from fatigue_pin.core.text import shown

#: Integrators of the plant.
PLANT_INTEGRATORS = ("rk4", "rk45")
#: Generator channels (the third entry of the seed of every draw).
_MEASURE, _PROBE, _DISTURB = 0, 1, 2


def _std(owner: str, value: object, unit: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(float(value)) or value < 0:
        raise ParameterError(f"{owner} = {shown(value)}: expected a standard deviation >= 0 ({unit})")
    return float(value)


def _per_joint(owner: str, value: object, what: str) -> tuple[float, ...] | float:
    """A number or a list of numbers (N m), each finite (and >= 0 for a std)."""
    values = value if isinstance(value, (list, tuple)) else [value]
    for v in values:
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(float(v)) or (what == "std" and v < 0):
            expected = "a standard deviation >= 0 (N m)" if what == "std" else "a torque (N m)"
            raise ParameterError(f"{owner} = {shown(value)}: expected {expected}, or a list of them (one per joint)")
    return tuple(float(v) for v in values) if isinstance(value, (list, tuple)) else float(value)


@dataclass(frozen=True)
class PlantNoise:
    """Measurement noise (standard deviations, normal, independent per node and entry).

    Attributes:
        q: of the measured joint positions (rad, or m for a prismatic joint).
        qdot: of the measured joint velocities (rad/s or m/s).
        capacity: of the probed capacity ``1 - mf`` of every half (dimensionless).
    """

    q: float = 0.0
    qdot: float = 0.0
    capacity: float = 0.0

    def __post_init__(self) -> None:
        for key, unit in (("q", "rad"), ("qdot", "rad/s"), ("capacity", "a fraction of the half's limit")):
            object.__setattr__(self, key, _std(f"plant.noise.{key}", getattr(self, key), unit))


@dataclass(frozen=True)
class PlantDisturbance:
    """A torque disturbance added to every joint's torque, held over each interval.

    Attributes:
        constant: N m, one value for every joint or one per joint.
        std: standard deviation of a normal draw per interval and joint (N m), one value or one
            per joint.
    """

    constant: tuple[float, ...] | float = 0.0
    std: tuple[float, ...] | float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "constant", _per_joint("plant.disturbance.constant", self.constant, "torque"))
        object.__setattr__(self, "std", _per_joint("plant.disturbance.std", self.std, "std"))

    def vectors(self, joint_names: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
        """``(constant, std)`` as arrays of shape (nv,) for a model with ``joint_names``."""
        nv = len(joint_names)
        out = []
        for key in ("constant", "std"):
            value = np.atleast_1d(np.asarray(getattr(self, key), dtype=float))
            if value.size == 1:
                value = np.full(nv, float(value[0]))
            if value.size != nv:
                raise ParameterError(f"plant.disturbance.{key} has {value.size} values; expected 1 or one per joint "
                                     f"{list(joint_names)}")
            out.append(value)
        return out[0], out[1]

    @property
    def active(self) -> bool:
        return bool(np.any(np.asarray(self.constant) != 0) or np.any(np.asarray(self.std) > 0))


@dataclass(frozen=True)
class PlantSettings:
    """How the plant is simulated and measured (its model and fatigue come from its problem).

    Attributes:
        noise: measurement noise.
        disturbance: torque disturbance.
        seed: seed of every random draw (an integer >= 0).
        integrator: ``rk45`` (scipy's adaptive ``solve_ivp``, RK45 with ``rtol``, ``atol``;
            the default: about 1e-8 of the exact flow where 2 RK4 substeps of 0.05 s are 1 rad/s
            off it) or ``rk4`` (``substeps`` classical steps per interval: the plan's own scheme
            with the controller's substeps, for comparisons with the sliding horizon).
        substeps: RK4 steps per interval of ``rk4``; ``None``: the controller's transcription's.
        rtol, atol: relative and absolute (in each state's unit) tolerances of ``rk45``.
    """

    noise: PlantNoise = field(default_factory=PlantNoise)
    disturbance: PlantDisturbance = field(default_factory=PlantDisturbance)
    seed: int = 0
    integrator: str = "rk45"
    substeps: int | None = None
    rtol: float = 1e-9
    atol: float = 1e-11

    def __post_init__(self) -> None:
        if not isinstance(self.noise, PlantNoise):
            raise ParameterError(f"plant.noise = {self.noise!r}: expected a PlantNoise")
        if not isinstance(self.disturbance, PlantDisturbance):
            raise ParameterError(f"plant.disturbance = {self.disturbance!r}: expected a PlantDisturbance")
        if isinstance(self.seed, bool) or not isinstance(self.seed, (int, np.integer)) or self.seed < 0:
            raise ParameterError(f"seed = {self.seed!r}: expected an integer >= 0")
        if self.integrator not in PLANT_INTEGRATORS:
            raise ParameterError(f"plant.integrator = {self.integrator!r}: expected one of {list(PLANT_INTEGRATORS)}")
        if self.substeps is not None and (isinstance(self.substeps, bool) or not isinstance(self.substeps, int) or self.substeps < 1):
            raise ParameterError(f"plant.substeps = {self.substeps!r}: expected an integer >= 1 (RK4 steps per interval)")
        for key in ("rtol", "atol"):
            v = getattr(self, key)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not (0 < v < 1):
                raise ParameterError(f"plant.{key} = {shown(v)}: expected a tolerance in (0, 1)")

    @property
    def noisy(self) -> bool:
        """Whether anything the controller measures or the plant feels is random."""
        n = self.noise
        return n.q > 0 or n.qdot > 0 or n.capacity > 0 or bool(np.any(np.asarray(self.disturbance.std) > 0))


class Plant:
    """The simulated body (see the module docstring).

    Args:
        problem: the plant's problem: its model (payload included) and actuators (true fatigue
            parameters); its state layout must be the controller's.
        dt: interval length (s).
        settings: noise, disturbance, seed, integrator.
        substeps: RK4 steps per interval when ``settings.substeps`` is None.
    """

    def __init__(self, problem: Problem, dt: float, settings: PlantSettings | None = None, substeps: int = 5) -> None:
        self.settings = settings or PlantSettings()
        self.problem = problem
        self.model, self.actuators = problem.model, problem.actuators
        self.layout = problem.layout
        self.dt = float(dt)
        self.substeps = self.settings.substeps or int(substeps)
        self._data = self.model.pin_model.createData()
        L = self.layout
        m, u = ca.SX.sym("m", L.n_fatigue), ca.SX.sym("u", L.nu)
        # the halves' own right-hand sides with the plant's parameters (one owner of the equations)
        self._rates = ca.Function("plant_rates", [m, u], [self.actuators.fatigue_rates(m, u)])
        self._fatigued = [L.nq + L.nv + r for r in self.actuators.fatigued_rows()]
        self._measured = [L.nq + L.nv + r for r in self.actuators.measured_rows()]
        self._constant, self._std = self.settings.disturbance.vectors(self.model.joint_names)
        self._limits_u = self.actuators.controls(self.actuators.signed_limits)  # in control order

    def _rng(self, node: int, channel: int) -> np.random.Generator:
        return np.random.default_rng([int(self.settings.seed), int(node), channel])

    # -- what the plant does ---------------------------------------------------------------------

    def capacity(self, x: np.ndarray) -> np.ndarray:
        """True capacity ``1 - mf`` of every half (half order), shape (n_halves,)."""
        return 1.0 - np.asarray(x)[self._fatigued]

    def deliver(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """The torques (nu,) the plant delivers for the command ``u`` (nu,) in state ``x``: the
        layer's :meth:`~fatigue_pin.ocp.actuation_layer.ActuationLayer.delivered_loads`. A half's
        target load is limited to its capacity ``max(1 - mf, 0)`` (the sign of a command is not
        corrected: the solver's bounds hold up to its bound relaxation, about 1e-8); a motor
        delivers its command while its winding is below the limit and trips to 0 at it (derated:
        within ``limit sqrt(1 - x_w)``)."""
        cap = self.actuators.controls(np.maximum(self.capacity(x), 0.0))  # in control order
        TL = np.asarray(u, dtype=float) / self._limits_u
        return self.actuators.delivered_loads(TL, cap) * self._limits_u

    def disturbance(self, node: int) -> np.ndarray:
        """Torque disturbance of the interval starting at ``node`` (nv,), N m."""
        d = self._constant.copy()
        if np.any(self._std > 0):
            d = d + self._std * self._rng(node, _DISTURB).standard_normal(self._std.size)
        return d

    def rhs(self, x: np.ndarray, u: np.ndarray, d: np.ndarray) -> np.ndarray:
        """``dx/dt`` (nx,) under the delivered torques ``u`` (nu,) and disturbance ``d`` (nv,)."""
        L = self.layout
        q, v = x[L.q], x[L.v]
        # the actuators' torque (0 on passive joints; muscles': at this q and qdot)
        tau = self.actuators.joint_torque(u, x[L.m], np.concatenate([q, v])) + d
        a = pin.aba(self.model.pin_model, self._data, q, v, tau)
        m = np.asarray(self._rates(x[L.m], u)).reshape(-1)
        return np.concatenate([v, a, m])

    def step(self, x: np.ndarray, u_command: np.ndarray, node: int) -> tuple[np.ndarray, np.ndarray]:
        """One interval from ``x`` (nx,) at ``node`` under the command ``u_command`` (nu,).

        Returns:
            The state at the next node (nx,) and the delivered torques (nu,).
        """
        x = np.asarray(x, dtype=float)
        u = self.deliver(x, u_command)
        d = self.disturbance(node)
        if self.settings.integrator == "rk45":
            return self._solve(x, u, d, "RK45", self.settings.rtol, self.settings.atol), u
        h = self.dt / self.substeps
        for _ in range(self.substeps):
            k1 = self.rhs(x, u, d)
            k2 = self.rhs(x + h / 2 * k1, u, d)
            k3 = self.rhs(x + h / 2 * k2, u, d)
            k4 = self.rhs(x + h * k3, u, d)
            x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        return x, u

    def _solve(self, x: np.ndarray, u: np.ndarray, d: np.ndarray, method: str, rtol: float, atol: float) -> np.ndarray:
        """``solve_ivp`` over one interval from ``x`` (nx,) with ``u`` (nu,) and ``d`` (nv,) held;
        NaN (nx,) where it fails or the state turns non-finite."""
        with np.errstate(all="ignore"):
            sol = solve_ivp(lambda t, y: self.rhs(y, u, d), (0.0, self.dt), x, method=method, rtol=rtol, atol=atol)
        if not sol.success or not np.all(np.isfinite(sol.y[:, -1])):
            return np.full(x.shape, np.nan)
        return sol.y[:, -1].copy()

    def flow_gap(self, x: np.ndarray, u_delivered: np.ndarray, node: int, x_next: np.ndarray) -> tuple[float, float]:
        """How far the plant's interval from ``x`` (nx,) at ``node`` to ``x_next`` (nx,) under the
        delivered torques ``u_delivered`` (nu,) is from the exact flow: the reference integration
        (:mod:`fatigue_pin.core.accuracy`, verify's) from ``x`` with the same torques and
        disturbance. Returns the largest gap of (q, qdot) (rad, rad/s) and of the fatigue states
        (dimensionless); ``inf`` where the reference integration fails."""
        L = self.layout
        x = np.asarray(x, dtype=float)
        if not np.all(np.isfinite(x)):
            return math.inf, math.inf
        exact = self._solve(x, np.asarray(u_delivered, dtype=float), self.disturbance(node), REFERENCE_METHOD,
                            REFERENCE_RTOL, REFERENCE_ATOL)
        gap = np.abs(exact - np.asarray(x_next, dtype=float))
        if not np.all(np.isfinite(gap)):
            return math.inf, math.inf
        body = gap[: L.nq + L.nv]
        fatigue = gap[L.nq + L.nv :]
        return float(body.max(initial=0.0)), float(fatigue.max(initial=0.0))

    # -- what the controller sees ----------------------------------------------------------------

    def measure(self, x: np.ndarray, node: int) -> tuple[np.ndarray, np.ndarray]:
        """Measured q (nq,) and qdot (nv,) at ``node``."""
        L, n = self.layout, self.settings.noise
        q, v = np.array(x[L.q], dtype=float), np.array(x[L.v], dtype=float)
        if n.q > 0 or n.qdot > 0:
            e = self._rng(node, _MEASURE).standard_normal(L.nq + L.nv)
            q, v = q + n.q * e[: L.nq], v + n.qdot * e[L.nq :]
        return q, v

    def probe(self, x: np.ndarray, node: int) -> np.ndarray:
        """Measured capacity ``1 - mf`` of every half (half order) at ``node``, shape (n_halves,):
        ``1 -`` the state of :meth:`~fatigue_pin.ocp.actuation_layer.ActuationLayer.measured_rows`
        (a motor's housing)."""
        c = 1.0 - np.asarray(x)[self._measured]
        if self.settings.noise.capacity > 0:
            c = c + self.settings.noise.capacity * self._rng(node, _PROBE).standard_normal(c.size)
        return c
