# Structure analysis -> elimination plan for the Riccati prototype (pattern + constant +-1 values).
import numpy as np, collections, sys, glob
case=sys.argv[1]
d=np.fromfile(f'/tmp/ric/{case}.pat',dtype=np.int32); n,nz=int(d[0]),int(d[1])
irn=d[2:2+nz]-1; jcn=d[2+nz:2+2*nz]-1
V=np.array([np.fromfile(f) for f in sorted(glob.glob(f'/tmp/ric/{case}.val*'))])
const1=np.all(np.abs(V)==1.0,axis=0); constv=np.all(V==V[0],axis=0)&(V[0]!=0)
lo=np.minimum(irn,jcn); hi=np.maximum(irn,jcn)
p=int(lo[lo!=hi].max())+1
rows=collections.defaultdict(dict); crow=collections.defaultdict(dict); vrows=collections.defaultdict(set); hn=collections.defaultdict(set)
for k in range(nz):
    a,b=int(lo[k]),int(hi[k])
    if a==b: continue
    if b>=p: rows[b][a]=rows[b].get(a,True) and bool(const1[k]); crow[b][a]=crow[b].get(a,True) and bool(constv[k]); vrows[a].add(b)
    else: hn[a].add(b); hn[b].add(a)
slack={a for a in range(p) if len(vrows[a])==1 and not hn[a]}
ineq={next(iter(vrows[s])) for s in slack}
pair={}
for r in range(p,n):
    if r in ineq: continue
    c=[a for a,u in rows[r].items() if u and a not in slack]
    if c: pair[r]=max(c)
cnt=collections.Counter(pair.values())
pair={r:v for r,v in pair.items() if cnt[v]==1}
taken=set(pair.values())
for r in range(p,n):
    if r in ineq or r in pair: continue
    c=[a for a,u in crow[r].items() if u and a not in slack and a not in taken]
    if c and len(c)<len(crow[r]): pair[r]=max(c)
cnt=collections.Counter(pair.values())
pair={r:v for r,v in pair.items() if cnt[v]==1}   # drop ambiguous
state=set(pair.values()); defrow={v:r for r,v in pair.items()}
# stage of states: longest path over dynamics rows
stage={}
import sys as _s
_s.setrecursionlimit(100000)
def st(v):
    if v in stage: return stage[v]
    r=defrow[v]; s=0
    for a in rows[r]:
        if a!=v and a in state: s=max(s,st(a))
    stage[v]=s+1; return s+1
for v in state: st(v)
S=max(stage.values())
# rows: paired row stage = stage(v)-1 ; other vars / rows: iterate
vst={v:s for v,s in stage.items()}; rst={r:stage[v]-1 for r,v in pair.items()}
# unpaired primal (non-slack): stage = min stage of paired rows touching it, else of states in its hessian nbrs
for a in range(p):
    if a in state or a in slack: continue
    c=[rst[r] for r in vrows[a] if r in rst]
    if c: vst[a]=min(c)
for it in range(5):
    for r in range(p,n):
        if r in rst: continue
        c=[vst[a] for a in rows[r] if a in vst]
        if c: rst[r]=max(c)
    for a in range(p):
        if a in vst or a in slack: continue
        c=[rst[r] for r in vrows[a] if r in rst]+[vst[b] for b in hn[a] if b in vst]
        if c: vst[a]=min(c)
for r in range(p,n): rst.setdefault(r,S)
for s_ in slack: vst[s_]=rst[next(iter(vrows[s_]))]
miss=[i for i in range(n) if (i<p and i not in vst) or (i>=p and i not in rst)]
print(case,'n',n,'primal',p,'rows',n-p,'slacks',len(slack),'ineq rows',len(ineq),'paired rows',len(pair),'stages 0..',S,'unassigned',len(miss))
# type: 1 state (x_k, k>=1 -> stage k), 2 paired row (stage k, pairs x_{k+1}), 0 local
typ=np.zeros(n,np.int32); stg=np.zeros(n,np.int32); pv=np.full(n,-1,np.int32)
for i in range(n):
    stg[i]=vst[i] if i<p else rst[i]
for v in state: typ[v]=1
import os
if os.environ.get('PUSH'):
    moved=0
    for r in range(p,n):
        if r in pair: continue
        vs=[a for a in rows[r] if a not in slack]
        if vs and all(a in state for a in vs) and stg[r]>=1 and all(stg[a]==stg[r] for a in vs):
            stg[r]-=1; moved+=1
            for a in rows[r]:
                if a in slack: stg[a]-=1
    print(' state-only rows moved to the previous stage:', moved)
for r,v in pair.items(): typ[r]=2; pv[r]=v
# per stage sizes
for k in [0,1,2,S//2,S]:
    idx=np.where(stg==k)[0]
    nx=sum(1 for i in idx if typ[i]==1); nl=sum(1 for i in idx if typ[i]==2)
    loc=[i for i in idx if typ[i]==0]
    print(' stage',k,'nx',nx,'dyn rows',nl,'controls',sum(1 for i in loc if i<p and i not in slack),'slacks',sum(1 for i in loc if i in slack),
          'ineq rows',sum(1 for i in loc if i in ineq),'eq path rows',sum(1 for i in loc if i>=p and i not in ineq))
# check: every entry stage-local or pair-row -> next state
bad=0; badE=0
for k in range(nz):
    a,b=int(lo[k]),int(hi[k])
    if a==b: continue
    sa,sb=stg[a],stg[b]
    if sa==sb: continue
    # allowed: paired row (stage k) with state of stage k+1
    r,v=(b,a)
    if typ[r]==2 and typ[v]==1 and stg[v]==stg[r]+1:
        if pv[r]!=v: badE+=1
        continue
    bad+=1
print(' entries not stage-local', bad, 'dyn rows touching a next state they are not paired with', badE)
# hessian blockdiag?
hb=sum(1 for a in range(p) for b in hn[a] if stg[a]!=stg[b]); print(' hessian entries across stages', hb)
np.concatenate([[n,p,S],typ,stg,pv]).astype(np.int32).tofile(f'{case}'+os.environ.get('PUSH','')+'.plan')
if len(sys.argv)>2:
    ex=collections.Counter()
    for k in range(nz):
        a,b=int(lo[k]),int(hi[k])
        if a==b or stg[a]==stg[b]: continue
        r,v=(b,a)
        if typ[r]==2 and typ[v]==1 and stg[v]==stg[r]+1: continue
        ex[(typ[a], a in slack, int(stg[b]-stg[a]), typ[b], b>=p)]+=1
    print(ex.most_common(12))
    k75=[i for i in range(n) if stg[i]==75]
    for i in k75: print(i, typ[i], i in slack, sorted((j,stg[j]) for j in (list(rows[i]) if i>=p else list(vrows[i])+list(hn[i]))))
