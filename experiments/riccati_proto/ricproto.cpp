// Riccati-style stage recursion for IPOPT's augmented KKT matrix (feasibility prototype).
// Input: the harness's .pat/.valNNN files and a plan (plan.py): per index a type
// (0 local, 1 state x_k, 2 dynamics row paired with a state of the next stage), a stage, the paired variable.
// Backward over stages k = S..0:
//   local step: front [loc_k ; x_k ; J_{k-1}] (J_{k-1}: previous-stage entities coupled directly with
//     loc_k or x_k, e.g. the previous control through a control-rate cost), LDL^T of the loc block
//     (Eigen LDLT, diagonal pivoting; a congruence: its D gives the block's inertia), Schur complement on
//     [x_k ; J_{k-1}];
//   pair step: (x_k, lambda_{k-1}) with lambda_{k-1}'s coefficients on x_k diagonal (E) and zero
//     (-delta_c) diagonal on the rows: [[P, E],[E, 0]] has nx positive and nx negative eigenvalues
//     whatever P; its Schur complement on stage k-1's front is
//       Ct^T P Ct - B^T Ct - Ct^T B  (+ S_JJ on J),  Ct = E^{-1} C, B = S_xJ,
//     with C the rows' coefficients on stage k-1's front (sparse).
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <string>
#include <vector>
#include <array>
#include "bk.h"
using Mat = Eigen::MatrixXd;
using Vec = Eigen::VectorXd;
static double cpu_now() { timespec ts; clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts); return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6; }

struct Trip { int i, j; double v; };
struct Stage {
  std::vector<int> loc, xs, J, lam;  // lam: rows of this stage paired with next stage's xs (same order)
  std::vector<int> front;            // loc, xs, J (global ids)
  // assembled entries: (front pos a, front pos b, value slot), a>=b
  std::vector<std::array<int, 3>> ent;
  // C: lam row r (0..nl-1), front pos j, slot
  std::vector<std::array<int, 3>> cent;
  std::vector<int> eslot;   // slot of E_ii for lam row i
  std::vector<int> dslot;   // diagonal slots of lam rows (delta_c), -1 if none
  // numeric
  PartialBK bk;
  Mat K, Klr, S;            // K: front; Klr: loc x rest; S: Schur on rest (x ; J)
  Vec e;                    // E diagonal of lam (pairs with next stage xs)
  Mat Pn, Bn;               // next stage's S_xx and S_xJ (J = positions in this front)
  std::vector<int> Jpos;    // for next stage's J: positions in this front
  Vec yl;
};

