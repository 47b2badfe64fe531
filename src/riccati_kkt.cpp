// A stage-wise solver of IPOPT's augmented system behind the HSL MA27 interface.
//
// IPOPT 3.14 (inside the CasADi wheel) loads HSL routines at run time from the library named by
// its option `hsllib` (Ipopt::LibraryLoader, symbols "ma27ad", "ma27ad_", ... tried in turn; only
// the chosen solver's four routines are looked up: Ma27TSolverInterface::InitializeImpl). This
// library exports ma27id/ma27ad/ma27bd/ma27cd with MA27's Fortran calling convention and the
// parts of its contract that Ipopt::Ma27TSolverInterface reads:
//   ma27ad: analysis of the triplet pattern (1-based, one triangle or both, duplicates summed);
//           INFO(1) = 0, INFO(5)/INFO(6) = real/integer workspace wanted (small: the factors live
//           here, not in IPOPT's arrays).
//   ma27bd: numerical factorisation; INFO(1) = 0 or 3 (singular), INFO(15) = negative eigenvalues.
//   ma27cd: solve of one right-hand side in place.
// The solver's state is kept here; its handle travels in IKEEP (ma27ad -> ma27bd) and IW
// (ma27bd -> ma27cd), both owned by IPOPT and kept between the calls.
//
// Two methods. The pair step (src/riccati_pair.hpp: its header says how and when) is tried
// first at every factorisation where the analysis found its structure; any guard that trips at
// factor time makes that factorisation use the block LDL^T below. FATIGUE_PIN_RICCATI_PAIR=0
// (read at each analysis) turns the pair step off.
//
// Block LDL^T: the pattern gives an elimination order by stages. Primal variables (the indices before
// the trailing independent set of constraint rows) keep their NLP order, which the project's
// transcription interleaves by stage; each constraint row comes right after the last primal
// variable it touches, and a slack (a primal touching one row only) right after its row. Blocks
// end after each run of rows, and are merged until every block couples only with the next one.
// The matrix is then block tridiagonal with dense blocks of a stage's size; a block LDL^T
// eliminates them in order, each diagonal block (after the Schur complement of the previous
// one) factorised densely with Bunch-Kaufman pivoting inside the block. The factorisation is a
// congruence, so the inertia is exact (Sylvester) whenever no pivot is zero; a zero pivot is
// reported as singularity, as MA27 does, and IPOPT regularises.
//
// The matrix is first equilibrated, S A S with S = diag(1 / sqrt(largest |entry| of its row)) (a
// congruence: the same inertia), as MUMPS scales internally: without it two orderings of one
// muscle problem ended 3e-8 apart at IPOPT's tol 1e-9 (MUMPS: 1.5e-12).
//
// Cost: a block's front is mostly zeros (a stage's own couplings are sparse; only the previous
// stages' Schur complement is dense), so the block's rows are put in a minimum-degree order on
// the front's pattern (Solver::order_block: the pivots that create the least fill first, the
// rows with the dense Schur complement last), and a pivot's update of the trailing matrix loops
// over its column's nonzeros (DenseLdl::gather). Once a pivot's column is dense, the rest of the
// front is factorised by panels (DenseLdl::dense_tail: matrix products instead of rank-1
// updates). The fronts are assembled one at a time in two shared workspaces (the block being
// factorised and the next, which receives its Schur complement); each block's factor is kept
// for the solves, compressed column by column where it is sparse, dense for the panels' columns.
#include <Eigen/Dense>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <memory>
#include <mutex>
#include <new>
#include <thread>
#include <utility>
#include <vector>

#include "riccati_pair.hpp"

namespace {

using Mat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic>;
using Vec = Eigen::VectorXd;
using IVec = std::vector<int>;

constexpr int MAGIC = 0x52494343;  // "RICC"
constexpr int MAX_BLOCK = 600;      // analysis fails above this block size
constexpr int KEEP = 16;            // solvers kept alive (see ma27ad_)

// Dense symmetric indefinite factorisation P^T A P = L D L^T (Bunch-Kaufman partial pivoting,
// full row/column swaps so that L is a plain unit lower triangle).
struct DenseLdl {
  Eigen::Map<Mat> M{nullptr, 0, 0};  // the front, in a workspace shared by the blocks (bind)
  int n = 0;        // the front's size: the block's rows, then the next block's coupled rows
  IVec perm;        // P: row i of P^T A is row perm[i] of A
  Vec d, e;         // D: diagonal d, sub-diagonal e (nonzero at the first index of a 2x2 pivot)
  int negative = 0;
  bool singular = false;

  int ns = 0;       // pivots: the block's own rows; the rows below are the next block's coupled rows
  IVec nzi;         // scratch: the rows where a pivot column (or either of a 2x2's) is nonzero
  std::vector<double> wv;  // scratch: that column's values there (a 2x2: both columns, one after the other)

  // A pivot's rank-1 or rank-2 update of the trailing matrix touches only the rows where its
  // column is nonzero (the stage's own couplings, the previous stages' Schur complement): the
  // update loops over those (index lists), until the columns are dense (dense_tail).
  void gather(const double* w1, const double* w2, int m) {
    nzi.clear();
    if (w2 == nullptr) {
      for (int i = 0; i < m; ++i)
        if (w1[i] != 0.0) nzi.push_back(i);
      wv.resize(nzi.size());
      for (size_t a = 0; a < nzi.size(); ++a) wv[a] = w1[nzi[a]];
    } else {
      for (int i = 0; i < m; ++i)
        if (w1[i] != 0.0 || w2[i] != 0.0) nzi.push_back(i);
      const size_t nn = nzi.size();
      wv.resize(2 * nn);
      for (size_t a = 0; a < nn; ++a) {
        wv[a] = w1[nzi[a]];
        wv[nn + a] = w2[nzi[a]];
      }
    }
  }

