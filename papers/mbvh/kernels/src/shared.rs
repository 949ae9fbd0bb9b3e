//! Steps the three MBVH kernels share: decoding a leaf ref, the slab test's
//! arithmetic, the child sort and a broadcast triangle. Each issues the
//! same ops in the same order wherever it is called.

use crate::layout::{block_bytes, LEAF_COUNT_MASK, LEAF_FIRST_SHIFT};
use isa::{At, Buf, Cmp, Machine, SOp, Shift, Site};
use rt::single::Block;
use scene::bvh::LEAF;
use scene::Hit;

/// Rows of an SoA packet record (each `W` f32), as the packet kernels
/// keep their rays.
pub(crate) mod row {
    pub const ORG: usize = 0;
    pub const DIR: usize = 3;
    pub const IDIR: usize = 6;
    pub const TFAR: usize = 9;
    pub const PRIM: usize = 10;
    pub const U: usize = 11;
    pub const V: usize = 12;
    pub const ROWS: usize = 16;
}

/// `slots` rays in SoA records of `w` lanes: slot `i` holds `ray(i)`'s
/// origin, direction, inverse direction and t_far, and no hit yet.
pub(crate) fn soa_records(
    w: usize,
    slots: usize,
    ray: impl Fn(usize) -> ([f32; 3], [f32; 3], f32),
) -> Vec<f32> {
    let mut v = vec![0f32; slots.div_ceil(w) * row::ROWS * w];
    for i in 0..slots {
        let (p, l) = (i / w, i % w);
        let at = |r: usize| p * row::ROWS * w + r * w + l;
        let (o, d, tf) = ray(i);
        for a in 0..3 {
            v[at(row::ORG + a)] = o[a];
            v[at(row::DIR + a)] = d[a];
            v[at(row::IDIR + a)] = 1.0 / d[a];
        }
        v[at(row::TFAR)] = tf;
        v[at(row::PRIM)] = f32::from_bits(u32::MAX);
    }
    v
}

/// Slot `i`'s answer in SoA records of `w` lanes.
pub(crate) fn soa_hit(records: &Buf, w: usize, i: usize) -> Hit {
    let (p, l) = (i / w, i % w);
    let at = |r: usize| 4 * (p * row::ROWS * w + r * w + l);
    Hit::from_record(records.f32_at(at(row::TFAR)), records.u32_at(at(row::PRIM)))
}

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
