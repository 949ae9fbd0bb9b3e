//! The paper's "gcc" baseline: a naive floating-point ray caster as gcc 4.x
//! makes it from plain C, one scalar at a time. Same bricked volume, offset
//! tables, preintegrated table and sample sequence as Listing 2
//! ([`crate::dvr`]), but written as the paper counts its naive code ("over
//! 32 muls, 34 adds, 3 casts, and 8 voxel address translations"):
//!
//! - every corner of the stencil is its own address translation
//!   (`vdata[voff_x[i + di] + voff_y[j + dj] + voff_z[k + dk]]`: three
//!   offset loads, two adds and a byte load each; nothing shared between
//!   corners), counted with the interpolation as the paper's profile
//!   counts it (its Table 1 gives the same voxel-fetch time per frame with
//!   and without trilinear interpolation);
//! - the trilinear interpolant is the eight-term sum of eq. 8 in scalar
//!   floats, the gradient eq. 9 term by term, vectors normalised by `sqrtss`
//!   and a division, the colour four scalars;
//! - register pressure as x86-64 has it (16 xmm registers): the loop keeps
//!   the position, its parameter and step, the colour and the last value in
//!   registers ([`Frame`] says which); the loop-invariant steps, exit and
//!   direction live in the stack frame and are reloaded where used, float
//!   constants are memory operands (a load at each use), the eight corners
//!   are spilled once converted and reloaded at each use, and the six
//!   weights are spilled for the gradient, which runs after the table
//!   lookup and blending have needed the registers.
//!
//! Written as straight-line scalar code: a compiler does not vectorise a
//! loop whose trip count depends on the data and whose body gathers through
//! tables (the paper calls it "compiler-vectorized", its Table 1 profile
//! is that of scalar code: voxel fetching dominates).

use crate::dvr::Counters;
use crate::layout::VolBufs;
use crate::site;
use isa::{At, BinOp, Buf, Cmp, Machine, MemKind, Program, Region, SOp};
use scene::volume_bvh::BRICK;
use scene::volume_ref::{Filter, Lighting, Sampling};
use std::cell::Cell;

/// The "gcc" method over a set of rays: RGBA per ray.
#[derive(Clone)]
pub struct GccRun {
    /// The volume and transfer function.
    pub prepared: std::sync::Arc<crate::Prepared>,
    /// The rays.
    pub rays: std::sync::Arc<crate::Rays>,
    /// Sampling and lighting.
    pub sampling: Sampling,
    /// How an address is made from voxel indices.
    pub translation: Translation,
}

/// How the naive caster turns a voxel's indices into its address in the
/// bricked volume.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Translation {
    /// Computed, as naive C addresses a bricked array: per axis the index
    /// clamped to the volume, its brick (`i >> 2`) times the brick stride
    /// and its place in the brick (`i & 3`) times the voxel stride, the
    /// three summed (about 17 integer ops and a byte load).
    Arithmetic,
    /// Through Listing 2's offset tables (three loads, two adds and a byte
    /// load): the translation the paper's SSE code amortizes.
    Tables,
}

/// Per-axis strides of the bricked layout, as [`Translation::Arithmetic`]
/// uses them: largest index, brick stride, voxel stride within a brick.
#[derive(Clone, Copy)]
struct Strides {
    hi: [i64; 3],
    brick: [i64; 3],
    within: [u32; 3],
}

impl Strides {
    fn of(dims: [u32; 3]) -> Strides {
        let b = i64::from(BRICK);
        let nb = dims.map(|d| i64::from(d.div_ceil(BRICK)));
        let cube = b * b * b;
        Strides {
            hi: dims.map(|d| i64::from(d.max(1) - 1)),
            brick: [cube, nb[0] * cube, nb[0] * nb[1] * cube],
            within: [0, BRICK.trailing_zeros(), 2 * BRICK.trailing_zeros()],
        }
    }
}

impl Program for GccRun {
    type Out = (Vec<[f32; 4]>, Counters);
    fn run<M: Machine>(&self, m: &mut M) -> Self::Out {
        let pr = &self.prepared;
        let v = crate::layout::lay_out(m, &pr.bricked, pr.volume.dims, &pr.tf);
        self.trace_on(m, &v)
    }
}

/// Three scalars.
type X3<M> = [<M as Machine>::X; 3];

