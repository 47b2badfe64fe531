// The pair-step recursion of src/riccati_kkt.cpp (included there: one translation unit, one
// library). Tried first at every factorisation when the analysis found the structure; any guard
// that trips makes that factorisation use the block LDL^T instead (riccati_kkt.cpp, Solver).
//
// Structure (found from the pattern alone, PairSolver::analyse):
//   - constraint rows: the trailing indices with no coupling among themselves; slacks: primal
//     indices coupled with one row and nothing else (their rows: inequality rows);
//   - dynamics rows: the transcription declares the states of all nodes before the controls
//     (casadi Opti: X (nx, N + 1) column-major, then U) and IPOPT keeps the order, so a dynamics
//     row's partner (the next state it defines) is the highest variable it touches below the
//     first control B. B is the lowest variable that is the highest of two or more equality
//     rows (a control enters several rows of its node; with interleaved stages no variable is,
//     B = all, and the partner is the row's highest variable). When several rows name one
//     variable, the row reaching the lowest index (back into the previous stage) gets it;
//     (identical to experiments/riccati_proto/plan.py's value-based pairing on both dumps);
//   - stages: a state's stage is 1 + the largest stage of the states its row touches (longest
//     path); a dynamics row belongs to its partner's stage - 1; every other variable takes the
//     earliest stage of the dynamics rows touching it, every other row the latest stage of its
//     variables, a slack its row's stage;
//   - checked (else no pair path, the block LDL^T only): every entry is within a stage, between a
//     dynamics row and its partner (E), or couples a stage's non-dynamics entities with the
//     previous stage's (the interface J: control-difference costs); no row-row entry; every stage
//     but the first has its rows' partners as states.
// Recursion (backward, k = S..0, on the equilibrated matrix S A S):
//   local step: the front [loc_k ; x_k ; J_{k-1}], lower triangle only, partial Bunch-Kaufman
//     with pivots among loc_k (slacks, inequality rows, then the rest): its trailing block is
//     the Schur complement S_k on [x_k ; J_{k-1}], symmetrised (upper := lower) before use;
//   pair step of (x_{k+1}, lambda_k): with E = diag(lambda_k's coefficients on x_{k+1}) and
//     delta_c = 0 on these rows, [[P, E],[E, 0]] has nx positive and nx negative eigenvalues;
//     its Schur complement onto stage k's front is Ct^T P Ct - B^T Ct - Ct^T B (+ S_JJ on J),
//     Ct = E^{-1} C (C: the rows' coefficients on stage k's front), P = S_xx, B = S_xJ.
//   Inertia (Sylvester): the local blocks' negative pivots + nx per pair.
// Guards at factor time (false: the caller factorises with the block LDL^T): a non-finite value,
// E zero or non-finite, a nonzero diagonal on a dynamics row (delta_c), a local pivot column
// that is zero or cancelled (below CANCEL = 1e-10 times its diagonal's magnitude before the
// updates: a local block singular in exact arithmetic, seen in tests/ocp/test_task_ends.py with
// round-off pivots of 1e-17), a non-finite Schur block. Not handled (falls back): delta_c > 0.
#pragma once
#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <vector>

namespace pairstep {

using Mat = Eigen::MatrixXd;
using Vec = Eigen::VectorXd;
using IVec = std::vector<int>;

// Partial Bunch-Kaufman LDL^T of a dense symmetric front, reading and updating the lower
// triangle only (the upper is stale): pivots among the first m indices; the trailing (n - m)
// block becomes the Schur complement. Sparse pivot columns (slacks, their rows) update only
// their nonzero rows; from the first dense pivot column on, updates stay within the candidates
// and the rest rows are done at the end by one triangular solve and one product.
#ifndef RICCATI_PAIR_CANCEL
#define RICCATI_PAIR_CANCEL 1e-10
#endif
constexpr double CANCEL = RICCATI_PAIR_CANCEL;

struct PartialBK {
  int n = 0, m = 0, neg = 0;
  bool singular = false;
  IVec swp, piv2;            // swp[k]: index swapped with k (k + 1 for a 2x2 at k); piv2[k]: 2x2 starts at k
  std::vector<double> dinv, off;  // 1x1: 1/d at k; 2x2: inverse entries dinv[k], off[k], dinv[k + 1]
  IVec nz, cptr, cend, cidx;  // per step: the column's nonzero rows if it was sparse (cptr < 0: dense)
  std::vector<double> l0v, l1v;
  Mat X, W2, Lw;
  int k0 = 0;
  const Mat* Kp = nullptr;  // the factor's columns, kept outside the front (PairSolver::keep_factor)

  static void swap_sym(Eigen::Ref<Mat> K, int i, int j) {
    if (i == j) return;
    if (i > j) std::swap(i, j);
    const int n = static_cast<int>(K.rows());
    std::swap(K(i, i), K(j, j));
    for (int c = 0; c < i; ++c) std::swap(K(i, c), K(j, c));
    for (int c = i + 1; c < j; ++c) std::swap(K(c, i), K(j, c));
    for (int r = j + 1; r < n; ++r) std::swap(K(r, i), K(r, j));
  }
  static double low(const Eigen::Ref<Mat>& K, int i, int j) { return i >= j ? K(i, j) : K(j, i); }

