//! Dynamic ray stream traversal over a BVH4 (Barringer and Akenine-Moller
//! 2014), closest hit, as the paper specifies:
//!
//! - one ray stream stack shared by all rays; its items reference ranges of 9
//!   pre-allocated ray pointer lists of 16-bit ray indices (m x d entries each),
//!   appended in place and reclaimed by counter when an item is popped;
//! - items in the order c0-c1-c0-c2-c3-c2-c0-c1-c0 (two levels of a BVH2:
//!   the nearer child group first, within a group the nearer child first);
//! - rays binned by direction octant into 8 initial items, so the near and far
//!   box planes of every item are chosen once per node, outside the core loop;
//! - the core loop tests LANES/4 rays per iteration against the 4 child boxes
//!   (2 rays on AVX2: 4-wide box tests over two rays), with fmsub on the
//!   premultiplied origin, and appends each ray index to all 9 lists with
//!   scalar stores, advancing each list by its condition (branch-free); the
//!   last index of an item is duplicated as padding, and skipped on reading;
//!   the loop is software-pipelined as the paper's Appendix A
//!   ([`crate::pipeline`]): the next rays are fetched during the box test and
//!   the last ray's appends are deferred to the next iteration;
//! - leaves test all of an item's rays against the leaf block, loaded once;
//! - below [`FALLBACK`] active rays an item switches to single-ray traversal;
//! - shadow rays (any hit) all take one path: one item per hit child (4
//!   lists), the item with the most rays popped first; an occluded ray's
//!   t_far becomes -1 so it drops out at its next box test.
//!
//! Deviations: runs on 4 and 8 lanes (the paper's Haswell kernel) and, as an
//! extension for lane-width experiments, 16 and 32 (4 and 8 rays an
//! iteration, their records merged from 128-bit loads: `pipeline::blocks`);
//! list counters live in a small array in memory, loaded and stored once per
//! node (the paper keeps list pointers in registers).

use crate::pipeline::{conds, core_loop};
pub use crate::stream::StreamBufs;
use isa::{At, Buf, Cmp, Int, Machine, Region, Shift};
use rt::boxtest::Pat;
use rt::layout::{Bvh4Bufs, BLOCK_BYTES};
use rt::single::{intersect, load_block, trace_ray_bvh4};
use scene::HitPolicy;

/// Below this many rays an item is traced ray by ray (the paper's n for BVH4).
pub const FALLBACK: i64 = 16;
pub use crate::stream::ITEM_BYTES;
/// Which child each of the 9 items holds: c0-c1-c0-c2-c3-c2-c0-c1-c0.
pub const CHILD_OF_ITEM: [usize; 9] = [0, 1, 0, 2, 3, 2, 0, 1, 0];

/// Branch sites.
pub mod site {
    use isa::Site;
    /// Binning loop.
    pub const BIN: Site = isa::sites::DRS_BVH4.at(0);
    /// Octant item non-empty?
    pub const OCTANT: Site = isa::sites::DRS_BVH4.at(1);
    /// Stack empty?
    pub const STACK: Site = isa::sites::DRS_BVH4.at(2);
    /// Few rays: fall back?
    pub const FEW: Site = isa::sites::DRS_BVH4.at(3);
    /// Leaf item?
    pub const LEAF: Site = isa::sites::DRS_BVH4.at(4);
    /// Core loop back edge.
    pub const CORE: Site = isa::sites::DRS_BVH4.at(5);
    /// Padding duplicate?
    pub const PAD: Site = isa::sites::DRS_BVH4.at(6);
    /// New item non-empty?
    pub const ITEM: Site = isa::sites::DRS_BVH4.at(7);
    /// Ray loop of a leaf or fallback item.
    pub const RAYS: Site = isa::sites::DRS_BVH4.at(8);
    /// Shadow items' push order (count compares).
    pub const ORDER: Site = isa::sites::DRS_BVH4.at(9);

    /// Every site of the module (checked for duplicates by the layout test).
    pub const ALL: [Site; 10] = [BIN, OCTANT, STACK, FEW, LEAF, CORE, PAD, ITEM, RAYS, ORDER];
}