  // Partial factorisation of the front [A, C^T; C, 0] (A: ns x ns, lower triangle): pivots
  // chosen in A only; afterwards the rows below hold C P L^{-T} D^{-1} and the bottom-right
  // corner holds -C A^{-1} C^T (the Schur complement's contribution to the next block).
  void factor(double tiny, Mat& W) {
    perm.resize(ns);
    for (int i = 0; i < ns; ++i) perm[i] = i;
    swap_kk.assign(ns, -1);
    swap_kp.assign(ns, -1);
    colptr.assign(ns + 1, 0);
    ri.clear();
    lv.clear();
    k0 = ns;
    d.setZero(ns);
    e.setZero(ns);
    negative = 0;
    singular = false;
    const double alpha = (1.0 + std::sqrt(17.0)) / 8.0;
    int k = 0;
    while (k < ns) {
      const int m = n - k - 1;
      if (ns - k >= DENSE_MIN && dense_column(k)) {
        dense_tail(k, tiny, W);
        break;
      }
      double absakk = std::abs(M(k, k));
      int imax = k;
      double colmax = 0.0;
      if (ns - k - 1 > 0) {
        Eigen::Index r;
        colmax = M.col(k).segment(k + 1, ns - k - 1).cwiseAbs().maxCoeff(&r);
        imax = k + 1 + static_cast<int>(r);
      }
      if (!(std::max(absakk, colmax) > tiny)) {
        singular = true;
        return;
      }
      int kstep = 1, kp = k;
      if (absakk < alpha * colmax) {
        double rowmax = 0.0;
        if (imax > k) rowmax = M.row(imax).segment(k, imax - k).cwiseAbs().maxCoeff();
        if (imax < ns - 1) rowmax = std::max(rowmax, M.col(imax).segment(imax + 1, ns - 1 - imax).cwiseAbs().maxCoeff());
        if (absakk * rowmax >= alpha * colmax * colmax) {
          kp = k;
        } else if (std::abs(M(imax, imax)) >= alpha * rowmax) {
          kp = imax;
        } else {
          kp = imax;
          kstep = 2;
        }
      }
      const int kk = k + kstep - 1;
      if (kp != kk) interchange(k, kk, kp);
      if (!pivot(k, kstep, M, k, tiny)) return;
      if (kstep == 1) {
        const double dk = d(k);
        if (m > 0) {
          double* w = &M(k + 1, k);
          gather(w, nullptr, m);
          const int nn = static_cast<int>(nzi.size());
          // the rank-1 update on the column's nonzeros only
          const double s = -1.0 / dk;
          const Eigen::Index ld = M.outerStride();
          double* T = &M(k + 1, k + 1);
          const int* ix = nzi.data();
          const double* wp = wv.data();
          for (int a = 0; a < nn; ++a) {
            const double wj = wp[a] * s;
            double* col = T + ix[a] * ld;
            for (int b = a; b < nn; ++b) col[ix[b]] += wp[b] * wj;
          }
          for (int a = 0; a < nn; ++a) w[ix[a]] /= dk;
          keep(k, k + 1);
        } else {
          colptr[k + 1] = static_cast<int>(ri.size());
        }
      } else {
        const double a = d(k), b = e(k), c = d(k + 1), det = a * c - b * b;
        const int m2 = n - k - 2;
        if (m2 > 0) {
          // trailing -= W D^{-1} W^T = p w1 w1^T + r w2 w2^T + q (w1 w2^T + w2 w1^T)
          const double pp = c / det, qq = -b / det, rr = a / det;
          double* w1 = &M(k + 2, k);
          double* w2 = &M(k + 2, k + 1);
          gather(w1, w2, m2);
          const int nn = static_cast<int>(nzi.size());
          const Eigen::Index ld = M.outerStride();
          double* T = &M(k + 2, k + 2);
          const int* ix = nzi.data();
          const double* p1 = wv.data();
          const double* p2 = wv.data() + nn;
          for (int a2 = 0; a2 < nn; ++a2) {
            const double u1 = pp * p1[a2] + qq * p2[a2], u2 = qq * p1[a2] + rr * p2[a2];
            double* col = T + ix[a2] * ld;
            for (int b2 = a2; b2 < nn; ++b2) col[ix[b2]] -= p1[b2] * u1 + p2[b2] * u2;
          }
          for (int a2 = 0; a2 < nn; ++a2) {
            const int i = nzi[a2];
            const double x1 = w1[i], x2 = w2[i];
            w1[i] = x1 * pp + x2 * qq;
            w2[i] = x1 * qq + x2 * rr;
          }
          keep(k, k + 2);
          keep(k + 1, k + 2);
        } else {
          colptr[k + 1] = colptr[k + 2] = static_cast<int>(ri.size());
        }
        M(k + 1, k) = 0.0;
      }
      k += kstep;
    }
    Ld = M.block(k0, k0, n - k0, ns - k0);
    // rows kept at a pivot are positions at that time: later interchanges moved them. Walking
    // back, g maps a position at the time of the pivot to its final one.
    g.resize(n);
    for (int i = 0; i < n; ++i) g[i] = i;
    for (int c = ns - 1; c >= 0; --c) {
      for (int t = colptr[c]; t < colptr[c + 1]; ++t) ri[t] = g[ri[t]];
      if (swap_kp[c] >= 0) std::swap(g[swap_kk[c]], g[swap_kp[c]]);
    }
  }

  // D's block at pivot k, read in A's column j (and j + 1) from row k, and its negative
  // eigenvalues; false (and singular) when it is zero
  template <class Matrix>
  bool pivot(int k, int kstep, const Matrix& A, int j, double tiny) {
    const double a = A(k, j), b = kstep == 2 ? A(k + 1, j) : 0.0, c = kstep == 2 ? A(k + 1, j + 1) : 0.0;
    const double det = kstep == 1 ? a : a * c - b * b;
    if (!(std::abs(det) > tiny)) {
      singular = true;
      return false;
    }
    d(k) = a;
    if (kstep == 1) {
      negative += a < 0;
    } else {
      d(k + 1) = c;
      e(k) = b;
      negative += det < 0 ? 1 : (a + c < 0 ? 2 : 0);
    }
    return true;
  }

  // symmetric interchange of kk and kp in the lower triangle (as LAPACK's dsytf2), at pivot k
  void interchange(int k, int kk, int kp) {
    M.row(kk).head(kk).swap(M.row(kp).head(kk));
    if (kp + 1 < n) M.col(kk).tail(n - kp - 1).swap(M.col(kp).tail(n - kp - 1));
    for (int j = kk + 1; j < kp; ++j) std::swap(M(j, kk), M(kp, j));
    std::swap(M(kk, kk), M(kp, kp));
    std::swap(perm[kk], perm[kp]);
    swap_kk[k] = kk;
    swap_kp[k] = kp;
  }

