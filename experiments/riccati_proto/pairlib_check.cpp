// Checks the library's pair step (src/riccati_pair.hpp) against its block LDL^T on the dumped
// matrices (dump_shim.cpp): per matrix, the inertia (INFO(15)) and the relative residual
// max|Ax - b| / max|b| of one solve and of one solve + one refinement step (as IPOPT's
// min_refinement_steps = 1), and the CPU time of the factorisation and of one solve (medians over
// REPS repeats, the two methods alternating). Both methods are the same library loaded once; the
// method is chosen at the analysis by FATIGUE_PIN_RICCATI_PAIR (0: block LDL^T only). ONLY_PAIR=1:
// the pair step alone (profiling). AB=/path/B.so: an A/B of two builds instead, both with the pair
// step, alternating in one process (A: the first library, B: this one; columns "block" and "pair"
// then read A and B).
//
//   g++ -O2 experiments/riccati_proto/pairlib_check.cpp -o /tmp/ric2/check -ldl
//   /tmp/ric2/check fatigue_pin/libfatigue_pin_riccati.so /tmp/ric/ur5 [REPS]
#include <dlfcn.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <string>
#include <vector>

using Ad = void (*)(int*, int*, const int*, const int*, int*, int*, int*, int*, int*, int*, int*, double*, int*, double*);
using Bd = void (*)(int*, int*, const int*, const int*, double*, int*, int*, int*, int*, int*, int*, int*, int*, double*, int*);
using Cd = void (*)(int*, double*, int*, int*, int*, double*, int*, double*, int*, int*, int*, int*);
using Counts = void (*)(long*, long*);

static double cpu_ms() {
  timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}
static double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0 : v[v.size() / 2];
}

struct Method {
  int ikeep[16] = {0}, iw[16] = {0}, info[20] = {0}, icntl[30] = {0};
  double cntl[5] = {0};
};

