//! Single-ray BVH4 traversal, Embree style (the DRS paper's "Single BVH4"):
//! an ordered stack, the 4 child boxes tested with one set of 4-wide ops
//! (repeated across the lanes), hit children ordered as Embree 2.0's
//! `BVH4Intersector1` orders them (one: go on; two: push the farther; three
//! or four: push all and sort them by entry distance with compare-exchange
//! networks, closest-hit rays only), entries culled on pop when farther than
//! the hit; leaves are 8-wide SoA Moller-Trumbore blocks (1 ray vs 8
//! triangles).
//!
//! Deviations: a leaf is one block of <= 8 triangles (Embree: triangle4
//! lists); the sort's exchanges happen in registers before the stores
//! (Embree exchanges stack entries in memory; the compares and branches are
//! the same); leaves divide on every test (Embree takes a reciprocal only on
//! a hit: open, issue 12).

use crate::filter::{Candidate1, Filter};
use crate::layout::{is_leaf, Bvh2Bufs, Bvh4Bufs, BLOCK_BYTES, NODE_BYTES};
use crate::stats::Tests;
use isa::{At, BinOp, Buf, Cmp, Fma, Int, Logic, Machine, Region};
use scene::bvh::EMPTY_SLOT;
use scene::HitPolicy;

/// Branch sites of the kernel.
pub mod site {
    use isa::Site;
    /// More rays?
    pub const RAYS: Site = isa::sites::SINGLE.at(0);
    /// Stack empty?
    pub const STACK: Site = isa::sites::SINGLE.at(1);
    /// Popped entry farther than the current hit?
    pub const CULL: Site = isa::sites::SINGLE.at(2);
    /// Leaf or inner?
    pub const LEAF: Site = isa::sites::SINGLE.at(3);
    /// Any child hit?
    pub const ANY_CHILD: Site = isa::sites::SINGLE.at(4);
    /// Next hit child?
    pub const CHILD: Site = isa::sites::SINGLE.at(5);
    /// Two hit children: which is nearer?
    pub const CLOSER: Site = isa::sites::SINGLE.at(6);
    /// Any triangle passes the depth test?
    pub const TRI: Site = isa::sites::SINGLE.at(7);
    /// Another block pass (narrow flavours)?
    pub const PASS: Site = isa::sites::SINGLE.at(8);
    /// BVH2: the only hit child is the left one?
    pub const SIDE: Site = isa::sites::SINGLE.at(9);
    /// BVH4, 3 or 4 hit children: one compare-exchange of the sort.
    pub const SORT: Site = isa::sites::SINGLE.at(10);
    /// Any triangle passes the edge tests?
    pub const TRI_EDGE: Site = isa::sites::SINGLE.at(11);

    /// Filtered leaves: another candidate in the pass?
    pub const FILTERED: Site = isa::sites::SINGLE.at(12);

    /// Every site of the module (checked for duplicates by the layout test).
    pub const ALL: [Site; 13] = [
        RAYS, STACK, CULL, LEAF, ANY_CHILD, CHILD, CLOSER, TRI, PASS, SIDE, SORT, TRI_EDGE,
        FILTERED,
    ];
}

/// Stack entries one ray can need (3 pushes per level x 64 levels, rounded up).
pub const STACK_ENTRIES: usize = 256;

/// Trace rays `[0, nrays)`: `trav`/`isect` are the ray records of
/// [`crate::layout::ray_records`]; `hits` holds one 16-byte record per ray
/// ([`crate::layout::hit_records`]); `stack` needs `STACK_ENTRIES * 8` bytes.
#[allow(clippy::too_many_arguments)]
pub fn trace_bvh4<M: Machine>(
    m: &mut M,
    s: &Bvh4Bufs,
    trav: &mut Buf,
    isect: &Buf,
    hits: &mut Buf,
    stack: &mut Buf,
    nrays: usize,
    tests: &mut Tests,
    policy: HitPolicy,
) {
    let root = m.int(0);
    each_ray(m, nrays, |m, ray| {
        trace_ray_bvh4(m, s, trav, isect, hits, stack, ray, root, tests, policy);
    });
}

/// Call `f` with each ray index `0..nrays` (a counted loop, at least once).
fn each_ray<M: Machine>(m: &mut M, nrays: usize, mut f: impl FnMut(&mut M, M::S)) {
    let mut ray = m.int(0);
    let nr = m.int(nrays as i64);
    loop {
        f(m, ray);
        ray = m.s_addi(ray, 1);
        if !m.branch_if(site::RAYS, Cmp::Lt, ray, nr) {
            break;
        }
    }
}

/// Trace one ray from node `start` (a BVH4 node index or leaf ref), keeping the
/// best hit already in its hit record and its current `t_far`; writes back
/// the hit record and `t_far` (so ray-stream kernels can fall back to this).
#[allow(clippy::too_many_arguments)]
pub fn trace_ray_bvh4<M: Machine>(
    m: &mut M,
    s: &Bvh4Bufs,
    trav: &mut Buf,
    isect: &Buf,
    hits: &mut Buf,
    stack: &mut Buf,
    ray: M::S,
    start: M::S,
    tests: &mut Tests,
    policy: HitPolicy,
) {
    let bufs = (trav, isect, hits, stack);
    trace_ray_with(m, s, bufs, (ray, start), tests, policy, None);
}