  // The dense rest of a front: once a pivot's column is nonzero on 2/5 of the trailing rows
  // (the minimum-degree order leaves the rows with the dense Schur complement last), the
  // remaining pivots are factorised by panels of PANEL columns (as LAPACK's dlasyf): within a
  // panel each column is brought up to date only when it is reached (one matrix-vector product
  // with the panel's columns), Bunch-Kaufman chooses the pivot on it as above, and the trailing
  // matrix receives the panel's updates at once (one matrix product) instead of one rank-1 or
  // rank-2 update per pivot. The same pivots, the same products, in another order.
  static constexpr int PANEL = 16;
  static constexpr int DENSE_MIN = 8;  // fewer remaining pivots: not worth a panel
  bool dense_column(int k) const {
    const int m = n - k - 1;
    const double* c = &M(k + 1, k);
    int nn = 0;
    for (int i = 0; i < m; ++i) nn += c[i] != 0.0;
    return 5 * nn >= 2 * m;
  }
  // W: scratch for the panel's updated columns (L D), by the front's rows
  void dense_tail(int k, double tiny, Mat& W) {
    k0 = k;
    const double alpha = (1.0 + std::sqrt(17.0)) / 8.0;
    if (W.rows() < n) W.resize(n, PANEL);
    while (k < ns) {
      const int p0 = k;
      int jc = 0;
      while (k < ns && jc < PANEL - 1) {
        const int r = n - k;
        // column k up to date: its stored (lower-triangle) entries minus the panel's updates
        W.col(jc).segment(k, r) = M.col(k).tail(r) - M.block(k, p0, r, jc) * W.row(k).head(jc).transpose();
        double absakk = std::abs(W(k, jc)), colmax = 0.0;
        int imax = k;
        if (ns - k - 1 > 0) {
          Eigen::Index t;
          colmax = W.col(jc).segment(k + 1, ns - k - 1).cwiseAbs().maxCoeff(&t);
          imax = k + 1 + static_cast<int>(t);
        }
        if (!(std::max(absakk, colmax) > tiny)) {
          singular = true;
          return;
        }
        int kstep = 1, kp = k;
        if (absakk < alpha * colmax) {
          // column imax up to date (row imax of the lower triangle, then its column)
          for (int i = k; i < imax; ++i) W(i, jc + 1) = M(imax, i);
          W.col(jc + 1).segment(imax, n - imax) = M.col(imax).tail(n - imax);
          W.col(jc + 1).segment(k, r) -= M.block(k, p0, r, jc) * W.row(imax).head(jc).transpose();
          double rowmax = 0.0;
          for (int i = k; i < ns; ++i)
            if (i != imax) rowmax = std::max(rowmax, std::abs(W(i, jc + 1)));
          if (absakk * rowmax >= alpha * colmax * colmax) {
            kp = k;
          } else if (std::abs(W(imax, jc + 1)) >= alpha * rowmax) {
            kp = imax;
            W.col(jc).segment(k, r) = W.col(jc + 1).segment(k, r);
          } else {
            kp = imax;
            kstep = 2;
          }
        }
        const int kk = k + kstep - 1;
        if (kp != kk) {
          interchange(k, kk, kp);
          W.row(kk).head(jc + kstep).swap(W.row(kp).head(jc + kstep));
        }
        if (!pivot(k, kstep, W, jc, tiny)) return;
        if (kstep == 1) {
          M.col(k).tail(r - 1) = W.col(jc).segment(k + 1, r - 1) / d(k);
          colptr[k + 1] = colptr[k];
        } else {
          const double a = d(k), b = e(k), c = d(k + 1), det = a * c - b * b;
          const double pp = c / det, qq = -b / det, rr = a / det;
          const int r2 = r - 2;
          M.col(k).tail(r2) = W.col(jc).segment(k + 2, r2) * pp + W.col(jc + 1).segment(k + 2, r2) * qq;
          M.col(k + 1).tail(r2) = W.col(jc).segment(k + 2, r2) * qq + W.col(jc + 1).segment(k + 2, r2) * rr;
          M(k + 1, k) = 0.0;
          colptr[k + 1] = colptr[k + 2] = colptr[k];
        }
        k += kstep;
        jc += kstep;
      }
      // the panel's updates of the trailing matrix (the next block's coupled rows included)
      const int r = n - k;
      if (r > 0)
        M.bottomRightCorner(r, r).triangularView<Eigen::Lower>() -= M.block(k, p0, r, jc) * W.block(k, 0, r, jc).transpose();
    }
  }

  // L's column c (divided by D) on the rows r0 + nzi, where it is nonzero: kept for the solves
  // as soon as it is final (only later interchanges move its rows), which spares a scan of the
  // front afterwards
  void keep(int c, int r0) {
    const double* col = &M(r0, c);
    for (int i : nzi)
      if (col[i] != 0.0) {
        ri.push_back(r0 + i);
        lv.push_back(col[i]);
      }
    colptr[c + 1] = static_cast<int>(ri.size());
  }

  // Y <- D^{-1} Y (rows in pivoted order)
  template <class T>
  void apply_dinv(T& Y) const {
    for (int k = 0; k < ns;) {
      if (k + 1 < ns && e(k) != 0.0) {
        const double a = d(k), b = e(k), c = d(k + 1), det = a * c - b * b;
        for (Eigen::Index j = 0; j < Y.cols(); ++j) {
          const double y0 = Y(k, j), y1 = Y(k + 1, j);
          Y(k, j) = (c * y0 - b * y1) / det;
          Y(k + 1, j) = (a * y1 - b * y0) / det;
        }
        k += 2;
      } else {
        Y.row(k) /= d(k);
        k += 1;
      }
    }
  }

  void bind(double* storage) { new (&M) Eigen::Map<Mat>(storage, n, n); }

  // L's nonzeros column by column (below the diagonal, the next block's coupled rows included,
  // rows in final positions), for the solves: the front's storage is free for the next block
  IVec colptr, ri;
  std::vector<double> lv;
  IVec swap_kk, swap_kp, g;  // the interchange at each pivot (-1: none), and the map above
  int k0 = 0;  // the first pivot of the dense rest (dense_tail; ns: none)
  Mat Ld;      // L's columns [k0, ns) on the rows [k0, n), dense (unit lower triangle on top)

