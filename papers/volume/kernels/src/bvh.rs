//! Coherent traversal of the implicit min-max BVH (section 5.2, after Wald
//! et al. 2007): 8x8-ray packets of 16 packlets of 4 rays (SoA), a stack of
//! (node, first active packlet), the first active packlet tested
//! speculatively and then the following ones until one hits; per node the
//! preintegrated opacity over its value range decides empty space (eq. 5)
//! and pruning (eq. 6, the node taken as a leaf); at a leaf every active
//! packlet from the first is clipped to the leaf's box and each of its rays
//! integrated by Listing 2 from where it stopped ([`crate::dvr::State`],
//! kept per ray in memory) to its exit from the leaf. Children are visited
//! nearer first along the node's split axis by the first active ray's
//! direction.
//!
//! The sample sequence of a ray is the brute-force caster's (it starts at
//! the volume's box and steps on), so the BVH only removes samples: those in
//! nodes eq. 5 calls empty (and the classification chain through them).
//!
//! A node whose range is constant for the transfer function (eq. 7) is
//! integrated whole by the constant-subvolume routine ([`crate::constant`]).
//!
//! After a failed speculative test, the packet's interval-arithmetic
//! frustum (its rays' origin and inverse-direction ranges) is tested
//! against the box: if every ray misses, the node is done.

use crate::constant::{constant_node, packlet as constant_packlet, ConstNode};
use crate::dvr::{integrate, Consts, State};
use crate::layout::{VolBufs, PRE_BYTES, STATE_BYTES};
use crate::site;
use isa::{At, Buf, Cmp, Int, Machine, MemKind, Region, Shift};
use scene::volume_bvh::{MinMaxBvh, VNODE_BYTES};
use scene::volume_ref::Sampling;

/// Rays per packet side (8 x 8) and per packlet.
pub const PACKET_SIDE: u32 = 8;
/// Packlets per packet.
pub const PACKLETS: usize = 16;
/// Flag on a node's child word: a leaf.
const LEAF: u32 = 1 << 31;
/// Bytes of one packlet's SoA record: org, dir, idir, 3 rows each.
const PACKLET_BYTES: usize = 9 * 16;

/// The BVH's nodes in simulated memory: per node its box (6 f32), its
/// range and split axis (`min | max << 8 | axis << 16`) and its first
/// child (or `LEAF`).
pub fn lay_out_nodes<M: Machine>(m: &mut M, t: &MinMaxBvh) -> Buf {
    lay_out_node_words(m, &node_words(t))
}

/// [`lay_out_nodes`] of the words [`node_words`] gave (a caller laying out
/// the same tree for many runs makes them once).
pub fn lay_out_node_words<M: Machine>(m: &mut M, words: &[u32]) -> Buf {
    m.space()
        .alloc_u32(MemKind::Volume, "minmax-bvh", words, 64)
}

/// The words [`lay_out_nodes`] writes for `t`'s nodes.
#[must_use]
pub fn node_words(t: &MinMaxBvh) -> Vec<u32> {
    let mut words: Vec<u32> = Vec::with_capacity(t.nodes.len() * 8);
    for n in &t.nodes {
        for c in n.lo.iter().chain(&n.hi) {
            words.push((*c as f32).to_bits());
        }
        words.push(u32::from(n.min) | u32::from(n.max) << 8 | u32::from(n.axis) << 16);
        words.push(n.children.map_or(LEAF, |c| c[0]));
    }
    if words.is_empty() {
        words.resize(8, 0);
    }
    assert_eq!(words.len() * 4, t.nodes.len().max(1) * VNODE_BYTES);
    words
}

/// The thresholds of eqs. 5 and 6 and the volume's diagonal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Heuristics {
    /// Eq. 5's culling threshold delta_c.
    pub delta_c: f32,
    /// Eq. 6's pruning threshold delta_p.
    pub delta_p: f32,
    /// Eq. 7's constant-subvolume threshold delta_sv (0: never).
    pub delta_sv: f32,
    /// Where eq. 7 is tested.
    pub constant_at: ConstantAt,
}