/// Trace rays `[0, nrays)` (records as for [`rt::single::trace_bvh4`]).
#[allow(clippy::too_many_arguments)]
pub fn trace<M: Machine>(
    m: &mut M,
    s: &Bvh4Bufs,
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
    s: &Bvh4Bufs,
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
    let inf = m.splat(f32::INFINITY);
    let zero_v = m.splat(0.0);
    // ---- direction binning: 8 initial items ----
    m.region(Region::Setup);
    let nr = m.int(nrays as i64);
    let mut i = m.int(0);
    loop {
        let ro = m.s_shift(Shift::Shl, i, 5);
        let rec = m.load_repeat(trav, At::idx(ro, 1, 0), 4);
        let neg = m.cmp(Cmp::Lt, rec, zero_v);
        let bits = m.movemask(neg);
        let seven = m.int(7);
        let oct = m.s_and(bits, seven);
        let cnt = m.s_load(&st.counters, At::idx(oct, 8, 0), 8, false);
        let cap2v = m.int(cap2);
        let list_base = m.s_op(isa::SOp::Mul, oct, cap2v);
        let slot = m.s_shift(Shift::Shl, cnt, 1);
        let addr = m.s_add(list_base, slot);
        m.s_store(&mut st.lists, At::idx(addr, 1, 0), 2, i);
        let c1 = m.s_addi(cnt, 1);
        m.s_store(&mut st.counters, At::idx(oct, 8, 0), 8, c1);
        i = m.s_addi(i, 1);
        if !m.branch_if(site::BIN, Cmp::Lt, i, nr) {
            break;
        }
    }
    let mut sp = m.int(0);
    for oct in (0..8usize).rev() {
        let cnt = m.s_load(&st.counters, At::off(8 * oct), 8, false);
        if !m.branch_if(site::OCTANT, Cmp::Gt, cnt, zero) {
            continue;
        }
        let octv = m.int(oct as i64);
        let root = m.int(0);
        pad_and_push(m, st, &mut sp, oct, root, zero, cnt, octv, r);
    }
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
        let oct = m.s_load(&st.items, At::idx(io, 1, 5), 1, false);
        let start = m.s_load(&st.items, At::idx(io, 1, 8), 4, false);
        let count = m.s_load(&st.items, At::idx(io, 1, 12), 4, false);
        // Reclaim: this item's range is the last of its list.
        m.s_store(&mut st.counters, At::idx(list, 8, 0), 8, start);
        let cap2v = m.int(cap2);
        let lbase = m.s_op(isa::SOp::Mul, list, cap2v);
        let first = m.s_shift(Shift::Shl, start, 1);
        let rays_at = m.s_add(lbase, first); // byte offset of the item's first index
        let few = m.int(FALLBACK);
        if m.branch_if(site::FEW, Cmp::Lt, count, few) {
            m.region(Region::SingleRay);
            for_each_ray(m, &st.lists, rays_at, count, |m, ray| {
                trace_ray_bvh4(
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
        core_node::<M, N>(
            m, s, st, trav, &mut sp, node, oct, rays_at, count, inf, policy,
        );
    }
}

/// Reserve `r - 1` padding slots after an item's last index (a copy of it),
/// set the list counter past them, and push the item.
#[allow(clippy::too_many_arguments)]
pub(crate) fn pad_and_push<M: Machine>(
    m: &mut M,
    st: &mut StreamBufs,
    sp: &mut M::S,
    list: usize,
    node: M::S,
    start: M::S,
    end: M::S,
    oct: M::S,
    r: usize,
) {
    let base = list * st.cap * 2;
    let last_at = m.s_addi(end, -1);
    let last = m.s_load(&st.lists, At::idx(last_at, 2, base), 2, false);
    for k in 0..r - 1 {
        m.s_store(&mut st.lists, At::idx(end, 2, base + 2 * k), 2, last);
    }
    let reserved = m.s_addi(end, (r - 1) as i64);
    m.s_store(&mut st.counters, At::off(8 * list), 8, reserved);
    let count = m.s_sub(end, start);
    let listv = m.int(list as i64);
    let io = m.s_shift(Shift::Shl, *sp, 4);
    m.s_store(&mut st.items, At::idx(io, 1, 0), 4, node);
    m.s_store(&mut st.items, At::idx(io, 1, 4), 1, listv);
    m.s_store(&mut st.items, At::idx(io, 1, 5), 1, oct);
    m.s_store(&mut st.items, At::idx(io, 1, 8), 4, start);
    m.s_store(&mut st.items, At::idx(io, 1, 12), 4, count);
    *sp = m.s_addi(*sp, 1);
}

/// Call `f` with each ray index of an item (`count` u16 indices at byte `at` of `lists`).
pub(crate) fn for_each_ray<M: Machine>(
    m: &mut M,
    lists: &Buf,
    at: M::S,
    count: M::S,
    mut f: impl FnMut(&mut M, M::S),
) {
    let mut j = m.int(0);
    loop {
        // The index lives at byte `at + 2j`.
        let addr = m.s_shift(Shift::Shl, j, 1);
        let addr = m.s_add(addr, at);
        let ray = m.s_load(lists, At::idx(addr, 1, 0), 2, false);
        f(m, ray);
        j = m.s_addi(j, 1);
        if !m.branch_if(site::RAYS, Cmp::Lt, j, count) {
            break;
        }
    }
}

/// Every ray of a leaf item against the leaf's block, loaded once.
#[allow(clippy::too_many_arguments)]
pub(crate) fn leaf_item<M: Machine>(
    m: &mut M,
    tris: &Buf,
    trav: &mut Buf,
    isect: &Buf,
    hits: &mut Buf,
    lists: &Buf,
    node: M::S,
    at: M::S,
    count: M::S,
    policy: HitPolicy,
) {
    m.region(Region::Leaf);
    let width = M::LANES.min(8);
    let passes = 8 / width;
    let idx_mask = m.int(i64::from(!scene::bvh::LEAF));
    let blk = m.s_and(node, idx_mask);
    let bytes = m.int(BLOCK_BYTES as i64);
    let bb = m.s_op(isa::SOp::Mul, blk, bytes);
    let blocks: Vec<_> = (0..passes)
        .map(|p| load_block(m, tris, bb, p, width))
        .collect();
    for_each_ray(m, lists, at, count, |m, ray| {
        let ro = m.s_shift(Shift::Shl, ray, 5);
        let bc = |m: &mut M, b: &Buf, k: usize| m.load_bcast(b, At::idx(ro, 1, 4 * k));
        let org = [bc(m, isect, 0), bc(m, isect, 1), bc(m, isect, 2)];
        let dir = [bc(m, isect, 4), bc(m, isect, 5), bc(m, isect, 6)];
        let mut tfar = bc(m, trav, 7);
        let mut best = None;
        for (p, b) in blocks.iter().enumerate() {
            if let Some(h) = intersect(m, b, width, &org, &dir, tfar) {
                tfar = h.tb;
                best = Some((p, h));
            }
        }
        if let Some((p, h)) = best {
            let ho = m.s_shift(Shift::Shl, ray, 4);
            let prim = m.s_load(
                tris,
                At::idx(bb, 1, 32 * 9 + 4 * (width * p + h.lane)),
                4,
                true,
            );
            m.x_store(hits, At::idx(ho, 1, 0), h.t);
            m.x_store(hits, At::idx(ho, 1, 4), h.u);
            m.x_store(hits, At::idx(ho, 1, 8), h.v);
            m.s_store(hits, At::idx(ho, 1, 12), 4, prim);
            // A shadow ray is done: t_far = -1 fails every later box test.
            let tf = if policy.is_any() { m.float(-1.0) } else { h.t };
            m.x_store(trav, At::idx(ro, 1, 28), tf);
        }
    });
}

/// Push order of a shadow node's items: the item with the most rays is
/// popped first (pushed last). `counts` are the items' ray counts; the
/// comparisons of an insertion sort are recorded branches.
pub(crate) fn larger_last<M: Machine>(m: &mut M, counts: &[M::S], site: isa::Site) -> Vec<usize> {
    let mut order: Vec<usize> = Vec::with_capacity(counts.len());
    for k in 0..counts.len() {
        let mut at = order.len();
        while at > 0 && m.branch_if(site, Cmp::Lt, counts[k], counts[order[at - 1]]) {
            at -= 1;
        }
        order.insert(at, k);
    }
    order
}

/// One inner node: the core loop over the item's rays, then the new items.
#[allow(clippy::too_many_arguments)]
fn core_node<M: Machine, const N: usize>(
    m: &mut M,
    s: &Bvh4Bufs,
    st: &mut StreamBufs,
    trav: &Buf,
    sp: &mut M::S,
    node: M::S,
    oct: M::S,
    at: M::S,
    count: M::S,
    inf: M::F,
    policy: HitPolicy,
) {
    let r = N / 4;
    m.region(Region::Traversal);
    let base = m.s_shift(Shift::Shl, node, 7);
    let (near, far) = node_planes(m, s, base, oct);
    let vmask = valid_mask::<M, N>(m, s, base);
    // List counters into registers: each new item starts where its list ends.
    let nlists = if policy.is_any() { 4 } else { 9 };
    let starts: Vec<M::S> = (0..nlists)
        .map(|k| m.s_load(&st.counters, At::off(8 * k), 8, false))
        .collect();
    let mut cnt = starts.clone();
    m.region(Region::CoreLoop);
    let sites = (site::CORE, site::PAD);
    core_loop::<M, N>(
        m,
        st,
        trav,
        (at, count),
        &mut cnt,
        sites,
        move |m, dir_near, org_far| {
            // The patterns named as constants here (not captured): each
            // permute then compiles to one shuffle natively.
            let sp4 = &Pat::<N>::SPLAT;
            let mut tn = m.permute(dir_near, &sp4[3]);
            let mut tf = m.permute(org_far, &sp4[3]);
            for a in 0..3 {
                let d = m.permute(dir_near, &sp4[a]);
                let o = m.permute(org_far, &sp4[a]);
                let t0 = m.fmsub(near[a], d, o);
                let t1 = m.fmsub(far[a], d, o);
                tn = m.max(tn, t0);
                tf = m.min(tf, t1);
            }
            let hit = m.cmp(Cmp::Le, tn, tf);
            let hbits = m.movemask(hit);
            let hbits = m.s_and(hbits, vmask);
            if policy.is_any() {
                // Shadow rays: one list per child, no order.
                let shr = |m: &mut M, v: M::S, n: u32| m.s_shift(Shift::Shr, v, n);
                let c = [hbits, shr(m, hbits, 1), shr(m, hbits, 2), shr(m, hbits, 3)];
                return conds(m, &c);
            }
            closest_conds::<M, N>(m, (hit, tn, hbits), inf)
        },
    );
    push_items(m, s, st, sp, (base, oct, r), (&starts, &cnt), policy);
}

/// Near and far planes per axis from the octant (constant over the item),
/// each repeated for the rays of an iteration.
fn node_planes<M: Machine>(
    m: &mut M,
    s: &Bvh4Bufs,
    base: M::S,
    oct: M::S,
) -> ([M::F; 3], [M::F; 3]) {
    let planes: [(M::F, M::F); 3] = std::array::from_fn(|a| {
        let sh = m.s_shift(Shift::Shr, oct, a as u32);
        let one = m.int(1);
        let neg = m.s_and(sh, one).get() as usize;
        let near = m.load_repeat(&s.nodes, At::idx(base, 1, 16 * (2 * a + neg)), 4);
        (
            near,
            m.load_repeat(&s.nodes, At::idx(base, 1, 16 * (2 * a + 1 - neg)), 4),
        )
    });
    (planes.map(|p| p.0), planes.map(|p| p.1))
}

/// The node's valid children, repeated for the LANES/4 rays of an
/// iteration (4 bits each).
fn valid_mask<M: Machine, const N: usize>(m: &mut M, s: &Bvh4Bufs, base: M::S) -> M::S {
    let r = N / 4;
    let valid = m.s_load(&s.nodes, At::idx(base, 1, 112), 4, false);
    let mut vmask = valid;
    for q in 1..r {
        let sh = m.s_shift(Shift::Shl, valid, 4 * q as u32);
        vmask = m.s_op(isa::SOp::Or, vmask, sh);
    }
    vmask
}

/// The 9 list conditions of closest-hit rays from the hit mask, the entry
/// distances and the hit bits: the c0-c1-c0-c2-c3-c2-c0-c1-c0 order of
/// each ray's hit children, bit-parallel for all rays of the iteration.
/// Inlined into the core loop's step: a call there spilled the loop's
/// vector registers around it every iteration.
#[inline(always)]
fn closest_conds<M: Machine, const N: usize>(
    m: &mut M,
    (hit, tn, hbits): (M::K, M::F, M::S),
    inf: M::F,
) -> [M::S; 9] {
    let (swp, swg) = (&Pat::<N>::SWAP_PAIRS, &Pat::<N>::SWAP_GROUPS);
    let shr = |m: &mut M, v: M::S, n: u32| m.s_shift(Shift::Shr, v, n);
    let nsel = m.select(hit, tn, inf);
    let sw = m.permute(nsel, swp);
    let lt = m.cmp(Cmp::Lt, nsel, sw);
    let abits = m.movemask(lt);
    let pm = m.min(nsel, sw);
    let gs = m.permute(pm, swg);
    let le = m.cmp(Cmp::Le, pm, gs);
    let gbits = m.movemask(le);
    // The 9 list conditions, bit-parallel for all r rays at once: ray q's
    // condition k is bit 4q of conds[k] (other bits are don't-care).
    let all = m.int(((1u64 << N.max(16)) - 1) as i64);
    let (h0, h1, h2, h3) = (hbits, shr(m, hbits, 1), shr(m, hbits, 2), shr(m, hbits, 3));
    let (a0, a2, g0) = (abits, shr(m, abits, 2), gbits);
    let na0 = m.s_op(isa::SOp::Xor, a0, all);
    let na2 = m.s_op(isa::SOp::Xor, a2, all);
    let ng0 = m.s_op(isa::SOp::Xor, g0, all);
    let hg = m.s_and(h0, g0);
    let hng = m.s_and(h0, ng0);
    [
        m.s_and(hg, a0),
        m.s_and(h1, g0),
        m.s_and(hg, na0),
        m.s_and(h2, a2),
        h3,
        m.s_and(h2, na2),
        m.s_and(hng, a0),
        m.s_and(h1, ng0),
        m.s_and(hng, na0),
    ]
}

/// The node's new items, pushed so that the first is popped first
/// (closest hit: item 0; any hit: the largest).
fn push_items<M: Machine>(
    m: &mut M,
    s: &Bvh4Bufs,
    st: &mut StreamBufs,
    sp: &mut M::S,
    (base, oct, r): (M::S, M::S, usize),
    (starts, cnt): (&[M::S], &[M::S]),
    policy: HitPolicy,
) {
    m.region(Region::Traversal);
    if policy.is_any() {
        // List k holds child k's rays; the largest item is popped first.
        let counts: Vec<M::S> = (0..4).map(|k| m.s_sub(cnt[k], starts[k])).collect();
        for k in larger_last(m, &counts, site::ORDER) {
            if !m.branch_if(site::ITEM, Cmp::Gt, cnt[k], starts[k]) {
                continue;
            }
            let child = m.s_load(&s.nodes, At::idx(base, 1, 96 + 4 * k), 4, false);
            pad_and_push(m, st, sp, k, child, starts[k], cnt[k], oct, r);
        }
        return;
    }
    // New items, pushed so that item 0 is popped first.
    for k in (0..9).rev() {
        if !m.branch_if(site::ITEM, Cmp::Gt, cnt[k], starts[k]) {
            continue;
        }
        let child = m.s_load(
            &s.nodes,
            At::idx(base, 1, 96 + 4 * CHILD_OF_ITEM[k]),
            4,
            false,
        );
        pad_and_push(m, st, sp, k, child, starts[k], cnt[k], oct, r);
    }
}