/// Constant-pool slots (4 bytes each): float constants are memory operands.
mod pool {
    pub const ONE: usize = 0;
    pub const ZERO: usize = 1;
    pub const AMBIENT: usize = 2;
    pub const ALPHA_TERM: usize = 3;
    pub const LIGHT_THRESHOLD: usize = 4;
    pub const TINY: usize = 5;
    /// The light's position, three slots.
    pub const LIGHT: usize = 6;
    pub const SLOTS: usize = 9;
}

/// Stack-frame slots (4 bytes each).
mod slot {
    /// The step vector, three slots.
    pub const SDT: usize = 0;
    /// Its growth per sample, three slots.
    pub const SRDA: usize = 3;
    /// The ray's exit distance.
    pub const TEXIT: usize = 6;
    /// The step's growth (a scalar).
    pub const RDA: usize = 7;
    /// The direction, three slots.
    pub const DIR: usize = 8;
    /// The weights `w[axis][k]`, six slots.
    pub const W: usize = 11;
    /// The corners `v[z][y][x]`, eight slots.
    pub const CORNER: usize = 17;
    pub const SLOTS: usize = 25;
}

/// What the compiled loop keeps in memory: its stack frame (spill slots)
/// and its constant pool. Registers hold `p` (3), `t`, the step, the colour
/// (4) and temporaries; everything in [`slot`] and [`pool`] is loaded at
/// each use.
struct Frame {
    stack: Buf,
    pool: Buf,
    translation: Translation,
    strides: Strides,
}

impl Frame {
    fn k<M: Machine>(&self, m: &mut M, k: usize) -> M::X {
        m.x_load(&self.pool, At::off(4 * k))
    }
    fn spill<M: Machine>(&mut self, m: &mut M, k: usize, x: M::X) {
        m.x_store(&mut self.stack, At::off(4 * k), x);
    }
    fn fill<M: Machine>(&self, m: &mut M, k: usize) -> M::X {
        m.x_load(&self.stack, At::off(4 * k))
    }
}

impl GccRun {
    /// Cast every ray over a laid-out volume: RGBA per ray, and the counts.
    pub fn trace_on<M: Machine>(&self, m: &mut M, v: &VolBufs) -> (Vec<[f32; 4]>, Counters) {
        let n = self.rays.len();
        let sp = m.space();
        let rays = sp.alloc_f32(MemKind::Rays, "volume-rays", &self.rays.records(), 64);
        let mut image = sp.alloc(MemKind::Image, "image", 16 * n.max(1), 64);
        let s = &self.sampling;
        let l = s.light.map(|c| c as f32);
        let mut consts = [0f32; pool::SLOTS];
        consts[pool::ONE] = 1.0;
        consts[pool::AMBIENT] = 0.15;
        consts[pool::ALPHA_TERM] = 0.95;
        consts[pool::LIGHT_THRESHOLD] = s.light_threshold as f32;
        consts[pool::TINY] = 1e-20;
        consts[pool::LIGHT..pool::LIGHT + 3].copy_from_slice(&l);
        let mut f = Frame {
            pool: sp.alloc_f32(MemKind::Lut, "gcc-constants", &consts, 64),
            stack: sp.alloc(MemKind::Stack, "gcc-frame", 4 * slot::SLOTS, 64),
            translation: self.translation,
            strides: Strides::of(v.dims),
        };
        let count = Cell::new(Counters::default());
        let hi = v.dims.map(|d| (d.max(1) - 1) as f32);
        let box_hi = m.consts(&[hi[0], hi[1], hi[2], f32::INFINITY]);
        let mut i = m.int(0);
        let end = m.int(n as i64);
        for k in 0..n {
            m.region(Region::Setup);
            let base = m.s_shift(isa::Shift::Shl, i, 5);
            let org = m.load(&rays, At::idx(base, 1, 0));
            let dir = m.load(&rays, At::idx(base, 1, 16));
            let (_, tenter, texit, miss) = crate::clip(m, org, dir, box_hi);
            let rgba = if m.branch(site::BOX, miss) {
                [0.0f32; 4].map(|z| m.float(z))
            } else {
                let o: X3<M> = std::array::from_fn(|a| m.x_load(&rays, At::idx(base, 1, 4 * a)));
                let d: X3<M> =
                    std::array::from_fn(|a| m.x_load(&rays, At::idx(base, 1, 16 + 4 * a)));
                cast(m, v, &mut f, (o, d, tenter, texit), s, &count)
            };
            m.region(Region::Setup);
            for (ch, x) in rgba.into_iter().enumerate() {
                m.x_store(&mut image, At::off(16 * k + 4 * ch), x);
            }
            i = m.s_addi(i, 1);
            m.branch_if(site::PIXELS, Cmp::Lt, i, end);
        }
        let mut counters = count.get();
        counters.rays += n as u64;
        let img = (0..n)
            .map(|k| std::array::from_fn(|ch| image.f32_at(16 * k + 4 * ch)))
            .collect();
        (img, counters)
    }
}

