//! Ray workloads, seeded and deterministic: the same rays whatever kernel
//! traces them. Paths are advanced with the f64 reference intersector.
//!
//! - [`primary_tile`]: a tile of T x T pixels x S samples per pixel as one
//!   ray stream (the DRS paper: 16 x 16 x 16 = 4096 rays).
//! - [`path_trace_tile`]: the DRS render loop: the primary stream, then per
//!   bounce the surviving paths as a new stream, with one shadow ray per hit
//!   toward a random point of the scene's first quad light, batched into
//!   shadow streams of at most the primary stream's size. Diffuse surfaces
//!   bounce cosine-weighted, mirrors reflect, glossy surfaces reflect with a
//!   Phong-lobe perturbation.
//! - [`soft_shadow_frusta`]: the MFT inputs: per 4 x 4 pixel group, the 16
//!   primary hit points and 16 light samples each, pixel k of the group using
//!   interleaved set k of a 256-point Hammersley set ([`SampleSplit`]: by
//!   default a 16-point net spanning the light, the paper's sets).
//! - [`distribution_tile`]: distribution ray tracing as the MBVH ray-stream
//!   paper: 16 paths per pixel through a thin lens (depth of field), soft
//!   shadow rays to random points of the area light, one glossy reflection.
//! - [`visibility_rays`]: primary rays over the whole image for multi-hit
//!   (all hits along each ray).

use crate::bvh::Bvh2;
use crate::mesh::Mesh;
use crate::reference::{Ray, Reference};
use crate::scene::{Camera, Light, Material, Scene};
use isa::rng::Rng;
use rayon::prelude::*;

/// What a stream's rays are for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StreamKind {
    /// Camera rays.
    Primary,
    /// Continuation rays of bounce n (1 = the first bounce off a primary hit).
    Bounce(u32),
    /// Shadow rays toward the light from the hits of bounce n (0 = primary hits).
    Shadow(u32),
}

/// A stream of rays in f32, as the kernels read them.
#[derive(Clone, Debug, PartialEq)]
pub struct RayStream {
    /// What the rays are.
    pub kind: StreamKind,
    /// Origins.
    pub org: Vec<[f32; 3]>,
    /// Directions (unnormalised for shadow rays: t = 1 reaches the light sample).
    pub dir: Vec<[f32; 3]>,
    /// Far limits (1 - epsilon for shadow rays, infinity otherwise).
    pub tmax: Vec<f32>,
    /// The path each ray belongs to: the index of its camera sample in the
    /// tile, `(py * size + px) * spp + k` (visibility rays: the pixel index),
    /// so a packet renderer can keep a path in its lane.
    pub path: Vec<u32>,
}

impl RayStream {
    fn new(kind: StreamKind) -> RayStream {
        RayStream {
            kind,
            org: Vec::new(),
            dir: Vec::new(),
            tmax: Vec::new(),
            path: Vec::new(),
        }
    }
    /// A stream of given rays (path i for ray i; t_far `tmax`).
    #[must_use]
    pub fn from_rays(
        kind: StreamKind,
        org: Vec<[f32; 3]>,
        dir: Vec<[f32; 3]>,
        tmax: Vec<f32>,
    ) -> RayStream {
        assert!(org.len() == dir.len() && org.len() == tmax.len());
        let path = (0..org.len() as u32).collect();
        RayStream {
            kind,
            org,
            dir,
            tmax,
            path,
        }
    }
    /// Closest-hit rays over (0, inf).
    #[must_use]
    pub fn closest(org: Vec<[f32; 3]>, dir: Vec<[f32; 3]>) -> RayStream {
        let n = org.len();
        RayStream::from_rays(StreamKind::Primary, org, dir, vec![f32::INFINITY; n])
    }
    /// Whether the rays are shadow rays (any hit).
    #[must_use]
    pub fn is_shadow(&self) -> bool {
        matches!(self.kind, StreamKind::Shadow(_))
    }
    /// The hit a kernel looks for on these rays: any for shadow rays, else
    /// the closest.
    #[must_use]
    pub fn policy(&self) -> crate::hit::HitPolicy {
        if self.is_shadow() {
            crate::hit::HitPolicy::Any
        } else {
            crate::hit::HitPolicy::Closest
        }
    }
    /// Number of rays.
    #[must_use]
    pub fn len(&self) -> usize {
        self.org.len()
    }
    /// Whether empty.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.org.is_empty()
    }
    fn push(&mut self, o: [f64; 3], d: [f64; 3], tmax: f32, path: u32) {
        self.org.push(o.map(|x| x as f32));
        self.dir.push(d.map(|x| x as f32));
        self.tmax.push(tmax);
        self.path.push(path);
    }
    /// Ray `i` in f64 for the reference.
    #[must_use]
    pub fn ray(&self, i: usize) -> Ray {
        Ray {
            org: self.org[i].map(f64::from),
            dir: self.dir[i].map(f64::from),
            tmin: 0.0,
            tmax: f64::from(self.tmax[i]),
        }
    }
}

