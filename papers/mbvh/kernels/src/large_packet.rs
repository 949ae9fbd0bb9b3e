//! Large packets with interval-arithmetic culling: the paper's baseline,
//! Boulos et al. 2007 (their packets traverse as Wald et al. 2007's BVH
//! packets do). A packet is `P` consecutive rays of a stream (the paths of
//! neighbouring samples, of one ray type) held as `P / W` SIMD groups of
//! `W` rays in memory. Traversal keeps, per stack entry, the packet's first
//! active group: at a child box the first active group is tested (the
//! "first hit" test); if no ray of it hits, the packet's interval bounds
//! (origins and inverse directions, per axis) are tested against the box
//! and a miss culls the child for the whole packet; otherwise the groups
//! after it are tested until one hits, which becomes the child's first
//! active group (none: culled). Children are visited nearest first (by
//! their first hit group's entry). A leaf tests every triangle against the
//! groups from the first active one.
//!
//! Deviations (papers/mbvh/README.md): the tree is the same 4-wide MBVH as
//! the other kernels (Boulos et al. traverse a binary BVH; the counters per
//! ray compare traversal methods over one tree), and the interval test runs
//! on scalar floats (the box's six planes against the packet's twelve
//! bounds) where an SSE version would pack the axes into lanes.

use crate::layout::{node_bytes, MbvhBufs};
use crate::shared::{
    broadcast_triangle, leaf_blocks, row, slab_axis, slab_hits, soa_hit, soa_records,
    sort_farthest_first,
};
use crate::stats::Counters;
use isa::{At, BinOp, Buf, Cmp, Machine, MemKind, Region, Shift};
use rt::single::moller;
use scene::bvh::LEAF;
use scene::{Hit, HitPolicy};

/// Branch sites of the kernel.
pub mod site {
    use isa::Site;
    const B: isa::sites::SiteBlock = isa::sites::MBVH_LARGE;
    /// More packets?
    pub const PACKETS: Site = B.at(0);
    /// Stack empty?
    pub const STACK: Site = B.at(1);
    /// Leaf?
    pub const LEAF: Site = B.at(2);
    /// Child slot used?
    pub const SLOT: Site = B.at(3);
    /// Does the first active group hit the child?
    pub const FIRST_HIT: Site = B.at(4);
    /// Interval bounds usable (every axis's directions of one sign)?
    pub const IA_OK: Site = B.at(5);
    /// Does the interval test cull the child?
    pub const IA_CULL: Site = B.at(6);
    /// Does a later group hit the child?
    pub const GROUP_HIT: Site = B.at(7);
    /// More groups?
    pub const GROUPS: Site = B.at(8);
    /// One compare-exchange of the child sort.
    pub const SORT: Site = B.at(9);
    /// Any ray passes a triangle's edge tests?
    pub const TRI_EDGE: Site = B.at(10);
    /// Any ray passes its depth test?
    pub const TRI_DEPTH: Site = B.at(11);
    /// More triangles?
    pub const TRI: Site = B.at(12);
    /// Is an axis's direction positive for the whole packet?
    pub const SIGN: Site = B.at(13);
    /// More groups in the bounds pass?
    pub const BOUNDS: Site = B.at(14);

    /// Every site of the module (checked for duplicates by the layout test).
    pub const ALL: [Site; 15] = [
        PACKETS, STACK, LEAF, SLOT, FIRST_HIT, IA_OK, IA_CULL, GROUP_HIT, GROUPS, SORT, TRI_EDGE,
        TRI_DEPTH, TRI, SIGN, BOUNDS,
    ];
}

/// Rays per packet by default: 8 x 8 (the packet of Wald et al. 2007's BVH
/// traversal, which Boulos et al. 2007 extend to secondary rays; a named
/// assumption, its sensitivity measured in papers/mbvh/README.md).
pub const DEFAULT_PACKET: usize = 64;

/// The kernel's buffers for one stream.
pub struct LargeBufs {
    /// SoA group records, `groups` per packet.
    pub records: Buf,
    /// Stack entries: (node, first active group) as two u32.
    stack: Buf,
    npackets: usize,
    groups: usize,
    nrays: usize,
    w: usize,
}

