//! Dynamic ray stream traversal over a BVH2 (Barringer and Akenine-Moller
//! 2014, Appendix A), closest hit:
//!
//! - one ray stream stack; items reference ranges of 3 pre-allocated ray
//!   pointer lists of 16-bit indices (the BVH4 kernel's [`StreamBufs`], of
//!   which 3 lists are used), appended in place, reclaimed by counter;
//! - items in the order left-right-left: list 0 holds rays that hit the left
//!   child nearer (or only the left), list 1 every ray that hit the right
//!   child, list 2 rays that hit the left child farther than the right;
//! - no direction binning (the paper: it did not pay off for BVH2): the near
//!   and far planes are chosen per ray in the core loop by a blend on the
//!   direction's sign (`blendv`), from the node's rows `[min_l, min_r, max_l,
//!   max_r]` and their half-swapped copies, the far planes negated
//!   (`posNegMask`) so one max tree gives entry and negated exit distances;
//!   one compare and one mask move give each ray's left hit, right hit and
//!   order bits, as the listing's `mask`;
//! - the core loop tests LANES/4 rays per iteration (2 on AVX2), fmsub on the
//!   premultiplied origin, scalar appends to all 3 lists advanced by their
//!   conditions, the last index duplicated as padding; software-pipelined
//!   as the paper's listing ([`crate::pipeline`]);
//! - leaves test an item's rays against the block loaded once; below
//!   [`FALLBACK2`] rays an item is traced ray by ray;
//! - shadow rays: one item per hit child, the larger popped first.
//!
//! Deviations: list counters live in memory between nodes; the listing
//! omits how `mask` is formed: here a negation, a shuffle, a permute, a
//! compare and a mask move.

use crate::bvh4::{for_each_ray, larger_last, leaf_item, pad_and_push};
use crate::pipeline::{conds, core_loop};
use crate::stream::StreamBufs;
use isa::{At, Buf, Cmp, Int, Logic, Machine, Region, Shift};
use rt::boxtest::Pat;
use rt::layout::Bvh2Bufs;
use rt::single::trace_ray_bvh2;
use scene::HitPolicy;

/// Below this many rays an item is traced ray by ray (the paper's n for BVH2).
pub const FALLBACK2: i64 = 8;
/// Which child each of the 3 items holds: left-right-left.
pub const CHILD_OF_ITEM2: [usize; 3] = [0, 1, 0];

/// Branch sites.
pub mod site {
    use isa::Site;
    /// Initial list loop.
    pub const INIT: Site = isa::sites::DRS_BVH2.at(0);
    /// Stack empty?
    pub const STACK: Site = isa::sites::DRS_BVH2.at(1);
    /// Few rays: fall back?
    pub const FEW: Site = isa::sites::DRS_BVH2.at(2);
    /// Leaf item?
    pub const LEAF: Site = isa::sites::DRS_BVH2.at(3);
    /// Core loop back edge.
    pub const CORE: Site = isa::sites::DRS_BVH2.at(4);
    /// Padding duplicate?
    pub const PAD: Site = isa::sites::DRS_BVH2.at(5);
    /// New item non-empty?
    pub const ITEM: Site = isa::sites::DRS_BVH2.at(6);
    /// Shadow items' push order.
    pub const ORDER: Site = isa::sites::DRS_BVH2.at(7);

    /// Every site of the module (checked for duplicates by the layout test).
    pub const ALL: [Site; 8] = [INIT, STACK, FEW, LEAF, CORE, PAD, ITEM, ORDER];
}

/// Trace rays `[0, nrays)` through a BVH2 (records as for [`rt::single::trace_bvh4`]).
#[allow(clippy::too_many_arguments)]
pub fn trace<M: Machine>(
    m: &mut M,
    s: &Bvh2Bufs,
    st: &mut StreamBufs,
    trav: &mut Buf,
    isect: &Buf,
    hits: &mut Buf,
    nrays: usize,
    policy: HitPolicy,
) {
    match M::LANES {
        4 => trace_n::<M, 4>(m, s, st, trav, isect, hits, nrays, policy),
        8 => trace_n::<M, 8>(m, s, st, trav, isect, hits, nrays, policy),
        16 => trace_n::<M, 16>(m, s, st, trav, isect, hits, nrays, policy),
        32 => trace_n::<M, 32>(m, s, st, trav, isect, hits, nrays, policy),
        n => panic!("the DRS kernel runs on 4 to 32 lanes, not {n}"),
    }
}