int main(int argc, char** argv) {
  const char* other = std::getenv("AB");  // an A/B of two builds' pair steps
  Ad ad[2];
  Bd bd[2];
  Cd cd[2];
  Counts counts = nullptr;
  for (int w = 0; w < 2; ++w) {
    void* lib = dlopen(w == 1 && other ? other : argv[1], RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
      std::printf("%s\n", dlerror());
      return 1;
    }
    ad[w] = reinterpret_cast<Ad>(dlsym(lib, "ma27ad_"));
    bd[w] = reinterpret_cast<Bd>(dlsym(lib, "ma27bd_"));
    cd[w] = reinterpret_cast<Cd>(dlsym(lib, "ma27cd_"));
    counts = reinterpret_cast<Counts>(dlsym(lib, "riccati_pair_counts"));
  }
  const std::string base = argv[2];
  const int reps = argc > 3 ? std::atoi(argv[3]) : 7;
  const int only_pair = std::getenv("ONLY_PAIR") ? 1 : 0;  // profiling: the pair step alone
  FILE* f = std::fopen((base + ".pat").c_str(), "rb");
  int N, NZ;
  if (std::fread(&N, 4, 1, f) != 1 || std::fread(&NZ, 4, 1, f) != 1) return 1;
  std::vector<int> irn(NZ), jcn(NZ);
  if (std::fread(irn.data(), 4, NZ, f) != size_t(NZ) || std::fread(jcn.data(), 4, NZ, f) != size_t(NZ)) return 1;
  std::fclose(f);
  Method M[2];  // 0: block LDL^T, 1: pair step
  for (int w = 0; w < 2; ++w) {
    setenv("FATIGUE_PIN_RICCATI_PAIR", w || other ? "1" : "0", 1);
    int liw = 16, iw1[64], nsteps, iflag = 0;
    double ops;
    ad[w](&N, &NZ, irn.data(), jcn.data(), M[w].iw, &liw, M[w].ikeep, iw1, &nsteps, &iflag, M[w].icntl, M[w].cntl, M[w].info, &ops);
    if (M[w].info[0] != 0) {
      std::printf("analysis failed (method %d): %d\n", w, M[w].info[0]);
      return 1;
    }
  }
  std::vector<double> b(N), tf[2], ts[2], r1[2], r2[2];
  for (int i = 0; i < N; ++i) b[i] = std::sin(1.0 + i);
  int agree = 0, total = 0;
  std::printf("matrix   neg(block) neg(pair)  res1(block) res1(pair)  res2(block) res2(pair)  factor ms (block pair)  solve ms (block pair)\n");
  for (int v = 0;; ++v) {
    char fn[600];
    std::snprintf(fn, sizeof fn, "%s.val%03d", base.c_str(), v);
    FILE* h = std::fopen(fn, "rb");
    if (!h) break;
    std::vector<double> A(NZ);
    if (std::fread(A.data(), 8, NZ, h) != size_t(NZ)) return 1;
    std::fclose(h);
    auto resid = [&](const std::vector<double>& x, std::vector<double>& res) {
      res = b;
      for (int t = 0; t < NZ; ++t) {
        const int i = irn[t] - 1, j = jcn[t] - 1;
        res[i] -= A[t] * x[j];
        if (i != j) res[j] -= A[t] * x[i];
      }
      double m = 0, bm = 0;
      for (int i = 0; i < N; ++i) {
        m = std::max(m, std::abs(res[i]));
        bm = std::max(bm, std::abs(b[i]));
      }
      return m / bm;
    };
    int neg[2] = {0, 0}, flag[2] = {0, 0};
    double res1[2] = {0, 0}, res2[2] = {0, 0};
    std::vector<double> tfv[2], tsv[2];
    for (int rep = 0; rep < reps; ++rep)
      for (int w = only_pair; w < 2; ++w) {
        Method& m = M[w];
        std::vector<double> a = A;
        int la = NZ, liw = 16, nsteps = 1, maxfrt = 1, iw1[64];
        const double t0 = cpu_ms();
        bd[w](&N, &NZ, irn.data(), jcn.data(), a.data(), &la, m.iw, &liw, m.ikeep, &nsteps, &maxfrt, iw1, m.icntl, m.cntl, m.info);
        const double t1 = cpu_ms();
        neg[w] = m.info[14];
        flag[w] = m.info[0];
        std::vector<double> x = b, wk(N);
        const double t2 = cpu_ms();
        cd[w](&N, a.data(), &la, m.iw, &liw, wk.data(), &maxfrt, x.data(), iw1, &nsteps, m.icntl, m.info);
        const double t3 = cpu_ms();
        tfv[w].push_back(t1 - t0);
        tsv[w].push_back(t3 - t2);
        if (rep == 0) {
          std::vector<double> res;
          res1[w] = resid(x, res);
          cd[w](&N, a.data(), &la, m.iw, &liw, wk.data(), &maxfrt, res.data(), iw1, &nsteps, m.icntl, m.info);
          for (int i = 0; i < N; ++i) x[i] += res[i];
          res2[w] = resid(x, res);
        }
      }
    ++total;
    agree += neg[0] == neg[1] && flag[0] == flag[1];
    for (int w = 0; w < 2; ++w) {
      tf[w].push_back(median(tfv[w]));
      ts[w].push_back(median(tsv[w]));
      r1[w].push_back(res1[w]);
      r2[w].push_back(res2[w]);
    }
    std::printf("val%03d   %6d%s %6d%s   %.2e   %.2e    %.2e   %.2e    %.3f %.3f    %.3f %.3f\n", v, neg[0], flag[0] ? "s" : " ", neg[1],
                flag[1] ? "s" : " ", res1[0], res1[1], res2[0], res2[1], median(tfv[0]), median(tfv[1]), median(tsv[0]),
                median(tsv[1]));
  }
  long np = 0, nb = 0;
  if (counts) counts(&np, &nb);
  auto mx = [](const std::vector<double>& v) { return *std::max_element(v.begin(), v.end()); };
  std::printf("SUMMARY %s: %d matrices, inertia equal %d/%d; factorisations pair %ld block %ld\n", base.c_str(), total, agree, total, np, nb);
  std::printf("  residual one solve   median/max: block %.1e/%.1e  pair %.1e/%.1e\n", median(r1[0]), mx(r1[0]), median(r1[1]), mx(r1[1]));
  std::printf("  residual + 1 refine  median/max: block %.1e/%.1e  pair %.1e/%.1e\n", median(r2[0]), mx(r2[0]), median(r2[1]), mx(r2[1]));
  std::printf("  CPU ms (medians): factor block %.3f pair %.3f; solve block %.3f pair %.3f\n", median(tf[0]), median(tf[1]), median(ts[0]),
              median(ts[1]));
}
