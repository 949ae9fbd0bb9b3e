//! MBVH ray-stream traversal (MBVH RS, Tsakok 2009, Algorithm 1 and
//! Listing 1), written once for any lane count `W` over a `W`-wide MBVH.
//!
//! A group of rays sits in a buffer that never moves and is referenced by
//! 16-bit ray ids. Each SIMD lane has a pre-allocated active-ray stack of
//! ids; a task stack holds (node, lane, ray count). An inner-node task pops
//! its ids from its lane's stack in place (`rayPtr`: ids are read ahead of
//! the pushes that overwrite them, no copy), fetches the node's box packet
//! once, tests each ray alone against it (Kay-Kajiya slabs culled by the
//! ray's current hit length, origin and inverse direction loaded replicated
//! in SoA form), accumulates the hit lengths (`length4`), writes the ray id
//! at the top of every lane's stack and advances the counts of the lanes
//! it hit (`numActive`, stored each ray, read back per lane, as Listing 1),
//! and finally pushes a task per hit child, sorted by accumulated length so
//! that the shortest is popped first (the ordered heuristic; unordered:
//! lane order). A leaf task builds temporary SoA packets of `W` active rays
//! (ids widened through a small buffer, fields gathered), tests them against
//! each triangle alone and scatters the hits back to the ray records. A
//! shadow ray is dropped after its first hit: its t_min becomes +inf, so no
//! later box or leaf admits it.
//!
//! Deviations: the empty-slot mask (`valid`) is ANDed into each box result
//! (one op per ray and node; the paper's nodes are always full, an SAH
//! tree's are not); the leaf's ray-id widening goes through memory (SSE has
//! no 16-to-32-bit gather index; 2 scalar ops per ray per leaf).

use crate::layout::{node_bytes, MbvhBufs, RayForm, RayRecord};
use crate::shared::{broadcast_triangle, leaf_blocks, slab_axis, slab_hits, sort_farthest_first};
use crate::stats::Counters;
use isa::{At, Buf, Cmp, IOp, Int, Machine, MemKind, Region, SOp, Shift};
use rt::single::moller;
use scene::bvh::LEAF;
use scene::{Hit, HitPolicy};

/// Branch sites of the kernel.
pub mod site {
    use isa::Site;
    /// More groups?
    pub const GROUPS: Site = isa::sites::MBVH_RS.at(0);
    /// More ray ids to push at the start?
    pub const INIT: Site = isa::sites::MBVH_RS.at(1);
    /// Task stack empty?
    pub const TASKS: Site = isa::sites::MBVH_RS.at(2);
    /// Leaf task?
    pub const LEAF: Site = isa::sites::MBVH_RS.at(3);
    /// More rays in the task?
    pub const RAY: Site = isa::sites::MBVH_RS.at(4);
    /// Any child hit by any ray?
    pub const ANY: Site = isa::sites::MBVH_RS.at(5);
    /// Another hit child?
    pub const CHILD: Site = isa::sites::MBVH_RS.at(6);
    /// One compare-exchange of the task sort.
    pub const SORT: Site = isa::sites::MBVH_RS.at(7);
    /// More triangles in the leaf?
    pub const TRI: Site = isa::sites::MBVH_RS.at(8);
    /// Any lane passes the edge tests?
    pub const TRI_EDGE: Site = isa::sites::MBVH_RS.at(9);
    /// Any lane passes the depth test?
    pub const TRI_DEPTH: Site = isa::sites::MBVH_RS.at(10);
    /// Shadow packet: any lane not yet occluded?
    pub const ALIVE: Site = isa::sites::MBVH_RS.at(11);
    /// More packets of active rays in the leaf?
    pub const PACKETS: Site = isa::sites::MBVH_RS.at(12);

    /// Every site of the module (checked for duplicates by the layout test).
    pub const ALL: [Site; 13] = [
        GROUPS, INIT, TASKS, LEAF, RAY, ANY, CHILD, SORT, TRI, TRI_EDGE, TRI_DEPTH, ALIVE, PACKETS,
    ];
}

/// The order in which a node's child tasks are pushed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Order {
    /// By accumulated hit length, shortest popped first (the paper's).
    Ordered,
    /// In lane order (the paper's baseline for its +18%).
    Unordered,
}

/// How MBVH RS runs: ray group size, child order, ray record form.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StreamConfig {
    /// Rays per group (a power of two, 2^4 to 2^16; the paper's default 2^8).
    pub group: usize,
    /// Child order.
    pub order: Order,
    /// Ray record form.
    pub form: RayForm,
}