/// [`trace_ray_bvh4`] with an optional intersection filter (which keeps its
/// state by the ray's index).
fn trace_ray_with<M: Machine>(
    m: &mut M,
    s: &Bvh4Bufs,
    (trav, isect, hits, stack): (&mut Buf, &Buf, &mut Buf, &mut Buf),
    (ray, start): (M::S, M::S),
    tests: &mut Tests,
    policy: HitPolicy,
    filter: Option<&mut dyn Filter<M>>,
) {
    let mut st = RayState::load(m, trav, isect, hits, ray);
    let filter = filter.map(|f| (f, ray));
    walk4_with(m, s, &mut st, (stack, start), tests, policy, filter);
    // Write the hit record and the new t_far.
    m.region(Region::SingleRay);
    st.write(m, trav, hits);
}

/// The BVH4 stack loop of [`trace_ray`] for a loaded ray, from node `start`
/// (`shadow`: stop at the first hit).
pub fn walk4<M: Machine>(
    m: &mut M,
    s: &Bvh4Bufs,
    st: &mut RayState<M>,
    stack: &mut Buf,
    start: M::S,
    tests: &mut Tests,
    policy: HitPolicy,
) {
    walk4_with(m, s, st, (stack, start), tests, policy, None);
}

/// Trace rays `[0, nrays)` as [`trace_bvh4`] (closest hit), every
/// candidate hit judged by `filter` ([`crate::filter`]): ray `i`'s hit
/// record ends as the last candidate accepted, its t_far as the t_far the
/// filter set.
#[allow(clippy::too_many_arguments)]
pub fn trace_bvh4_filtered<M: Machine>(
    m: &mut M,
    s: &Bvh4Bufs,
    trav: &mut Buf,
    isect: &Buf,
    hits: &mut Buf,
    stack: &mut Buf,
    nrays: usize,
    tests: &mut Tests,
    filter: &mut dyn Filter<M>,
) {
    let root = m.int(0);
    each_ray(m, nrays, |m, ray| {
        let bufs = (&mut *trav, isect, &mut *hits, &mut *stack);
        let f: &mut dyn Filter<M> = &mut *filter;
        trace_ray_with(m, s, bufs, (ray, root), tests, HitPolicy::Closest, Some(f));
    });
}

/// [`walk4`], with an intersection filter and the index of the ray it
/// keeps its state by.
fn walk4_with<M: Machine>(
    m: &mut M,
    s: &Bvh4Bufs,
    st: &mut RayState<M>,
    (stack, start): (&mut Buf, M::S),
    tests: &mut Tests,
    policy: HitPolicy,
    mut filter: Option<(&mut dyn Filter<M>, M::S)>,
) {
    let (idir, oid, tnear_ray) = (st.idir, st.oid, st.tnear);
    let neg = sign_bits(m, &idir);
    // Push the start node.
    let mut sp = m.int(0);
    m.s_store(stack, At::off(0), 4, start);
    let z = m.float(0.0);
    m.x_store(stack, At::off(4), z);
    sp = m.s_addi(sp, 1);
    loop {
        m.region(Region::Traversal);
        let zero = m.int(0);
        if !m.branch_if(site::STACK, Cmp::Gt, sp, zero) {
            break;
        }
        sp = m.s_addi(sp, -1);
        let mut node = m.s_load(stack, At::idx(sp, 8, 0), 4, false);
        let tn = m.x_load(stack, At::idx(sp, 8, 4));
        let cull = m.x_cmp(Cmp::Gt, tn, st.tfar_x);
        if m.branch(site::CULL, cull) {
            tests.culled += 1;
            continue;
        }
        // Descend through inner nodes.
        loop {
            let leaf_flag = m.int(i64::from(scene::bvh::LEAF));
            let lf = m.s_and(node, leaf_flag);
            if m.branch(site::LEAF, lf) {
                break;
            }
            // node * 128: a shift.
            let base = m.s_shift(isa::Shift::Shl, node, NODE_BYTES.trailing_zeros());
            tests.other += 1;
            // The near and far planes by the ray's direction signs, as Embree
            // 2.0 (`msub(load4f(node + nearX), rdir.x, org_rdir.x)`: the plane
            // is the fmsub's memory operand); an empty slot's bounds (+inf)
            // miss for either sign.
            let b = |m: &mut M, k: usize| m.load_operand(&s.nodes, At::idx(base, 1, 16 * k), 4);
            let mut t_near = [tnear_ray; 3];
            let mut t_far = [st.tfar; 3];
            for a in 0..3 {
                let lo = b(m, 2 * a + neg[a]);
                let hi = b(m, 2 * a + 1 - neg[a]);
                t_near[a] = m.fmsub(lo, idir[a], oid[a]);
                t_far[a] = m.fmsub(hi, idir[a], oid[a]);
            }
            let n01 = m.max(t_near[0], t_near[1]);
            let n2r = m.max(t_near[2], tnear_ray);
            let tn_v = m.max(n01, n2r);
            let f01 = m.min(t_far[0], t_far[1]);
            let f2r = m.min(t_far[2], st.tfar);
            let tf_v = m.min(f01, f2r);
            let hitk = m.cmp(Cmp::Le, tn_v, tf_v);
            let mut bits = m.movemask(hitk);
            if M::LANES > 4 {
                // The 4 children are repeated across wider vectors (Embree's
                // SSE test moves exactly 4 bits): one more op.
                let low = m.int(0xF);
                bits = m.s_and(bits, low);
            }
            let none = m.s_cmp(Cmp::Eq, bits, zero);
            if m.branch(site::ANY_CHILD, none) {
                node = m.int(i64::from(EMPTY_SLOT));
                break;
            }
            node = descend4(m, (s, base, tn_v), stack, &mut sp, bits, policy);
        }
        if !is_leaf(node.get() as u32) {
            continue;
        }
        // Leaf: one block of 8 triangles, in passes of the lanes there are.
        tests.leaf += 1;
        if let Some((f, ray)) = filter.as_mut() {
            st.leaf_filtered(m, &s.tris, node, (&mut **f, *ray));
            continue;
        }
        if st.leaf(m, &s.tris, node, policy) && policy.is_any() {
            break;
        }
    }
}