/// Where the traversal tests a node for a constant subvolume (eq. 7).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ConstantAt {
    /// At leaves and at nodes eq. 6 prunes into leaves, as the paper does
    /// ("we can analyze a leaf", section 5.2).
    Leaves,
    /// At every node popped, inner ones included (a variant: large
    /// homogeneous regions are taken whole without descending).
    EveryNode,
}

/// One packet's buffers.
pub struct PacketBufs<'a> {
    /// Packlet records (SoA).
    pub packlets: &'a Buf,
    /// Per-ray states.
    pub states: &'a mut Buf,
    /// Traversal stack: (node, first) pairs.
    pub stack: &'a mut Buf,
    /// Listing 2's scratch.
    pub scratch: &'a mut Buf,
}

/// Packlet record rows (16 bytes each).
mod row {
    pub const ORG: usize = 0;
    pub const DIR: usize = 3;
    pub const IDIR: usize = 6;
}

/// SoA packlet records of a packet's 64 rays (ray `k` of the packet is
/// lane `k % 4` of packlet `k / 4`).
#[must_use]
pub fn packlet_records(org: &[[f32; 3]], dir: &[[f32; 3]]) -> Vec<f32> {
    assert_eq!(org.len(), PACKLETS * 4);
    let mut v = vec![0f32; PACKLETS * PACKLET_BYTES / 4];
    for (k, (o, d)) in org.iter().zip(dir).enumerate() {
        let (p, l) = (k / 4, k % 4);
        for a in 0..3 {
            let at = |r: usize| p * PACKLET_BYTES / 4 + (r + a) * 4 + l;
            v[at(row::ORG)] = o[a];
            v[at(row::DIR)] = d[a];
            v[at(row::IDIR)] = 1.0 / d[a];
        }
    }
    v
}

/// Traverse the BVH for one packet whose rays' states are set up; each
/// state ends with the ray's colour.
#[allow(clippy::too_many_arguments)]
pub fn trace_packet<M: Machine>(
    m: &mut M,
    v: &VolBufs,
    nodes: &Buf,
    pb: PacketBufs,
    c: &Consts<M>,
    (h, vol_diag): (Heuristics, f32),
    s: &Sampling,
) {
    m.region(Region::Traversal);
    let PacketBufs {
        packlets,
        states,
        stack,
        scratch,
    } = pb;
    let zero = m.int(0);
    m.s_store(stack, At::off(0), 4, zero);
    m.s_store(stack, At::off(4), 4, zero);
    let mut sp = m.int(1);
    let dc = m.float(h.delta_c);
    let dp_vol = m.float(h.delta_p / vol_diag);
    let dsv = m.float(h.delta_sv);
    let frustum = Frustum::of(m, packlets);
    loop {
        m.region(Region::Traversal);
        if !m.branch_if(site::STACK, Cmp::Gt, sp, zero) {
            break;
        }
        sp = m.s_addi(sp, -1);
        c.bump(|k| k.nodes += 1);
        let node = m.s_load(stack, At::idx(sp, 8, 0), 4, false);
        let first = m.s_load(stack, At::idx(sp, 8, 4), 4, false);
        let nb = m.s_shift(Shift::Shl, node, VNODE_BYTES.trailing_zeros());
        let range = m.s_load(nodes, At::idx(nb, 1, 24), 4, false);
        let alpha = range_alpha(m, v, range);
        // Eq. 5: nothing visible in the node's range.
        let empty = m.x_cmp(Cmp::Le, alpha, dc);
        if m.branch(site::EMPTY, empty) {
            continue;
        }
        let bx = NodeBox::load(m, nodes, nb);
        let Some(first) = first_hit(m, (packlets, &frustum), (&bx, nb, nodes), (first, c)) else {
            continue;
        };
        let bufs = (packlets, &mut *states, &mut *scratch);
        if h.constant_at == ConstantAt::EveryNode
            && taken_as_constant(m, v, bufs, (&bx, first), (range, alpha, dsv), (c, s))
        {
            continue;
        }
        m.region(Region::Traversal);
        let child = m.s_load(nodes, At::idx(nb, 1, 28), 4, false);
        let leaf_flag = m.int(i64::from(LEAF));
        let is_leaf = m.s_and(child, leaf_flag);
        // Eq. 6: opaque for its size: take it as a leaf.
        let pruned = is_leaf.get() == 0 && {
            let diag = bx.diagonal(m);
            let limit = m.x_op(isa::BinOp::Mul, dp_vol, diag);
            let prune = m.x_cmp(Cmp::Gt, alpha, limit);
            m.branch(site::PRUNE, prune)
        };
        if m.branch(site::LEAF, is_leaf) || pruned {
            let bufs = (packlets, &mut *states, &mut *scratch);
            if h.constant_at == ConstantAt::Leaves
                && taken_as_constant(m, v, bufs, (&bx, first), (range, alpha, dsv), (c, s))
            {
                continue;
            }
            leaf(
                m,
                (v, packlets, &mut *states, &mut *scratch),
                &bx,
                first,
                c,
                s,
            );
            continue;
        }
        push_children(m, (stack, &mut sp), (packlets, first), (range, child));
    }
}