/// A square tile of the image: its column and row in tiles, and its size in pixels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tile {
    /// Column, in tiles.
    pub x: u32,
    /// Row, in tiles.
    pub y: u32,
    /// Side in pixels.
    pub size: u32,
}

/// A seed for (scene seed, tile, pixel, sample) so every path is reproducible alone.
fn path_seed(seed: u64, tile: (u32, u32), pixel: u32, sample: u32) -> u64 {
    let mut r =
        Rng::new(seed ^ (u64::from(tile.0) << 40) ^ (u64::from(tile.1) << 20) ^ u64::from(pixel));
    r.next_u64() ^ u64::from(sample).wrapping_mul(0x9e37_79b9_7f4a_7c15)
}

/// Call `f` with the pinhole ray and the path's own generator for every
/// jittered sample of every pixel of tile (`tx`, `ty`) (`t` x `t` pixels).
fn for_each_sample(
    cam: &Camera,
    tx: u32,
    ty: u32,
    t: u32,
    spp: u32,
    seed: u64,
    f: impl FnMut([f64; 3], [f64; 3], Rng, u32),
) {
    let raster = (0..t).flat_map(|py| (0..t).map(move |px| (px, py)));
    for_each_sample_in(cam, (tx, ty, t), raster, (spp, false), seed, f);
}

/// The tile's pixels in Morton (Z) order: every aligned run of 4^k pixels is
/// a square of 2^k x 2^k (of 2^k x 2^(k+1) for odd powers), so a group of
/// consecutive rays covers neighbouring pixels at any power-of-two size.
fn morton_pixels(t: u32) -> Vec<(u32, u32)> {
    let spread = |mut v: u32| {
        let mut r = 0u64;
        for b in 0..16 {
            r |= u64::from(v & 1) << (2 * b);
            v >>= 1;
        }
        r
    };
    let mut px: Vec<(u32, u32)> = (0..t).flat_map(|y| (0..t).map(move |x| (x, y))).collect();
    px.sort_by_key(|&(x, y)| spread(x) | spread(y) << 1);
    px
}

/// [`for_each_sample`] over pixels of the tile in the given order;
/// `stratified` (and `spp` a square n^2): sample k of a pixel jittered in
/// cell (k mod n, k div n) of an n x n grid over the pixel.
fn for_each_sample_in(
    cam: &Camera,
    (tx, ty, t): (u32, u32, u32),
    pixels: impl IntoIterator<Item = (u32, u32)>,
    (spp, stratified): (u32, bool),
    seed: u64,
    mut f: impl FnMut([f64; 3], [f64; 3], Rng, u32),
) {
    let n = strata(spp).filter(|_| stratified);
    for (px, py) in pixels {
        {
            let (x, y) = (tx * t + px, ty * t + py);
            if x >= cam.width || y >= cam.height {
                continue;
            }
            for k in 0..spp {
                let mut r = Rng::new(path_seed(seed, (tx, ty), py * t + px, k));
                let (jx, jy) = (f64::from(r.f32()), f64::from(r.f32()));
                let (ox, oy) = match n {
                    Some(n) => (
                        (f64::from(k % n) + jx) / f64::from(n),
                        (f64::from(k / n) + jy) / f64::from(n),
                    ),
                    None => (jx, jy),
                };
                let (o, d) = cam.ray(f64::from(x) + ox, f64::from(y) + oy);
                f(o, d, r, (py * t + px) * spp + k);
            }
        }
    }
}

/// n if `spp` is n^2 (n > 1), else none.
fn strata(spp: u32) -> Option<u32> {
    let n = f64::from(spp).sqrt().round() as u32;
    (n > 1 && n * n == spp).then_some(n)
}

/// Sample `k`'s cell of the n x n strata of a second 2D dimension (the
/// lens), in a seeded shuffled order per pixel so it is not correlated with
/// the pixel cell `k` takes.
fn shuffled_cell(n: u32, k: u32, pixel_seed: u64) -> (u32, u32) {
    let mut perm: Vec<u32> = (0..n * n).collect();
    let mut r = Rng::new(pixel_seed);
    for i in (1..perm.len()).rev() {
        let j = (r.next_u64() % (i as u64 + 1)) as usize;
        perm.swap(i, j);
    }
    let c = perm[k as usize];
    (c % n, c / n)
}

/// Primary rays of tile (`tx`, `ty`) of size `t` x `t` pixels, `spp` jittered samples each.
#[must_use]
pub fn primary_tile(cam: &Camera, tx: u32, ty: u32, t: u32, spp: u32, seed: u64) -> RayStream {
    let mut s = RayStream::new(StreamKind::Primary);
    for_each_sample(cam, tx, ty, t, spp, seed, |o, d, _, path| {
        s.push(o, d, f32::INFINITY, path)
    });
    s
}

/// The scene's largest extent (scales hit-point offsets).
/// The scene's largest extent (sets the shadow-ray origin offset).
#[must_use]
pub fn scene_size(scene: &Scene) -> f64 {
    let b = scene.bounds();
    (0..3)
        .map(|a| f64::from(b.hi[a] - b.lo[a]))
        .fold(0.0, f64::max)
}