/// Per axis, 1 if the ray's direction is negative (the row offset of its
/// near plane), 0 otherwise: a compare, a mask move and a mask per axis,
/// once per ray (Embree 2.0's `nearX`, `nearY`, `nearZ`).
fn sign_bits<M: Machine>(m: &mut M, idir: &[M::F; 3]) -> [usize; 3] {
    let zero_v = m.splat(0.0);
    let one = m.int(1);
    let mut neg = [0; 3];
    for (n, &d) in neg.iter_mut().zip(idir) {
        let lt = m.cmp(Cmp::Lt, d, zero_v);
        let bits = m.movemask(lt);
        *n = m.s_and(bits, one).get() as usize;
    }
    neg
}

/// The next node after a BVH4 node test, as Embree 2.0's single-ray
/// traversal picks it: the hit children (`bits`) in lane order; one: go on
/// with it; two: push the farther, go on with the nearer; three or four:
/// push all, sort the stack's top entries by entry distance (closest-hit
/// rays; Embree's 3- and 4-element compare-exchange networks, here on
/// registers before the stores), pop the nearest.
fn descend4<M: Machine>(
    m: &mut M,
    (s, base, tn_v): (&Bvh4Bufs, M::S, M::F),
    stack: &mut Buf,
    sp: &mut M::S,
    mut bits: M::S,
    policy: HitPolicy,
) -> M::S {
    let zero = m.int(0);
    // At most 4 hit children, kept on the host stack (no allocation per node).
    let mut hit: [Option<(M::S, M::X)>; 4] = [None; 4];
    let mut n = 0;
    loop {
        let lane = m.s_tzcnt(bits);
        let l = lane.get() as usize;
        // The child ref at the bit scan's lane: its address depends on the
        // scan, as Embree's `node->child(r)` does.
        let child = m.s_load(&s.nodes, At::base_idx(base, lane, 4, 96), 4, false);
        let d = m.extract(tn_v, l);
        hit[n] = Some((child, d));
        n += 1;
        let lm1 = m.s_addi(bits, -1);
        bits = m.s_and(bits, lm1);
        let more = m.s_cmp(Cmp::Ne, bits, zero);
        if !m.branch(site::CHILD, more) {
            break;
        }
    }
    let mut push = |m: &mut M, sp: &mut M::S, (c, d): (M::S, M::X)| {
        m.s_store(stack, At::idx(*sp, 8, 0), 4, c);
        m.x_store(stack, At::idx(*sp, 8, 4), d);
        *sp = m.s_addi(*sp, 1);
    };
    let at = |hit: &[Option<(M::S, M::X)>; 4], i: usize| hit[i].expect("a hit child");
    match n {
        1 => at(&hit, 0).0,
        2 => {
            let (a, b) = (at(&hit, 0), at(&hit, 1));
            let first = m.x_cmp(Cmp::Lt, a.1, b.1);
            let (near, far) = if m.branch(site::CLOSER, first) {
                (a, b)
            } else {
                (b, a)
            };
            push(m, sp, far);
            near.0
        }
        _ => {
            if !policy.is_any() {
                // Nearest last: it is popped first.
                for &(i, j) in sort_network(n) {
                    let swap = m.x_cmp(Cmp::Lt, at(&hit, i).1, at(&hit, j).1);
                    if m.branch(site::SORT, swap) {
                        hit.swap(i, j);
                    }
                }
            }
            for &h in hit[..n].iter().flatten() {
                push(m, sp, h);
            }
            *sp = m.s_addi(*sp, -1);
            m.s_load(stack, At::idx(*sp, 8, 0), 4, false)
        }
    }
}

/// Embree's compare-exchange network over `n` (3 or 4) hit children: each
/// pair (i, j) is swapped when child i is nearer than child j, which leaves
/// the nearest last (popped first).
#[must_use]
pub fn sort_network(n: usize) -> &'static [(usize, usize)] {
    match n {
        3 => &[(0, 1), (1, 2), (0, 1)],
        4 => &[(0, 1), (2, 3), (0, 2), (1, 3), (1, 2)],
        _ => panic!("a sort network for 3 or 4 children, not {n}"),
    }
}

/// One ray's registers in the single-ray kernels: its data broadcast per
/// component (vbroadcastss m32) and its best hit so far.
pub struct RayState<M: Machine> {
    /// Lane of an SoA packet record the ray came from (hybrid kernel), or
    /// `None` for the AoS ray records.
    lane: Option<usize>,
    /// Triangles per leaf test: `min(LANES, 8)`, or 4 in the hybrid kernel
    /// (Embree 2.0's hybrid tests one ray against a triangle4).
    leaf_lanes: usize,
    ro: M::S,
    ho: M::S,
    idir: [M::F; 3],
    oid: [M::F; 3],
    tnear: M::F,
    org: [M::F; 3],
    dir: [M::F; 3],
    tfar_x: M::X,
    tfar: M::F,
    best_u: M::X,
    best_v: M::X,
    best_prim: M::S,
}