/// The ray's set-up: its first position in registers, the loop-invariant
/// values in the frame.
fn set_up<M: Machine>(
    m: &mut M,
    f: &mut Frame,
    (o, d, tenter, texit): (X3<M>, X3<M>, M::X, M::X),
    s: &Sampling,
) -> X3<M> {
    m.region(Region::Setup);
    let p = std::array::from_fn(|a| m.x_fma(isa::Fma::MAdd, tenter, d[a], o[a]));
    let dt = m.float(s.dt as f32);
    let rda = m.float(s.rda as f32);
    for (a, &da) in d.iter().enumerate() {
        let sdt = m.x_op(BinOp::Mul, da, dt);
        f.spill(m, slot::SDT + a, sdt);
        let srda = m.x_op(BinOp::Mul, da, rda);
        f.spill(m, slot::SRDA + a, srda);
        f.spill(m, slot::DIR + a, da);
    }
    f.spill(m, slot::TEXIT, texit);
    f.spill(m, slot::RDA, rda);
    p
}

/// One ray from its entry to its exit or opacity.
fn cast<M: Machine>(
    m: &mut M,
    v: &VolBufs,
    f: &mut Frame,
    (o, d, tenter, texit): (X3<M>, X3<M>, M::X, M::X),
    s: &Sampling,
    count: &Cell<Counters>,
) -> [M::X; 4] {
    let mut p = set_up(m, f, (o, d, tenter, texit), s);
    let mut t = tenter;
    let mut step = m.float(s.dt as f32);
    let mut rgba = [0.0f32; 4].map(|z| m.float(z));
    let mut flast = m.int(-1);
    loop {
        bump(count, |k| k.samples += 1);
        m.region(Region::VoxelFetch);
        let i: [M::S; 3] = p.map(|x| m.x_to_int(x));
        let val = translate(m, v, f, i);
        let zero = m.int(0);
        m.region(Region::Volume);
        if m.branch_if(site::NAIVE_VAL, Cmp::Ne, val, zero) {
            bump(count, |k| k.classified += 1);
            let (fval, lit) = match s.filter {
                Filter::Nearest => (val, false),
                Filter::Trilinear => {
                    // The stencil's fetch counts as interpolation, as in
                    // the paper's profile (see `crate::dvr::Stencil`).
                    m.region(Region::Interpolation);
                    corners(m, v, f, i);
                    let w = weights(m, f, (p, i));
                    (value(m, f, &w), s.lighting != Lighting::Unlit)
                }
            };
            m.region(Region::Classification);
            let from_first = m.s_cmp(Cmp::Lt, flast, zero);
            let front = m.s_select(from_first, fval, flast);
            let row = m.s_shift(isa::Shift::Shl, front, 8);
            let e = m.s_add(row, fval);
            let off = m.s_shift(isa::Shift::Shl, e, 4);
            let mut sample: [M::X; 4] =
                std::array::from_fn(|ch| m.x_load(&v.pre, At::idx(off, 1, 4 * ch)));
            if lit {
                light(m, f, (&mut sample, p), s.lighting);
            }
            m.region(Region::Blending);
            let one = f.k(m, pool::ONE);
            let keep = m.x_op(BinOp::Sub, one, rgba[3]);
            for ch in 0..4 {
                let w = m.x_op(BinOp::Mul, sample[ch], keep);
                rgba[ch] = m.x_op(BinOp::Add, rgba[ch], w);
            }
            flast = fval;
        }
        m.region(Region::Volume);
        for (a, pa) in p.iter_mut().enumerate() {
            let sdt = f.fill(m, slot::SDT + a);
            *pa = m.x_op(BinOp::Add, *pa, sdt);
        }
        t = m.x_op(BinOp::Add, t, step);
        if s.rda != 0.0 {
            for a in 0..3 {
                let sdt = f.fill(m, slot::SDT + a);
                let srda = f.fill(m, slot::SRDA + a);
                let grown = m.x_op(BinOp::Add, sdt, srda);
                f.spill(m, slot::SDT + a, grown);
            }
            let rda = f.fill(m, slot::RDA);
            step = m.x_op(BinOp::Add, step, rda);
        }
        let alpha_term = f.k(m, pool::ALPHA_TERM);
        let opaque = m.x_cmp(Cmp::Gt, rgba[3], alpha_term);
        let exit = f.fill(m, slot::TEXIT);
        let out = m.x_cmp(Cmp::Gt, t, exit);
        let done = m.s_op(SOp::Or, opaque, out);
        if m.branch(site::NAIVE_TERM, done) {
            break rgba;
        }
    }
}

