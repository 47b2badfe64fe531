// Writes the KKT matrices IPOPT hands the stage-wise solver, for the prototype's harness: a shim
// with MA27's four entry points that forwards each call to the real library (RIC_REAL_LIB, e.g.
// fatigue_pin/libfatigue_pin_riccati.so) and, with RIC_DUMP=/path/prefix, writes the pattern at
// the analysis (prefix.pat: int32 N, int32 NZ, NZ int32 rows, NZ int32 columns, 1-based) and the
// values at every factorisation (prefix.val000, .val001, ...: NZ float64).
//
//   g++ -O2 -shared -fPIC experiments/riccati_proto/dump_shim.cpp -o /tmp/ric/libdump.so -ldl
//   FATIGUE_PIN_RICCATI_LIB=/tmp/ric/libdump.so RIC_REAL_LIB=$PWD/fatigue_pin/libfatigue_pin_riccati.so \
//     RIC_DUMP=/tmp/ric/ur5 python -c "import sys; sys.path.insert(0, 'benchmarks'); import kkt_solvers as k; \
//     k.first_window(k.CASES['ur5'], 'riccati')"
#include <dlfcn.h>

#include <cstdio>
#include <cstdlib>

namespace {
using Id = void (*)(int*, double*);
using Ad = void (*)(int*, int*, const int*, const int*, int*, int*, int*, int*, int*, int*, int*, double*, int*, double*);
using Bd = void (*)(int*, int*, const int*, const int*, double*, int*, int*, int*, int*, int*, int*, int*, int*, double*, int*);
using Cd = void (*)(int*, double*, int*, int*, int*, double*, int*, double*, int*, int*, int*, int*);
using MaxBlock = int (*)(int, int, const int*, const int*, int*);
int count = 0;

void* real(const char* name) {
  static void* lib = dlopen(std::getenv("RIC_REAL_LIB"), RTLD_NOW | RTLD_LOCAL);
  if (!lib) {
    std::fprintf(stderr, "dump_shim: set RIC_REAL_LIB to the stage-wise solver's library\n");
    std::abort();
  }
  return dlsym(lib, name);
}

FILE* open(const char* suffix) {
  const char* prefix = std::getenv("RIC_DUMP");
  if (!prefix) return nullptr;
  char name[1024];
  std::snprintf(name, sizeof name, "%s%s", prefix, suffix);
  return std::fopen(name, "wb");
}
}  // namespace

extern "C" {
__attribute__((visibility("default"))) void ma27id_(int* icntl, double* cntl) { reinterpret_cast<Id>(real("ma27id_"))(icntl, cntl); }

__attribute__((visibility("default"))) void ma27ad_(int* N, int* NZ, const int* IRN, const int* ICN, int* IW, int* LIW, int* IKEEP,
                                                    int* IW1, int* NSTEPS, int* IFLAG, int* ICNTL, double* CNTL, int* INFO, double* OPS) {
  if (FILE* f = open(".pat")) {
    std::fwrite(N, 4, 1, f);
    std::fwrite(NZ, 4, 1, f);
    std::fwrite(IRN, 4, *NZ, f);
    std::fwrite(ICN, 4, *NZ, f);
    std::fclose(f);
    count = 0;
  }
  reinterpret_cast<Ad>(real("ma27ad_"))(N, NZ, IRN, ICN, IW, LIW, IKEEP, IW1, NSTEPS, IFLAG, ICNTL, CNTL, INFO, OPS);
}

__attribute__((visibility("default"))) void ma27bd_(int* N, int* NZ, const int* IRN, const int* ICN, double* A, int* LA, int* IW,
                                                    int* LIW, int* IKEEP, int* NSTEPS, int* MAXFRT, int* IW1, int* ICNTL,
                                                    double* CNTL, int* INFO) {
  char suffix[32];
  std::snprintf(suffix, sizeof suffix, ".val%03d", count++);
  if (FILE* f = open(suffix)) {
    std::fwrite(A, 8, *NZ, f);
    std::fclose(f);
  }
  reinterpret_cast<Bd>(real("ma27bd_"))(N, NZ, IRN, ICN, A, LA, IW, LIW, IKEEP, NSTEPS, MAXFRT, IW1, ICNTL, CNTL, INFO);
}

__attribute__((visibility("default"))) void ma27cd_(int* N, double* A, int* LA, int* IW, int* LIW, double* W, int* MAXFRT,
                                                    double* RHS, int* IW1, int* NSTEPS, int* ICNTL, int* INFO) {
  reinterpret_cast<Cd>(real("ma27cd_"))(N, A, LA, IW, LIW, W, MAXFRT, RHS, IW1, NSTEPS, ICNTL, INFO);
}

// the analysis alone, which fatigue_pin's structure check asks before the first solve
__attribute__((visibility("default"))) int riccati_max_block(int n, int nz, const int* irn, const int* jcn, int* nblocks) {
  return reinterpret_cast<MaxBlock>(real("riccati_max_block"))(n, nz, irn, jcn, nblocks);
}
}