impl<M: Machine> RayState<M> {
    /// Load ray `ray`'s records and its hit record (inlined: built in
    /// place natively, not copied out).
    #[inline(always)]
    fn load(m: &mut M, trav: &Buf, isect: &Buf, hits: &Buf, ray: M::S) -> Self {
        m.region(Region::SingleRay);
        let ro = m.s_shift(isa::Shift::Shl, ray, 5);
        let bc = |m: &mut M, b: &Buf, k: usize| m.load_bcast(b, At::idx(ro, 1, 4 * k));
        let idir = [bc(m, trav, 0), bc(m, trav, 1), bc(m, trav, 2)];
        let oid = [bc(m, trav, 4), bc(m, trav, 5), bc(m, trav, 6)];
        let tnear = bc(m, trav, 3);
        let org = [bc(m, isect, 0), bc(m, isect, 1), bc(m, isect, 2)];
        let dir = [bc(m, isect, 4), bc(m, isect, 5), bc(m, isect, 6)];
        let tfar_x = m.x_load(trav, At::idx(ro, 1, 28));
        let tfar = m.broadcast(tfar_x);
        let ho = m.s_shift(isa::Shift::Shl, ray, 4);
        let best_u = m.x_load(hits, At::idx(ho, 1, 4));
        let best_v = m.x_load(hits, At::idx(ho, 1, 8));
        let best_prim = m.s_load(hits, At::idx(ho, 1, 12), 4, true);
        RayState {
            lane: None,
            leaf_lanes: M::LANES.min(8),
            ro,
            ho,
            idir,
            oid,
            tnear,
            org,
            dir,
            tfar_x,
            tfar,
            best_u,
            best_v,
            best_prim,
        }
    }

    /// Load lane `k` of the SoA packet record at byte `pb` of `pk`
    /// (the packet record of [`crate::layout::packet_bytes`]): broadcasts of its rows; the premultiplied
    /// origin is computed (Embree's hybrid kernel does the same in registers).
    pub fn load_packet(m: &mut M, pk: &Buf, pb: M::S, k: usize) -> Self {
        use crate::layout::row;
        m.region(Region::SingleRay);
        let w = M::LANES;
        let bc = |m: &mut M, r: usize| m.load_bcast(pk, At::idx(pb, 1, row(w, r) + 4 * k));
        let org = [bc(m, row::ORG), bc(m, row::ORG + 1), bc(m, row::ORG + 2)];
        let dir = [bc(m, row::DIR), bc(m, row::DIR + 1), bc(m, row::DIR + 2)];
        let idir = [bc(m, row::IDIR), bc(m, row::IDIR + 1), bc(m, row::IDIR + 2)];
        let oid = [
            m.mul(org[0], idir[0]),
            m.mul(org[1], idir[1]),
            m.mul(org[2], idir[2]),
        ];
        let tnear = bc(m, row::TNEAR);
        let x = |m: &mut M, r: usize| m.x_load(pk, At::idx(pb, 1, row(w, r) + 4 * k));
        let tfar_x = x(m, row::TFAR);
        let tfar = m.broadcast(tfar_x);
        let best_u = x(m, row::U);
        let best_v = x(m, row::V);
        let best_prim = m.s_load(pk, At::idx(pb, 1, row(w, row::PRIM) + 4 * k), 4, true);
        RayState {
            lane: Some(k),
            leaf_lanes: 4,
            ro: pb,
            ho: pb,
            idir,
            oid,
            tnear,
            org,
            dir,
            tfar_x,
            tfar,
            best_u,
            best_v,
            best_prim,
        }
    }

    /// Leaf `node`: one block of 8 triangles, in passes of `leaf_lanes`
    /// triangles; whether a triangle was hit. A shadow ray's t_far becomes -1 on a
    /// hit (it is done).
    #[inline(always)]
    fn leaf(&mut self, m: &mut M, tris: &Buf, node: M::S, policy: HitPolicy) -> bool {
        let mut any = false;
        let width = self.leaf_lanes;
        m.region(Region::Leaf);
        let mask_idx = m.int(i64::from(!scene::bvh::LEAF));
        let blk = m.s_and(node, mask_idx);
        let bytes = m.int(BLOCK_BYTES as i64);
        let bb = m.s_op(isa::SOp::Mul, blk, bytes);
        for p in 0..8 / width {
            let blk = load_block(m, tris, bb, p, width);
            if let Some(h) = intersect(m, &blk, width, &self.org, &self.dir, self.tfar) {
                self.tfar_x = h.t;
                self.tfar = h.tb;
                self.best_u = h.u;
                self.best_v = h.v;
                let off = 32 * 9 + 4 * (width * p + h.lane);
                self.best_prim = m.s_load(tris, At::idx(bb, 1, off), 4, true);
                any = true;
                if policy.is_any() {
                    self.tfar_x = m.float(-1.0);
                    self.tfar = m.splat(-1.0);
                    return true;
                }
            }
        }
        any
    }