impl Default for StreamConfig {
    fn default() -> Self {
        StreamConfig {
            group: 256,
            order: Order::Ordered,
            form: RayForm::Replicated,
        }
    }
}

/// Smallest and largest ray group (16-bit ray ids).
pub const GROUP_RANGE: (usize, usize) = (1 << 4, 1 << 16);

/// Bytes of one task-stack entry: node ref, lane, ray count, pad.
const TASK_BYTES: usize = 16;

/// The kernel's buffers for one stream.
pub struct StreamBufs {
    /// Ray records of the whole stream (groups are consecutive).
    pub rays: Buf,
    /// Their layout.
    pub rec: RayRecord,
    stacks: Buf,
    cap: usize,
    num_active: Buf,
    scratch: Buf,
    tasks: Buf,
    nrays: usize,
}

/// Scratch rows: node-local counts, accumulated lengths, leaf ray offsets.
const SCRATCH_ROWS: usize = 3;

impl StreamBufs {
    /// Lay out rays `(org, dir, tfar)` and size the stacks for `tree` and `cfg`.
    ///
    /// # Panics
    /// If the group size is not a power of two in [`GROUP_RANGE`].
    pub fn new<M: Machine>(
        m: &mut M,
        tree: &MbvhBufs,
        cfg: &StreamConfig,
        (org, dir, tfar): (&[[f32; 3]], &[[f32; 3]], &[f32]),
    ) -> StreamBufs {
        let g = cfg.group;
        assert!(
            g.is_power_of_two() && (GROUP_RANGE.0..=GROUP_RANGE.1).contains(&g),
            "ray group size {g}: a power of two from 2^4 to 2^16"
        );
        let w = M::LANES;
        let rec = RayRecord::of(cfg.form, w);
        let bytes = rec.records(cfg.form, w, org, dir, tfar);
        let g = g.min(org.len().max(1));
        // Per lane, at most a group's ids per pending level, plus the level
        // being pushed.
        let cap = g * (tree.depth + 1);
        let sp = m.space();
        StreamBufs {
            rays: sp.alloc_bytes(MemKind::Rays, "mbvh-rs-rays", bytes, 64),
            rec,
            stacks: sp.alloc(MemKind::RayLists, "active-ray-stacks", 2 * cap * w, 64),
            cap,
            num_active: sp.alloc(MemKind::Stack, "num-active", 4 * w, 64),
            scratch: sp.alloc(MemKind::Stack, "mbvh-rs-scratch", 4 * w * SCRATCH_ROWS, 64),
            tasks: sp.alloc(
                MemKind::Stack,
                "task-stack",
                TASK_BYTES * w * (tree.depth + 2),
                64,
            ),
            nrays: org.len(),
        }
    }

    /// Ray `i`'s answer as its record holds it.
    #[must_use]
    pub fn hit(&self, i: usize) -> Hit {
        let at = i * self.rec.bytes;
        Hit::from_record(
            self.rays.f32_at(at + self.rec.length),
            self.rays.u32_at(at + self.rec.prim),
        )
    }
}

/// Trace every ray of `b` in groups of `cfg.group`.
pub fn trace<M: Machine>(
    m: &mut M,
    tree: &MbvhBufs,
    b: &mut StreamBufs,
    cfg: &StreamConfig,
    policy: HitPolicy,
    c: &mut Counters,
) {
    let g = cfg.group;
    let groups = b.nrays.div_ceil(g);
    c.rays += b.nrays as u64;
    let mut gi = m.int(0);
    let ng = m.int(groups as i64);
    for k in 0..groups {
        let n = g.min(b.nrays - k * g);
        trace_group(m, tree, b, cfg, (k * g * b.rec.bytes, n), policy, c);
        gi = m.s_addi(gi, 1);
        if !m.branch_if(site::GROUPS, Cmp::Lt, gi, ng) {
            break;
        }
    }
}