impl LargeBufs {
    /// Rays `(org, dir, tfar)` in packets of `packet` consecutive rays (a
    /// multiple of the lanes; the last padded with rays that hit nothing:
    /// t_far -1, inside the packet's bounds).
    ///
    /// # Panics
    /// If `packet` is not a positive multiple of the machine's lanes.
    pub fn new<M: Machine>(
        m: &mut M,
        tree: &MbvhBufs,
        (org, dir, tfar): (&[[f32; 3]], &[[f32; 3]], &[f32]),
        packet: usize,
    ) -> LargeBufs {
        let w = M::LANES;
        assert!(
            packet >= w && packet.is_multiple_of(w),
            "packet of {packet} rays"
        );
        let groups = packet / w;
        let np = org.len().div_ceil(packet).max(1);
        // Padding copies the packet's first ray (its bounds unchanged).
        let v = soa_records(w, np * packet, |i| {
            let head = i - i % packet;
            if i < org.len() {
                (org[i], dir[i], tfar[i])
            } else if head < org.len() {
                (org[head], dir[head], -1.0)
            } else {
                ([0.0; 3], [1.0; 3], -1.0)
            }
        });
        let entries = 4 * w * (tree.depth + 2);
        let sp = m.space();
        LargeBufs {
            records: sp.alloc_f32(MemKind::Rays, "mbvh-large-packets", &v, 64),
            stack: sp.alloc(MemKind::Stack, "mbvh-large-stack", 8 * entries, 64),
            npackets: np,
            groups,
            nrays: org.len(),
            w,
        }
    }

    /// Ray `i`'s answer.
    #[must_use]
    pub fn hit(&self, i: usize) -> Hit {
        soa_hit(&self.records, self.w, i)
    }
}

/// Byte offset of group `g`'s row `r` from its packet's first group.
fn group_base<M: Machine>(m: &mut M, packet_base: M::S, g: M::S) -> M::S {
    let w = M::LANES;
    let gb = m.s_shift(Shift::Shl, g, (4 * row::ROWS * w).trailing_zeros());
    m.s_add(packet_base, gb)
}

/// A box's (low, high) planes per axis, broadcast.
type Planes<M> = [(<M as Machine>::F, <M as Machine>::F); 3];

/// One group's rays as a box test needs them.
struct Group<M: Machine> {
    org: [M::F; 3],
    idir: [M::F; 3],
    tfar: M::F,
    live: M::K,
}

fn load_group<M: Machine>(m: &mut M, b: &LargeBufs, gb: M::S, policy: HitPolicy) -> Group<M> {
    let w = M::LANES;
    let mut ld = |r: usize| m.load(&b.records, At::idx(gb, 1, 4 * w * r));
    let org = [ld(row::ORG), ld(row::ORG + 1), ld(row::ORG + 2)];
    let idir = [ld(row::IDIR), ld(row::IDIR + 1), ld(row::IDIR + 2)];
    let tfar = ld(row::TFAR);
    let prim = |m: &mut M| {
        let pf = m.load(&b.records, At::idx(gb, 1, 4 * w * row::PRIM));
        m.bits_to_i(pf)
    };
    let live = live_lanes(m, tfar, prim, policy);
    Group {
        org,
        idir,
        tfar,
        live,
    }
}

/// Lanes still looking for a hit: t_far not negative, and for an any-hit
/// (shadow) ray no hit yet (its triangle row from `prim`, read only then).
fn live_lanes<M: Machine>(
    m: &mut M,
    tfar: M::F,
    prim: impl FnOnce(&mut M) -> M::I,
    policy: HitPolicy,
) -> M::K {
    let zero = m.splat(0.0);
    let open = m.cmp(Cmp::Ge, tfar, zero);
    if !policy.is_any() {
        return open;
    }
    let prim = prim(m);
    let none = m.splat_i(-1);
    let unhit = m.icmp(Cmp::Eq, prim, none);
    m.kand(open, unhit)
}

/// The packet's interval bounds, per axis: origin min and max, inverse
/// direction min and max.
struct Bounds<M: Machine> {
    o: [(M::X, M::X); 3],
    id: [(M::X, M::X); 3],
    /// Every axis's directions have one sign (the interval test applies).
    usable: bool,
    /// Per axis: directions positive (the entry plane is the box's low one).
    positive: [bool; 3],
}

