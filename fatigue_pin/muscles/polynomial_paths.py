"""Muscle paths as polynomials of the joint coordinates, fitted once per model.

The exact paths of :class:`~fatigue_pin.muscles.geometry.MuscleGeometry` (points on the links,
wrap cylinders) sit inside every RK4 stage of a muscle-driven problem, and the exact Hessian holds
their second and third derivatives: arm26's compiled library then takes minutes to build.
PredSim (Falisse et al.) and OpenSim Moco's ``PolynomialPathFitter`` replace each path by a
polynomial of the coordinates it crosses; :class:`PolynomialPaths` does the same from the exact
paths, so that the problem's derivatives are those of small polynomials.

For muscle i crossing the d coordinates ``q_J`` (the structural dependence of its exact length),
with ``s_j = (q_j - c_j) / h_j`` in [-1, 1] over the fitted range ``[c_j - h_j, c_j + h_j]``::

    L_i(q) = sum_k a_ik prod_j T_{e_kj}(s_j)          (m)

over the Chebyshev products of total degree ``sum_j e_kj <= order`` (T_n the Chebyshev polynomials
of the first kind). The coefficients solve one least-squares problem on the lengths and the
derivatives ``dL/dq_j`` together (the moment arms are then the polynomial's own derivative,
``r = -dL/dq``), on a grid of the range. The order is the lowest in 1..``max_order`` (found by
bisection: the errors fall with the order) whose root mean square errors, on a second grid between
the first's points, are at most ``tolerance`` for the length (m) and for every moment arm (m per
rad, or dimensionless for a prismatic joint); a muscle that ``max_order`` does not fit is refused
in one line with its errors.

The fitted range is the joints' position limits unless given. Outside it the polynomial is
extrapolated: :meth:`PolynomialPaths.errors_along` measures the fit against the exact paths on a
motion.
"""

from __future__ import annotations

import itertools
import json
import math
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import casadi as ca
import numpy as np
import scipy.linalg

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.core.text import shown

__all__ = ["PathPolynomial", "PolynomialPaths", "polynomial_lengths", "DEFAULT_PATH_TOLERANCE", "MAX_PATH_ORDER"]

#: Root mean square error allowed in the lengths (m) and moment arms (m per rad) of a fit: Moco's
#: ``PolynomialPathFitter`` default.
DEFAULT_PATH_TOLERANCE = 1e-4
#: The highest total degree tried.
MAX_PATH_ORDER = 16
#: Poses of the fit: a muscle crossing d coordinates is sampled on a grid of about ``_SAMPLES``
#: poses (at most ``_PER_COORDINATE`` per coordinate), and checked on the grid between them.
_SAMPLES = 1600
_PER_COORDINATE = 201
#: Ridge of the least squares, relative to columns of unit norm.
_RIDGE = 1e-6