  // A pivot step is refused (singular = true) when its candidate column is no larger than CANCEL
  // times the magnitude its diagonal had before cancellation (mag: |the assembled diagonal| + the
  // |updates| it received): restricted to the local block, a pivot that is zero in exact
  // arithmetic comes out as round-off, not as zero. A small pivot formed without cancellation
  // (a row after its slack: -c^2 / Sigma_s) passes.
  std::vector<double> mag;
  void factor(Eigen::Ref<Mat> K, int m_) {
    n = static_cast<int>(K.rows());
    m = m_;
    neg = 0;
    singular = false;
    swp.assign(m, -1);
    piv2.assign(m, 0);
    dinv.assign(m, 0);
    off.assign(m, 0);
    cptr.assign(m, -1);
    cend.assign(m, -1);
    const double alpha = (1 + std::sqrt(17.0)) / 8;
    int nu = n;
    k0 = m;
    mag.resize(m);
    for (int i = 0; i < m; ++i) mag[i] = std::abs(K(i, i));
    int k = 0;
    while (k < m) {
      const double akk = std::abs(K(k, k));
      int imax = -1;
      double colmax = 0;
      for (int i = k + 1; i < m; ++i) {
        const double v = std::abs(K(i, k));
        if (v > colmax) {
          colmax = v;
          imax = i;
        }
      }
      const double big = std::max(akk, colmax);
      if (!(big > std::numeric_limits<double>::min() && big > CANCEL * mag[k])) {
        singular = true;
        return;
      }
      int kind = 1, p = k;
      if (akk < alpha * colmax) {
        double rowmax = 0;
        for (int j = k; j < m; ++j)
          if (j != imax) rowmax = std::max(rowmax, std::abs(low(K, imax, j)));
        if (akk * rowmax >= alpha * colmax * colmax) p = k;
        else if (std::abs(K(imax, imax)) >= alpha * rowmax) p = imax;
        else {
          kind = 2;
          p = imax;
        }
      }
      if (kind == 1) {
        swp[k] = p;
        swap_sym(K, k, p);
        std::swap(mag[k], mag[p]);
        const double d = K(k, k);
        if (d == 0 || !std::isfinite(d)) {
          singular = true;
          return;
        }
        if (d < 0) ++neg;
        const double di = 1 / d;
        dinv[k] = di;
        if (nu == n) {
          int c = 0;
          for (int i = k + 1; i < m; ++i) c += K(i, k) != 0;
          if (c * 2 > m - k - 1) {
            nu = m;
            k0 = k;
          }
        }
        nz.clear();
        for (int i = k + 1; i < nu; ++i)
          if (K(i, k) != 0) nz.push_back(i);
        const int r = nu - k - 1;
        if (static_cast<int>(nz.size()) * 2 > r) {
          const double* ck = &K(0, k);
          for (int j = k + 1; j < nu; ++j) {
            const double lj = K(j, k) * di;
            if (lj != 0) {
              if (j < m) mag[j] += std::abs(lj * K(j, k));
              double* cj = &K(0, j);  // plain loop: the columns are short (the candidates)
              for (int i = j; i < nu; ++i) cj[i] -= lj * ck[i];
            }
          }
          K.col(k).segment(k + 1, r) *= di;
        } else {
          cptr[k] = 0;  // sparse: its row list is taken at the end (later interchanges move rows)
          for (size_t t = 0; t < nz.size(); ++t) {
            const int a = nz[t];
            const double la = K(a, k) * di;
            if (a < m) mag[a] += std::abs(la * K(a, k));
            for (size_t u = t; u < nz.size(); ++u) K(nz[u], a) -= la * K(nz[u], k);
          }
          for (int a : nz) K(a, k) *= di;
        }
        ++k;
      } else {
        swp[k] = p;
        piv2[k] = 1;
        swap_sym(K, k + 1, p);
        std::swap(mag[k + 1], mag[p]);
        const double a = K(k, k), b = K(k + 1, k), c = K(k + 1, k + 1), det = a * c - b * b;
        if (det == 0 || !std::isfinite(det)) {
          singular = true;
          return;
        }
        if (det < 0) ++neg;
        else if (a + c < 0) neg += 2;
        const double ia = c / det, ib = -b / det, ic = a / det;
        dinv[k] = ia;
        off[k] = ib;
        dinv[k + 1] = ic;
        if (nu == n) {
          int cnt = 0;
          for (int i = k + 2; i < m; ++i) cnt += K(i, k) != 0 || K(i, k + 1) != 0;
          if (cnt * 2 > m - k - 2) {
            nu = m;
            k0 = k;
          }
        }
        nz.clear();
        for (int i = k + 2; i < nu; ++i)
          if (K(i, k) != 0 || K(i, k + 1) != 0) nz.push_back(i);
        const int r = nu - k - 2;
        if (static_cast<int>(nz.size()) * 2 > r) {
          W2 = K.block(k + 2, k, r, 2);
          Eigen::Matrix2d Di;
          Di << ia, ib, ib, ic;
          Lw = W2 * Di;
          const double* w0 = W2.data();
          const double* w1 = W2.data() + r;
          for (int j = 0; j < r; ++j) {
            const double a0 = Lw(j, 0), a1 = Lw(j, 1);
            if (k + 2 + j < m) mag[k + 2 + j] += std::abs(a0 * W2(j, 0)) + std::abs(a1 * W2(j, 1));
            double* cj = &K(k + 2, k + 2 + j);  // rows k + 2 + i, i >= j
            for (int i = j; i < r; ++i) cj[i] -= a0 * w0[i] + a1 * w1[i];
          }
          K.block(k + 2, k, r, 2) = Lw;
        } else {
          l0v.resize(nz.size());
          l1v.resize(nz.size());
          for (size_t t = 0; t < nz.size(); ++t) {
            const double u = K(nz[t], k), v = K(nz[t], k + 1);
            l0v[t] = u * ia + v * ib;
            l1v[t] = u * ib + v * ic;
          }
          for (size_t t = 0; t < nz.size(); ++t) {
            const int rr = nz[t];
            if (rr < m) mag[rr] += std::abs(l0v[t] * K(rr, k)) + std::abs(l1v[t] * K(rr, k + 1));
            for (size_t u = t; u < nz.size(); ++u) {
              const int s = nz[u];
              K(s, rr) -= l0v[t] * K(s, k) + l1v[t] * K(s, k + 1);
            }
          }
          for (size_t t = 0; t < nz.size(); ++t) {
            K(nz[t], k) = l0v[t];
            K(nz[t], k + 1) = l1v[t];
          }
        }
        K(k + 1, k) = 0;  // unit lower L with identity 2x2 blocks (the triangular solve below)
        k += 2;
      }
    }
    if (n > m && k0 < m) {
      // rest rows of the deferred pivots k0..m: X = K_rl L^{-T}, L_rl = X D^{-1}, S -= L_rl X^T (lower)
      const int r = n - m, w = m - k0;
      X = K.block(m, k0, r, w);
      K.block(k0, k0, w, w).triangularView<Eigen::UnitLower>().transpose().solveInPlace<Eigen::OnTheRight>(X);
      auto Lr = K.block(m, k0, r, w);
      for (int q = 0; q < w;) {
        const int g = q + k0;
        if (!piv2[g]) {
          Lr.col(q) = X.col(q) * dinv[g];
          ++q;
        } else {
          Lr.col(q) = X.col(q) * dinv[g] + X.col(q + 1) * off[g];
          Lr.col(q + 1) = X.col(q) * off[g] + X.col(q + 1) * dinv[g + 1];
          q += 2;
        }
      }
      K.bottomRightCorner(r, r).triangularView<Eigen::Lower>() -= Lr * X.transpose();
    }
    cidx.clear();
    for (int c = 0; c < m; ++c)
      if (cptr[c] >= 0) {
        cptr[c] = static_cast<int>(cidx.size());
        for (int i = c + 1; i < n; ++i)
          if (K(i, c) != 0) cidx.push_back(i);
        cend[c] = static_cast<int>(cidx.size());
      }
  }
  double L(int i, int k) const { return (*Kp)(i, k); }
  // interchanges and L^{-1} on the front vector y (length n), then y[0..m) *= D^{-1}
  void forward(Vec& y) const {
    for (int k = 0; k < m;) {
      if (!piv2[k]) {
        std::swap(y[k], y[swp[k]]);
        ++k;
      } else {
        std::swap(y[k + 1], y[swp[k]]);
        k += 2;
      }
    }
    for (int k = 0; k < m;) {
      if (!piv2[k]) {
        const double yk = y[k];
        if (yk != 0) {
          if (cptr[k] >= 0) {
            for (int t = cptr[k]; t < cend[k]; ++t) y[cidx[t]] -= L(cidx[t], k) * yk;
          } else {
            y.segment(k + 1, n - k - 1).noalias() -= yk * Kp->col(k).segment(k + 1, n - k - 1);
          }
        }
        ++k;
      } else {
        const double y0 = y[k], y1 = y[k + 1];
        y.segment(k + 2, n - k - 2).noalias() -= y0 * Kp->col(k).segment(k + 2, n - k - 2) + y1 * Kp->col(k + 1).segment(k + 2, n - k - 2);
        k += 2;
      }
    }
    for (int k = 0; k < m;) {
      if (!piv2[k]) {
        y[k] *= dinv[k];
        ++k;
      } else {
        const double y0 = y[k], y1 = y[k + 1];
        y[k] = dinv[k] * y0 + off[k] * y1;
        y[k + 1] = off[k] * y0 + dinv[k + 1] * y1;
        k += 2;
      }
    }
  }
  // y[m..n): the rest's solution; y[0..m): the forward values
  void backward(Vec& y) const {
    int k = m - 1;
    while (k >= 0) {
      if (!(k >= 1 && piv2[k - 1])) {
        double s = y[k];
        if (cptr[k] >= 0) {
          for (int t = cptr[k]; t < cend[k]; ++t) s -= L(cidx[t], k) * y[cidx[t]];
        } else {
          s -= Kp->col(k).segment(k + 1, n - k - 1).dot(y.segment(k + 1, n - k - 1));
        }
        y[k] = s;
        k -= 1;
      } else {
        const int j = k - 1;
        y[j] -= Kp->col(j).segment(k + 1, n - k - 1).dot(y.segment(k + 1, n - k - 1));
        y[k] -= Kp->col(k).segment(k + 1, n - k - 1).dot(y.segment(k + 1, n - k - 1));
        k -= 2;
      }
    }
    for (int k = m - 1; k >= 0; --k) {
      if (k >= 1 && piv2[k - 1]) {
        std::swap(y[k], y[swp[k - 1]]);
        --k;
      } else {
        std::swap(y[k], y[swp[k]]);
      }
    }
  }
};


struct Stage {
  IVec loc, xs, J, lam;  // lam: this stage's dynamics rows, paired with the next stage's xs (same order)
  IVec front;            // loc, xs (global ids); J follows in the extended front
  std::vector<std::array<int, 3>> ent;   // (front row, front column, triplet), row >= column
  std::vector<std::array<int, 3>> cent;  // C: (lam index, front position, triplet)
  std::vector<std::array<int, 3>> ccent;  // the same, by front position (the pair step's products)
  IVec ccol, cptr;       // C's columns (the distinct front positions it touches, ascending) and
                         // their entries' ranges in ccent
  std::vector<IVec> eslot, dslot;  // per lam row: E's triplets, its diagonal's (duplicates are summed)
  IVec Jpos;             // the next stage's J: positions in this front
  PartialBK bk;
  // The front is factorised in PairSolver's scratch F (one buffer for all stages, so it stays
  // in cache; zeroing and assembling a cold front per stage was a quarter of the factor time).
  // Kept per stage, for the solve and the next stage's pair step:
  Mat L;                 // F's first m columns: the local factor (read through bk's L(i, k))
  Mat S;                 // the Schur block on [xs; J] (F's trailing block from m), symmetric
  Mat& Sb() { return S; }
  Vec e, yl;
  int m = 0, nf = 0;
};

#ifdef RICCATI_PAIR_DEBUG
inline bool fail(int line) {
  std::fprintf(stderr, "pair analysis: no (riccati_pair.hpp:%d)\n", line);
  return false;
}
#else
inline bool fail(int) { return false; }
#endif

struct PairSolver {
  int n = 0, nz = 0, nstages = 0;
  IVec ti, tj;  // the triplets (0-based)
  std::vector<Stage> st;
  std::vector<double> sc, av;  // equilibration; the equilibrated values
  std::vector<double> fbuf;  // the front being factorised (scratch, the largest front's size)
  Mat Tc, Tct;               // the pair step's products
  std::vector<double> cv, w;  // Ct's values; one column of Ct^T P Ct
  Vec fv, gv, a, l, u, zJ, r, x;
  int negative = 0;