  // Forward half of a solve: y[0, ns) <- D^{-1} L11^{-1} P^T x and y[ns, n) <- -L21 L11^{-1} P^T x
  // (to be added to the next block's coupled rows)
  void forward(const Eigen::Ref<const Vec>& x, Vec& y) const {
    y.setZero(n);
    for (int i = 0; i < ns; ++i) y(i) = x(perm[i]);
    for (int k = 0; k < k0; ++k) {
      const double yk = y(k);
      if (yk == 0.0) continue;
      for (int t = colptr[k]; t < colptr[k + 1]; ++t) y(ri[t]) -= lv[t] * yk;
    }
    const int t = ns - k0;
    Ld.topRows(t).triangularView<Eigen::UnitLower>().solveInPlace(y.segment(k0, t));
    y.tail(n - ns).noalias() -= Ld.bottomRows(n - ns) * y.segment(k0, t);
    auto head = y.head(ns);
    apply_dinv(head);
  }
  // Backward half: y[ns, n) holds the next block's solution at the coupled rows on entry;
  // x <- P L11^{-T} (y[0, ns) - L21^T y[ns, n))
  void backward(Eigen::Ref<Vec> x, Vec& y) const {
    const int t = ns - k0;
    y.segment(k0, t).noalias() -= Ld.bottomRows(n - ns).transpose() * y.tail(n - ns);
    Ld.topRows(t).triangularView<Eigen::UnitLower>().transpose().solveInPlace(y.segment(k0, t));
    for (int k = k0 - 1; k >= 0; --k) {
      double acc = y(k);
      for (int t = colptr[k]; t < colptr[k + 1]; ++t) acc -= lv[t] * y(ri[t]);
      y(k) = acc;
    }
    for (int i = 0; i < ns; ++i) x(perm[i]) = y(i);
  }
};

struct Block {
  int start = 0, size = 0;
  DenseLdl ldl;
  IVec rows;  // local indices in the next block that couple with this one (below the block in its front)
  Vec y;      // a solve's work vector over the front
};

// Breadth-first levels over the non-slack primal variables [0, p): the order sorts by (level,
// index), levels counted from a pseudo-peripheral start (George-Liu), component after component.
IVec primal_levels(int p, const std::vector<std::vector<int>>& adj, const IVec& slack_row) {
  std::vector<std::vector<int>> nb(p);
  for (int i = 0; i < p; ++i) {
    if (slack_row[i] >= 0) continue;
    for (int j : adj[i]) {
      if (j < p) {
        if (slack_row[j] < 0) nb[i].push_back(j);
      } else {
        for (int k : adj[j])
          if (k < p && k != i && slack_row[k] < 0) nb[i].push_back(k);
      }
    }
    std::sort(nb[i].begin(), nb[i].end());
    nb[i].erase(std::unique(nb[i].begin(), nb[i].end()), nb[i].end());
  }
  IVec level(p, -1), comp_mark(p, 0), queue;
  queue.reserve(p);
  auto bfs = [&](int start, IVec& dist, const IVec& members) {
    for (int v : members) dist[v] = -1;
    queue.clear();
    queue.push_back(start);
    dist[start] = 0;
    for (size_t h = 0; h < queue.size(); ++h) {
      const int v = queue[h];
      for (int w : nb[v])
        if (dist[w] < 0) {
          dist[w] = dist[v] + 1;
          queue.push_back(w);
        }
    }
    return queue.back();
  };
  IVec dist(p, -1), result;
  int offset = 0;
  for (int s0 = 0; s0 < p; ++s0) {
    if (slack_row[s0] >= 0 || comp_mark[s0]) continue;
    // the component
    IVec members;
    {
      IVec tmp(p, -1);
      bfs(s0, tmp, IVec());
      members = queue;
      for (int v : members) comp_mark[v] = 1;
    }
    int start = s0, ecc = -1;
    for (int round = 0; round < 4; ++round) {
      const int far = bfs(start, dist, members);
      // among the last level, the variable of least degree
      int best = far;
      for (int v : members)
        if (dist[v] == dist[far] && nb[v].size() < nb[best].size()) best = v;
      if (dist[far] <= ecc) break;
      ecc = dist[far];
      start = best;
    }
    bfs(start, dist, members);
    std::sort(members.begin(), members.end(), [&](int a, int b) { return dist[a] != dist[b] ? dist[a] < dist[b] : a < b; });
    for (int v : members) level[v] = offset + dist[v];
    offset += ecc + 2;
    result.insert(result.end(), members.begin(), members.end());
  }
  return result;
}

// An owning pointer copied deeply (a Solver is copied from the analyses kept by pattern).
template <class T>
struct DeepPtr : std::unique_ptr<T> {
  DeepPtr() = default;
  DeepPtr(DeepPtr&&) noexcept = default;
  DeepPtr& operator=(DeepPtr&&) noexcept = default;
  DeepPtr(const DeepPtr& o) : std::unique_ptr<T>(o ? std::make_unique<T>(*o) : nullptr) {}
  DeepPtr& operator=(const DeepPtr&) = delete;
};

struct Solver {
  int n = 0, nz = 0;
  IVec order;  // position -> index
  IVec pos;    // index -> position
  std::vector<Block> blocks;
  std::vector<std::vector<std::pair<int, int>>> by_block;  // per block: (triplet, offset in its front)
  int max_front = 0;
  IVec tri_i, tri_j;      // the triplets' rows and columns (0-based)
  std::vector<double> sc; // the equilibration, per index
  std::vector<double> workspace[2];  // the fronts of two consecutive blocks
  Mat panel;                         // DenseLdl::dense_tail's scratch
  std::vector<int> block_of;  // position -> block
  Vec rhs;
  int negative = 0;
  bool singular = false;
  int max_block = 0;
  const void* ikeep = nullptr;
  DeepPtr<pairstep::PairSolver> pair;  // the pair-step recursion, when the structure fits
  bool pair_used = false;                       // the last factorisation is the pair step's
  long pair_factors = 0, block_factors = 0;     // counts (riccati_pair_stats)
  std::thread::id owner;  // the thread whose IPOPT solve analysed it (riccati_release_thread)
  bool released = false;  // its factor freed: its IPOPT solve has returned

