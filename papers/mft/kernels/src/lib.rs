//! Multi-frusta tracing (Benthin and Wald 2009, "Efficient Ray Traced Soft
//! Shadows using Multi-Frusta Tracing"): 16 frusta traced in parallel, one per
//! SIMD lane, through a BVH2 by interval-arithmetic slab culling only; at
//! leaves back-face and corner-ray culling for all frusta at once, then for
//! each surviving frustum (bitscan) one 16-wide ray-triangle test of its rays,
//! generated on demand from a start and a delta vector.
//!
//! Primary frusta: 16 frusta of 4 x 4 pixels = a 16 x 16 pixel block, one
//! common origin, closest hit per ray. Shadow frusta: the 16 hit points of a
//! 4 x 4 pixel group, each with 16 rays to its own interleaved light samples
//! (per-frustum origins and delta vectors), occlusion bits per ray, a frustum
//! terminated once all its rays are occluded.
//!
//! Frusta record (16 lanes = 16 frusta, rows of 64 B):
//!
//! | rows | field |
//! |---|---|
//! | 0-2 | origin x, y, z |
//! | 3-5 | reciprocal direction interval, low end (x, y, z) |
//! | 6-8 | reciprocal direction interval, high end |
//! | 9-11 | direction interval, low end (for the zero-interval fix) |
//! | 12-14 | direction interval, high end |
//! | 15-26 | corner rays 0-3 (x, y, z each): corner c axis a at row 15 + 3c + a |
//! | 27-29 | start vector (ray 0 of each frustum) |
//! | 30-32 | delta vector (offset of ray k in lane k; shared by primary frusta) |
//! | 33 | origin as 4 x `[x y z 0]`... laid out per BVH2 node row (`[ox x4, oy x4, oz x4, 0 x4]`) |
//! | 34 | per-frustum distance bound (all rays' farthest hit, +inf while any ray misses; shadow: the rays' t limit) |
//! | 35 | active frusta (bits, lane 0) |
//! | 36-83 | shadow frusta only: frustum n's delta vectors at rows 36 + 3n .. 38 + 3n |
//! | 84-115 | shadow frusta only: frustum n's samples' (u, v) on the light, rows 84 + 2n, 85 + 2n |
//! | 116 | shadow frusta only: the light's corner, edge 1, edge 2 (lanes 0-8) |
//!
//! Hits: per frustum 2 rows, t then prim (i32, -1: none), 2 KB for 256 rays.
//!
//! Deviations from the paper: MFT's triangles come from our 8-wide blocks
//! (v0 and two edges precomputed; the paper reads three vertex indices, as
//! the 16-ray packet baseline does here, [`PacketLeaves::Indexed`]); the stack
//! keeps a frustum mask as a u32 (a scalar load and a `kmov` back to a mask
//! register); per-triangle per-frustum values are stored once and read back
//! as broadcast memory operands; a node is tested with per-lane signs (the paper picks
//! the planes once per frusta set from the first frustum's signs).

#![warn(missing_docs)]
// Component loops over x, y, z index several arrays in step.
#![allow(clippy::needless_range_loop)]

pub mod shade;

use isa::{At, BinOp, Buf, Cmp, Int, Machine, MemKind, Program, Region, Shift, UnitProgram};
use rt::layout::{Bvh2Bufs, BLOCK, BLOCK_BYTES};
use rt::single::Sides;
use scene::bvh::{LEAF, LEAF_BLOCKS_SHIFT, LEAF_FIRST_MASK};
use scene::{Hit, HitPolicy};

/// Scratch row of a node's boxes relative to the common origin.
pub const SCRATCH_BOX: usize = 11;

/// Frusta traced together (the SIMD width of the kernel).
pub const FRUSTA: usize = 16;

/// Shadow corner rays go through the samples' 2D bounds on the light widened
/// by this much (in units of the light's edges), so the f32 rays stay inside.
pub const CORNER_MARGIN: f32 = 1e-3;

/// The MFT kernel's shallow BVH: SAH with leaves of up to 32 triangles (4
/// blocks) and a traversal cost of 32 triangle tests. Measured (quick runs,
/// 256 x 256, this session): with leaves of at most 8 triangles and cost 8
/// the shadow AABB reduction over 16-ray packets was 5.5 / 7.3 / 17.1 / 5.0
/// (T-Rex, Fern, Saloon, Fairy stand-ins), with 32 / 32 it is 10.5 / 15.9 /
/// 22.4 / 12.9, at simulated cycles within 5% except Saloon's primary frusta
/// (+40%). A node test costs MFT one test for 16 frusta where the SAH
/// assumes one ray, so a high traversal cost is the bundle's; the paper's
/// 16x-plus AABB reductions need a tree this shallow.
pub const SHALLOW_BVH: scene::bvh::BuildConfig = scene::bvh::BuildConfig {
    bins: 16,
    max_leaf: 32,
    c_trav: 32.0,
};

/// Rows of the frusta record.
pub mod row {
    /// Origin x (y, z follow).
    pub const ORG: usize = 0;
    /// Reciprocal direction interval low end x (y, z follow).
    pub const RCP_LO: usize = 3;
    /// Reciprocal direction interval high end x.
    pub const RCP_HI: usize = 6;
    /// Direction interval low end x.
    pub const DIR_LO: usize = 9;
    /// Direction interval high end x.
    pub const DIR_HI: usize = 12;
    /// Corner ray 0, x (corner c axis a at `CORNER + 3c + a`).
    pub const CORNER: usize = 15;
    /// Start vector x.
    pub const START: usize = 27;
    /// Delta vector x.
    pub const DELTA: usize = 30;
    /// The common origin laid out like a BVH2 node's rows.
    pub const ORG_NODE: usize = 33;
    /// Distance bound per frustum.
    pub const DIST: usize = 34;
    /// Active frusta (u32 bits in lane 0).
    pub const ACTIVE: usize = 35;
    /// Shadow frusta: frustum n's own delta vector x at `DELTA_SETS + 3n` (y, z follow).
    pub const DELTA_SETS: usize = 36;
    /// Shadow frusta: frustum n's rays' light-sample parameters, u at
    /// `UV + 2n` and v at `UV + 2n + 1` (ray k in lane k).
    pub const UV: usize = 84;
    /// Shadow frusta: the light (corner xyz, edge 1 xyz, edge 2 xyz in lanes 0-8).
    pub const LIGHT: usize = 116;
    /// Rows of a primary record.
    pub const ROWS: usize = 36;
    /// Rows of a shadow record.
    pub const ROWS_SHADOW: usize = 117;
}

/// Rays nearly in a triangle's plane: `d . n` (the sum of the three edge
/// tests) below the rounding noise of the edge tests, where the inside test
/// is meaningless. Not in the paper, on by default: without it a grazing
/// ray can hit a triangle the reference misses (full `mft-table1`: one T-Rex
/// primary ray).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PlaneNoise {
    /// The edge tests' verdict stands (the paper).
    Keep,
    /// Such rays miss: 5 more ops per intersection test and 5 per
    /// triangle a frustum reaches (the noise floor, stored). Charged to the
    /// 16-ray packet baseline too ([`PacketPrimaryRun::plane_noise`]), so
    /// the comparison is even.
    #[default]
    Reject,
}

/// The interval slab test of a node's boxes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SlabTest {
    /// The paper's `SlabsTest` (Appendix A): the near and far plane of each
    /// axis picked once per frusta set by an offset table from the sign of
    /// the set's directions, so a box costs 6 multiplies with the plane as a
    /// broadcast memory operand, 2 max and 2 min over the axes, the clamps
    /// to 0 and to the distance, and the compare: 13 VPU ops (shadow frusta:
    /// 6 subtractions of their own origins more). It needs every active
    /// frustum's direction interval to keep one sign on each axis; a set
    /// where one does not (an interval holding zero, or frusta of both
    /// signs) takes the sign-free test below (one branch per set).
    #[default]
    Paper,
    /// A named variant: the sign-free test for every set: per axis entry
    /// min(lo rlo, hi rhi) and exit max(lo rlo, hi rhi), the zero-interval
    /// lanes masked out (20 VPU ops a box), then the zero-interval fix.
    SignFree,
}

/// Frustum shrinking for partly occluded shadow frusta (the paper's section
/// 5.3 and Table 2).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Shrink {
    /// None: frusta keep their initial bounds.
    #[default]
    None,
    /// Ray-AABB: at each leaf, the live rays of every non-terminated frustum
    /// against the leaf's box (per-ray reciprocals computed on the spot); a
    /// frustum none of whose rays hits the box skips the leaf.
    RayAabb,
    /// CR: after a leaf in which a frustum's rays newly became occluded, its
    /// corner rays are recomputed through the 2D bounds (on the light) of its
    /// still-live samples.
    CornerRays,
    /// FS: CR, and the frustum's direction interval (and reciprocals) shrunk
    /// to its live rays too, so traversal culls with the tighter frustum.
    Intervals,
}

impl Shrink {
    /// The four, in the paper's Table 2 order.
    pub const ALL: [Shrink; 4] = [
        Shrink::None,
        Shrink::RayAabb,
        Shrink::CornerRays,
        Shrink::Intervals,
    ];

    /// The paper's row label.
    #[must_use]
    pub fn label(self) -> &'static str {
        match self {
            Shrink::None => "no-shrink",
            Shrink::RayAabb => "ray-aabb",
            Shrink::CornerRays => "cr",
            Shrink::Intervals => "fs",
        }
    }
}

/// Byte offset of row `r`.
const fn at_row(r: usize) -> usize {
    64 * r
}