  // Returns false when the structure does not fit (the block LDL^T is then the only method).
  // The structure, or false (no pair path). The first control B is found as below, lowered to
  // the first of its node's controls (widen); should that structure fail the checks, the
  // analysis is made again with B as found.
  bool analyse(int n_, int nz_, const int* irn, const int* jcn) {
    if (analyse_from(n_, nz_, irn, jcn, true)) return true;
    if (!widened) return false;  // the same B: a second analysis would repeat the first
    *this = PairSolver();
    return analyse_from(n_, nz_, irn, jcn, false);
  }

  bool widened = false;  // the analysis lowered B (analyse)

  bool analyse_from(int n_, int nz_, const int* irn, const int* jcn, bool widen) {
    n = n_;
    nz = nz_;
    ti.resize(nz);
    tj.resize(nz);
    std::vector<IVec> adj(n);
    for (int k = 0; k < nz; ++k) {
      ti[k] = irn[k] - 1;
      tj[k] = jcn[k] - 1;
      if (ti[k] < 0 || tj[k] < 0 || ti[k] >= n || tj[k] >= n) return fail(__LINE__);
      if (ti[k] != tj[k]) {
        adj[ti[k]].push_back(tj[k]);
        adj[tj[k]].push_back(ti[k]);
      }
    }
    for (auto& v : adj) {
      std::sort(v.begin(), v.end());
      v.erase(std::unique(v.begin(), v.end()), v.end());
    }
    int p = 0;
    for (int i = 0; i < n; ++i)
      for (int j : adj[i])
        if (j > i) p = std::max(p, i + 1);
    if (p == 0 || p >= n) return fail(__LINE__);
    IVec slack_row(n, -1), is_ineq(n, 0);
    for (int i = 0; i < p; ++i)
      if (adj[i].size() == 1 && adj[i][0] >= p) {
        slack_row[i] = adj[i][0];
        is_ineq[adj[i][0]] = 1;
      }
    // rows: their non-slack primals (adj is sorted, so the last is the highest)
    std::vector<IVec> rv(n);
    for (int rr = p; rr < n; ++rr)
      for (int j : adj[rr])
        if (j < p && slack_row[j] < 0) rv[rr].push_back(j);
    // The transcription declares the states of all nodes before the controls (casadi Opti:
    // X (nx, N + 1) column-major, then U), and IPOPT keeps that order: a dynamics row touches
    // the states of its node, its controls and one next state, the highest state it touches.
    // The first control B is the lowest variable that is the highest of two or more rows (a
    // control enters several rows of its node; a state is the highest of at most one row, a
    // path row on its node's states). A wrong B only gives a structure the checks below reject
    // (or another exact elimination order).
    IVec tops(p, 0);
    for (int rr = p; rr < n; ++rr)
      if (!is_ineq[rr] && !rv[rr].empty()) ++tops[rv[rr].back()];
    int B = p;
    for (int v = 0; v < p; ++v)
      if (tops[v] >= 2) {
        B = v;
        break;
      }
    // Rows that reach every control of their node (a dense input matrix: torques through the mass
    // matrix) all have their node's last control as their highest variable, which the rule above
    // then takes for B. Lowered to the node's first control: the lowest of the variables that all
    // those rows touch (the node's controls, and states) above every variable that only some of
    // them touch (their partners, the next states).
    if (widen && B < p) {
      IVec rows_b, count(p, 0);
      for (int rr = p; rr < n; ++rr)
        if (!is_ineq[rr] && !rv[rr].empty() && rv[rr].back() == B) rows_b.push_back(rr);
      for (int rr : rows_b)
        for (int v : rv[rr]) ++count[v];
      const int all = static_cast<int>(rows_b.size());
      int below = -1;  // the highest variable not touched by all of them
      for (int rr : rows_b)
        for (int v : rv[rr])
          if (count[v] < all) below = std::max(below, v);
      if (below >= 0) {
        int lowest = B;
        for (int v = below + 1; v < B; ++v)
          if (count[v] == all) {
            lowest = v;
            break;
          }
        widened = lowest != B;
        B = lowest;
      }
    }
    // a row's partner: its highest variable below B; several rows naming one variable: the row
    // reaching the lowest index (the dynamics row reaches back into the previous node)
    IVec defrow(p, -1);
    for (int rr = p; rr < n; ++rr) {
      if (is_ineq[rr] || rv[rr].size() < 2) continue;
      const auto it = std::lower_bound(rv[rr].begin(), rv[rr].end(), B);
      if (it == rv[rr].begin()) continue;
      const int v = *(it - 1);
      const int o = defrow[v];
      if (o < 0 || rv[rr].front() < rv[o].front()) defrow[v] = rr;
    }
    IVec pv(n, -1), stage(n, -1), typ(n, 0);
    for (int v = 0; v < p; ++v)
      if (defrow[v] >= 0) {
        pv[defrow[v]] = v;
        typ[v] = 1;
        typ[defrow[v]] = 2;
      }
    // states' stages by longest path (a row's other variables have lower indices)
    for (int v = 0; v < p; ++v) {
      if (typ[v] != 1) continue;
      int s = 0;
      for (int w : rv[defrow[v]])
        if (w != v && typ[w] == 1) s = std::max(s, stage[w]);
      stage[v] = s + 1;
    }
    int S = 0;
    for (int v = 0; v < p; ++v)
      if (typ[v] == 1) S = std::max(S, stage[v]);
    if (S < 2) return fail(__LINE__);
    for (int rr = p; rr < n; ++rr)
      if (typ[rr] == 2) stage[rr] = stage[pv[rr]] - 1;
    auto settle_var = [&](int v) {  // the earliest stage of the dynamics rows touching v (-1: none)
      int s = -1;
      for (int rr : adj[v])
        if (rr >= p && typ[rr] == 2) s = s < 0 ? stage[rr] : std::min(s, stage[rr]);
      return s;
    };
    for (int v = 0; v < p; ++v)
      if (typ[v] == 0 && slack_row[v] < 0) stage[v] = settle_var(v);
    for (int it = 0; it < 5; ++it) {
      for (int rr = p; rr < n; ++rr) {
        if (typ[rr] == 2) continue;
        int s = -1;
        for (int v : rv[rr])
          if (stage[v] >= 0) s = std::max(s, stage[v]);
        if (s >= 0) stage[rr] = s;
      }
      for (int v = 0; v < p; ++v) {
        if (stage[v] >= 0 || slack_row[v] >= 0) continue;
        int s = -1;
        for (int w : adj[v])
          if (stage[w] >= 0) s = s < 0 ? stage[w] : std::min(s, stage[w]);
        if (s >= 0) stage[v] = s;
      }
    }
    for (int rr = p; rr < n; ++rr)
      if (stage[rr] < 0) stage[rr] = S;
    for (int v = 0; v < p; ++v)
      if (slack_row[v] >= 0) stage[v] = stage[slack_row[v]];
    for (int i = 0; i < n; ++i)
      if (stage[i] < 0) return fail(__LINE__);
    nstages = S + 1;
    st.assign(nstages, Stage());
    IVec key(n, 2);
    for (int i = 0; i < p; ++i)
      if (slack_row[i] >= 0) {
        key[i] = 0;
        key[slack_row[i]] = 1;
      }
    for (int i = 0; i < n; ++i) {
      if (typ[i] == 0 || (typ[i] == 1 && stage[i] == 0)) st[stage[i]].loc.push_back(i);
      if (typ[i] == 2) st[stage[i]].lam.push_back(i);
    }
    for (auto& s : st) std::stable_sort(s.loc.begin(), s.loc.end(), [&](int x1, int x2) { return key[x1] < key[x2]; });
    for (int k = 0; k < S; ++k)
      for (int rr : st[k].lam) st[k + 1].xs.push_back(pv[rr]);
    // the interface J and the check that nothing else crosses stages
    for (int t = 0; t < nz; ++t) {
      int x1 = ti[t], x2 = tj[t];
      if (x1 == x2) continue;
      int s1 = stage[x1], s2 = stage[x2];
      if (typ[x1] == 2 && typ[x2] == 2) return fail(__LINE__);  // row-row
      if (s1 == s2) continue;
      if (s1 > s2) {
        std::swap(x1, x2);
        std::swap(s1, s2);
      }
      if (typ[x1] == 2 && typ[x2] == 1 && s2 == s1 + 1 && pv[x1] == x2) continue;  // E
      if (s2 == s1 + 1 && typ[x1] != 2 && typ[x2] != 2) {
        st[s2].J.push_back(x1);
        continue;
      }
      return fail(__LINE__);
    }
    IVec owner(n, -1), pos(n, -1);
    for (int k = 0; k <= S; ++k) {
      Stage& s = st[k];
      std::sort(s.J.begin(), s.J.end());
      s.J.erase(std::unique(s.J.begin(), s.J.end()), s.J.end());
      s.front = s.loc;
      s.front.insert(s.front.end(), s.xs.begin(), s.xs.end());
      s.nf = static_cast<int>(s.front.size());
      for (int i : s.front) owner[i] = k;
      s.m = k == 0 ? s.nf + static_cast<int>(s.J.size()) : static_cast<int>(s.loc.size());
    }
    if (!st[0].J.empty() || !st[0].xs.empty()) return fail(__LINE__);
    for (int k = 0; k <= S; ++k)
      for (size_t q = 0; q < st[k].front.size(); ++q) pos[st[k].front[q]] = static_cast<int>(q);
    for (int k = 0; k < S; ++k)
      for (size_t q = 0; q < st[k].lam.size(); ++q) pos[st[k].lam[q]] = static_cast<int>(q);
    for (int k = 1; k <= S; ++k)
      for (int j : st[k].J) {
        if (owner[j] != k - 1) return fail(__LINE__);
        st[k - 1].Jpos.push_back(pos[j]);
      }
    auto fpos = [&](int k, int i) -> int {
      if (owner[i] == k) return pos[i];
      const IVec& J = st[k].J;
      return st[k].nf + static_cast<int>(std::lower_bound(J.begin(), J.end(), i) - J.begin());
    };
    for (auto& s : st) {
      s.eslot.assign(s.lam.size(), IVec());
      s.dslot.assign(s.lam.size(), IVec());
    }
    for (int t = 0; t < nz; ++t) {
      int x1 = ti[t], x2 = tj[t];
      if (x1 == x2) {
        if (typ[x1] == 2) st[stage[x1]].dslot[pos[x1]].push_back(t);
        else st[owner[x1]].ent.push_back({pos[x1], pos[x1], t});
        continue;
      }
      if (typ[x1] == 2 || typ[x2] == 2) {
        if (typ[x2] == 2) std::swap(x1, x2);
        const int k = stage[x1];
        if (stage[x2] == k + 1) {
          st[k].eslot[pos[x1]].push_back(t);
          continue;
        }
        if (owner[x2] != k) return fail(__LINE__);
        st[k].cent.push_back({pos[x1], pos[x2], t});
        continue;
      }
      const int k = std::max(stage[x1], stage[x2]);
      const int pa = fpos(k, x1), pb = fpos(k, x2);
      st[k].ent.push_back({std::max(pa, pb), std::min(pa, pb), t});
    }
    for (auto& s : st)
      for (const IVec& e : s.eslot)
        if (e.empty()) return fail(__LINE__);
    for (auto& s : st) {  // C by column, for the pair step's products
      s.ccent = s.cent;
      std::stable_sort(s.ccent.begin(), s.ccent.end(), [](const std::array<int, 3>& c1, const std::array<int, 3>& c2) { return c1[1] < c2[1]; });
      s.ccol.clear();
      s.cptr.clear();
      for (size_t t = 0; t < s.ccent.size(); ++t)
        if (t == 0 || s.ccent[t][1] != s.ccent[t - 1][1]) {
          s.ccol.push_back(s.ccent[t][1]);
          s.cptr.push_back(static_cast<int>(t));
        }
      s.cptr.push_back(static_cast<int>(s.ccent.size()));
    }
    for (int k = 0; k < S; ++k)
      if (st[k].lam.size() != st[k + 1].xs.size()) return fail(__LINE__);
    r.resize(n);
    x.resize(n);
    return true;
  }