/// Reduce the packet's groups to its interval bounds.
fn packet_bounds<M: Machine>(m: &mut M, b: &mut LargeBufs, pb: M::S) -> Bounds<M> {
    let w = M::LANES;
    let ld = |m: &mut M, gb: M::S, r: usize| m.load(&b.records, At::idx(gb, 1, 4 * w * r));
    let mut lo: Vec<M::F> = (0..6).map(|r| ld(m, pb, [0, 1, 2, 6, 7, 8][r])).collect();
    let mut hi = lo.clone();
    let mut g = m.int(1);
    let ng = m.int(b.groups as i64);
    for _ in 1..b.groups {
        let gb = group_base(m, pb, g);
        for (k, r) in [0, 1, 2, 6, 7, 8].into_iter().enumerate() {
            let x = ld(m, gb, r);
            lo[k] = m.min(lo[k], x);
            hi[k] = m.max(hi[k], x);
        }
        g = m.s_addi(g, 1);
        if !m.branch_if(site::BOUNDS, Cmp::Lt, g, ng) {
            break;
        }
    }
    let red = |m: &mut M, k: usize| (m.reduce(BinOp::Min, lo[k]), m.reduce(BinOp::Max, hi[k]));
    let o = [red(m, 0), red(m, 1), red(m, 2)];
    let id = [red(m, 3), red(m, 4), red(m, 5)];
    let zero = m.float(0.0);
    let mut positive = [false; 3];
    let mut usable = true;
    for a in 0..3 {
        let pos = m.x_cmp(Cmp::Gt, id[a].0, zero);
        positive[a] = m.branch(site::SIGN, pos);
        if !positive[a] {
            let neg = m.x_cmp(Cmp::Lt, id[a].1, zero);
            usable &= m.branch(site::IA_OK, neg);
        }
    }
    Bounds {
        o,
        id,
        usable,
        positive,
    }
}

/// Trace every packet of `b`.
pub fn trace<M: Machine>(
    m: &mut M,
    tree: &MbvhBufs,
    b: &mut LargeBufs,
    policy: HitPolicy,
    c: &mut Counters,
) {
    let w = M::LANES;
    c.rays += b.nrays as u64;
    let mut p = m.int(0);
    let np = m.int(b.npackets as i64);
    let packet_bytes = 4 * row::ROWS * w * b.groups;
    for _ in 0..b.npackets {
        m.region(Region::Traversal);
        let stride = m.int(packet_bytes as i64);
        let pb = m.s_op(isa::SOp::Mul, p, stride);
        let bounds = packet_bounds(m, b, pb);
        walk(m, tree, b, pb, &bounds, policy, c);
        p = m.s_addi(p, 1);
        if !m.branch_if(site::PACKETS, Cmp::Lt, p, np) {
            break;
        }
    }
}

/// The packet's stack loop.
#[allow(clippy::too_many_arguments)]
fn walk<M: Machine>(
    m: &mut M,
    tree: &MbvhBufs,
    b: &mut LargeBufs,
    pb: M::S,
    bounds: &Bounds<M>,
    policy: HitPolicy,
    c: &mut Counters,
) {
    let mut sp = m.int(0);
    let root = m.int(0);
    m.s_store(&mut b.stack, At::off(0), 4, root);
    m.s_store(&mut b.stack, At::off(4), 4, root);
    sp = m.s_addi(sp, 1);
    loop {
        m.region(Region::Traversal);
        let zero = m.int(0);
        if !m.branch_if(site::STACK, Cmp::Gt, sp, zero) {
            break;
        }
        sp = m.s_addi(sp, -1);
        let node = m.s_load(&b.stack, At::idx(sp, 8, 0), 4, false);
        let first = m.s_load(&b.stack, At::idx(sp, 8, 4), 4, false);
        c.tasks += 1;
        let leaf_flag = m.int(i64::from(LEAF));
        let lf = m.s_and(node, leaf_flag);
        if m.branch(site::LEAF, lf) {
            leaf(m, tree, b, pb, (node, first), policy, c);
        } else {
            sp = inner(m, tree, b, pb, bounds, (node, first, sp), policy, c);
        }
    }
}