  // A fill-reducing order inside block b (minimum degree): the block's front holds its own
  // couplings, the previous block's Schur complement (dense on the block's rows that couple with
  // the previous block) and the rows of the next block it couples with, which stay last. The
  // pivots that create the least fill go first; ties keep the breadth-first order. Measured (the
  // dumped matrices' patterns, the front's symbolic updates): the UR5 window's 54 M multiply-adds
  // per factorisation fall to 26 M, arm26's 2.1 M to 1.0 M.
  void order_block(int b, const std::vector<std::vector<int>>& adj) {
    const Block& B = blocks[b];
    const int s = B.size;
    IVec outer;  // the next block's rows coupled with this one (positions): front indices s, s + 1, ...
    for (int i = 0; i < s; ++i)
      for (int j : adj[order[B.start + i]])
        if (block_of[pos[j]] == b + 1) outer.push_back(pos[j]);
    std::sort(outer.begin(), outer.end());
    outer.erase(std::unique(outer.begin(), outer.end()), outer.end());
    // the front's graph as bit rows (the updates are unions of rows), degrees among the rows
    // not eliminated yet
    const int f = s + static_cast<int>(outer.size()), nw = (f + 63) / 64;
    std::vector<std::uint64_t> g(static_cast<size_t>(f) * nw, 0), alive(nw, ~std::uint64_t{0}), nb(nw);
    auto row = [&](int i) { return g.data() + static_cast<size_t>(i) * nw; };
    auto bit = [](int i) { return std::uint64_t{1} << (i & 63); };
    auto link = [&](int i, int j) {
      if (i == j) return;
      row(i)[j >> 6] |= bit(j);
      row(j)[i >> 6] |= bit(i);
    };
    auto degree = [&](int i) {
      int c = 0;
      for (int w = 0; w < nw; ++w) c += __builtin_popcountll(row(i)[w] & alive[w]);
      return c;
    };
    IVec in;  // the rows that receive the previous block's (dense) Schur complement
    for (int i = 0; i < s; ++i) {
      bool coupled = false;
      for (int j : adj[order[B.start + i]]) {
        const int q = pos[j], bj = block_of[q];
        if (bj == b) link(i, q - B.start);
        else if (bj == b + 1) link(i, s + static_cast<int>(std::lower_bound(outer.begin(), outer.end(), q) - outer.begin()));
        else if (bj == b - 1) coupled = true;
      }
      if (coupled) in.push_back(i);
    }
    for (size_t a = 0; a < in.size(); ++a)
      for (size_t c = a + 1; c < in.size(); ++c) link(in[a], in[c]);
    IVec deg(s), result;
    for (int i = 0; i < s; ++i) deg[i] = degree(i);
    for (int step = 0; step < s; ++step) {
      int v = -1;
      for (int i = 0; i < s; ++i)
        if ((alive[i >> 6] & bit(i)) && (v < 0 || deg[i] < deg[v])) v = i;
      alive[v >> 6] &= ~bit(v);
      result.push_back(order[B.start + v]);
      for (int w = 0; w < nw; ++w) nb[w] = row(v)[w] & alive[w];
      // v's neighbours become a clique (the front's rows keep their rows: they are not pivots)
      for (int w = 0; w < nw; ++w)
        for (std::uint64_t m = nb[w]; m != 0; m &= m - 1) {
          const int a = w * 64 + __builtin_ctzll(m);
          if (a >= s) break;
          std::uint64_t* r = row(a);
          for (int t = 0; t < nw; ++t) r[t] |= nb[t];
          r[a >> 6] &= ~bit(a);
          deg[a] = degree(a);
        }
    }
    std::copy(result.begin(), result.end(), order.begin() + B.start);
  }