def _chebyshev(s: np.ndarray, order: int, derivatives: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
    """T_n(s) and T_n'(s) (None unless ``derivatives``) for n = 0..order, each (len(s), order + 1)."""
    s = np.asarray(s, dtype=float)
    T = np.zeros((s.size, order + 1))
    T[:, 0] = 1.0
    if order >= 1:
        T[:, 1] = s
    for n in range(1, order):
        T[:, n + 1] = 2 * s * T[:, n] - T[:, n - 1]
    if not derivatives:
        return T, None
    U = np.zeros((s.size, order + 1))  # second kind: T_n' = n U_{n-1}
    U[:, 0] = 1.0
    if order >= 1:
        U[:, 1] = 2 * s
    for n in range(1, order):
        U[:, n + 1] = 2 * s * U[:, n] - U[:, n - 1]
    dT = np.zeros_like(T)
    dT[:, 1:] = np.arange(1, order + 1) * U[:, :order]
    return T, dT


def _exponents(d: int, order: int) -> np.ndarray:
    """Every exponent tuple of d coordinates with total degree <= order, (n_terms, d), by degree."""
    rows = [e for e in itertools.product(range(order + 1), repeat=d) if sum(e) <= order]
    rows.sort(key=lambda e: (sum(e), tuple(-x for x in e)))
    return np.array(rows, dtype=int).reshape(-1, d)


@dataclass(frozen=True)
class PathPolynomial:
    """One muscle's length as a polynomial (module docstring).

    Attributes:
        muscle: the muscle's name.
        joints: indices of the coordinates it crosses, into q (d,).
        center: c (d,) (rad or m), the middle of the fitted range.
        half_range: h (d,) (rad or m), its half width.
        exponents: (n_terms, d) Chebyshev degrees of each term.
        coefficients: (n_terms,) (m).
        order: the total degree.
        rms_length: root mean square error of the length on the check grid (m).
        rms_moment_arm: the largest root mean square error of a moment arm there (m per rad).
    """

    muscle: str
    joints: tuple[int, ...]
    center: tuple[float, ...]
    half_range: tuple[float, ...]
    exponents: tuple[tuple[int, ...], ...]
    coefficients: tuple[float, ...]
    order: int
    rms_length: float
    rms_moment_arm: float

    def _scaled(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The exponents (n_terms, d) and the scaled crossed coordinates s (n, d) of poses q (n, nq)."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        e = np.asarray(self.exponents, dtype=int).reshape(-1, len(self.joints))
        return e, (q[:, list(self.joints)] - np.asarray(self.center)) / np.asarray(self.half_range)

    def _basis(self, q: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]]:
        """Terms (n, n_terms) and their derivatives in each crossed coordinate (d of (n, n_terms)),
        at poses q (n, nq)."""
        e, s = self._scaled(q)
        tables = [_chebyshev(s[:, j], self.order) for j in range(len(self.joints))]
        terms = np.ones((s.shape[0], e.shape[0]))
        for j, (T, _) in enumerate(tables):
            terms *= T[:, e[:, j]]
        derivatives = []
        for j in range(len(self.joints)):
            dj = np.ones_like(terms)
            for k, (T, dT) in enumerate(tables):
                dj *= (dT[:, e[:, k]] / self.half_range[k]) if k == j else T[:, e[:, k]]
            derivatives.append(dj)
        return terms, derivatives

    def length(self, q: np.ndarray) -> np.ndarray:
        """Lengths (n,) (m) at poses q (n, nq), on numbers."""
        e, s = self._scaled(q)
        terms = np.ones((s.shape[0], e.shape[0]))
        for j in range(len(self.joints)):
            terms *= _chebyshev(s[:, j], self.order, derivatives=False)[0][:, e[:, j]]
        return terms @ np.asarray(self.coefficients)

    def gradient(self, q: np.ndarray, nq: int) -> np.ndarray:
        """dL/dq (n, nq) at poses q (n, nq), on numbers (zero in the coordinates it does not cross)."""
        _, derivatives = self._basis(q)
        out = np.zeros((np.atleast_2d(q).shape[0], nq))
        for j, dj in zip(self.joints, derivatives):
            out[:, j] = dj @ np.asarray(self.coefficients)
        return out

    def expression(self, q: ca.SX) -> ca.SX:
        """The length on SX symbols q (nq,)."""
        s = [(q[j] - c) / h for j, c, h in zip(self.joints, self.center, self.half_range)]
        T = []
        for sj in s:  # T_0..T_order of each crossed coordinate
            row = [ca.SX(1.0), sj]
            for _ in range(1, self.order):
                row.append(2 * sj * row[-1] - row[-2])
            T.append(row[: self.order + 1])
        total = ca.SX(0.0)
        for a, e in zip(self.coefficients, self.exponents):
            term = ca.SX(a)
            for j, n in enumerate(e):
                if n:
                    term = term * T[j][n]
            total = total + term
        return total

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-ready values (what a run stores)."""
        return {"muscle": self.muscle, "joints": list(self.joints), "center": list(self.center),
                "half_range": list(self.half_range), "exponents": [list(e) for e in self.exponents],
                "coefficients": list(self.coefficients), "order": self.order, "rms_length": self.rms_length,
                "rms_moment_arm": self.rms_moment_arm}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> "PathPolynomial":
        """The inverse of :meth:`to_dict`."""
        return cls(str(data["muscle"]), tuple(int(j) for j in data["joints"]), tuple(float(c) for c in data["center"]),
                   tuple(float(h) for h in data["half_range"]), tuple(tuple(int(x) for x in e) for e in data["exponents"]),
                   tuple(float(a) for a in data["coefficients"]), int(data["order"]), float(data["rms_length"]),
                   float(data["rms_moment_arm"]))


def polynomial_lengths(polynomials: Sequence[PathPolynomial], q: np.ndarray) -> np.ndarray:
    """Every muscle's length (nm,) (m) at one pose q (nq,), on numbers: what verify checks a run on."""
    pose = np.asarray(q, dtype=float).reshape(1, -1)
    return np.array([float(p.length(pose)[0]) for p in polynomials])


def _grid(lower: np.ndarray, upper: np.ndarray, per: int, between: bool) -> np.ndarray:
    """A tensor grid of ``per`` points per coordinate over the box (n, d); ``between``: the points
    half a step inside, between the others."""
    axes = []
    for lo, hi in zip(lower, upper):
        pts = np.linspace(lo, hi, per)
        axes.append((pts[:-1] + pts[1:]) / 2 if between else pts)
    return np.array(list(itertools.product(*axes)), dtype=float)


def _crossed(model: Any, muscles: Any) -> list[list[int]]:
    """The coordinates (indices into q) each muscle crosses: the joints on the kinematic tree's
    path between the links of its points and wraps (a muscle whose points are all on the humerus
    and the forearm crosses the elbow only, though its world coordinates move with the shoulder)."""
    crossed = []
    for m in muscles.muscles:
        frames = list(m.frames) + [muscles.wrap(use.name).frame for use in m.wraps]
        supports = [set(model.supports[model.frames[model.getFrameId(f)].parentJoint]) for f in frames]
        joints = set.union(*supports) - set.intersection(*supports)
        crossed.append(sorted(model.joints[j].idx_q for j in joints))
    return crossed


class PolynomialPaths:
    """Polynomial paths fitted to a muscle set's exact paths (module docstring): the same functions
    as :class:`~fatigue_pin.muscles.geometry.MuscleGeometry`.

    Args:
        geometry: the exact paths (:class:`~fatigue_pin.muscles.geometry.MuscleGeometry`).
        lower: the lower end of the fitted range of every coordinate (nq,) (rad or m); default
            the model's lower position limits.
        upper: the upper end (nq,); default the model's upper position limits.
        tolerance: root mean square error allowed in the lengths (m) and moment arms (m per rad).
        max_order: the highest total degree tried.

    Raises:
        ParameterError: a range that is not finite and increasing, a tolerance that is not
            positive, or a muscle that no order up to ``max_order`` fits within the tolerance.
    """

    def __init__(self, geometry: Any, lower: Sequence[float] | None = None, upper: Sequence[float] | None = None,
                 tolerance: float = DEFAULT_PATH_TOLERANCE, max_order: int = MAX_PATH_ORDER) -> None:
        model = geometry.model
        nq = model.nq
        lower = np.asarray(model.lowerPositionLimit if lower is None else lower, dtype=float).reshape(-1)
        upper = np.asarray(model.upperPositionLimit if upper is None else upper, dtype=float).reshape(-1)
        if lower.shape != (nq,) or upper.shape != (nq,):
            raise ParameterError(f"polynomial muscle paths: a range of {lower.size} and {upper.size} coordinates; expected {nq}")
        names = [model.names[j + 1] for j in range(nq)]
        for j in range(nq):
            if not (np.isfinite(lower[j]) and np.isfinite(upper[j]) and lower[j] < upper[j]):
                raise ParameterError(f"polynomial muscle paths: joint {names[j]!r} has the range [{shown(lower[j])}, {shown(upper[j])}]; "
                                     "expected finite position limits, lower < upper")
        if not (isinstance(tolerance, (int, float)) and math.isfinite(tolerance) and tolerance > 0):
            raise ParameterError(f"polynomial muscle paths: tolerance = {shown(tolerance)}; expected a length > 0 (m)")
        self.geometry, self.muscles, self.model = geometry, geometry.muscles, model
        self.tolerance, self.lower, self.upper = float(tolerance), lower, upper
        crossed = _crossed(model, self.muscles)
        self.polynomials = tuple(self._fit(i, crossed[i], int(max_order)) for i in range(len(self.muscles.muscles)))
        self._build(nq)

    @classmethod
    def from_polynomials(cls, polynomials: Sequence[PathPolynomial], muscles: Any, model: Any) -> "PolynomialPaths":
        """Paths from polynomials already fitted (a stored run's), on ``model`` with ``muscles``."""
        self = cls.__new__(cls)
        self.geometry, self.muscles, self.model = None, muscles, model
        self.tolerance = max((max(p.rms_length, p.rms_moment_arm) for p in polynomials), default=0.0)
        self.lower = np.asarray(model.lowerPositionLimit, dtype=float)
        self.upper = np.asarray(model.upperPositionLimit, dtype=float)
        self.polynomials = tuple(polynomials)
        if [p.muscle for p in self.polynomials] != list(muscles.names):
            raise ParameterError(f"polynomial muscle paths for {[p.muscle for p in self.polynomials]}; expected one per muscle "
                                 f"of {list(muscles.names)}, in order")
        self._build(model.nq)
        return self

    def _fit(self, i: int, joints: list[int], max_order: int) -> PathPolynomial:
        name = self.muscles.muscles[i].name
        d = len(joints)
        lo, hi = self.lower[joints], self.upper[joints]
        center, half = tuple(float(c) for c in (lo + hi) / 2), tuple(float(h) for h in (hi - lo) / 2)
        per = min(_PER_COORDINATE, max(3, int(round(_SAMPLES ** (1.0 / d)))))
        fit_q, check_q = (self._poses(_grid(lo, hi, per, between), joints) for between in (False, True))
        L_fit, G_fit = self._exact(fit_q, i, joints)
        L_chk, G_chk = self._exact(check_q, i, joints)
        b = np.concatenate([L_fit, *G_fit.T])
        # every term of the highest order once, on both grids; an order takes its columns
        full = PathPolynomial(name, tuple(joints), center, half, tuple(tuple(int(x) for x in e) for e in _exponents(d, max_order)),
                              (), max_order, 0.0, 0.0)
        fit_terms, fit_derivatives = full._basis(fit_q)
        chk_terms, chk_derivatives = full._basis(check_q)
        degrees = np.asarray(full.exponents).sum(axis=1)

        def fitted(order: int) -> PathPolynomial:
            cols = np.flatnonzero(degrees <= order)
            A = np.vstack([fit_terms[:, cols], *(dj[:, cols] for dj in fit_derivatives)])
            # columns of unit norm and a ridge of 1e-6 of it: a well-posed problem (the highest
            # orders are nearly singular without it); then the coefficients to 1e-10 m (|T_n| <= 1:
            # the lengths move by less than 1e-8 m, a thousandth of the fit's error), because their
            # last bits follow the BLAS's threads and the compiled-code cache key follows them
            norms = np.linalg.norm(A, axis=0)
            ridge = np.vstack([A / norms, _RIDGE * np.eye(cols.size)])
            scaled = scipy.linalg.lstsq(ridge, np.concatenate([b, np.zeros(cols.size)]), lapack_driver="gelsy")[0]
            coeffs = np.round(scaled / norms, 10) + 0.0  # + 0.0: no negative zeros
            rms_L = float(np.sqrt(np.mean((chk_terms[:, cols] @ coeffs - L_chk) ** 2)))
            rms_r = max(float(np.sqrt(np.mean((dj[:, cols] @ coeffs - G_chk[:, j]) ** 2))) for j, dj in enumerate(chk_derivatives))
            return PathPolynomial(name, tuple(joints), center, half, tuple(full.exponents[c] for c in cols),
                                  tuple(float(a) for a in coeffs), order, rms_L, rms_r)

        def fits(p: PathPolynomial) -> bool:
            return p.rms_length <= self.tolerance and p.rms_moment_arm <= self.tolerance

        # the errors fall with the order: bisection for the lowest order that fits
        top = fitted(max_order)
        if not fits(top):
            raise ParameterError(f"polynomial muscle paths: muscle {name!r} is fitted at best to {top.rms_length:.2g} m in length "
                                 f"and {top.rms_moment_arm:.2g} m in moment arm (order {max_order}); expected both <= "
                                 f"{self.tolerance:g} (a larger tolerance, a smaller range, or the exact paths)")
        low, best = 0, top
        high = max_order
        while high - low > 1:
            mid = (low + high) // 2
            trial = fitted(mid)
            if fits(trial):
                high, best = mid, trial
            else:
                low = mid
        return best

    def _poses(self, sub: np.ndarray, joints: list[int]) -> np.ndarray:
        """Full poses (n, nq): the crossed coordinates from ``sub``, the others at the middle of
        their range (the length does not depend on them)."""
        q = np.tile((self.lower + self.upper) / 2, (sub.shape[0], 1))
        q[:, joints] = sub
        return q

    def _exact(self, q: np.ndarray, i: int, joints: list[int]) -> tuple[np.ndarray, np.ndarray]:
        """Exact length (n,) and dL/dq in the crossed coordinates (n, d) of muscle i."""
        n, nq = q.shape[0], self.model.nq
        L = np.array(self.geometry.lengths.map(n)(q.T)).reshape(-1, n)[i]
        r = np.array(self.geometry.moment_arms.map(n)(q.T))[i].reshape(n, nq)  # poses side by side: (nm, n nq)
        return L, -r[:, joints]

    def _build(self, nq: int) -> None:
        q, v = ca.SX.sym("q", nq), ca.SX.sym("v", nq)
        L = ca.vertcat(*[p.expression(q) for p in self.polynomials])
        J = ca.jacobian(L, q)
        self.lengths = ca.Function("muscle_lengths", [q], [L], ["q"], ["L"])
        self.moment_arms = ca.Function("muscle_moment_arms", [q], [-J], ["q"], ["r"])
        self.speeds = ca.Function("muscle_speeds", [q, v], [ca.mtimes(J, v)], ["q", "v"], ["Ldot"])

    def joint_torque(self, q: ca.SX, forces: ca.SX) -> ca.SX:
        """``r(q)^T F`` (nv,) (N m) of tendon forces ``F`` (nm,) (N)."""
        return ca.mtimes(self.moment_arms(q).T, forces)

    def to_json(self) -> str:
        """Every muscle's polynomial as JSON (what a run stores, :meth:`from_json`)."""
        return json.dumps([p.to_dict() for p in self.polynomials])

    @staticmethod
    def polynomials_from_json(text: str) -> tuple[PathPolynomial, ...]:
        """The polynomials of :meth:`to_json`."""
        return tuple(PathPolynomial.from_dict(d) for d in json.loads(text))

    def numeric_lengths(self, q: np.ndarray) -> np.ndarray:
        """Lengths (nm,) (m) at one pose q (nq,), on numbers (:func:`polynomial_lengths`)."""
        return polynomial_lengths(self.polynomials, q)

    def errors_along(self, q: np.ndarray, exact: Any) -> tuple[float, float]:
        """The largest differences (m, m per rad) between these paths and ``exact``'s (an object
        with CasADi ``lengths`` and ``moment_arms``) over poses q (n, nq)."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        n = q.shape[0]
        dL = np.array(self.lengths.map(n)(q.T)) - np.array(exact.lengths.map(n)(q.T))
        dr = np.array(self.moment_arms.map(n)(q.T)) - np.array(exact.moment_arms.map(n)(q.T))
        return float(np.max(np.abs(dL))), float(np.max(np.abs(dr)))