/// Algorithm 1 over one group: `n` rays at byte `base` of the ray buffer.
fn trace_group<M: Machine>(
    m: &mut M,
    tree: &MbvhBufs,
    b: &mut StreamBufs,
    cfg: &StreamConfig,
    (base, n): (usize, usize),
    policy: HitPolicy,
    c: &mut Counters,
) {
    let mut tsp = init_group(m, b, n);
    loop {
        m.region(Region::Traversal);
        let zero = m.int(0);
        if !m.branch_if(site::TASKS, Cmp::Gt, tsp, zero) {
            break;
        }
        tsp = m.s_addi(tsp, -(TASK_BYTES as i64));
        let node = m.s_load(&b.tasks, At::idx(tsp, 1, 0), 4, false);
        let lane = m.s_load(&b.tasks, At::idx(tsp, 1, 4), 4, false);
        let cnt = m.s_load(&b.tasks, At::idx(tsp, 1, 8), 4, false);
        c.tasks += 1;
        let leaf_flag = m.int(i64::from(LEAF));
        let lf = m.s_and(node, leaf_flag);
        if m.branch(site::LEAF, lf) {
            leaf(m, tree, b, (base, node, lane, cnt), policy, c);
        } else {
            let task = Task { node, lane, cnt };
            tsp = inner(m, tree, b, cfg, base, task, tsp, c);
        }
    }
}

/// Lines 4-7: the root task over all `n` rays on lane 0's stack; returns the
/// task stack's top (bytes).
fn init_group<M: Machine>(m: &mut M, b: &mut StreamBufs, n: usize) -> M::S {
    m.region(Region::Setup);
    let zero_v = m.splat_i(0);
    let zf = m.bits_to_f(zero_v);
    m.store(&mut b.num_active, At::off(0), zf);
    let nn = m.int(n as i64);
    m.s_store(&mut b.num_active, At::off(0), 4, nn);
    let mut i = m.int(0);
    loop {
        m.s_store(&mut b.stacks, At::idx(i, 2, 0), 2, i);
        i = m.s_addi(i, 1);
        if !m.branch_if(site::INIT, Cmp::Lt, i, nn) {
            break;
        }
    }
    let zero = m.int(0);
    m.s_store(&mut b.tasks, At::off(0), 4, zero);
    m.s_store(&mut b.tasks, At::off(4), 4, zero);
    m.s_store(&mut b.tasks, At::off(8), 4, nn);
    m.int(TASK_BYTES as i64)
}

/// A popped task.
#[derive(Clone, Copy)]
struct Task<S> {
    node: S,
    lane: S,
    cnt: S,
}

/// `numActive[lane] -= cnt`; returns the index (in ids) of the task's first
/// ray id on the lane's stack (`rayPtr`, plus the lane's stack base).
fn pop_rays<M: Machine>(m: &mut M, b: &mut StreamBufs, lane: M::S, cnt: M::S) -> M::S {
    let na = m.s_load(&b.num_active, At::idx(lane, 4, 0), 4, false);
    let na = m.s_op(SOp::Sub, na, cnt);
    m.s_store(&mut b.num_active, At::idx(lane, 4, 0), 4, na);
    let cap = m.int(b.cap as i64);
    let lb = m.s_op(SOp::Mul, lane, cap);
    m.s_add(lb, na)
}

/// Lines 9-31 for an inner node: Listing 1's loop, then the child tasks.
/// Returns the new task-stack top.
#[allow(clippy::too_many_arguments)]
fn inner<M: Machine>(
    m: &mut M,
    tree: &MbvhBufs,
    b: &mut StreamBufs,
    cfg: &StreamConfig,
    base: usize,
    t: Task<M::S>,
    tsp: M::S,
    c: &mut Counters,
) -> M::S {
    let w = M::LANES;
    c.box_fetches += 1;
    let mut ptr = pop_rays(m, b, t.lane, t.cnt);
    let nb = m.s_shift(Shift::Shl, t.node, node_bytes(w).trailing_zeros());
    let bx: [M::F; 6] = std::array::from_fn(|r| m.load(&tree.nodes, At::idx(nb, 1, 4 * w * r)));
    let vw = m.s_load(&tree.nodes, At::idx(nb, 1, 28 * w), 4, false);
    let valid = m.kmov(vw);
    let before = m.load(&b.num_active, At::off(0));
    let before = m.bits_to_i(before);
    let mut active = before;
    let mut length = m.splat(0.0);
    let mut g = m.mask(0);
    let one = m.splat_i(1);
    let mut i = m.int(0);
    loop {
        m.region(Region::CoreLoop);
        let id = m.s_load(&b.stacks, At::idx(ptr, 2, 0), 2, false);
        ptr = m.s_addi(ptr, 1);
        let rec = m.s_shift(Shift::Shl, id, b.rec.bytes.trailing_zeros());
        let (hit, thit) = box_test(m, b, cfg.form, (base, rec), &bx);
        let hit = m.kand(hit, valid);
        c.box_tests += 1;
        let add = m.keep(hit, thit);
        length = m.add(length, add);
        for u in 0..w {
            let nu = m.s_load(&b.num_active, At::off(4 * u), 4, false);
            m.s_store(&mut b.stacks, At::idx(nu, 2, 2 * u * b.cap), 2, id);
        }
        let inc = m.keep_i(hit, one);
        active = m.iop(IOp::Add, inc, active);
        let af = m.bits_to_f(active);
        m.store(&mut b.num_active, At::off(0), af);
        g = m.kor(hit, g);
        i = m.s_addi(i, 1);
        if !m.branch_if(site::RAY, Cmp::Lt, i, t.cnt) {
            break;
        }
    }
    m.region(Region::Traversal);
    let counts = m.iop(IOp::Sub, active, before);
    push_children(m, tree, b, cfg.order, (nb, g, counts, length), tsp)
}