/// Branch sites.
pub mod site {
    use isa::Site;
    /// Stack empty?
    pub const STACK: Site = isa::sites::MFT.at(0);
    /// Leaf?
    pub const LEAF: Site = isa::sites::MFT.at(1);
    /// Which children are hit (both / one / none)?
    pub const CHILDREN: Site = isa::sites::MFT.at(2);
    /// Left first?
    pub const ORDER: Site = isa::sites::MFT.at(3);
    /// Empty triangle slot?
    pub const SLOT: Site = isa::sites::MFT.at(4);
    /// Any frustum front-facing?
    pub const FRONT: Site = isa::sites::MFT.at(5);
    /// Any frustum left after corner culling?
    pub const CORNER: Site = isa::sites::MFT.at(6);
    /// Next active frustum?
    pub const FRUSTUM: Site = isa::sites::MFT.at(7);
    /// Any ray hits?
    pub const RAY_HIT: Site = isa::sites::MFT.at(8);
    /// Any frustum whose direction interval holds zero?
    pub const ZERO: Site = isa::sites::MFT.at(9);
    /// Next updated frustum?
    pub const UPDATE: Site = isa::sites::MFT.at(10);
    /// Shadow frustum fully occluded?
    pub const DONE: Site = isa::sites::MFT.at(11);
    /// Next active packet (256-ray packets)?
    pub const PACKET: Site = isa::sites::MFT.at(12);
    /// Another triangle block in this leaf?
    pub const BLOCK: Site = isa::sites::MFT.at(13);
    /// Any frustum's rays reach the leaf's box (Ray-AABB)?
    pub const LEAF_BOX: Site = isa::sites::MFT.at(14);
    /// Next frustum to test against the leaf box (Ray-AABB)?
    pub const BOX_FRUSTUM: Site = isa::sites::MFT.at(15);
    /// Next frustum to shrink (CR, FS)?
    pub const SHRINK: Site = isa::sites::MFT.at(16);
    /// Does the set keep one sign per axis (the paper's slab test)?
    pub const ONE_SIGN: Site = isa::sites::MFT.at(17);

    /// Every site of the module (checked for duplicates by the layout test).
    pub const ALL: [Site; 18] = [
        STACK,
        LEAF,
        CHILDREN,
        ORDER,
        SLOT,
        FRONT,
        CORNER,
        FRUSTUM,
        RAY_HIT,
        ZERO,
        UPDATE,
        DONE,
        PACKET,
        BLOCK,
        LEAF_BOX,
        BOX_FRUSTUM,
        SHRINK,
        ONE_SIGN,
    ];
}

pub use rt::stats::MftStats;

/// 16 frusta: primary (a 16 x 16 pixel block, each frustum a 4 x 4 pixel
/// grid, rays through the pixel centres) or shadow (a 4 x 4 pixel group's hit
/// points, 16 light samples each). Rays are `start + delta` in f32.
#[derive(Clone, Debug, PartialEq)]
pub struct Frusta {
    /// Origin of each frustum (one common origin for primary frusta).
    pub org: [[f32; 3]; FRUSTA],
    /// Ray 0 of each frustum.
    pub start: [[f32; 3]; FRUSTA],
    /// Offsets of ray k from ray 0: one set shared by all frusta (primary)
    /// or one set per frustum (shadow).
    pub delta: Vec<[[f32; 3]; FRUSTA]>,
    /// The 4 corner rays bounding each frustum's rays.
    pub corners: [[[f32; 3]; 4]; FRUSTA],
    /// The rays' t limit (shadow rays stop before the light sample).
    pub tmax: f32,
    /// Frusta with rays (bit n); a shadow frustum needs a primary hit.
    pub active: u16,
    /// `Any`: shadow frusta (per-frustum origins, occlusion bits, a frustum
    /// stops once all its rays are occluded); `Closest`: primary frusta.
    pub policy: HitPolicy,
    /// Top-left pixel (of the block or the group).
    pub pixel: (u32, u32),
    /// Shadow frusta: each ray's sample (u, v) on the light.
    pub uv: Vec<[[f32; 2]; FRUSTA]>,
    /// Shadow frusta: the light (corner, edge 1, edge 2).
    pub light: [[f32; 3]; 3],
}

impl Frusta {
    /// The primary frusta of block (`bx`, `by`) (pixels `16 bx ..`, `16 by ..`).
    #[must_use]
    pub fn primary(cam: &scene::scene::Camera, bx: u32, by: u32) -> Frusta {
        let (x0, y0) = (16 * bx, 16 * by);
        let dir = |x: u32, y: u32| cam.ray(f64::from(x) + 0.5, f64::from(y) + 0.5).1;
        let (o, _) = cam.ray(0.5, 0.5);
        let d00 = dir(x0, y0);
        let start: [[f32; 3]; FRUSTA] = std::array::from_fn(|n| {
            let (fx, fy) = (x0 + 4 * (n as u32 % 4), y0 + 4 * (n as u32 / 4));
            dir(fx, fy).map(|c| c as f32)
        });
        // The direction is affine in the pixel, so one delta serves all frusta.
        let delta: [[f32; 3]; FRUSTA] = std::array::from_fn(|k| {
            let d = dir(x0 + k as u32 % 4, y0 + k as u32 / 4);
            [0, 1, 2].map(|a| (d[a] - d00[a]) as f32)
        });
        let mut f = Frusta {
            org: [o.map(|c| c as f32); FRUSTA],
            start,
            delta: vec![delta],
            corners: [[[0.0; 3]; 4]; FRUSTA],
            tmax: f32::INFINITY,
            active: 0xFFFF,
            policy: HitPolicy::Closest,
            pixel: (x0, y0),
            uv: Vec::new(),
            light: [[0.0; 3]; 3],
        };
        // Corner rays: the grid's corner pixels' rays themselves.
        for n in 0..FRUSTA {
            for (c, k) in [0usize, 3, 12, 15].into_iter().enumerate() {
                f.corners[n][c] = f.ray(n, k).1;
            }
        }
        f
    }

    /// The shadow frusta of a 4 x 4 pixel group toward a quad light
    /// (`corner`, `e1`, `e2`): frustum n starts at pixel n's hit point and
    /// holds the rays to its 16 light samples; its corner rays go to the
    /// corners of the samples' 2D bounds on the light, widened by 1e-3 of the
    /// light's extent so the f32 rays stay inside.
    #[must_use]
    pub fn shadow(input: &scene::workload::FrustumInput, light: [[f32; 3]; 3]) -> Frusta {
        let [c0, e1, e2] = light.map(|v| v.map(f64::from));
        let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let mut f = Frusta {
            org: [[0.0; 3]; FRUSTA],
            start: [[1.0; 3]; FRUSTA],
            delta: vec![[[0.0; 3]; FRUSTA]; FRUSTA],
            corners: [[[1.0; 3]; 4]; FRUSTA],
            tmax: 1.0 - 1e-4,
            active: 0,
            policy: HitPolicy::Any,
            pixel: input.pixel,
            uv: vec![[[0.0; 2]; FRUSTA]; FRUSTA],
            light,
        };
        for n in 0..FRUSTA {
            let Some(o) = input.hits[n] else { continue };
            f.active |= 1 << n;
            let smp = &input.samples[n];
            f.org[n] = o;
            f.start[n] = [0, 1, 2].map(|a| smp[0][a] - o[a]);
            for k in 0..FRUSTA {
                f.delta[n][k] = [0, 1, 2].map(|a| smp[k][a] - smp[0][a]);
            }
            // The samples' (u, v) on the light and their bounds.
            let uv = |p: [f32; 3]| {
                let q = [0, 1, 2].map(|a| f64::from(p[a]) - c0[a]);
                (dot(q, e1) / dot(e1, e1), dot(q, e2) / dot(e2, e2))
            };
            let (mut ul, mut uh, mut vl, mut vh) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
            for (k, p) in smp.iter().enumerate() {
                let (u, v) = uv(*p);
                f.uv[n][k] = [u as f32, v as f32];
                (ul, uh, vl, vh) = (ul.min(u), uh.max(u), vl.min(v), vh.max(v));
            }
            let m = f64::from(CORNER_MARGIN);
            let (ul, uh, vl, vh) = (ul - m, uh + m, vl - m, vh + m);
            for (c, (u, v)) in [(ul, vl), (uh, vl), (ul, vh), (uh, vh)]
                .into_iter()
                .enumerate()
            {
                let p = [0, 1, 2].map(|a| c0[a] + u * e1[a] + v * e2[a]);
                f.corners[n][c] = [0, 1, 2].map(|a| (p[a] - f64::from(o[a])) as f32);
            }
        }
        f
    }

    /// Ray `k` of frustum `n` exactly as the kernel generates it.
    #[must_use]
    pub fn ray(&self, n: usize, k: usize) -> ([f32; 3], [f32; 3]) {
        let set = if self.delta.len() == 1 { 0 } else { n };
        let d = [0, 1, 2].map(|a| self.start[n][a] + self.delta[set][k][a]);
        (self.org[n], d)
    }

    /// The pixel of ray `k` of frustum `n` (primary frusta).
    #[must_use]
    pub fn ray_pixel(&self, n: usize, k: usize) -> (u32, u32) {
        (
            self.pixel.0 + 4 * (n as u32 % 4) + k as u32 % 4,
            self.pixel.1 + 4 * (n as u32 / 4) + k as u32 / 4,
        )
    }

