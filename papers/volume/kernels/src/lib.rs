//! # volume-kernels
//!
//! The simulated code of Knoll et al. 2011, "Full-Resolution Interactive
//! CPU Volume Rendering with Coherent BVH Traversal": DVR integration as
//! Listing 2 ([`dvr`]) over the bricked volume and preintegrated table in
//! simulated memory ([`layout`]), and the ray caster that runs it per pixel
//! without an acceleration structure (the paper's "sse" method, [`Run`]);
//! the naive scalar baseline ("gcc", [`naive`]) and the coherent BVH
//! traversal ("bvh", [`bvh`]).
//! Written against `isa::Machine` on 4 lanes (SSE), traced or native.

#![warn(missing_docs)]

pub mod bvh;
pub mod constant;
pub mod dvr;
pub mod layout;
pub mod naive;

use isa::{At, Buf, Cmp, Machine, MemKind, Program, Region};
use layout::VolBufs;
use scene::transfer::Transfer;
use scene::volume::Volume;
use scene::volume_bvh::Bricked;
use scene::volume_ref::Sampling;
use std::sync::Arc;

/// Branch sites.
pub mod site {
    use isa::Site;
    /// Base voxel non-zero (sample it)?
    pub const VAL: Site = isa::sites::VOLUME.at(0);
    /// Opaque enough or past the exit (stop)?
    pub const TERM: Site = isa::sites::VOLUME.at(1);
    /// Opacity above the lighting threshold (light it)?
    pub const LIT: Site = isa::sites::VOLUME.at(2);
    /// More pixels?
    pub const PIXELS: Site = isa::sites::VOLUME.at(3);
    /// The ray meets the volume's box?
    pub const BOX: Site = isa::sites::VOLUME.at(4);
    /// BVH: stack empty?
    pub const STACK: Site = isa::sites::VOLUME.at(5);
    /// BVH: node empty for the transfer function (eq. 5)?
    pub const EMPTY: Site = isa::sites::VOLUME.at(6);
    /// BVH: node pruned to a leaf (eq. 6)?
    pub const PRUNE: Site = isa::sites::VOLUME.at(7);
    /// BVH: a leaf?
    pub const LEAF: Site = isa::sites::VOLUME.at(8);
    /// BVH: the packlet hits the box?
    pub const PACKLET_HIT: Site = isa::sites::VOLUME.at(9);
    /// BVH: more packlets?
    pub const PACKLET: Site = isa::sites::VOLUME.at(10);
    /// BVH: the first active ray's direction negative on the split axis?
    pub const ORDER: Site = isa::sites::VOLUME.at(11);
    /// BVH leaf: another ray of the packlet?
    pub const LEAF_RAY: Site = isa::sites::VOLUME.at(12);
    /// BVH leaf: the ray opaque or its next sample beyond the leaf?
    pub const SKIP: Site = isa::sites::VOLUME.at(13);
    /// BVH leaf: the next sample before the leaf's entry?
    pub const SKIP_AHEAD: Site = isa::sites::VOLUME.at(14);
    /// BVH leaf: another differential step to the entry?
    pub const SKIP_STEP: Site = isa::sites::VOLUME.at(15);
    /// More packets?
    pub const PACKETS: Site = isa::sites::VOLUME.at(16);
    /// Naive caster: base voxel non-zero?
    pub const NAIVE_VAL: Site = isa::sites::VOLUME.at(17);
    /// Naive caster: opaque or past the exit?
    pub const NAIVE_TERM: Site = isa::sites::VOLUME.at(18);
    /// Naive caster: opacity above the lighting threshold?
    pub const NAIVE_LIT: Site = isa::sites::VOLUME.at(19);
    /// BVH: node not constant for eq. 7?
    pub const CONSTANT: Site = isa::sites::VOLUME.at(20);
    /// Constant subvolume: a ray still before the box?
    pub const CONST_SKIP: Site = isa::sites::VOLUME.at(21);
    /// Constant subvolume: a ray still inside and not opaque?
    pub const CONST_STEP: Site = isa::sites::VOLUME.at(22);
    /// Constant subvolume: another ray to write back?
    pub const CONST_RAY: Site = isa::sites::VOLUME.at(23);
    /// Constant subvolume: the colour opaque enough to light?
    pub const CONST_LIT: Site = isa::sites::VOLUME.at(24);
    /// BVH: the packet's frustum misses the box (interval arithmetic)?
    pub const FRUSTUM: Site = isa::sites::VOLUME.at(25);
    /// BVH leaf: the ray's next sample past the leaf after the skip?
    pub const SKIP_PAST: Site = isa::sites::VOLUME.at(26);

