//! Single-ray MBVH traversal (Dammertz et al. 2008, Wald et al. 2008), the
//! paper's MBVH baseline: one ray at a time against the `W` boxes of a node
//! (the node's box packet fetched for every box test), hit children pushed
//! on an ordered stack nearest last, entries culled on pop when farther than
//! the ray's hit; leaves test the ray against `W` triangles at once (one
//! block per SIMD primitive test). Same tree and triangle blocks as MBVH RS;
//! rays in the compact record (loaded and broadcast once per ray).

use crate::layout::{block_bytes, node_bytes, MbvhBufs, RayForm, RayRecord};
use crate::shared::{leaf_blocks, slab_hits, sort_farthest_first};
use crate::stats::Counters;
use isa::{At, BinOp, Buf, Cmp, Int, Logic, Machine, MemKind, Region, Shift};
use rt::single::{moller, Block};
use scene::bvh::LEAF;
use scene::{Hit, HitPolicy};

/// Branch sites of the kernel.
pub mod site {
    use isa::Site;
    /// More rays?
    pub const RAYS: Site = isa::sites::MBVH_SINGLE.at(0);
    /// Stack empty?
    pub const STACK: Site = isa::sites::MBVH_SINGLE.at(1);
    /// Popped entry farther than the hit?
    pub const CULL: Site = isa::sites::MBVH_SINGLE.at(2);
    /// Leaf?
    pub const LEAF: Site = isa::sites::MBVH_SINGLE.at(3);
    /// Any child hit?
    pub const ANY: Site = isa::sites::MBVH_SINGLE.at(4);
    /// Another hit child?
    pub const CHILD: Site = isa::sites::MBVH_SINGLE.at(5);
    /// One compare-exchange of the child sort.
    pub const SORT: Site = isa::sites::MBVH_SINGLE.at(6);
    /// Any triangle passes the edge tests?
    pub const TRI_EDGE: Site = isa::sites::MBVH_SINGLE.at(7);
    /// Any triangle passes the depth test?
    pub const TRI_DEPTH: Site = isa::sites::MBVH_SINGLE.at(8);
    /// Another block in the leaf?
    pub const BLOCK: Site = isa::sites::MBVH_SINGLE.at(9);

    /// Every site of the module (checked for duplicates by the layout test).
    pub const ALL: [Site; 10] = [
        RAYS, STACK, CULL, LEAF, ANY, CHILD, SORT, TRI_EDGE, TRI_DEPTH, BLOCK,
    ];
}

/// Bytes of a stack entry: node ref and entry distance.
const ENTRY: usize = 8;

/// The kernel's buffers for one stream.
pub struct SingleBufs {
    /// Ray records (compact form).
    pub rays: Buf,
    rec: RayRecord,
    stack: Buf,
    nrays: usize,
}

impl SingleBufs {
    /// Lay out rays `(org, dir, tfar)` and a stack deep enough for `tree`.
    pub fn new<M: Machine>(
        m: &mut M,
        tree: &MbvhBufs,
        (org, dir, tfar): (&[[f32; 3]], &[[f32; 3]], &[f32]),
    ) -> SingleBufs {
        let rec = RayRecord::of(RayForm::Compact, M::LANES);
        let bytes = rec.records(RayForm::Compact, M::LANES, org, dir, tfar);
        let sp = m.space();
        SingleBufs {
            rays: sp.alloc_bytes(MemKind::Rays, "mbvh-single-rays", bytes, 64),
            rec,
            stack: sp.alloc(
                MemKind::Stack,
                "mbvh-single-stack",
                ENTRY * M::LANES * (tree.depth + 2),
                64,
            ),
            nrays: org.len(),
        }
    }

    /// Ray `i`'s answer.
    #[must_use]
    pub fn hit(&self, i: usize) -> Hit {
        let at = i * self.rec.bytes;
        Hit::from_record(
            self.rays.f32_at(at + self.rec.length),
            self.rays.u32_at(at + self.rec.prim),
        )
    }
}

/// One ray's registers.
struct Ray<M: Machine> {
    org: [M::F; 3],
    dir: [M::F; 3],
    idir: [M::F; 3],
    tmin: M::F,
    tfar: M::F,
    tfar_x: M::X,
    prim: M::S,
    u: M::X,
    v: M::X,
}