/// Eq. 7 on a node (range word `range`, range opacity `alpha`): if it is
/// constant within `dsv`, every packlet from `first` is integrated through
/// its box by the constant-subvolume routine. Whether it was.
fn taken_as_constant<M: Machine>(
    m: &mut M,
    v: &VolBufs,
    bufs: (&Buf, &mut Buf, &mut Buf),
    (bx, first): (&NodeBox<M>, M::S),
    (range, alpha, dsv): (M::S, M::X, M::X),
    (c, s): (&Consts<M>, &Sampling),
) -> bool {
    let Some(cn) = constant_node(m, v, (range, alpha), dsv, (c, s)) else {
        return false;
    };
    constant(m, bufs, bx, first, &cn, (c, s));
    true
}

/// The preintegrated opacity over a node's range word.
fn range_alpha<M: Machine>(m: &mut M, v: &VolBufs, range: M::S) -> M::X {
    let mask = m.int(0xffff);
    let mm = m.s_and(range, mask);
    // Entry (min, max) of the table, its alpha at byte 12.
    let lo = m.int(0xff);
    let min = m.s_and(mm, lo);
    let max = m.s_shift(Shift::Shr, mm, 8);
    let row = m.s_shift(Shift::Shl, min, 8);
    let k = m.s_add(row, max);
    let off = m.s_shift(Shift::Shl, k, PRE_BYTES.trailing_zeros());
    m.x_load(&v.pre, At::idx(off, 1, 12))
}

/// A node's box, each bound broadcast.
struct NodeBox<M: Machine> {
    lo: [M::F; 3],
    hi: [M::F; 3],
    lo_x: [M::X; 3],
    hi_x: [M::X; 3],
}

impl<M: Machine> NodeBox<M> {
    fn load(m: &mut M, nodes: &Buf, nb: M::S) -> Self {
        let lo_x = [0, 1, 2].map(|a| m.x_load(nodes, At::idx(nb, 1, 4 * a)));
        let hi_x = [0, 1, 2].map(|a| m.x_load(nodes, At::idx(nb, 1, 12 + 4 * a)));
        NodeBox {
            lo: lo_x.map(|x| m.broadcast(x)),
            hi: hi_x.map(|x| m.broadcast(x)),
            lo_x,
            hi_x,
        }
    }
    /// The box's diagonal length.
    fn diagonal(&self, m: &mut M) -> M::X {
        let d = [0, 1, 2].map(|a| m.x_op(isa::BinOp::Sub, self.hi_x[a], self.lo_x[a]));
        let d0 = m.x_op(isa::BinOp::Mul, d[0], d[0]);
        let d1 = m.x_fma(isa::Fma::MAdd, d[1], d[1], d0);
        let d2 = m.x_fma(isa::Fma::MAdd, d[2], d[2], d1);
        m.x_sqrt(d2)
    }
    /// Packlet `k` (register index) against the box: entry, exit, hit mask.
    fn test(&self, m: &mut M, packlets: &Buf, k: M::S) -> (M::F, M::F, M::K) {
        let bytes = m_int(m, PACKLET_BYTES);
        let base = m.s_op(isa::SOp::Mul, k, bytes);
        let mut near = m.splat(0.0);
        let mut far = m.splat(f32::INFINITY);
        for a in 0..3 {
            let o = m.load(packlets, At::idx(base, 1, 16 * (row::ORG + a)));
            let id = m.load(packlets, At::idx(base, 1, 16 * (row::IDIR + a)));
            let l = m.sub(self.lo[a], o);
            let h = m.sub(self.hi[a], o);
            let t0 = m.mul(l, id);
            let t1 = m.mul(h, id);
            let mn = m.min(t0, t1);
            let mx = m.max(t0, t1);
            near = m.max(near, mn);
            far = m.min(far, mx);
        }
        let hit = m.cmp(Cmp::Le, near, far);
        (near, far, hit)
    }
}