  // Returns false when a guard trips (nothing of this factorisation may then be used).
  bool factor(const double* A) {
    sc.assign(n, 0.0);
    double total = 0.0;  // non-finite if any value is
    for (int t = 0; t < nz; ++t) {
      const double w = std::abs(A[t]);
      total += w;
      sc[ti[t]] = std::max(sc[ti[t]], w);
      sc[tj[t]] = std::max(sc[tj[t]], w);
    }
    if (!std::isfinite(total)) return false;
    for (double& v : sc) v = v > 0.0 ? 1.0 / std::sqrt(v) : 1.0;
    av.resize(nz);
    for (int t = 0; t < nz; ++t) av[t] = A[t] * sc[ti[t]] * sc[tj[t]];
    negative = 0;
    const int S = nstages - 1;
    for (int k = S; k >= 0; --k) {
      Stage& s = st[k];
      const int nn = s.nf + static_cast<int>(s.J.size());
      if (fbuf.size() < static_cast<size_t>(nn) * nn) fbuf.resize(static_cast<size_t>(nn) * nn);
      Eigen::Map<Mat> K(fbuf.data(), nn, nn);
      K.triangularView<Eigen::Lower>().setZero();
      for (const auto& q : s.ent) K(q[0], q[1]) += av[q[2]];
      if (k < S) {
        const int nl = static_cast<int>(s.lam.size());
        s.e.resize(nl);
        for (int i = 0; i < nl; ++i) {
          double d = 0.0, e = 0.0;
          for (int t : s.dslot[i]) d += av[t];
          if (d != 0.0) return false;  // delta_c on a dynamics row
          for (int t : s.eslot[i]) e += av[t];
          s.e[i] = e;
          if (s.e[i] == 0 || !std::isfinite(s.e[i])) return false;
        }
        const Mat& P = st[k + 1].Sb();  // over the next stage's [xs; J]
        const int nJn = static_cast<int>(st[k + 1].J.size());
        add_ct_p_ct(s, P, K, nl, nJn);
        const IVec& Jp = s.Jpos;
        for (int a1 = 0; a1 < nJn; ++a1) {
          const int ja = Jp[a1];
          // K -= G^T e_a + e_a G (lower triangle): row ja left of the diagonal, column ja below
          // (G's columns are Ct's: zero elsewhere)
          for (size_t b = 0; b < s.ccol.size(); ++b) {
            const int c = s.ccol[b];
            const double g = Tc(nl + a1, b);
            if (c < ja) K(ja, c) -= g;
            else K(c, ja) -= c == ja ? 2 * g : g;
          }
          for (int b1 = 0; b1 < nJn; ++b1) {
            const int jb = Jp[b1];
            if (ja >= jb) K(ja, jb) += P(nl + a1, nl + b1);
          }
        }
        negative += nl;
      }
      s.bk.factor(K, s.m);
      if (s.bk.singular) return false;
      negative += s.bk.neg;
      keep_factor(s, K);
      if (s.m < nn && !s.S.allFinite()) return false;
    }
    return true;
  }