    /// The frusta record (see the module table).
    #[must_use]
    pub fn record(&self) -> Vec<f32> {
        let rows = if self.policy.is_any() {
            row::ROWS_SHADOW
        } else {
            row::ROWS
        };
        let mut v = vec![0f32; rows * FRUSTA];
        let mut set = |r: usize, n: usize, x: f32| v[r * FRUSTA + n] = x;
        for n in 0..FRUSTA {
            let rays: Vec<[f32; 3]> = (0..16).map(|k| self.ray(n, k).1).collect();
            for a in 0..3 {
                set(row::ORG + a, n, self.org[n][a]);
                let lo = rays.iter().map(|d| d[a]).fold(f32::INFINITY, f32::min);
                let hi = rays.iter().map(|d| d[a]).fold(f32::NEG_INFINITY, f32::max);
                set(row::DIR_LO + a, n, lo);
                set(row::DIR_HI + a, n, hi);
                // Reciprocal interval, widened by 2^-20 relative on each side so
                // the f32 products of the slab test stay conservative.
                let (rlo, rhi) = if lo > 0.0 || hi < 0.0 {
                    let (p, q) = (1.0 / hi, 1.0 / lo);
                    let w = |x: f32, up: bool| {
                        let e = x.abs() * (1.0 / 1_048_576.0);
                        if up {
                            x + e
                        } else {
                            x - e
                        }
                    };
                    (w(p.min(q), false), w(p.max(q), true))
                } else {
                    (f32::NEG_INFINITY, f32::INFINITY)
                };
                set(row::RCP_LO + a, n, rlo);
                set(row::RCP_HI + a, n, rhi);
                set(row::START + a, n, self.start[n][a]);
                set(row::DELTA + a, n, self.delta[0][n][a]);
                for c in 0..4 {
                    set(row::CORNER + 3 * c + a, n, self.corners[n][c][a]);
                }
                if self.policy.is_any() {
                    for k in 0..FRUSTA {
                        set(row::DELTA_SETS + 3 * n + a, k, self.delta[n][k][a]);
                    }
                }
            }
            if self.policy.is_any() {
                for k in 0..FRUSTA {
                    set(row::UV + 2 * n, k, self.uv[n][k][0]);
                    set(row::UV + 2 * n + 1, k, self.uv[n][k][1]);
                }
            }
            set(row::DIST, n, self.tmax);
        }
        for a in 0..3 {
            for q in 0..4 {
                set(row::ORG_NODE, 4 * a + q, self.org[0][a]);
            }
        }
        set(row::ACTIVE, 0, f32::from_bits(u32::from(self.active)));
        if self.policy.is_any() {
            for (i, c) in self.light.iter().flatten().enumerate() {
                set(row::LIGHT, i, *c);
            }
        }
        v
    }
}

/// The MFT kernel's buffers for one frusta set.
pub struct MftBufs {
    /// The frusta record.
    pub frusta: Buf,
    /// Hits: per frustum a t row and a prim row.
    pub hits: Buf,
    /// Traversal stack: (node u32, frustum mask u32) entries.
    pub stack: Buf,
    /// Per-triangle values read back by broadcast (rows 0-10) and a node's
    /// boxes relative to the common origin (row [`SCRATCH_BOX`]).
    pub scratch: Buf,
    /// Shadow frusta: occlusion bits of each frustum's rays (u32 each).
    pub occl: Buf,
    /// The frusta's hit policy (`Any`: shadow frusta).
    pub policy: HitPolicy,
    /// 256-ray packets (the paper's section 5.2): MFT's frustum traversal
    /// replaced by per-ray box tests of the 16 packets; leaves unchanged.
    pub packets256: bool,
    /// Frustum shrinking (shadow frusta).
    pub shrink: Shrink,
    /// Rays nearly in a triangle's plane.
    pub plane_noise: PlaneNoise,
    /// The slab test of a node's boxes.
    pub slab: SlabTest,
    /// Per-ray reciprocal directions of the 256-ray packet traversal.
    pub rcp: Buf,
    /// Frusta terminated because all their rays were occluded.
    pub terminated: u64,
    /// Counters.
    pub stats: MftStats,
}

impl MftBufs {
    /// Buffers for frusta `f`.
    pub fn new<M: Machine>(m: &mut M, f: &Frusta) -> MftBufs {
        let mut hits = Vec::with_capacity(2 * FRUSTA * FRUSTA);
        for _ in 0..FRUSTA {
            hits.extend(std::iter::repeat_n(f32::INFINITY, FRUSTA));
            hits.extend(std::iter::repeat_n(f32::from_bits(u32::MAX), FRUSTA));
        }
        let sp = m.space();
        MftBufs {
            frusta: {
                let mut rec = f.record();
                rec.resize(row::ROWS_SHADOW * FRUSTA, 0.0);
                sp.alloc_f32(MemKind::Rays, "frusta", &rec, 64)
            },
            hits: sp.alloc_f32(MemKind::Hits, "frusta-hits", &hits, 64),
            stack: sp.alloc(MemKind::Stack, "frusta-stack", 8 * 256, 64),
            scratch: sp.alloc(MemKind::Stack, "frusta-scratch", 64 * (SCRATCH_BOX + 1), 64),
            occl: sp.alloc(MemKind::Hits, "frusta-occlusion", 64, 64),
            policy: f.policy,
            packets256: false,
            shrink: Shrink::None,
            plane_noise: PlaneNoise::Reject,
            slab: SlabTest::Paper,
            rcp: sp.alloc(MemKind::Rays, "packet-rcp", 64 * 48, 64),
            terminated: 0,
            stats: MftStats::default(),
        }
    }

    /// Reuse the buffers for frusta `f` (contents rewritten in place, host
    /// side, like the initial contents); the counters are kept.
    pub fn reload(&mut self, f: &Frusta) {
        let rec: Vec<u8> = f.record().iter().flat_map(|x| x.to_le_bytes()).collect();
        self.frusta.write(0, &rec);
        let mut hits = Vec::with_capacity(2 * FRUSTA * FRUSTA * 4);
        for _ in 0..FRUSTA {
            hits.extend(std::iter::repeat_n(f32::INFINITY.to_le_bytes(), FRUSTA).flatten());
            hits.extend(std::iter::repeat_n(u32::MAX.to_le_bytes(), FRUSTA).flatten());
        }
        self.hits.write(0, &hits);
        self.occl.write(0, &[0u8; 64]);
        self.policy = f.policy;
    }

    /// The hit of ray `k` of frustum `n`.
    #[must_use]
    pub fn hit(&self, n: usize, k: usize) -> Hit {
        let base = 128 * n + 4 * k;
        Hit::from_record(self.hits.f32_at(base), self.hits.u32_at(base + 64))
    }
}

/// Trace 16 frusta through a BVH2 laid out by [`rt::layout::lay_out_bvh2`]:
/// primary frusta to their closest hits, shadow frusta to the occlusion of
/// each ray; `cull_back`: back-face culling (the paper's; front faces only).
///
/// # Panics
/// On machines without 16 lanes.
pub fn trace<M: Machine>(m: &mut M, s: &Bvh2Bufs, b: &mut MftBufs, cull_back: bool) {
    let shadow = b.policy.is_any();
    assert_eq!(M::LANES, FRUSTA, "MFT runs 16 frusta on 16 lanes");
    m.region(Region::Setup);
    let fr = &b.frusta;
    let ld = |m: &mut M, r: usize| m.load(fr, At::off(at_row(r)));
    let rlo = [0, 1, 2].map(|a| ld(m, row::RCP_LO + a));
    let rhi = [0, 1, 2].map(|a| ld(m, row::RCP_HI + a));
    let dlo = [0, 1, 2].map(|a| ld(m, row::DIR_LO + a));
    let dhi = [0, 1, 2].map(|a| ld(m, row::DIR_HI + a));
    let org = [0, 1, 2].map(|a| ld(m, row::ORG + a));
    let org_node = ld(m, row::ORG_NODE);
    let delta = [0, 1, 2].map(|a| ld(m, row::DELTA + a));
    let corner: [[M::F; 3]; 4] =
        std::array::from_fn(|c| [0, 1, 2].map(|a| ld(m, row::CORNER + 3 * c + a)));
    let mut dist = ld(m, row::DIST);
    let zero_v = m.splat(0.0);
    let mut fr_regs = Regs {
        rlo,
        rhi,
        dlo,
        dhi,
        zero_axis: [0, 1, 2].map(|_| m.mask(0)),
        culls: [0, 1, 2].map(|_| m.mask(0)),
        any_zero: [0, 1, 2].map(|_| m.int(0)),
        corner,
        signs: None,
    };
    fr_regs.zero_axes(m);
    let fmax = m.splat(f32::MAX);
    let c = Consts {
        zero_v,
        fmax,
        org,
        org_node,
    };
    // Stack: the root with every active frustum.
    let root = m.int(i64::from(s.root));
    let all = m.s_load(fr, At::off(at_row(row::ACTIVE)), 4, false);
    let mut alive = bits_mask(m, fr, At::off(at_row(row::ACTIVE)));
    m.s_store(&mut b.stack, At::off(0), 4, root);
    m.s_store(&mut b.stack, At::off(4), 4, all);
    let mut sp = m.int(1);
    let p256 = b.packets256;
    if p256 {
        store_ray_rcp(m, b, &delta);
    } else if b.slab == SlabTest::Paper {
        fr_regs.signs = one_sign(m, &fr_regs, all);
    }
    let zero = m.int(0);
    let leaf_flag = m.int(i64::from(LEAF));
    loop {
        m.region(Region::Traversal);
        if !m.branch_if(site::STACK, Cmp::Gt, sp, zero) {
            break;
        }
        sp = m.s_addi(sp, -1);
        let mut node = m.s_load(&b.stack, At::idx(sp, 8, 0), 4, false);
        // Mask register from the stored bits.
        let mut mask = bits_mask(m, &b.stack, At::idx(sp, 8, 4));
        if shadow {
            // Terminated frusta drop out.
            mask = m.kand(mask, alive);
        }
        let mut missed = false;
        loop {
            let lf = m.s_and(node, leaf_flag);
            if m.branch(site::LEAF, lf) {
                break;
            }
            b.stats.aabb_tests += 2;
            let nb = m.s_shift(Shift::Shl, node, 6);
            let next = if p256 {
                packets256_node(m, s, b, (nb, mask), &c, &mut sp)
            } else {
                frusta_node(m, s, b, (nb, mask), (&c, &fr_regs, dist), &mut sp)
            };
            let Some((n, k)) = next else {
                missed = true;
                break;
            };
            (node, mask) = (n, k);
        }
        if missed {
            continue;
        }
        leaf(
            m,
            s,
            b,
            node,
            mask,
            &org,
            &delta,
            &mut fr_regs,
            (&mut dist, &mut alive),
            cull_back,
        );
    }
}

/// Registers a frusta traversal keeps for its whole run.
struct Consts<M: Machine> {
    zero_v: M::F,
    fmax: M::F,
    /// Each frustum's origin, and the common origin laid out per node row.
    org: [M::F; 3],
    org_node: M::F,
}