    /// Every site of the crate (checked for duplicates by the layout test).
    pub const ALL: [Site; 27] = [
        VAL,
        TERM,
        LIT,
        PIXELS,
        BOX,
        STACK,
        EMPTY,
        PRUNE,
        LEAF,
        PACKLET_HIT,
        PACKLET,
        ORDER,
        LEAF_RAY,
        SKIP,
        SKIP_AHEAD,
        SKIP_STEP,
        PACKETS,
        NAIVE_VAL,
        NAIVE_TERM,
        NAIVE_LIT,
        CONSTANT,
        CONST_SKIP,
        CONST_STEP,
        CONST_RAY,
        CONST_LIT,
        FRUSTUM,
        SKIP_PAST,
    ];
}

/// A volume made ready: its bricks and transfer function.
pub struct Prepared {
    /// The volume.
    pub volume: Volume,
    /// Its bricked layout.
    pub bricked: Bricked,
    /// The transfer function.
    pub tf: Transfer,
}

impl Prepared {
    /// Brick `volume` for `tf`.
    #[must_use]
    pub fn new(volume: Volume, tf: Transfer) -> Prepared {
        Prepared {
            bricked: Bricked::new(&volume),
            volume,
            tf,
        }
    }
}

/// Rays in voxel coordinates: per ray origin `{x, y, z, 0}` and normalised
/// direction `{x, y, z, 1}` (32 bytes).
#[derive(Clone, Debug, PartialEq)]
pub struct Rays {
    /// Origins.
    pub org: Vec<[f32; 3]>,
    /// Directions (normalised).
    pub dir: Vec<[f32; 3]>,
}

impl Rays {
    /// A pinhole camera's `w` x `h` pixel-centre rays at `eye`, looking at
    /// the volume's centre, vertical field of view `fov` degrees, row by row.
    #[must_use]
    pub fn camera(dims: [u32; 3], eye: [f64; 3], fov: f64, (w, h): (u32, u32)) -> Rays {
        let pixels: Vec<(u32, u32)> = (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).collect();
        Rays::pixels(dims, eye, fov, (w, h), &pixels)
    }

    /// The same camera's rays of 8x8-pixel packet (`px`, `py`) in packet
    /// order: 16 packlets of 2x2 pixels (lanes in row order), packlets row
    /// by row.
    #[must_use]
    pub fn packet(
        dims: [u32; 3],
        eye: [f64; 3],
        fov: f64,
        wh: (u32, u32),
        (px, py): (u32, u32),
    ) -> Rays {
        let pixels: Vec<(u32, u32)> = (0..64u32)
            .map(|k| {
                let (p, l) = (k / 4, k % 4);
                (px * 8 + (p % 4) * 2 + l % 2, py * 8 + (p / 4) * 2 + l / 2)
            })
            .collect();
        Rays::pixels(dims, eye, fov, wh, &pixels)
    }

    fn pixels(
        dims: [u32; 3],
        eye: [f64; 3],
        fov: f64,
        (w, h): (u32, u32),
        px: &[(u32, u32)],
    ) -> Rays {
        let centre = dims.map(|d| f64::from(d.max(1) - 1) / 2.0);
        let cam = scene::scene::Camera {
            eye: eye.map(|c| c as f32),
            target: centre.map(|c| c as f32),
            up: [0.0, 0.0, 1.0],
            fov: fov as f32,
            width: w,
            height: h,
        };
        let (mut org, mut dir) = (Vec::new(), Vec::new());
        for &(x, y) in px {
            let (o, d) = cam.ray(f64::from(x) + 0.5, f64::from(y) + 0.5);
            let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            org.push(o.map(|c| c as f32));
            dir.push(d.map(|c| (c / l) as f32));
        }
        Rays { org, dir }
    }
    /// Rays.
    #[must_use]
    pub fn len(&self) -> usize {
        self.org.len()
    }
    /// Whether there are none.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.org.is_empty()
    }
    fn records(&self) -> Vec<f32> {
        (0..self.len())
            .flat_map(|i| {
                let (o, d) = (self.org[i], self.dir[i]);
                [o[0], o[1], o[2], 0.0, d[0], d[1], d[2], 1.0]
            })
            .collect()
    }
}

/// The "sse" method over a set of rays: each ray clipped to the volume's
/// box, then integrated by Listing 2; the image is RGBA per ray.
#[derive(Clone)]
pub struct Run {
    /// The volume and transfer function.
    pub prepared: Arc<Prepared>,
    /// The rays.
    pub rays: Arc<Rays>,
    /// Sampling and lighting.
    pub sampling: Sampling,
}

