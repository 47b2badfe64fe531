# Summaries of harness/prototype outputs: python stats.py LIBRARY_OUT PROTO_OUT [PROTO_OUT...]
# Per file: median and max relative residual, count above 1e-6, median factor/solve ms (the MEDIAN line),
# inertia (neg) agreement with the first file matrix by matrix.
import sys, re, statistics as st
def parse(fn):
    rows, med = {}, None
    for ln in open(fn):
        m = re.match(r'(val\d+).* neg (\d+) relres (\S+) factor (\S+) ms solve (\S+) ms', ln)
        if m: rows[m[1]] = (int(m[2]), float(m[3]), float(m[4]), float(m[5]))
        m = re.match(r'MEDIAN factor (\S+) ms solve (\S+) ms', ln)
        if m: med = (float(m[1]), float(m[2]))
    return rows, med
ref, _ = parse(sys.argv[1])
for fn in sys.argv[1:]:
    r, med = parse(fn); res = [v[1] for v in r.values()]
    agree = sum(1 for k, v in r.items() if k in ref and ref[k][0] == v[0])
    print(f'{fn}: n={len(r)} relres median {st.median(res):.2e} max {max(res):.2e} >1e-6: {sum(x > 1e-6 for x in res)} '
          f'inertia = library: {agree}/{len(r)}  factor {med[0]:.3f} ms solve {med[1]:.3f} ms  f+s {med[0] + med[1]:.3f} ms')