  // Returns 0 or an MA27-style error code.
  int analyse(int n_, int nz_, const int* irn, const int* jcn) {
    n = n_;
    nz = nz_;
    std::vector<std::vector<int>> adj(n);
    for (int k = 0; k < nz; ++k) {
      const int i = irn[k] - 1, j = jcn[k] - 1;
      if (i < 0 || j < 0 || i >= n || j >= n) return 1;  // MA27: index out of range (warning 1)
      if (i != j) {
        adj[i].push_back(j);
        adj[j].push_back(i);
      }
    }
    for (auto& a : adj) {
      std::sort(a.begin(), a.end());
      a.erase(std::unique(a.begin(), a.end()), a.end());
    }
    // constraint rows: the trailing set with no coupling among itself
    int p = 0;
    for (int i = 0; i < n; ++i)
      for (int j : adj[i])
        if (j > i) p = std::max(p, i + 1);
    // slacks: primal indices coupled with exactly one row
    IVec slack_row(n, -1);
    for (int i = 0; i < p; ++i)
      if (adj[i].size() == 1 && adj[i][0] >= p) slack_row[i] = adj[i][0];
    // rows after the last non-slack primal they touch (-1: none)
    std::vector<std::vector<int>> rows_after(p + 1);
    std::vector<std::vector<int>> slacks_of(n);
    for (int i = 0; i < p; ++i)
      if (slack_row[i] >= 0) slacks_of[slack_row[i]].push_back(i);
    IVec primal_order = primal_levels(p, adj, slack_row);
    IVec rank(p, -1);
    for (size_t t = 0; t < primal_order.size(); ++t) rank[primal_order[t]] = static_cast<int>(t);
    for (int r = p; r < n; ++r) {
      int last = -1;
      for (int j : adj[r])
        if (j < p && slack_row[j] < 0) last = std::max(last, rank[j]);
      rows_after[last + 1].push_back(r);
    }
    // primal order: breadth-first levels of the primal graph (Hessian couplings and variables
    // sharing a row) from a pseudo-peripheral variable. In a multiple-shooting OCP the levels are
    // the stages, whatever the NLP's variable order (states of all nodes, then controls, ...).
    order.clear();
    IVec natural;  // positions where a block may start
    auto emit_rows = [&](const IVec& rows) {
      for (int r : rows) {
        order.push_back(r);
        for (int s : slacks_of[r]) order.push_back(s);
      }
    };
    emit_rows(rows_after[0]);
    bool after_row = !rows_after[0].empty();
    natural.push_back(0);
    for (size_t t = 0; t < primal_order.size(); ++t) {
      if (after_row) natural.push_back(static_cast<int>(order.size()));
      order.push_back(primal_order[t]);
      emit_rows(rows_after[t + 1]);
      after_row = !rows_after[t + 1].empty();
    }
    if (static_cast<int>(order.size()) != n) return -1;
    natural.push_back(n);
    natural.erase(std::unique(natural.begin(), natural.end()), natural.end());
    pos.assign(n, 0);
    for (int q = 0; q < n; ++q) pos[order[q]] = q;
    IVec far(n, 0);
    for (int q = 0; q < n; ++q) {
      far[q] = q;
      for (int j : adj[order[q]]) far[q] = std::max(far[q], pos[j]);
    }
    // blocks: natural boundaries, merged so that each block couples with the next only
    IVec starts{0};
    {
      size_t nb = 1;
      int end = natural[nb];
      while (true) {
        const int start = starts.back();
        int reach = start;
        for (int q = start; q < end; ++q) reach = std::max(reach, far[q]);
        if (end >= n) break;
        starts.push_back(end);
        // next block ends at the first natural boundary beyond both its start and this reach
        while (nb < natural.size() && natural[nb] <= std::max(reach, end)) ++nb;
        end = nb < natural.size() ? natural[nb] : n;
      }
    }
    // a block that reaches beyond the next one can still happen when the next block's own end
    // was fixed by the previous reach only; check and merge until clean
    for (bool changed = true; changed;) {
      changed = false;
      block_of.assign(n, 0);
      for (size_t b = 0; b < starts.size(); ++b) {
        const int e = b + 1 < starts.size() ? starts[b + 1] : n;
        for (int q = starts[b]; q < e; ++q) block_of[q] = static_cast<int>(b);
      }
      for (size_t b = 0; b + 1 < starts.size() && !changed; ++b) {
        const int e = starts[b + 1];
        int reach_block = static_cast<int>(b);
        for (int q = starts[b]; q < e; ++q) reach_block = std::max(reach_block, block_of[far[q]]);
        if (reach_block > static_cast<int>(b) + 1) {
          starts.erase(starts.begin() + b + 2, starts.begin() + reach_block + 1);
          changed = true;
        }
      }
    }
    const int nb = static_cast<int>(starts.size());
    blocks.assign(nb, Block());
    max_block = 0;
    for (int b = 0; b < nb; ++b) {
      blocks[b].start = starts[b];
      blocks[b].size = (b + 1 < nb ? starts[b + 1] : n) - starts[b];
      max_block = std::max(max_block, blocks[b].size);
    }
    if (max_block > MAX_BLOCK) return -2;
    for (int b = 0; b < nb; ++b) order_block(b, adj);
    for (int q = 0; q < n; ++q) pos[order[q]] = q;
    // coupling rows of each block in the next one
    for (int b = 0; b + 1 < nb; ++b) {
      Block& B = blocks[b];
      std::vector<char> mark(blocks[b + 1].size, 0);
      for (int q = B.start; q < B.start + B.size; ++q)
        for (int j : adj[order[q]]) {
          const int pj = pos[j];
          if (block_of[pj] == b + 1) mark[pj - blocks[b + 1].start] = 1;
        }
      B.rows.clear();
      for (int r = 0; r < blocks[b + 1].size; ++r)
        if (mark[r]) B.rows.push_back(r);
    }
    max_front = 0;
    for (auto& B : blocks) {
      B.ldl.ns = B.size;
      B.ldl.n = B.size + static_cast<int>(B.rows.size());
      max_front = std::max(max_front, B.ldl.n);
    }
    // the two front workspaces are allocated at the first block factorisation (factor): a copy
    // from the analyses kept by pattern stays small, and the pair step never needs them
    // where each triplet goes
    by_block.assign(nb, {});
    for (int k = 0; k < nz; ++k) {
      int qi = pos[irn[k] - 1], qj = pos[jcn[k] - 1];
      if (qi < qj) std::swap(qi, qj);  // qi >= qj: lower triangle in block order
      const int bi = block_of[qi], bj = block_of[qj];
      if (bi == bj) {
        const Block& B = blocks[bi];
        const int li = qi - B.start, lj = qj - B.start;  // li >= lj: the lower triangle, all the factorisation reads
        by_block[bi].push_back({k, li + lj * B.ldl.n});
      } else {
        const Block& B = blocks[bj];
        const int lr = qi - blocks[bi].start;
        const auto it = std::lower_bound(B.rows.begin(), B.rows.end(), lr);
        const int li = B.size + static_cast<int>(it - B.rows.begin()), lj = qj - B.start;
        by_block[bj].push_back({k, li + lj * B.ldl.n});
      }
    }
    tri_i.resize(nz);
    tri_j.resize(nz);
    for (int k = 0; k < nz; ++k) {
      tri_i[k] = irn[k] - 1;
      tri_j[k] = jcn[k] - 1;
    }
    rhs.resize(n);
    return 0;
  }

  // A block's front: bound to a workspace, zeroed (lower triangle) and assembled from its
  // triplets just before it is factorised. Two workspaces, so that a block's Schur complement goes
  // into the next block's front; the factor is kept apart (DenseLdl::keep, DenseLdl::Ld).
  void assemble(int b, const double* a) {
    DenseLdl& F = blocks[b].ldl;
    F.bind(workspace[b % 2].data());
    F.M.triangularView<Eigen::Lower>().setZero();
    double* base = F.M.data();
    for (const auto& [k, off] : by_block[b]) base[off] += a[k] * sc[tri_i[k]] * sc[tri_j[k]];
  }

  // Symmetric equilibration S A S, S = diag(1 / sqrt(largest |entry| of each row)): a congruence,
  // so the inertia is A's; IPOPT's matrices carry bound terms and regularisations many orders of
  // magnitude apart (MUMPS scales internally too).
  void equilibrate(const double* a) {
    sc.assign(n, 0.0);
    for (int k = 0; k < nz; ++k) {
      const double v = std::abs(a[k]);
      sc[tri_i[k]] = std::max(sc[tri_i[k]], v);
      sc[tri_j[k]] = std::max(sc[tri_j[k]], v);
    }
    for (double& v : sc) v = (v > 0.0 && std::isfinite(v)) ? 1.0 / std::sqrt(v) : 1.0;
  }