type V3 = [f64; 3];
fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn scale(a: V3, s: f64) -> V3 {
    a.map(|c| c * s)
}
fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn norm(a: V3) -> V3 {
    scale(a, 1.0 / dot(a, a).sqrt().max(1e-300))
}

/// Geometric normal of triangle `prim`, facing against `dir`.
fn facing_normal(mesh: &Mesh, prim: u32, dir: V3) -> V3 {
    let [p, q, r] = mesh.tri(prim as usize).map(|v| v.map(f64::from));
    let n = norm(cross(sub(q, p), sub(r, p)));
    if dot(n, dir) > 0.0 {
        scale(n, -1.0)
    } else {
        n
    }
}

/// A direction around `n` with cosine-power lobe `exp` (1 = cosine-weighted hemisphere).
fn lobe(n: V3, exp: f64, r: &mut Rng) -> V3 {
    let (u1, u2) = (f64::from(r.f32()), f64::from(r.f32()));
    let cos_t = u1.powf(1.0 / (exp + 1.0));
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    let phi = 2.0 * std::f64::consts::PI * u2;
    let a = if n[0].abs() > 0.9 {
        [0.0, 1.0, 0.0]
    } else {
        [1.0, 0.0, 0.0]
    };
    let t = norm(cross(a, n));
    let b = cross(n, t);
    norm(add(
        add(scale(t, sin_t * phi.cos()), scale(b, sin_t * phi.sin())),
        scale(n, cos_t),
    ))
}

/// A point on the scene's first quad light (or its point light).
fn light_point(scene: &Scene, u: f64, v: f64) -> Option<V3> {
    scene
        .config
        .lights
        .iter()
        .map(|l| match *l {
            Light::Quad(c, e1, e2, _) => {
                let (c, e1, e2) = (c.map(f64::from), e1.map(f64::from), e2.map(f64::from));
                Some(add(c, add(scale(e1, u), scale(e2, v))))
            }
            Light::Point(p, _) => Some(p.map(f64::from)),
        })
        .next()
        .flatten()
}

/// Offset a hit point along the normal so continuation rays do not re-hit it.
fn offset(p: V3, n: V3, scene_size: f64) -> V3 {
    add(p, scale(n, 1e-5 * scene_size.max(1e-3)))
}

/// The DRS render loop over one tile: the streams in the order they are traced.
#[must_use]
pub fn path_trace_tile(
    scene: &Scene,
    bvh: &Bvh2,
    tile: Tile,
    spp: u32,
    max_bounces: u32,
    seed: u64,
) -> Vec<RayStream> {
    let (tx, ty, t) = (tile.x, tile.y, tile.size);
    let refi = Reference::with_bvh(&scene.mesh, bvh);
    let size = scene_size(scene);
    let primary = primary_tile(&scene.config.camera, tx, ty, t, spp, seed);
    let stream_size = primary.len().max(1);
    let mut out = vec![primary.clone()];
    let mut current = primary;
    // Every path keeps its own generator, seeded by its identity.
    let mut rngs: Vec<Rng> = (0..current.len() as u64)
        .map(|i| {
            Rng::new(seed.wrapping_mul(31) ^ (u64::from(tx) << 48) ^ (u64::from(ty) << 32) ^ i)
        })
        .collect();
    for bounce in 0..=max_bounces {
        let mut next = RayStream::new(StreamKind::Bounce(bounce + 1));
        let mut next_rngs = Vec::new();
        let mut shadows = RayStream::new(StreamKind::Shadow(bounce));
        for i in 0..current.len() {
            let ray = current.ray(i);
            let Some(hit) = refi.closest(&ray) else {
                continue;
            };
            let p = add(ray.org, scale(ray.dir, hit.t));
            let n = facing_normal(&scene.mesh, hit.prim, ray.dir);
            let o = offset(p, n, size);
            let r = &mut rngs[i];
            if let Some(l) = light_point(scene, f64::from(r.f32()), f64::from(r.f32())) {
                shadows.push(o, sub(l, o), 1.0 - 1e-4, current.path[i]);
                if shadows.len() == stream_size {
                    out.push(std::mem::replace(
                        &mut shadows,
                        RayStream::new(StreamKind::Shadow(bounce)),
                    ));
                }
            }
            if bounce == max_bounces {
                continue;
            }
            let d = norm(ray.dir);
            let refl = sub(d, scale(n, 2.0 * dot(d, n)));
            let nd = match scene.materials[hit.prim as usize] {
                Material::Diffuse => lobe(n, 1.0, r),
                Material::Mirror => refl,
                Material::Glossy => {
                    let g = lobe(refl, 50.0, r);
                    if dot(g, n) > 0.0 {
                        g
                    } else {
                        refl
                    }
                }
            };
            next.push(o, nd, f32::INFINITY, current.path[i]);
            next_rngs.push(r.clone());
        }
        if !shadows.is_empty() {
            out.push(shadows);
        }
        if next.is_empty() {
            break;
        }
        if bounce < max_bounces {
            out.push(next.clone());
        }
        current = next;
        rngs = next_rngs;
    }
    out
}

