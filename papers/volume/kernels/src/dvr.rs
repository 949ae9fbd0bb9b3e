//! Listing 2: DVR integration of one ray at a time in AoS SIMD over
//! (x, y, z, t) and (r, g, b, a), on 4 lanes (SSE). Each sample is a
//! sequence of named steps: the base voxel through the offset tables
//! ([`base_voxel`]), the trilinear stencil by swizzles ([`Stencil`]),
//! classification from the preintegrated table, the analytic gradient and
//! lighting ([`light`]), front-to-back blending; then the step along the
//! ray and one test for early termination and exit.
//!
//! Integer lanes reach scalar code through memory, as Listing 2's unions do
//! (`pi.i[0]`, `icx0.i[k] = ...`, `*((int*)&dpfv)`): a vector store and
//! scalar loads, or scalar stores and a vector load (a store-forwarding
//! failure on the paper's cores, which the model prices).
//!
//! Deviations: `_mm_dp_ps` (SSE4.1) is a multiply and a two-step
//! horizontal add (the ISA layer has no dot-product op); the table holds
//! associated colour (Engel et al.), so blending multiplies by `1 - A` only;
//! a zero gradient is guarded (`+ 1e-20` before the reciprocal square root)
//! where Listing 2 would make a NaN.

use crate::layout::{VolBufs, PRE_BYTES};
use crate::site;
use isa::{At, BinOp, Buf, Cmp, IOp, Machine, Region};
use scene::volume_ref::{Filter, Lighting, Sampling};

/// One ray as Listing 2 takes it: origin `{x, y, z, 0}`, direction
/// `{x, y, z, 1}` (normalised in x, y, z), entry and exit distances.
#[derive(Clone, Copy)]
pub struct Ray4<M: Machine> {
    /// Origin.
    pub org: M::F,
    /// Direction, w = 1.
    pub dir: M::F,
    /// Entry distance.
    pub tenter: M::X,
    /// Exit distance.
    pub texit: M::X,
}

/// What the casters count, host side (beside the code they count).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counters {
    /// Rays cast.
    pub rays: u64,
    /// Sample positions visited (Listing 2's loop iterations).
    pub samples: u64,
    /// Samples classified and blended (base voxel non-zero).
    pub classified: u64,
    /// BVH nodes popped.
    pub nodes: u64,
    /// Rays integrated through a leaf.
    pub leaf_rays: u64,
    /// Nodes the packet's frustum test culled.
    pub frustum_culls: u64,
    /// Samples the constant-subvolume routine took (of `samples`).
    pub constant_samples: u64,
}

/// The routine's constants (globals in Listing 2), made once per frame,
/// and the run's counters.
pub struct Consts<M: Machine> {
    /// The run's counters.
    pub count: std::cell::Cell<Counters>,
    one: M::F,
    zero: M::F,
    one_i: M::I,
    m1110: M::F,
    alpha_term: M::F,
    ambient: M::F,
    light: M::F,
    light_threshold: M::F,
    tiny: M::F,
    dt: M::F,
    rda: M::F,
}

impl<M: Machine> Consts<M> {
    /// Add to the counters.
    pub fn bump(&self, f: impl FnOnce(&mut Counters)) {
        let mut c = self.count.get();
        f(&mut c);
        self.count.set(c);
    }

    /// The step growth `rda` in every lane.
    pub fn rda_vec(&self) -> M::F {
        self.rda
    }

    /// A sample's colour lit where the gradient vanishes (a constant
    /// field): Listing 2's diffuse term `0.15 + |n . l|` with n = 0 on its
    /// colour if its opacity is above the lighting threshold.
    pub fn ambient_only(&self, m: &mut M, colour: M::F) -> M::F {
        let over = m.cmp(Cmp::Gt, colour, self.light_threshold);
        let any = m.any(over);
        if !m.branch(site::CONST_LIT, any) {
            return colour;
        }
        let lit = m.mul(colour, self.ambient);
        let last = m.mask(0b1000);
        m.select(last, colour, lit)
    }

    /// The constants for sampling `s`.
    pub fn new(m: &mut M, s: &Sampling) -> Self {
        assert_eq!(M::LANES, 4, "Listing 2 is 4-wide AoS (SSE)");
        let l = s.light.map(|c| c as f32);
        let thr = s.light_threshold as f32;
        Consts {
            count: std::cell::Cell::new(Counters::default()),
            one: m.splat(1.0),
            zero: m.splat(0.0),
            one_i: m.splat_i(1),
            m1110: m.consts(&[1.0, 1.0, 1.0, 0.0]),
            alpha_term: m.consts(&[f32::INFINITY, f32::INFINITY, f32::INFINITY, 0.95]),
            ambient: m.splat(0.15),
            light: m.consts(&[l[0], l[1], l[2], 0.0]),
            light_threshold: m.consts(&[f32::INFINITY, f32::INFINITY, f32::INFINITY, thr]),
            tiny: m.splat(1e-20),
            dt: m.splat(s.dt as f32),
            rda: m.splat(s.rda as f32),
        }
    }
}

