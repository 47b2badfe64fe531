"""Activation dynamics: a muscle's activation as a state, driven by its excitation.

With ``[actuators] activation_dynamics = true`` a muscle's control is its excitation ``e`` in
[0, 1] and its activation ``a`` is a state with De Groote et al.'s first-order dynamics
(:func:`~fatigue_pin.muscles.curves.activation_rate`, Moco's ``DeGrooteFregly2016Muscle``):

    f = tanh(b (e - a)) / 2,   z = 0.5 + 1.5 a,
    da/dt = ((f + 1/2) / (tau_a z) + (1/2 - f) z / tau_d) (e - a)

with the muscle's own ``activation_time`` tau_a, ``deactivation_time`` tau_d (s) and
``activation_smoothing`` b. The force follows ``a``; the fatigue model's target load is the
excitation ``e`` (bioptim's and MyoSuite's choice: the command sent to the motor units).

The activation is carried as the first state of the muscle's unit in the actuation layer: the
unit's model is its fatigue model with the activation put in front (:func:`activated`), a
:class:`~fatigue_pin.fatigue.interface.FatigueModel` whose states are ``("a", *states)`` and whose
parameters are the fatigue model's followed by the three of the activation. So the layer's state
layout, its names, the result files, the plots and verify's re-integration carry the activation
with no code of their own; verify reads the force's activation from the ``a`` column
(:class:`ActivatedFatigue`).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from typing import ClassVar

import casadi as ca
import numpy as np

from fatigue_pin.core.errors import DimensionError, ParameterError
from fatigue_pin.core.text import shown
from fatigue_pin.fatigue.interface import STABILITY_LIMITS, FatigueModel
from fatigue_pin.muscles.curves import activation_rate

__all__ = ["ACTIVATION", "SUFFIX", "ActivatedFatigue", "activated", "with_activation", "activation_stiffness"]

#: The activation's state name.
ACTIVATION = "a"
#: What the kind of an activated model adds to its fatigue model's kind (``"xia+activation"``).
SUFFIX = "+activation"
#: The activation's parameters, after the fatigue model's, with their units.
ACTIVATION_PARAMS = ("activation_time", "deactivation_time", "activation_smoothing")
ACTIVATION_UNITS = ("s", "s", "1")


def activation_stiffness(tau_act: float, tau_deact: float, smoothing: float, samples: int = 201) -> float:
    """The largest ``-d(da/dt)/da`` (1/s) over excitations and activations in [0, 1]: the rate
    an explicit step must resolve (``rate * dt`` inside the method's stability interval)."""
    e, a = np.meshgrid(np.linspace(0.0, 1.0, samples), np.linspace(0.0, 1.0, samples))
    h = 1e-6
    lo, hi = np.clip(a - h, 0.0, None), np.clip(a + h, None, 1.0)
    slope = (activation_rate(e, hi, tau_act, tau_deact, smoothing) - activation_rate(e, lo, tau_act, tau_deact, smoothing)) / (hi - lo)
    return float(max(-slope.min(), 0.0))


class ActivatedFatigue(FatigueModel):
    """A fatigue model with the activation dynamics in front (module docstring): states
    ``("a", *fatigue states)``, parameters ``(*fatigue parameters, activation_time,
    deactivation_time, activation_smoothing)``, target load the excitation. Made per fatigue
    model class by :func:`activated`."""

    base: ClassVar[type[FatigueModel]]

    def __post_init__(self) -> None:
        owner = type(self).__name__
        for name in ACTIVATION_PARAMS:
            value = getattr(self, name)
            ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool) and math.isfinite(value)
            if not ok or value <= 0:
                what = "a time constant > 0 (s)" if name != "activation_smoothing" else "a smoothing > 0 (dimensionless)"
                raise ParameterError(f"{owner}.{name} = {shown(value)}: expected {what}")
            object.__setattr__(self, name, float(value))
        super().__post_init__()

    def fatigue(self) -> FatigueModel:
        """The fatigue model alone (without the activation)."""
        names = [f.name for f in dataclasses.fields(self.base)]
        return self.base(**{n: getattr(self, n) for n in names})

    def rhs(self) -> ca.Function:
        """``(m = (a, *fatigue states), e, p) -> dm`` (1/s): the activation rate, then the fatigue
        model's rates at the target load ``e``."""
        inner = self.fatigue().rhs()
        n, k = self.n_states(), self.base.n_params()
        m, e, p = ca.SX.sym("m", n), ca.SX.sym("TL"), ca.SX.sym("p", self.n_params())
        da = activation_rate(e, m[0], p[k], p[k + 1], p[k + 2])
        return ca.Function(f"{self.base.kind}_activated_rhs", [m, e, p], [ca.vertcat(da, inner(m[1:], e, p[:k]))],
                           ["m", "TL", "p"], ["dm"])

    @classmethod
    def total_states(cls) -> tuple[str, ...]:
        """The fatigue model's states (the activation is not part of its sum)."""
        return cls.base.state_names

    @classmethod
    def rest_state(cls) -> np.ndarray:
        """A relaxed, rested muscle: activation 0 and the fatigue model's rested state."""
        return np.concatenate([[0.0], cls.base.rest_state()])

    def check_state(self, m: np.ndarray, owner: str = "fatigue state", tol: float = 1e-4) -> np.ndarray:
        """The activation a fraction in [0, 1], and the rest a valid state of the fatigue model."""
        m = np.asarray(m, dtype=float).reshape(-1)
        if m.shape != (self.n_states(),):
            raise DimensionError(f"{owner} has {m.size} entries; expected {self.n_states()} {list(self.state_names)}")
        if not math.isfinite(m[0]) or m[0] < -tol or m[0] > 1.0 + tol:
            raise ParameterError(f"{owner}: a = {m[0]:g}; expected an activation in [0, 1]")
        self.fatigue().check_state(m[1:], owner, tol)
        return m

    def check_step(self, dt: float, method: str = "rk4") -> None:
        """The fatigue model's check, then the activation's: its stiffest rate times ``dt``
        inside the method's stability interval."""
        self.fatigue().check_step(dt, method)
        limit = STABILITY_LIMITS.get(method.lower())
        if limit is None:
            return
        rate = activation_stiffness(self.activation_time, self.deactivation_time, self.activation_smoothing)
        if rate * float(dt) >= limit:
            raise ParameterError(f"activation dynamics (activation_time = {self.activation_time:g} s, deactivation_time = "
                                 f"{self.deactivation_time:g} s) with {method} step dt = {float(dt)!r} s: rate x dt = "
                                 f"{rate * float(dt):.4g} is outside the method's stability interval (< {limit:.4g}); "
                                 f"expected a step below {limit / rate:.4g} s (more substeps)")