/// Thin-lens parameters for depth of field.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lens {
    /// Aperture radius, in scene units.
    pub aperture: f64,
    /// Distance of the plane in focus from the eye, along the view direction.
    pub focus: f64,
}

/// Distribution ray tracing of one tile, `paths` per pixel, to a maximum
/// bounce depth of `bounces`: streams of primary rays (thin lens), shadow
/// rays from their hits (`Shadow(0)`), glossy reflection rays off every hit
/// (`Bounce(1)`), shadow rays from those hits (`Shadow(1)`), and so on to
/// `Bounce(bounces)`, in the order they are traced: 2 n + 1 rays per path
/// of n bounces that stays in the scene (the MBVH ray-stream paper's rays
/// per frame: 12.6, 21, 29 and 38 M at 512x512 and 16 paths for 1-4
/// bounces), the last bounce's hits lit without a shadow ray. No
/// attenuation: a path ends only when it leaves the scene or reaches the
/// depth. The tile's
/// pixels are visited in Morton order, each pixel's paths together.
#[must_use]
pub fn distribution_tile(
    scene: &Scene,
    bvh: &Bvh2,
    tile: Tile,
    paths: u32,
    lens: Lens,
    bounces: u32,
    seed: u64,
) -> Vec<RayStream> {
    let (tx, ty, t) = (tile.x, tile.y, tile.size);
    let refi = Reference::with_bvh(&scene.mesh, bvh);
    let cam = &scene.config.camera;
    let size = scene_size(scene);
    let mut primary = RayStream::new(StreamKind::Primary);
    let mut rngs = Vec::new();
    let eye = cam.eye.map(f64::from);
    let (_, centre) = cam.ray(f64::from(cam.width) / 2.0, f64::from(cam.height) / 2.0);
    let fwd = norm(centre);
    let right = norm(cross(fwd, cam.up.map(f64::from)));
    let up = cross(right, fwd);
    // Pixels in Morton order: a ray group of any power-of-two size covers
    // a compact block of pixels (the stream kernels group consecutive rays).
    let pixels = morton_pixels(t);
    // Pixel and lens positions stratified n x n per pixel (16 paths: 4 x 4),
    // the lens cells in a shuffled order (the paper: sudoku samples, whose
    // 2D projections are stratified alike).
    let n = strata(paths);
    for_each_sample_in(
        cam,
        (tx, ty, t),
        pixels,
        (paths, true),
        seed,
        |o, d, mut r, path| {
            // Thin lens: the ray through the lens point meets the pinhole ray on the focus plane.
            let focal = add(o, scale(d, lens.focus / dot(d, fwd)));
            let (mut u, mut v) = (f64::from(r.f32()), f64::from(r.f32()));
            if let Some(n) = n {
                let pixel = path / paths;
                let (cx, cy) =
                    shuffled_cell(n, path % paths, path_seed(seed, (tx, ty), pixel, u32::MAX));
                u = (f64::from(cx) + u) / f64::from(n);
                v = (f64::from(cy) + v) / f64::from(n);
            }
            let (a, phi) = (lens.aperture * u.sqrt(), 2.0 * std::f64::consts::PI * v);
            let lo = add(
                eye,
                add(scale(right, a * phi.cos()), scale(up, a * phi.sin())),
            );
            primary.push(lo, sub(focal, lo), f32::INFINITY, path);
            rngs.push(r);
        },
    );
    let mut out = vec![primary.clone()];
    let mut current = primary;
    for bounce in 0..bounces {
        let mut shadows = RayStream::new(StreamKind::Shadow(bounce));
        let mut glossy = RayStream::new(StreamKind::Bounce(bounce + 1));
        let mut next_rngs = Vec::new();
        for i in 0..current.len() {
            let ray = current.ray(i);
            let Some(hit) = refi.closest(&ray) else {
                continue;
            };
            let n = facing_normal(&scene.mesh, hit.prim, ray.dir);
            let o = offset(add(ray.org, scale(ray.dir, hit.t)), n, size);
            let r = &mut rngs[i];
            if let Some(l) = light_point(scene, f64::from(r.f32()), f64::from(r.f32())) {
                shadows.push(o, sub(l, o), 1.0 - 1e-4, current.path[i]);
            }
            let d = norm(ray.dir);
            let refl = sub(d, scale(n, 2.0 * dot(d, n)));
            let g = lobe(refl, 20.0, r);
            let gd = if dot(g, n) > 0.0 { g } else { refl };
            glossy.push(o, gd, f32::INFINITY, current.path[i]);
            next_rngs.push(r.clone());
        }
        out.push(shadows);
        out.push(glossy.clone());
        current = glossy;
        rngs = next_rngs;
    }
    out
}

/// Radical inverse in base 2 (van der Corput).
#[must_use]
pub fn radical_inverse2(mut i: u32) -> f64 {
    i = i.reverse_bits();
    f64::from(i) / 4_294_967_296.0
}