#[allow(clippy::too_many_arguments)]
fn trace_n<M: Machine, const N: usize>(
    m: &mut M,
    s: &Bvh2Bufs,
    st: &mut StreamBufs,
    trav: &mut Buf,
    isect: &Buf,
    hits: &mut Buf,
    nrays: usize,
    policy: HitPolicy,
) {
    let r = N / 4;
    let cap2 = (st.cap * 2) as i64;
    let zero = m.int(0);
    // ---- every ray into list 0, one item at the root ----
    m.region(Region::Setup);
    let nr = m.int(nrays as i64);
    let mut i = m.int(0);
    loop {
        m.s_store(&mut st.lists, At::idx(i, 2, 0), 2, i);
        i = m.s_addi(i, 1);
        if !m.branch_if(site::INIT, Cmp::Lt, i, nr) {
            break;
        }
    }
    let mut sp = m.int(0);
    let root = m.int(i64::from(s.root));
    pad_and_push(m, st, &mut sp, 0, root, zero, nr, zero, r);
    // ---- the ray stream stack ----
    loop {
        m.region(Region::Traversal);
        if !m.branch_if(site::STACK, Cmp::Gt, sp, zero) {
            break;
        }
        sp = m.s_addi(sp, -1);
        let io = m.s_shift(Shift::Shl, sp, 4);
        let node = m.s_load(&st.items, At::idx(io, 1, 0), 4, false);
        let list = m.s_load(&st.items, At::idx(io, 1, 4), 1, false);
        let start = m.s_load(&st.items, At::idx(io, 1, 8), 4, false);
        let count = m.s_load(&st.items, At::idx(io, 1, 12), 4, false);
        m.s_store(&mut st.counters, At::idx(list, 8, 0), 8, start);
        let cap2v = m.int(cap2);
        let lbase = m.s_op(isa::SOp::Mul, list, cap2v);
        let first = m.s_shift(Shift::Shl, start, 1);
        let rays_at = m.s_add(lbase, first);
        let few = m.int(FALLBACK2);
        if m.branch_if(site::FEW, Cmp::Lt, count, few) {
            m.region(Region::SingleRay);
            for_each_ray(m, &st.lists, rays_at, count, |m, ray| {
                trace_ray_bvh2(
                    m,
                    s,
                    trav,
                    isect,
                    hits,
                    &mut st.stack,
                    ray,
                    node,
                    &mut st.tests,
                    policy,
                )
            });
            continue;
        }
        let leaf_flag = m.int(i64::from(scene::bvh::LEAF));
        let lf = m.s_and(node, leaf_flag);
        if m.branch(site::LEAF, lf) {
            st.tests.leaf += count.get() as u64;
            leaf_item(
                m, &s.tris, trav, isect, hits, &st.lists, node, rays_at, count, policy,
            );
            continue;
        }
        core_node::<M, N>(m, s, st, trav, &mut sp, node, rays_at, count, policy);
    }
}

/// One inner node's item as the traversal meets it: the core loop over the
/// `count` ray indices at byte `at` of the lists (list counters as
/// `st.counters` holds them), then the new items pushed at `sp`. Public for
/// the `listloop` bench, which times it against the paper's listing
/// written by hand.
#[allow(clippy::too_many_arguments)]
pub fn node_item<M: Machine>(
    m: &mut M,
    s: &Bvh2Bufs,
    st: &mut StreamBufs,
    trav: &Buf,
    sp: &mut M::S,
    node: M::S,
    (at, count): (M::S, M::S),
    policy: HitPolicy,
) {
    match M::LANES {
        4 => core_node::<M, 4>(m, s, st, trav, sp, node, at, count, policy),
        8 => core_node::<M, 8>(m, s, st, trav, sp, node, at, count, policy),
        16 => core_node::<M, 16>(m, s, st, trav, sp, node, at, count, policy),
        32 => core_node::<M, 32>(m, s, st, trav, sp, node, at, count, policy),
        n => panic!("the DRS kernel runs on 4 to 32 lanes, not {n}"),
    }
}