/// 256-ray packets need every ray's reciprocal direction in memory.
fn store_ray_rcp<M: Machine>(m: &mut M, b: &mut MftBufs, delta: &[M::F; 3]) {
    let (shadow, fr) = (b.policy.is_any(), &b.frusta);
    for n in 0..FRUSTA {
        for a in 0..3 {
            let st = m.load_bcast(fr, At::off(at_row(row::START + a) + 4 * n));
            let dl = if shadow {
                m.load(fr, At::off(at_row(row::DELTA_SETS + 3 * n + a)))
            } else {
                delta[a]
            };
            let d = m.add(st, dl);
            let r = m.rcp(d);
            m.store(&mut b.rcp, At::off(64 * (3 * n + a)), r);
        }
    }
}

/// One inner node for 256-ray packets (section 5.2): each active 16-ray
/// packet against both children, ray by ray; the next node and its mask,
/// `None` when no packet enters a child.
fn packets256_node<M: Machine>(
    m: &mut M,
    s: &Bvh2Bufs,
    b: &mut MftBufs,
    (nb, mask): (M::S, M::K),
    c: &Consts<M>,
    sp: &mut M::S,
) -> Option<(M::S, M::K)> {
    let (shadow, zero_v) = (b.policy.is_any(), c.zero_v);
    // Each active 16-ray packet against both children, ray by ray.
    b.stats.aabb_tests -= 2;
    let zero = m.int(0);
    let (mut lbits, mut rbits) = (m.int(0), m.int(0));
    let mut bits = m.movemask(mask);
    while m.branch_if(site::PACKET, Cmp::Ne, bits, zero) {
        let lane = m.s_tzcnt(bits);
        let n = lane.get() as usize;
        b.stats.aabb_tests += 2;
        let rc = [0, 1, 2].map(|a| m.load(&b.rcp, At::off(64 * (3 * n + a))));
        let frb = &b.frusta;
        let on = [0, 1, 2].map(|a| m.load_bcast(frb, At::off(at_row(row::ORG + a) + 4 * n)));
        // Each ray's far limit: its hit so far (primary), the
        // light sample (shadow).
        let far_n = if shadow {
            m.load_bcast(frb, At::off(at_row(row::DIST) + 4 * n))
        } else {
            m.load(&b.hits, At::off(128 * n))
        };
        for (child, acc) in [(0usize, &mut lbits), (1, &mut rbits)] {
            let mut near = zero_v;
            let mut far = far_n;
            for a in 0..3 {
                let lo_at = 4 * (4 * a + child);
                let hi_at = 4 * (4 * a + 2 + child);
                let lo = m.load_bcast(&s.nodes, At::idx(nb, 1, lo_at));
                let hi = m.load_bcast(&s.nodes, At::idx(nb, 1, hi_at));
                let lo = m.sub(lo, on[a]);
                let hi = m.sub(hi, on[a]);
                let t0 = m.mul(lo, rc[a]);
                let t1 = m.mul(hi, rc[a]);
                let mn = m.min(t0, t1);
                let mx = m.max(t0, t1);
                near = m.max(near, mn);
                far = m.min(far, mx);
            }
            let hit = m.cmp(Cmp::Le, near, far);
            let any = m.any(hit);
            let bit = m.s_shift(Shift::Shl, any, n as u32);
            *acc = m.s_op(isa::SOp::Or, *acc, bit);
        }
        let lm1 = m.s_addi(bits, -1);
        bits = m.s_and(bits, lm1);
    }
    // The packets' masks back into mask registers.
    let hl = m.kmov(lbits);
    let hr = m.kmov(rbits);
    let (l, r, which) = children(m, &s.nodes, nb, lbits, rbits);
    // Both: left first (no per-frustum entry distances here).

    descend(
        m,
        &mut b.stack,
        sp,
        which,
        (l, hl, lbits),
        (r, hr, rbits),
        |_| true,
    )
}

/// One inner node for 16 frusta: interval-arithmetic slab tests of both
/// children for every frustum, the zero-interval fix, then the descent; the
/// next node and its mask, `None` when no frustum enters a child.
fn frusta_node<M: Machine>(
    m: &mut M,
    s: &Bvh2Bufs,
    b: &mut MftBufs,
    (nb, mask): (M::S, M::K),
    (c, fr_regs, dist): (&Consts<M>, &Regs<M>, M::F),
    sp: &mut M::S,
) -> Option<(M::S, M::K)> {
    let shadow = b.policy.is_any();
    let (zero_v, fmax, org, org_node) = (c.zero_v, c.fmax, c.org, c.org_node);
    if !shadow {
        // The paper's `box16 = node - origin4`, kept in memory: each plane
        // is then a broadcast memory operand of its multiply.
        let boxes = m.load(&s.nodes, At::idx(nb, 1, 0));
        let rel = m.sub(boxes, org_node);
        m.store(&mut b.scratch, At::off(64 * SCRATCH_BOX), rel);
    }
    let (nodes, scratch) = (&s.nodes, &b.scratch);
    // A plane relative to each frustum's origin.
    let plane = |m: &mut M, a: usize, max: bool, child: usize| {
        let lane = 4 * a + 2 * usize::from(max) + child;
        if shadow {
            let p = m.load_operand(nodes, At::idx(nb, 1, 4 * lane), 1);
            m.sub(p, org[a])
        } else {
            m.load_operand(scratch, At::off(64 * SCRATCH_BOX + 4 * lane), 1)
        }
    };
    let r = fr_regs;
    let test = |m: &mut M, child: usize| {
        if let Some(pos) = r.signs {
            // The paper's SlabsTest: per axis the near plane (lo for a
            // positive direction, hi for a negative one) times the
            // reciprocal nearest zero's other end, the far plane likewise,
            // as the set's offset table picks them.
            let t = |m: &mut M, a: usize, far: bool| {
                let hi_plane = pos[a] == far;
                let p = plane(m, a, hi_plane, child);
                let rc = if hi_plane { r.rhi[a] } else { r.rlo[a] };
                m.mul(p, rc)
            };
            let (nx, ny, nz) = (t(m, 0, false), t(m, 1, false), t(m, 2, false));
            let (xx, xy, xz) = (t(m, 0, true), t(m, 1, true), t(m, 2, true));
            let min_dist = m.max(nx, ny);
            let min_dist = m.max(min_dist, nz);
            let max_dist = m.min(xx, xy);
            let max_dist = m.min(max_dist, xz);
            let near = m.max(min_dist, zero_v);
            let far = m.min(max_dist, dist);
            let hit = m.cmp(Cmp::Le, near, far);
            return (near, far, m.kand(hit, mask));
        }
        let mut near = zero_v;
        let mut far = dist;
        for a in 0..3 {
            let lo = plane(m, a, false, child);
            let hi = plane(m, a, true, child);
            // Sign-free interval slab: with r in [rlo, rhi] of one sign, the
            // entry is at least min(lo rlo, hi rhi) and the exit at most
            // max(lo rlo, hi rhi) (near is clamped at 0).
            let t0 = m.mul(lo, r.rlo[a]);
            let t1 = m.mul(hi, r.rhi[a]);
            let na = m.min(t0, t1);
            let xa = m.max(t0, t1);
            // An axis whose direction interval holds zero culls nothing:
            // its lanes are masked out.
            near = m.masked(BinOp::Max, r.culls[a], near, near, na);
            far = m.masked(BinOp::Min, r.culls[a], far, far, xa);
        }
        let mut hit = m.cmp(Cmp::Le, near, far);
        hit = m.kand(hit, mask);
        (near, far, hit)
    };
    let (nl, fl_, mut hl) = test(m, 0);
    let (nr, fr_, mut hr) = test(m, 1);
    // The zero-interval fix: on an axis whose direction interval holds
    // zero, the rays reach only o + [near, far] x [dlo, dhi] there.
    // Only the axes where some frustum's interval holds zero (a branch each).
    let r = &fr_regs;
    // A set of one sign per axis has no direction interval holding zero.
    for a in (0..3).filter(|_| r.signs.is_none()) {
        if !m.branch(site::ZERO, r.any_zero[a]) {
            continue;
        }
        for (child, near, far, hit) in [(0, nl, fl_, &mut hl), (1, nr, fr_, &mut hr)] {
            let far_c = m.min(far, fmax);
            let lo = plane(m, a, false, child);
            let hi = plane(m, a, true, child);
            let p0 = m.mul(near, r.dlo[a]);
            let p1 = m.mul(far_c, r.dlo[a]);
            let q0 = m.mul(near, r.dhi[a]);
            let q1 = m.mul(far_c, r.dhi[a]);
            let pmin = m.min(p0, p1);
            let qmax = m.max(q0, q1);
            let below = m.cmp(Cmp::Le, pmin, hi);
            let above = m.cmp(Cmp::Ge, qmax, lo);
            let ok = m.kand(below, above);
            let ok = m.kor(ok, r.culls[a]);
            *hit = m.kand(*hit, ok);
        }
    }
    let lb = m.movemask(hl);
    let rb = m.movemask(hr);
    let (l, r, which) = children(m, &s.nodes, nb, lb, rb);
    // Both: the child any frustum enters first goes first.
    let left_first = |m: &mut M| {
        let lt = m.cmp(Cmp::Lt, nl, nr);
        let both = m.kand(hl, hr);
        let lt = m.kand(lt, both);
        let any = m.any(lt);
        m.branch(site::ORDER, any)
    };

    descend(
        m,
        &mut b.stack,
        sp,
        which,
        (l, hl, lb),
        (r, hr, rb),
        left_first,
    )
}

/// The frusta's bounds held in registers during a trace: reciprocal and
/// direction intervals, sign and zero-interval masks, corner rays. Frustum
/// shrinking (CR, FS) rewrites one frustum's lane.
struct Regs<M: Machine> {
    rlo: [M::F; 3],
    rhi: [M::F; 3],
    dlo: [M::F; 3],
    dhi: [M::F; 3],
    zero_axis: [M::K; 3],
    /// Lanes whose axis culls: its direction interval does not hold zero.
    culls: [M::K; 3],
    /// Per axis: any lane whose interval holds zero (a scalar for the branch).
    any_zero: [M::S; 3],
    corner: [[M::F; 3]; 4],
    /// The paper's slab test: per axis whether every active frustum's
    /// direction is positive (else every one is negative); `None`: the
    /// sign-free test.
    signs: Option<[bool; 3]>,
}