/// How the 256 Hammersley points on the light are split into the 16
/// interleaved sets of a 4 x 4 pixel group (pixel k takes set k). Both
/// partition the same 256 points, so a filtered 4 x 4 tile sees all of them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum SampleSplit {
    /// The paper's sets (the default): set k is a 16-point (0,4,2)-net in
    /// base 2 over the whole light, points `16 h + ((h + k) mod 16)` for h
    /// in 0..16: one point in each 1/16 column and each 1/16 row, so each
    /// set spans the light (its 2D bounds cover at least 29/32 of each
    /// edge; the xor family `16 h + (h xor k)`, nets too, reaches only
    /// 225/256 on some sets). The paper bounds
    /// each set's 2D box for its corner rays and calls that only "slightly
    /// more beneficial" than the light's own corners, which holds for sets
    /// that span the light; interleaved sampling (Keller and Heidrich 2001)
    /// gives every pixel a well-spread estimate of its own.
    #[default]
    Nets,
    /// A named variant: set k is points `16 j + k`, j in 0..16, all in one
    /// 1/16-high strip of the light (the low 4 bits of the index fix the
    /// top 4 bits of the radical inverse), one per 1/16 column: thin frusta,
    /// each pixel's estimate a strip's, the filter combining the strips.
    Strips,
}

impl SampleSplit {
    /// Both splits, the default first.
    pub const ALL: [SampleSplit; 2] = [SampleSplit::Nets, SampleSplit::Strips];

    /// Its name in reports and options.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            SampleSplit::Nets => "nets",
            SampleSplit::Strips => "strips",
        }
    }

    /// Indices (into the 256-point Hammersley set) of set `k` (k in 0..16).
    #[must_use]
    pub fn indices(self, k: u32) -> [u32; 16] {
        let k = k & 15;
        std::array::from_fn(|j| {
            let j = j as u32;
            match self {
                SampleSplit::Nets => 16 * j + ((j + k) & 15),
                SampleSplit::Strips => 16 * j + k,
            }
        })
    }

    /// Set `k` of the 256-point Hammersley set (`i / 256`, radical inverse
    /// of `i`) as (u, v) on the light.
    #[must_use]
    pub fn set(self, k: u32) -> [[f64; 2]; 16] {
        self.indices(k)
            .map(|i| [f64::from(i) / 256.0, radical_inverse2(i)])
    }
}

/// Interleaved Hammersley set `k` of 16 as the strip split gives it
/// ([`SampleSplit::Strips`]). Measured (an earlier session,
/// `mft-quality --quick` on the T-Rex stand-in): nets give each pixel a good
/// estimate on its own (45.8 dB unfiltered, 40.2 dB filtered), strips 30.8
/// dB unfiltered and 39.8 dB filtered.
#[must_use]
pub fn hammersley_set(k: u32) -> [[f64; 2]; 16] {
    SampleSplit::Strips.set(k)
}

/// MFT soft-shadow inputs of one 4 x 4 pixel group.
#[derive(Clone, Debug, PartialEq)]
pub struct FrustumInput {
    /// Top-left pixel of the group.
    pub pixel: (u32, u32),
    /// Primary hit point of each of the 16 pixels (row-major), if any.
    pub hits: [Option<[f32; 3]>; 16],
    /// 16 light sample points per pixel (pixel k uses set k of the split).
    pub samples: [[[f32; 3]; 16]; 16],
}

/// MFT inputs over the camera's image, 4 x 4 pixel groups, the paper's
/// sample sets ([`SampleSplit::Nets`]).
#[must_use]
pub fn soft_shadow_frusta(scene: &Scene, bvh: &Bvh2) -> Vec<FrustumInput> {
    let refi = Reference::with_bvh(&scene.mesh, bvh);
    let cam = &scene.config.camera;
    let groups: Vec<(u32, u32)> = (0..cam.height)
        .step_by(4)
        .flat_map(|gy| (0..cam.width).step_by(4).map(move |gx| (gx, gy)))
        .collect();
    soft_shadow_groups(scene, &refi, &groups, SampleSplit::Nets)
}

/// The MFT soft-shadow input of the 4 x 4 pixel group whose top-left pixel
/// is (`gx`, `gy`): primary hits by `refi`, offset along the facing normal,
/// and pixel k's 16 light samples from set k of the paper's split
/// ([`SampleSplit::Nets`]).
#[must_use]
pub fn soft_shadow_group(scene: &Scene, refi: &Reference, gx: u32, gy: u32) -> FrustumInput {
    let cam = &scene.config.camera;
    let hit = |x: u32, y: u32| {
        let (o, d) = cam.ray(f64::from(x) + 0.5, f64::from(y) + 0.5);
        refi.closest(&Ray::new(o, d)).map(|h| (h.t, h.prim))
    };
    shadow_group_with(
        scene,
        scene_size(scene),
        &hit,
        (gx, gy),
        0,
        SampleSplit::Nets,
    )
}