    /// Leaf `node` with an intersection filter: per block pass, the
    /// candidates within the interval nearest first, each judged by `f`
    /// (Embree 3's `Intersect1EpilogM`): an accepted one becomes the hit
    /// and its t_far the filter's; after each verdict the candidate and
    /// those beyond t_far are dropped.
    fn leaf_filtered(
        &mut self,
        m: &mut M,
        tris: &Buf,
        node: M::S,
        (f, ray): (&mut dyn Filter<M>, M::S),
    ) {
        let width = self.leaf_lanes;
        m.region(Region::Leaf);
        let mask_idx = m.int(i64::from(!scene::bvh::LEAF));
        let blk = m.s_and(node, mask_idx);
        let bytes = m.int(BLOCK_BYTES as i64);
        let bb = m.s_op(isa::SOp::Mul, blk, bytes);
        let inf = m.splat(f32::INFINITY);
        for p in 0..8 / width {
            let blk = load_block(m, tris, bb, p, width);
            let live = (M::LANES > width).then(|| m.mask((1 << width) - 1));
            let sites = [site::TRI_EDGE, site::TRI];
            let ray_v = (&self.org, &self.dir, self.tfar);
            let Some(Moller { t, u, v, mut valid }) = moller(m, &blk, ray_v, live, sites) else {
                continue;
            };
            loop {
                // The nearest remaining candidate.
                let tv = m.select(valid, t, inf);
                let tmin = m.reduce(BinOp::Min, tv);
                let tb = m.broadcast(tmin);
                let eq = m.cmp(Cmp::Eq, tv, tb);
                let at_min = m.klogic(Logic::And, eq, valid);
                let lane = m.bitscan(at_min).get() as usize;
                let off = 32 * 9 + 4 * (width * p + lane);
                let prim = m.s_load(tris, At::idx(bb, 1, off), 4, true);
                let verdict = f.one(m, Candidate1 { ray, t: tmin, prim });
                m.region(Region::Leaf);
                if let Some(t_far) = verdict {
                    self.tfar_x = t_far;
                    self.tfar = m.broadcast(t_far);
                    self.best_u = m.extract(u, lane);
                    self.best_v = m.extract(v, lane);
                    self.best_prim = prim;
                }
                // Drop it, and every candidate beyond the ray's t_far.
                let this = m.mask(1 << lane);
                let others = m.knot(this);
                valid = m.kand(valid, others);
                let within = m.cmp(Cmp::Le, t, self.tfar);
                valid = m.kand(valid, within);
                let more = m.any(valid);
                if !m.branch(site::FILTERED, more) {
                    break;
                }
            }
        }
    }

    /// Write the hit (t_far, u, v, prim) back to lane `k` of its packet record.
    pub fn write_packet(self, m: &mut M, pk: &mut Buf) {
        use crate::layout::row;
        let (w, k, pb) = (M::LANES, self.lane.expect("a packet lane"), self.ro);
        let at = |r: usize| At::idx(pb, 1, row(w, r) + 4 * k);
        m.x_store(pk, at(row::TFAR), self.tfar_x);
        m.x_store(pk, at(row::U), self.best_u);
        m.x_store(pk, at(row::V), self.best_v);
        m.s_store(pk, at(row::PRIM), 4, self.best_prim);
    }

    /// Write the hit record and the new t_far.
    #[inline(always)]
    fn write(self, m: &mut M, trav: &mut Buf, hits: &mut Buf) {
        let (ro, ho) = (self.ro, self.ho);
        m.x_store(hits, At::idx(ho, 1, 0), self.tfar_x);
        m.x_store(trav, At::idx(ro, 1, 28), self.tfar_x);
        m.x_store(hits, At::idx(ho, 1, 4), self.best_u);
        m.x_store(hits, At::idx(ho, 1, 8), self.best_v);
        m.s_store(hits, At::idx(ho, 1, 12), 4, self.best_prim);
    }
}

/// The rows of one 8-wide triangle block (one pass of `min(LANES, 8)` lanes).
pub struct Block<M: Machine> {
    /// First vertex.
    pub v0: [M::F; 3],
    /// First edge.
    pub e1: [M::F; 3],
    /// Second edge.
    pub e2: [M::F; 3],
    /// Triangle ids as i32 (-1: empty slot).
    pub prim: M::I,
}

/// Load pass `p` of `width` triangles (4 or 8, at most the lanes there
/// are) of the block at byte `bb` of `tris`, repeated across wider vectors.
#[inline(always)]
pub fn load_block<M: Machine>(m: &mut M, tris: &Buf, bb: M::S, p: usize, width: usize) -> Block<M> {
    let n = M::LANES;
    assert!(
        width <= n.min(8) && 8 % width == 0,
        "{width} triangles per pass"
    );
    let pw = (p, width);
    let v0 = [
        block_row(m, tris, bb, pw, 0),
        block_row(m, tris, bb, pw, 1),
        block_row(m, tris, bb, pw, 2),
    ];
    let e1 = [
        block_row(m, tris, bb, pw, 3),
        block_row(m, tris, bb, pw, 4),
        block_row(m, tris, bb, pw, 5),
    ];
    let e2 = [
        block_row(m, tris, bb, pw, 6),
        block_row(m, tris, bb, pw, 7),
        block_row(m, tris, bb, pw, 8),
    ];
    let pf = block_row(m, tris, bb, pw, 9);
    let prim = m.bits_to_i(pf);
    Block { v0, e1, e2, prim }
}