/// Scratch bytes the routine spills through (unions of Listing 2).
pub const SCRATCH_BYTES: usize = 64;

/// A ray's integration state between calls (leaf to leaf): its colour,
/// the next sample's position `{x, y, z, t}`, the next step, and the last
/// classified value (-1: none yet).
#[derive(Clone, Copy)]
pub struct State<M: Machine> {
    /// Associated RGBA so far.
    pub rgba: M::F,
    /// The next sample.
    pub p: M::F,
    /// The next step (direction times step length; w: the step).
    pub sdt: M::F,
    /// The last classified value.
    pub flast: M::S,
}

impl<M: Machine> State<M> {
    /// A ray's state at `tenter`, nothing gathered.
    pub fn start(m: &mut M, c: &Consts<M>, (org, dir): (M::F, M::F), tenter: M::X) -> Self {
        let te = m.broadcast(tenter);
        State {
            rgba: c.zero,
            p: m.fmadd(te, dir, org),
            sdt: m.mul(dir, c.dt),
            flast: m.int(-1),
        }
    }
}

/// Integrate `ray` through the volume: its associated RGBA.
pub fn dvr<M: Machine>(
    m: &mut M,
    v: &VolBufs,
    scratch: &mut Buf,
    c: &Consts<M>,
    ray: Ray4<M>,
    s: &Sampling,
) -> M::F {
    m.region(Region::Setup);
    let mut st = State::start(m, c, (ray.org, ray.dir), ray.tenter);
    integrate(m, (v, scratch), c, &mut st, (ray.dir, ray.texit), s);
    st.rgba
}

/// Listing 2's loop from the state's next sample until the ray is opaque
/// or the next sample lies beyond `texit`; the state is left at the next
/// sample.
pub fn integrate<M: Machine>(
    m: &mut M,
    (v, scratch): (&VolBufs, &mut Buf),
    c: &Consts<M>,
    st: &mut State<M>,
    (dir, texit): (M::F, M::X),
    s: &Sampling,
) {
    m.region(Region::Setup);
    let mut pi = m.to_int(st.p);
    let srda = (s.rda != 0.0).then(|| m.mul(dir, c.rda));
    let tx = m.broadcast(texit);
    let last_lane = m.mask(0b1000);
    let inf = m.splat(f32::INFINITY);
    let ray_texit = m.select(last_lane, tx, inf);
    let State {
        mut rgba,
        mut p,
        mut sdt,
        mut flast,
    } = *st;
    loop {
        c.bump(|k| k.samples += 1);
        let (base, val) = base_voxel(m, v, scratch, pi);
        let zero = m.int(0);
        m.region(Region::Volume);
        if m.branch_if(site::VAL, Cmp::Ne, val, zero) {
            c.bump(|k| k.classified += 1);
            let (fval, stn) = match s.filter {
                Filter::Nearest => (val, None),
                Filter::Trilinear => {
                    let stn = Stencil::new(m, v, scratch, (p, pi), (base, val), c);
                    (stn.value(m, scratch), Some(stn))
                }
            };
            m.region(Region::Classification);
            let from_first = m.s_cmp(Cmp::Lt, flast, zero);
            let front = m.s_select(from_first, fval, flast);
            let mut sample = classify(m, v, front, fval);
            if let Some(stn) = stn.filter(|_| s.lighting != Lighting::Unlit) {
                sample = light(m, &stn, (sample, p, dir), c, s.lighting);
            }
            m.region(Region::Blending);
            let a = m.permute(rgba, &[3, 3, 3, 3]);
            let keep = m.sub(c.one, a);
            rgba = m.fmadd(sample, keep, rgba);
            flast = fval;
        }
        m.region(Region::Volume);
        p = m.add(p, sdt);
        pi = m.to_int(p);
        if let Some(r) = srda {
            sdt = m.add(sdt, r);
        }
        let done_a = m.cmp(Cmp::Gt, rgba, c.alpha_term);
        let done_t = m.cmp(Cmp::Gt, p, ray_texit);
        let done = m.kor(done_a, done_t);
        let any = m.any(done);
        if m.branch(site::TERM, any) {
            break;
        }
    }
    *st = State {
        rgba,
        p,
        sdt,
        flast,
    };
}

/// Spill an integer vector and read its x, y, z lanes back as scalars.
fn lanes_xyz<M: Machine>(m: &mut M, scratch: &mut Buf, at: usize, v: M::I) -> [M::S; 3] {
    let f = m.bits_to_f(v);
    m.storeu(scratch, At::off(at), f);
    [0, 1, 2].map(|k| m.s_load(scratch, At::off(at + 4 * k), 4, true))
}

