"""What an OCP hands back: its solution (:class:`OcpSolution`, states and controls by name) and
its NLP parameters addressed by name (:class:`ParameterLayout`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import casadi as ca
import numpy as np

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.ocp.problem import StateLayout
from fatigue_pin.ocp.solver import NlpResult

class ParameterLayout:
    """Named blocks of the NLP's parameter vector, created through Opti in a recorded order."""

    def __init__(self, opti: ca.Opti) -> None:
        self._opti = opti
        self._blocks: dict[str, tuple[slice, tuple[int, int]]] = {}
        self._size = 0
        #: the size at which the Opti problem's parameters were last found to be the layout's
        #: (asking Opti for its parameter vector takes about 10 ms on a window)
        self._checked_size = -1

    def add(self, name: str, rows: int, cols: int = 1) -> ca.MX:
        sym = self._opti.parameter(rows, cols)
        self._blocks[name] = (slice(self._size, self._size + rows * cols), (rows, cols))
        self._size += rows * cols
        return sym

    @property
    def size(self) -> int:
        return self._size

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self._blocks)

    def vector(self, values: Mapping[str, np.ndarray]) -> np.ndarray:
        """The parameter vector from a value per block (column-major, as CasADi stores it)."""
        if self._checked_size != self._size:
            if self._size != self._opti.p.numel():
                raise RuntimeError("the Opti problem has parameters that are not in the parameter layout")
            self._checked_size = self._size
        out = np.zeros(self._size)
        for name, (sl, shape) in self._blocks.items():
            if name not in values:
                raise ParameterError(f"no value for NLP parameter block {name!r}")
            a = np.asarray(values[name], dtype=float)
            if a.size != sl.stop - sl.start:
                raise ParameterError(f"NLP parameter block {name!r} has {a.size} values; expected shape {shape}")
            out[sl] = a.reshape(shape).reshape(-1, order="F")
        return out


@dataclass
class OcpSolution:
    """A solved (or failed) OCP on its node grid.

    Attributes:
        t: node times (s), shape (N+1,).
        x: states, shape (N+1, nx); u: controls, shape (N, nu) (two halves per actuated joint).
        layout: the state layout; actuator_names: names of the halves.
        status, success, iterations, wall_time_s: from IPOPT (a failure keeps the last iterate).
        nlp: the raw NLP result (flat vectors and multipliers, for warm starts).
        cycle_costs: weighted cost terms per cycle, shape (n_cycles, n_terms), columns ``cost_terms``.
        objective: the objective value.
        cost_terms: names of the columns of ``cycle_costs``.
    """

    t: np.ndarray
    x: np.ndarray
    u: np.ndarray
    layout: StateLayout
    actuator_names: tuple[str, ...]
    status: str
    success: bool
    iterations: int
    wall_time_s: float
    nlp: NlpResult
    cycle_costs: np.ndarray
    objective: float
    cost_terms: tuple[str, ...] = ()

    @property
    def kind(self) -> str:
        """How the solve ended (:func:`fatigue_pin.ocp.solver.failure_kind`): ``converged``,
        ``infeasible``, ``infeasible-growing``, ``not-converged`` or ``numerical``."""
        return self.nlp.kind

    @property
    def q(self) -> np.ndarray:
        return self.x[:, self.layout.q]

    @property
    def qdot(self) -> np.ndarray:
        return self.x[:, self.layout.v]

    def fatigue(self, state: str) -> np.ndarray:
        """Fatigue state ``state`` of every half, shape (N+1, n_halves) (NaN where a half's model
        has no such state)."""
        return self.layout.fatigue_columns(self.x, state)

    @property
    def tau_plus(self) -> np.ndarray:
        """Flexion-half torques (N m), (N, nv), 0 on passive joints."""
        return self.layout.actuators.per_joint(self.u)[0]

    @property
    def tau_minus(self) -> np.ndarray:
        """Extension-half torques (N m), (N, nv), 0 on passive joints."""
        return self.layout.actuators.per_joint(self.u)[1]

    @property
    def tau(self) -> np.ndarray:
        """Joint torques as the actuators deliver them (N m), (N, nv): the halves' sum, 0 on
        passive joints (under the ``active`` coupling, from the active fractions at the interval
        starts)."""
        L = self.layout
        return np.asarray(L.actuators.joint_torque(self.u, self.x[:-1, L.m], self.x[:-1, : L.nq + L.nv]))
