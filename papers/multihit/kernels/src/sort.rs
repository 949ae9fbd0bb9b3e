//! The naive method's post-traversal selection of the N_query closest hits
//! (Amstutz et al. 2015): a selection sort of a ray's first
//! `min(count, N_query)` places over its `count` entries. Packets sort
//! coherently: every lane walks the same entry index, so an entry row is
//! one vector load, and a lane sits idle past its own count.

use crate::buffers::HitBufs;
use crate::filters::EntryIndex;
use crate::site;
use crate::{at, each, FILTER_REGION};
use isa::{At, Cmp, IOp, Machine, SOp};

/// What a sort did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Sorted {
    /// Entries (lane entries, for packets) swapped into place.
    pub moves: u64,
    /// Steps of the inner walk: entries (single rays) or entry rows
    /// (packets) compared with the nearest so far.
    pub steps: u64,
}

/// Sort `n` single rays' entries.
pub fn single<M: Machine>(m: &mut M, b: &mut HitBufs, n: usize, n_query: u32) -> Sorted {
    m.region(FILTER_REGION);
    let (mut moves, mut steps) = (0, 0);
    let stride = m.int(8 * i64::from(b.cap));
    let nq = m.int(i64::from(n_query));
    each(m, n, site::SORT_RAY, |m, ray| {
        let count = m.s_load(&b.counts, At::idx(ray, 4, 0), 4, false);
        let places = m.s_op(SOp::Min, count, nq);
        let base = m.s_op(SOp::Mul, ray, stride);
        let end = m.s_shift(isa::Shift::Shl, count, 3);
        let end = m.s_add(base, end);
        let last = m.s_shift(isa::Shift::Shl, places, 3);
        let last = m.s_add(base, last);
        let mut pi = base;
        loop {
            if !m.branch_if(site::SORT_I, Cmp::Lt, pi, last) {
                break;
            }
            let e = &mut b.entries;
            let (mut best, mut bt) = (pi, m.x_load(e, at(pi, 0)));
            let mut pj = m.s_addi(pi, 8);
            loop {
                if !m.branch_if(site::SORT_J, Cmp::Lt, pj, end) {
                    break;
                }
                steps += 1;
                let tj = m.x_load(e, at(pj, 0));
                let less = m.x_cmp(Cmp::Lt, tj, bt);
                if m.branch(site::SORT_LESS, less) {
                    (best, bt) = (pj, tj);
                }
                pj = m.s_addi(pj, 8);
            }
            let ei = m.s_load(e, at(pi, 0), 8, false);
            let eb = m.s_load(e, at(best, 0), 8, false);
            m.s_store(e, at(pi, 0), 8, eb);
            m.s_store(e, at(best, 0), 8, ei);
            moves += 1;
            pi = m.s_addi(pi, 8);
        }
    });
    Sorted { moves, steps }
}

/// Sort `np` packets' entries, lanes together.
pub fn packets<M: Machine>(m: &mut M, b: &mut HitBufs, np: usize, n_query: u32) -> Sorted {
    m.region(FILTER_REGION);
    let w = M::LANES;
    let (mut moves, mut steps) = (0, 0);
    let step = m.int(b.packet_bytes() as i64);
    let ix = EntryIndex::new(m);
    let one = m.splat_i(1);
    let nq = m.splat_i(n_query as i32);
    each(m, np, site::SORT_PACKET, |m, p| {
        let e = &mut b.entries;
        let base = m.s_op(SOp::Mul, p, step);
        let count_f = m.load(e, at(base, 0));
        let count = m.bits_to_i(count_f);
        let fewer = m.icmp(Cmp::Lt, count, nq);
        let places = m.iselect(fewer, count, nq);
        let mut iv = m.splat_i(0);
        let mut ri = m.s_addi(base, 4 * w as i64);
        loop {
            let act_i = m.icmp(Cmp::Lt, iv, places);
            let any = m.any(act_i);
            if !m.branch(site::SORT_PK_I, any) {
                break;
            }
            let ti = m.load(e, at(ri, 0));
            let (mut bt, mut best) = (ti, iv);
            let mut jv = m.iop(IOp::Add, iv, one);
            let mut rj = m.s_addi(ri, 8 * w as i64);
            loop {
                let within = m.icmp(Cmp::Lt, jv, count);
                let act_j = m.kand(act_i, within);
                let any = m.any(act_j);
                if !m.branch(site::SORT_PK_J, any) {
                    break;
                }
                steps += 1;
                let tj = m.load(e, at(rj, 0));
                let nearer = m.cmp(Cmp::Lt, tj, bt);
                let less = m.kand(nearer, act_j);
                bt = m.select(less, tj, bt);
                best = m.iselect(less, jv, best);
                jv = m.iop(IOp::Add, jv, one);
                rj = m.s_addi(rj, 8 * w as i64);
            }
            // Swap place i and the nearest, in the active lanes.
            let pi = m.load(e, at(ri, 4 * w));
            let from = ix.t(m, best);
            let pb = m.gather(act_i, pi, e, At::idx(base, 1, 4 * w), from, 4);
            m.scatter(act_i, e, at(base, 0), from, 4, ti);
            m.scatter(act_i, e, at(base, 4 * w), from, 4, pi);
            m.store_masked(act_i, e, at(ri, 0), bt);
            m.store_masked(act_i, e, at(ri, 4 * w), pb);
            moves += u64::from(m.bits(act_i).count_ones());
            iv = m.iop(IOp::Add, iv, one);
            ri = m.s_addi(ri, 8 * w as i64);
        }
    });
    Sorted { moves, steps }
}