  void factor(const double* a) {
    pair_used = pair && pair->factor(a);
    if (pair_used) {
      ++pair_factors;
      negative = pair->negative;
      singular = false;
      return;
    }
    ++block_factors;
    if (workspace[0].empty())
      for (auto& w : workspace) w.assign(static_cast<size_t>(max_front) * max_front, 0.0);
    equilibrate(a);
    // zero pivots only, as MA27 and MUMPS (IPOPT's settings) report singularity: a threshold
    // relative to the largest entry would call every matrix singular once IPOPT's bound terms
    // or its regularisation grow large (measured: arm26's 15th iteration, perturbations to 1e20)
    const double tiny = std::numeric_limits<double>::min();
    negative = 0;
    singular = false;
    const int nb = static_cast<int>(blocks.size());
    if (nb > 0) assemble(0, a);
    for (int b = 0; b < nb; ++b) {
      Block& B = blocks[b];
      B.ldl.factor(tiny, panel);
      if (B.ldl.singular) {
        singular = true;
        return;
      }
      negative += B.ldl.negative;
      if (b + 1 < nb) {
        assemble(b + 1, a);
        const int s = B.size, r = static_cast<int>(B.rows.size());
        auto& N = blocks[b + 1].ldl.M;
        for (int j = 0; j < r; ++j)
          for (int i = j; i < r; ++i) N(B.rows[i], B.rows[j]) += B.ldl.M(s + i, s + j);  // rows ascending: lower
      }
    }
  }

  void solve(double* x) {
    if (pair_used) {
      pair->solve(x);
      return;
    }
    for (int q = 0; q < n; ++q) rhs(q) = x[order[q]] * sc[order[q]];
    const int nb = static_cast<int>(blocks.size());
    for (int b = 0; b < nb; ++b) {
      Block& B = blocks[b];
      B.ldl.forward(rhs.segment(B.start, B.size), B.y);
      const int s1 = b + 1 < nb ? blocks[b + 1].start : 0;
      for (size_t i = 0; i < B.rows.size(); ++i) rhs(s1 + B.rows[i]) += B.y(B.size + static_cast<int>(i));
    }
    for (int b = nb - 1; b >= 0; --b) {
      Block& B = blocks[b];
      const int s1 = b + 1 < nb ? blocks[b + 1].start : 0;
      for (size_t i = 0; i < B.rows.size(); ++i) B.y(B.size + static_cast<int>(i)) = rhs(s1 + B.rows[i]);
      B.ldl.backward(rhs.segment(B.start, B.size), B.y);
    }
    for (int q = 0; q < n; ++q) x[order[q]] = rhs(q) * sc[order[q]];
  }
};

std::mutex registry_mutex;
std::vector<std::unique_ptr<Solver>> registry;  // handle = index + 1

Solver* lookup(int handle) {
  std::lock_guard<std::mutex> lock(registry_mutex);
  if (handle < 1 || handle > static_cast<int>(registry.size())) return nullptr;
  return registry[handle - 1].get();
}

// Analyses kept by pattern. IPOPT analyses the pattern again at every optimisation, and a
// closed loop's re-plans, a sliding run's windows and a sweep's runs hand over the same pattern
// each time: a pattern met before (the same n, triplets and pair-step switch, compared in full)
// gets a copy of its analysed solver, never factorised, instead of a new analysis.
// A closed loop that re-plans K times per cycle meets K patterns in turn (the task's targets fall
// on other nodes of each window: 10 on arm26 re-planning every 0.1 s), and a least-recently-used
// cache smaller than that cycle never hits. So the cache holds up to ANALYSES patterns and
// ANALYSIS_ENTRIES KKT entries in all (an analysed solver takes about 63 bytes per entry, measured
// on the arm26 window: 2.1 MB for 32,684 entries; so about 66 MB at most), and always the newest.
struct Analysis {
  bool pair_on = false;
  std::unique_ptr<Solver> solver;  // analysed, never factorised; its triplets are the pattern
};
constexpr size_t ANALYSES = 64;                       // patterns kept, the most recently used last
constexpr size_t ANALYSIS_ENTRIES = size_t{1} << 20;  // their KKT entries, in all
std::mutex analyses_mutex;
std::vector<Analysis> analyses;
std::atomic<long> analyses_made{0};  // fresh analyses (patterns not found), riccati_analyses_made

bool same_pattern(const Analysis& a, int n, int nz, const int* irn, const int* icn, bool pair_on) {
  const Solver& s = *a.solver;
  if (s.n != n || s.nz != nz || a.pair_on != pair_on) return false;
  for (int k = 0; k < nz; ++k)  // the solver keeps them 0-based, IPOPT hands them 1-based
    if (s.tri_i[k] != irn[k] - 1 || s.tri_j[k] != icn[k] - 1) return false;
  return true;
}

std::unique_ptr<Solver> analysed_copy(int n, int nz, const int* irn, const int* icn, bool pair_on) {
  std::lock_guard<std::mutex> lock(analyses_mutex);
  for (size_t k = 0; k < analyses.size(); ++k) {
    if (!same_pattern(analyses[k], n, nz, irn, icn, pair_on)) continue;
    std::rotate(analyses.begin() + k, analyses.begin() + k + 1, analyses.end());
    return std::make_unique<Solver>(*analyses.back().solver);
  }
  return nullptr;
}

void remember_analysis(bool pair_on, const Solver& s) {
  Analysis a;
  a.pair_on = pair_on;
  a.solver = std::make_unique<Solver>(s);
  std::lock_guard<std::mutex> lock(analyses_mutex);
  analyses.push_back(std::move(a));
  size_t entries = 0;
  for (const Analysis& k : analyses) entries += static_cast<size_t>(k.solver->nz);
  while (analyses.size() > 1 && (analyses.size() > ANALYSES || entries > ANALYSIS_ENTRIES)) {
    entries -= static_cast<size_t>(analyses.front().solver->nz);
    analyses.erase(analyses.begin());
  }
}

}  // namespace

#define RICCATI_EXPORT __attribute__((visibility("default")))