impl Program for Run {
    type Out = (Vec<[f32; 4]>, dvr::Counters);
    fn run<M: Machine>(&self, m: &mut M) -> Self::Out {
        let pr = &self.prepared;
        let v = layout::lay_out(m, &pr.bricked, pr.volume.dims, &pr.tf);
        self.trace_on(m, &v)
    }
}

impl Run {
    /// Cast every ray over a laid-out volume: RGBA per ray, and the counts.
    pub fn trace_on<M: Machine>(&self, m: &mut M, v: &VolBufs) -> (Vec<[f32; 4]>, dvr::Counters) {
        let n = self.rays.len();
        let sp = m.space();
        let rays = sp.alloc_f32(MemKind::Rays, "volume-rays", &self.rays.records(), 64);
        let mut image = sp.alloc(MemKind::Image, "image", 16 * n.max(1), 64);
        let mut scratch = sp.alloc(MemKind::Stack, "dvr-scratch", dvr::SCRATCH_BYTES, 64);
        let c = dvr::Consts::new(m, &self.sampling);
        let hi = v.dims.map(|d| (d.max(1) - 1) as f32);
        let box_hi = m.consts(&[hi[0], hi[1], hi[2], f32::INFINITY]);
        let mut i = m.int(0);
        let end = m.int(n as i64);
        if n > 0 {
            loop {
                pixel(
                    m,
                    v,
                    (&rays, &mut image, &mut scratch),
                    (&c, box_hi),
                    i,
                    &self.sampling,
                );
                i = m.s_addi(i, 1);
                if !m.branch_if(site::PIXELS, Cmp::Lt, i, end) {
                    break;
                }
            }
        }
        c.bump(|k| k.rays += n as u64);
        let img = (0..n)
            .map(|k| std::array::from_fn(|ch| image.f32_at(16 * k + 4 * ch)))
            .collect();
        (img, c.count.get())
    }
}

/// One pixel: load its ray, clip it to the box `[0, hi]` (slabs, 4-wide;
/// the w lane keeps t >= 0), integrate, store its colour.
fn pixel<M: Machine>(
    m: &mut M,
    v: &VolBufs,
    (rays, image, scratch): (&Buf, &mut Buf, &mut Buf),
    (c, box_hi): (&dvr::Consts<M>, M::F),
    i: M::S,
    s: &Sampling,
) {
    m.region(Region::Setup);
    let base = m.s_shift(isa::Shift::Shl, i, 5);
    let org = m.load(rays, At::idx(base, 1, 0));
    let dir = m.load(rays, At::idx(base, 1, 16));
    let (zero, tenter, texit, miss) = clip(m, org, dir, box_hi);
    let out = if m.branch(site::BOX, miss) {
        zero
    } else {
        let ray = dvr::Ray4 {
            org,
            dir,
            tenter,
            texit,
        };
        dvr::dvr(m, v, scratch, c, ray, s)
    };
    m.region(Region::Setup);
    let off = m.s_shift(isa::Shift::Shl, i, 4);
    m.store(image, At::idx(off, 1, 0), out);
}

/// The "bvh" method: the image's 8x8-ray packets (2x2-ray packlets) traced
/// through the implicit min-max BVH, each ray integrated leaf by leaf.
#[derive(Clone)]
pub struct BvhRun {
    /// The volume and transfer function.
    pub prepared: Arc<Prepared>,
    /// Its min-max BVH.
    pub tree: Arc<scene::volume_bvh::MinMaxBvh>,
    /// The rays in packet order ([`Rays::packet`]): 64 per packet.
    pub rays: Arc<Rays>,
    /// Sampling and lighting.
    pub sampling: Sampling,
    /// Eqs. 5 and 6's thresholds.
    pub heuristics: bvh::Heuristics,
}

impl Program for BvhRun {
    type Out = (Vec<[f32; 4]>, dvr::Counters);
    fn run<M: Machine>(&self, m: &mut M) -> Self::Out {
        let pr = &self.prepared;
        let v = layout::lay_out(m, &pr.bricked, pr.volume.dims, &pr.tf);
        let nodes = bvh::lay_out_nodes(m, &self.tree);
        self.trace_on(m, &v, &nodes)
    }
}