  // The pair step's products on the front K (lower triangle): K += Ct^T P_xx Ct, and
  // Tc = [P_xx; P_Jx] Ct (its rows nl.. are G = B^T Ct, which the caller subtracts on the J
  // rows). Ct is sparse (s.cent: the dynamics rows' entries on this front, over E) and its columns
  // (s.ccol) are a part of the front (UR5: 66 of 108), so both products run over its entries
  // column by column (one column of Tc or of the result stays in L1), and Tc and the result
  // are kept compressed to those columns. Plain loops: the columns are 48-66 long, too short
  // for Eigen's per-expression overhead.
  void add_ct_p_ct(const Stage& s, const Mat& P, Eigen::Map<Mat>& K, int nl, int nJn) {
    const int nS = nl + nJn, nc = static_cast<int>(s.ccol.size());
    const int ne = static_cast<int>(s.ccent.size());
    cv.resize(ne);
    for (int t = 0; t < ne; ++t) cv[t] = av[s.ccent[t][2]] / s.e[s.ccent[t][0]];
    Tc.resize(nS, nc);
    for (int a = 0; a < nc; ++a)  // Tc's column a = sum of c * P's column l over C's column
      combine(Tc.data() + static_cast<Eigen::Index>(a) * nS, nS, P.data(), nS, 0, s, a);
    Tct = Tc.topRows(nl).transpose();  // nc x nl
    w.resize(nc);
    for (int a = 0; a < nc; ++a) {  // column ccol[a] of Ct^T (P Ct), rows ccol[a..nc)
      const int len = nc - a;
      double* wp = w.data();
      combine(wp, len, Tct.data(), nc, a, s, a);
      double* kc = K.data() + static_cast<Eigen::Index>(s.ccol[a]) * K.rows();
      for (int b = 0; b < len; ++b) kc[s.ccol[a + b]] += wp[b];
    }
  }