/// The offsets of voxel `pi` along x, y, z and its value.
fn base_voxel<M: Machine>(
    m: &mut M,
    v: &VolBufs,
    scratch: &mut Buf,
    pi: M::I,
) -> ([M::S; 3], M::S) {
    m.region(Region::VoxelFetch);
    let [ix, iy, iz] = lanes_xyz(m, scratch, 0, pi);
    let off = [ix, iy, iz]
        .iter()
        .zip(&v.off)
        .map(|(&i, t)| m.s_load(t, At::idx(i, 4, 0), 4, false))
        .collect::<Vec<_>>();
    let xy = m.s_add(off[0], off[1]);
    let a = m.s_add(xy, off[2]);
    let val = m.s_load(&v.voxels, At::idx(a, 1, 0), 1, false);
    ([off[0], off[1], off[2]], val)
}

/// A sample's trilinear stencil: its fractions and 8 corner values
/// (`cx0`: the x0 corners, `cx1`: the x1 corners, lanes in (y, z) order
/// 00, 01, 10, 11), and the weight vectors the swizzles make.
pub struct Stencil<M: Machine> {
    pc: M::F,
    one_m_pc: M::F,
    cx0: M::F,
    cx1: M::F,
    y0011: M::F,
    z0101: M::F,
}

impl<M: Machine> Stencil<M> {
    fn new(
        m: &mut M,
        v: &VolBufs,
        scratch: &mut Buf,
        (p, pi): (M::F, M::I),
        (base, val): ([M::S; 3], M::S),
        c: &Consts<M>,
    ) -> Self {
        m.region(Region::Interpolation);
        let pi1 = m.iop(IOp::Add, pi, c.one_i);
        let fl = m.to_float(pi);
        let pc = m.sub(p, fl);
        let one_m_pc = m.sub(c.one, pc);
        let ztmp = m.shuffle2(one_m_pc, pc, &[2, 2, 6, 6]);
        let z0101 = m.shuffle2(ztmp, ztmp, &[0, 2, 4, 6]);
        let y0011 = m.shuffle2(one_m_pc, pc, &[1, 1, 5, 5]);
        // The corners (ls. 83-92) count as interpolation, as the paper's
        // profile counts them: its Table 1 gives the same voxel-fetch time
        // per frame with and without trilinear interpolation.
        let [ix1, iy1, iz1] = lanes_xyz(m, scratch, 0, pi1);
        let x1 = m.s_load(&v.off[0], At::idx(ix1, 4, 0), 4, false);
        let y1 = m.s_load(&v.off[1], At::idx(iy1, 4, 0), 4, false);
        let z1 = m.s_load(&v.off[2], At::idx(iz1, 4, 0), 4, false);
        let [x0, y0, z0] = base;
        let mut at = 16;
        for x in [x0, x1] {
            let row = [m.s_add(x, y0), m.s_add(x, y1)];
            for xy in row {
                for z in [z0, z1] {
                    let value = if at == 16 {
                        val
                    } else {
                        let a = m.s_add(xy, z);
                        m.s_load(&v.voxels, At::idx(a, 1, 0), 1, false)
                    };
                    m.s_store(scratch, At::off(at), 4, value);
                    at += 4;
                }
            }
        }
        let load = |m: &mut M, scratch: &Buf, off: usize| {
            let raw = m.loadu(scratch, At::off(off));
            let i = m.bits_to_i(raw);
            m.to_float(i)
        };
        let cx0 = load(m, scratch, 16);
        let cx1 = load(m, scratch, 32);
        m.region(Region::Interpolation);
        Stencil {
            pc,
            one_m_pc,
            cx0,
            cx1,
            y0011,
            z0101,
        }
    }

    /// The interpolated value, truncated to an integer (the table index).
    fn value(&self, m: &mut M, scratch: &mut Buf) -> M::S {
        let x0000 = m.shuffle2(self.one_m_pc, self.one_m_pc, &[0, 0, 4, 4]);
        let x1111 = m.shuffle2(self.pc, self.pc, &[0, 0, 4, 4]);
        let sw_yz = m.mul(self.z0101, self.y0011);
        let a = m.mul(x0000, self.cx0);
        let acc = m.fmadd(x1111, self.cx1, a);
        let d = hsum(m, sw_yz, acc);
        let i = m.to_int(d);
        let f = m.bits_to_f(i);
        m.storeu(scratch, At::off(48), f);
        m.s_load(scratch, At::off(48), 4, true)
    }
}

/// `a . b` in every lane: a multiply and two swizzle-and-add steps.
fn hsum<M: Machine>(m: &mut M, a: M::F, b: M::F) -> M::F {
    let d = m.mul(a, b);
    let s = m.permute(d, &[1, 0, 3, 2]);
    let t = m.add(d, s);
    let u = m.permute(t, &[2, 3, 0, 1]);
    m.add(t, u)
}