/// Row `r` of pass `p` of a block ([`load_block`]); inlined, so natively
/// the row is one load into a register.
#[inline(always)]
fn block_row<M: Machine>(
    m: &mut M,
    tris: &Buf,
    bb: M::S,
    (p, width): (usize, usize),
    r: usize,
) -> M::F {
    let at = At::idx(bb, 1, 32 * r + 4 * width * p);
    if M::LANES > width {
        m.load_repeat(tris, at, width)
    } else {
        m.load(tris, at)
    }
}

/// The closest hit in a block pass.
pub struct BlockHit<M: Machine> {
    /// Its t.
    pub t: M::X,
    /// Its t in every lane.
    pub tb: M::F,
    /// Its lane.
    pub lane: usize,
    /// Barycentric u.
    pub u: M::X,
    /// Barycentric v.
    pub v: M::X,
}

/// Lane-wise Moller-Trumbore in Embree 2.0's form
/// (`triangle4_intersector1_moeller.h`): rays `(org, dir, tfar)` against
/// triangles `b`, either side broadcast (one ray vs 8 triangles, or a packet
/// vs one triangle), only lanes in `live` (all when `None`). Edge tests on
/// the determinant-scaled barycentrics (`U`, `V` with the sign of det moved
/// in, `U + V <= |det|`), then the depth test `0 < T < |det| * t_far`, each
/// followed by an early exit when no lane passes (recorded branches at
/// `sites`); the reciprocal of `|det|` (an estimate and one Newton step, as
/// Embree's `rcp`) and the three multiplies only when a lane hits.
///
/// Deviation: Embree stores the geometric normal with each triangle and
/// needs one cross product; the block holds v0, e1, e2 only, so det and the
/// depth take a second cross product (6 more ops per test, 9 fewer floats
/// per triangle).
#[inline(always)]
pub fn moller<M: Machine>(
    m: &mut M,
    b: &Block<M>,
    (org, dir, tfar): (&[M::F; 3], &[M::F; 3], M::F),
    live: Option<M::K>,
    sites: [isa::Site; 2],
) -> Option<Moller<M>> {
    moller_sided(m, b, (org, dir, tfar), Sides::Both, live, sites)
}

/// Which faces a ray-triangle test reports.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Sides {
    /// Both faces.
    Both,
    /// Front faces only (det > 0, i.e. the ray meets the side the winding's
    /// normal points to), as back-face culling.
    Front,
    /// Front faces, and rays within the f32 rounding noise of the
    /// triangle's plane miss: det^2 <= (4 eps)^2 |e1|^2 |e2|^2 |d|^2, where
    /// the edge tests' signs mean nothing (the robustness test the MFT
    /// kernel runs, `mft_kernels::PlaneNoise::Reject`, charged to its
    /// packet baseline too: 15 more ops per test).
    FrontNoGrazing,
}

/// [`moller`] with a choice of faces.
#[inline(always)]
pub fn moller_sided<M: Machine>(
    m: &mut M,
    b: &Block<M>,
    (org, dir, tfar): (&[M::F; 3], &[M::F; 3], M::F),
    sides: Sides,
    live: Option<M::K>,
    sites: [isa::Site; 2],
) -> Option<Moller<M>> {
    let zero_v = m.splat(0.0);
    let cross = |m: &mut M, a: [M::F; 3], c: [M::F; 3]| {
        let x0 = m.mul(a[2], c[1]);
        let x = m.fmsub(a[1], c[2], x0);
        let y0 = m.mul(a[0], c[2]);
        let y = m.fmsub(a[2], c[0], y0);
        let z0 = m.mul(a[1], c[0]);
        let zz = m.fmsub(a[0], c[1], z0);
        [x, y, zz]
    };
    let dot = |m: &mut M, a: [M::F; 3], c: [M::F; 3]| {
        let d0 = m.mul(a[0], c[0]);
        let d1 = m.fmadd(a[1], c[1], d0);
        m.fmadd(a[2], c[2], d1)
    };
    // Edge tests.
    let pv = cross(m, *dir, b.e2);
    let det = dot(m, b.e1, pv);
    let sv = [
        m.sub(org[0], b.v0[0]),
        m.sub(org[1], b.v0[1]),
        m.sub(org[2], b.v0[2]),
    ];
    let u0 = dot(m, sv, pv);
    let qv = cross(m, sv, b.e1);
    let v0_ = dot(m, *dir, qv);
    let sign_bit = m.splat(-0.0);
    let sgn = m.logic(Logic::And, det, sign_bit);
    let adet = m.logic(Logic::AndNot, sign_bit, det);
    let su = m.logic(Logic::Xor, u0, sgn);
    let sv_ = m.logic(Logic::Xor, v0_, sgn);
    let suv = m.add(su, sv_);
    let det_cmp = if sides == Sides::Both {
        Cmp::Ne
    } else {
        Cmp::Gt
    };
    let mut ok_det = m.cmp(det_cmp, det, zero_v);
    if sides == Sides::FrontNoGrazing {
        let ee1 = dot(m, b.e1, b.e1);
        let ee2 = dot(m, b.e2, b.e2);
        let dd = dot(m, *dir, *dir);
        let k = m.splat((4.0 * f32::EPSILON) * (4.0 * f32::EPSILON));
        let floor = m.mul(ee1, ee2);
        let floor = m.mul(floor, k);
        let floor = m.mul(floor, dd);
        let det2 = m.mul(det, det);
        let reliable = m.cmp(Cmp::Gt, det2, floor);
        ok_det = m.kand(ok_det, reliable);
    }
    let ok_u = m.cmp(Cmp::Ge, su, zero_v);
    let ok_v = m.cmp(Cmp::Ge, sv_, zero_v);
    let ok_uv = m.cmp(Cmp::Le, suv, adet);
    let zi = m.splat_i(0);
    let ok_p = m.icmp(Cmp::Ge, b.prim, zi);
    // One And per mask, written out: natively an iterator over the masks
    // went through the stack (a store-forwarding stall per leaf).
    let mut valid = m.klogic(Logic::And, ok_det, ok_u);
    valid = m.klogic(Logic::And, valid, ok_v);
    valid = m.klogic(Logic::And, valid, ok_uv);
    valid = m.klogic(Logic::And, valid, ok_p);
    if let Some(l) = live {
        valid = m.klogic(Logic::And, valid, l);
    }
    let any = m.any(valid);
    if !m.branch(sites[0], any) {
        return None;
    }
    // Depth test.
    let t0 = dot(m, b.e2, qv);
    let st = m.logic(Logic::Xor, t0, sgn);
    let far = m.mul(adet, tfar);
    let ok_t0 = m.cmp(Cmp::Gt, st, zero_v);
    let ok_t1 = m.cmp(Cmp::Lt, st, far);
    valid = m.klogic(Logic::And, valid, ok_t0);
    valid = m.klogic(Logic::And, valid, ok_t1);
    let any = m.any(valid);
    if !m.branch(sites[1], any) {
        return None;
    }
    // A hit: the reciprocal, then u, v, t.
    let est = m.rcp_approx(adet);
    let two = m.splat(2.0);
    let corr = m.fma(Fma::NMAdd, est, adet, two);
    let rcp = m.mul(est, corr);
    let u = m.mul(su, rcp);
    let v = m.mul(sv_, rcp);
    let t = m.mul(st, rcp);
    Some(Moller { t, u, v, valid })
}