impl<M: Machine> Regs<M> {
    /// The zero-holding axes from the direction intervals.
    fn zero_axes(&mut self, m: &mut M) {
        let zero_v = m.splat(0.0);
        self.zero_axis = [0, 1, 2].map(|a| {
            let l = m.cmp(Cmp::Le, self.dlo[a], zero_v);
            let h = m.cmp(Cmp::Ge, self.dhi[a], zero_v);
            m.kand(l, h)
        });
        self.culls = self.zero_axis.map(|z| m.knot(z));
        self.any_zero = self.zero_axis.map(|z| m.any(z));
    }
}

/// The offset table of the paper's `SlabsTest` for a frusta set: per axis,
/// whether every active frustum (bits `active`) has a positive direction
/// interval (else every one a negative one); `None` (one branch) when some
/// axis has both signs or an interval holding zero.
fn one_sign<M: Machine>(m: &mut M, r: &Regs<M>, active: M::S) -> Option<[bool; 3]> {
    let zero_v = m.splat(0.0);
    let mut ok = m.int(1);
    let mut pos = [false; 3];
    for a in 0..3 {
        let p = m.cmp(Cmp::Gt, r.dlo[a], zero_v);
        let n = m.cmp(Cmp::Lt, r.dhi[a], zero_v);
        let (pb, nb) = (m.movemask(p), m.movemask(n));
        let (pa, na) = (m.s_and(pb, active), m.s_and(nb, active));
        let all_p = m.s_cmp(Cmp::Eq, pa, active);
        let all_n = m.s_cmp(Cmp::Eq, na, active);
        let one = m.s_op(isa::SOp::Or, all_p, all_n);
        ok = m.s_and(ok, one);
        pos[a] = all_p.get() != 0;
    }
    m.branch(site::ONE_SIGN, ok).then_some(pos)
}

/// A mask register from frustum bits stored as a u32 at `at` of `buf`: a
/// scalar load and a move to the mask register (`kmov`).
fn bits_mask<M: Machine>(m: &mut M, buf: &Buf, at: At<M::S>) -> M::K {
    let x = m.s_load(buf, at, 4, false);
    m.kmov(x)
}

/// A BVH2 node's children (at byte `nb` of `nodes`) and which of them the
/// frusta (or packets) in `lbits` / `rbits` reach: 0 none, 1 left, 2 right,
/// 3 both (one recorded branch).
fn children<M: Machine>(
    m: &mut M,
    nodes: &Buf,
    nb: M::S,
    lbits: M::S,
    rbits: M::S,
) -> (M::S, M::S, i64) {
    let zero = m.int(0);
    let l = m.s_load(nodes, At::idx(nb, 1, 48), 4, false);
    let r = m.s_load(nodes, At::idx(nb, 1, 52), 4, false);
    let lnz = m.s_cmp(Cmp::Ne, lbits, zero);
    let rnz = m.s_cmp(Cmp::Ne, rbits, zero);
    let two = m.int(2);
    let rnz2 = m.s_op(isa::SOp::Mul, rnz, two);
    let which = m.s_add(lnz, rnz2);
    let v = which.get();
    m.branch(site::CHILDREN, which);
    (l, r, v)
}

/// The step down from a BVH2 node to the children the frusta (or packets)
/// reach, `which` from [`children`]: one child becomes the next node; of
/// two, the one `left_first` picks goes next and the other (its node and
/// frustum bits) onto the stack; `None` when neither is reached.
fn descend<M: Machine>(
    m: &mut M,
    stack: &mut Buf,
    sp: &mut M::S,
    which: i64,
    (l, hl, lbits): (M::S, M::K, M::S),
    (r, hr, rbits): (M::S, M::K, M::S),
    left_first: impl FnOnce(&mut M) -> bool,
) -> Option<(M::S, M::K)> {
    match which {
        0 => None,
        3 => {
            let (first, fmask, second, sbits) = if left_first(m) {
                (l, hl, r, rbits)
            } else {
                (r, hr, l, lbits)
            };
            m.s_store(stack, At::idx(*sp, 8, 0), 4, second);
            m.s_store(stack, At::idx(*sp, 8, 4), 4, sbits);
            *sp = m.s_addi(*sp, 1);
            Some((first, fmask))
        }
        1 => Some((l, hl)),
        _ => Some((r, hr)),
    }
}

/// Every triangle of leaf `node` against the frusta in `mask`.
#[allow(clippy::too_many_arguments)]
fn leaf<M: Machine>(
    m: &mut M,
    s: &Bvh2Bufs,
    b: &mut MftBufs,
    node: M::S,
    mask: M::K,
    org: &[M::F; 3],
    delta: &[M::F; 3],
    regs: &mut Regs<M>,
    (dist, alive): (&mut M::F, &mut M::K),
    cull_back: bool,
) {
    let shadow = b.policy.is_any();
    m.region(Region::Leaf);
    let mut mask = mask;
    if shadow && b.shrink == Shrink::RayAabb {
        mask = leaf_box_cull(m, s, b, node, mask, *alive);
        let any = m.any(mask);
        if !m.branch(site::LEAF_BOX, any) {
            return;
        }
    }
    let corner = &regs.corner;
    let tris = &s.tris;
    let idx = m.int(i64::from(LEAF_FIRST_MASK));
    let blk = m.s_and(node, idx);
    let bytes = m.int(BLOCK_BYTES as i64);
    let mut bb = m.s_op(isa::SOp::Mul, blk, bytes);
    // Blocks of the leaf after the first (the shallow BVH's large leaves).
    let more = m.s_shift(Shift::Shr, node, LEAF_BLOCKS_SHIFT);
    let seven = m.int(0x7F);
    let mut more = m.s_and(more, seven);
    let zero_v = m.splat(0.0);
    let mut updated = m.int(0);
    'blocks: loop {
        for j in 0..BLOCK {
            let id = m.s_load(tris, At::idx(bb, 1, 32 * 9 + 4 * j), 4, true);
            let zero = m.int(0);
            if m.branch_if(site::SLOT, Cmp::Lt, id, zero) {
                break 'blocks;
            }
            b.stats.tris_accessed += 1;
            let t3 = load_triangle(m, tris, bb, j, org, zero_v);
            let live = if shadow { Some(*alive) } else { None };
            let Some((tmask, edges)) =
                cull_triangle(m, &t3, (mask, live), (corner, zero_v), cull_back)
            else {
                continue;
            };
            b.stats.tris_after_culling += 1;
            store_per_frustum(m, b, &t3, &edges);
            intersect_rays(
                m,
                b,
                &t3,
                (tmask, edges.len()),
                delta,
                zero_v,
                (&mut updated, alive),
            );
        }
        // Next block of the leaf, if any.
        let zero = m.int(0);
        if !m.branch_if(site::BLOCK, Cmp::Gt, more, zero) {
            break;
        }
        more = m.s_addi(more, -1);
        bb = m.s_addi(bb, BLOCK_BYTES as i64);
    }
    if shadow {
        if matches!(b.shrink, Shrink::CornerRays | Shrink::Intervals) {
            shrink(m, b, updated, regs, *alive);
        }
        return;
    }
    update_dist(m, b, updated, dist);
}

/// `p x q` per lane (fmsub form).
fn cross3<M: Machine>(m: &mut M, p: [M::F; 3], q: [M::F; 3]) -> [M::F; 3] {
    let x0 = m.mul(p[2], q[1]);
    let x = m.fmsub(p[1], q[2], x0);
    let y0 = m.mul(p[0], q[2]);
    let y = m.fmsub(p[2], q[0], y0);
    let z0 = m.mul(p[1], q[0]);
    let z = m.fmsub(p[0], q[1], z0);
    [x, y, z]
}

/// `p . q` per lane.
fn dot3<M: Machine>(m: &mut M, p: [M::F; 3], q: [M::F; 3]) -> M::F {
    let d0 = m.mul(p[0], q[0]);
    let d1 = m.fmadd(p[1], q[1], d0);
    m.fmadd(p[2], q[2], d1)
}

/// A triangle's edge normals, one per edge (x, y, z per lane).
type Edges<M> = Vec<[<M as Machine>::F; 3]>;

/// A leaf triangle as every frustum sees it: vertices relative to each
/// frustum's origin, the normal, `a . n` (orientation and distance), where
/// its id is (read, as f32 bits, only when a ray hits it) and the sign
/// masks of `a . n`.
struct LeafTri<'t, M: Machine> {
    a: [M::F; 3],
    bv: [M::F; 3],
    cv: [M::F; 3],
    nrm: [M::F; 3],
    an: M::F,
    /// The triangle block's buffer, the block's byte offset and the slot.
    id_at: (&'t Buf, M::S, usize),
    front: M::K,
    back: M::K,
}

impl<M: Machine> LeafTri<'_, M> {
    /// The triangle's id broadcast to every lane (as f32 bits): read when a
    /// ray hits it, not per triangle.
    fn prim_f(&self, m: &mut M) -> M::F {
        let (tris, bb, j) = self.id_at;
        m.load_bcast(tris, At::idx(bb, 1, 32 * 9 + 4 * j))
    }
}

