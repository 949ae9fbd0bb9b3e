//! Packet traversal of the MBVH (Wald et al. 2001; the paper compares with
//! Boulos et al. 2007's coherent packets): `W` consecutive rays of a stream
//! (the paths of neighbouring samples, of one ray type) in an SoA packet
//! walk the tree together. At an inner node each child box is tested
//! against the whole packet (one SIMD box test and one box fetch per child);
//! children hit by any active ray are pushed with their per-ray entry
//! distances, nearest (by the packet's smallest entry) popped first; a
//! popped entry keeps only the rays that reach it before their hit. Leaves
//! test the packet against one triangle at a time (broadcast).
//!
//! Deviation: Boulos et al. trace larger packets (of 4-wide SIMD groups)
//! with interval-arithmetic culling; these are single SIMD packets of the
//! machine's width, the paper's "4-wide packets" on SSE.

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
    /// More packets?
    pub const PACKETS: Site = isa::sites::MBVH_PACKET.at(0);
    /// Stack empty?
    pub const STACK: Site = isa::sites::MBVH_PACKET.at(1);
    /// Any ray reaches the popped entry before its hit?
    pub const CULL: Site = isa::sites::MBVH_PACKET.at(2);
    /// Leaf?
    pub const LEAF: Site = isa::sites::MBVH_PACKET.at(3);
    /// Child slot used?
    pub const SLOT: Site = isa::sites::MBVH_PACKET.at(4);
    /// Any ray hits the child?
    pub const HIT: Site = isa::sites::MBVH_PACKET.at(5);
    /// One compare-exchange of the child sort.
    pub const SORT: Site = isa::sites::MBVH_PACKET.at(6);
    /// Any ray passes a triangle's edge tests?
    pub const TRI_EDGE: Site = isa::sites::MBVH_PACKET.at(7);
    /// Any ray passes its depth test?
    pub const TRI_DEPTH: Site = isa::sites::MBVH_PACKET.at(8);
    /// More triangles?
    pub const TRI: Site = isa::sites::MBVH_PACKET.at(9);
    /// Shadow packet: any ray not yet occluded?
    pub const ALIVE: Site = isa::sites::MBVH_PACKET.at(10);

    /// Every site of the module (checked for duplicates by the layout test).
    pub const ALL: [Site; 11] = [
        PACKETS, STACK, CULL, LEAF, SLOT, HIT, SORT, TRI_EDGE, TRI_DEPTH, TRI, ALIVE,
    ];
}

/// The kernel's buffers for one stream.
pub struct PacketBufs {
    /// SoA packet records.
    pub packets: Buf,
    nodes_stack: Buf,
    dist_stack: Buf,
    npackets: usize,
    nrays: usize,
    w: usize,
}

impl PacketBufs {
    /// Rays `(org, dir, tfar)` in packets of `W` consecutive rays (the last
    /// padded with rays that hit nothing: t_far -1).
    pub fn new<M: Machine>(
        m: &mut M,
        tree: &MbvhBufs,
        (org, dir, tfar): (&[[f32; 3]], &[[f32; 3]], &[f32]),
    ) -> PacketBufs {
        let w = M::LANES;
        let np = org.len().div_ceil(w).max(1);
        let v = soa_records(w, np * w, |i| {
            if i < org.len() {
                (org[i], dir[i], tfar[i])
            } else {
                ([0.0; 3], [1.0; 3], -1.0)
            }
        });
        let entries = w * (tree.depth + 2);
        let sp = m.space();
        PacketBufs {
            packets: sp.alloc_f32(MemKind::Rays, "mbvh-packets", &v, 64),
            nodes_stack: sp.alloc(MemKind::Stack, "mbvh-packet-nodes", 4 * entries, 64),
            dist_stack: sp.alloc(MemKind::Stack, "mbvh-packet-dists", 4 * w * entries, 64),
            npackets: np,
            nrays: org.len(),
            w,
        }
    }

    /// Ray `i`'s answer.
    #[must_use]
    pub fn hit(&self, i: usize) -> Hit {
        soa_hit(&self.packets, self.w, i)
    }
}