/// One inner node: the core loop over the item's rays, then the new items.
#[allow(clippy::too_many_arguments)]
fn core_node<M: Machine, const N: usize>(
    m: &mut M,
    s: &Bvh2Bufs,
    st: &mut StreamBufs,
    trav: &Buf,
    sp: &mut M::S,
    node: M::S,
    at: M::S,
    count: M::S,
    policy: HitPolicy,
) {
    let r = N / 4;
    m.region(Region::Traversal);
    let base = m.s_shift(Shift::Shl, node, 6);
    // The paper's bbX = [min_l, min_r, -max_l, -max_r] and bbXneg = [max_l,
    // max_r, -min_l, -min_r] (the planes for a negative direction): far
    // planes negated, so one max gives entry and negated exit distances.
    // Arrays, not vectors: natively a Vec here was an allocation per node.
    let pos_neg = m.consts(&POS_NEG[..N]);
    let planes: [(M::F, M::F); 3] = std::array::from_fn(|a| {
        let row = m.load_repeat(&s.nodes, At::idx(base, 1, 16 * a), 4);
        let swapped = m.permute(row, &Pat::<N>::SWAP_GROUPS);
        let bb = m.logic(Logic::Xor, row, pos_neg);
        (bb, m.logic(Logic::Xor, swapped, pos_neg))
    });
    let (bb, bb_neg) = (planes.map(|p| p.0), planes.map(|p| p.1));
    let neg = m.splat(-0.0);
    let nlists = if policy.is_any() { 2 } else { 3 };
    let mut starts_at = [count; 3];
    for (k, s) in starts_at.iter_mut().enumerate().take(nlists) {
        *s = m.s_load(&st.counters, At::off(8 * k), 8, false);
    }
    let starts = &starts_at[..nlists];
    let mut cnt_at = starts_at;
    let cnt = &mut cnt_at[..nlists];
    m.region(Region::CoreLoop);
    let sites = (site::CORE, site::PAD);
    core_loop::<M, N>(
        m,
        st,
        trav,
        (at, count),
        cnt,
        sites,
        move |m, dir_near, org_far| {
            // The listing's shuffle patterns, named as constants here (not
            // captured): each shuffle then compiles to one instruction natively.
            let near_far_ray = &Groups::<N>::NEAR_FAR_RAY;
            let (rhs_pat, lhs_pat) = (&Groups::<N>::RHS, &Groups::<N>::LHS);
            // Per axis a, each ray's 4 lanes: [near_l, near_r, -far_l, -far_r].
            let org_far_neg = m.logic(Logic::Xor, org_far, neg);
            // An inlined function per axis, not a closure: natively the
            // closure compiled to a call per axis with the axis a variable,
            // so every shuffle pattern was checked and built at run time
            // (a quarter of DRS BVH2's host time).
            let rays = (dir_near, org_far, org_far_neg);
            let near_far: [M::F; 3] = [
                axis::<M, N>(m, 0, rays, (bb[0], bb_neg[0])),
                axis::<M, N>(m, 1, rays, (bb[1], bb_neg[1])),
                axis::<M, N>(m, 2, rays, (bb[2], bb_neg[2])),
            ];
            let ray = m.shuffle2(dir_near, org_far_neg, near_far_ray);
            let m01 = m.max(ray, near_far[0]);
            let m23 = m.max(near_far[1], near_far[2]);
            let x = m.max(m01, m23);
            // Lanes 0, 1, 2: near_l <= far_l, near_r <= far_r, near_r <= near_l.
            let xn = m.logic(Logic::Xor, x, neg);
            let rhs = m.shuffle2(xn, x, rhs_pat);
            let lhs = m.permute(x, lhs_pat);
            let hit = m.cmp(Cmp::Le, lhs, rhs);
            let mask = m.movemask(hit);
            let shr = |m: &mut M, v: M::S, n: u32| m.s_shift(Shift::Shr, v, n);
            let right = shr(m, mask, 1);
            if policy.is_any() {
                // Shadow rays: list 0 left, list 1 right, no order.
                return conds(m, &[mask, right]);
            }
            // Ray q's conditions at bit 4q: left-first, right, left-second.
            let o2 = shr(m, mask, 2);
            let order = m.s_and(o2, right);
            let all = m.int(((1u64 << N.max(16)) - 1) as i64);
            let norder = m.s_op(isa::SOp::Xor, order, all);
            let (first, second) = (m.s_and(mask, norder), m.s_and(mask, order));
            conds(m, &[first, right, second])
        },
    );
    m.region(Region::Traversal);
    let zero = m.int(0);
    if policy.is_any() {
        // The larger of the two items is popped first.
        let counts: Vec<M::S> = (0..2).map(|k| m.s_sub(cnt[k], starts[k])).collect();
        for k in larger_last(m, &counts, site::ORDER) {
            if !m.branch_if(site::ITEM, Cmp::Gt, cnt[k], starts[k]) {
                continue;
            }
            let child = m.s_load(&s.nodes, At::idx(base, 1, 48 + 4 * k), 4, false);
            pad_and_push(m, st, sp, k, child, starts[k], cnt[k], zero, r);
        }
        return;
    }
    // New items, pushed so that item 0 is popped first.
    for k in (0..3).rev() {
        if !m.branch_if(site::ITEM, Cmp::Gt, cnt[k], starts[k]) {
            continue;
        }
        let child = m.s_load(
            &s.nodes,
            At::idx(base, 1, 48 + 4 * CHILD_OF_ITEM2[k]),
            4,
            false,
        );
        pad_and_push(m, st, sp, k, child, starts[k], cnt[k], zero, r);
    }
}