int main(int argc, char** argv) {
  std::string base = argv[1], plan = argv[2];
  int nvals = atoi(argv[3]), reps = argc > 4 ? atoi(argv[4]) : 11;
  FILE* f = fopen((base + ".pat").c_str(), "rb");
  int N, NZ; fread(&N, 4, 1, f); fread(&NZ, 4, 1, f);
  std::vector<int> irn(NZ), jcn(NZ); fread(irn.data(), 4, NZ, f); fread(jcn.data(), 4, NZ, f); fclose(f);
  for (auto& x : irn) --x; for (auto& x : jcn) --x;
  FILE* g = fopen(plan.c_str(), "rb"); int hdr[3]; fread(hdr, 4, 3, g);
  int S = hdr[2];
  std::vector<int> typ(N), stg(N), pv(N); fread(typ.data(), 4, N, g); fread(stg.data(), 4, N, g); fread(pv.data(), 4, N, g); fclose(g);
  std::vector<Stage> st(S + 1);
  std::vector<int> pos(N, -1), pairrow(N, -1);
  for (int i = 0; i < N; ++i) {
    if (typ[i] == 0) st[stg[i]].loc.push_back(i);
    if (typ[i] == 2) { st[stg[i]].lam.push_back(i); pairrow[pv[i]] = i; }
  }
  {
    std::vector<int> deg(N, 0), nb(N, -1);
    for (int t = 0; t < NZ; ++t) if (irn[t] != jcn[t]) { deg[irn[t]]++; deg[jcn[t]]++; nb[irn[t]] = jcn[t]; nb[jcn[t]] = irn[t]; }
    int p = hdr[1];
    std::vector<int> key(N, 2);
    for (int i = 0; i < p; ++i) if (deg[i] == 1 && nb[i] >= p) { key[i] = 0; key[nb[i]] = 1; }
    for (auto& s : st) std::stable_sort(s.loc.begin(), s.loc.end(), [&](int a, int b) { return key[a] < key[b]; });
  }
  for (int k = 0; k < S; ++k) for (int r : st[k].lam) st[k + 1].xs.push_back(pv[r]);
  // stage 0: everything local; xs of stage 0 (should be none)
  for (int i = 0; i < N; ++i) if (typ[i] == 1 && stg[i] == 0) st[0].loc.push_back(i);
  // J_{k-1}: entities of stage k-1 (not lam rows) coupled directly with loc_k or xs_k
  int nonlocal = 0;
  for (int t = 0; t < NZ; ++t) {
    int a = irn[t], b = jcn[t]; if (a == b) continue;
    int sa = stg[a], sb = stg[b];
    if (sa == sb) continue;
    if (sa > sb) std::swap(a, b), std::swap(sa, sb);   // a earlier stage
    if (typ[a] == 2 && typ[b] == 1 && sb == sa + 1 && pv[a] == b) continue;  // E entry
    if (sb == sa + 1 && typ[a] != 2 && typ[b] != 2) { st[sb].J.push_back(a); continue; }
    ++nonlocal;
  }
  if (nonlocal) { printf("FALLBACK: %d entries couple non-adjacent stages or a dynamics row with a non-paired variable\n", nonlocal); return 2; }
  std::vector<int> owner(N, -1);
  for (int k = 0; k <= S; ++k) {
    auto& s = st[k];
    std::sort(s.J.begin(), s.J.end()); s.J.erase(std::unique(s.J.begin(), s.J.end()), s.J.end());
    s.front = s.loc; s.front.insert(s.front.end(), s.xs.begin(), s.xs.end());
    for (int i : s.front) owner[i] = k;
  }
  for (int k = 0; k <= S; ++k) for (size_t q = 0; q < st[k].front.size(); ++q) pos[st[k].front[q]] = q;
  for (int k = 0; k < S; ++k) for (size_t q = 0; q < st[k].lam.size(); ++q) pos[st[k].lam[q]] = q;
  for (int k = 1; k <= S; ++k) for (int j : st[k].J) {
    if (owner[j] != k - 1) { printf("FALLBACK: J entity %d not in previous front\n", j); return 2; }
    st[k - 1].Jpos.push_back(pos[j]);
  }
  // per-front J positions in stage k's own front: after loc, xs
  auto fpos = [&](int k, int i) -> int {  // position of global i in stage k's extended front
    if (owner[i] == k) return pos[i];
    auto& J = st[k].J; int q = std::lower_bound(J.begin(), J.end(), i) - J.begin();
    return st[k].front.size() + q;
  };
  for (auto& s : st) { s.eslot.assign(s.lam.size(), -1); s.dslot.assign(s.lam.size(), -1); }
  for (int t = 0; t < NZ; ++t) {
    int a = irn[t], b = jcn[t];
    if (a == b) {
      if (typ[a] == 2) st[stg[a]].dslot[pos[a]] = t;
      else { int k = owner[a]; st[k].ent.push_back({pos[a], pos[a], t}); }
      continue;
    }
    if (typ[a] == 2 || typ[b] == 2) {
      if (typ[b] == 2) std::swap(a, b);
      if (typ[b] == 2) { printf("FALLBACK: row-row entry\n"); return 2; }
      int k = stg[a];
      if (stg[b] == k + 1) { st[k].eslot[pos[a]] = t; continue; }
      st[k].cent.push_back({pos[a], pos[b], t});
      continue;
    }
    int k = std::max(stg[a], stg[b]);
    int pa = fpos(k, a), pb = fpos(k, b);
    st[k].ent.push_back({std::max(pa, pb), std::min(pa, pb), t});
  }
  for (auto& s : st) for (int x : s.eslot) if (x < 0) { printf("FALLBACK: missing E entry\n"); return 2; }

  if (getenv("SIZES")) { long c = 0, f = 0; for (int k = 0; k < S; ++k) { c += st[k].cent.size(); f += st[k].front.size() + st[k].J.size(); } printf("nnz(C) total %ld, mean %.1f per stage; mean front %.1f\n", c, (double)c / S, (double)f / S); }
  Mat T, G, Tt; Vec fv, gv, a, l, u, zJ;  // work buffers reused across stages and factorisations
  double tf_all = 0; std::vector<double> tfm, tsm;
  int worst_fb = 0;
  for (int v = 0; v < nvals; ++v) {
    char fn[600]; snprintf(fn, 600, "%s.val%03d", base.c_str(), v);
    FILE* h = fopen(fn, "rb"); if (!h) break;
    std::vector<double> A0(NZ), A(NZ), sc(N); fread(A0.data(), 8, NZ, h); fclose(h);
    const bool equil = !getenv("NOSCALE");
    int neg = 0; std::string fb;
    std::vector<double> tf, ts; double res = 0;
    std::vector<double> x(N);
    for (int rep = 0; rep < reps; ++rep) {
      double t0 = cpu_now();
      neg = 0; fb.clear();
      // equilibration S A S, S = diag(1/sqrt(max |row|)) (as the library): a congruence
      std::fill(sc.begin(), sc.end(), 0.0);
      for (int t = 0; t < NZ; ++t) { double w = std::abs(A0[t]); sc[irn[t]] = std::max(sc[irn[t]], w); sc[jcn[t]] = std::max(sc[jcn[t]], w); }
      for (int i = 0; i < N; ++i) sc[i] = (equil && sc[i] > 0) ? 1 / std::sqrt(sc[i]) : 1.0;
      for (int t = 0; t < NZ; ++t) A[t] = A0[t] * sc[irn[t]] * sc[jcn[t]];
      // ---------------- factor ----------------
      for (int k = S; k >= 0; --k) {
        auto& s = st[k];
        int nf = s.front.size(), nJ = s.J.size(), n = nf + nJ;
        int m = (k == 0) ? n : (int)s.loc.size();
        // lower triangle only (bk.h reads nothing above the diagonal)
        if (s.K.rows() != n) s.K.resize(n, n);
        s.K.triangularView<Eigen::Lower>().setZero();
        for (auto& q : s.ent) s.K(q[0], q[1]) += A[q[2]];
        if (k < S) {
          // pair step of (x_{k+1}, lam_k): contributions to this front
          int nl = s.lam.size();
          for (int i = 0; i < nl; ++i) if (s.dslot[i] >= 0 && A[s.dslot[i]] != 0) fb = "delta_c != 0";
          s.e.resize(nl);
          for (int i = 0; i < nl; ++i) s.e[i] = A[s.eslot[i]];
          const Mat& P = st[k + 1].S;  // (nx+nJ') over next stage's [xs; J]; J ⊂ this front
          int nx = nl;
          T.setZero(nx, n);     // P Ct
          G.setZero(st[k + 1].J.size(), n);  // B^T Ct
          for (auto& q : s.cent) {
            double c = A[q[2]] / s.e[q[0]];
            T.col(q[1]) += P.col(q[0]).head(nx) * c;
            if (G.rows()) G.col(q[1]) += P.row(q[0]).tail(G.rows()).transpose() * c;
          }
          // K(lower) += Ct^T T  (full symmetric update done in full then use lower)
          Tt = T.transpose();
          for (auto& q : s.cent) {
            double c = A[q[2]] / s.e[q[0]];
            s.K.col(q[1]).tail(n - q[1]) += c * Tt.col(q[0]).tail(n - q[1]);
          }
          const auto& Jp = s.Jpos;
          for (size_t a = 0; a < Jp.size(); ++a) {
            s.K.row(Jp[a]) -= G.row(a);
            s.K.col(Jp[a]) -= G.row(a).transpose();
            for (size_t b = 0; b < Jp.size(); ++b) s.K(Jp[a], Jp[b]) += P(nx + a, nx + b);
          }
          neg += nx;
        }
        Mat K0; if (getenv("DBG") && rep == 0 && v == 0) K0 = s.K;
        s.bk.factor(s.K, m); s.bk.Kp = &s.K;
        if (getenv("DBG") && rep == 0 && v == 0 && m < n && k % 30 == 1) {
          Mat Sref = K0.bottomRightCorner(n - m, n - m) - K0.bottomLeftCorner(n - m, m) * K0.topLeftCorner(m, m).inverse() * K0.topRightCorner(m, n - m);
          Vec y0 = Vec::Random(n), yr = K0.fullPivLu().solve(y0), yy = y0; s.bk.forward(yy);
          double e1 = (yy.tail(n-m) - s.K.bottomRightCorner(n-m,n-m) * yr.tail(n-m)).norm();
          yy.tail(n-m) = yr.tail(n-m); s.bk.backward(yy);
          printf("stage %d m %d n %d Serr %g asym %g fwd %g back %g\n", k, m, n, (Sref - s.K.bottomRightCorner(n - m, n - m)).norm() / Sref.norm(), (K0 - K0.transpose()).norm(), e1, (yy-yr).norm()/yr.norm());
        }
        if (s.bk.singular) fb = "zero pivot";
        neg += s.bk.neg;
        if (m < n) { s.S = s.K.bottomRightCorner(n - m, n - m); s.S.triangularView<Eigen::StrictlyUpper>() = s.S.transpose(); }
        if (getenv("DBG3") && rep == 0 && v == atoi(getenv("DBG3")) && m > 0) {  // where is the largest |L| of this stage
          std::vector<int> perm(n); for (int i = 0; i < n; ++i) perm[i] = i;
          for (int q = 0; q < m;) { if (!s.bk.piv2[q]) { std::swap(perm[q], perm[s.bk.swp[q]]); ++q; } else { std::swap(perm[q + 1], perm[s.bk.swp[q]]); q += 2; } }
          int bi = 0, bk_ = 0; double bl = 0;
          for (int c = 0; c < m; ++c) for (int i = c + 1; i < n; ++i) if (std::abs(s.K(i, c)) > bl) { bl = std::abs(s.K(i, c)); bi = i; bk_ = c; }
          auto gid = [&](int q) { return q < nf ? s.front[q] : s.J[q - nf]; };
          int gi = gid(perm[bi]), gk = gid(perm[bk_]);
          if (bl > 1e3) printf("v%d stage %d |L| %.2e at row %d (%s, global %d typ %d %s) col %d (global %d typ %d %s, 2x2 %d)\n", v, k, bl, bi, bi < m ? "cand" : "rest", gi, typ[gi], gi >= hdr[1] ? "row" : "var", bk_, gk, typ[gk], gk >= hdr[1] ? "row" : "var", (bk_ > 0 && s.bk.piv2[bk_ - 1]) || s.bk.piv2[bk_]);
        }
        if (getenv("DBG2") && rep == 0 && (getenv("DBGALL") || k % 15 == 0 || k > S - 3)) {
          double lmax = m > 0 ? s.K.leftCols(m).triangularView<Eigen::StrictlyLower>().toDenseMatrix().cwiseAbs().maxCoeff() : 0;
          printf("v%d stage %d m %d n %d |S|max %.2e |L|max %.2e e min %.2e max %.2e\n", v, k, m, n, m < n ? s.S.cwiseAbs().maxCoeff() : 0.0, lmax,
                 s.e.size() ? s.e.cwiseAbs().minCoeff() : 0.0, s.e.size() ? s.e.cwiseAbs().maxCoeff() : 0.0);
        }
      }
      double t1 = cpu_now();
      // ---------------- solve ----------------
      std::vector<double> b(N); for (int i = 0; i < N; ++i) b[i] = std::sin(1.0 + i);
      const int nref = getenv("REFINE") ? atoi(getenv("REFINE")) : 0;
      std::vector<double> xacc(N, 0.0), rhs = b;
      double t2 = 0;
      for (int it = 0; it <= nref; ++it) {
      if (it > 0) { std::vector<double> ax(N, 0.0); for (int t = 0; t < NZ; ++t) { int i = irn[t], j = jcn[t]; ax[i] += A0[t] * xacc[j]; if (i != j) ax[j] += A0[t] * xacc[i]; } for (int i = 0; i < N; ++i) rhs[i] = b[i] - ax[i]; }
      std::vector<double> r = rhs;
      if (it == 0) t2 = cpu_now();
      for (int i = 0; i < N; ++i) r[i] *= sc[i];
      for (int k = S; k >= 0; --k) {
        auto& s = st[k];
        int nf = s.front.size(), nJ = s.J.size(), n = nf + nJ;
        int m = (k == 0) ? n : (int)s.loc.size();
        s.yl.resize(n);
        for (int i = 0; i < n; ++i) s.yl[i] = r[i < nf ? s.front[i] : s.J[i - nf]];
        s.bk.forward(s.yl);
        for (int i = m; i < n; ++i) r[i < nf ? s.front[i] : s.J[i - nf]] = s.yl[i];
        if (k > 0) {  // pair (x_k, lam_{k-1}): rhs of stage k-1's front -= B^T a + C^T l
          auto& p = st[k - 1];
          int nx = p.lam.size();
          fv.resize(nx); gv.resize(nx);
          for (int i = 0; i < nx; ++i) { fv[i] = r[s.xs[i]]; gv[i] = r[p.lam[i]]; }
          a = gv.cwiseQuotient(p.e);
          l = (fv - s.S.topLeftCorner(nx, nx) * a).cwiseQuotient(p.e);
          for (auto& q : p.cent) r[p.front[q[1]]] -= A[q[2]] * l[q[0]];
          if (nJ) { u = s.S.block(0, nx, nx, nJ).transpose() * a; for (int j = 0; j < nJ; ++j) r[s.J[j]] -= u[j]; }
        }
      }
      // back substitution
      for (int k = 0; k <= S; ++k) {
        auto& s = st[k];
        int nf = s.front.size(), nJ = s.J.size(), n = nf + nJ;
        int m = (k == 0) ? n : (int)s.loc.size();
        if (k > 0) {
          auto& p = st[k - 1];
          int nx = p.lam.size();
          fv.resize(nx); gv.resize(nx);
          for (int i = 0; i < nx; ++i) { fv[i] = r[s.xs[i]]; gv[i] = r[p.lam[i]]; }
          for (auto& q : p.cent) gv[q[0]] -= A[q[2]] * x[p.front[q[1]]];
          if (nJ) { zJ.resize(nJ); for (int j = 0; j < nJ; ++j) zJ[j] = x[s.J[j]]; fv -= s.S.block(0, nx, nx, nJ) * zJ; }
          a = gv.cwiseQuotient(p.e);
          l = (fv - s.S.topLeftCorner(nx, nx) * a).cwiseQuotient(p.e);
          for (int i = 0; i < nx; ++i) { x[s.xs[i]] = a[i]; x[p.lam[i]] = l[i]; }
        }
        for (int i = m; i < n; ++i) s.yl[i] = x[i < nf ? s.front[i] : s.J[i - nf]];
        s.bk.backward(s.yl);
        for (int i = 0; i < m; ++i) x[s.front[i]] = s.yl[i];
      }
      for (int i = 0; i < N; ++i) { x[i] *= sc[i]; xacc[i] += x[i]; }
      if (it == 0 && nref == 0) break; }
      x = xacc;
      double t3 = cpu_now();
      tf.push_back(t1 - t0); ts.push_back(t3 - t2);
      if (rep == 0) {
        std::vector<double> ax(N, 0.0); double bmax = 0;
        for (int t = 0; t < NZ; ++t) { int i = irn[t], j = jcn[t]; ax[i] += A0[t] * x[j]; if (i != j) ax[j] += A0[t] * x[i]; }
        res = 0; for (int i = 0; i < N; ++i) { res = std::max(res, std::abs(ax[i] - b[i])); bmax = std::max(bmax, std::abs(b[i])); }
        res /= bmax;
      }
    }
    std::sort(tf.begin(), tf.end()); std::sort(ts.begin(), ts.end());
    printf("val%03d neg %d relres %.2e factor %.3f ms solve %.3f ms %s\n", v, neg, res, tf[tf.size() / 2], ts[ts.size() / 2], fb.empty() ? "" : ("FALLBACK: " + fb).c_str());
    tfm.push_back(tf[tf.size() / 2]); tsm.push_back(ts[ts.size() / 2]);
  }
  std::sort(tfm.begin(), tfm.end()); std::sort(tsm.begin(), tsm.end());
  printf("MEDIAN factor %.3f ms solve %.3f ms over %zu matrices\n", tfm[tfm.size() / 2], tsm[tsm.size() / 2], tfm.size());
}