/// Each used child box against the packet (first hit, interval test, the
/// later groups); the children hit pushed with their first active group,
/// the nearest last. Returns the new stack top.
#[allow(clippy::too_many_arguments)]
fn inner<M: Machine>(
    m: &mut M,
    tree: &MbvhBufs,
    b: &mut LargeBufs,
    pb: M::S,
    bounds: &Bounds<M>,
    (node, first, mut sp): (M::S, M::S, M::S),
    policy: HitPolicy,
    c: &mut Counters,
) -> M::S {
    let w = M::LANES;
    let nb = m.s_shift(Shift::Shl, node, node_bytes(w).trailing_zeros());
    let vw = m.s_load(&tree.nodes, At::idx(nb, 1, 28 * w), 4, false);
    let fb = group_base(m, pb, first);
    let g0 = load_group(m, b, fb, policy);
    let mut kids: Vec<(M::S, M::S, M::X)> = Vec::with_capacity(w);
    for ch in 0..w {
        let bit = m.int(1 << ch);
        let used = m.s_and(vw, bit);
        if !m.branch(site::SLOT, used) {
            continue;
        }
        c.box_fetches += 1;
        let mut planes = [(g0.tfar, g0.tfar); 3];
        for (a, pl) in planes.iter_mut().enumerate() {
            let lo = m.load_bcast(&tree.nodes, At::idx(nb, 1, 4 * w * (2 * a) + 4 * ch));
            let hi = m.load_bcast(&tree.nodes, At::idx(nb, 1, 4 * w * (2 * a + 1) + 4 * ch));
            *pl = (lo, hi);
        }
        if let Some((g, dmin)) = first_hit_group(
            m,
            tree,
            b,
            pb,
            bounds,
            (nb, ch, &planes),
            (first, &g0),
            policy,
            c,
        ) {
            let child = m.s_load(&tree.nodes, At::idx(nb, 1, 24 * w + 4 * ch), 4, false);
            kids.push((child, g, dmin));
        }
    }
    sort_farthest_first(m, &mut kids, |k: &(M::S, M::S, M::X)| k.2, site::SORT);
    for (child, g, _) in kids {
        m.s_store(&mut b.stack, At::idx(sp, 8, 0), 4, child);
        m.s_store(&mut b.stack, At::idx(sp, 8, 4), 4, g);
        sp = m.s_addi(sp, 1);
    }
    sp
}

/// One group's slab test against a box: the lanes that hit, and the
/// smallest entry among them (+inf for none).
fn group_box<M: Machine>(m: &mut M, g: &Group<M>, planes: &Planes<M>) -> (M::S, M::X) {
    let zero = m.splat(0.0);
    let mut near = [zero; 3];
    let mut far = [zero; 3];
    for a in 0..3 {
        (near[a], far[a]) = slab_axis(m, planes[a], g.org[a], g.idir[a]);
    }
    let (hit, tn) = slab_hits(m, near, far, zero, g.tfar);
    let hit = m.kand(hit, g.live);
    let inf = m.splat(f32::INFINITY);
    let d = m.select(hit, tn, inf);
    (m.any(hit), m.reduce(BinOp::Min, d))
}

/// The child's first active group: the packet's first if it hits, else
/// (unless the interval test culls the box) the first later group that
/// does; None: the packet misses the child.
#[allow(clippy::too_many_arguments)]
fn first_hit_group<M: Machine>(
    m: &mut M,
    tree: &MbvhBufs,
    b: &LargeBufs,
    pb: M::S,
    bounds: &Bounds<M>,
    (nb, ch, planes): (M::S, usize, &Planes<M>),
    (first, g0): (M::S, &Group<M>),
    policy: HitPolicy,
    c: &mut Counters,
) -> Option<(M::S, M::X)> {
    c.box_tests += 1;
    let (any, dmin) = group_box(m, g0, planes);
    if m.branch(site::FIRST_HIT, any) {
        return Some((first, dmin));
    }
    if bounds.usable {
        c.box_tests += 1;
        let culled = interval_misses(m, tree, bounds, nb, ch);
        if m.branch(site::IA_CULL, culled) {
            return None;
        }
    }
    let ng = m.int(b.groups as i64);
    let mut g = m.s_addi(first, 1);
    loop {
        if !m.branch_if(site::GROUPS, Cmp::Lt, g, ng) {
            return None;
        }
        c.box_tests += 1;
        let gb = group_base(m, pb, g);
        let grp = load_group(m, b, gb, policy);
        let (any, dmin) = group_box(m, &grp, planes);
        if m.branch(site::GROUP_HIT, any) {
            return Some((g, dmin));
        }
        g = m.s_addi(g, 1);
    }
}