/// Axis `a`'s `[near_l, near_r, -far_l, -far_r]` per ray of the core loop's
/// iteration (`dir_near`, `org_far` and `org_far` negated; the node's bbX
/// and bbXneg for the axis).
#[inline(always)]
fn axis<M: Machine, const N: usize>(
    m: &mut M,
    a: usize,
    (dir_near, org_far, org_far_neg): (M::F, M::F, M::F),
    (bb, bb_neg): (M::F, M::F),
) -> M::F {
    let d = m.permute(dir_near, &Pat::<N>::SPLAT[a]);
    let o = m.shuffle2(org_far, org_far_neg, &Groups::<N>::ORG_AXIS[a]);
    let planes = m.blend_sign(d, bb, bb_neg);
    m.fmsub(planes, d, o)
}

/// The listing's `posNegMask`, for up to 32 lanes: per 4-lane group
/// `[0, 0, -0, -0]` (xor negates the far planes).
const POS_NEG: [f32; 32] = {
    let mut p = [0.0f32; 32];
    let mut l = 0;
    while l < 32 {
        if l % 4 >= 2 {
            p[l] = -0.0;
        }
        l += 1;
    }
    p
};

/// The listing's shuffle patterns, per 4-lane group of N lanes.
struct Groups<const N: usize>;
impl<const N: usize> Groups<N> {
    /// Per axis a: each ray's `[org_a, org_a, -org_a, -org_a]` (times idir).
    const ORG_AXIS: [[u8; N]; 3] = [
        groups::<N>([0, 0, 4, 4]),
        groups::<N>([1, 1, 5, 5]),
        groups::<N>([2, 2, 6, 6]),
    ];
    /// Each ray's `[near, near, -far, -far]`.
    const NEAR_FAR_RAY: [u8; N] = groups::<N>([3, 3, 7, 7]);
    /// The hit test's right-hand sides.
    const RHS: [u8; N] = groups::<N>([2, 3, 4, 4]);
    /// The hit test's left-hand sides.
    const LHS: [u8; N] = groups::<N>([0, 1, 1, 1]);
}

/// A 4-lane pattern repeated for each 4-lane group of N lanes: indices 0-3
/// pick the group's lanes of the first source, 4-7 those of the second.
const fn groups<const N: usize>(p: [u8; 4]) -> [u8; N] {
    let mut r = [0u8; N];
    let mut l = 0;
    while l < N {
        let (g, x) = (l / 4 * 4, p[l % 4] as usize);
        r[l] = (if x < 4 { g + x } else { N + g + x - 4 }) as u8;
        l += 1;
    }
    r
}
