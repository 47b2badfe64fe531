"""Frame kinematics of a model on CasADi symbols, from Pinocchio itself.

For a frame of a Pinocchio model (a link, a joint, a tool frame of the URDF), three SX
``casadi.Function`` objects, all in the world frame:

* ``position(q[nq]) -> p[3]``         origin of the frame (m);
* ``rotation(q[nq]) -> R[3x3]``       orientation of the frame (columns: its axes in world axes);
* ``velocity(q[nq], v[nv]) -> pdot[3]`` linear velocity of the frame's origin, world axes
  (Pinocchio's ``LOCAL_WORLD_ALIGNED``), m/s.

They are Pinocchio's ``forwardKinematics``, ``updateFramePlacement`` and ``getFrameVelocity``
evaluated on ``casadi::SX``: through ``pinocchio.casadi`` where the installed Pinocchio has it,
otherwise through the compiled extension ``fatigue_pin._pinocchio_casadi`` (the model crosses as
``saveToString()``). The model used is the one *with its frames* (a :class:`RobotModel`'s
``pin_model``), not :func:`fatigue_pin.robot.dynamics.aligned_model`, which drops them.

:class:`~fatigue_pin.robot.model.RobotModel` caches them per frame: ``model.frame_position("tool0")``.
Numeric helpers for checks and initial guesses (:func:`frame_placement`, :func:`reach`) use
numeric Pinocchio.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np
import pinocchio as pin

from fatigue_pin.core.errors import ModelError
from fatigue_pin.robot.dynamics import compiled_extension


@dataclass(frozen=True)
class FrameFunctions:
    """The CasADi kinematics of one frame (see the module docstring)."""

    frame: str
    frame_id: int
    position: ca.Function
    rotation: ca.Function
    velocity: ca.Function


def frame_id(model: pin.Model, frame: str | int, owner: str = "model") -> int:
    """Id of ``frame`` (a name or an id) in ``model``; ModelError naming the known frames."""
    if isinstance(frame, (int, np.integer)) and not isinstance(frame, bool):
        if 0 <= int(frame) < len(model.frames):
            return int(frame)
        raise ModelError(f"frame id {frame} is not a frame of {owner} {model.name!r} (it has {len(model.frames)} frames)")
    if not isinstance(frame, str) or not model.existFrame(frame):
        names = [f.name for f in model.frames if f.type in (pin.FrameType.BODY, pin.FrameType.OP_FRAME)]
        raise ModelError(f"frame {frame!r} is not in {owner} {model.name!r}; its link and tool frames are {names}")
    return int(model.getFrameId(frame))


def frame_functions(model: pin.Model, frame: str | int) -> FrameFunctions:
    """Build the CasADi kinematics of ``frame`` of ``model`` (see the module docstring)."""
    fid = frame_id(model, frame)
    name = model.frames[fid].name
    try:
        import pinocchio.casadi as cpin
    except ImportError:
        position, rotation, velocity = _extension_kinematics(model, fid)
    else:
        position, rotation, velocity = _pinocchio_casadi_kinematics(cpin, model, fid)
    return FrameFunctions(name, fid, position, rotation, velocity)


def _pinocchio_casadi_kinematics(cpin, model: pin.Model, fid: int) -> tuple[ca.Function, ca.Function, ca.Function]:
    """The three functions through ``pinocchio.casadi`` (conda-forge builds)."""
    cmodel = cpin.Model(model)
    cdata = cmodel.createData()
    q, v = ca.SX.sym("q", model.nq), ca.SX.sym("v", model.nv)
    cpin.forwardKinematics(cmodel, cdata, q, v)
    oMf = cpin.updateFramePlacement(cmodel, cdata, fid)
    pdot = cpin.getFrameVelocity(cmodel, cdata, fid, pin.LOCAL_WORLD_ALIGNED).linear
    name = model.frames[fid].name
    return (ca.Function(f"{name}_position", [q], [oMf.translation], ["q"], ["p"]),
            ca.Function(f"{name}_rotation", [q], [oMf.rotation], ["q"], ["R"]),
            ca.Function(f"{name}_velocity", [q, v], [pdot], ["q", "v"], ["pdot"]))


def _extension_kinematics(model: pin.Model, fid: int) -> tuple[ca.Function, ca.Function, ca.Function]:
    """The three functions through the compiled extension (PyPI wheels)."""
    ext = compiled_extension("frame_kinematics_from_string")
    texts = ext.frame_kinematics_from_string(model.saveToString(), fid)
    return tuple(ca.Function.deserialize(t) for t in texts)  # type: ignore[return-value]


# -- numeric helpers ---------------------------------------------------------------------------


def frame_placement(model: pin.Model, frame: str | int, q: np.ndarray) -> pin.SE3:
    """World placement of ``frame`` at configuration ``q`` (numeric Pinocchio)."""
    fid = frame_id(model, frame)
    data = model.createData()
    pin.framesForwardKinematics(model, data, np.asarray(q, dtype=float))
    return data.oMf[fid].copy()


def reach(model: pin.Model, frame: str | int) -> tuple[np.ndarray, float]:
    """A ball (centre (3,), radius, m) that holds every position the frame can take.

    The centre is the first moving joint of the frame's chain (its place does not depend on q);
    the radius is the sum of the lengths of the links from there to the frame (the translations
    of the joint and frame placements along the chain), plus the travel of prismatic joints.
    """
    fid = frame_id(model, frame)
    f = model.frames[fid]
    chain = []
    j = f.parentJoint
    while j > 0:
        chain.append(j)
        j = model.parents[j]
    radius = float(np.linalg.norm(f.placement.translation))
    if not chain:  # a frame of the fixed base
        data = model.createData()
        pin.framesForwardKinematics(model, data, pin.neutral(model))
        return data.oMf[fid].translation.copy(), radius
    root = chain[-1]
    for jid in chain[:-1]:  # placements of the joints below the root, in their parents
        radius += float(np.linalg.norm(model.jointPlacements[jid].translation))
    for jid in chain:
        if model.joints[jid].shortname().startswith("JointModelP"):
            i = model.joints[jid].idx_q
            radius += float(max(abs(model.lowerPositionLimit[i]), abs(model.upperPositionLimit[i])))
    data = model.createData()
    pin.forwardKinematics(model, data, pin.neutral(model))
    return data.oMi[root].translation.copy(), radius  # a revolute root turns about its own origin
