"""The ``[actuators]`` settings of a problem: which joints are passive and how each actuator
half's torque is coupled to its fatigue (docs/model.md, "Passive joints" and "Couplings");
:class:`~fatigue_pin.ocp.actuators.SignedTorqueActuators` applies them."""

from __future__ import annotations

from dataclasses import dataclass

from fatigue_pin.core.settings import check_fields, is_strs, setting

__all__ = ["COUPLINGS", "Actuation"]

#: How the torque of a half and its fatigue are coupled (docs/model.md, "Couplings"):
#: ``tl+mf<=1``: the torque is the control, fatigue is integrated from its target load TL, and
#: ``0 <= TL + m_fatigued <= 1`` at every node (the paper's); ``observed``: the same without that
#: row (fatigue integrated, no limit on the torque); ``active``: the control sets TL only, and the
#: torque the half delivers is ``m_active * limit`` (the torque is driven through the fatigue).
COUPLINGS = ("tl+mf<=1", "observed", "active")


@dataclass(frozen=True)
class Actuation:
    """The ``[actuators]`` table of a study: which joints are passive and how the torque and the
    fatigue are coupled.

    Attributes:
        passive: joints without an actuator (no halves, no fatigue states, torque 0); a joint
            whose URDF effort limit is 0 is passive too, named here or not.
        coupling: one of :data:`COUPLINGS` (docs/model.md).
    """

    passive: tuple[str, ...] = setting((), "a list of joint names", is_strs)
    coupling: str = setting("tl+mf<=1", f"one of {list(COUPLINGS)}", lambda v: v in COUPLINGS)

    def __post_init__(self) -> None:
        check_fields(self)
        object.__setattr__(self, "passive", tuple(self.passive))
