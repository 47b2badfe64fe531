# Stability remedy 1 (experiment): merge every stage that holds a pure state constraint (a row, other
# than a dynamics row, whose non-slack variables are all states x_k of that stage: the target rows
# and the final-node bounds) into the previous stage. x_k and the dynamics rows lam_{k-1} paired with
# it become local (pivot candidates) of the merged front, so Bunch-Kaufman can pivot the constraint
# row with the state it touches instead of with its slack only. Reads CASE.plan (plan.py), writes
# CASEmerge.plan. Usage: merge.py CASE [DEPTH]  (DEPTH: merge that many previous stages, default 1)
import numpy as np, sys
case = sys.argv[1]; depth = int(sys.argv[2]) if len(sys.argv) > 2 else 1
d = np.fromfile(f'/tmp/ric/{case}.pat', dtype=np.int32); n, nz = int(d[0]), int(d[1])
irn = d[2:2 + nz] - 1; jcn = d[2 + nz:2 + 2 * nz] - 1
pl = np.fromfile(f'{case}.plan', dtype=np.int32); N, p, S = pl[:3]
typ, stg, pv = pl[3:3 + n].copy(), pl[3 + n:3 + 2 * n].copy(), pl[3 + 2 * n:3 + 3 * n].copy()
lo = np.minimum(irn, jcn); hi = np.maximum(irn, jcn); off = lo != hi
rowvars = {}
for a, b in zip(lo[off], hi[off]):
    if b >= p: rowvars.setdefault(int(b), []).append(int(a))
deg = np.bincount(np.concatenate([lo[off], hi[off]]), minlength=n)
slack = {a for a in range(p) if deg[a] == 1 and any(True for _ in [0])}
slack = {a for r, vs in rowvars.items() for a in vs if deg[a] == 1}
bad = set()
for r, vs in rowvars.items():
    if typ[r] != 0: continue
    v = [a for a in vs if a not in slack]
    if v and all(typ[a] == 1 and stg[a] == stg[r] for a in v): bad.add(int(stg[r]))
print(case, 'stages with pure state constraints:', sorted(bad))
merged = 0
for k in sorted(bad, reverse=True):
    for _ in range(depth):
        if k < 1: break
        xs = np.where((stg == k) & (typ == 1))[0]
        for x in xs:
            r = np.where((typ == 2) & (pv == x))[0]
            typ[r] = 0; pv[r] = -1
        typ[xs] = 0
        stg[stg >= k] -= 1
        merged += 1; k -= 1
S2 = int(stg.max())
print(' merged', merged, 'stages; stages 0..', S2)
np.concatenate([[n, p, S2], typ, stg, pv]).astype(np.int32).tofile(f'{case}merge{depth if depth > 1 else ""}.plan')
