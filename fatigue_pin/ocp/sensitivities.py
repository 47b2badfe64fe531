"""Derivatives of an explicit RK4 flow built from its stages.

The flow ``y_{s+1} = y_s + h (k1 + 2 k2 + 2 k3 + k4) / 6`` with ``k_j = g(Z_j, c)`` (the state's
right-hand side at the stage points ``Z_j``, with parameters ``c`` held over the interval) is
linear in everything but ``g``. So its derivatives need those of ``g`` alone, at each stage:

- :func:`rk4_sensitivities`: the Jacobian by forward sensitivities, ``S = dy/dw``, stepped as the
  state is (``dk_j = dg/dZ T_j + dg/dc dc/dw``, ``T_j = dZ_j/dw``);
- :func:`rk4_adjoint_hessian`: the Hessian of ``mu' y_end`` by the second-order adjoint rule:
  a backward sweep gives each stage's adjoint ``kbar_j`` (the weight of ``g`` at that stage in
  ``mu' y_end``), and

  ``H = sum over stages of D_j' (d2/dv2 kbar_j' g)(Z_j, c) D_j``, ``D_j = [T_j; dc/dw]``, ``v = (z, c)``,

  because every other operation of the flow is linear (docs/ocp.md, "What makes a robot window
  faster").

CasADi differentiates the whole unrolled flow instead: one forward-over-reverse sweep per
direction through every stage. Both give the same numbers to rounding.
"""

from __future__ import annotations

from typing import Callable

import casadi as ca

#: RK4's stage offsets a_{j, j-1} and weights b_j
_A = (0.0, 0.5, 0.5, 1.0)
_B = (1.0 / 6.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0)


def rk4_sensitivities(rates: Callable[[ca.MX, ca.MX], tuple[ca.MX, ca.MX]], y: ca.MX, S: ca.MX, h: float,
                      substeps: int) -> tuple[ca.MX, ca.MX]:
    """``substeps`` RK4 steps of length h (s) of the state y (ny,) and of its sensitivities S
    (ny, n) to n parameters, where ``rates(y, S)`` gives (ydot, dS/dt): the sensitivities step as
    the state does (forward sensitivities of an explicit RK4, exact to rounding). Returns
    (y, S) at the end."""
    for _ in range(substeps):
        k1, d1 = rates(y, S)
        k2, d2 = rates(y + h / 2 * k1, S + h / 2 * d1)
        k3, d3 = rates(y + h / 2 * k2, S + h / 2 * d2)
        k4, d4 = rates(y + h * k3, S + h * d3)
        y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        S = S + h / 6 * (d1 + 2 * d2 + 2 * d3 + d4)
    return y, S


def rk4_adjoint_hessian(first: Callable[[ca.MX], tuple[ca.MX, ca.MX, ca.MX]],
                        second: Callable[[ca.MX, ca.MX], ca.MX],
                        y: ca.MX, S: ca.MX, C: ca.MX, mu: ca.MX, h: float, substeps: int) -> ca.MX:
    """The Hessian (n, n) of ``mu' y_end`` with respect to n parameters w, where y_end is
    ``substeps`` RK4 steps of length h (s) from y (ny,) whose sensitivity to w is S (ny, n), of a
    right-hand side g(z, c) whose parameters c have the sensitivity C (nc, n) (constant over the
    interval).

    Args:
        first: ``first(Z) -> (g, dg/dz (ny, ny), dg/dc (ny, nc))`` at a stage point Z.
        second: ``second(Z, lam) -> d2/dv2 (lam' g)`` ((ny + nc)^2, symmetric, full), v = (z, c).
        y: the state at the start (ny,).
        S: its sensitivity to w (ny, n).
        C: the sensitivity of c to w (nc, n).
        mu: the weights of the end state (ny,).
        h: the substep (s).
        substeps: RK4 steps over the interval.
    """
    stages = []
    for _ in range(substeps):
        ks: list[ca.MX] = []
        dks: list[ca.MX] = []
        points = []
        for j in range(4):
            Z = y if j == 0 else y + h * _A[j] * ks[-1]
            T = S if j == 0 else S + h * _A[j] * dks[-1]
            g, gz, gc = first(Z)
            ks.append(g)
            dks.append(ca.mtimes(gz, T) + ca.mtimes(gc, C))
            points.append((Z, T, gz))
        y = y + h * sum(b * k for b, k in zip(_B, ks))
        S = S + h * sum(b * d for b, d in zip(_B, dks))
        stages.append(points)
    ybar, H = mu, 0
    for points in reversed(stages):
        zbar_next = None
        zbars = []
        for j in (3, 2, 1, 0):
            Z, T, gz = points[j]
            kbar = h * _B[j] * ybar + (h * _A[j + 1] * zbar_next if j < 3 else 0)
            zbar_next = ca.mtimes(gz.T, kbar)
            zbars.append(zbar_next)
            D = ca.vertcat(T, C)
            H = H + ca.mtimes([D.T, second(Z, kbar), D])
        ybar = ybar + sum(zbars)
    return H