extern "C" {

RICCATI_EXPORT void ma27id_(int* icntl, double* cntl) {
  for (int i = 0; i < 30; ++i) icntl[i] = 0;
  for (int i = 0; i < 5; ++i) cntl[i] = 0.0;
  cntl[0] = 0.1;
}

RICCATI_EXPORT void ma27ad_(int* N, int* NZ, const int* IRN, const int* ICN, int* IW, int* LIW, int* IKEEP, int* IW1, int* NSTEPS,
             int* IFLAG, int* ICNTL, double* CNTL, int* INFO, double* OPS) {
  (void)IW; (void)LIW; (void)IW1; (void)IFLAG; (void)ICNTL; (void)CNTL;
  for (int i = 0; i < 20; ++i) INFO[i] = 0;
  *OPS = 0.0;
  *NSTEPS = 1;
  // the pair step first, where the pattern fits (FATIGUE_PIN_RICCATI_PAIR=0: the block LDL^T only)
  const char* use_pair = std::getenv("FATIGUE_PIN_RICCATI_PAIR");
  const bool pair_on = !(use_pair && std::strcmp(use_pair, "0") == 0);
  std::unique_ptr<Solver> solver = analysed_copy(*N, *NZ, IRN, ICN, pair_on);
  if (!solver) {
    solver = std::make_unique<Solver>();
    const int rc = solver->analyse(*N, *NZ, IRN, ICN);
    if (rc != 0) {
      INFO[0] = rc > 0 ? -rc : -100 + rc;
      INFO[1] = solver->max_block;
      return;
    }
    if (pair_on) {
      solver->pair.reset(new pairstep::PairSolver());
      if (!solver->pair->analyse(*N, *NZ, IRN, ICN)) solver->pair.reset();
    }
    remember_analysis(pair_on, *solver);
    ++analyses_made;
  }
  solver->ikeep = IKEEP;
  solver->owner = std::this_thread::get_id();
  int handle;
  {
    std::lock_guard<std::mutex> lock(registry_mutex);
    // a solver whose IKEEP array is handed back again is being replaced
    for (auto& s : registry)
      if (s && s->ikeep == IKEEP) s.reset();
    registry.push_back(std::move(solver));
    handle = static_cast<int>(registry.size());
    // IPOPT analyses again at every optimisation (a new IKEEP each time) and never says when an
    // instance is gone: keep the newest KEEP solvers (one per IPOPT solve that can be under way)
    if (handle > KEEP) registry[handle - 1 - KEEP].reset();
  }
  if (*N >= 2) {
    IKEEP[0] = MAGIC;
    IKEEP[1] = handle;
  }
  INFO[4] = std::max(*NZ, 1);   // real workspace wanted (IPOPT only copies the values there)
  INFO[5] = 16;                 // integer workspace wanted (the handle)
}

RICCATI_EXPORT void ma27bd_(int* N, int* NZ, const int* IRN, const int* ICN, double* A, int* LA, int* IW, int* LIW, int* IKEEP,
             int* NSTEPS, int* MAXFRT, int* IW1, int* ICNTL, double* CNTL, int* INFO) {
  (void)N; (void)NZ; (void)IRN; (void)ICN; (void)LA; (void)IW1; (void)ICNTL; (void)CNTL;
  for (int i = 0; i < 20; ++i) INFO[i] = 0;
  *NSTEPS = 1;
  *MAXFRT = 1;
  Solver* s = (*N >= 2 && IKEEP[0] == MAGIC) ? lookup(IKEEP[1]) : nullptr;
  if (!s || s->released || *LIW < 2) {
    INFO[0] = -1;
    return;
  }
  IW[0] = MAGIC;
  IW[1] = IKEEP[1];
  s->factor(A);
  if (s->singular) {
    INFO[0] = 3;
    INFO[1] = *N - 1;  // rank (unknown; MA27 reports the rank found so far)
    INFO[14] = s->negative;
    return;
  }
  INFO[14] = s->negative;
}

RICCATI_EXPORT void ma27cd_(int* N, double* A, int* LA, int* IW, int* LIW, double* W, int* MAXFRT, double* RHS, int* IW1, int* NSTEPS,
             int* ICNTL, int* INFO) {
  (void)N; (void)A; (void)LA; (void)LIW; (void)W; (void)MAXFRT; (void)IW1; (void)NSTEPS; (void)ICNTL;
  for (int i = 0; i < 20; ++i) INFO[i] = 0;
  Solver* s = IW[0] == MAGIC ? lookup(IW[1]) : nullptr;
  if (!s || s->released) {
    INFO[0] = -1;
    return;
  }
  s->solve(RHS);
}

// Analysis only (for the Python side's structure check): the largest dense block the pattern
// gives, or -1 when the pattern cannot be ordered.
RICCATI_EXPORT int riccati_max_block(int n, int nz, const int* irn, const int* jcn, int* nblocks) {
  Solver s;
  const int rc = s.analyse(n, nz, irn, jcn);
  *nblocks = static_cast<int>(s.blocks.size());
  if (rc == -1) return -1;
  return s.max_block;
}

// Analysis only: the pair step's stage count on this pattern (0: the structure does not fit and
// every factorisation uses the block LDL^T).
RICCATI_EXPORT int riccati_pair_stages(int n, int nz, const int* irn, const int* jcn) {
  pairstep::PairSolver p;
  return p.analyse(n, nz, irn, jcn) ? p.nstages : 0;
}

// Frees the factors of every solver the calling thread analysed: the caller's IPOPT solves have
// returned (IPOPT never says when an instance is gone, and KEEP live UR5 factors hold about 10 MB
// each). A freed solver keeps its counts and refuses to factorise or solve (INFO(1) = -1). Solvers
// of other threads, whose solves may be under way, are left alone. Returns the number freed.
RICCATI_EXPORT int riccati_release_thread() {
  const std::thread::id me = std::this_thread::get_id();
  std::lock_guard<std::mutex> lock(registry_mutex);
  int freed = 0;
  for (auto& s : registry) {
    if (!s || s->released || s->owner != me) continue;
    auto stub = std::make_unique<Solver>();
    stub->pair_factors = s->pair_factors;
    stub->block_factors = s->block_factors;
    stub->ikeep = s->ikeep;
    stub->owner = me;
    stub->released = true;
    s = std::move(stub);
    ++freed;
  }
  return freed;
}

// Fresh analyses made in this process (a pattern not found among those kept; tests, benchmarks).
RICCATI_EXPORT long riccati_analyses_made() { return analyses_made.load(); }

// Factorisations made by each method by the newest solver (the last analysis: tests, benchmarks).
RICCATI_EXPORT void riccati_pair_counts(long* pair, long* block) {
  std::lock_guard<std::mutex> lock(registry_mutex);
  *pair = 0;
  *block = 0;
  if (!registry.empty() && registry.back()) {
    *pair = registry.back()->pair_factors;
    *block = registry.back()->block_factors;
  }
}

}  // extern "C"
