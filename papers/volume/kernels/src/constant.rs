//! The constant-subvolume routine (section 5.2, eq. 7): a node whose
//! classified range is constant within delta_sv is integrated without
//! fetching a voxel, in SoA over a packlet (4 rays in the lanes): each ray's
//! samples inside the node's box are blended with the node's one colour
//! (the preintegrated entry of its range), counting steps, and each ray's
//! state is moved past them.
//!
//! The samples are the ray's own sequence (the brute-force caster's), so
//! what eq. 7 changes is each sample's colour (the range's entry instead of
//! the entry between its interpolated neighbours) and its lighting: the
//! gradient of a constant field is zero, so a lit sample above the
//! threshold gets the ambient term only (Listing 2's `0.15 + |n . l|` with
//! n = 0).

use crate::dvr::Consts;
use crate::layout::{VolBufs, PRE_BYTES, STATE_BYTES};
use crate::site;
use isa::{At, BinOp, Buf, Cmp, Int, Machine, Region, Shift};
use scene::volume_ref::{Lighting, Sampling};

/// A constant node's colour, one splat per channel, and the value the
/// classification chain continues from.
pub struct ConstNode<M: Machine> {
    rgba: [M::F; 4],
    mid: M::S,
}

/// The preintegrated entry of (`a`, `b`), its byte offset.
fn entry<M: Machine>(m: &mut M, a: M::S, b: M::S) -> M::S {
    let row = m.s_shift(Shift::Shl, a, 8);
    let k = m.s_add(row, b);
    m.s_shift(Shift::Shl, k, PRE_BYTES.trailing_zeros())
}

/// `|a - b|` on scalars.
fn abs_diff<M: Machine>(m: &mut M, a: M::X, b: M::X) -> M::X {
    let d = m.x_op(BinOp::Sub, a, b);
    let e = m.x_op(BinOp::Sub, b, a);
    m.x_op(BinOp::Max, d, e)
}

/// Eq. 7 on a node's range word (`min | max << 8 | ...`) whose range
/// opacity is `alpha`: its colour if the range is constant within `dsv`
/// and holds no empty value (every sample in it is classified), else
/// `None`.
pub fn constant_node<M: Machine>(
    m: &mut M,
    v: &VolBufs,
    (range, alpha): (M::S, M::X),
    dsv: M::X,
    (c, s): (&Consts<M>, &Sampling),
) -> Option<ConstNode<M>> {
    let lo = m.int(0xff);
    let min = m.s_and(range, lo);
    let shifted = m.s_shift(Shift::Shr, range, 8);
    let max = m.s_and(shifted, lo);
    let zero = m.int(0);
    let empty_value = m.s_cmp(Cmp::Eq, min, zero);
    let at_min = entry(m, min, min);
    let at_max = entry(m, max, max);
    let a_min = m.x_load(&v.pre, At::idx(at_min, 1, 12));
    let a_max = m.x_load(&v.pre, At::idx(at_max, 1, 12));
    let d_min = abs_diff(m, alpha, a_min);
    let d_max = abs_diff(m, alpha, a_max);
    let d = m.x_op(BinOp::Max, d_min, d_max);
    let varies = m.x_cmp(Cmp::Ge, d, dsv);
    let no = m.s_op(isa::SOp::Or, varies, empty_value);
    if m.branch(site::CONSTANT, no) {
        return None;
    }
    let at = entry(m, min, max);
    let mut colour = m.load(&v.pre, At::idx(at, 1, 0));
    if s.lighting != Lighting::Unlit {
        colour = c.ambient_only(m, colour);
    }
    let rgba = [0, 1, 2, 3].map(|ch| m.permute(colour, &[ch; 4]));
    let sum = m.s_add(min, max);
    let mid = m.s_shift(Shift::Shr, sum, 1);
    Some(ConstNode { rgba, mid })
}

/// Four rays' states in SoA: colour channels, the next sample's t, the
/// next step, and the steps taken here.
struct Soa<M: Machine> {
    rgba: [M::F; 4],
    t: M::F,
    step: M::F,
    k: M::F,
}

/// The 4x4 transpose of `rows` (row i's lane j to row j's lane i).
fn transpose<M: Machine>(m: &mut M, r: [M::F; 4]) -> [M::F; 4] {
    let a = m.shuffle2(r[0], r[1], &[0, 4, 1, 5]);
    let b = m.shuffle2(r[2], r[3], &[0, 4, 1, 5]);
    let c = m.shuffle2(r[0], r[1], &[2, 6, 3, 7]);
    let d = m.shuffle2(r[2], r[3], &[2, 6, 3, 7]);
    [
        m.shuffle2(a, b, &[0, 1, 4, 5]),
        m.shuffle2(a, b, &[2, 3, 6, 7]),
        m.shuffle2(c, d, &[0, 1, 4, 5]),
        m.shuffle2(c, d, &[2, 3, 6, 7]),
    ]
}