/// `BoxIntersect4`: one ray (record at `base + rec`) against the box packet
/// `bx`; the lanes whose slab interval is non-empty within the ray's
/// [t_min, length], and the entry distances.
fn box_test<M: Machine>(
    m: &mut M,
    b: &StreamBufs,
    form: RayForm,
    (base, rec): (usize, M::S),
    bx: &[M::F; 6],
) -> (M::K, M::F) {
    let r = &b.rec;
    let ld = |m: &mut M, off: usize| match form {
        RayForm::Replicated => m.load(&b.rays, At::idx(rec, 1, base + off)),
        RayForm::Compact => m.load_bcast(&b.rays, At::idx(rec, 1, base + off)),
    };
    let o: [M::F; 3] = std::array::from_fn(|a| ld(m, r.org[a]));
    let id: [M::F; 3] = std::array::from_fn(|a| ld(m, r.idir[a]));
    let tmin = m.load_bcast(&b.rays, At::idx(rec, 1, base + r.tmin));
    let len = m.load_bcast(&b.rays, At::idx(rec, 1, base + r.length));
    let mut near = [tmin; 3];
    let mut far = [len; 3];
    for a in 0..3 {
        (near[a], far[a]) = slab_axis(m, (bx[2 * a], bx[2 * a + 1]), o[a], id[a]);
    }
    slab_hits(m, near, far, tmin, len)
}

/// A hit child: its ref, lane, ray count and (ordered) accumulated length.
type Kid<M> = (
    <M as Machine>::S,
    <M as Machine>::S,
    <M as Machine>::S,
    Option<<M as Machine>::X>,
);

/// Lines 25-31: a task per hit child (`g`), sorted by accumulated length
/// (ordered) or in lane order; returns the new task-stack top.
fn push_children<M: Machine>(
    m: &mut M,
    tree: &MbvhBufs,
    b: &mut StreamBufs,
    order: Order,
    (nb, g, counts, length): (M::S, M::K, M::I, M::F),
    mut tsp: M::S,
) -> M::S {
    let w = M::LANES;
    let mut bits = m.movemask(g);
    let zero = m.int(0);
    let none = m.s_cmp(Cmp::Eq, bits, zero);
    if m.branch(site::ANY, none) {
        return tsp;
    }
    let cf = m.bits_to_f(counts);
    m.store(&mut b.scratch, At::off(0), cf);
    if order == Order::Ordered {
        m.store(&mut b.scratch, At::off(4 * w), length);
    }
    // (child ref, lane, count, accumulated length) of each hit child.
    let mut kids: Vec<Kid<M>> = Vec::with_capacity(w);
    loop {
        let lane = m.s_tzcnt(bits);
        let child = m.s_load(&tree.nodes, At::base_idx(nb, lane, 4, 24 * w), 4, false);
        let cnt = m.s_load(&b.scratch, At::idx(lane, 4, 0), 4, false);
        let len = (order == Order::Ordered).then(|| m.x_load(&b.scratch, At::idx(lane, 4, 4 * w)));
        kids.push((child, lane, cnt, len));
        let lm1 = m.s_addi(bits, -1);
        bits = m.s_and(bits, lm1);
        let more = m.s_cmp(Cmp::Ne, bits, zero);
        if !m.branch(site::CHILD, more) {
            break;
        }
    }
    if order == Order::Ordered {
        let len = |k: &Kid<M>| k.3.expect("ordered");
        sort_farthest_first(m, &mut kids, len, site::SORT);
    }
    for (child, lane, cnt, _) in kids {
        m.s_store(&mut b.tasks, At::idx(tsp, 1, 0), 4, child);
        m.s_store(&mut b.tasks, At::idx(tsp, 1, 4), 4, lane);
        m.s_store(&mut b.tasks, At::idx(tsp, 1, 8), 4, cnt);
        tsp = m.s_addi(tsp, TASK_BYTES as i64);
    }
    tsp
}