  // out[0..len) = sum over C's column a's entries t of cv[t] * X(off + 0..len, l_t), X's column l
  // at base + l * ld. Eight rows at a time in registers: one load per multiply-add, where an axpy
  // per entry needs two loads and a store (the machine's limit, not its multiply-adds).
  void combine(double* out, int len, const double* base, Eigen::Index ld, int off, const Stage& s, int a) const {
    const int t0 = s.cptr[a], t1 = s.cptr[a + 1];
    int i0 = 0;
    for (; i0 + 8 <= len; i0 += 8) {
      double acc[8] = {0, 0, 0, 0, 0, 0, 0, 0};
      for (int t = t0; t < t1; ++t) {
        const double c = cv[t];
        const double* x = base + static_cast<Eigen::Index>(s.ccent[t][0]) * ld + off + i0;
        for (int u = 0; u < 8; ++u) acc[u] += c * x[u];
      }
      for (int u = 0; u < 8; ++u) out[i0 + u] = acc[u];
    }
    for (; i0 < len; ++i0) {
      double acc = 0;
      for (int t = t0; t < t1; ++t) acc += cv[t] * base[static_cast<Eigen::Index>(s.ccent[t][0]) * ld + off + i0];
      out[i0] = acc;
    }
  }

  // Copies what the solve and the next stage need out of the scratch front F: the local factor's
  // columns and the Schur block, symmetrised (upper := lower).
  void keep_factor(Stage& s, Eigen::Map<Mat>& F) {
    const int nn = static_cast<int>(F.rows()), m = s.m, r = nn - m;
    s.L = F.leftCols(m);
    s.bk.Kp = &s.L;
    auto Fs = F.bottomRightCorner(r, r);
    Fs.triangularView<Eigen::StrictlyUpper>() = Fs.transpose();
    s.S = Fs;
  }