/// One packet's registers.
struct Packet<M: Machine> {
    org: [M::F; 3],
    dir: [M::F; 3],
    idir: [M::F; 3],
    tfar: M::F,
    live: M::K,
    prim: M::I,
    u: M::F,
    v: M::F,
}

/// Trace every packet of `b`.
pub fn trace<M: Machine>(
    m: &mut M,
    tree: &MbvhBufs,
    b: &mut PacketBufs,
    policy: HitPolicy,
    c: &mut Counters,
) {
    let w = M::LANES;
    c.rays += b.nrays as u64;
    let mut p = m.int(0);
    let np = m.int(b.npackets as i64);
    for _ in 0..b.npackets {
        m.region(Region::Traversal);
        let base = m.s_shift(Shift::Shl, p, (4 * row::ROWS * w).trailing_zeros());
        let ld = |m: &mut M, r: usize| m.load(&b.packets, At::idx(base, 1, 4 * w * r));
        let org = [ld(m, 0), ld(m, 1), ld(m, 2)];
        let dir = [ld(m, 3), ld(m, 4), ld(m, 5)];
        let idir = [ld(m, 6), ld(m, 7), ld(m, 8)];
        let tfar = ld(m, row::TFAR);
        let zero = m.splat(0.0);
        let live = m.cmp(Cmp::Ge, tfar, zero);
        let prim = m.splat_i(-1);
        let mut pk = Packet {
            org,
            dir,
            idir,
            tfar,
            live,
            prim,
            u: zero,
            v: zero,
        };
        walk(m, tree, b, &mut pk, policy, c);
        let mut st =
            |m: &mut M, r: usize, x: M::F| m.store(&mut b.packets, At::idx(base, 1, 4 * w * r), x);
        st(m, row::TFAR, pk.tfar);
        let pf = m.bits_to_f(pk.prim);
        st(m, row::PRIM, pf);
        st(m, row::U, pk.u);
        st(m, row::V, pk.v);
        p = m.s_addi(p, 1);
        if !m.branch_if(site::PACKETS, Cmp::Lt, p, np) {
            break;
        }
    }
}

/// The packet's stack loop.
fn walk<M: Machine>(
    m: &mut M,
    tree: &MbvhBufs,
    b: &mut PacketBufs,
    pk: &mut Packet<M>,
    policy: HitPolicy,
    c: &mut Counters,
) {
    let w = M::LANES;
    let mut sp = m.int(0);
    let root = m.int(0);
    m.s_store(&mut b.nodes_stack, At::off(0), 4, root);
    let z = m.splat(0.0);
    m.store(&mut b.dist_stack, At::off(0), z);
    sp = m.s_addi(sp, 1);
    loop {
        m.region(Region::Traversal);
        let zero = m.int(0);
        if !m.branch_if(site::STACK, Cmp::Gt, sp, zero) {
            break;
        }
        sp = m.s_addi(sp, -1);
        let node = m.s_load(&b.nodes_stack, At::idx(sp, 4, 0), 4, false);
        let db = m.s_shift(Shift::Shl, sp, (4 * w).trailing_zeros());
        let d = m.load(&b.dist_stack, At::idx(db, 1, 0));
        c.tasks += 1;
        let reach = m.cmp(Cmp::Le, d, pk.tfar);
        let act = m.kand(reach, pk.live);
        let any = m.any(act);
        if !m.branch(site::CULL, any) {
            continue;
        }
        let leaf_flag = m.int(i64::from(LEAF));
        let lf = m.s_and(node, leaf_flag);
        if m.branch(site::LEAF, lf) {
            leaf(m, tree, pk, node, act, policy, c);
            if policy.is_any() {
                let alive = m.any(pk.live);
                if !m.branch(site::ALIVE, alive) {
                    break;
                }
            }
        } else {
            sp = inner(m, tree, b, pk, node, sp, c);
        }
    }
}

