"""fatigue_pin: predictive simulation of motion with actuator fatigue.

Rigid-body models come from URDF files through Pinocchio, every signed torque actuator carries
Xia's three-compartment fatigue model with an invariant stabiliser (3CC-S), and optimal control
problems are written with CasADi Opti and solved over the full horizon or window by window.
"""

from fatigue_pin.robot.model import RobotModel, load_model

__all__ = ["RobotModel", "load_model"]
__version__ = "0.1.0"
