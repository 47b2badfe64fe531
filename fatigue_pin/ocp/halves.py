"""One half of a signed torque actuator (:class:`ActuatorHalf`) and the groups of halves with the
same fatigue equations (:class:`FatigueGroup`); :mod:`fatigue_pin.ocp.actuators` assembles them."""

from __future__ import annotations

import math
from dataclasses import dataclass

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.core.text import shown
from fatigue_pin.fatigue.interface import FatigueModel

__all__ = ["ActuatorHalf", "FatigueGroup"]


@dataclass(frozen=True)
class FatigueGroup:
    """Actuator halves whose fatigue models have the same equations
    (:meth:`SignedTorqueActuators.fatigue_groups`).

    Attributes:
        label: the model's kind (``xia``; runs of other characters than letters and digits as one
            ``_``), with ``_2``, ``_3``, ... for further groups of the same kind (other options,
            e.g. Xia's ``rest_load``).
        model: the model of the group's first half (its equations are every half's).
        halves: indices of the halves, increasing.
        state_rows: rows of their states in the fatigue state vector, half after half (each
            half's states in its model's order), length ``len(halves) * model.n_states()``.
        param_rows: entries of their parameters in the parameter vector, half after half.
    """

    label: str
    model: FatigueModel
    halves: tuple[int, ...]
    state_rows: tuple[int, ...]
    param_rows: tuple[int, ...]


@dataclass(frozen=True)
class ActuatorHalf:
    """One half of a signed torque actuator.

    Attributes:
        joint: name of the joint it drives.
        sign: +1 for the flexion half (torque >= 0), -1 for the extension half (torque <= 0).
        tau_limit: magnitude of its torque limit (N m, or N for a prismatic joint), > 0.
        params: its fatigue model with its parameter values (any :class:`FatigueModel`).
    """

    joint: str
    sign: int
    tau_limit: float
    params: FatigueModel

    def __post_init__(self) -> None:
        if self.sign not in (1, -1) or isinstance(self.sign, bool):
            raise ParameterError(f"ActuatorHalf({self.joint!r}).sign = {shown(self.sign)}: expected +1 or -1")
        lim = float(self.tau_limit)
        if not math.isfinite(lim) or lim <= 0.0:
            raise ParameterError(
                f"ActuatorHalf({self.joint!r}, sign {self.sign:+d}).tau_limit = {shown(self.tau_limit)}: "
                "expected a finite torque magnitude > 0 (N m)"
            )
        object.__setattr__(self, "tau_limit", lim)
        if not isinstance(self.params, FatigueModel):
            raise ParameterError(f"ActuatorHalf({self.joint!r}).params = {self.params!r}: expected a fatigue model (FatigueModel)")

    @property
    def name(self) -> str:
        """``<joint>_plus`` or ``<joint>_minus``."""
        return f"{self.joint}_{'plus' if self.sign > 0 else 'minus'}"

    @property
    def signed_limit(self) -> float:
        """The torque at TL = 1: ``+tau_limit`` or ``-tau_limit`` (N m)."""
        return self.sign * self.tau_limit

    @property
    def tau_bounds(self) -> tuple[float, float]:
        """``(lower, upper)`` torque bounds of this half (N m): ``(0, tau_limit)`` or ``(-tau_limit, 0)``."""
        return (0.0, self.tau_limit) if self.sign > 0 else (-self.tau_limit, 0.0)