/// Triangle `j` of the block at byte `bb`, broadcast to all frusta.
fn load_triangle<'t, M: Machine>(
    m: &mut M,
    tris: &'t Buf,
    bb: M::S,
    j: usize,
    org: &[M::F; 3],
    zero_v: M::F,
) -> LeafTri<'t, M> {
    // e2 in registers; e1 (and v0) read at each use as the op's broadcast
    // memory operand (LRBni's {1to16}: no issue slot), so e1 costs no load.
    let at = |k: usize| At::idx(bb, 1, 32 * k + 4 * j);
    let e2 = [6, 7, 8].map(|k| m.load_bcast(tris, at(k)));
    // Vertices relative to each frustum's origin; v0 is read once, as the
    // subtraction's broadcast memory operand.
    let a = [0, 1, 2].map(|i| {
        let v0 = m.load_operand(tris, at(i), 1);
        m.sub(v0, org[i])
    });
    let bv = [0, 1, 2].map(|i| {
        let e1 = m.load_operand(tris, at(3 + i), 1);
        m.add(e1, a[i])
    });
    let cv = [0, 1, 2].map(|i| m.add(a[i], e2[i]));
    // n = e1 x e2 (fmsub form), each e1 component the memory operand of
    // its op: x = e1y e2z - e1z e2y, and so on.
    let nrm = [(2, 1, 1, 2), (0, 2, 2, 0), (1, 0, 0, 1)].map(|(i, j, k, l)| {
        let e = m.load_operand(tris, at(3 + i), 1);
        let t0 = m.mul(e, e2[j]);
        let e = m.load_operand(tris, at(3 + k), 1);
        m.fmsub(e, e2[l], t0)
    });
    let an = dot3(m, a, nrm);
    // Orientation: front faces (origin on the normal's side) have a.n < 0.
    let front = m.cmp(Cmp::Lt, an, zero_v);
    let back = m.cmp(Cmp::Gt, an, zero_v);
    LeafTri {
        a,
        bv,
        cv,
        nrm,
        an,
        id_at: (tris, bb, j),
        front,
        back,
    }
}

/// Back-face culling, then corner-ray culling edge by edge with the paper's
/// early exit: a frustum whose 4 corner rays are all outside one edge misses
/// the triangle, and once no frustum is left the other edges are not
/// computed. The frusta left and the edge normals; `None`: none left.
fn cull_triangle<M: Machine>(
    m: &mut M,
    t3: &LeafTri<'_, M>,
    (mask, alive): (M::K, Option<M::K>),
    (corner, zero_v): (&[[M::F; 3]; 4], M::F),
    cull_back: bool,
) -> Option<(M::K, Edges<M>)> {
    let facing = if cull_back {
        t3.front
    } else {
        m.kor(t3.front, t3.back)
    };
    let mut tmask = m.kand(mask, facing);
    if let Some(alive) = alive {
        tmask = m.kand(tmask, alive);
    }
    let anyf = m.any(tmask);
    if !m.branch(site::FRONT, anyf) {
        return None;
    }
    // Edge normals, one edge at a time; inside a front face: d . e <= 0 for
    // all three.
    let mut edges = Vec::with_capacity(3);
    let (a, bv, cv) = (t3.a, t3.bv, t3.cv);
    for (p, q) in [(a, bv), (bv, cv), (cv, a)] {
        let mut e = cross3(m, p, q);
        if !cull_back {
            // Back faces seen from the origin: flip the edge normal.
            let flip = m.splat(-1.0);
            for c in &mut e {
                let f = m.mul(*c, flip);
                *c = m.select(t3.back, f, *c);
            }
        }
        let mut out = None;
        for c in corner {
            let d = dot3(m, *c, e);
            let o = m.cmp(Cmp::Gt, d, zero_v);
            out = Some(match out {
                None => o,
                Some(p) => m.kand(p, o),
            });
        }
        let keep = m.knot(out.expect("4 corners"));
        tmask = m.kand(tmask, keep);
        edges.push(e);
        let anyc = m.any(tmask);
        if !m.branch(site::CORNER, anyc) {
            return None;
        }
    }
    Some((tmask, edges))
}

/// Per-frustum values the ray tests read back with broadcasts: the edge
/// normals, `a . n`, and the noise floor of `d . E` in f32 (about 4 ulp x
/// |a|^2 x |d| for cross products of two long, nearly parallel vectors),
/// kept squared as (4 eps)^2 |a|^4.
fn store_per_frustum<M: Machine>(
    m: &mut M,
    b: &mut MftBufs,
    t3: &LeafTri<'_, M>,
    edges: &[[M::F; 3]],
) {
    let mut slot = 0;
    let mut keep = |m: &mut M, buf: &mut Buf, v: M::F| {
        m.store(buf, At::off(64 * slot), v);
        slot += 1;
    };
    for e in edges {
        for &c in e {
            keep(m, &mut b.scratch, c);
        }
    }
    keep(m, &mut b.scratch, t3.an);
    if b.plane_noise == PlaneNoise::Keep {
        return;
    }
    let a2 = dot3(m, t3.a, t3.a);
    let a4 = m.mul(a2, a2);
    let k = m.splat((4.0 * f32::EPSILON) * (4.0 * f32::EPSILON));
    let floor = m.mul(a4, k);
    keep(m, &mut b.scratch, floor);
}

/// One 16-wide ray-triangle test per surviving frustum (bitscan over
/// `tmask`), its rays generated from start + delta; closest hits recorded
/// (primary) or occlusion bits set and finished frusta terminated (shadow).
/// `updated` collects the frusta whose bounds must be recomputed.
fn intersect_rays<M: Machine>(
    m: &mut M,
    b: &mut MftBufs,
    t3: &LeafTri<'_, M>,
    (tmask, nedges): (M::K, usize),
    delta: &[M::F; 3],
    zero_v: M::F,
    (updated, alive): (&mut M::S, &mut M::K),
) {
    let shadow = b.policy.is_any();
    let mut bits = m.movemask(tmask);
    b.stats.isec_tests += u64::from(bits.get().count_ones());
    loop {
        let lane = m.s_tzcnt(bits);
        let n = lane.get() as usize;
        // Per-frustum values, each read once: broadcast memory operands.
        let bc = |m: &mut M, buf: &Buf, off: usize| m.load_operand(buf, At::off(off), 1);
        // Rays of frustum n: start[n] + delta (shadow: frustum n's own deltas).
        let d = [0, 1, 2].map(|i| {
            let st = bc(m, &b.frusta, at_row(row::START + i) + 4 * n);
            let dl = if shadow {
                m.load(&b.frusta, At::off(at_row(row::DELTA_SETS + 3 * n + i)))
            } else {
                delta[i]
            };
            m.add(st, dl)
        });
        let mut inside = None;
        for i in 0..nedges {
            let e = [0, 1, 2].map(|c| bc(m, &b.scratch, 64 * (3 * i + c) + 4 * n));
            let sdot = dot3(m, d, e);
            let ok = m.cmp(Cmp::Le, sdot, zero_v);
            inside = Some(match inside {
                None => ok,
                Some(p) => m.kand(p, ok),
            });
        }
        let an_n = bc(m, &b.scratch, 64 * 9 + 4 * n);
        let dn = dot3(m, d, t3.nrm);
        let t = m.div(an_n, dn);
        let ht = 128 * n;
        let pos = m.cmp(Cmp::Gt, t, zero_v);
        let mut hit = m.kand(inside.expect("3 edges"), pos);
        if b.plane_noise == PlaneNoise::Reject {
            // A ray nearly in the triangle's plane: d . n (the sum of the
            // three edge tests) below their rounding noise makes the inside
            // test meaningless; such rays miss.
            let fl = bc(m, &b.scratch, 64 * 10 + 4 * n);
            let d2 = dot3(m, d, d);
            let noise = m.mul(fl, d2);
            let dn2 = m.mul(dn, dn);
            let reliable = m.cmp(Cmp::Gt, dn2, noise);
            hit = m.kand(hit, reliable);
        }
        if shadow {
            // Rays not yet occluded, t below the limit.
            let lim = bc(m, &b.frusta, at_row(row::DIST) + 4 * n);
            let below = m.cmp(Cmp::Lt, t, lim);
            let live = live_rays(m, b, n);
            hit = m.kand(hit, below);
            hit = m.kand(hit, live);
            let any = m.any(hit);
            if m.branch(site::RAY_HIT, any) {
                let prim_f = t3.prim_f(m);
                m.store_masked(hit, &mut b.hits, At::off(ht + 64), prim_f);
                let new = m.movemask(hit);
                let old = m.s_load(&b.occl, At::off(4 * n), 4, false);
                let now = m.s_op(isa::SOp::Or, old, new);
                m.s_store(&mut b.occl, At::off(4 * n), 4, now);
                if matches!(b.shrink, Shrink::CornerRays | Shrink::Intervals) {
                    let bit = m.int(1 << n);
                    *updated = m.s_op(isa::SOp::Or, *updated, bit);
                }
                let full = m.int(0xFFFF);
                if m.branch_if(site::DONE, Cmp::Eq, now, full) {
                    // All 16 rays occluded: the frustum is done.
                    let gone = m.mask(!(1u32 << n) & 0xFFFF);
                    *alive = m.kand(*alive, gone);
                    b.terminated += 1;
                }
            }
        } else {
            let tcur = m.load(&b.hits, At::off(ht));
            let closer = m.cmp(Cmp::Lt, t, tcur);
            hit = m.kand(hit, closer);
            let any = m.any(hit);
            if m.branch(site::RAY_HIT, any) {
                m.store_masked(hit, &mut b.hits, At::off(ht), t);
                let prim_f = t3.prim_f(m);
                m.store_masked(hit, &mut b.hits, At::off(ht + 64), prim_f);
                let bit = m.int(1 << n);
                *updated = m.s_op(isa::SOp::Or, *updated, bit);
            }
        }
        let lm1 = m.s_addi(bits, -1);
        bits = m.s_and(bits, lm1);
        let zero = m.int(0);
        if !m.branch_if(site::FRUSTUM, Cmp::Ne, bits, zero) {
            break;
        }
    }
}

/// Distance bound of each updated primary frustum: its farthest ray hit.
fn update_dist<M: Machine>(m: &mut M, b: &MftBufs, updated: M::S, dist: &mut M::F) {
    let zero = m.int(0);
    let mut bits = updated;
    while m.branch_if(site::UPDATE, Cmp::Ne, bits, zero) {
        let lane = m.s_tzcnt(bits);
        let n = lane.get() as usize;
        let tr = m.load(&b.hits, At::off(128 * n));
        let far = m.reduce(BinOp::Max, tr);
        let farv = m.broadcast(far);
        let k = m.mask(1 << n);
        *dist = m.select(k, farv, *dist);
        let lm1 = m.s_addi(bits, -1);
        bits = m.s_and(bits, lm1);
    }
}