/// Lines 32-41: the task's rays in temporary SoA packets of `W` against each
/// triangle of the leaf, hits scattered back.
fn leaf<M: Machine>(
    m: &mut M,
    tree: &MbvhBufs,
    b: &mut StreamBufs,
    (base, node, lane, cnt): (usize, M::S, M::S, M::S),
    policy: HitPolicy,
    c: &mut Counters,
) {
    let w = M::LANES;
    m.region(Region::Leaf);
    let mut ptr = pop_rays(m, b, lane, cnt);
    let (fb, ntri) = leaf_blocks(m, node);
    let total = cnt.get() as usize;
    let mut done = m.int(0);
    let mut k0 = 0;
    loop {
        let k = w.min(total - k0);
        let idx = packet_index(m, b, &mut ptr, k);
        let live = m.mask(((1u64 << k) - 1) as u32);
        packet(m, tree, b, (base, fb, ntri), idx, live, policy, c);
        k0 += k;
        done = m.s_addi(done, k as i64);
        if !m.branch_if(site::PACKETS, Cmp::Lt, done, cnt) {
            break;
        }
    }
}

/// The next `k` ray ids as byte offsets of their records, in a vector
/// (widened through the scratch row).
fn packet_index<M: Machine>(m: &mut M, b: &mut StreamBufs, ptr: &mut M::S, k: usize) -> M::I {
    let w = M::LANES;
    for j in 0..k {
        let id = m.s_load(&b.stacks, At::idx(*ptr, 2, 0), 2, false);
        *ptr = m.s_addi(*ptr, 1);
        let off = m.s_shift(Shift::Shl, id, b.rec.bytes.trailing_zeros());
        m.s_store(&mut b.scratch, At::off(8 * w + 4 * j), 4, off);
    }
    let v = m.load(&b.scratch, At::off(8 * w));
    m.bits_to_i(v)
}

/// `ray4.loadSoA`, `intersect4` per triangle, `ray4.storeAoS`.
#[allow(clippy::too_many_arguments)]
fn packet<M: Machine>(
    m: &mut M,
    tree: &MbvhBufs,
    b: &mut StreamBufs,
    (base, fb, ntri): (usize, M::S, M::S),
    idx: M::I,
    mut live: M::K,
    policy: HitPolicy,
    c: &mut Counters,
) {
    let r = b.rec;
    let zero = m.splat(0.0);
    let gat =
        |m: &mut M, k: M::K, off: usize| m.gather(k, zero, &b.rays, At::off(base + off), idx, 1);
    let org: [M::F; 3] = std::array::from_fn(|a| gat(m, live, r.org[a]));
    let dir: [M::F; 3] = std::array::from_fn(|a| gat(m, live, r.dir[a]));
    let mut tfar = gat(m, live, r.length);
    if policy.is_any() {
        let tmin = gat(m, live, r.tmin);
        let inf = m.splat(f32::INFINITY);
        let open = m.cmp(Cmp::Lt, tmin, inf);
        live = m.kand(live, open);
    }
    let mut prim = m.splat_i(-1);
    let (mut u, mut v) = (zero, zero);
    let mut hit = m.mask(0);
    let mut t = 0;
    let mut ti = m.int(0);
    loop {
        let blk = broadcast_triangle(m, &tree.tris, fb, t);
        c.prim_tests += 1;
        c.prim_lanes += u64::from(m.bits(live).count_ones());
        let sites = [site::TRI_EDGE, site::TRI_DEPTH];
        if let Some(h) = moller(m, &blk, (&org, &dir, tfar), Some(live), sites) {
            tfar = m.select(h.valid, h.t, tfar);
            prim = m.iselect(h.valid, blk.prim, prim);
            u = m.select(h.valid, h.u, u);
            v = m.select(h.valid, h.v, v);
            hit = m.kor(hit, h.valid);
            if policy.is_any() {
                let open = m.knot(h.valid);
                live = m.kand(live, open);
                let any = m.any(live);
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
    let mut sc = |m: &mut M, off: usize, x: M::F| {
        m.scatter(hit, &mut b.rays, At::off(base + off), idx, 1, x)
    };
    sc(m, r.length, tfar);
    let pf = m.bits_to_f(prim);
    sc(m, r.prim, pf);
    sc(m, r.u, u);
    sc(m, r.v, v);
    if policy.is_any() {
        let inf = m.splat(f32::INFINITY);
        sc(m, r.tmin, inf);
    }
}
