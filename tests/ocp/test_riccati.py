"""The stage-wise KKT solver (``linear_solver = "riccati"``, src/riccati_kkt.cpp): IPOPT's
iterates as with MUMPS, the inertia IPOPT's inertia correction needs, and the fall back to MUMPS."""

from __future__ import annotations

import ctypes
import os

import casadi as ca
import numpy as np
import pytest

from fatigue_pin.ocp.riccati import linear_solver_options, riccati_library, riccati_structure
from fatigue_pin.ocp.solver import NlpSolver, SolverOptions

# `pip install .` builds the library; a source tree without it (a developer's) skips, CI (CI=true,
# as .ci/run sets) runs and fails without it
pytestmark = pytest.mark.skipif(riccati_library() is None and not os.environ.get("CI"),
                                reason="the stage-wise solver's library is not built (pip install . builds it)")


def pendulum(N: int = 40, states_first: bool = False):
    """A swing-up of a pendulum by multiple shooting (RK4), with a path inequality per stage; the
    variables stage by stage, or (``states_first``) all states and then all controls, as the
    project's transcription orders them."""
    dt = 0.05
    X = [ca.SX.sym(f"x{k}", 2) for k in range(N + 1)]
    U = [ca.SX.sym(f"u{k}") for k in range(N)]

    def f(x, u):
        return ca.vertcat(x[1], -9.81 * ca.sin(x[0]) - 0.1 * x[1] + u)

    g, lbg, ubg, J = [], [], [], 0
    for k in range(N):
        x, u = X[k], U[k]
        k1 = f(x, u)
        k2 = f(x + dt / 2 * k1, u)
        k3 = f(x + dt / 2 * k2, u)
        k4 = f(x + dt * k3, u)
        g += [X[k + 1] - (x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)), X[k + 1][0] + 0.1 * u]
        lbg += [0, 0, -20]
        ubg += [0, 0, 20]
        J += 0.1 * u**2 + 0.01 * x[0] ** 2 + (0.5 * (u - U[k - 1]) ** 2 if k else 0)
    J += 10 * ca.sumsqr(X[N])
    if states_first:
        w = X + U
        lbw = [np.pi, 0] + [-10, -10] * N + [-3] * N
    else:
        w = [v for k in range(N) for v in (X[k], U[k])] + [X[N]]
        lbw = [np.pi, 0, -3] + [-10, -10, -3] * (N - 1) + [-10, -10]
    ubw = [-v if i >= 2 else v for i, v in enumerate(lbw)]
    return {"x": ca.vertcat(*w), "f": J, "g": ca.vertcat(*g)}, dict(lbx=lbw, ubx=ubw, lbg=lbg, ubg=ubg)


def iterations(nlp, bounds, linear_solver):
    opts = {"ipopt": {**linear_solver_options(linear_solver), "print_level": 0, "sb": "yes", "max_iter": 100}, "print_time": False}
    solver = ca.nlpsol("s", "ipopt", nlp, opts)
    solver(x0=0, **bounds)
    return solver.stats()


@pytest.mark.parametrize("states_first", [False, True])
def test_ipopt_iterates_are_mumps_iterates(states_first):
    nlp, bounds = pendulum(states_first=states_first)
    lib = ctypes.CDLL(str(riccati_library()))  # loaded first: IPOPT unloads it with its solver
    ric = iterations(nlp, bounds, "riccati")
    # the pair step (src/riccati_pair.hpp) factorised the iterations with no regularisation of the rows
    pair, block = pair_counts(lib)
    assert pair > 0, (pair, block)
    mumps = iterations(nlp, bounds, "mumps")
    assert ric["return_status"] == mumps["return_status"] == "Solve_Succeeded"
    assert ric["iter_count"] == mumps["iter_count"]
    a, b = ric["iterations"], mumps["iterations"]
    for key in ("obj", "inf_pr", "inf_du"):
        np.testing.assert_allclose(a[key], b[key], rtol=1e-8, atol=1e-12)
    # the inertia correction ran (a regularised iteration) and took the same decisions
    np.testing.assert_array_equal(np.asarray(a["regularization_size"]) > 0, np.asarray(b["regularization_size"]) > 0)