/// Per-lane result of [`moller`].
pub struct Moller<M: Machine> {
    /// Distance.
    pub t: M::F,
    /// Barycentric u.
    pub u: M::F,
    /// Barycentric v.
    pub v: M::F,
    /// Lanes with a hit: det != 0, U, V >= 0, U + V <= |det|, 0 < T < |det| t_far, prim >= 0, live.
    pub valid: M::K,
}

/// Moller-Trumbore of one ray (`org`, `dir` broadcast) against a block
/// pass of `width` triangles, hits with 0 < t < `tfar`; the closest, if any.
#[inline(always)]
pub fn intersect<M: Machine>(
    m: &mut M,
    b: &Block<M>,
    width: usize,
    org: &[M::F; 3],
    dir: &[M::F; 3],
    tfar: M::F,
) -> Option<BlockHit<M>> {
    let inf = m.splat(f32::INFINITY);
    // Wider vectors repeat the pass's triangles: its low lanes only.
    let live = (M::LANES > width).then(|| m.mask((1 << width) - 1));
    let sites = [site::TRI_EDGE, site::TRI];
    let Moller { t, u, v, valid } = moller(m, b, (org, dir, tfar), live, sites)?;
    let tv = m.select(valid, t, inf);
    let tmin = m.reduce(BinOp::Min, tv);
    let tb = m.broadcast(tmin);
    let eq = m.cmp(Cmp::Eq, tv, tb);
    let at_min = m.klogic(Logic::And, eq, valid);
    let lane = m.bitscan(at_min).get() as usize;
    let uu = m.extract(u, lane);
    let vv = m.extract(v, lane);
    Some(BlockHit {
        t: tmin,
        tb,
        lane,
        u: uu,
        v: vv,
    })
}

/// Trace rays `[0, nrays)` through a BVH2 (the DRS paper's "Single BVH2"):
/// as [`trace`], buffers the same.
#[allow(clippy::too_many_arguments)]
pub fn trace_bvh2<M: Machine>(
    m: &mut M,
    s: &Bvh2Bufs,
    trav: &mut Buf,
    isect: &Buf,
    hits: &mut Buf,
    stack: &mut Buf,
    nrays: usize,
    tests: &mut Tests,
    policy: HitPolicy,
) {
    each_ray(m, nrays, |m, ray| {
        let root = m.int(i64::from(s.root));
        trace_ray_bvh2(m, s, trav, isect, hits, stack, ray, root, tests, policy);
    });
}

