"""Muscle-tendon geometry on CasADi SX, from the model's frames.

For the muscles of a :class:`~fatigue_pin.muscles.muscle_set.MuscleSet` on a Pinocchio model (nm
muscles, nq = nv joint coordinates), :class:`MuscleGeometry` builds, once:

* ``lengths(q[nq]) -> L[nm]``: each path's length (m), the sum of its segments between
  consecutive points; a segment goes round each wrap cylinder of the muscle that it would enter
  (:func:`~fatigue_pin.muscles.wraps.wrapped_length`);
* ``moment_arms(q) -> r[nm x nv]``: ``r = -dL/dq`` (m per rad, or dimensionless for a prismatic
  joint), positive where the muscle pulls the joint the positive way;
* ``speeds(q, v[nv]) -> Ldot[nm]``: lengthening speeds ``dL/dq v`` (m/s).

A point ``c`` on link ``b`` is at ``R_b(q) c + p_b(q)`` in the world, with ``R_b``, ``p_b`` the
link's placement from Pinocchio's forward kinematics on SX
(:func:`~fatigue_pin.robot.kinematics.frame_functions`). The joint torque of muscle forces
``F[nm]`` (N) is ``r^T F`` (N m), :meth:`MuscleGeometry.joint_torque`.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pinocchio as pin

from fatigue_pin.core.errors import ModelError, ParameterError
from fatigue_pin.muscles.muscle import Muscle
from fatigue_pin.muscles.muscle_set import MuscleSet
from fatigue_pin.muscles.wraps import wrapped_length
from fatigue_pin.robot.kinematics import frame_functions

__all__ = ["MuscleGeometry", "FixedMomentArms"]


class MuscleGeometry:
    """The path lengths, speeds and moment arms of a muscle set on a model (module docstring).

    Raises:
        ModelError: a point or wrap on a frame the model does not have, or a model whose
            configuration is not its velocity space (nq != nv).
        ParameterError: a muscle that crosses no joint (its length does not depend on q).
    """

    def __init__(self, model: pin.Model, muscles: MuscleSet) -> None:
        if model.nq != model.nv:
            raise ModelError(f"model {model.name!r} has nq = {model.nq} != nv = {model.nv}: muscle moment arms -dL/dq "
                             "need one coordinate per degree of freedom (revolute or prismatic joints)")
        self.muscles = muscles
        self.model = model
        q, v = ca.SX.sym("q", model.nq), ca.SX.sym("v", model.nv)
        frames = dict.fromkeys(f for m in muscles.muscles for f in m.frames)
        frames.update(dict.fromkeys(w.frame for w in muscles.wraps))
        links = [f.name for f in model.frames if f.type == pin.FrameType.BODY]
        placements = {}
        for name in frames:
            if not model.existFrame(name):
                owner = next((m.name for m in muscles.muscles if name in m.frames), None)
                what = f"muscle {owner!r} has a path point on" if owner else "a wrap cylinder is on"
                where = f" ({muscles.source})" if muscles.source else ""
                raise ModelError(f"{what} {name!r}{where}, which is not a link of model {model.name!r}; its links are {links}")
            ff = frame_functions(model, name)
            placements[name] = (ff.rotation(q), ff.position(q))
        self._placements = placements
        # common subexpressions merged: each link's placement is built once per muscle otherwise
        # (arm26: 1542 operations for the six lengths, against 2613)
        L = ca.cse(ca.vertcat(*[self._length(m) for m in muscles.muscles]))
        J = ca.cse(ca.jacobian(L, q))
        for m in muscles.muscles:  # links that fixed joints join move together: one parent joint
            if len({model.frames[model.getFrameId(f)].parentJoint for f in m.frames}) == 1:
                raise ParameterError(f"muscle {m.name!r} crosses no joint: its points are all on {list(m.frames)}, "
                                     "which move together; expected a path across at least one joint")
        self.lengths = ca.Function("muscle_lengths", [q], [L], ["q"], ["L"])
        self.moment_arms = ca.Function("muscle_moment_arms", [q], [-J], ["q"], ["r"])
        self.speeds = ca.Function("muscle_speeds", [q, v], [ca.mtimes(J, v)], ["q", "v"], ["Ldot"])

    def _world(self, frame: str, location) -> ca.SX:
        R, p = self._placements[frame]
        return ca.mtimes(R, ca.DM(np.asarray(location, dtype=float))) + p

    def _length(self, muscle: Muscle) -> ca.SX:
        wraps = [(self.muscles.wrap(use.name), use.turn) for use in muscle.wraps]
        points = [self._world(p.frame, p.location) for p in muscle.points]
        total = 0
        for a, b in zip(points[:-1], points[1:]):
            segment = None
            for w, turn in wraps:  # the segment in each wrap's frame; a segment goes round at most one
                R, p = self._placements[w.frame]
                Rw, c = ca.DM(w.matrix()), ca.DM(np.asarray(w.translation))
                to_local = lambda x: ca.mtimes(Rw.T, ca.mtimes(R.T, x - p) - c)  # noqa: E731
                length = wrapped_length(to_local(a), to_local(b), w.radius, turn)
                segment = length if segment is None else ca.fmax(segment, length)
            total = total + (ca.norm_2(b - a) if segment is None else segment)
        return total

    def joint_torque(self, q: ca.SX, forces: ca.SX) -> ca.SX:
        """``r(q)^T F`` (nv,) (N m) of tendon forces ``F`` (nm,) (N)."""
        return ca.mtimes(self.moment_arms(q).T, forces)


class FixedMomentArms:
    """Paths with constant moment arms: ``L(q) = L0 - r q``, ``r(q) = r``, ``Ldot = -r qdot``: the
    geometry of an idealised joint actuator, and a check of the muscle layer against torque
    actuators (the same functions as :class:`MuscleGeometry`).

    Args:
        moment_arms: (nm, nv) (m).
        lengths_at_zero: L0 (nm,) (m), the lengths at q = 0.
    """

    def __init__(self, moment_arms: np.ndarray, lengths_at_zero: np.ndarray) -> None:
        r = np.atleast_2d(np.asarray(moment_arms, dtype=float))
        L0 = np.asarray(lengths_at_zero, dtype=float).reshape(-1)
        if L0.shape != (r.shape[0],):
            raise ParameterError(f"lengths_at_zero has {L0.size} entries; expected one per muscle ({r.shape[0]})")
        nm, nv = r.shape
        q, v = ca.SX.sym("q", nv), ca.SX.sym("v", nv)
        R = ca.DM(r)
        self.lengths = ca.Function("muscle_lengths", [q], [ca.DM(L0) - ca.mtimes(R, q)], ["q"], ["L"])
        self.moment_arms = ca.Function("muscle_moment_arms", [q], [ca.SX(R)], ["q"], ["r"])
        self.speeds = ca.Function("muscle_speeds", [q, v], [-ca.mtimes(R, v)], ["q", "v"], ["Ldot"])

    def joint_torque(self, q: ca.SX, forces: ca.SX) -> ca.SX:
        """``r^T F`` (nv,) (N m)."""
        return ca.mtimes(self.moment_arms(q).T, forces)