/// Trace every ray of `b`.
pub fn trace<M: Machine>(
    m: &mut M,
    tree: &MbvhBufs,
    b: &mut SingleBufs,
    policy: HitPolicy,
    c: &mut Counters,
) {
    c.rays += b.nrays as u64;
    let mut i = m.int(0);
    let n = m.int(b.nrays as i64);
    for _ in 0..b.nrays {
        m.region(Region::SingleRay);
        let rec = m.s_shift(Shift::Shl, i, b.rec.bytes.trailing_zeros());
        let mut ray = load_ray(m, b, rec);
        walk(m, tree, b, &mut ray, policy, c);
        m.region(Region::SingleRay);
        m.x_store(&mut b.rays, At::idx(rec, 1, b.rec.length), ray.tfar_x);
        m.s_store(&mut b.rays, At::idx(rec, 1, b.rec.prim), 4, ray.prim);
        m.x_store(&mut b.rays, At::idx(rec, 1, b.rec.u), ray.u);
        m.x_store(&mut b.rays, At::idx(rec, 1, b.rec.v), ray.v);
        i = m.s_addi(i, 1);
        if !m.branch_if(site::RAYS, Cmp::Lt, i, n) {
            break;
        }
    }
}

fn load_ray<M: Machine>(m: &mut M, b: &SingleBufs, rec: M::S) -> Ray<M> {
    let r = b.rec;
    let bc = |m: &mut M, off: usize| m.load_bcast(&b.rays, At::idx(rec, 1, off));
    let org = r.org.map(|o| bc(m, o));
    let dir = r.dir.map(|o| bc(m, o));
    let idir = r.idir.map(|o| bc(m, o));
    let tmin = bc(m, r.tmin);
    let tfar = bc(m, r.length);
    let tfar_x = m.x_load(&b.rays, At::idx(rec, 1, r.length));
    let prim = m.int(-1);
    let u = m.float(0.0);
    Ray {
        org,
        dir,
        idir,
        tmin,
        tfar,
        tfar_x,
        prim,
        u,
        v: u,
    }
}

/// The stack loop of one ray.
fn walk<M: Machine>(
    m: &mut M,
    tree: &MbvhBufs,
    b: &mut SingleBufs,
    ray: &mut Ray<M>,
    policy: HitPolicy,
    c: &mut Counters,
) {
    let mut sp = m.int(0);
    let root = m.int(0);
    m.s_store(&mut b.stack, At::off(0), 4, root);
    let z = m.float(0.0);
    m.x_store(&mut b.stack, At::off(4), z);
    sp = m.s_addi(sp, 1);
    loop {
        m.region(Region::Traversal);
        let zero = m.int(0);
        if !m.branch_if(site::STACK, Cmp::Gt, sp, zero) {
            break;
        }
        sp = m.s_addi(sp, -1);
        let node = m.s_load(&b.stack, At::idx(sp, 8, 0), 4, false);
        let d = m.x_load(&b.stack, At::idx(sp, 8, 4));
        c.tasks += 1;
        let cull = m.x_cmp(Cmp::Gt, d, ray.tfar_x);
        if m.branch(site::CULL, cull) {
            continue;
        }
        let leaf_flag = m.int(i64::from(LEAF));
        let lf = m.s_and(node, leaf_flag);
        if m.branch(site::LEAF, lf) {
            if leaf(m, tree, ray, node, c) && policy.is_any() {
                break;
            }
        } else {
            sp = inner(m, tree, b, ray, node, sp, c);
        }
    }
}

