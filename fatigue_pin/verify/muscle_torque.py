"""The joint torque of a muscle run's muscles, computed for ``fatigue-pin verify`` apart from the
transcription's CasADi expressions.

* Geometry: numeric ``pinocchio.framesForwardKinematics`` places every path point (numpy); a
  segment that goes round a wrap cylinder takes the analytic length of
  :func:`~fatigue_pin.muscles.wraps.wrapped_length` evaluated on numbers (that formula is checked
  against OpenSim 4.6, docs/muscles.md).
* Moment arms and lengthening speeds: five-point central differences of the lengths in q (step
  :data:`STEP` rad or m), not the transcription's algorithmic derivatives.
* Forces: :meth:`~fatigue_pin.muscles.muscle.Muscle.force` on numpy numbers, the De Groote-Fregly
  curves with Moco's constants (checked against their formulas at sample points).

So a transcription whose muscle paths, moment arms or forces were wrong would show as gaps.

A run solved on polynomial paths (:mod:`fatigue_pin.muscles.polynomial_paths`) is checked on its
stored polynomials, evaluated on numbers (numpy Chebyshev recurrences, not the transcription's SX),
with the same differences; :meth:`NumericMuscles.polynomial_errors` says how far they are from the
exact paths along the run.
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from fatigue_pin.muscles.muscle_set import MuscleSet
from fatigue_pin.muscles.wraps import wrapped_length

__all__ = ["STEP", "NumericMuscles"]

#: Step of the moment arms' five-point central differences (rad or m): the truncation (h^4) and
#: the round-off (eps L / h) of a path of about 0.3 m are both near 1e-13 m, so the adaptive
#: reference integration at rtol 1e-10 does not see the differences' noise.
STEP = 1e-4


class NumericMuscles:
    """The muscles of a set on a Pinocchio model, evaluated on numbers.

    Args:
        model: the numeric ``pinocchio.Model`` the run was solved on (nq == nv).
        muscles: the muscle set stored with the run.
        polynomials: the run's polynomial paths, one per muscle in order
            (:class:`~fatigue_pin.muscles.polynomial_paths.PathPolynomial`), or None: the exact paths.
    """

    def __init__(self, model: Any, muscles: MuscleSet, polynomials: Sequence[Any] | None = None) -> None:
        import pinocchio as pin

        self.pin, self.model, self.data, self.muscles = pin, model, model.createData(), muscles
        self.polynomials = None if polynomials is None else tuple(polynomials)
        frames = {p.frame for m in muscles.muscles for p in m.points} | {w.frame for w in muscles.wraps}
        self._frame_ids = {f: model.getFrameId(f) for f in frames}
        # the constant geometry, once: each muscle's points (frame, location) and, per wrap it
        # uses, (frame, the cylinder's orientation and centre on its link, radius, turn)
        self._points = [[(p.frame, np.asarray(p.location, dtype=float)) for p in m.points] for m in muscles.muscles]
        wraps = {w.name: (w.frame, w.matrix(), np.asarray(w.translation, dtype=float), w.radius) for w in muscles.wraps}
        self._uses = [[(*wraps[u.name], u.turn) for u in m.wraps] for m in muscles.muscles]

    def lengths(self, q: np.ndarray) -> np.ndarray:
        """Path length of every muscle (m), (nm,), at joint positions ``q`` (nq,): the run's
        polynomials if it has them, else the exact paths."""
        if self.polynomials is not None:
            from fatigue_pin.muscles.polynomial_paths import polynomial_lengths

            return polynomial_lengths(self.polynomials, q)
        return self.exact_lengths(q)

    def polynomial_errors(self, q: np.ndarray) -> tuple[float, float]:
        """The largest differences between the polynomial and the exact paths over poses q
        (n, nq): length (m) and moment arm (m per rad, by five-point differences); (0, 0) for a
        run on exact paths."""
        if self.polynomials is None:
            return 0.0, 0.0
        dL = dr = 0.0
        for pose in np.atleast_2d(np.asarray(q, dtype=float)):
            Lp, Jp = self.length_gradient(pose)
            Le, Je = self.length_gradient(pose, exact=True)
            dL, dr = max(dL, float(np.max(np.abs(Lp - Le)))), max(dr, float(np.max(np.abs(Jp - Je))))
        return dL, dr

    def exact_lengths(self, q: np.ndarray) -> np.ndarray:
        """Path length of every muscle (m), (nm,), at joint positions ``q`` (nq,), from the points
        and wraps on the links."""
        pin, model, data = self.pin, self.model, self.data
        pin.framesForwardKinematics(model, data, np.asarray(q, dtype=float))
        placed = {f: (data.oMf[i].rotation.copy(), data.oMf[i].translation.copy()) for f, i in self._frame_ids.items()}
        out = np.zeros(len(self._points))
        for i, (muscle_points, uses) in enumerate(zip(self._points, self._uses)):
            points = [placed[f][0] @ location + placed[f][1] for f, location in muscle_points]
            total = 0.0
            for a, b in zip(points[:-1], points[1:]):
                segment = float(np.linalg.norm(b - a))
                for k, (frame, Rw, c, radius, turn) in enumerate(uses):  # at most one cylinder per segment: the longest path
                    R, p = placed[frame]
                    local = [Rw.T @ (R.T @ (x - p) - c) for x in (a, b)]
                    length = float(wrapped_length(local[0], local[1], radius, turn))
                    segment = length if k == 0 else max(segment, length)
                total += segment
            out[i] = total
        return out

    def length_gradient(self, q: np.ndarray, exact: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """The lengths (nm,) and dL/dq (nm, nq) by five-point central differences (``exact``: of
        the exact paths, whatever the run's)."""
        q = np.asarray(q, dtype=float)
        lengths = self.exact_lengths if exact else self.lengths
        J = np.zeros((len(self.muscles.muscles), q.size))
        for j in range(q.size):
            e = np.zeros(q.size)
            e[j] = STEP
            J[:, j] = (8 * (lengths(q + e) - lengths(q - e)) - (lengths(q + 2 * e) - lengths(q - 2 * e))) / (12 * STEP)
        return lengths(q), J

    def forces(self, q: np.ndarray, qdot: np.ndarray, a: np.ndarray) -> np.ndarray:
        """Tendon force of every muscle (N), (nm,), at activations ``a`` (nm,)."""
        L, J = self.length_gradient(q)
        Ldot = J @ np.asarray(qdot, dtype=float)
        return np.array([m.force(float(a[i]), L[i], Ldot[i]) for i, m in enumerate(self.muscles.muscles)], dtype=float)

    def torque(self, q: np.ndarray, qdot: np.ndarray, a: np.ndarray) -> np.ndarray:
        """Joint torque ``r(q)^T F`` (nv,) (N m or N), with ``r = -dL/dq``."""
        L, J = self.length_gradient(q)
        Ldot = J @ np.asarray(qdot, dtype=float)
        F = np.array([m.force(float(a[i]), L[i], Ldot[i]) for i, m in enumerate(self.muscles.muscles)], dtype=float)
        return -J.T @ F