fn bump(count: &Cell<Counters>, f: impl FnOnce(&mut Counters)) {
    let mut k = count.get();
    f(&mut k);
    count.set(k);
}

/// One address translation: the voxel at indices `i`.
fn translate<M: Machine>(m: &mut M, v: &VolBufs, f: &Frame, i: [M::S; 3]) -> M::S {
    let o: [M::S; 3] = match f.translation {
        Translation::Tables => {
            std::array::from_fn(|a| m.s_load(&v.off[a], At::idx(i[a], 4, 0), 4, false))
        }
        Translation::Arithmetic => std::array::from_fn(|a| {
            let st = f.strides;
            let hi = m.int(st.hi[a]);
            let ic = m.s_op(SOp::Min, i[a], hi);
            let brick = m.s_shift(isa::Shift::Shr, ic, BRICK.trailing_zeros());
            let stride = m.int(st.brick[a]);
            let at_brick = m.s_op(SOp::Mul, brick, stride);
            let mask = m.int(i64::from(BRICK - 1));
            let inner = m.s_and(ic, mask);
            let at_inner = m.s_shift(isa::Shift::Shl, inner, st.within[a]);
            m.s_add(at_brick, at_inner)
        }),
    };
    let xy = m.s_add(o[0], o[1]);
    let a = m.s_add(xy, o[2]);
    m.s_load(&v.voxels, At::idx(a, 1, 0), 1, false)
}

/// The stencil's eight corners, each its own translation from the base
/// indices `i`, converted to float and spilled to the frame.
fn corners<M: Machine>(m: &mut M, v: &VolBufs, f: &mut Frame, i: [M::S; 3]) {
    for z in 0..2 {
        for y in 0..2 {
            for x in 0..2 {
                let at: [M::S; 3] = std::array::from_fn(|a| {
                    if [x, y, z][a] == 0 {
                        i[a]
                    } else {
                        m.s_addi(i[a], 1)
                    }
                });
                let raw = translate(m, v, f, at);
                let c = m.x_from_int(raw);
                f.spill(m, corner(x, y, z), c);
            }
        }
    }
}

/// The frame slot of corner `v[z][y][x]`.
fn corner(x: usize, y: usize, z: usize) -> usize {
    slot::CORNER + 4 * z + 2 * y + x
}

/// The weights `w[axis][0]` = 1 - fraction, `w[axis][1]` = fraction at `p`
/// (base voxel `i`), spilled for the gradient.
fn weights<M: Machine>(m: &mut M, f: &mut Frame, (p, i): (X3<M>, [M::S; 3])) -> [[M::X; 2]; 3] {
    std::array::from_fn(|a| {
        let base = m.x_from_int(i[a]);
        let frac = m.x_op(BinOp::Sub, p[a], base);
        let one = f.k(m, pool::ONE);
        let w = [m.x_op(BinOp::Sub, one, frac), frac];
        f.spill(m, slot::W + 2 * a, w[0]);
        f.spill(m, slot::W + 2 * a + 1, w[1]);
        w
    })
}

/// Eq. 8: the sum over the corners of `x_i y_j z_k v_ijk` (each corner
/// reloaded), truncated.
fn value<M: Machine>(m: &mut M, f: &Frame, w: &[[M::X; 2]; 3]) -> M::S {
    let mut sum = f.k(m, pool::ZERO);
    for z in 0..2 {
        for y in 0..2 {
            for x in 0..2 {
                let xy = m.x_op(BinOp::Mul, w[0][x], w[1][y]);
                let xyz = m.x_op(BinOp::Mul, xy, w[2][z]);
                let c = f.fill(m, corner(x, y, z));
                let t = m.x_op(BinOp::Mul, xyz, c);
                sum = m.x_op(BinOp::Add, sum, t);
            }
        }
    }
    m.x_to_int(sum)
}

