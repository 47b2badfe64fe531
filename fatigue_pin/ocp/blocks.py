"""The NLP's exact Hessian and constraint Jacobian from per-interval derivative blocks.

In library mode (:mod:`fatigue_pin.ocp.compiled`) the interval functions are compiled externals
``map``-ped over the horizon, and CasADi's virtual machine assembles the NLP's derivatives
around the maps (forward sweeps over the colouring of the whole Jacobian and Hessian): that
assembly, not the compiled calls, was most of an iteration's function time. This module gives
``nlpsol`` its own ``jac_g`` and ``hess_lag`` instead:

1. For every mapped per-interval function ``f(a_1, ..., a_m) -> y`` (one output, n_out rows),
   with ``w`` the stacked inputs that depend on the decision variables (n_w rows):
   ``jblk_<f>(w, others) -> (y, dy/dw)`` and ``hblk_<f>(w, others, mu) -> tril(d2(mu' y)/dw2)``,
   built once per model (:func:`block_functions`) and compiled into the model's library.
2. The NLP's constraints and objective are linear in the map outputs ``S`` (gaps ``X - S``,
   coupling rows ``S``, objective ``w' sum(S)``) and the map inputs are linear in the scaled
   variables (``W = A x``). Then, with ``g = g~(x, S)`` and ``L = lam_f f + lam_g' g``::

       jac_g   = dg~/dx + C . blockdiag(dy_k/dw_k) . A          C = dg~/dS (constant)
       hess_L  = d2L~/dx2 + A' . blockdiag(d2(mu_k' y_k)/dw_k2) . A      mu = dL~/dS

   and every nonzero of the result is one constant sparse matrix times the stacked block
   nonzeros (scaling, selection and overlapping contributions folded in; built with SciPy when
   the NLP is assembled): one map of a compiled block function per interval function and one
   sparse product per derivative.
3. ``dg~/dx`` and ``d2L~/dx2`` (the linear parts, the task's state constraints at their nodes)
   are left to CasADi's automatic derivatives; they are small.

:func:`nlp_derivatives` checks the linearity conditions and returns None when one fails, so the
caller keeps CasADi's own derivatives (correct, slower).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Sequence

import casadi as ca
import numpy as np
import scipy.sparse as sps

#: Name prefixes of the block functions of an interval function ``f``.
JAC_BLOCK, HESS_BLOCK = "jblk_", "hblk_"


@dataclass(frozen=True)
class MappedCall:
    """One ``map`` of a per-interval function inside the NLP.

    Attributes:
        function: the per-interval function (one output, n_out rows).
        args: the map's inputs as they were passed, each (rows of input i, n) or (rows, 1)
            for an input shared by every interval.
        out: the map's output (n_out, n), the expression the NLP's objective and constraints use.
        n: number of intervals mapped.
    """

    function: ca.Function
    args: tuple[ca.MX, ...]
    out: ca.MX
    n: int


@dataclass(frozen=True)
class BlockPair:
    """The block functions of one interval function.

    Attributes:
        diff: indices of the inputs stacked in ``w`` (those that depend on the decision variables).
        jac: ``jblk_<f>(w, others...) -> (y, J)``, J = dy/dw of shape (n_out, n_w), sparse.
        hess: ``hblk_<f>(w, others..., mu) -> H``, H = tril(d2(mu' y)/dw2) of shape (n_w, n_w);
            None: the Lagrangian's Hessian leaves out the second derivatives of ``f`` (Gauss-Newton
            for its rows, :attr:`~fatigue_pin.ocp.solver.SolverOptions.hessian`).
    """

    diff: tuple[int, ...]
    jac: ca.Function
    hess: ca.Function | None


def differentiated_inputs(call: MappedCall, x: ca.MX) -> tuple[int, ...]:
    """Indices of the inputs of ``call`` that depend on the decision variables ``x``."""
    return tuple(i for i, a in enumerate(call.args) if ca.depends_on(a, x))


#: A block function built from MX is expanded to SX if that has at most this many operations:
#: the fatigue RK4's blocks (about 14 000 and 40 operations for arm26) then run 2-10 times
#: faster, while the rigid body's (65 000 and 220 000) would take minutes to compile and run no
#: faster than their MX form (measured on arm26).
EXPAND_MAX_INSTRUCTIONS = 50_000


def _called_instructions(f: ca.Function, limit: int) -> int:
    """The SX instructions of the functions that an MX function ``f`` calls (recursively through
    MX callees), counted until they pass ``limit``: about what ``f.expand()`` would hold (its
    inputs and outputs counted too), without expanding."""
    total = 0
    for k in range(f.n_instructions()):
        if f.instruction_id(k) != ca.OP_CALL:
            continue
        callee = f.instruction_MX(k).which_function()
        total += callee.n_instructions() if callee.is_a("SXFunction") else _called_instructions(callee, limit - total)
        if total > limit:
            break
    return total


def _maybe_expanded(f: ca.Function) -> ca.Function:
    """``f`` expanded to an SX function of the same name if that is small enough. Functions whose
    calls alone hold over 10 times :data:`EXPAND_MAX_INSTRUCTIONS` are not expanded to be
    measured: the muscle curl's exact Hessian block of the rigid body would take 8 s to reach
    21 M instructions, only to be kept as MX."""
    if f.is_a("SXFunction"):
        return f
    if _called_instructions(f, 10 * EXPAND_MAX_INSTRUCTIONS) > 10 * EXPAND_MAX_INSTRUCTIONS:
        return f
    sx = f.expand()
    if sx.n_instructions() > EXPAND_MAX_INSTRUCTIONS:
        return f
    return ca.Function(f.name(), sx.sx_in(), sx.call(sx.sx_in()), f.name_in(), f.name_out())


def block_functions(f: ca.Function, diff: Sequence[int], hessian: bool = True, hessian_of: ca.Function | None = None,
                    jacobian: ca.Function | None = None, hessian_block: ca.Function | None = None) -> BlockPair:
    """``jblk_<f>`` and ``hblk_<f>`` of a one-output function ``f`` for the inputs ``diff``
    (``hessian=False``: no ``hblk_<f>``; the Lagrangian's Hessian then omits f's curvature;
    ``hessian_of``: ``hblk_<f>`` holds the second derivatives of this function of the same
    signature instead, e.g. a coarser integrator of the same flow: an approximate Hessian;
    ``jacobian``: a ready ``jblk_<f>`` of the same inputs and outputs, taken as it is instead of
    CasADi's, e.g. one from analytical derivatives; ``hessian_block``: likewise a ready
    ``hblk_<f>`` (with ``hessian``), e.g. one from the stages' adjoints).

    SX functions give SX blocks; MX functions (RK4 as calls of an SX right-hand side) are
    inlined, so the blocks call derivatives of the SX right-hand side only, and each block is
    expanded to SX when that is small (:data:`EXPAND_MAX_INSTRUCTIONS`).
    """
    if f.n_out() != 1 or not f.sparsity_out(0).is_column() or not f.sparsity_out(0).is_dense():
        raise ValueError(f"{f.name()}: block functions need one dense column output")
    diff = tuple(int(i) for i in diff)
    kind = ca.SX if f.is_a("SXFunction") else ca.MX
    sizes = [f.sparsity_in(i).numel() for i in diff]
    w = kind.sym("w", sum(sizes))
    pieces = ca.vertsplit(w, list(np.cumsum([0, *sizes]))) if diff else []
    others = [kind.sym(f.name_in(i), f.sparsity_in(i)) for i in range(f.n_in()) if i not in diff]
    args, it_w, it_o = [], iter(pieces), iter(others)
    for i in range(f.n_in()):
        args.append(ca.reshape(next(it_w), f.size_in(i)) if i in diff else next(it_o))
    y = f.call(args, True, False)[0] if kind is ca.MX else f(*args)
    mu = kind.sym("mu", f.size1_out(0))
    names = ["w", *[f.name_in(i) for i in range(f.n_in()) if i not in diff]]
    jac = jacobian if jacobian is not None else _maybe_expanded(
        ca.Function(JAC_BLOCK + f.name(), [w, *others], [y, ca.jacobian(y, w)], names, ["y", "J"]))
    if not hessian:
        return BlockPair(diff, jac, None)
    if hessian_block is not None:
        return BlockPair(diff, jac, hessian_block)
    if hessian_of is not None:
        y = hessian_of.call(args, True, False)[0] if kind is ca.MX else hessian_of(*args)
    hess = ca.Function(HESS_BLOCK + f.name(), [w, *others, mu], [ca.tril(ca.hessian(ca.dot(mu, y), w)[0])],
                       [*names, "mu"], ["H"])
    return BlockPair(diff, jac, _maybe_expanded(hess))


def _call_function(out: ca.MX) -> str | None:
    """Name of the function whose call produced ``out`` (None if it is no call output)."""
    node = out.dep(0) if out.is_output() else out
    return node.which_function().name() if node.is_call() else None


def _reachable(f: ca.Function) -> set[str]:
    """Names of every function called, at any depth, by ``f``."""
    seen: dict[str, ca.Function] = {}
    stack = [f]
    while stack:
        for g in stack.pop().find_functions():
            if g.name() not in seen:
                seen[g.name()] = g
                stack.append(g)
    return set(seen)


def _constant(expr: ca.MX, symbols: Sequence[ca.MX]) -> ca.DM | None:
    """``expr`` as a DM if it depends on none of ``symbols``, else None."""
    if any(ca.depends_on(expr, s) for s in symbols):
        return None
    return ca.evalf(expr)


def _csr(m: ca.DM) -> sps.csr_matrix:
    """A sparse DM as a SciPy CSR matrix (structural nonzeros kept)."""
    sp = m.sparsity()
    csc = sps.csc_matrix((np.asarray(m.nonzeros(), dtype=float), np.asarray(sp.row()), np.asarray(sp.colind())),
                         shape=m.shape)
    return csc.tocsr()


def _pairs(a: sps.csr_matrix, ia: np.ndarray, b: sps.csr_matrix, ib: np.ndarray):
    """For every t, all pairs (p, q) of nonzeros p in row ``ia[t]`` of ``a`` and q in row
    ``ib[t]`` of ``b``. Returns t, column of p, value of p, column of q, value of q (arrays)."""
    na, nb = np.diff(a.indptr)[ia], np.diff(b.indptr)[ib]
    cnt = na * nb
    t = np.repeat(np.arange(len(ia)), cnt)
    offset = np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt)
    ka = a.indptr[ia[t]] + offset // np.maximum(nb[t], 1)
    kb = b.indptr[ib[t]] + offset % np.maximum(nb[t], 1)
    return t, a.indices[ka], a.data[ka], b.indices[kb], b.data[kb]


def _block_coordinates(block: ca.Sparsity, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Stacked (row, column) of every nonzero of ``n`` blocks of pattern ``block`` placed on the
    diagonal, in the order of the mapped output's nonzeros (block k after block k-1)."""
    r, c = (np.asarray(v, dtype=np.int64) for v in block.get_triplet())
    k = np.repeat(np.arange(n), block.nnz())
    return np.tile(r, n) + k * block.size1(), np.tile(c, n) + k * block.size2()


@dataclass
class _Assembly:
    """Constant map from stacked nonzeros to the nonzeros of one sparse result."""

    rows: list[np.ndarray]
    cols: list[np.ndarray]
    vals: list[np.ndarray]
    sources: list[np.ndarray]
    offset: int = 0

    def add(self, rows: np.ndarray, cols: np.ndarray, vals: np.ndarray, sources: np.ndarray, n_sources: int) -> None:
        """Contributions ``vals * source[sources]`` to entries (rows, cols); the next source
        block starts ``n_sources`` further on."""
        self.rows.append(np.asarray(rows, dtype=np.int64))
        self.cols.append(np.asarray(cols, dtype=np.int64))
        self.vals.append(np.asarray(vals, dtype=float))
        self.sources.append(np.asarray(sources, dtype=np.int64) + self.offset)
        self.offset += n_sources

    def build(self, shape: tuple[int, int]) -> tuple[ca.Sparsity, ca.DM]:
        """The result's sparsity and the matrix (nnz x n_sources) mapping sources to nonzeros."""
        rows, cols = np.concatenate(self.rows), np.concatenate(self.cols)
        keys = cols * shape[0] + rows  # column-major position: sorted keys are CasADi's nonzero order
        unique, target = np.unique(keys, return_inverse=True)
        colind = np.searchsorted(unique // shape[0], np.arange(shape[1] + 1))
        sp = ca.Sparsity(shape[0], shape[1], colind.tolist(), (unique % shape[0]).tolist())
        m = sps.coo_matrix((np.concatenate(self.vals), (target, np.concatenate(self.sources))),
                           shape=(sp.nnz(), self.offset)).tocsc()
        m.sum_duplicates()
        m.sort_indices()
        dm = ca.DM(ca.Sparsity(m.shape[0], m.shape[1], m.indptr.tolist(), m.indices.tolist()), m.data)
        return sp, dm


def _nonzeros(m: ca.MX) -> ca.MX:
    """The nonzeros of ``m`` as a dense column."""
    return ca.sparsity_cast(m, ca.Sparsity.dense(m.nnz(), 1))


def _add_jacobian(assembly: _Assembly, jac_pattern: ca.Sparsity, n: int, C_t: sps.csr_matrix, A: sps.csr_matrix) -> None:
    """Contributions C[g, o] J_k[o, i] A[i, x] of ``n`` mapped Jacobian blocks to dg/dx."""
    o, i = _block_coordinates(jac_pattern, n)
    t, rows, cv, cols, av = _pairs(C_t, o, A, i)
    assembly.add(rows, cols, cv * av, t, len(o))


def _add_hessian(assembly: _Assembly, hess_pattern: ca.Sparsity, n: int, A: sps.csr_matrix) -> None:
    """Contributions A[i, r] H_k[i, j] A[j, c] of ``n`` mapped lower-triangular Hessian blocks to
    the upper triangle of the Hessian (an entry below a block's diagonal stands for two)."""
    i, j = _block_coordinates(hess_pattern, n)
    t, r, ar, c, ac = _pairs(A, i, A, j)
    below = i[t] > j[t]
    keep = below | (r <= c)  # of a diagonal entry's pairs, those in the upper triangle
    t, r, c, v, below = t[keep], r[keep], c[keep], (ar * ac)[keep], below[keep]
    v = v * np.where(below & (r == c), 2.0, 1.0)
    assembly.add(np.minimum(r, c), np.maximum(r, c), v, t, len(i))


def _add_rest(assembly: _Assembly, m: ca.MX) -> None:
    """The nonzeros of ``m`` (already in the result's coordinates) as the first sources."""
    r, c = m.sparsity().get_triplet()
    assembly.add(r, c, np.ones(m.nnz()), np.arange(m.nnz()), m.nnz())


def _stacked_inputs(call: MappedCall, diff: Sequence[int]) -> tuple[ca.MX, list[ca.MX]]:
    """The differentiated inputs of ``call`` stacked per interval, W (n_w, n), and the others."""
    W = ca.vertcat(*[call.args[i] if call.args[i].size2() == call.n else ca.repmat(call.args[i], 1, call.n) for i in diff])
    return W, [a for i, a in enumerate(call.args) if i not in diff]


def nlp_derivatives(
    nlp: Mapping[str, ca.MX],
    calls: Sequence[MappedCall],
    blocks: Mapping[str, BlockPair],
    map_args: tuple = ("serial",),
) -> dict[str, ca.Function] | None:
    """``nlpsol`` options ``jac_g`` and ``hess_lag`` assembled from per-interval blocks.

    Args:
        nlp: ``{"x", "p", "f", "g"}`` of the NLP (``g`` after any row selection).
        calls: the mapped per-interval functions whose outputs ``f`` and ``g`` use.
        blocks: block functions per interval function name (:func:`block_functions`, compiled
            or not); a call whose function has no blocks, or other differentiated inputs, is
            left to CasADi.
        map_args: how the block functions are mapped (e.g. ``("thread", 2)``).

    Returns:
        ``{"jac_g": (x, p) -> (g, jac_g_x), "hess_lag": (x, p, lam_f, lam_g) -> triu(hess)}``,
        or None if the NLP is not linear in the map outputs, or the map inputs not affine in x
        (then nlpsol's own derivatives must be used).
    """
    x, p, f, g = nlp["x"], nlp["p"], nlp["f"], nlp["g"]
    used = [c for c in calls if c.function.name() in blocks and blocks[c.function.name()].diff == differentiated_inputs(c, x)]
    if not used or any(_call_function(c.out) is None for c in used):
        return None
    # f and g as functions of x and the map outputs S: f~(x, S), g~(x, S)
    S = [ca.MX.sym(f"S_{c.function.name()}", c.out.sparsity()) for c in used]
    ft, gt = ca.graph_substitute([f, g], [c.out for c in used], S)
    if {_call_function(c.out) for c in used} & _reachable(ca.Function("rest", [x, p, *S], [ft, gt])):
        return None  # a map output is used other than through the substituted node
    lam_f, lam_g = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", g.sparsity())
    lag = lam_f * ft + ca.dot(lam_g, gt)
    mus = [ca.reshape(ca.gradient(lag, s), s.shape) for s in S]  # dL~/dS: the blocks' multipliers
    if any(ca.depends_on(mu, v) for mu in mus for v in (x, *S)):
        return None  # the Lagrangian is not linear in the map outputs (or has cross terms)
    # derivatives of g~ and L~ with the map outputs held fixed: CasADi's
    j_rest, h_rest = ca.jacobian(gt, x), ca.triu(ca.hessian(lag, x)[0])
    jac_assembly, hess_assembly = _Assembly([], [], [], []), _Assembly([], [], [], [])
    _add_rest(jac_assembly, j_rest)
    _add_rest(hess_assembly, h_rest)
    inputs = []
    for call, s in zip(used, S):
        pair = blocks[call.function.name()]
        W, others = _stacked_inputs(call, pair.diff)
        A = _constant(ca.jacobian(ca.vec(W), x), [x, p])
        C = _constant(ca.jacobian(gt, s), [x, p, *S])
        if A is None or C is None:
            return None  # map inputs not affine in x, or g~ not linear in S
        A_csr = _csr(A)
        _add_jacobian(jac_assembly, pair.jac.sparsity_out(1), call.n, _csr(C.T), A_csr)
        if pair.hess is not None:
            _add_hessian(hess_assembly, pair.hess.sparsity_out(0), call.n, A_csr)
        inputs.append((call, pair, W, others))
    jac_sp, jac_m = jac_assembly.build((g.numel(), x.numel()))
    hess_sp, hess_m = hess_assembly.build((x.numel(), x.numel()))

    # the functions nlpsol calls: block maps, then one sparse product each
    mu_values = ca.Function("mu", [p, lam_f, lam_g], mus).call([p, lam_f, lam_g])
    y_values, j_nz, h_nz = [], [], []
    for (call, pair, W, others), mu in zip(inputs, mu_values):
        y, J = pair.jac.map(call.n, *map_args)(W, *others)
        y_values.append(y)
        j_nz.append(_nonzeros(J))
        if pair.hess is not None:
            h_nz.append(_nonzeros(pair.hess.map(call.n, *map_args)(W, *others, mu)))
    g_out, j_rest_nz = ca.Function("rest_jac", [x, p, *S], [gt, _nonzeros(j_rest)]).call([x, p, *y_values])
    jac = ca.sparsity_cast(ca.mtimes(jac_m, ca.vertcat(j_rest_nz, *j_nz)), jac_sp)
    # L~ is linear in S, so its Hessian in x does not depend on S: zeros keep the graph small
    h_rest_nz = ca.Function("rest_hess", [x, p, lam_f, lam_g, *S], [_nonzeros(h_rest)]).call(
        [x, p, lam_f, lam_g, *[ca.MX(s.sparsity(), 0) for s in S]])[0]
    hess = ca.sparsity_cast(ca.mtimes(hess_m, ca.vertcat(h_rest_nz, *h_nz)), hess_sp)
    jac_g = ca.Function("nlp_jac_g", [x, p], [g_out, jac], ["x", "p"], ["g", "jac_g_x"])
    hess_lag = ca.Function("nlp_hess_l", [x, p, lam_f, lam_g], [hess], ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"])
    return {"jac_g": jac_g, "hess_lag": hess_lag}
