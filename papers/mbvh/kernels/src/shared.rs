//! Steps the three MBVH kernels share: decoding a leaf ref, the slab test's
//! arithmetic, the child sort and a broadcast triangle. Each issues the
//! same ops in the same order wherever it is called.

use crate::layout::{block_bytes, LEAF_COUNT_MASK, LEAF_FIRST_SHIFT};
use isa::{At, Buf, Cmp, Machine, SOp, Shift, Site};
use rt::single::Block;
use scene::bvh::LEAF;

/// A leaf ref's first block as a byte offset into the triangle blocks, and
/// its triangle count.
pub(crate) fn leaf_blocks<M: Machine>(m: &mut M, node: M::S) -> (M::S, M::S) {
    let fm = m.int(i64::from(!LEAF));
    let first = m.s_and(node, fm);
    let first = m.s_shift(Shift::Shr, first, LEAF_FIRST_SHIFT);
    let cm = m.int(i64::from(LEAF_COUNT_MASK));
    let ntri = m.s_and(node, cm);
    let bbytes = m.int(block_bytes(M::LANES) as i64);
    (m.s_op(SOp::Mul, first, bbytes), ntri)
}

/// One axis of the Kay-Kajiya slab test: the entry and exit distances of
/// the planes `lo` and `hi` for origin `o` and inverse direction `id`.
pub(crate) fn slab_axis<M: Machine>(
    m: &mut M,
    (lo, hi): (M::F, M::F),
    o: M::F,
    id: M::F,
) -> (M::F, M::F) {
    let d0 = m.sub(lo, o);
    let t0 = m.mul(d0, id);
    let d1 = m.sub(hi, o);
    let t1 = m.mul(d1, id);
    (m.min(t0, t1), m.max(t0, t1))
}

/// The three axes' intervals clipped to [`tmin`, `tfar`]: the lanes where
/// the interval is not empty, and its entry distance.
pub(crate) fn slab_hits<M: Machine>(
    m: &mut M,
    near: [M::F; 3],
    far: [M::F; 3],
    tmin: M::F,
    tfar: M::F,
) -> (M::K, M::F) {
    let n01 = m.max(near[0], near[1]);
    let n2 = m.max(near[2], tmin);
    let tn = m.max(n01, n2);
    let f01 = m.min(far[0], far[1]);
    let f2 = m.min(far[2], tfar);
    let tf = m.min(f01, f2);
    (m.cmp(Cmp::Le, tn, tf), tn)
}

/// Insertion sort, largest `key` first (so the smallest is pushed last and
/// popped first): a compare and a branch at `site` per step.
pub(crate) fn sort_farthest_first<M: Machine, T>(
    m: &mut M,
    items: &mut [T],
    key: impl Fn(&T) -> M::X,
    site: Site,
) {
    for i in 1..items.len() {
        let mut j = i;
        while j > 0 {
            let lt = m.x_cmp(Cmp::Lt, key(&items[j - 1]), key(&items[j]));
            if !m.branch(site, lt) {
                break;
            }
            items.swap(j - 1, j);
            j -= 1;
        }
    }
}

/// Triangle `t` of the leaf whose blocks start at byte `fb` of `tris`, each
/// component broadcast into every lane.
pub(crate) fn broadcast_triangle<M: Machine>(
    m: &mut M,
    tris: &Buf,
    fb: M::S,
    t: usize,
) -> Block<M> {
    let w = M::LANES;
    let at = (t / w) * block_bytes(w) + 4 * (t % w);
    let mut row = |r: usize| m.load_bcast(tris, At::idx(fb, 1, at + 4 * w * r));
    let v0 = [row(0), row(1), row(2)];
    let e1 = [row(3), row(4), row(5)];
    let e2 = [row(6), row(7), row(8)];
    let pf = row(9);
    let prim = m.bits_to_i(pf);
    Block { v0, e1, e2, prim }
}