fn m_int<M: Machine>(m: &mut M, v: usize) -> M::S {
    m.int(v as i64)
}

/// The packet's frustum as intervals (Wald et al. 2007): per axis (lanes
/// x, y, z) the range of its rays' origins and inverse directions, and
/// which axes the interval test may use (inverse directions finite and of
/// one sign).
struct Frustum<M: Machine> {
    omin: M::F,
    omax: M::F,
    idmin: M::F,
    idmax: M::F,
    usable: M::K,
}

impl<M: Machine> Frustum<M> {
    /// Bound the packet's 16 packlet records.
    fn of(m: &mut M, packlets: &Buf) -> Self {
        let axes = |m: &mut M, first_row: usize| -> (M::F, M::F) {
            let mut lo = [m.splat(f32::INFINITY); 3];
            let mut hi = [m.splat(f32::NEG_INFINITY); 3];
            for k in 0..PACKLETS {
                for a in 0..3 {
                    let r = m.load(packlets, At::off(k * PACKLET_BYTES + 16 * (first_row + a)));
                    lo[a] = m.min(lo[a], r);
                    hi[a] = m.max(hi[a], r);
                }
            }
            let lo = lo.map(|v| m.hmin(v));
            let hi = hi.map(|v| m.hmax(v));
            (xyz(m, lo), xyz(m, hi))
        };
        let (omin, omax) = axes(m, row::ORG);
        let (idmin, idmax) = axes(m, row::IDIR);
        let big = m.splat(1e30);
        let nbig = m.splat(-1e30);
        let zero = m.splat(0.0);
        let finite = {
            let a = m.cmp(Cmp::Gt, idmin, nbig);
            let b = m.cmp(Cmp::Lt, idmax, big);
            m.kand(a, b)
        };
        let one_sign = {
            let a = m.cmp(Cmp::Ge, idmin, zero);
            let b = m.cmp(Cmp::Le, idmax, zero);
            m.kor(a, b)
        };
        let xyz_lanes = m.mask(0b0111);
        let usable = m.kand(finite, one_sign);
        let usable = m.kand(usable, xyz_lanes);
        Frustum {
            omin,
            omax,
            idmin,
            idmax,
            usable,
        }
    }

    /// Whether every ray of the packet misses the box at `nb` (interval
    /// arithmetic over the slabs; conservative: `false` when unsure).
    fn misses(&self, m: &mut M, nodes: &Buf, nb: M::S) -> M::S {
        let lo = m.loadu(nodes, At::idx(nb, 1, 0));
        let hi = m.loadu(nodes, At::idx(nb, 1, 12));
        let slab = |m: &mut M, b: M::F| -> (M::F, M::F) {
            // [b - omax, b - omin] * [idmin, idmax]
            let x0 = m.sub(b, self.omax);
            let x1 = m.sub(b, self.omin);
            let p = [
                m.mul(x0, self.idmin),
                m.mul(x0, self.idmax),
                m.mul(x1, self.idmin),
                m.mul(x1, self.idmax),
            ];
            let l01 = m.min(p[0], p[1]);
            let l23 = m.min(p[2], p[3]);
            let h01 = m.max(p[0], p[1]);
            let h23 = m.max(p[2], p[3]);
            (m.min(l01, l23), m.max(h01, h23))
        };
        let (lo_l, lo_h) = slab(m, lo);
        let (hi_l, hi_h) = slab(m, hi);
        let near = m.min(lo_l, hi_l);
        let far = m.max(lo_h, hi_h);
        let ninf = m.splat(f32::NEG_INFINITY);
        let inf = m.splat(f32::INFINITY);
        let near = m.select(self.usable, near, ninf);
        let far = m.select(self.usable, far, inf);
        let tn = m.hmax(near);
        let tf = m.hmin(far);
        let apart = m.x_cmp(Cmp::Gt, tn, tf);
        let z = m.float(0.0);
        let behind = m.x_cmp(Cmp::Lt, tf, z);
        m.s_op(isa::SOp::Or, apart, behind)
    }
}

