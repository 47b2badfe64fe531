"""The ``[actuators]`` settings of a problem: the actuator kind (signed torque halves on the
joints, or the model's muscles with optional residual torques), which joints are passive and how
each actuator's torque is coupled to its fatigue (docs/model.md, "Passive joints" and
"Couplings"; docs/muscles.md); :class:`~fatigue_pin.ocp.actuators.SignedTorqueActuators` and
:class:`~fatigue_pin.ocp.muscle_actuators.MuscleActuators` apply them."""

from __future__ import annotations

from dataclasses import dataclass

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.core.settings import check_fields, is_bool, is_number, is_strs, setting

__all__ = ["ACTUATOR_KINDS", "COUPLINGS", "MUSCLE_PATHS", "Actuation"]

#: The actuator kinds of a study: ``torque``: signed torque halves on the joints; ``muscles``: the
#: muscles of ``[model] muscles`` (docs/muscles.md); ``motors``: a motor on every actuated joint,
#: its temperatures the capacity states (``[motors]``, docs/motors.md).
ACTUATOR_KINDS = ("torque", "muscles", "motors")

#: How the torque of a half and its fatigue are coupled (docs/model.md, "Couplings"):
#: ``tl+mf<=1``: the torque is the control, fatigue is integrated from its target load TL, and
#: ``0 <= TL + m_fatigued <= 1`` at every node (the paper's); ``observed``: the same without that
#: row (fatigue integrated, no limit on the torque); ``active``: the control sets TL only, and the
#: torque the half delivers is ``m_active * limit`` (the torque is driven through the fatigue).
COUPLINGS = ("tl+mf<=1", "observed", "active")

#: How muscle paths enter the problem (docs/muscles.md, "Polynomial paths"): ``exact``: the points
#: on the links and the wrap cylinders; ``polynomial``: a polynomial of the crossed coordinates per
#: muscle, fitted to the exact paths over the joints' ranges
#: (:class:`~fatigue_pin.muscles.polynomial_paths.PolynomialPaths`).
MUSCLE_PATHS = ("exact", "polynomial")


@dataclass(frozen=True)
class Actuation:
    """The ``[actuators]`` table of a study: the actuator kind, which joints are passive and how
    the torque and the fatigue are coupled.

    Attributes:
        kind: one of :data:`ACTUATOR_KINDS`.
        passive: joints without a torque actuator (no halves, no fatigue states, torque 0); a
            joint whose URDF effort limit is 0 is passive too, named here or not. With muscles:
            joints without a residual torque.
        coupling: one of :data:`COUPLINGS` (docs/model.md), for every actuator.
        residuals: with muscles, the bound of a residual torque on each joint (N m, +-residuals),
            0: none.
        residual_fatigue: with muscles, the residual torques tire with the study's fatigue
            models (true), or not (false: their models' F and R are 0, so that they never tire).
        paths: with muscles, one of :data:`MUSCLE_PATHS`.
        path_tolerance: with ``paths = "polynomial"``, the root mean square error allowed in the
            fitted lengths (m) and moment arms (m per rad) over the joints' ranges.
        activation_dynamics: with muscles, the controls are excitations and each muscle's
            activation is a state with the muscle's time constants
            (:mod:`fatigue_pin.muscles.activation`); false: the controls are the activations.
    """

    kind: str = setting("torque", f"one of {list(ACTUATOR_KINDS)}", lambda v: v in ACTUATOR_KINDS)
    passive: tuple[str, ...] = setting((), "a list of joint names", is_strs)
    coupling: str = setting("tl+mf<=1", f"one of {list(COUPLINGS)}", lambda v: v in COUPLINGS)
    residuals: float = setting(0.0, "a finite torque bound >= 0 (N m; 0: no residual torques)",
                               lambda v: is_number(v) and v >= 0)
    residual_fatigue: bool = setting(False, "true or false", is_bool)
    paths: str = setting("exact", f"one of {list(MUSCLE_PATHS)}", lambda v: v in MUSCLE_PATHS)
    path_tolerance: float = setting(1e-4, "a length > 0 (m)", lambda v: is_number(v) and v > 0)
    activation_dynamics: bool = setting(False, "true or false", is_bool)

    def __post_init__(self) -> None:
        check_fields(self)
        object.__setattr__(self, "passive", tuple(self.passive))
        if self.kind != "muscles" and self.residuals > 0:
            raise ParameterError(f"Actuation.residuals = {self.residuals:g}: residual torques go beside muscles; expected "
                                 "kind = 'muscles', or residuals = 0")
        if self.kind == "motors" and self.coupling == "active":
            raise ParameterError("Actuation.coupling = 'active' with kind = 'motors': a motor's torque is its control and its "
                                 "temperatures only bound it; expected coupling 'tl+mf<=1' or 'observed' (both mean the same for motors)")
        if self.kind != "muscles" and self.activation_dynamics:
            raise ParameterError("Actuation.activation_dynamics = true: activations are muscle states; expected kind = 'muscles', "
                                 "or activation_dynamics = false")
        if self.kind == "muscles" and self.activation_dynamics and self.coupling == "active":
            raise ParameterError("Actuation.activation_dynamics = true with coupling = 'active': the force would follow m_active, "
                                 "not the activation; expected coupling 'tl+mf<=1' or 'observed', or activation_dynamics = false")
        if self.kind != "muscles" and self.paths != "exact":
            raise ParameterError(f"Actuation.paths = {self.paths!r}: polynomial paths are muscle paths; expected kind = 'muscles', "
                                 "or paths = 'exact'")