/// Interval arithmetic (Boulos et al. 2006): the box's entry and exit
/// planes per axis (by the packet's direction signs) against the packet's
/// origin and inverse-direction intervals. The packet misses when the
/// latest lower bound of an axis's entry (or 0) exceeds the earliest upper
/// bound of an axis's exit.
fn interval_misses<M: Machine>(
    m: &mut M,
    tree: &MbvhBufs,
    bounds: &Bounds<M>,
    nb: M::S,
    ch: usize,
) -> M::S {
    let w = M::LANES;
    let mut entry_lo = m.float(0.0);
    let mut exit_hi = m.float(f32::INFINITY);
    for a in 0..3 {
        let pos = bounds.positive[a];
        let (en, ex) = if pos { (0, 1) } else { (1, 0) };
        let pe = m.x_load(&tree.nodes, At::idx(nb, 1, 4 * w * (2 * a + en) + 4 * ch));
        let px = m.x_load(&tree.nodes, At::idx(nb, 1, 4 * w * (2 * a + ex) + 4 * ch));
        let (omin, omax) = bounds.o[a];
        let (idmin, idmax) = bounds.id[a];
        // (plane - o) * id is monotone in o for one sign of id: its least
        // value takes the farthest origin, its greatest the nearest.
        let (o_lo, o_hi) = if pos { (omax, omin) } else { (omin, omax) };
        let de = m.x_op(BinOp::Sub, pe, o_lo);
        let e0 = m.x_op(BinOp::Mul, de, idmin);
        let e1 = m.x_op(BinOp::Mul, de, idmax);
        let e = m.x_op(BinOp::Min, e0, e1);
        entry_lo = m.x_op(BinOp::Max, entry_lo, e);
        let dx = m.x_op(BinOp::Sub, px, o_hi);
        let x0 = m.x_op(BinOp::Mul, dx, idmin);
        let x1 = m.x_op(BinOp::Mul, dx, idmax);
        let x = m.x_op(BinOp::Max, x0, x1);
        exit_hi = m.x_op(BinOp::Min, exit_hi, x);
    }
    m.x_cmp(Cmp::Gt, entry_lo, exit_hi)
}

/// The leaf's triangles against the groups from the first active one.
fn leaf<M: Machine>(
    m: &mut M,
    tree: &MbvhBufs,
    b: &mut LargeBufs,
    pb: M::S,
    (node, first): (M::S, M::S),
    policy: HitPolicy,
    c: &mut Counters,
) {
    let w = M::LANES;
    m.region(Region::Leaf);
    let (fb, ntri) = leaf_blocks(m, node);
    let ng = m.int(b.groups as i64);
    let mut g = first;
    loop {
        let gb = group_base(m, pb, g);
        let ld = |m: &mut M, r: usize| m.load(&b.records, At::idx(gb, 1, 4 * w * r));
        let org = [ld(m, row::ORG), ld(m, row::ORG + 1), ld(m, row::ORG + 2)];
        let dir = [ld(m, row::DIR), ld(m, row::DIR + 1), ld(m, row::DIR + 2)];
        let mut tfar = ld(m, row::TFAR);
        let pf = ld(m, row::PRIM);
        let mut prim = m.bits_to_i(pf);
        let mut u = ld(m, row::U);
        let mut v = ld(m, row::V);
        let mut act = live_lanes(m, tfar, |_| prim, policy);
        let mut ti = m.int(0);
        let mut t = 0;
        loop {
            let blk = broadcast_triangle(m, &tree.tris, fb, t);
            c.prim_tests += 1;
            c.prim_lanes += u64::from(m.bits(act).count_ones());
            let sites = [site::TRI_EDGE, site::TRI_DEPTH];
            if let Some(h) = moller(m, &blk, (&org, &dir, tfar), Some(act), sites) {
                tfar = m.select(h.valid, h.t, tfar);
                prim = m.iselect(h.valid, blk.prim, prim);
                u = m.select(h.valid, h.u, u);
                v = m.select(h.valid, h.v, v);
                if policy.is_any() {
                    let open = m.knot(h.valid);
                    act = m.kand(act, open);
                }
            }
            t += 1;
            ti = m.s_addi(ti, 1);
            if !m.branch_if(site::TRI, Cmp::Lt, ti, ntri) {
                break;
            }
        }
        let mut st =
            |m: &mut M, r: usize, x: M::F| m.store(&mut b.records, At::idx(gb, 1, 4 * w * r), x);
        st(m, row::TFAR, tfar);
        let pf = m.bits_to_f(prim);
        st(m, row::PRIM, pf);
        st(m, row::U, u);
        st(m, row::V, v);
        g = m.s_addi(g, 1);
        if !m.branch_if(site::GROUPS, Cmp::Lt, g, ng) {
            break;
        }
    }
}
