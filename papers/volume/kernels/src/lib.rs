//! # volume-kernels
//!
//! The simulated code of Knoll et al. 2011, "Full-Resolution Interactive
//! CPU Volume Rendering with Coherent BVH Traversal": DVR integration as
//! Listing 2 ([`dvr`]) over the bricked volume and preintegrated table in
//! simulated memory ([`layout`]), and the ray caster that runs it per pixel
//! without an acceleration structure (the paper's "sse" method, [`Run`]).
//! Written against `isa::Machine` on 4 lanes (SSE), traced or native.

#![warn(missing_docs)]

pub mod dvr;
pub mod layout;

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

    /// Every site of the crate (checked for duplicates by the layout test).
    pub const ALL: [Site; 5] = [VAL, TERM, LIT, PIXELS, BOX];
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
    /// the volume's centre, vertical field of view `fov` degrees.
    #[must_use]
    pub fn camera(dims: [u32; 3], eye: [f64; 3], fov: f64, (w, h): (u32, u32)) -> Rays {
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
        for y in 0..h {
            for x in 0..w {
                let (o, d) = cam.ray(f64::from(x) + 0.5, f64::from(y) + 0.5);
                let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                org.push(o.map(|c| c as f32));
                dir.push(d.map(|c| (c / l) as f32));
            }
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
    type Out = Vec<[f32; 4]>;
    fn run<M: Machine>(&self, m: &mut M) -> Self::Out {
        let pr = &self.prepared;
        let v = layout::lay_out(m, &pr.bricked, pr.volume.dims, &pr.tf);
        self.trace_on(m, &v)
    }
}

impl Run {
    /// Cast every ray over a laid-out volume: RGBA per ray.
    pub fn trace_on<M: Machine>(&self, m: &mut M, v: &VolBufs) -> Vec<[f32; 4]> {
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
        (0..n)
            .map(|k| std::array::from_fn(|c| image.f32_at(16 * k + 4 * c)))
            .collect()
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