/// [`soft_shadow_group`] of each top-left pixel in `groups`, in order, with
/// the sample sets of `split` (the scene's extent computed once: it walks
/// the whole mesh).
#[must_use]
pub fn soft_shadow_groups(
    scene: &Scene,
    refi: &Reference,
    groups: &[(u32, u32)],
    split: SampleSplit,
) -> Vec<FrustumInput> {
    let cam = &scene.config.camera;
    let size = scene_size(scene);
    let hit = |x: u32, y: u32| {
        let (o, d) = cam.ray(f64::from(x) + 0.5, f64::from(y) + 0.5);
        refi.closest(&Ray::new(o, d)).map(|h| (h.t, h.prim))
    };
    groups
        .par_iter()
        .map(|&g| shadow_group_with(scene, size, &hit, g, 0, split))
        .collect()
}

/// The shadow-ray origin of a primary hit (`t`, `prim`) of pixel (`x`, `y`)
/// in a scene of extent `size` ([`scene_size`]): the hit point offset along
/// the facing normal (f32).
#[must_use]
pub fn shadow_origin(scene: &Scene, size: f64, x: u32, y: u32, t: f64, prim: u32) -> [f32; 3] {
    let (o, d) = scene
        .config
        .camera
        .ray(f64::from(x) + 0.5, f64::from(y) + 0.5);
    let p = add(o, scale(d, t));
    let n = facing_normal(&scene.mesh, prim, d);
    offset(p, n, size).map(|c| c as f32)
}

/// [`soft_shadow_group`] in a scene of extent `size` ([`scene_size`]) with
/// the primary hits (t, prim) of each pixel from `hit`, and pixel k
/// sampling set `k ^ rot` of `split`: the 16 rotations give every pixel all
/// 256 points (a 256-sample reference, 16 at a time).
#[must_use]
pub fn shadow_group_with(
    scene: &Scene,
    size: f64,
    hit: &dyn Fn(u32, u32) -> Option<(f64, u32)>,
    (gx, gy): (u32, u32),
    rot: u32,
    split: SampleSplit,
) -> FrustumInput {
    let cam = &scene.config.camera;
    let mut f = FrustumInput {
        pixel: (gx, gy),
        hits: [None; 16],
        samples: [[[0.0; 3]; 16]; 16],
    };
    for k in 0..16u32 {
        let (x, y) = (gx + k % 4, gy + k / 4);
        if x < cam.width && y < cam.height {
            if let Some((t, prim)) = hit(x, y) {
                f.hits[k as usize] = Some(shadow_origin(scene, size, x, y, t, prim));
            }
        }
        for (j, uv) in split.set(k ^ (rot & 15)).iter().enumerate() {
            if let Some(l) = light_point(scene, uv[0], uv[1]) {
                f.samples[k as usize][j] = l.map(|c| c as f32);
            }
        }
    }
    f
}

/// One primary ray per pixel center over the camera's image (multi-hit visibility).
#[must_use]
pub fn visibility_rays(cam: &Camera) -> RayStream {
    let mut s = RayStream::new(StreamKind::Primary);
    for y in 0..cam.height {
        for x in 0..cam.width {
            let (o, d) = cam.ray(f64::from(x) + 0.5, f64::from(y) + 0.5);
            s.push(o, d, f32::INFINITY, y * cam.width + x);
        }
    }
    s
}

