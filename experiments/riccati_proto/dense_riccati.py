"""A dense Riccati recursion in numpy on random stage blocks: the yardstick of the issue "The
Newton step by a Riccati recursion" (its table: UR5 with Xia halves, 48 states, 18 controls, 150
stages, 6-7 ms per factorisation and solve), measured again beside the library's pair step.

Per stage k (backwards): Ruu = R + B^T P B, Rux = S + B^T P A, Pxx = Q + A^T P A, a Cholesky of
Ruu, K = Ruu^{-1} Rux, P <- Pxx - Rux^T K; then one forward/backward solve. About 0.36 M
multiply-adds per UR5 stage (A^T P A alone is 2 * 48^3), 54 M per factorisation.

    OPENBLAS_NUM_THREADS=1 python experiments/riccati_proto/dense_riccati.py [--repeats 20]
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
import scipy.linalg as sl

SIZES = {"ur5": (48, 18, 150), "ur5-mr-eliminated": (36, 18, 150), "arm26": (16, 6, 150)}


def stages(nx: int, nu: int, n: int, rng: np.random.Generator) -> list[tuple[np.ndarray, ...]]:
    out = []
    for _ in range(n):
        A = np.eye(nx) + 0.05 * rng.standard_normal((nx, nx))
        B = 0.1 * rng.standard_normal((nx, nu))
        M = rng.standard_normal((nx + nu, nx + nu))
        H = M @ M.T / (nx + nu) + np.eye(nx + nu)
        out.append((A, B, H[:nx, :nx].copy(), H[nx:, nx:].copy(), H[nx:, :nx].copy()))
    return out


def factor_and_solve(st: list, q: list, r: list) -> np.ndarray:
    nx = st[0][0].shape[0]
    P = np.eye(nx)
    p = np.zeros(nx)
    gains = []
    for (A, B, Q, R, S), qk, rk in zip(reversed(st), reversed(q), reversed(r)):
        PA, PB = P @ A, P @ B
        Ruu = R + B.T @ PB
        Rux = S + B.T @ PA
        c = sl.cho_factor(Ruu, lower=True, check_finite=False)
        K = sl.cho_solve(c, Rux, check_finite=False)
        k = sl.cho_solve(c, rk + B.T @ p, check_finite=False)
        P = Q + A.T @ PA - Rux.T @ K
        P = 0.5 * (P + P.T)
        p = qk + A.T @ p - Rux.T @ k
        gains.append((K, k))
    x = np.zeros(nx)
    for (A, B, *_), (K, k) in zip(st, reversed(gains)):
        u = -(K @ x + k)
        x = A @ x + B @ u
    return x


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=20)
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    print("| stage sizes (states, controls, stages) | ms per factorisation and solve, median (min) |")
    print("|---|---|")
    for name, (nx, nu, n) in SIZES.items():
        st = stages(nx, nu, n, rng)
        q = [rng.standard_normal(nx) for _ in range(n)]
        r = [rng.standard_normal(nu) for _ in range(n)]
        times = []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            factor_and_solve(st, q, r)
            times.append(1e3 * (time.perf_counter() - t0))
        print(f"| {name} ({nx}, {nu}, {n}) | {statistics.median(times):.2f} ({min(times):.2f}) |", flush=True)


if __name__ == "__main__":
    main()
