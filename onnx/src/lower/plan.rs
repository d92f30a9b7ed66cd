//! Arena planning: give every activation storage a per-sample offset so that storages alive
//! at the same time never overlap (greedy best-fit by decreasing size over live intervals).

use dips_kernel::nn::format::{Buf, Op, OpRef, Operand};

pub(super) fn reads(op: &Op) -> Vec<Buf> {
    let mut out = Vec::new();
    op.refs(|r| match r {
        OpRef::Reads(b) | OpRef::ReadsOperand(Operand::Act(b)) => out.push(*b),
        _ => {}
    });
    out
}

pub(super) fn writes(op: &Op) -> Buf {
    op.output()
}

/// Offsets per storage and the arena size per sample.
pub(super) fn plan(
    ops: &[Op],
    sizes: &[usize],
    inputs: &[usize],
    output: usize,
) -> (Vec<usize>, usize) {
    let n = sizes.len();
    let end = ops.len() as i64 + 1;
    let mut def = vec![i64::MAX; n];
    let mut last = vec![i64::MIN; n];
    for st in inputs {
        def[*st] = -1;
    }
    for (i, op) in ops.iter().enumerate() {
        let i = i as i64;
        let w = writes(op).off as usize;
        def[w] = def[w].min(i);
        last[w] = last[w].max(i);
        for r in reads(op) {
            last[r.off as usize] = last[r.off as usize].max(i);
        }
    }
    last[output] = end;
    for st in inputs {
        last[*st] = last[*st].max(def[*st]);
    }
    let mut order: Vec<usize> = (0..n).filter(|s| def[*s] != i64::MAX).collect();
    order.sort_by(|a, b| sizes[*b].cmp(&sizes[*a]).then(a.cmp(b)));
    let mut offsets = vec![0usize; n];
    let mut placed: Vec<usize> = Vec::new();
    let mut arena = 0;
    for s in order {
        let mut busy: Vec<(usize, usize)> = placed
            .iter()
            .filter(|p| def[**p] <= last[s] && def[s] <= last[**p])
            .map(|p| (offsets[*p], offsets[*p] + sizes[*p]))
            .collect();
        busy.sort_unstable();
        let mut at = 0;
        let mut best: Option<(usize, usize)> = None;
        for (b0, b1) in &busy {
            if *b0 >= at + sizes[s] {
                let gap = b0 - at;
                if best.is_none_or(|(_, g)| gap < g) {
                    best = Some((at, gap));
                }
            }
            at = at.max(*b1);
        }
        let off = best.map_or(at, |(o, _)| o);
        offsets[s] = off;
        arena = arena.max(off + sizes[s]);
        placed.push(s);
    }
    (offsets, arena)
}
