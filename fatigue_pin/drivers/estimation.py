"""Estimators of the fatigue states that nobody measures: what a closed-loop controller plans from.

The controller of a closed loop (:mod:`fatigue_pin.drivers.mpc`) never sees the plant's fatigue
states. It knows the torques the plant delivered in every interval, the measured q and qdot and,
every ``probe_every`` cycles, a noisy measurement of each half's capacity ``1 - mf`` (an MVC test,
a motor reading). An estimator turns these into the fatigue states (and fatigue parameters) the
next window starts from:

* ``open-loop`` (:class:`OpenLoopEstimator`): the controller's own fatigue model driven by the
  delivered torques, ``m_{k+1} = Phi(m_k, u_k; p)`` with the interval function of the OCP;
  probes are ignored.
* ``mhe`` (:class:`MheEstimator`): moving-horizon estimation. At every re-plan (node k) it solves,
  over the last ``cycles`` cycles (nodes k0 = max(0, k - cycles n) .. k, L = k - k0 intervals)::

      min over m_k0, theta   sum_probes |y_j - (1 - mf_j)|^2 / sigma_y^2
                           + sum_saturated |TL_i - (1 - mf_i)|^2 / sigma_s^2
                           + sum_i max(0, TL_i + mf_i - 1)^2 / sigma_s^2
                           + |m_k0 - mbar_k0|^2 / sigma_m^2
                           + sum_e ((theta_e - thetabar_e) / (sigma_theta * theta0_e))^2
      with m_{i+1} = Phi(m_i, u_i; p(theta)), 0 <= m_k0 <= 1, theta >= 0

  where theta are the estimated parameters of every half (``params``, e.g. F and R), theta0
  their values in the controller's model, thetabar and mbar_k0 the current estimates (the
  arrival cost), TL_i the delivered target loads. A half whose delivered torque is below the
  command was saturated: its capacity was exactly the delivered load (the second term); otherwise
  the delivered load is at most the capacity (the third term, soft). The measured motion adds
  nothing about fatigue once the delivered torques are known (the rigid body does not depend on
  the fatigue states), so it does not enter. It is a CasADi NLP solved with IPOPT, one per
  window length L (at most ``cycles n / replan_every`` of them).

Between re-plans both estimators propagate the current estimate with the current parameters.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.ocp.actuation_layer import ActuationLayer
from fatigue_pin.ocp.transcription import IntervalFunctions
from fatigue_pin.core.text import shown

#: Estimators of a closed loop.
ESTIMATORS = ("open-loop", "mhe")


def _positive(owner: str, value: object, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(float(value)) or value <= 0:
        raise ParameterError(f"{owner} = {shown(value)}: expected {what}")
    return float(value)


@dataclass(frozen=True)
class MheSettings:
    """Settings of the moving-horizon estimator.

    Attributes:
        cycles: length of the estimation window (cycles, >= 1).
        params: fatigue parameters estimated for every half (names of its model's parameters,
            e.g. ``("F", "R")``; empty: the states only).
        probe_std: standard deviation assumed for a capacity probe (dimensionless).
        saturation_std: standard deviation of the capacity read from a saturated half.
        state_std: prior standard deviation of the fatigue states at the window start.
        param_std: prior standard deviation of every estimated parameter, as a fraction of its
            value in the controller's model.
        max_iter: IPOPT iteration limit of one estimate.
    """

    cycles: int = 3
    params: tuple[str, ...] = ("F", "R")
    probe_std: float = 0.01
    saturation_std: float = 0.001
    state_std: float = 0.05
    param_std: float = 1.0
    max_iter: int = 200

    def __post_init__(self) -> None:
        if isinstance(self.cycles, bool) or not isinstance(self.cycles, int) or self.cycles < 1:
            raise ParameterError(f"mpc.mhe.cycles = {self.cycles!r}: expected an integer number of cycles >= 1")
        if isinstance(self.params, str) or not all(isinstance(p, str) for p in self.params):
            raise ParameterError(f"mpc.mhe.params = {shown(self.params)}: expected a list of fatigue parameter names, e.g. ['F', 'R']")
        object.__setattr__(self, "params", tuple(self.params))
        for key in ("probe_std", "saturation_std", "state_std", "param_std"):
            object.__setattr__(self, key, _positive(f"mpc.mhe.{key}", getattr(self, key), "a standard deviation > 0"))
        if isinstance(self.max_iter, bool) or not isinstance(self.max_iter, int) or self.max_iter < 1:
            raise ParameterError(f"mpc.mhe.max_iter = {self.max_iter!r}: expected an integer >= 1")


@dataclass
class History:
    """What the controller knows, node by node (k = 0 .. current node).

    Attributes:
        m: estimated fatigue states at every node (after the correction at re-plans), (nodes, n_states).
        u_command: commanded controls of every interval, (intervals, nu).
        u_delivered: delivered controls of every interval, (intervals, nu).
        probes: capacity probes by node, each (n_halves,).
    """

    m: list[np.ndarray] = field(default_factory=list)
    u_command: list[np.ndarray] = field(default_factory=list)
    u_delivered: list[np.ndarray] = field(default_factory=list)
    probes: dict[int, np.ndarray] = field(default_factory=dict)


class OpenLoopEstimator:
    """The controller's fatigue model driven by the delivered torques (probes are ignored).

    Args:
        functions: the controller's interval functions (``F_fatigue``).
        actuators: the controller's actuators (their parameters start the estimate).
    """

    kind = "open-loop"

    def __init__(self, functions: IntervalFunctions, actuators: ActuationLayer) -> None:
        self.functions = functions
        self.actuators = actuators
        #: the fatigue parameters the controller plans with (n_params,)
        self.params = actuators.param_vector()

    def predict(self, m: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Estimate at the next node from ``m`` (n_states,) under the delivered ``u`` (nu,)."""
        return np.asarray(self.functions.F_fatigue(m, u, self.params)).reshape(-1)

    def correct(self, k: int, history: History) -> np.ndarray:
        """The estimate at node ``k`` given everything known then (open loop: the prediction)."""
        del k
        return history.m[-1]