  // The pair (x_k, lam_{k-1})'s right-hand side from v: fv on stage k's states, gv on stage
  // k-1's dynamics rows; returns their count.
  int pair_rhs(const Stage& s, const Stage& q, const Vec& v) {
    const int nx = static_cast<int>(q.lam.size());
    fv.resize(nx);
    gv.resize(nx);
    for (int i = 0; i < nx; ++i) {
      fv[i] = v[s.xs[i]];
      gv[i] = v[q.lam[i]];
    }
    return nx;
  }

  void solve(double* rhs) {
    for (int i = 0; i < n; ++i) r[i] = rhs[i] * sc[i];
    const int S = nstages - 1;
    for (int k = S; k >= 0; --k) {
      Stage& s = st[k];
      const int nJ = static_cast<int>(s.J.size()), nn = s.nf + nJ, m = s.m;
      s.yl.resize(nn);
      for (int i = 0; i < nn; ++i) s.yl[i] = r[i < s.nf ? s.front[i] : s.J[i - s.nf]];
      s.bk.forward(s.yl);
      for (int i = m; i < nn; ++i) r[i < s.nf ? s.front[i] : s.J[i - s.nf]] = s.yl[i];
      if (k > 0) {  // the pair (x_k, lam_{k-1}): stage k-1's right-hand side -= B^T a + C^T l
        const Stage& q = st[k - 1];
        const int nx = pair_rhs(s, q, r);
        a = gv.cwiseQuotient(q.e);
        l = (fv - s.Sb().topLeftCorner(nx, nx) * a).cwiseQuotient(q.e);
        for (const auto& c : q.cent) r[q.front[c[1]]] -= av[c[2]] * l[c[0]];
        if (nJ) {
          u = s.Sb().block(0, nx, nx, nJ).transpose() * a;
          for (int j = 0; j < nJ; ++j) r[s.J[j]] -= u[j];
        }
      }
    }
    for (int k = 0; k <= S; ++k) {
      Stage& s = st[k];
      const int nJ = static_cast<int>(s.J.size()), nn = s.nf + nJ, m = s.m;
      if (k > 0) {
        const Stage& q = st[k - 1];
        const int nx = pair_rhs(s, q, r);
        for (const auto& c : q.cent) gv[c[0]] -= av[c[2]] * x[q.front[c[1]]];
        if (nJ) {
          zJ.resize(nJ);
          for (int j = 0; j < nJ; ++j) zJ[j] = x[s.J[j]];
          fv -= s.Sb().block(0, nx, nx, nJ) * zJ;
        }
        a = gv.cwiseQuotient(q.e);
        l = (fv - s.Sb().topLeftCorner(nx, nx) * a).cwiseQuotient(q.e);
        for (int i = 0; i < nx; ++i) {
          x[s.xs[i]] = a[i];
          x[q.lam[i]] = l[i];
        }
      }
      for (int i = m; i < nn; ++i) s.yl[i] = x[i < s.nf ? s.front[i] : s.J[i - s.nf]];
      s.bk.backward(s.yl);
      for (int i = 0; i < m; ++i) x[s.front[i]] = s.yl[i];
    }
    for (int i = 0; i < n; ++i) rhs[i] = x[i] * sc[i];
  }
};

}  // namespace pairstep