/// One ray through a BVH2 from node `start` (a node index or leaf ref;
/// hit record and `t_far` kept and written back as in [`trace_ray`]): inner
/// nodes by [`bvh2_node`], the nearer hit child taken, the farther pushed
/// with its entry distance.
///
/// Deviation: the node test uses the lanes there are (4 of them carry
/// data), as Embree's BVH2 path does with SSE.
#[allow(clippy::too_many_arguments)]
pub fn trace_ray_bvh2<M: Machine>(
    m: &mut M,
    s: &Bvh2Bufs,
    trav: &mut Buf,
    isect: &Buf,
    hits: &mut Buf,
    stack: &mut Buf,
    ray: M::S,
    start: M::S,
    tests: &mut Tests,
    policy: HitPolicy,
) {
    let mut st = RayState::load(m, trav, isect, hits, ray);
    let (idir, oid, tnear_ray) = (st.idir, st.oid, st.tnear);
    let mut sp = m.int(0);
    m.s_store(stack, At::off(0), 4, start);
    let z = m.float(0.0);
    m.x_store(stack, At::off(4), z);
    sp = m.s_addi(sp, 1);
    loop {
        m.region(Region::Traversal);
        let zero = m.int(0);
        if !m.branch_if(site::STACK, Cmp::Gt, sp, zero) {
            break;
        }
        sp = m.s_addi(sp, -1);
        let mut node = m.s_load(stack, At::idx(sp, 8, 0), 4, false);
        let tn = m.x_load(stack, At::idx(sp, 8, 4));
        let cull = m.x_cmp(Cmp::Gt, tn, st.tfar_x);
        if m.branch(site::CULL, cull) {
            tests.culled += 1;
            continue;
        }
        let mut missed = false;
        loop {
            let leaf_flag = m.int(i64::from(scene::bvh::LEAF));
            let lf = m.s_and(node, leaf_flag);
            if m.branch(site::LEAF, lf) {
                break;
            }
            let base = m.s_shift(isa::Shift::Shl, node, 6);
            tests.other += 1;
            let ray = (&idir, &oid, tnear_ray, st.tfar);
            match bvh2_node(m, &s.nodes, base, ray, stack, &mut sp) {
                Some(next) => node = next,
                None => {
                    missed = true;
                    break;
                }
            }
        }
        if missed {
            continue;
        }
        tests.leaf += 1;
        if st.leaf(m, &s.tris, node, policy) && policy.is_any() {
            break;
        }
    }
    m.region(Region::SingleRay);
    st.write(m, trav, hits);
}

/// Lane i takes lane i ^ 2, for up to 32 lanes: pairs each plane of a BVH2
/// node row `[min_l, min_r, max_l, max_r]` with its opposite. A constant, so
/// natively the permute folds into one shuffle instruction.
const SWAP_MIN_MAX: [u8; 32] = {
    let mut p = [0u8; 32];
    let mut i = 0;
    while i < 32 {
        p[i] = (i ^ 2) as u8;
        i += 1;
    }
    p
};

/// A ray's slab inputs, each broadcast: `idir`, `org * idir`, `t_near`, `t_far`.
pub type SlabRay<'a, M> = (
    &'a [<M as Machine>::F; 3],
    &'a [<M as Machine>::F; 3],
    <M as Machine>::F,
    <M as Machine>::F,
);

/// Single-ray BVH2's inner step: the node at byte `base` of `nodes` against
/// a ray (`idir`, `org * idir`, `t_near`, `t_far`, each broadcast); the next
/// node: the only hit child, or the nearer of two with the farther pushed
/// on `stack` at `sp` with its entry distance; `None` when neither child
/// is hit. Per node one 16-byte load per axis (`[min_l, min_r, max_l,
/// max_r]`, repeated across the lanes), one FMA per axis for all four
/// planes, a lane swap (`vpermilps`) to pair each min with its max, so
/// lanes 0 and 1 hold the two children's entry and exit.
#[inline(always)]
pub fn bvh2_node<M: Machine>(
    m: &mut M,
    nodes: &Buf,
    base: M::S,
    (idir, oid, tnear, tfar): SlabRay<'_, M>,
    stack: &mut Buf,
    sp: &mut M::S,
) -> Option<M::S> {
    let swap = &SWAP_MIN_MAX[..M::LANES];
    let (mut tn_v, mut tf_v) = (tnear, tfar);
    for a in 0..3 {
        let planes = m.load_repeat(nodes, At::idx(base, 1, 16 * a), 4);
        let t = m.fmsub(planes, idir[a], oid[a]);
        let sw = m.permute(t, swap);
        let mn = m.min(t, sw);
        let mx = m.max(t, sw);
        tn_v = m.max(tn_v, mn);
        tf_v = m.min(tf_v, mx);
    }
    let hitk = m.cmp(Cmp::Le, tn_v, tf_v);
    let bits = m.movemask(hitk);
    let lr = m.int(3);
    let bits = m.s_and(bits, lr);
    let zero = m.int(0);
    let none = m.s_cmp(Cmp::Eq, bits, zero);
    if m.branch(site::ANY_CHILD, none) {
        return None;
    }
    let l = m.s_load(nodes, At::idx(base, 1, 48), 4, false);
    let r = m.s_load(nodes, At::idx(base, 1, 52), 4, false);
    let is_both = m.s_cmp(Cmp::Eq, bits, lr);
    if !m.branch(site::CHILD, is_both) {
        let one = m.int(1);
        let only_left = m.s_cmp(Cmp::Eq, bits, one);
        return Some(if m.branch(site::SIDE, only_left) {
            l
        } else {
            r
        });
    }
    let dl = m.extract(tn_v, 0);
    let dr = m.extract(tn_v, 1);
    let right_closer = m.x_cmp(Cmp::Lt, dr, dl);
    let (near, far, dfar) = if m.branch(site::CLOSER, right_closer) {
        (r, l, dl)
    } else {
        (l, r, dr)
    };
    m.s_store(stack, At::idx(*sp, 8, 0), 4, far);
    m.x_store(stack, At::idx(*sp, 8, 4), dfar);
    *sp = m.s_addi(*sp, 1);
    Some(near)
}