@functools.cache
def activated(base: type[FatigueModel]) -> type[ActivatedFatigue]:
    """The class of ``base``'s model with the activation in front (:class:`ActivatedFatigue`),
    made once per fatigue model class: a frozen dataclass with ``base``'s fields and the
    activation's three."""
    if issubclass(base, ActivatedFatigue):
        raise ParameterError(f"fatigue model {base.kind!r} already carries an activation")
    namespace = {
        "base": base,
        "kind": base.kind + SUFFIX,
        "state_names": (ACTIVATION, *base.state_names),
        "param_names": (*base.param_names, *ACTIVATION_PARAMS),
        "param_units": (*base.param_units, *ACTIVATION_UNITS),
        "__doc__": f"{base.__name__} with the activation dynamics in front (:class:`ActivatedFatigue`).",
        "__module__": __name__,
    }
    fields = [(name, float, dataclasses.field(default=default)) for name, default in zip(ACTIVATION_PARAMS, (0.015, 0.060, 0.1))]
    return dataclasses.make_dataclass(f"Activated{base.__name__}", fields, bases=(ActivatedFatigue, base), frozen=True,
                                      namespace=namespace)


def with_activation(params: FatigueModel, activation_time: float, deactivation_time: float,
                    activation_smoothing: float) -> ActivatedFatigue:
    """``params`` with the activation dynamics in front, of the given time constants (s) and
    smoothing."""
    values = {f.name: getattr(params, f.name) for f in dataclasses.fields(params)}
    return activated(type(params))(**values, activation_time=activation_time, deactivation_time=deactivation_time,
                                   activation_smoothing=activation_smoothing)