/// Packet lanes of a tile's stream as an SoA packet renderer (Embree's ISPC
/// path tracer) forms them: one packet per camera sample index and block of
/// `w` pixels (4 x 2 for 8 lanes, 2 x 2 for 4, 4 x 4 for 16), a path keeps its
/// lane for all its bounces and shadow rays, and lanes whose path has no ray
/// in this stream are empty (`u32::MAX`); packets with no ray are dropped.
/// Returns, per lane slot, the stream index of its ray.
#[must_use]
pub fn packet_slots(stream: &RayStream, size: u32, spp: u32, w: usize) -> Vec<u32> {
    let bw = if w >= 8 { 4 } else { 2 }.min(w as u32);
    let bh = (w as u32 / bw).max(1);
    let (nbx, nby) = (size.div_ceil(bw), size.div_ceil(bh));
    let npk = (spp * nbx * nby) as usize;
    let mut slots = vec![u32::MAX; npk * w];
    for (i, &p) in stream.path.iter().enumerate() {
        let (pixel, k) = (p / spp, p % spp);
        let (px, py) = (pixel % size, pixel / size);
        let pk = (k * nby + py / bh) * nbx + px / bw;
        let lane = (py % bh) * bw + px % bw;
        slots[pk as usize * w + lane as usize] = i as u32;
    }
    slots
        .chunks(w)
        .filter(|c| c.iter().any(|&s| s != u32::MAX))
        .flatten()
        .copied()
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::BuildConfig;

    fn sphere_scene() -> (Scene, Bvh2) {
        let s = Scene::load("sphere").unwrap();
        let b = Bvh2::build(&s.mesh, &BuildConfig::default()).unwrap();
        (s, b)
    }

    #[test]
    fn primary_tile_is_4096_rays_and_deterministic() {
        let (s, _) = sphere_scene();
        let a = primary_tile(&s.config.camera, 3, 2, 16, 16, 1);
        assert_eq!(a.len(), 4096);
        assert_eq!(a, primary_tile(&s.config.camera, 3, 2, 16, 16, 1));
        assert_ne!(a, primary_tile(&s.config.camera, 3, 2, 16, 16, 2));
    }

    #[test]
    fn path_tracing_streams_shrink_and_shadow_rays_reach_the_light() {
        let (s, b) = sphere_scene();
        let streams = path_trace_tile(
            &s,
            &b,
            Tile {
                x: 6,
                y: 6,
                size: 16,
            },
            4,
            3,
            7,
        );
        assert_eq!(streams[0].kind, StreamKind::Primary);
        assert_eq!(
            streams,
            path_trace_tile(
                &s,
                &b,
                Tile {
                    x: 6,
                    y: 6,
                    size: 16
                },
                4,
                3,
                7
            ),
            "deterministic"
        );
        let bounces: Vec<usize> = streams
            .iter()
            .filter(|x| matches!(x.kind, StreamKind::Bounce(_)))
            .map(RayStream::len)
            .collect();
        assert!(!bounces.is_empty());
        assert!(
            bounces.windows(2).all(|w| w[1] <= w[0]),
            "paths only terminate: {bounces:?}"
        );
        for st in streams
            .iter()
            .filter(|x| matches!(x.kind, StreamKind::Shadow(_)))
        {
            assert!(
                st.len() <= streams[0].len(),
                "shadow batches at most the stream size"
            );
            for i in 0..st.len() {
                let end: Vec<f32> = (0..3).map(|a| st.org[i][a] + st.dir[i][a]).collect();
                assert!(
                    (end[1] - 4.0).abs() < 1e-3,
                    "shadow ray ends on the light plane y = 4: {end:?}"
                );
            }
        }
    }

    #[test]
    fn strata_cover_every_cell_once_in_a_shuffled_order() {
        assert_eq!(
            (strata(16), strata(15), strata(1), strata(64)),
            (Some(4), None, None, Some(8))
        );
        for seed in [1, 2, 3] {
            let mut cells: Vec<(u32, u32)> = (0..16).map(|k| shuffled_cell(4, k, seed)).collect();
            let in_order = cells == (0..16).map(|k| (k % 4, k / 4)).collect::<Vec<_>>();
            cells.sort_unstable();
            cells.dedup();
            assert_eq!(cells.len(), 16);
            assert!(!in_order, "shuffled, not the pixel's order");
        }
    }

    #[test]
    fn distribution_tracing_bounces_to_the_depth_asked_with_shadows_at_each() {
        let (s, b) = sphere_scene();
        let lens = Lens {
            aperture: 0.05,
            focus: 4.0,
        };
        let tile = Tile {
            x: 7,
            y: 7,
            size: 8,
        };
        let one = distribution_tile(&s, &b, tile, 4, lens, 1, 9);
        let three = distribution_tile(&s, &b, tile, 4, lens, 3, 9);
        let kinds: Vec<StreamKind> = three.iter().map(|r| r.kind).collect();
        use StreamKind::{Bounce, Primary, Shadow};
        let want = [
            Primary,
            Shadow(0),
            Bounce(1),
            Shadow(1),
            Bounce(2),
            Shadow(2),
            Bounce(3),
        ];
        assert_eq!(kinds, want);
        // The deeper render starts as the shallower one (same samples).
        assert_eq!(one[..3], three[..3]);
        // A bounce has no more rays than the hits before it.
        assert!(three[4].len() <= three[2].len() && three[2].len() <= three[0].len());
    }

    #[test]
    fn distribution_tracing_has_16_paths_per_pixel_and_focuses() {
        let (s, b) = sphere_scene();
        let lens = Lens {
            aperture: 0.05,
            focus: 4.0,
        };
        let st = distribution_tile(
            &s,
            &b,
            Tile {
                x: 7,
                y: 7,
                size: 8,
            },
            16,
            lens,
            1,
            3,
        );
        assert_eq!(st[0].len(), 8 * 8 * 16);
        assert_eq!(
            st,
            distribution_tile(
                &s,
                &b,
                Tile {
                    x: 7,
                    y: 7,
                    size: 8
                },
                16,
                lens,
                1,
                3
            ),
            "deterministic"
        );
        let kinds: Vec<StreamKind> = st.iter().map(|x| x.kind).collect();
        assert_eq!(
            kinds,
            [
                StreamKind::Primary,
                StreamKind::Shadow(0),
                StreamKind::Bounce(1),
            ]
        );
        // Lens origins spread within the aperture around the eye.
        let eye = s.config.camera.eye;
        let spread = st[0]
            .org
            .iter()
            .map(|o| (0..3).map(|a| (o[a] - eye[a]).powi(2)).sum::<f32>().sqrt())
            .fold(0.0, f32::max);
        assert!(spread > 0.0 && spread <= 0.05 + 1e-6, "{spread}");
    }

    #[test]
    fn hammersley_sets_partition_256_points() {
        let mut all: Vec<u64> = (0..16)
            .flat_map(|k| hammersley_set(k).map(|p| (p[0] * 256.0) as u64))
            .collect();
        all.sort_unstable();
        assert_eq!(all, (0..256).collect::<Vec<u64>>());
        assert_eq!(radical_inverse2(1), 0.5);
        assert_eq!(radical_inverse2(3), 0.75);
        // Each set: one point per 1/16 column, all in one 1/16 row.
        for k in 0..16 {
            let set = hammersley_set(k);
            let mut cols: Vec<u64> = set.iter().map(|p| (p[0] * 16.0) as u64).collect();
            cols.sort_unstable();
            assert_eq!(cols, (0..16).collect::<Vec<u64>>(), "set {k}");
            let row = (set[0][1] * 16.0) as u64;
            assert!(set.iter().all(|p| (p[1] * 16.0) as u64 == row), "set {k}");
        }
    }

    #[test]
    fn both_splits_partition_the_256_points() {
        for split in SampleSplit::ALL {
            let mut all: Vec<u32> = (0..16).flat_map(|k| split.indices(k)).collect();
            all.sort_unstable();
            assert_eq!(all, (0..256).collect::<Vec<u32>>(), "{split:?}");
        }
    }

    /// The paper's sets each span the light: the 2D bounds of every set
    /// cover at least 90% of each edge (29/32 at least), and each is a
    /// (0,4,2)-net in base 2 (one point in every cell of the 16 x 1, 8 x 2,
    /// 4 x 4, 2 x 8 and 1 x 16 dyadic grids); the strips do not (one row:
    /// under 1/16 high).
    #[test]
    fn each_net_spans_the_light_and_strips_do_not() {
        let span = |set: [[f64; 2]; 16], a: usize| {
            let lo = set.iter().map(|p| p[a]).fold(f64::INFINITY, f64::min);
            let hi = set.iter().map(|p| p[a]).fold(f64::NEG_INFINITY, f64::max);
            hi - lo
        };
        for k in 0..16 {
            let net = SampleSplit::Nets.set(k);
            for a in 0..2 {
                assert!(span(net, a) >= 0.9, "net {k} axis {a}: {}", span(net, a));
            }
            for bits in 0..=4 {
                let (nu, nv) = (f64::from(1u32 << bits), f64::from(1u32 << (4 - bits)));
                let mut cells: Vec<(u64, u64)> = net
                    .iter()
                    .map(|p| ((p[0] * nu) as u64, (p[1] * nv) as u64))
                    .collect();
                cells.sort_unstable();
                cells.dedup();
                assert_eq!(cells.len(), 16, "net {k}: {nu} x {nv} cells");
            }
            assert!(span(SampleSplit::Strips.set(k), 1) < 1.0 / 16.0);
        }
        assert_eq!(SampleSplit::default(), SampleSplit::Nets);
    }

    /// On a scene: each pixel's 16 light points (the default split) span
    /// at least 90% of the light's quad along both edges.
    #[test]
    fn each_pixel_s_light_samples_span_the_light() {
        let mut s = Scene::load("sphere").unwrap();
        s.config.camera.width = 16;
        s.config.camera.height = 16;
        let b = Bvh2::build(&s.mesh, &BuildConfig::default()).unwrap();
        let Some(Light::Quad(c, e1, e2, _)) = s.config.lights.first().cloned() else {
            panic!("the sphere scene has a quad light");
        };
        let (c, e) = (c.map(f64::from), [e1, e2].map(|e| e.map(f64::from)));
        let mut checked = 0;
        for g in soft_shadow_frusta(&s, &b) {
            for pts in &g.samples {
                for e in e {
                    let ee = dot(e, e);
                    let t: Vec<f64> = pts
                        .iter()
                        .map(|p| dot(sub(p.map(f64::from), c), e) / ee)
                        .collect();
                    let lo = t.iter().copied().fold(f64::INFINITY, f64::min);
                    let hi = t.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                    assert!(hi - lo >= 0.9, "span {}", hi - lo);
                    checked += 1;
                }
            }
        }
        assert!(checked > 0);
    }

    #[test]
    fn frusta_cover_the_image_in_4x4_groups() {
        let mut s = Scene::load("sphere").unwrap();
        s.config.camera.width = 32;
        s.config.camera.height = 16;
        let b = Bvh2::build(&s.mesh, &BuildConfig::default()).unwrap();
        let f = soft_shadow_frusta(&s, &b);
        assert_eq!(f.len(), 8 * 4);
        assert!(f.iter().any(|g| g.hits.iter().any(Option::is_some)));
        assert!(
            f[0].samples
                .iter()
                .flatten()
                .all(|p| (p[1] - 4.0).abs() < 1e-6),
            "samples on the light"
        );
        assert_eq!(visibility_rays(&s.config.camera).len(), 32 * 16);
    }
}