/// The live rays of shadow frustum `n`: lanes whose occlusion bit is clear.
fn live_rays<M: Machine>(m: &mut M, b: &MftBufs, n: usize) -> M::K {
    let occluded = bits_mask(m, &b.occl, At::off(4 * n));
    m.knot(occluded)
}

/// Ray-AABB (Table 2): the live rays of every non-terminated frustum in
/// `mask` against leaf `node`'s box, per-ray reciprocals computed here; the
/// frusta some ray of which reaches the box.
fn leaf_box_cull<M: Machine>(
    m: &mut M,
    s: &Bvh2Bufs,
    b: &mut MftBufs,
    node: M::S,
    mask: M::K,
    alive: M::K,
) -> M::K {
    let boxes = s
        .leaf_boxes
        .as_ref()
        .expect("Ray-AABB reads the leaf boxes of lay_out_bvh2_multi");
    let fm = m.int(i64::from(LEAF_FIRST_MASK));
    let first = m.s_and(node, fm);
    let off = m.s_shift(Shift::Shl, first, 5);
    let lo = [0, 1, 2].map(|a| m.load_bcast(boxes, At::idx(off, 1, 4 * a)));
    let hi = [0, 1, 2].map(|a| m.load_bcast(boxes, At::idx(off, 1, 16 + 4 * a)));
    let tm = m.kand(mask, alive);
    let mut bits = m.movemask(tm);
    let mut keep = m.int(0);
    let zero = m.int(0);
    let zero_v = m.splat(0.0);
    while m.branch_if(site::BOX_FRUSTUM, Cmp::Ne, bits, zero) {
        let lane = m.s_tzcnt(bits);
        let n = lane.get() as usize;
        b.stats.leaf_box_tests += 1;
        b.stats.aabb_tests += 1;
        let fr = &b.frusta;
        let mut near = zero_v;
        let mut far = m.load_bcast(fr, At::off(at_row(row::DIST) + 4 * n));
        for a in 0..3 {
            let st = m.load_bcast(fr, At::off(at_row(row::START + a) + 4 * n));
            let dl = m.load(fr, At::off(at_row(row::DELTA_SETS + 3 * n + a)));
            let d = m.add(st, dl);
            let rc = m.rcp(d);
            let o = m.load_bcast(fr, At::off(at_row(row::ORG + a) + 4 * n));
            let l = m.sub(lo[a], o);
            let h = m.sub(hi[a], o);
            let t0 = m.mul(l, rc);
            let t1 = m.mul(h, rc);
            let mn = m.min(t0, t1);
            let mx = m.max(t0, t1);
            near = m.max(near, mn);
            far = m.min(far, mx);
        }
        let hit = m.cmp(Cmp::Le, near, far);
        let live = live_rays(m, b, n);
        let hit = m.kand(hit, live);
        let any = m.any(hit);
        let bit = m.s_shift(Shift::Shl, any, n as u32);
        keep = m.s_op(isa::SOp::Or, keep, bit);
        let lm1 = m.s_addi(bits, -1);
        bits = m.s_and(bits, lm1);
    }
    let k = m.kmov(keep);
    m.kand(mask, k)
}

/// CR and FS (Table 2), after a leaf: every still-active frustum in
/// `updated` (rays newly occluded here) gets corner rays through the 2D
/// bounds of its live samples on the light (widened by [`CORNER_MARGIN`]);
/// FS also shrinks its direction interval and reciprocals to its live rays.
fn shrink<M: Machine>(m: &mut M, b: &mut MftBufs, updated: M::S, regs: &mut Regs<M>, alive: M::K) {
    let zero = m.int(0);
    let al = m.movemask(alive);
    let mut bits = m.s_and(updated, al);
    let (ninf, pinf) = (m.splat(f32::NEG_INFINITY), m.splat(f32::INFINITY));
    let margin = m.splat(CORNER_MARGIN);
    let zero_v = m.splat(0.0);
    while m.branch_if(site::SHRINK, Cmp::Ne, bits, zero) {
        let lane = m.s_tzcnt(bits);
        let n = lane.get() as usize;
        b.stats.shrinks += 1;
        let live = live_rays(m, b, n);
        let fr = &b.frusta;
        let bound = |m: &mut M, v: M::F| {
            let l = m.select(live, v, pinf);
            let h = m.select(live, v, ninf);
            let l = m.reduce(BinOp::Min, l);
            let h = m.reduce(BinOp::Max, h);
            (m.broadcast(l), m.broadcast(h))
        };
        let u = m.load(fr, At::off(at_row(row::UV + 2 * n)));
        let v = m.load(fr, At::off(at_row(row::UV + 2 * n + 1)));
        let (ul, uh) = bound(m, u);
        let (vl, vh) = bound(m, v);
        let ul = m.sub(ul, margin);
        let uh = m.add(uh, margin);
        let vl = m.sub(vl, margin);
        let vh = m.add(vh, margin);
        let lt = |m: &mut M, i: usize| m.load_bcast(fr, At::off(at_row(row::LIGHT) + 4 * i));
        let c0 = [0, 1, 2].map(|a| lt(m, a));
        let e1 = [0, 1, 2].map(|a| lt(m, 3 + a));
        let e2 = [0, 1, 2].map(|a| lt(m, 6 + a));
        let o = [0, 1, 2].map(|a| m.load_bcast(fr, At::off(at_row(row::ORG + a) + 4 * n)));
        let k = m.mask(1 << n);
        for (c, (uu, vv)) in [(ul, vl), (uh, vl), (ul, vh), (uh, vh)]
            .into_iter()
            .enumerate()
        {
            for a in 0..3 {
                let p = m.fmadd(uu, e1[a], c0[a]);
                let p = m.fmadd(vv, e2[a], p);
                let p = m.sub(p, o[a]);
                regs.corner[c][a] = m.select(k, p, regs.corner[c][a]);
            }
        }
        if b.shrink == Shrink::Intervals {
            let one = m.splat(1.0);
            let dn = m.splat(1.0 - 1.0 / 1_048_576.0);
            let up = m.splat(1.0 + 1.0 / 1_048_576.0);
            for a in 0..3 {
                let st = m.load_bcast(fr, At::off(at_row(row::START + a) + 4 * n));
                let dl = m.load(fr, At::off(at_row(row::DELTA_SETS + 3 * n + a)));
                let d = m.add(st, dl);
                let (lo, hi) = bound(m, d);
                let p = m.div(one, hi);
                let q = m.div(one, lo);
                let small = m.min(p, q);
                let big = m.max(p, q);
                // Widened by 2^-20 relative, as the record's.
                let s0 = m.mul(small, dn);
                let s1 = m.mul(small, up);
                let rl = m.min(s0, s1);
                let b0 = m.mul(big, dn);
                let b1 = m.mul(big, up);
                let rh = m.max(b0, b1);
                let zl = m.cmp(Cmp::Le, lo, zero_v);
                let zh = m.cmp(Cmp::Ge, hi, zero_v);
                let zc = m.kand(zl, zh);
                let rl = m.select(zc, ninf, rl);
                let rh = m.select(zc, pinf, rh);
                regs.rlo[a] = m.select(k, rl, regs.rlo[a]);
                regs.rhi[a] = m.select(k, rh, regs.rhi[a]);
                regs.dlo[a] = m.select(k, lo, regs.dlo[a]);
                regs.dhi[a] = m.select(k, hi, regs.dhi[a]);
            }
            regs.zero_axes(m);
        }
        let lm1 = m.s_addi(bits, -1);
        bits = m.s_and(bits, lm1);
    }
}

/// MFT over frusta sets of a scene (a [`Program`]): every set's rays'
/// (t, prim) in (set, frustum, ray) order (prim >= 0: hit, or occluded for
/// shadow frusta; inactive frusta give misses), and the counters summed.
pub struct FrustaRun<'a> {
    /// The scene.
    pub scene: &'a scene::scene::Scene,
    /// Its BVH2 (the shallow one of the MFT comparison).
    pub bvh: &'a scene::bvh::Bvh2,
    /// The frusta sets.
    pub sets: Vec<Frusta>,
    /// Back-face culling.
    pub cull_back: bool,
    /// Traverse as 256-ray packets instead of frusta (section 5.2).
    pub packets256: bool,
    /// Frustum shrinking of shadow frusta (section 5.3).
    pub shrink: Shrink,
    /// Rays nearly in a triangle's plane (the paper's kernel: `Keep`).
    pub plane_noise: PlaneNoise,
    /// The slab test of a node's boxes.
    pub slab: SlabTest,
}

impl Program for FrustaRun<'_> {
    type Out = (Vec<Hit>, MftStats);
    fn run<M: Machine>(&self, m: &mut M) -> Self::Out {
        run_units(self, m, &self.sets)
    }
}

/// A [`UnitProgram`]'s units in order on one machine, buffers released
/// after each: the hits in order and the counters summed.
fn run_units<P, M>(p: &P, m: &mut M, sets: &[Frusta]) -> (Vec<Hit>, MftStats)
where
    P: UnitProgram<Unit = Frusta, Out = (Vec<Hit>, MftStats)>,
    M: Machine,
{
    let laid = p.lay_out(m);
    let mut out = Vec::with_capacity(sets.len() * FRUSTA * FRUSTA);
    let mut stats = MftStats::default();
    for f in sets {
        let mark = m.space().mark();
        let (hits, st) = p.unit(m, &laid, f);
        m.space().release(mark);
        out.extend(hits);
        stats.add(st);
    }
    (out, stats)
}