class MheEstimator(OpenLoopEstimator):
    """Moving-horizon estimation of the fatigue states and parameters (module docstring).

    Args:
        functions: the controller's interval functions.
        actuators: the controller's actuators.
        settings: window, estimated parameters, prior and noise levels.
        intervals_per_cycle: n.
    """

    kind = "mhe"

    def __init__(self, functions: IntervalFunctions, actuators: ActuationLayer, settings: MheSettings,
                 intervals_per_cycle: int) -> None:
        super().__init__(functions, actuators)
        self.settings = settings
        self.n = int(intervals_per_cycle)
        index = []
        for h, offset in zip(actuators.halves, actuators.param_offsets()):
            unknown = [p for p in settings.params if p not in h.params.param_names]
            if unknown:
                raise ParameterError(f"mpc.mhe.params = {list(settings.params)}: half {h.name!r} has no parameter "
                                     f"{unknown[0]!r}; its parameters are {list(h.params.param_names)}")
            index += [offset + h.params.param_names.index(p) for p in settings.params]
        #: rows of the parameter vector that are estimated
        self.index = np.array(index, dtype=int)
        self.nominal = actuators.param_vector()[self.index]
        self._fatigued = np.array(actuators.fatigued_rows())
        self._measured = np.array(actuators.measured_rows())
        self._actuators = actuators
        self._solvers: dict[int, ca.Function] = {}
        self._traj: dict[int, ca.Function] = {}
        #: wall time of the last correction (s)
        self.last_wall_time_s = 0.0

    def _target_loads(self, u: np.ndarray) -> np.ndarray:
        """Target loads (n_halves, L) from controls (L, nu)."""
        A = self._actuators
        return (A.half_torques(np.asarray(u, dtype=float).reshape(-1, A.nu)) / A.signed_limits).T

    def _solver(self, L: int) -> ca.Function:
        """The estimation NLP over L intervals (built once per L)."""
        if L in self._solvers:
            return self._solvers[L]
        s, A = self.settings, self.actuators
        ns, nu, nh, ne, npar = A.n_states, A.nu, A.n_halves, self.index.size, A.n_params
        m0, theta = ca.MX.sym("m0", ns), ca.MX.sym("theta", ne)
        U, Y, YM = ca.MX.sym("U", nu, L), ca.MX.sym("Y", nh, L + 1), ca.MX.sym("YM", nh, L + 1)
        TL, SM = ca.MX.sym("TL", nh, L), ca.MX.sym("SM", nh, L)
        mbar, tbar, p_base = ca.MX.sym("mbar", ns), ca.MX.sym("tbar", ne), ca.MX.sym("p", npar)
        select = np.zeros((npar, ne))
        select[self.index, np.arange(ne)] = 1.0
        keep = 1.0 - select.sum(axis=1)
        p = p_base * ca.DM(keep) + ca.mtimes(ca.DM(select), theta)
        traj = self.functions.F_fatigue.mapaccum(L)(m0, U, ca.repmat(p, 1, L))
        M = ca.horzcat(m0, traj)
        mf = M[self._fatigued.tolist(), :]
        capacity = 1 - mf
        f = ca.sumsqr(YM * (Y - (1 - M[self._measured.tolist(), :]))) / s.probe_std**2  # the probes (a motor's housing)
        if A.capacity_limits_load:  # a saturated half's capacity was its load; no load above capacity
            f += ca.sumsqr(SM * (TL - capacity[:, :L])) / s.saturation_std**2
            f += ca.sumsqr(ca.fmax(0, TL + mf[:, :L] - 1)) / s.saturation_std**2
        f += ca.sumsqr(m0 - mbar) / s.state_std**2
        f += ca.sumsqr((theta - tbar) / ca.DM(np.maximum(self.nominal, 1e-12))) / s.param_std**2
        params = ca.vertcat(ca.vec(U), ca.vec(Y), ca.vec(YM), ca.vec(TL), ca.vec(SM), mbar, tbar, p_base)
        nlp = {"x": ca.vertcat(m0, theta), "p": params, "f": f}
        opts = {"print_time": False, "ipopt": {"print_level": 0, "sb": "yes", "max_iter": s.max_iter}}
        self._solvers[L] = ca.nlpsol(f"mhe_{L}", "ipopt", nlp, opts)
        self._traj[L] = ca.Function(f"mhe_traj_{L}", [m0, theta, U, p_base], [M])
        return self._solvers[L]

    def correct(self, k: int, history: History) -> np.ndarray:
        """Solve the estimation NLP over the window ending at node ``k``; update :attr:`params`
        and return the corrected estimate at node ``k`` (n_states,). Without a probe or a
        saturated half in the window the prediction is returned unchanged."""
        t0 = time.perf_counter()
        k0 = max(0, k - self.settings.cycles * self.n)
        L = k - k0
        nh = self.actuators.n_halves
        Y, YM = np.zeros((nh, L + 1)), np.zeros((nh, L + 1))
        for node, value in history.probes.items():
            if k0 <= node <= k:
                Y[:, node - k0], YM[:, node - k0] = value, 1.0
        if L == 0 or not (YM.any() or self._saturated(history, k0, k).any()):
            self.last_wall_time_s = time.perf_counter() - t0
            return history.m[-1]
        u_del = np.array(history.u_delivered[k0:k])
        TL = self._target_loads(u_del)
        SM = self._saturated(history, k0, k).astype(float)
        solver = self._solver(L)
        tbar = self.params[self.index]
        mbar = history.m[k0]
        p = np.concatenate([u_del.T.reshape(-1, order="F"), Y.reshape(-1, order="F"), YM.reshape(-1, order="F"),
                            TL.reshape(-1, order="F"), SM.reshape(-1, order="F"), mbar, tbar, self.params])
        ns = self.actuators.n_states
        lbx = np.concatenate([np.zeros(ns), np.full(self.index.size, 1e-9)])
        ubx = np.concatenate([np.ones(ns), np.full(self.index.size, np.inf)])
        res = solver(x0=np.concatenate([mbar, tbar]), p=p, lbx=lbx, ubx=ubx)
        z = np.asarray(res["x"]).reshape(-1)
        self.last_wall_time_s = time.perf_counter() - t0
        if not solver.stats()["success"] or not np.all(np.isfinite(z)):
            return history.m[-1]  # keep the prediction
        params = self.params.copy()
        params[self.index] = z[ns:]
        traj = np.asarray(self._traj[L](z[:ns], z[ns:], u_del.T, self.params))
        self.params = params
        return np.clip(traj[:, -1], 0.0, 1.0)

    def _saturated(self, history: History, k0: int, k: int) -> np.ndarray:
        """Whether each half was saturated (delivered below its command) in intervals k0..k-1,
        shape (n_halves, L)."""
        if k == k0:
            return np.zeros((self.actuators.n_halves, 0), dtype=bool)
        cmd = self._target_loads(np.array(history.u_command[k0:k]))
        dlv = self._target_loads(np.array(history.u_delivered[k0:k]))
        return cmd - dlv > 1e-9


def make_estimator(kind: str, functions: IntervalFunctions, actuators: ActuationLayer,
                   mhe: MheSettings | None = None, intervals_per_cycle: int = 1) -> OpenLoopEstimator:
    """The estimator named ``kind`` (:data:`ESTIMATORS`)."""
    if kind == "open-loop":
        return OpenLoopEstimator(functions, actuators)
    if kind == "mhe":
        return MheEstimator(functions, actuators, mhe or MheSettings(), intervals_per_cycle)
    raise ParameterError(f"mpc.estimator = {kind!r}: expected one of {list(ESTIMATORS)}")
