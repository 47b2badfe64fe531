"""What a structure-exploiting solver could save (issue 23): the KKT cost per iteration of the
solvers the CasADi wheel ships, on stage-wise OCPs of this project's sizes.

Usage::

    python benchmarks/structured_solvers.py [--repeats 3]

Two synthetic problems (no fatigue_pin code; random but seeded), medians of ``--repeats`` solves:

* an NLP of the UR5 window's size (48 states, 18 controls, 150 stages: nonlinear dynamics,
  bounds, one nonlinear path constraint per stage), solved by IPOPT (MUMPS) and by FATROP
  (Riccati), both on CasADi's expanded derivatives: time per iteration outside the function
  evaluations (IPOPT) and FATROP's own step computation;
* a linear-quadratic problem of arm26's window size (20 states, 6 controls, 150 stages) and of
  the UR5's (48, 18), solved by HPIPM (Riccati interior point): time per iteration.

Printed: one table row per (problem, solver).
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # one BLAS thread, as fatigue_pin sets it (solver.blas_threads)

import casadi as ca  # noqa: E402
import numpy as np  # noqa: E402
import scipy.sparse as sps  # noqa: E402


def nlp_problem(nx: int, nu: int, N: int):
    """A stage-wise NLP (variables x0, u0, x1, ...; rows gap_k then the path row of stage k+1)."""
    rng = np.random.default_rng(0)
    A = rng.normal(size=(nx, nx)) * 0.3 / np.sqrt(nx)
    B = rng.normal(size=(nx, nu)) / np.sqrt(nu)
    x, u = ca.SX.sym("x", nx), ca.SX.sym("u", nu)
    f = ca.Function("f", [x, u], [x + 0.02 * (ca.mtimes(A, ca.sin(x)) + ca.mtimes(B, ca.tanh(u)))])
    X = [ca.MX.sym(f"x{k}", nx) for k in range(N + 1)]
    U = [ca.MX.sym(f"u{k}", nu) for k in range(N)]
    w, lbw, ubw, g, lbg, ubg, eq, J = [], [], [], [], [], [], [], 0
    x0 = np.full(nx, 0.5)
    for k in range(N):
        w += [X[k], U[k]]
        lbw += [x0 if k == 0 else -2 * np.ones(nx), -np.ones(nu)]
        ubw += [x0 if k == 0 else 2 * np.ones(nx), np.ones(nu)]
        g.append(X[k + 1] - f(X[k], U[k]))
        lbg.append(np.zeros(nx))
        ubg.append(np.zeros(nx))
        eq += [True] * nx
        if k > 0:
            g.append(ca.sumsqr(U[k]) - 0.9 * nu)
            lbg.append([-np.inf])
            ubg.append([0.0])
            eq.append(False)
        J += ca.sumsqr(X[k]) + 0.1 * ca.sumsqr(U[k])
    w.append(X[N])
    lbw.append(-2 * np.ones(nx))
    ubw.append(2 * np.ones(nx))
    J += 10 * ca.sumsqr(X[N])
    bounds = {"lbx": np.concatenate(lbw), "ubx": np.concatenate(ubw), "lbg": np.concatenate(lbg), "ubg": np.concatenate(ubg)}
    return {"x": ca.vertcat(*w), "f": J, "g": ca.vertcat(*g)}, bounds, eq


def nlp_rows(nx: int, nu: int, N: int, repeats: int) -> list[str]:
    nlp, bounds, eq = nlp_problem(nx, nu, N)
    rows = []
    for name, opts in [("ipopt", {"ipopt.print_level": 0, "ipopt.sb": "yes", "ipopt.tol": 1e-8}),
                       ("fatrop", {"structure_detection": "auto", "equality": eq, "fatrop.print_level": 0, "fatrop.tol": 1e-8})]:
        solver = ca.nlpsol("s", name, nlp, {**opts, "expand": True, "print_time": False})
        per_iteration, iterations = [], 0
        for _ in range(repeats):
            t0 = time.perf_counter()
            solver(x0=0, **bounds)
            wall = time.perf_counter() - t0
            st = solver.stats()
            iterations = int(st["iter_count"])
            functions = sum(v for k, v in st.items() if k.startswith("t_wall_nlp_"))
            kkt = st["fatrop"]["compute_sd_time"] if name == "fatrop" else wall - functions
            per_iteration.append(1e3 * kkt / max(iterations, 1))
        rows.append(f"| NLP {nx} states, {nu} controls, {N} stages | {name} | {iterations} | {statistics.median(per_iteration):.1f} |")
    return rows


def lq_rows(nx: int, nu: int, N: int, repeats: int) -> list[str]:
    rng = np.random.default_rng(0)
    A = np.eye(nx) + 0.05 * rng.normal(size=(nx, nx))
    B = 0.1 * rng.normal(size=(nx, nu))
    n = (N + 1) * nx + N * nu
    dyn = sps.lil_matrix((N * nx, n))
    for k in range(N):
        o, o1 = k * (nx + nu), (k + 1) * (nx + nu)
        dyn[k * nx:(k + 1) * nx, o:o + nx] = -A
        dyn[k * nx:(k + 1) * nx, o + nx:o + nx + nu] = -B
        dyn[k * nx:(k + 1) * nx, o1:o1 + nx] = np.eye(nx)

    def dm(m):
        m = sps.csc_matrix(m)
        m.sort_indices()
        return ca.DM(ca.Sparsity(m.shape[0], m.shape[1], m.indptr.tolist(), m.indices.tolist()), m.data)

    H, Ad = dm(sps.eye(n)), dm(dyn)
    lbx, ubx = -np.ones(n), np.ones(n)
    lbx[:nx] = ubx[:nx] = rng.uniform(-0.5, 0.5, nx)
    qp = ca.conic("q", "hpipm", {"h": H.sparsity(), "a": Ad.sparsity()},
                  {"N": N, "nx": [nx] * (N + 1), "nu": [nu] * N + [0], "ng": [0] * (N + 1), "print_time": False})
    per_iteration, iterations = [], 0
    for _ in range(repeats):
        t0 = time.perf_counter()
        qp(h=H, g=np.ones(n), a=Ad, lba=0, uba=0, lbx=lbx, ubx=ubx)
        iterations = int(qp.stats()["iter_count"])
        per_iteration.append(1e3 * (time.perf_counter() - t0) / max(iterations, 1))
    return [f"| LQ {nx} states, {nu} controls, {N} stages | hpipm | {iterations} | {statistics.median(per_iteration):.1f} |"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    print("| problem | solver | iterations | KKT ms / iteration (median) |")
    print("|---|---|---|---|")
    for line in nlp_rows(48, 18, 150, args.repeats) + lq_rows(20, 6, 150, args.repeats) + lq_rows(48, 18, 150, args.repeats):
        print(line, flush=True)


if __name__ == "__main__":
    main()
