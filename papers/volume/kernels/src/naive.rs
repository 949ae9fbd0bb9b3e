//! The paper's "gcc" baseline: a naive floating-point ray caster as a
//! compiler makes it from plain C, one scalar at a time. Same bricked
//! volume, offset tables, preintegrated table and sample sequence as
//! Listing 2 ([`crate::dvr`]), but every corner of the stencil is its own
//! address translation (`vdata[voff_x[i] + voff_y[j] + voff_z[k]]`, the
//! offsets of each axis loaded once, as a compiler's common-subexpression
//! pass leaves them), the trilinear interpolant is the eight-term sum of
//! eq. 8 in scalar floats, the gradient is eq. 9 term by term, vectors are
//! normalised by `sqrtss` and a division, and the colour is four scalars.
//!
//! Written as straight-line scalar code: a compiler does not vectorise a
//! loop whose trip count depends on the data and whose body gathers through
//! tables (the paper calls it "compiler-vectorized", its Table 1 profile
//! is that of scalar code: voxel fetching dominates).

use crate::dvr::Counters;
use crate::layout::VolBufs;
use crate::site;
use isa::{At, BinOp, Cmp, Machine, MemKind, Program, Region, SOp};
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

/// Per-frame constants.
struct Consts<M: Machine> {
    one: M::X,
    zero: M::X,
    ambient: M::X,
    alpha_term: M::X,
    light_threshold: M::X,
    tiny: M::X,
    light: X3<M>,
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
        let c = Consts {
            one: m.float(1.0),
            zero: m.float(0.0),
            ambient: m.float(0.15),
            alpha_term: m.float(0.95),
            light_threshold: m.float(s.light_threshold as f32),
            tiny: m.float(1e-20),
            light: l.map(|x| m.float(x)),
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
                cast(m, v, &c, (o, d, tenter, texit), s, &count)
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

/// One ray from its entry to its exit or opacity.
fn cast<M: Machine>(
    m: &mut M,
    v: &VolBufs,
    c: &Consts<M>,
    (o, d, tenter, texit): (X3<M>, X3<M>, M::X, M::X),
    s: &Sampling,
    count: &Cell<Counters>,
) -> [M::X; 4] {
    m.region(Region::Volume);
    let mut p: X3<M> = std::array::from_fn(|a| m.x_fma(isa::Fma::MAdd, tenter, d[a], o[a]));
    let mut t = tenter;
    let dt = m.float(s.dt as f32);
    let rda = m.float(s.rda as f32);
    let mut sdt: X3<M> = d.map(|x| m.x_op(BinOp::Mul, x, dt));
    let mut step = dt;
    let srda: X3<M> = d.map(|x| m.x_op(BinOp::Mul, x, rda));
    let mut rgba = [0.0f32; 4].map(|z| m.float(z));
    let mut flast = m.int(-1);
    loop {
        bump(count, |k| k.samples += 1);
        m.region(Region::VoxelFetch);
        let i: [M::S; 3] = p.map(|x| m.x_to_int(x));
        let off0: [M::S; 3] =
            std::array::from_fn(|a| m.s_load(&v.off[a], At::idx(i[a], 4, 0), 4, false));
        let val = fetch(m, v, off0);
        let zero = m.int(0);
        m.region(Region::Volume);
        if m.branch_if(site::NAIVE_VAL, Cmp::Ne, val, zero) {
            bump(count, |k| k.classified += 1);
            let (fval, corners) = match s.filter {
                Filter::Nearest => (val, None),
                Filter::Trilinear => {
                    let cs = Corners::fetch(m, v, (p, i), off0, (val, c.one));
                    (cs.value(m), Some(cs))
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
            if let Some(cs) = corners.filter(|_| s.lighting != Lighting::Unlit) {
                light(m, c, &cs, (&mut sample, p, d), s.lighting);
            }
            m.region(Region::Blending);
            let keep = m.x_op(BinOp::Sub, c.one, rgba[3]);
            for ch in 0..4 {
                let w = m.x_op(BinOp::Mul, sample[ch], keep);
                rgba[ch] = m.x_op(BinOp::Add, rgba[ch], w);
            }
            flast = fval;
        }
        m.region(Region::Volume);
        for a in 0..3 {
            p[a] = m.x_op(BinOp::Add, p[a], sdt[a]);
        }
        t = m.x_op(BinOp::Add, t, step);
        if s.rda != 0.0 {
            for a in 0..3 {
                sdt[a] = m.x_op(BinOp::Add, sdt[a], srda[a]);
            }
            step = m.x_op(BinOp::Add, step, rda);
        }
        let opaque = m.x_cmp(Cmp::Gt, rgba[3], c.alpha_term);
        let out = m.x_cmp(Cmp::Gt, t, texit);
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

/// The voxel at the offsets `(ox, oy, oz)`: two adds and a byte load.
fn fetch<M: Machine>(m: &mut M, v: &VolBufs, [ox, oy, oz]: [M::S; 3]) -> M::S {
    let xy = m.s_add(ox, oy);
    let a = m.s_add(xy, oz);
    m.s_load(&v.voxels, At::idx(a, 1, 0), 1, false)
}

/// A sample's eight corner values (`v[z][y][x]`, floats) and weights
/// (`w[axis][0]` = 1 - fraction, `w[axis][1]` = fraction).
struct Corners<M: Machine> {
    v: [[[M::X; 2]; 2]; 2],
    w: [[M::X; 2]; 3],
}

impl<M: Machine> Corners<M> {
    /// Fetch the stencil at `p` (base voxel `i`, its offsets `off0`, its
    /// value `val`).
    fn fetch(
        m: &mut M,
        v: &VolBufs,
        (p, i): (X3<M>, [M::S; 3]),
        off0: [M::S; 3],
        (val, one): (M::S, M::X),
    ) -> Self {
        let off1: [M::S; 3] = std::array::from_fn(|a| {
            let i1 = m.s_addi(i[a], 1);
            m.s_load(&v.off[a], At::idx(i1, 4, 0), 4, false)
        });
        let pick = |k: usize, a: usize| if k == 0 { off0[a] } else { off1[a] };
        let mut raw = [[[val; 2]; 2]; 2];
        for (z, plane) in raw.iter_mut().enumerate() {
            for (y, row) in plane.iter_mut().enumerate() {
                for (x, cell) in row.iter_mut().enumerate() {
                    if (x, y, z) != (0, 0, 0) {
                        *cell = fetch(m, v, [pick(x, 0), pick(y, 1), pick(z, 2)]);
                    }
                }
            }
        }
        m.region(Region::Interpolation);
        let vals = raw.map(|plane| plane.map(|row| row.map(|x| m.x_from_int(x))));
        let w = std::array::from_fn(|a| {
            let base = m.x_from_int(i[a]);
            let f = m.x_op(BinOp::Sub, p[a], base);
            [m.x_op(BinOp::Sub, one, f), f]
        });
        Corners { v: vals, w }
    }

    /// Eq. 8: the sum over the corners of `x_i y_j z_k v_ijk`, truncated.
    fn value(&self, m: &mut M) -> M::S {
        let mut sum = m.float(0.0);
        for z in 0..2 {
            for y in 0..2 {
                for x in 0..2 {
                    let xy = m.x_op(BinOp::Mul, self.w[0][x], self.w[1][y]);
                    let xyz = m.x_op(BinOp::Mul, xy, self.w[2][z]);
                    let t = m.x_op(BinOp::Mul, xyz, self.v[z][y][x]);
                    sum = m.x_op(BinOp::Add, sum, t);
                }
            }
        }
        m.x_to_int(sum)
    }

    /// Eq. 9: the gradient, each partial a bilinear sum of differences.
    fn gradient(&self, m: &mut M) -> X3<M> {
        let corner = |a: usize, k: usize, u: usize, w: usize| {
            // Axis `a` at `k`, the other two axes at `u`, `w` (in order).
            let mut idx = [0usize; 3];
            let others: Vec<usize> = (0..3).filter(|&b| b != a).collect();
            idx[a] = k;
            idx[others[0]] = u;
            idx[others[1]] = w;
            (idx, others)
        };
        std::array::from_fn(|a| {
            let mut g = m.float(0.0);
            for u in 0..2 {
                for w in 0..2 {
                    let (i0, others) = corner(a, 0, u, w);
                    let (i1, _) = corner(a, 1, u, w);
                    let v0 = self.v[i0[2]][i0[1]][i0[0]];
                    let v1 = self.v[i1[2]][i1[1]][i1[0]];
                    let dv = m.x_op(BinOp::Sub, v1, v0);
                    let wt = m.x_op(BinOp::Mul, self.w[others[0]][u], self.w[others[1]][w]);
                    let t = m.x_op(BinOp::Mul, wt, dv);
                    g = m.x_op(BinOp::Add, g, t);
                }
            }
            g
        })
    }
}

fn dot3<M: Machine>(m: &mut M, a: X3<M>, b: X3<M>) -> M::X {
    let xy = m.x_op(BinOp::Mul, a[0], b[0]);
    let y = m.x_op(BinOp::Mul, a[1], b[1]);
    let z = m.x_op(BinOp::Mul, a[2], b[2]);
    let s = m.x_op(BinOp::Add, xy, y);
    m.x_op(BinOp::Add, s, z)
}

/// `a / |a|` by `sqrtss` and a division (zero stays zero).
fn normalise<M: Machine>(m: &mut M, c: &Consts<M>, a: X3<M>) -> X3<M> {
    let aa = dot3(m, a, a);
    let aa = m.x_op(BinOp::Add, aa, c.tiny);
    let len = m.x_sqrt(aa);
    a.map(|x| m.x_op(BinOp::Div, x, len))
}

/// Diffuse (and Phong) lighting of a classified sample above the
/// threshold, in place.
fn light<M: Machine>(
    m: &mut M,
    c: &Consts<M>,
    cs: &Corners<M>,
    (sample, p, d): (&mut [M::X; 4], X3<M>, X3<M>),
    mode: Lighting,
) {
    m.region(Region::Diffuse);
    let over = m.x_cmp(Cmp::Gt, sample[3], c.light_threshold);
    if !m.branch(site::NAIVE_LIT, over) {
        return;
    }
    let g = cs.gradient(m);
    let n = normalise(m, c, g);
    let lv: X3<M> = std::array::from_fn(|a| m.x_op(BinOp::Sub, c.light[a], p[a]));
    let l = normalise(m, c, lv);
    let ndl = dot3(m, n, l);
    let neg = m.x_op(BinOp::Sub, c.zero, ndl);
    let ndl = m.x_op(BinOp::Max, ndl, neg);
    let diffuse = m.x_op(BinOp::Add, c.ambient, ndl);
    for x in sample.iter_mut().take(3) {
        *x = m.x_op(BinOp::Mul, *x, diffuse);
    }
    if mode == Lighting::Phong {
        m.region(Region::Phong);
        let hv: X3<M> = std::array::from_fn(|a| m.x_op(BinOp::Sub, l[a], d[a]));
        let h = normalise(m, c, hv);
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