class Ma27:
    """One analysed solver of the library, driven through the MA27 entry points step by step."""

    def __init__(self, lib, rows, cols, n):
        self.lib, self.n = lib, n
        self.irn, self.jcn = (np.asarray(v, dtype=np.int32) + 1 for v in (rows, cols))
        nz = self.irn.size
        self.icntl, self.cntl, self.info = np.zeros(30, np.int32), np.zeros(5), np.zeros(20, np.int32)
        self.iw, self.ikeep, self.iw1 = np.zeros(2 * nz + 3 * n + 16, np.int32), np.zeros(3 * n, np.int32), np.zeros(2 * n, np.int32)
        self.nsteps, self.maxfrt = ctypes.c_int(0), ctypes.c_int(0)
        lib.ma27id_(self._p(self.icntl), self._p(self.cntl))
        lib.ma27ad_(self._i(n), self._i(nz), self._p(self.irn), self._p(self.jcn), self._p(self.iw), self._i(self.iw.size),
                    self._p(self.ikeep), self._p(self.iw1), ctypes.byref(self.nsteps), ctypes.byref(ctypes.c_int(0)),
                    self._p(self.icntl), self._p(self.cntl), self._p(self.info), ctypes.byref(ctypes.c_double(0)))
        assert self.info[0] == 0

    @staticmethod
    def _i(v):
        return ctypes.byref(ctypes.c_int(v))

    @staticmethod
    def _p(a):
        return a.ctypes.data_as(ctypes.c_void_p)

    def factor(self, values) -> int:
        """INFO(1) of a factorisation of ``values`` (the triplets' values); INFO(15), the
        negative eigenvalues, stays in ``self.info[14]``."""
        a = self.a = np.asarray(values, dtype=float).copy()
        self.lib.ma27bd_(self._i(self.n), self._i(self.irn.size), self._p(self.irn), self._p(self.jcn), self._p(a), self._i(a.size),
                         self._p(self.iw), self._i(self.iw.size), self._p(self.ikeep), ctypes.byref(self.nsteps),
                         ctypes.byref(self.maxfrt), self._p(self.iw1), self._p(self.icntl), self._p(self.cntl), self._p(self.info))
        return int(self.info[0])

    def solve(self, rhs) -> np.ndarray:
        """The solution of the last factorised system for ``rhs``."""
        x, w = np.array(rhs, dtype=float), np.zeros(16)
        self.lib.ma27cd_(self._i(self.n), self._p(self.a), self._i(self.a.size), self._p(self.iw), self._i(self.iw.size), self._p(w),
                         ctypes.byref(self.maxfrt), self._p(x), self._p(self.iw1), ctypes.byref(self.nsteps), self._p(self.icntl),
                         self._p(self.info))
        return x


def ma27(lib, rows, cols, values, n, rhs):
    """Analysis, factorisation and one solve through the MA27 entry points; (INFO(1), INFO(15), x)."""
    solver = Ma27(lib, rows, cols, n)
    flag = solver.factor(values)
    negative = int(solver.info[14])
    x = solver.solve(rhs) if flag == 0 else np.array(rhs, dtype=float)
    return flag, negative, x