/// One box test of the ray against the node's `W` boxes; hit children
/// pushed farthest first. Returns the new stack top.
fn inner<M: Machine>(
    m: &mut M,
    tree: &MbvhBufs,
    b: &mut SingleBufs,
    ray: &Ray<M>,
    node: M::S,
    mut sp: M::S,
    c: &mut Counters,
) -> M::S {
    let w = M::LANES;
    c.box_tests += 1;
    c.box_fetches += 1;
    let nb = m.s_shift(Shift::Shl, node, node_bytes(w).trailing_zeros());
    let mut near = [ray.tmin; 3];
    let mut far = [ray.tfar; 3];
    for a in 0..3 {
        let lo = m.load_operand(&tree.nodes, At::idx(nb, 1, 4 * w * (2 * a)), w);
        let d0 = m.sub(lo, ray.org[a]);
        let t0 = m.mul(d0, ray.idir[a]);
        let hi = m.load_operand(&tree.nodes, At::idx(nb, 1, 4 * w * (2 * a + 1)), w);
        let d1 = m.sub(hi, ray.org[a]);
        let t1 = m.mul(d1, ray.idir[a]);
        near[a] = m.min(t0, t1);
        far[a] = m.max(t0, t1);
    }
    let (hit, tn) = slab_hits(m, near, far, ray.tmin, ray.tfar);
    let mut bits = m.movemask(hit);
    let vw = m.s_load(&tree.nodes, At::idx(nb, 1, 28 * w), 4, false);
    bits = m.s_and(bits, vw);
    let zero = m.int(0);
    let none = m.s_cmp(Cmp::Eq, bits, zero);
    if m.branch(site::ANY, none) {
        return sp;
    }
    let mut kids: Vec<(M::S, M::X)> = Vec::with_capacity(w);
    loop {
        let lane = m.s_tzcnt(bits);
        let l = lane.get() as usize;
        let child = m.s_load(&tree.nodes, At::base_idx(nb, lane, 4, 24 * w), 4, false);
        kids.push((child, m.extract(tn, l)));
        let lm1 = m.s_addi(bits, -1);
        bits = m.s_and(bits, lm1);
        let more = m.s_cmp(Cmp::Ne, bits, zero);
        if !m.branch(site::CHILD, more) {
            break;
        }
    }
    // Farthest first: the nearest is popped next.
    sort_farthest_first(m, &mut kids, |k: &(M::S, M::X)| k.1, site::SORT);
    for (child, d) in kids {
        m.s_store(&mut b.stack, At::idx(sp, 8, 0), 4, child);
        m.x_store(&mut b.stack, At::idx(sp, 8, 4), d);
        sp = m.s_addi(sp, 1);
    }
    sp
}

/// The ray against each block of `W` triangles of the leaf; the closest
/// hit kept. Returns whether any triangle was hit.
fn leaf<M: Machine>(
    m: &mut M,
    tree: &MbvhBufs,
    ray: &mut Ray<M>,
    node: M::S,
    c: &mut Counters,
) -> bool {
    let w = M::LANES;
    m.region(Region::Leaf);
    let (fb, ntri) = leaf_blocks(m, node);
    let nt = ntri.get() as usize;
    let mut any = false;
    let mut k = m.int(0);
    for blk_i in 0..nt.div_ceil(w) {
        let at = blk_i * block_bytes(w);
        let mut row = |r: usize| m.load(&tree.tris, At::idx(fb, 1, at + 4 * w * r));
        let blk = Block {
            v0: [row(0), row(1), row(2)],
            e1: [row(3), row(4), row(5)],
            e2: [row(6), row(7), row(8)],
            prim: {
                let p = row(9);
                m.bits_to_i(p)
            },
        };
        c.prim_tests += 1;
        c.prim_lanes += (nt - blk_i * w).min(w) as u64;
        let sites = [site::TRI_EDGE, site::TRI_DEPTH];
        if let Some(h) = moller(m, &blk, (&ray.org, &ray.dir, ray.tfar), None, sites) {
            any = true;
            let inf = m.splat(f32::INFINITY);
            let tv = m.select(h.valid, h.t, inf);
            let tmin = m.reduce(BinOp::Min, tv);
            let tb = m.broadcast(tmin);
            let eq = m.cmp(Cmp::Eq, tv, tb);
            let at_min = m.klogic(Logic::And, eq, h.valid);
            let lane = m.bitscan(at_min).get() as usize;
            ray.tfar = tb;
            ray.tfar_x = tmin;
            ray.prim = m.s_load(&tree.tris, At::idx(fb, 1, at + 36 * w + 4 * lane), 4, true);
            ray.u = m.extract(h.u, lane);
            ray.v = m.extract(h.v, lane);
        }
        k = m.s_addi(k, w as i64);
        if !m.branch_if(site::BLOCK, Cmp::Lt, k, ntri) {
            break;
        }
    }
    any
}