/// The preintegrated entry from value `front` to `back`.
fn classify<M: Machine>(m: &mut M, v: &VolBufs, front: M::S, back: M::S) -> M::F {
    let row = m.s_shift(isa::Shift::Shl, front, 8);
    let k = m.s_add(row, back);
    let off = m.s_shift(isa::Shift::Shl, k, PRE_BYTES.trailing_zeros());
    m.load(&v.pre, At::idx(off, 1, 0))
}

/// Diffuse (and Phong) lighting by the analytic gradient (eq. 9) for a
/// sample whose opacity exceeds the threshold.
fn light<M: Machine>(
    m: &mut M,
    st: &Stencil<M>,
    (sample, p, dir): (M::F, M::F, M::F),
    c: &Consts<M>,
    mode: Lighting,
) -> M::F {
    m.region(Region::Diffuse);
    let over = m.cmp(Cmp::Gt, sample, c.light_threshold);
    let any = m.any(over);
    if !m.branch(site::LIT, any) {
        return sample;
    }
    let g = gradient(m, st, p, c);
    // g: (gx, gy, gz, |l|^2); n and l normalised by one rsqrt.
    let n = m.mul(g.0, c.m1110);
    let nn = hsum(m, n, n);
    let both = m.shuffle2(nn, g.0, &[0, 0, 7, 7]);
    let both = m.add(both, c.tiny);
    let rs = m.rsqrt_approx(both);
    let rn = m.permute(rs, &[0, 0, 0, 0]);
    let rl = m.permute(rs, &[3, 3, 3, 3]);
    let n = m.mul(n, rn);
    let l = m.mul(g.1, rl);
    let ndl = hsum(m, n, l);
    let ndl = m.abs(ndl);
    let diffuse = m.add(c.ambient, ndl);
    let lit = m.mul(sample, diffuse);
    let last = m.mask(0b1000);
    let mut out = m.select(last, sample, lit);
    if mode == Lighting::Phong {
        m.region(Region::Phong);
        let h = m.sub(l, dir);
        let h = m.mul(h, c.m1110);
        let hh = hsum(m, h, h);
        let hh = m.add(hh, c.tiny);
        let rh = m.rsqrt_approx(hh);
        let h = m.mul(h, rh);
        let mut ph = hsum(m, n, h);
        for _ in 0..4 {
            ph = m.mul(ph, ph);
        }
        let a = m.permute(sample, &[3, 3, 3, 3]);
        let spec = m.mul(ph, a);
        out = m.fmadd(spec, c.m1110, out);
    }
    out
}

/// The gradient's three bilinear interpolants summed by a 4x4 transpose
/// alongside `l . l`: `(gx, gy, gz, |l|^2)`, and the light vector `l`.
fn gradient<M: Machine>(m: &mut M, st: &Stencil<M>, p: M::F, c: &Consts<M>) -> (M::F, M::F) {
    let (cx0, cx1) = (st.cx0, st.cx1);
    let dx = m.sub(cx1, cx0);
    let hi = m.shuffle2(cx0, cx1, &[2, 3, 6, 7]);
    let lo = m.shuffle2(cx0, cx1, &[0, 1, 4, 5]);
    let dy = m.sub(hi, lo);
    let odd = m.shuffle2(cx0, cx1, &[1, 3, 5, 7]);
    let even = m.shuffle2(cx0, cx1, &[0, 2, 4, 6]);
    let dz = m.sub(odd, even);
    let yz = m.mul(st.y0011, st.z0101);
    let dx = m.mul(yz, dx);
    let x0011 = m.shuffle2(st.one_m_pc, st.pc, &[0, 0, 4, 4]);
    let xz = m.mul(x0011, st.z0101);
    let dy = m.mul(xz, dy);
    let y0101 = m.shuffle2(st.y0011, st.y0011, &[0, 2, 4, 6]);
    let xy = m.mul(x0011, y0101);
    let dz = m.mul(xy, dz);
    let lv = m.sub(c.light, p);
    let l = m.mul(lv, c.m1110);
    let ml = m.mul(l, l);
    let t0 = m.shuffle2(dx, dy, &[0, 1, 4, 5]);
    let t1 = m.shuffle2(dx, dy, &[2, 3, 6, 7]);
    let t2 = m.shuffle2(dz, ml, &[0, 1, 4, 5]);
    let t3 = m.shuffle2(dz, ml, &[2, 3, 6, 7]);
    let s01 = m.add(t0, t1);
    let s23 = m.add(t2, t3);
    let e = m.shuffle2(s01, s23, &[0, 2, 4, 6]);
    let o = m.shuffle2(s01, s23, &[1, 3, 5, 7]);
    (m.bin(BinOp::Add, e, o), l)
}