def random_kkt(rng, stages=12, nx=4, nu=2, hessian_scale=1.0, group=0):
    """A random augmented system [H, J^T; J, -d I] of a stage-wise OCP (dynamics rows
    x_{k+1} - A x_k - B u_k), indefinite H blocks, in the NLP's order (primal, then rows).
    ``group`` > 0: the states in independent groups of that size (A and the states' Hessian block
    diagonal, each group driven by one control), like the fatigue states of separate actuators."""
    nw = stages * (nx + nu) + nx
    m = stages * nx
    K = np.zeros((nw + m, nw + m))
    mask_x = np.kron(np.eye(nx // group), np.ones((group, group))) if group else np.ones((nx, nx))
    mask_u = np.kron(np.eye(nx // group), np.ones((group, 1)))[:, :nu] if group else np.ones((nx, nu))
    for k in range(stages + 1):
        s = k * (nx + nu)
        size = nx + nu if k < stages else nx
        Q = rng.normal(size=(size, size)) * hessian_scale
        Q[:nx, :nx] *= mask_x
        K[s:s + size, s:s + size] = Q + Q.T
    for k in range(stages):
        s, r = k * (nx + nu), nw + k * nx
        K[r:r + nx, s:s + nx] = -rng.normal(size=(nx, nx)) * mask_x
        K[r:r + nx, s + nx:s + nx + nu] = -rng.normal(size=(nx, nu)) * mask_u
        K[r:r + nx, s + nx + nu:s + 2 * nx + nu] = np.eye(nx)
    K = np.tril(K)
    K[nw:, nw:] -= np.eye(m) * rng.choice([0.0, 1e-8])
    K = K + np.tril(K, -1).T
    return K


@pytest.mark.parametrize("seed", range(10))
def test_inertia_is_the_eigenvalue_count(seed):
    """Seeds 6-9: stages of independent state groups, whose pivot columns are mostly zero: their
    updates take the sparse path (index lists) longer; the dense stages go to the panels
    (DenseLdl::dense_tail) at once."""
    lib = ctypes.CDLL(str(riccati_library()))
    rng = np.random.default_rng(seed)
    if seed < 6:
        K = random_kkt(rng, hessian_scale=[0.1, 1.0, 10.0][seed % 3])
    else:
        K = random_kkt(rng, stages=8, nx=12, nu=4, hessian_scale=[0.1, 1.0][seed % 2], group=3)
    rows, cols = np.nonzero(np.tril(K))
    rows, cols = np.concatenate([rows, np.arange(len(K))]), np.concatenate([cols, np.arange(len(K))])
    values = np.concatenate([K[np.nonzero(np.tril(K))], np.zeros(len(K))])  # duplicates are summed
    b = rng.normal(size=len(K))
    flag, negative, x = ma27(lib, rows, cols, values, len(K), b)
    assert flag == 0
    assert negative == int(np.sum(np.linalg.eigvalsh(K) < 0))
    np.testing.assert_allclose(K @ x, b, atol=1e-8 * np.abs(K).max() * np.abs(x).max())


def pair_counts(lib) -> tuple[int, int]:
    """(pair-step, block LDL^T) factorisations of the library's last analysed solver."""
    p, b = ctypes.c_long(0), ctypes.c_long(0)
    lib.riccati_pair_counts(ctypes.byref(p), ctypes.byref(b))
    return p.value, b.value


@pytest.mark.parametrize("seed", range(8))
@pytest.mark.parametrize("delta_c", [0.0, 1e-8])
def test_pair_step_inertia_and_solution(seed, delta_c):
    """The pair step (src/riccati_pair.hpp) takes these systems when the dynamics rows carry no
    regularisation (delta_c = 0); with delta_c != 0 the factorisation falls back to the block LDL^T.
    Either way: the eigenvalue count and the solution."""
    lib = ctypes.CDLL(str(riccati_library()))
    rng = np.random.default_rng(100 + seed)
    if seed < 4:
        K = random_kkt(rng, hessian_scale=[0.1, 1.0, 10.0, 1.0][seed])
    else:
        K = random_kkt(rng, stages=8, nx=12, nu=4, hessian_scale=[0.1, 1.0, 3.0, 10.0][seed - 4], group=3)
    stages, nx = (12, 4) if seed < 4 else (8, 12)
    nw = len(K) - stages * nx
    K[nw:, nw:] = -delta_c * np.eye(len(K) - nw)
    rows, cols = np.nonzero(np.tril(K) + np.eye(len(K)))
    b = rng.normal(size=len(K))
    flag, negative, x = ma27(lib, rows, cols, K[rows, cols], len(K), b)
    assert flag == 0
    assert pair_counts(lib) == ((1, 0) if delta_c == 0.0 else (0, 1))
    assert negative == int(np.sum(np.linalg.eigvalsh(K) < 0))
    np.testing.assert_allclose(K @ x, b, atol=1e-8 * np.abs(K).max() * np.abs(x).max())


def test_analyses_kept_by_pattern_solve_each_matrix():
    """The library keeps its analyses by pattern (a re-plan or a sliding window hands IPOPT the same
    pattern again): a pattern met again, after others and after more patterns than it keeps, with
    new values, and two patterns of the same size and count that differ in one entry, each give
    their own matrix's solution and inertia."""
    lib = ctypes.CDLL(str(riccati_library()))
    rng = np.random.default_rng(7)

    def system(drop, seed):
        K = random_kkt(np.random.default_rng(seed))
        nw = len(K) - 12 * 4
        K[nw:, nw:] = 0.0
        i, j = drop  # one Hessian entry (and its mirror) left out of the pattern
        K[i, j] = K[j, i] = 0.0
        rows, cols = np.nonzero(np.tril(K) + np.eye(len(K)))
        return K, rows, cols

    drops = [(1, 0), (2, 0), (3, 1), (5, 4), (8, 6), (9, 7)]  # the same n and nz, six patterns
    for seed, d in enumerate([0, 1, 0, 2, 3, 4, 5, 0, 1, 0]):
        K, rows, cols = system(drops[d], seed)
        b = rng.normal(size=len(K))
        flag, negative, x = ma27(lib, rows, cols, K[rows, cols], len(K), b)
        assert flag == 0 and pair_counts(lib) == (1, 0)
        assert negative == int(np.sum(np.linalg.eigvalsh(K) < 0))
        np.testing.assert_allclose(K @ x, b, atol=1e-8 * np.abs(K).max() * np.abs(x).max())


def test_a_cycle_of_ten_patterns_is_analysed_once():
    """A closed loop re-planning every 0.1 s on arm26 hands IPOPT ten patterns in turn (the targets
    fall on other nodes of each window): the library keeps them all, so the second cycle's solves
    make no analysis of their own (with four patterns kept, as before, every solve analysed)."""
    patterns = 10
    lib = ctypes.CDLL(str(riccati_library()))
    lib.riccati_analyses_made.restype = ctypes.c_long
    rng = np.random.default_rng(11)
    K0 = random_kkt(np.random.default_rng(5))
    nw = len(K0) - 12 * 4
    K0[nw:, nw:] = 0.0
    low = np.argwhere(np.tril(K0, -1)[:nw, :nw] != 0.0)[:patterns]  # one entry dropped per pattern
    made = []
    for cycle in range(2):
        before = lib.riccati_analyses_made()
        for i, j in low:
            K = K0 + np.diag(rng.uniform(0.5, 1.5, len(K0)) * (np.arange(len(K0)) < nw))
            K[i, j] = K[j, i] = 0.0
            rows, cols = np.nonzero(np.tril(K) + np.eye(len(K)))
            b = rng.normal(size=len(K))
            flag, negative, x = ma27(lib, rows, cols, K[rows, cols], len(K), b)
            assert flag == 0
            assert negative == int(np.sum(np.linalg.eigvalsh(K) < 0))
            np.testing.assert_allclose(K @ x, b, atol=1e-8 * np.abs(K).max() * np.abs(x).max())
        made.append(lib.riccati_analyses_made() - before)
    assert made[0] <= patterns and made[1] == 0


def test_pair_step_off_by_environment(monkeypatch):
    lib = ctypes.CDLL(str(riccati_library()))
    K = random_kkt(np.random.default_rng(3))
    nw = len(K) - 12 * 4
    K[nw:, nw:] = 0.0
    rows, cols = np.nonzero(np.tril(K) + np.eye(len(K)))
    monkeypatch.setenv("FATIGUE_PIN_RICCATI_PAIR", "0")
    flag, negative, x = ma27(lib, rows, cols, K[rows, cols], len(K), np.ones(len(K)))
    assert flag == 0 and pair_counts(lib) == (0, 1)
    assert negative == int(np.sum(np.linalg.eigvalsh(K) < 0))


def test_a_singular_matrix_is_reported():
    lib = ctypes.CDLL(str(riccati_library()))
    K = random_kkt(np.random.default_rng(1))
    K[-1, :] = 0.0
    K[:, -1] = 0.0  # a row with no entry: a zero eigenvalue
    rows, cols = np.nonzero(np.tril(K) + np.eye(len(K)))
    flag, _, _ = ma27(lib, rows, cols, K[rows, cols], len(K), np.ones(len(K)))
    assert flag == 3  # MA27's "singular" (IPOPT then regularises)


def test_a_cost_coupling_all_stages_falls_back_to_mumps(capsys, monkeypatch):
    import fatigue_pin.ocp.riccati as riccati_module

    monkeypatch.setattr(riccati_module, "RICCATI_MAX_BLOCK", 30)  # a stage here is 6 rows; all controls, 40
    N = 40
    opti = ca.Opti()
    X = opti.variable(2, N + 1)
    U = opti.variable(1, N)
    opti.subject_to(X[:, 0] == 0)
    for k in range(N):
        opti.subject_to(X[:, k + 1] == X[:, k] + 0.1 * ca.vertcat(X[1, k], U[0, k]))
    opti.minimize(ca.sumsqr(X) + ca.sum2(U) ** 2)  # (sum of all controls)^2: every stage with every other
    nlp, _ = pendulum(10)
    hess = ca.Sparsity.dense(100, 100)
    assert "dense block" in riccati_structure(hess, ca.Sparsity(0, N))
    solver = NlpSolver(opti, SolverOptions(linear_solver="riccati", compile=False), name="riccati_fallback")
    said = capsys.readouterr().err.strip().splitlines()
    assert len(said) == 1 and "MUMPS instead" in said[0] and "dense block" in said[0]
    assert solver.options.linear_solver == "mumps"
    assert riccati_structure(*_patterns(nlp)) is None


def _patterns(nlp):
    x = nlp["x"]
    lam = ca.SX.sym("lam", nlp["g"].numel())
    return ca.hessian(nlp["f"] + ca.dot(lam, nlp["g"]), x)[0].sparsity(), ca.jacobian(nlp["g"], x).sparsity()


def _chain(N: int = 30, coupled: bool = False) -> ca.Opti:
    """A double integrator by forward Euler over N stages; ``coupled``: a cost on the sum of all
    controls, which couples every stage with every other."""
    opti = ca.Opti()
    X = opti.variable(2, N + 1)
    U = opti.variable(1, N)
    opti.subject_to(X[:, 0] == ca.vertcat(1, 0))
    for k in range(N):
        opti.subject_to(X[:, k + 1] == X[:, k] + 0.1 * ca.vertcat(X[1, k], U[0, k]))
    opti.subject_to(opti.bounded(-2, U, 2))
    opti.minimize(ca.sumsqr(X) + ca.sumsqr(U) + (ca.sum2(U) ** 2 if coupled else 0))
    return opti


@pytest.mark.parametrize("coupled, chosen", [(False, "riccati"), (True, "mumps")])
def test_auto_takes_the_stage_wise_solver_where_its_stages_are_small(capsys, coupled, chosen):
    """``auto`` (the default) resolves to ``riccati`` on stages of a few rows, and to MUMPS, without
    a message, where a cost merges the stages into one block above RICCATI_AUTO_MAX_BLOCK; both
    reach the optimum that MUMPS reaches."""
    from fatigue_pin.ocp.riccati import RICCATI_AUTO_MAX_BLOCK

    assert SolverOptions().linear_solver == "auto"
    N = 30 if not coupled else RICCATI_AUTO_MAX_BLOCK  # all controls in one block: > the limit
    opti = _chain(N, coupled)
    solver = NlpSolver(opti, SolverOptions(compile=False), name=f"auto_{chosen}")
    assert capsys.readouterr().err == ""
    assert solver.options.linear_solver == chosen
    reference = NlpSolver(_chain(N, coupled), SolverOptions(linear_solver="mumps", compile=False), name=f"auto_{chosen}_mumps")
    capsys.readouterr()
    nx = opti.nx
    a, b = solver.solve(np.zeros(0), np.zeros(nx)), reference.solve(np.zeros(0), np.zeros(nx))
    assert a.status == b.status == "Solve_Succeeded"
    np.testing.assert_allclose(a.f, b.f, rtol=1e-9)


def _wide_chain(N: int = 10, nx: int = 60, nu: int = 20) -> ca.Opti:
    """A linear system of nx states and nu controls over N stages (random A near the identity,
    dense B: every row of a stage reaches all its controls), controls bounded."""
    rng = np.random.default_rng(0)
    A, B = np.eye(nx) + 0.01 * rng.normal(size=(nx, nx)), 0.1 * rng.normal(size=(nx, nu))
    opti = ca.Opti()
    X, U = opti.variable(nx, N + 1), opti.variable(nu, N)
    opti.subject_to(X[:, 0] == 1)
    for k in range(N):
        opti.subject_to(X[:, k + 1] == ca.mtimes(A, X[:, k]) + ca.mtimes(B, U[:, k]))
    opti.subject_to(opti.bounded(-2, U, 2))
    opti.minimize(ca.sumsqr(X) + ca.sumsqr(U))
    return opti



@pytest.mark.parametrize("nx, nu", [(4, 2), (60, 20)])
def test_the_pair_step_takes_stages_whose_rows_reach_every_control(nx, nu):
    """Every row of a stage reaching all its controls: the analysis must take the node's first
    control as the first control (not its last, the highest variable of those rows). Every
    factorisation is then the pair step's, and the iterations and the optimum are MUMPS's."""
    opti = _wide_chain(nx=nx, nu=nu)
    solver = NlpSolver(opti, SolverOptions(linear_solver="riccati", compile=False), name=f"pair_wide_{nx}")
    assert solver.options.linear_solver == "riccati"
    reference = NlpSolver(_wide_chain(nx=nx, nu=nu), SolverOptions(linear_solver="mumps", compile=False), name=f"pair_wide_{nx}_mumps")
    lib = ctypes.CDLL(str(riccati_library()))  # loaded first: IPOPT unloads it with its solver
    a, b = solver.solve(np.zeros(0), np.zeros(opti.nx)), reference.solve(np.zeros(0), np.zeros(opti.nx))
    assert a.status == b.status == "Solve_Succeeded"
    np.testing.assert_allclose(a.f, b.f, rtol=1e-9)
    assert a.iterations == b.iterations
    pair, block = pair_counts(lib)
    assert pair > 0 and block == 0, (pair, block)


def test_release_frees_the_factors_of_this_threads_solves_only():
    """``riccati_release_thread`` (called by NlpSolver once an IPOPT solve has returned): the
    calling thread's solvers refuse to factorise afterwards (INFO(1) = -1, never a stale step) and
    keep their counts; a solver another thread is still using factorises as before."""
    import threading

    lib = ctypes.CDLL(str(riccati_library()))
    K = random_kkt(np.random.default_rng(7))
    rows, cols = np.nonzero(np.tril(K) + np.eye(len(K)))
    values = K[rows, cols]
    analysed, release_done, results = threading.Event(), threading.Event(), {}

    def other_thread():
        solver = Ma27(lib, rows, cols, len(K))
        results["before"] = solver.factor(values)
        analysed.set()
        release_done.wait(timeout=60)
        results["after"] = solver.factor(values)

    worker = threading.Thread(target=other_thread)
    worker.start()
    assert analysed.wait(timeout=60)
    mine = Ma27(lib, rows, cols, len(K))
    assert mine.factor(values) == 0
    counts = pair_counts(lib)
    assert sum(counts) >= 1
    assert lib.riccati_release_thread() >= 1
    assert lib.riccati_release_thread() == 0  # nothing of this thread's is left to free
    assert pair_counts(lib) == counts          # the newest solver is mine: its counts are kept
    assert mine.factor(values) == -1
    release_done.set()
    worker.join(timeout=60)
    assert results == {"before": 0, "after": 0}


def test_a_solve_on_riccati_leaves_no_factor_behind():
    """NlpSolver frees the stage-wise solver's factors once its IPOPT solve has returned (the
    library would otherwise keep 16 solves' factors alive), and solves again to the same optimum."""
    from fatigue_pin.ocp.riccati import riccati_releaser

    opti = _chain(30)
    release = riccati_releaser()
    release()  # whatever earlier tests of this thread left
    solver = NlpSolver(opti, SolverOptions(linear_solver="riccati", compile=False), name="riccati_release")
    assert solver.options.linear_solver == "riccati"
    first = solver.solve(np.zeros(0), np.zeros(opti.nx))
    assert release() == 0  # the solve freed its own
    assert pair_counts(ctypes.CDLL(str(riccati_library())))[0] >= first.iterations  # and they were the library's
    second = solver.solve(np.zeros(0), np.zeros(opti.nx))
    assert first.success and second.success and second.iterations == first.iterations
    np.testing.assert_allclose(second.x, first.x, rtol=0, atol=1e-12)