/// Each used child box against the packet; hit children pushed with their
/// entry distances, the nearest last. Returns the new stack top.
fn inner<M: Machine>(
    m: &mut M,
    tree: &MbvhBufs,
    b: &mut PacketBufs,
    pk: &Packet<M>,
    node: M::S,
    mut sp: M::S,
    c: &mut Counters,
) -> M::S {
    let w = M::LANES;
    let nb = m.s_shift(Shift::Shl, node, node_bytes(w).trailing_zeros());
    let vw = m.s_load(&tree.nodes, At::idx(nb, 1, 28 * w), 4, false);
    let inf = m.splat(f32::INFINITY);
    let zero = m.splat(0.0);
    let mut kids: Vec<(M::S, M::F, M::X)> = Vec::with_capacity(w);
    for ch in 0..w {
        let bit = m.int(1 << ch);
        let used = m.s_and(vw, bit);
        if !m.branch(site::SLOT, used) {
            continue;
        }
        c.box_tests += 1;
        c.box_fetches += 1;
        let mut near = [zero; 3];
        let mut far = [pk.tfar; 3];
        for a in 0..3 {
            let lo = m.load_bcast(&tree.nodes, At::idx(nb, 1, 4 * w * (2 * a) + 4 * ch));
            let hi = m.load_bcast(&tree.nodes, At::idx(nb, 1, 4 * w * (2 * a + 1) + 4 * ch));
            (near[a], far[a]) = slab_axis(m, (lo, hi), pk.org[a], pk.idir[a]);
        }
        let (hit, tn) = slab_hits(m, near, far, zero, pk.tfar);
        let hit = m.kand(hit, pk.live);
        let any = m.any(hit);
        if !m.branch(site::HIT, any) {
            continue;
        }
        let d = m.select(hit, tn, inf);
        let dmin = m.reduce(BinOp::Min, d);
        let child = m.s_load(&tree.nodes, At::idx(nb, 1, 24 * w + 4 * ch), 4, false);
        kids.push((child, d, dmin));
    }
    sort_farthest_first(m, &mut kids, |k: &(M::S, M::F, M::X)| k.2, site::SORT);
    for (child, d, _) in kids {
        m.s_store(&mut b.nodes_stack, At::idx(sp, 4, 0), 4, child);
        let db = m.s_shift(Shift::Shl, sp, (4 * w).trailing_zeros());
        m.store(&mut b.dist_stack, At::idx(db, 1, 0), d);
        sp = m.s_addi(sp, 1);
    }
    sp
}

/// The packet's active rays `act` against each triangle of the leaf.
fn leaf<M: Machine>(
    m: &mut M,
    tree: &MbvhBufs,
    pk: &mut Packet<M>,
    node: M::S,
    mut act: M::K,
    policy: HitPolicy,
    c: &mut Counters,
) {
    let _w = M::LANES;
    m.region(Region::Leaf);
    let (fb, ntri) = leaf_blocks(m, node);
    let mut ti = m.int(0);
    let mut t = 0;
    loop {
        let blk = broadcast_triangle(m, &tree.tris, fb, t);
        c.prim_tests += 1;
        c.prim_lanes += u64::from(m.bits(act).count_ones());
        let sites = [site::TRI_EDGE, site::TRI_DEPTH];
        if let Some(h) = moller(m, &blk, (&pk.org, &pk.dir, pk.tfar), Some(act), sites) {
            pk.tfar = m.select(h.valid, h.t, pk.tfar);
            pk.prim = m.iselect(h.valid, blk.prim, pk.prim);
            pk.u = m.select(h.valid, h.u, pk.u);
            pk.v = m.select(h.valid, h.v, pk.v);
            if policy.is_any() {
                let open = m.knot(h.valid);
                pk.live = m.kand(pk.live, open);
                act = m.kand(act, open);
                let any = m.any(act);
                if !m.branch(site::ALIVE, any) {
                    break;
                }
            }
        }
        t += 1;
        ti = m.s_addi(ti, 1);
        if !m.branch_if(site::TRI, Cmp::Lt, ti, ntri) {
            break;
        }
    }
}
