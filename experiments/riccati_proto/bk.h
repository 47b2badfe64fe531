// Partial Bunch-Kaufman LDL^T of a dense symmetric front (lower triangle read and updated; the
// upper triangle is left stale, in place): pivots only among
// the first m indices; the trailing (n-m) block becomes the Schur complement. Rank-1/2 updates loop
// over the pivot column's nonzeros (slacks and their rows are 1x1 pivots touching a few entries).
#pragma once
#include <Eigen/Dense>
#include <cmath>
#include <vector>
struct PartialBK {
  int n = 0, m = 0, neg = 0, pos = 0; bool singular = false;
  std::vector<int> swp;   // swp[k]: index swapped with k (or with k+1 for a 2x2 at k) before step k
  std::vector<int> piv2;  // 1 if step k starts a 2x2 pivot
  std::vector<double> dinv;  // 1x1: 1/d at k; 2x2: inverse entries a,b,c at k,k+1 (stored in dinv[k], dinv[k+1], off[k])
  std::vector<double> off;
  std::vector<int> nz; std::vector<double> l0v, l1v;
  bool blocked = getenv("UNBLOCKED") == nullptr;  // default: rest rows of the dense pivots by one triangular solve + product (README)
  Eigen::MatrixXd X; int k0 = 0;
  std::vector<int> cptr, cend, cidx;  // per step: the column's nonzero rows below the pivot block if it was sparse (cptr[k] < 0: dense)
  // symmetric interchange of i and j reading and writing the lower triangle only (the upper is stale)
  static void swap_sym(Eigen::MatrixXd& K, int i, int j) {
    if (i == j) return;
    if (i > j) std::swap(i, j);
    const int n = K.rows();
    std::swap(K(i, i), K(j, j));
    for (int c = 0; c < i; ++c) std::swap(K(i, c), K(j, c));
    for (int c = i + 1; c < j; ++c) std::swap(K(c, i), K(j, c));
    for (int r = j + 1; r < n; ++r) std::swap(K(r, i), K(r, j));
  }
  static double low(const Eigen::MatrixXd& K, int i, int j) { return i >= j ? K(i, j) : K(j, i); }
  void factor(Eigen::MatrixXd& K, int m_) {
    n = K.rows(); m = m_; neg = pos = 0; singular = false;
    swp.assign(m, -1); piv2.assign(m, 0); dinv.assign(m, 0); off.assign(m, 0); cptr.assign(m, -1); cend.assign(m, -1); cidx.clear();
    const double alpha = (1 + std::sqrt(17.0)) / 8;
    // BLOCKED: pivots taken before the first dense column update all n rows (sparse, cheap); from the
    // first dense pivot on (k0), updates stay within the candidates and the rest rows are done at the end.
    int nu = n; k0 = m;
    int k = 0;
    while (k < m) {
      double akk = std::abs(K(k, k)); int imax = -1; double colmax = 0;
      for (int i = k + 1; i < m; ++i) { double v = std::abs(K(i, k)); if (v > colmax) { colmax = v; imax = i; } }
      int kind = 1, p = k;
      if (akk >= alpha * colmax) { p = k; }
      else {
        double rowmax = 0;
        for (int j = k; j < m; ++j) if (j != imax) rowmax = std::max(rowmax, std::abs(low(K, imax, j)));
        if (akk * rowmax >= alpha * colmax * colmax) p = k;
        else if (std::abs(K(imax, imax)) >= alpha * rowmax) p = imax;
        else { kind = 2; p = imax; }
      }
      if (kind == 1) {
        swp[k] = p; swap_sym(K, k, p);
        double d = K(k, k);
        if (d == 0 || !std::isfinite(d)) { singular = true; return; }
        (d < 0 ? neg : pos)++;
        double di = 1 / d; dinv[k] = di;
        if (blocked && nu == n) { int c = 0; for (int i = k + 1; i < m; ++i) c += K(i, k) != 0; if (c * 2 > m - k - 1) { nu = m; k0 = k; } }
        nz.clear(); for (int i = k + 1; i < nu; ++i) if (K(i, k) != 0) nz.push_back(i);
        int r = nu - k - 1;
        if ((int)nz.size() * 2 > r) {
          // lower triangle only: column j of the trailing block from its diagonal down
          for (int j = k + 1; j < nu; ++j) {
            const double lj = K(j, k) * di;
            if (lj != 0) K.col(j).segment(j, nu - j).noalias() -= lj * K.col(k).segment(j, nu - j);
          }
          K.col(k).segment(k + 1, r) *= di;
        } else {
          cptr[k] = 0;  // sparse: its row list is taken at the end (later interchanges move rows)
          for (size_t t = 0; t < nz.size(); ++t) { int a = nz[t]; double la = K(a, k) * di; for (size_t u = t; u < nz.size(); ++u) K(nz[u], a) -= la * K(nz[u], k); }
          for (int a : nz) { K(a, k) *= di; }
        }
        ++k;
      } else {
        swp[k] = p; piv2[k] = 1; swap_sym(K, k + 1, p);
        double a = K(k, k), b = K(k + 1, k), c = K(k + 1, k + 1), det = a * c - b * b;
        if (det == 0) { singular = true; return; }
        if (det < 0) { ++neg; ++pos; } else if (a + c < 0) neg += 2; else pos += 2;
        double ia = c / det, ib = -b / det, ic = a / det;
        dinv[k] = ia; off[k] = ib; dinv[k + 1] = ic;
        if (blocked && nu == n) { int c = 0; for (int i = k + 2; i < m; ++i) c += K(i, k) != 0 || K(i, k + 1) != 0; if (c * 2 > m - k - 2) { nu = m; k0 = k; } }
        nz.clear(); for (int i = k + 2; i < nu; ++i) if (K(i, k) != 0 || K(i, k + 1) != 0) nz.push_back(i);
        int r = nu - k - 2;
        if ((int)nz.size() * 2 > r) {
          Eigen::MatrixXd W = K.block(k + 2, k, r, 2);
          Eigen::Matrix2d Di; Di << ia, ib, ib, ic;
          Eigen::MatrixXd Lw = W * Di;
          for (int j = 0; j < r; ++j) { const double a0 = Lw(j, 0), a1 = Lw(j, 1); K.col(k + 2 + j).segment(k + 2 + j, r - j) -= a0 * W.col(0).tail(r - j) + a1 * W.col(1).tail(r - j); }
          K.block(k + 2, k, r, 2) = Lw;
        } else {
        l0v.resize(nz.size()); l1v.resize(nz.size());
        for (size_t t = 0; t < nz.size(); ++t) { double u = K(nz[t], k), v = K(nz[t], k + 1); l0v[t] = u * ia + v * ib; l1v[t] = u * ib + v * ic; }
        for (size_t t = 0; t < nz.size(); ++t) { int r = nz[t]; for (size_t u = t; u < nz.size(); ++u) { int s = nz[u]; K(s, r) -= l0v[t] * K(s, k) + l1v[t] * K(s, k + 1); } }
        for (size_t t = 0; t < nz.size(); ++t) { K(nz[t], k) = l0v[t]; K(nz[t], k + 1) = l1v[t]; }
        }
        if (blocked) K(k + 1, k) = 0;  // unit lower L with 2x2 identity blocks for the triangular solve
        k += 2;
      }
    }
    if (blocked && n > m && k0 < m) {
      // rest rows of the deferred pivots k0..m at once: X = K_rl P^T L^{-T}, L_rl = X D^{-1}, S = K_rr - L_rl X^T (lower)
      const int r = n - m, w = m - k0;
      auto Lmm = K.block(k0, k0, w, w).triangularView<Eigen::UnitLower>();
      X = K.block(m, k0, r, w);
      Lmm.transpose().solveInPlace<Eigen::OnTheRight>(X);
      auto Lr = K.block(m, k0, r, w);
      for (int q = 0; q < w;) {
        const int g = q + k0;
        if (!piv2[g]) { Lr.col(q) = X.col(q) * dinv[g]; ++q; }
        else { Lr.col(q) = X.col(q) * dinv[g] + X.col(q + 1) * off[g]; Lr.col(q + 1) = X.col(q) * off[g] + X.col(q + 1) * dinv[g + 1]; q += 2; }
      }
      K.bottomRightCorner(r, r).triangularView<Eigen::Lower>() -= Lr * X.transpose();
    }
    build_lists(K);
  }
  void build_lists(const Eigen::MatrixXd& K) {
    cidx.clear();
    for (int k = 0; k < m; ++k) if (cptr[k] >= 0) {
      cptr[k] = cidx.size();
      for (int i = k + 1; i < n; ++i) if (K(i, k) != 0) cidx.push_back(i);
      cend[k] = cidx.size();
    }
  }
  // forward: apply swaps and L^{-1} to front vector y (length n); then y[0..m) *= D^{-1}
  template <class V> void forward(V& y) const {
    for (int k = 0; k < m;) { if (!piv2[k]) { std::swap(y[k], y[swp[k]]); ++k; } else { std::swap(y[k + 1], y[swp[k]]); k += 2; } }
    for (int k = 0; k < m;) {
      if (!piv2[k]) {
        double yk = y[k];
        if (yk != 0) {
          if (cptr[k] >= 0) { int e = cend[k]; for (int t = cptr[k]; t < e; ++t) y[cidx[t]] -= L(cidx[t], k) * yk; }
          else for (int i = k + 1; i < n; ++i) y[i] -= L(i, k) * yk;
        }
        ++k;
      } else {
        double y0 = y[k], y1 = y[k + 1];
        for (int i = k + 2; i < n; ++i) y[i] -= L(i, k) * y0 + L(i, k + 1) * y1;
        k += 2;
      }
    }
    for (int k = 0; k < m;) {
      if (!piv2[k]) { y[k] *= dinv[k]; ++k; }
      else { double y0 = y[k], y1 = y[k + 1]; y[k] = dinv[k] * y0 + off[k] * y1; y[k + 1] = off[k] * y0 + dinv[k + 1] * y1; k += 2; }
    }
  }
  // backward: y[m..n) hold the rest's solution; y[0..m) the forward values
  template <class V> void backward(V& y) const {
    int k = m - 1;
    while (k >= 0) {
      bool two = (k >= 1 && piv2[k - 1]);
      if (!two) {
        double s = y[k];
        if (cptr[k] >= 0) { int e = cend[k]; for (int t = cptr[k]; t < e; ++t) s -= L(cidx[t], k) * y[cidx[t]]; }
        else for (int i = k + 1; i < n; ++i) s -= L(i, k) * y[i];
        y[k] = s;
        k -= 1;
      } else {
        int j = k - 1; double s0 = y[j], s1 = y[k];
        for (int i = k + 1; i < n; ++i) { s0 -= L(i, j) * y[i]; s1 -= L(i, k) * y[i]; }
        y[j] = s0; y[k] = s1; k -= 2;
      }
    }
    std::vector<int> st; for (int k = 0; k < m;) { st.push_back(k); k += piv2[k] ? 2 : 1; }
    for (int t = st.size() - 1; t >= 0; --t) { int k = st[t]; if (!piv2[k]) std::swap(y[k], y[swp[k]]); else std::swap(y[k + 1], y[swp[k]]); }
  }
  const Eigen::MatrixXd* Kp = nullptr;
  double L(int i, int k) const { return (*Kp)(i, k); }
};