/// Eq. 9: the gradient, each partial a bilinear sum of differences, the
/// weights and corners reloaded from the frame.
fn gradient<M: Machine>(m: &mut M, f: &Frame) -> X3<M> {
    std::array::from_fn(|a| {
        // The other two axes, in order.
        let (b, c) = match a {
            0 => (1, 2),
            1 => (0, 2),
            _ => (0, 1),
        };
        let mut g = f.k(m, pool::ZERO);
        for u in 0..2 {
            for w in 0..2 {
                let at = |k: usize| {
                    let mut idx = [0usize; 3];
                    idx[a] = k;
                    idx[b] = u;
                    idx[c] = w;
                    corner(idx[0], idx[1], idx[2])
                };
                let v0 = f.fill(m, at(0));
                let v1 = f.fill(m, at(1));
                let dv = m.x_op(BinOp::Sub, v1, v0);
                let wb = f.fill(m, slot::W + 2 * b + u);
                let wc = f.fill(m, slot::W + 2 * c + w);
                let wt = m.x_op(BinOp::Mul, wb, wc);
                let t = m.x_op(BinOp::Mul, wt, dv);
                g = m.x_op(BinOp::Add, g, t);
            }
        }
        g
    })
}

fn dot3<M: Machine>(m: &mut M, a: X3<M>, b: X3<M>) -> M::X {
    let xy = m.x_op(BinOp::Mul, a[0], b[0]);
    let y = m.x_op(BinOp::Mul, a[1], b[1]);
    let z = m.x_op(BinOp::Mul, a[2], b[2]);
    let s = m.x_op(BinOp::Add, xy, y);
    m.x_op(BinOp::Add, s, z)
}

/// `a / |a|` by `sqrtss` and a division (zero stays zero).
fn normalise<M: Machine>(m: &mut M, f: &Frame, a: X3<M>) -> X3<M> {
    let aa = dot3(m, a, a);
    let tiny = f.k(m, pool::TINY);
    let aa = m.x_op(BinOp::Add, aa, tiny);
    let len = m.x_sqrt(aa);
    a.map(|x| m.x_op(BinOp::Div, x, len))
}

/// Diffuse (and Phong) lighting of a classified sample above the
/// threshold, in place.
fn light<M: Machine>(m: &mut M, f: &Frame, (sample, p): (&mut [M::X; 4], X3<M>), mode: Lighting) {
    m.region(Region::Diffuse);
    let threshold = f.k(m, pool::LIGHT_THRESHOLD);
    let over = m.x_cmp(Cmp::Gt, sample[3], threshold);
    if !m.branch(site::NAIVE_LIT, over) {
        return;
    }
    let g = gradient(m, f);
    let n = normalise(m, f, g);
    let lv: X3<M> = std::array::from_fn(|a| {
        let la = f.k(m, pool::LIGHT + a);
        m.x_op(BinOp::Sub, la, p[a])
    });
    let l = normalise(m, f, lv);
    let ndl = dot3(m, n, l);
    let zero = f.k(m, pool::ZERO);
    let neg = m.x_op(BinOp::Sub, zero, ndl);
    let ndl = m.x_op(BinOp::Max, ndl, neg);
    let ambient = f.k(m, pool::AMBIENT);
    let diffuse = m.x_op(BinOp::Add, ambient, ndl);
    for x in sample.iter_mut().take(3) {
        *x = m.x_op(BinOp::Mul, *x, diffuse);
    }
    if mode == Lighting::Phong {
        m.region(Region::Phong);
        let hv: X3<M> = std::array::from_fn(|a| {
            let da = f.fill(m, slot::DIR + a);
            m.x_op(BinOp::Sub, l[a], da)
        });
        let h = normalise(m, f, hv);
        let mut ph = dot3(m, n, h);
        for _ in 0..4 {
            ph = m.x_op(BinOp::Mul, ph, ph);
        }
        let spec = m.x_op(BinOp::Mul, ph, sample[3]);
        for x in sample.iter_mut().take(3) {
            *x = m.x_op(BinOp::Add, *x, spec);
        }
    }
}