/// `{x, y, z, 0}` from three scalars.
fn xyz<M: Machine>(m: &mut M, v: [M::X; 3]) -> M::F {
    let b = v.map(|x| m.broadcast(x));
    let zero = m.splat(0.0);
    let xy = m.shuffle2(b[0], b[1], &[0, 0, 4, 4]);
    let z0 = m.shuffle2(b[2], zero, &[0, 0, 4, 4]);
    m.shuffle2(xy, z0, &[0, 2, 4, 6])
}

/// The first packlet from `first` that hits the box, or `None`: the first
/// itself tested speculatively; if it misses, the packet's frustum (all
/// rays miss: done), then the following packlets in turn.
fn first_hit<M: Machine>(
    m: &mut M,
    (packlets, frustum): (&Buf, &Frustum<M>),
    (bx, nb, nodes): (&NodeBox<M>, M::S, &Buf),
    (first, c): (M::S, &Consts<M>),
) -> Option<M::S> {
    let end = m.int(PACKLETS as i64);
    let mut k = first;
    let mut speculative = true;
    loop {
        let (_, _, hit) = bx.test(m, packlets, k);
        let any = m.any(hit);
        if m.branch(site::PACKLET_HIT, any) {
            return Some(k);
        }
        if std::mem::take(&mut speculative) {
            let miss = frustum.misses(m, nodes, nb);
            if m.branch(site::FRUSTUM, miss) {
                c.bump(|x| x.frustum_culls += 1);
                return None;
            }
        }
        k = m.s_addi(k, 1);
        if !m.branch_if(site::PACKLET, Cmp::Lt, k, end) {
            return None;
        }
    }
}

/// Push the children, the farther along the split axis (by the first active
/// ray's direction) first, so the nearer is popped next.
fn push_children<M: Machine>(
    m: &mut M,
    (stack, sp): (&mut Buf, &mut M::S),
    (packlets, first): (&Buf, M::S),
    (range, child): (M::S, M::S),
) {
    let axis = m.s_shift(Shift::Shr, range, 16);
    let three = m.int(3);
    let axis = m.s_and(axis, three);
    let bytes = m_int(m, PACKLET_BYTES);
    let base = m.s_op(isa::SOp::Mul, first, bytes);
    let row = m.s_shift(Shift::Shl, axis, 4);
    let at = m.s_add(base, row);
    let d = m.x_load(packlets, At::idx(at, 1, 16 * row::DIR));
    let z = m.float(0.0);
    let neg = m.x_cmp(Cmp::Lt, d, z);
    let second = m.s_addi(child, 1);
    let (near, far) = if m.branch(site::ORDER, neg) {
        (second, child)
    } else {
        (child, second)
    };
    for n in [far, near] {
        m.s_store(stack, At::idx(*sp, 8, 0), 4, n);
        m.s_store(stack, At::idx(*sp, 8, 4), 4, first);
        *sp = m.s_addi(*sp, 1);
    }
}

