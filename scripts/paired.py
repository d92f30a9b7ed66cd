#!/usr/bin/env python3
"""Paired comparison of `dips` with k = 1 and max-likelihood (either task).

Usage: scripts/paired.py RESULTS.json [RESULTS.json ...]

Reads the `results.json` of one or more `dips eval` runs (trials of the same method and seed
in a later file replace earlier ones) and prints, over the seeds `dips` ran: each method's
valid count, mean ± standard error and median of the outcome (screwdriver: final yaw in rad;
card: distance to the goal in cm; lower is better for both; every trial, valid or not, as
`results.md` counts it), then the per-seed paired difference `dips` − method (same seed,
same start, same world): its mean, standard error, its share of the method's mean, and on
how many seeds `dips` did better. The tables of docs/results/README.md ("Twenty more
seeds", "Thirty more seeds") are its output.
"""
import json,sys,math,statistics as st
def load(p):
    r=json.load(open(p)); d={}
    for t in r['trials']: d[(t['method'],t['seed'])]=t
    return d
D={}
for p in sys.argv[1:]: D.update(load(p))
methods=['dips','dips-k1','dips-max-likelihood']
seeds=sorted({s for (m,s) in D if m=='dips'})
print('seeds',seeds[0],'..',seeds[-1],len(seeds))
for m in methods:
    xs=[D[(m,s)]['outcome'] for s in seeds if (m,s) in D]
    v=sum(D[(m,s)]['valid'] for s in seeds if (m,s) in D)
    print(f"{m:22s} valid {v}/{len(xs)} mean {st.mean(xs):.4f} ± SE {st.stdev(xs)/math.sqrt(len(xs)):.4f} median {st.median(xs):.4f}")
for m in methods[1:]:
    diff=[D[('dips',s)]['outcome']-D[(m,s)]['outcome'] for s in seeds if (m,s) in D]
    mean=st.mean(diff); se=st.stdev(diff)/math.sqrt(len(diff))
    base=st.mean([D[(m,s)]['outcome'] for s in seeds])
    better=sum(d< -1e-9 for d in diff); eq=sum(abs(d)<=1e-9 for d in diff)
    print(f"dips - {m}: {mean:+.4f} (SE {se:.4f}) = {mean/se:+.1f} SE, {100*mean/base:+.1f}% of its mean; dips better in {better} of {len(diff)} ({eq} equal)")