/// One frusta set per unit (the MFT renderer's work unit), the scene laid
/// out once ([`FrustaRun::sets`] is not used).
impl UnitProgram for FrustaRun<'_> {
    type Laid = Bvh2Bufs;
    type Unit = Frusta;
    type Out = (Vec<Hit>, MftStats);
    fn lay_out<M: Machine>(&self, m: &mut M) -> Bvh2Bufs {
        rt::layout::lay_out_bvh2_multi(m, &self.scene.mesh, self.bvh)
    }
    fn unit<M: Machine>(&self, m: &mut M, s: &Bvh2Bufs, f: &Frusta) -> Self::Out {
        let mut b = MftBufs::new(m, f);
        b.packets256 = self.packets256;
        b.shrink = self.shrink;
        b.plane_noise = self.plane_noise;
        b.slab = self.slab;
        trace(m, s, &mut b, self.cull_back);
        let hits = (0..FRUSTA)
            .flat_map(|n| (0..FRUSTA).map(move |k| (n, k)))
            .map(|(n, k)| b.hit(n, k))
            .collect();
        (hits, b.stats)
    }
}

impl FrustaRun<'_> {
    /// The rays in output order as the kernel forms them (with each ray's t
    /// limit), and whether each belongs to an active frustum.
    #[must_use]
    pub fn rays(&self) -> (scene::workload::RayStream, Vec<bool>) {
        rays_of(&self.sets)
    }
}

/// The rays of frusta sets in (set, frustum, ray) order, as a stream (a
/// shadow stream for shadow frusta), and whether each ray's frustum is active.
#[must_use]
pub fn rays_of(sets: &[Frusta]) -> (scene::workload::RayStream, Vec<bool>) {
    let (mut o, mut d, mut t, mut act) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for f in sets {
        for n in 0..FRUSTA {
            for k in 0..FRUSTA {
                let (a, b) = f.ray(n, k);
                o.push(a);
                d.push(b);
                t.push(f.tmax);
                act.push(f.active & (1 << n) != 0);
            }
        }
    }
    let kind = if sets.first().is_some_and(|f| f.policy.is_any()) {
        scene::workload::StreamKind::Shadow(0)
    } else {
        scene::workload::StreamKind::Primary
    };
    (scene::workload::RayStream::from_rays(kind, o, d, t), act)
}

/// Rays of active frusta in `sets` whose kernel answer `out` (in
/// [`rays_of`] order) differs from the reference's: closest hits by
/// [`scene::agreement::mismatches_for`], shadow rays by
/// [`scene::agreement::shadow_mismatches_for`], with the tolerance of `test`
/// (the MFT kernel's Pluecker test, the packet baseline's Moller-Trumbore).
#[must_use]
pub fn mismatches_of(
    test: scene::agreement::F32Test,
    label: &str,
    refi: &scene::reference::Reference,
    sets: &[Frusta],
    out: &[Hit],
) -> usize {
    let (sub, keep) = checked_rays(sets);
    let o: Vec<Hit> = keep.iter().map(|&i| out[i]).collect();
    if sub.is_shadow() {
        scene::agreement::shadow_mismatches_for(test, label, refi, &sub, &o)
    } else {
        scene::agreement::mismatches_for(test, label, refi, &sub.org, &sub.dir, &o)
    }
}

/// The rays of active frusta in `sets` as one stream, and their indices in
/// [`rays_of`] order: what [`mismatches_of`] checks.
#[must_use]
pub fn checked_rays(sets: &[Frusta]) -> (scene::workload::RayStream, Vec<usize>) {
    let (st, act) = rays_of(sets);
    let keep: Vec<usize> = (0..st.len()).filter(|&i| act[i]).collect();
    let pick = |v: &[[f32; 3]]| keep.iter().map(|&i| v[i]).collect::<Vec<_>>();
    let sub = scene::workload::RayStream::from_rays(
        st.kind,
        pick(&st.org),
        pick(&st.dir),
        keep.iter().map(|&i| st.tmax[i]).collect(),
    );
    (sub, keep)
}

/// [`mismatches_of`] against the reference's answers computed once for
/// every method tracing the same sets ([`checked_rays`], then
/// [`scene::agreement::Expected::of`]), one ray after another.
#[must_use]
pub fn mismatches_expected(
    test: scene::agreement::F32Test,
    label: &str,
    refi: &scene::reference::Reference,
    (sub, keep, want): (
        &scene::workload::RayStream,
        &[usize],
        &scene::agreement::Expected,
    ),
    out: &[Hit],
) -> usize {
    let o: Vec<Hit> = keep.iter().map(|&i| out[i]).collect();
    scene::agreement::mismatches_expected(test, label, refi, sub, want, &o)
}

/// The 16-ray packet baseline over the same rays (one packet = one frustum's
/// 16 rays: 4 x 4 pixels, or one hit point's 16 shadow rays): Embree-style masked packet traversal of a (deep) BVH2 and
/// packet Moller-Trumbore, [`rt::packet`] on 16 lanes.
pub struct PacketPrimaryRun<'a> {
    /// The scene.
    pub scene: &'a scene::scene::Scene,
    /// Its (deep) BVH2.
    pub bvh: &'a scene::bvh::Bvh2,
    /// The frusta sets whose rays are traced.
    pub sets: Vec<Frusta>,
    /// Back-face culling (front faces only).
    pub cull_back: bool,
    /// Where the packets' leaves read triangles from.
    pub leaves: PacketLeaves,
    /// Rays nearly in a triangle's plane (front faces only: with back-face
    /// culling, `Reject` runs the same robustness test as MFT's, in
    /// Moller-Trumbore's terms: [`rt::single::Sides::FrontNoGrazing`]).
    pub plane_noise: PlaneNoise,
    /// Which 16 rays of a set form one packet.
    pub grouping: PacketGrouping,
}

/// Which 16 of a soft-shadow set's 256 rays the packet baseline traces
/// together (the paper does not say; primary packets are always a
/// frustum's 4 x 4 pixel grid).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PacketGrouping {
    /// Ray k of every frustum: the 4 x 4 pixels' hit points toward their
    /// k-th light sample, as a packet tracer shades its packet of 16 surface
    /// samples one light sample at a time (the paper's "16 shadow rays each
    /// for a packet tracer's 16 surface samples"). The default, a named
    /// assumption; pixels without a hit leave their lanes empty.
    #[default]
    PerSample,
    /// One pixel's 16 rays (a frustum's: one origin, its 16 light samples).
    PerFrustum,
}

/// Where the 16-ray packet baseline's leaves read triangles from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PacketLeaves {
    /// Three vertex indices per triangle, then the vertices (the paper).
    #[default]
    Indexed,
    /// The triangle block's precomputed v0 and edges (as MFT's leaves).
    Edges,
}

impl Program for PacketPrimaryRun<'_> {
    type Out = (Vec<Hit>, MftStats);
    fn run<M: Machine>(&self, m: &mut M) -> Self::Out {
        run_units(self, m, &self.sets)
    }
}

/// One frusta set's rays per unit, as 16-ray packets (one per active
/// frustum); the BVH and triangles laid out once.
impl UnitProgram for PacketPrimaryRun<'_> {
    type Laid = (Bvh2Bufs, rt::packet::TriForm);
    type Unit = Frusta;
    type Out = (Vec<Hit>, MftStats);
    fn lay_out<M: Machine>(&self, m: &mut M) -> Self::Laid {
        assert_eq!(M::LANES, FRUSTA, "16-ray packets on 16 lanes");
        let s = rt::layout::lay_out_bvh2(m, &self.scene.mesh, self.bvh);
        let form = match self.leaves {
            PacketLeaves::Indexed => rt::packet::TriForm::Indexed(std::sync::Arc::new(
                rt::layout::lay_out_indexed(m, &self.scene.mesh),
            )),
            PacketLeaves::Edges => rt::packet::TriForm::Edges,
        };
        (s, form)
    }
    fn unit<M: Machine>(&self, m: &mut M, (s, form): &Self::Laid, f: &Frusta) -> Self::Out {
        let mut hits = vec![Hit::miss(f32::INFINITY); FRUSTA * FRUSTA];
        // One packet per active frustum.
        let live: Vec<usize> = (0..FRUSTA).filter(|&n| f.active & (1 << n) != 0).collect();
        if live.is_empty() {
            return (hits, MftStats::default());
        }
        let (org, dir): (Vec<_>, Vec<_>) = live
            .iter()
            .flat_map(|&n| (0..FRUSTA).map(move |k| f.ray(n, k)))
            .unzip();
        let tfar = vec![f.tmax; org.len()];
        // Room for 16 packets, then filled with this set's rays.
        let full = vec![[0.0f32; 3]; FRUSTA * FRUSTA];
        let tf = vec![0.0f32; FRUSTA * FRUSTA];
        let mut pb = rt::packet::PacketBufs::new(m, &full, &full, &tf, None);
        // Per sample: packet k holds ray k of each live frustum (lane j:
        // the j-th live one); ray j * 16 + k in the order above.
        let per_sample = self.grouping == PacketGrouping::PerSample && f.policy.is_any();
        let by_sample: Option<Vec<u32>> = per_sample.then(|| {
            (0..FRUSTA * FRUSTA)
                .map(|s| {
                    let (k, j) = (s / FRUSTA, s % FRUSTA);
                    if j < live.len() {
                        (j * FRUSTA + k) as u32
                    } else {
                        u32::MAX
                    }
                })
                .collect()
        });
        pb.reload(FRUSTA, &org, &dir, &tfar, by_sample.as_deref());
        pb.sides = match (self.cull_back, self.plane_noise) {
            (true, PlaneNoise::Reject) => Sides::FrontNoGrazing,
            (true, PlaneNoise::Keep) => Sides::Front,
            (false, _) => Sides::Both,
        };
        pb.tri_form = match form {
            rt::packet::TriForm::Indexed(ix) => rt::packet::TriForm::Indexed(ix.clone()),
            rt::packet::TriForm::Edges => rt::packet::TriForm::Edges,
        };
        rt::packet::trace_bvh2(m, s, &mut pb, f.policy);
        for (j, &n) in live.iter().enumerate() {
            for k in 0..FRUSTA {
                hits[n * FRUSTA + k] = pb.hit(FRUSTA, j * FRUSTA + k);
            }
        }
        (hits, pb.frusta_stats)
    }
}