/// A leaf: every packlet from `first` clipped to the box, each hitting ray
/// integrated from its next sample to its exit from the box.
fn leaf<M: Machine>(
    m: &mut M,
    (v, packlets, states, scratch): (&VolBufs, &Buf, &mut Buf, &mut Buf),
    bx: &NodeBox<M>,
    first: M::S,
    c: &Consts<M>,
    s: &Sampling,
) {
    let end = m.int(PACKLETS as i64);
    let mut k = first;
    loop {
        m.region(Region::Traversal);
        let (near, far, hit) = bx.test(m, packlets, k);
        let mut bits = m.movemask(hit);
        let zero = m.int(0);
        while m.branch_if(site::LEAF_RAY, Cmp::Ne, bits, zero) {
            let lane = m.s_tzcnt(bits);
            let l = lane.get() as usize;
            let tenter = m.extract(near, l);
            let texit = m.extract(far, l);
            let four = m.s_shift(Shift::Shl, k, 2);
            let ray = m.s_add(four, lane);
            let io = (tenter, texit);
            one_ray(
                m,
                (v, packlets, &mut *states, &mut *scratch),
                (k, l, ray),
                io,
                c,
                s,
            );
            m.region(Region::Traversal);
            let b1 = m.s_addi(bits, -1);
            bits = m.s_and(bits, b1);
        }
        k = m.s_addi(k, 1);
        if !m.branch_if(site::PACKLET, Cmp::Lt, k, end) {
            break;
        }
    }
}

/// A constant node (eq. 7): every packlet from `first` clipped to the box
/// and integrated by the constant-subvolume routine.
fn constant<M: Machine>(
    m: &mut M,
    (packlets, states, scratch): (&Buf, &mut Buf, &mut Buf),
    bx: &NodeBox<M>,
    first: M::S,
    cn: &ConstNode<M>,
    (c, s): (&Consts<M>, &Sampling),
) {
    let end = m.int(PACKLETS as i64);
    let mut k = first;
    loop {
        m.region(Region::Traversal);
        let io = bx.test(m, packlets, k);
        constant_packlet(m, (&mut *states, &mut *scratch), k, io, cn, c, s);
        m.region(Region::Traversal);
        k = m.s_addi(k, 1);
        if !m.branch_if(site::PACKLET, Cmp::Lt, k, end) {
            break;
        }
    }
}

/// Integrate one ray of the packet through a leaf it leaves at `texit`,
/// from its saved state (nothing if it is opaque or its next sample is
/// beyond the leaf).
fn one_ray<M: Machine>(
    m: &mut M,
    (v, packlets, states, scratch): (&VolBufs, &Buf, &mut Buf, &mut Buf),
    (k, l, ray): (M::S, usize, M::S),
    (tenter, texit): (M::X, M::X),
    c: &Consts<M>,
    s: &Sampling,
) {
    let sb = m.s_shift(Shift::Shl, ray, STATE_BYTES.trailing_zeros());
    let p = m.load(states, At::idx(sb, 1, 16));
    let t = m.extract(p, 3);
    let beyond = m.x_cmp(Cmp::Gt, t, texit);
    let rgba = m.load(states, At::idx(sb, 1, 0));
    let a = m.extract(rgba, 3);
    let opaque_at = m.float(0.95);
    let opaque = m.x_cmp(Cmp::Gt, a, opaque_at);
    let skip = m.s_op(isa::SOp::Or, beyond, opaque);
    if m.branch(site::SKIP, skip) {
        return;
    }
    let bytes = m_int(m, PACKLET_BYTES);
    let pb = m.s_op(isa::SOp::Mul, k, bytes);
    let d = [0, 1, 2].map(|a| m.x_load(packlets, At::idx(pb, 1, 16 * (row::DIR + a) + 4 * l)));
    let dir = {
        let bc = d.map(|x| m.broadcast(x));
        let xy = m.shuffle2(bc[0], bc[1], &[0, 0, 4, 4]);
        let one = c_one(m);
        let z1 = m.shuffle2(bc[2], one, &[0, 0, 4, 4]);
        m.shuffle2(xy, z1, &[0, 2, 4, 6])
    };
    let mut st = State {
        rgba,
        p,
        sdt: m.load(states, At::idx(sb, 1, 32)),
        flast: m.s_load(states, At::idx(sb, 1, 48), 4, true),
    };
    c.bump(|k| k.leaf_rays += 1);
    skip_to(m, &mut st, (dir, tenter), c, s);
    // The ray may cross the leaf between two samples: its next one then
    // belongs to a later node (and may lie outside the volume).
    let t = m.extract(st.p, 3);
    let past = m.x_cmp(Cmp::Gt, t, texit);
    if !m.branch(site::SKIP_PAST, past) {
        integrate(m, (v, scratch), c, &mut st, (dir, texit), s);
    }
    m.store(states, At::idx(sb, 1, 0), st.rgba);
    m.store(states, At::idx(sb, 1, 16), st.p);
    m.store(states, At::idx(sb, 1, 32), st.sdt);
    m.s_store(states, At::idx(sb, 1, 48), 4, st.flast);
}