impl BvhRun {
    /// Trace every packet over a laid-out volume and BVH: RGBA per ray, and
    /// the counts.
    ///
    /// # Panics
    /// If the rays are not whole packets.
    pub fn trace_on<M: Machine>(
        &self,
        m: &mut M,
        v: &VolBufs,
        nodes: &Buf,
    ) -> (Vec<[f32; 4]>, dvr::Counters) {
        let n = self.rays.len();
        assert!(n.is_multiple_of(64), "whole packets of 64 rays");
        let sp = m.space();
        let rays = sp.alloc_f32(MemKind::Rays, "volume-rays", &self.rays.records(), 64);
        let mut image = sp.alloc(MemKind::Image, "image", 16 * n.max(1), 64);
        let mut scratch = sp.alloc(MemKind::Stack, "dvr-scratch", dvr::SCRATCH_BYTES, 64);
        let mut states = sp.alloc(MemKind::Rays, "ray-states", 64 * 64, 64);
        let mut stack = sp.alloc(MemKind::Stack, "bvh-stack", 8 * 128, 64);
        let c = dvr::Consts::new(m, &self.sampling);
        let hi = v.dims.map(|d| (d.max(1) - 1) as f32);
        let box_hi = m.consts(&[hi[0], hi[1], hi[2], f32::INFINITY]);
        let dims = v.dims.map(|d| f64::from(d.max(1) - 1));
        let vol_diag = (dims[0] * dims[0] + dims[1] * dims[1] + dims[2] * dims[2]).sqrt() as f32;
        let mut p = m.int(0);
        let end = m.int((n / 64) as i64);
        for packet in 0..n / 64 {
            {
                let ids: Vec<usize> = (64 * packet..64 * packet + 64).collect();
                let org: Vec<[f32; 3]> = ids.iter().map(|&i| self.rays.org[i]).collect();
                let dir: Vec<[f32; 3]> = ids.iter().map(|&i| self.rays.dir[i]).collect();
                let recs = bvh::packlet_records(&org, &dir);
                let packlets = m.space().alloc_f32(MemKind::Rays, "packlets", &recs, 64);
                for (k, &i) in ids.iter().enumerate() {
                    start_ray(m, (&rays, &mut states), (i, k), (&c, box_hi));
                }
                let pb = bvh::PacketBufs {
                    packlets: &packlets,
                    states: &mut states,
                    stack: &mut stack,
                    scratch: &mut scratch,
                };
                let hv = (self.heuristics, vol_diag);
                bvh::trace_packet(m, v, nodes, pb, &c, hv, &self.sampling);
                m.region(Region::Setup);
                for (k, &i) in ids.iter().enumerate() {
                    let rgba = m.load(&states, At::off(64 * k));
                    m.store(&mut image, At::off(16 * i), rgba);
                }
                p = m.s_addi(p, 1);
                m.branch_if(site::PACKETS, Cmp::Lt, p, end);
            }
        }
        c.bump(|k| k.rays += n as u64);
        let img = (0..n)
            .map(|k| std::array::from_fn(|ch| image.f32_at(16 * k + 4 * ch)))
            .collect();
        (img, c.count.get())
    }
}

/// Set ray `i` (packet slot `k`) up: clipped to the volume's box, its state
/// at the entry (a ray that misses gets its next sample at +inf: every leaf
/// skips it).
fn start_ray<M: Machine>(
    m: &mut M,
    (rays, states): (&Buf, &mut Buf),
    (i, k): (usize, usize),
    (c, box_hi): (&dvr::Consts<M>, M::F),
) {
    m.region(Region::Setup);
    let org = m.load(rays, At::off(32 * i));
    let dir = m.load(rays, At::off(32 * i + 16));
    let (zero, tenter, _, miss) = clip(m, org, dir, box_hi);
    let st = if m.branch(site::BOX, miss) {
        let inf = m.splat(f32::INFINITY);
        dvr::State {
            rgba: zero,
            p: inf,
            sdt: zero,
            flast: m.int(-1),
        }
    } else {
        dvr::State::start(m, c, (org, dir), tenter)
    };
    m.store(states, At::off(64 * k), st.rgba);
    m.store(states, At::off(64 * k + 16), st.p);
    m.store(states, At::off(64 * k + 32), st.sdt);
    m.s_store(states, At::off(64 * k + 48), 4, st.flast);
}

/// Clip a ray to the volume's box `[0, box_hi]` by slabs, 4-wide (the w
/// lane keeps t >= 0): a zero vector, the entry and exit distances, and
/// whether it misses.
fn clip<M: Machine>(m: &mut M, org: M::F, dir: M::F, box_hi: M::F) -> (M::F, M::X, M::X, M::S) {
    let one = m.splat(1.0);
    let idir = m.div(one, dir);
    let zero = m.splat(0.0);
    let lo = m.sub(zero, org);
    let t0 = m.mul(lo, idir);
    let hi = m.sub(box_hi, org);
    let t1 = m.mul(hi, idir);
    let near = m.min(t0, t1);
    let far = m.max(t0, t1);
    let tenter = m.reduce(isa::BinOp::Max, near);
    let texit = m.reduce(isa::BinOp::Min, far);
    let miss = m.x_cmp(Cmp::Gt, tenter, texit);
    (zero, tenter, texit, miss)
}