/// Integrate packlet `k` (its rays' states at `states`, entry and exit
/// distances `near`, `far` through the node's box, `hit` the rays that
/// meet it) through a constant node.
#[allow(clippy::too_many_arguments)]
pub fn packlet<M: Machine>(
    m: &mut M,
    (states, scratch): (&mut Buf, &mut Buf),
    k: M::S,
    (near, far, hit): (M::F, M::F, M::K),
    node: &ConstNode<M>,
    c: &Consts<M>,
    s: &Sampling,
) {
    m.region(Region::Volume);
    let base = m.s_shift(Shift::Shl, k, 2 + STATE_BYTES.trailing_zeros());
    let at = |i: usize, off: usize| At::idx(base, 1, i * STATE_BYTES + off);
    let colour: [M::F; 4] = std::array::from_fn(|i| m.load(states, at(i, 0)));
    let p: [M::F; 4] = std::array::from_fn(|i| m.load(states, at(i, 16)));
    let sdt: [M::F; 4] = std::array::from_fn(|i| m.load(states, at(i, 32)));
    let mut st = Soa {
        rgba: transpose(m, colour),
        t: transpose(m, p)[3],
        step: transpose(m, sdt)[3],
        k: m.splat(0.0),
    };
    let rda = c.rda_vec();
    let one = m.splat(1.0);
    // Up to the box's entry: the samples before it lie in skipped nodes.
    loop {
        let before = m.cmp(Cmp::Lt, st.t, near);
        let go = m.kand(before, hit);
        let any = m.any(go);
        if !m.branch(site::CONST_SKIP, any) {
            break;
        }
        advance(m, &mut st, go, (rda, one), s);
    }
    let term = m.splat(scene::volume_ref::EARLY_TERMINATION as f32);
    loop {
        let inside = m.cmp(Cmp::Le, st.t, far);
        let clear = m.cmp(Cmp::Le, st.rgba[3], term);
        let live = m.kand(inside, clear);
        let live = m.kand(live, hit);
        let any = m.any(live);
        if !m.branch(site::CONST_STEP, any) {
            break;
        }
        let n = m.movemask(live).get().count_ones();
        c.bump(|x| {
            x.samples += u64::from(n);
            x.classified += u64::from(n);
            x.constant_samples += u64::from(n);
        });
        m.region(Region::Blending);
        let keep = m.sub(one, st.rgba[3]);
        for ch in 0..4 {
            let b = m.fmadd(node.rgba[ch], keep, st.rgba[ch]);
            st.rgba[ch] = m.select(live, b, st.rgba[ch]);
        }
        m.region(Region::Volume);
        advance(m, &mut st, live, (rda, one), s);
    }
    write_back(m, (states, scratch), base, (&st, &p, &sdt), node, s);
}

/// One step for the lanes of `go`: t by the step, the step by rda, k by 1.
fn advance<M: Machine>(
    m: &mut M,
    st: &mut Soa<M>,
    go: M::K,
    (rda, one): (M::F, M::F),
    s: &Sampling,
) {
    let t = m.add(st.t, st.step);
    st.t = m.select(go, t, st.t);
    if s.rda != 0.0 {
        let step = m.add(st.step, rda);
        st.step = m.select(go, step, st.step);
    }
    let k = m.add(st.k, one);
    st.k = m.select(go, k, st.k);
}

/// Store the colours, and for each ray that stepped its next sample and
/// step in closed form: with the step `w` now and direction `sdt / w`,
/// `k` steps move `p` by `sdt (k + k (k - 1) / 2 rda / w)` and grow `sdt`
/// by the factor `1 + k rda / w`.
fn write_back<M: Machine>(
    m: &mut M,
    (states, scratch): (&mut Buf, &mut Buf),
    base: M::S,
    (st, p, sdt): (&Soa<M>, &[M::F; 4], &[M::F; 4]),
    node: &ConstNode<M>,
    s: &Sampling,
) {
    let colour = transpose(m, st.rgba);
    for (i, c) in colour.into_iter().enumerate() {
        m.store(states, At::idx(base, 1, i * STATE_BYTES), c);
    }
    let (fk, gk) = if s.rda == 0.0 {
        (st.k, m.splat(1.0))
    } else {
        let rda = m.splat(s.rda as f32);
        let r = m.div(rda, st.step);
        let one = m.splat(1.0);
        let half = m.splat(0.5);
        let km1 = m.sub(st.k, one);
        let tri = m.mul(st.k, km1);
        let tri = m.mul(tri, half);
        let fk = m.fmadd(tri, r, st.k);
        let gk = m.fmadd(st.k, r, one);
        (fk, gk)
    };
    m.store(scratch, At::off(0), fk);
    m.store(scratch, At::off(16), gk);
    let zero = m.splat(0.0);
    let stepped = m.cmp(Cmp::Gt, st.k, zero);
    let mut bits = m.movemask(stepped);
    let izero = m.int(0);
    while m.branch_if(site::CONST_RAY, Cmp::Ne, bits, izero) {
        let lane = m.s_tzcnt(bits);
        let l = lane.get() as usize;
        let f = m.x_load(scratch, At::idx(lane, 4, 0));
        let g = m.x_load(scratch, At::idx(lane, 4, 16));
        let f = m.broadcast(f);
        let g = m.broadcast(g);
        let np = m.fmadd(sdt[l], f, p[l]);
        let nsdt = m.mul(sdt[l], g);
        m.store(states, At::idx(base, 1, l * STATE_BYTES + 16), np);
        m.store(states, At::idx(base, 1, l * STATE_BYTES + 32), nsdt);
        m.s_store(states, At::idx(base, 1, l * STATE_BYTES + 48), 4, node.mid);
        let b1 = m.s_addi(bits, -1);
        bits = m.s_and(bits, b1);
    }
}