/// Move a ray's next sample up to the leaf's entry `tenter` along its own
/// sample sequence (the samples between lie in nodes the traversal
/// skipped), in closed form: uniform steps `k = ceil((tenter - t) / dt)`,
/// differential ones by the quadratic's root.
fn skip_to<M: Machine>(
    m: &mut M,
    st: &mut State<M>,
    (dir, tenter): (M::F, M::X),
    c: &Consts<M>,
    s: &Sampling,
) {
    m.region(Region::Traversal);
    let t = m.extract(st.p, 3);
    let before = m.x_cmp(Cmp::Lt, t, tenter);
    if !m.branch(site::SKIP_AHEAD, before) {
        return;
    }
    let te = m.broadcast(tenter);
    if s.rda == 0.0 {
        let tv = m.permute(st.p, &[3, 3, 3, 3]);
        let gap = m.sub(te, tv);
        let dt = m.permute(st.sdt, &[3, 3, 3, 3]);
        let n = m.div(gap, dt);
        let ni = m.to_int(n);
        let k = m.to_float(ni);
        let covered = m.mul(k, dt);
        let short = m.cmp(Cmp::Lt, covered, gap);
        let one = m.splat(1.0);
        let k1 = m.add(k, one);
        let k = m.select(short, k1, k);
        st.p = m.fmadd(k, st.sdt, st.p);
        return;
    }
    // Differential steps: sample j ahead lies at t + j w + j (j - 1) / 2 rda
    // (w the step now); the first at or past the entry solves a quadratic.
    // Its floor (f32 may round it one low) in closed form, as the
    // constant-subvolume routine moves a state, then single steps.
    let tv = m.permute(st.p, &[3, 3, 3, 3]);
    let w = m.permute(st.sdt, &[3, 3, 3, 3]);
    let rda = c.rda_vec();
    let half = m.splat(0.5);
    let hr = m.mul(rda, half);
    let b = m.sub(w, hr);
    let gap = m.sub(te, tv);
    let two_r = m.add(rda, rda);
    let bb = m.mul(b, b);
    let disc = m.fmadd(two_r, gap, bb);
    let root = m.sqrt(disc);
    let num = m.sub(root, b);
    let j = m.div(num, rda);
    let ji = m.to_int(j);
    let j = m.to_float(ji);
    let r = m.div(rda, w);
    let one = m.splat(1.0);
    let jm1 = m.sub(j, one);
    let tri = m.mul(j, jm1);
    let tri = m.mul(tri, half);
    let fk = m.fmadd(tri, r, j);
    let gk = m.fmadd(j, r, one);
    st.p = m.fmadd(st.sdt, fk, st.p);
    st.sdt = m.mul(st.sdt, gk);
    let srda = m.mul(dir, rda);
    loop {
        let t = m.extract(st.p, 3);
        let short = m_lt(m, t, tenter);
        if !m.branch(site::SKIP_STEP, short) {
            break;
        }
        st.p = m.add(st.p, st.sdt);
        st.sdt = m.add(st.sdt, srda);
    }
}

fn m_lt<M: Machine>(m: &mut M, a: M::X, b: M::X) -> M::S {
    m.x_cmp(Cmp::Lt, a, b)
}

fn c_one<M: Machine>(m: &mut M) -> M::F {
    m.splat(1.0)
}
