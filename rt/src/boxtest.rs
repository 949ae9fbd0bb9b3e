//! Ray stream vs the 4 child boxes of one BVH4 node: the inner test of the
//! DRS core loop, used to check the native backend's speed against
//! hand-written AVX2 and as the default `rtsim run` workload.
//!
//! Layouts (as the DRS paper, section 5):
//! - node, 96 bytes, SoA over the 4 children:
//!   `min_x[4] max_x[4] min_y[4] max_y[4] min_z[4] max_z[4]` (f32).
//! - traversal ray, 32 bytes: `idir.x idir.y idir.z t_near | org.x*idir.x
//!   org.y*idir.y org.z*idir.z t_far` (origin premultiplied by the inverse
//!   direction, so each slab is one fmsub).
//!
//! Each iteration tests LANES/4 rays against the 4 boxes, one ray per 128-bit
//! block (the paper's "4-wide single-ray test over two rays" on AVX2).
//! Deviation from the paper: slab near/far come from min/max of the two
//! planes, not from a blend on the direction sign; rays are read in stream
//! order, not through ray pointer lists (the DRS kernel, issue 5, does that).

pub mod bvh2;

use crate::packet::{slab_test, PacketSlabs};
use isa::lanes::{fmax, fmin};
use isa::{At, Buf, Cmp, Machine, MemKind, Program, Region, Shift, Site};

/// Loop-back branch of the ray loop.
pub const SITE_RAYS: Site = isa::sites::BOXTEST.at(0);

/// Loop-back branch of the packet-vs-nodes loop.
pub const SITE_NODES: Site = isa::sites::BOXTEST.at(1);

/// Loop-back branch of the BVH2-step stream's ray loop.
pub const SITE_BVH2_RAYS: Site = isa::sites::BOXTEST.at(2);

/// Loop-back branch of the BVH2-step stream's node loop.
pub const SITE_BVH2_NODES: Site = isa::sites::BOXTEST.at(3);

/// Every branch site of the module (checked for duplicates by the layout test).
pub const SITES: [Site; 4] = [SITE_RAYS, SITE_NODES, SITE_BVH2_RAYS, SITE_BVH2_NODES];
/// Bytes of a node.
pub const NODE_BYTES: usize = 96;
/// Bytes of a traversal ray.
pub const RAY_BYTES: usize = 32;

/// One BVH4 node's 4 child boxes, SoA.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Node4 {
    /// `min_x[4] max_x[4] min_y[4] max_y[4] min_z[4] max_z[4]`.
    pub f: [f32; 24],
}

/// A traversal ray: `idir.xyz, t_near, org.xyz * idir.xyz, t_far`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray32 {
    /// The 8 floats.
    pub f: [f32; 8],
}

impl Ray32 {
    /// From origin, direction and the [t_near, t_far] interval.
    #[must_use]
    pub fn new(org: [f32; 3], dir: [f32; 3], t_near: f32, t_far: f32) -> Ray32 {
        let idir = dir.map(|d| 1.0 / d);
        Ray32 {
            f: [
                idir[0],
                idir[1],
                idir[2],
                t_near,
                org[0] * idir[0],
                org[1] * idir[1],
                org[2] * idir[2],
                t_far,
            ],
        }
    }
}

/// Scalar reference: bit `c` set if the ray overlaps child `c`, with the
/// kernel's exact arithmetic (`fused`: one rounding per slab, as with FMA).
#[must_use]
pub fn box4_ref(node: &Node4, ray: &Ray32, fused: bool) -> u8 {
    let mut bits = 0u8;
    for c in 0..4 {
        let slab = |axis: usize| {
            let (lo, hi) = (node.f[8 * axis + c], node.f[8 * axis + 4 + c]);
            let (id, oid) = (ray.f[axis], ray.f[4 + axis]);
            let f = |b: f32| {
                if fused {
                    b.mul_add(id, -oid)
                } else {
                    b * id - oid
                }
            };
            let (t0, t1) = (f(lo), f(hi));
            (fmin(t0, t1), fmax(t0, t1))
        };
        let (nx, fx) = slab(0);
        let (ny, fy) = slab(1);
        let (nz, fz) = slab(2);
        // The kernel's order: NaN slabs (0 * inf) make min/max order-dependent.
        let tn = fmax(fmax(fmax(ray.f[3], nx), ny), nz);
        let tf = fmin(fmin(fmin(ray.f[7], fx), fy), fz);
        if tn <= tf {
            bits |= 1 << c;
        }
    }
    bits
}

/// Lane patterns, as constants so the native backend folds every permute
/// into one shuffle instruction (runtime patterns cost a lookup per lane).
pub struct Pat<const N: usize>;

impl<const N: usize> Pat<N> {
    /// dirNear of ray i/4 into block i/4 (permute2f128 0x20 on AVX2).
    pub const DIR_NEAR: [u8; N] = half_pattern::<N>(0);
    /// orgFar of ray i/4 into block i/4 (permute2f128 0x31 on AVX2).
    pub const ORG_FAR: [u8; N] = half_pattern::<N>(4);
    /// Whether DIR_NEAR is the first load itself (one ray per vector).
    pub const DN_ID: bool = is_identity(&Self::DIR_NEAR, 0);
    /// Whether ORG_FAR is the second load itself.
    pub const OF_ID: bool = is_identity(&Self::ORG_FAR, N);
    /// Swap siblings within each block: lanes 1,0,3,2 (c0 <-> c1, c2 <-> c3).
    pub const SWAP_PAIRS: [u8; N] = xor_pattern::<N>(1);
    /// Swap child pairs within each block: lanes 2,3,0,1 ({c0,c1} <-> {c2,c3}).
    pub const SWAP_GROUPS: [u8; N] = xor_pattern::<N>(2);
    /// Broadcast element k within each 128-bit block (vpermilps).
    pub const SPLAT: [[u8; N]; 4] = [
        splat_pattern::<N>(0),
        splat_pattern::<N>(1),
        splat_pattern::<N>(2),
        splat_pattern::<N>(3),
    ];
}

/// Lane i takes lane i ^ d.
const fn xor_pattern<const N: usize>(d: usize) -> [u8; N] {
    let mut p = [0u8; N];
    let mut i = 0;
    while i < N {
        p[i] = (i ^ d) as u8;
        i += 1;
    }
    p
}

/// Lane i of the result takes element `8 * (i / 4) + base + i % 4` of the
/// concatenated loads (ray i/4's first or second half).
const fn half_pattern<const N: usize>(base: usize) -> [u8; N] {
    let mut p = [0u8; N];
    let mut i = 0;
    while i < N {
        p[i] = (8 * (i / 4) + base + i % 4) as u8;
        i += 1;
    }
    p
}

/// Lane i takes lane `4 * (i / 4) + k` (broadcast element k within each block).
const fn splat_pattern<const N: usize>(k: usize) -> [u8; N] {
    let mut p = [0u8; N];
    let mut i = 0;
    while i < N {
        p[i] = (4 * (i / 4) + k) as u8;
        i += 1;
    }
    p
}

const fn is_identity(p: &[u8], offset: usize) -> bool {
    let mut i = 0;
    while i < p.len() {
        if p[i] as usize != i + offset {
            return false;
        }
        i += 1;
    }
    true
}

/// Bytes of hit bits per group of LANES/4 rays (4 bits per ray).
#[must_use]
pub const fn mask_bytes(lanes: usize) -> usize {
    if lanes >= 8 {
        lanes / 8
    } else {
        1
    }
}

/// Test rays `[0, nrays)` of `rays` against `node`. Each group of LANES/4 rays
/// stores its movemask (4 bits per ray, ray j in bits 4j..4j+4) as one
/// little-endian integer of [`mask_bytes`] bytes at `g * mask_bytes` in `out`.
/// `nrays` must be a multiple of LANES/4.
pub fn box4_stream<M: Machine, const N: usize>(
    m: &mut M,
    node: &Buf,
    rays: &Buf,
    nrays: usize,
    out: &mut Buf,
) {
    assert_eq!(M::LANES, N, "lane count");
    let per = N / 4;
    assert!(
        nrays.is_multiple_of(per) && nrays > 0,
        "{nrays} rays is not a multiple of {per}"
    );
    m.region(Region::Setup);
    let zero = m.int(0);
    let b: [M::F; 6] = std::array::from_fn(|k| m.load_repeat(node, At::idx(zero, 1, 16 * k), 4));
    let dn = &Pat::<N>::DIR_NEAR;
    let of = &Pat::<N>::ORG_FAR;
    let sp = &Pat::<N>::SPLAT;
    let (dn_id, of_id) = (Pat::<N>::DN_ID, Pat::<N>::OF_ID);
    let mut ray = m.int(0);
    let groups = m.int((nrays / per) as i64);
    let mut g = m.int(0);
    m.region(Region::CoreLoop);
    loop {
        // ray = g * per; the byte offset of the group is ray * 32.
        let off = m.s_shift(Shift::Shl, ray, 5);
        let l0 = m.loadu(rays, At::idx(off, 1, 0));
        let l1 = m.loadu(rays, At::idx(off, 1, 4 * N));
        let dir_near = if dn_id { l0 } else { m.shuffle2(l0, l1, dn) };
        let org_far = if of_id { l1 } else { m.shuffle2(l0, l1, of) };
        let d = [
            m.permute(dir_near, &sp[0]),
            m.permute(dir_near, &sp[1]),
            m.permute(dir_near, &sp[2]),
        ];
        let o = [
            m.permute(org_far, &sp[0]),
            m.permute(org_far, &sp[1]),
            m.permute(org_far, &sp[2]),
        ];
        let near = m.permute(dir_near, &sp[3]);
        let far = m.permute(org_far, &sp[3]);
        let mut tn = near;
        let mut tf = far;
        for a in 0..3 {
            let t0 = m.fmsub(b[2 * a], d[a], o[a]);
            let t1 = m.fmsub(b[2 * a + 1], d[a], o[a]);
            let lo = m.min(t0, t1);
            let hi = m.max(t0, t1);
            tn = m.max(tn, lo);
            tf = m.min(tf, hi);
        }
        let hit = m.cmp(Cmp::Le, tn, tf);
        let bits = m.movemask(hit);
        let w = mask_bytes(N);
        m.s_store(out, At::idx(g, w as u8, 0), w as u8, bits);
        ray = m.s_addi(ray, per as i64);
        g = m.s_addi(g, 1);
        if !m.branch_if(SITE_RAYS, Cmp::Lt, g, groups) {
            break;
        }
    }
    m.region(Region::Other);
}

/// The packet kernels' inner step: one packet of LANES rays (`packet`:
/// rows idir.x idir.y idir.z oid.x oid.y oid.z t_near t_far of LANES floats)
/// against the 4 child boxes of each of `nnodes` BVH4 nodes (rows as
/// [`Node4`], 96 bytes apart), by the packet kernels' own box test
/// ([`slab_test`], each plane a broadcast load). The hit mask of node `j`'s
/// child `c` (bit i = lane i) is stored as the little-endian u32 `4 * j + c`
/// of `out`.
/// Deviation from the kernel's loop: no child order, push or early exit, the
/// test alone (what the hand-written twin in `rt/benches/boxtest.rs` does).
pub fn packet_nodes_stream<M: Machine>(
    m: &mut M,
    nodes: &Buf,
    nnodes: usize,
    packet: &Buf,
    out: &mut Buf,
) {
    assert!(nnodes > 0, "no nodes");
    m.region(Region::Setup);
    let zero = m.int(0);
    let row = |m: &mut M, r: usize| m.load(packet, At::idx(zero, 1, 4 * M::LANES * r));
    let pk = PacketSlabs {
        idir: [0, 1, 2].map(|a| row(m, a)),
        oid: [3, 4, 5].map(|a| row(m, a)),
        tnear: row(m, 6),
        tfar: row(m, 7),
    };
    let count = m.int(nnodes as i64);
    let (mut j, mut nb, mut ob) = (m.int(0), m.int(0), m.int(0));
    m.region(Region::CoreLoop);
    // The masks' buffer opened once for the loop's stores.
    let mut out = m.open(out);
    loop {
        for c in 0..4 {
            let plane =
                |m: &mut M, r: usize| m.load_operand(nodes, At::idx(nb, 1, 16 * r + 4 * c), 1);
            let (_, hit) = slab_test(m, &pk, plane);
            let bits = m.movemask(hit);
            m.s_store_open(&mut out, At::idx(ob, 1, 4 * c), 4, bits);
        }
        nb = m.s_addi(nb, NODE_BYTES as i64);
        ob = m.s_addi(ob, 16);
        j = m.s_addi(j, 1);
        if !m.branch_if(SITE_NODES, Cmp::Lt, j, count) {
            break;
        }
    }
    m.region(Region::Other);
}

/// Scalar reference of [`packet_nodes_stream`] for one child box and ray:
/// whether the ray (`slabs`: idir.xyz, oid.xyz, t_near, t_far) overlaps
/// child `c` of `node`, with the kernel's arithmetic and order.
#[must_use]
pub fn packet_box_ref(node: &Node4, c: usize, slabs: &[f32; 8], fused: bool) -> bool {
    let (mut near, mut far) = (slabs[6], slabs[7]);
    for a in 0..3 {
        let f = |b: f32| {
            if fused {
                b.mul_add(slabs[a], -slabs[3 + a])
            } else {
                b * slabs[a] - slabs[3 + a]
            }
        };
        let (t0, t1) = (f(node.f[8 * a + c]), f(node.f[8 * a + 4 + c]));
        near = fmax(near, fmin(t0, t1));
        far = fmin(far, fmax(t0, t1));
    }
    near <= far
}

/// The packet-vs-nodes workload: `nodes` BVH4 nodes and one packet of 8 rays
/// (the box stream's rays, aimed at the first node's boxes).
#[derive(Clone, Debug)]
pub struct PacketNodes {
    /// The nodes.
    pub nodes: Vec<Node4>,
    /// The packet's rays.
    pub rays: [Ray32; 8],
}

impl PacketNodes {
    /// A seeded workload of `n` nodes.
    #[must_use]
    pub fn generate(n: usize, seed: u64) -> PacketNodes {
        let nodes: Vec<Node4> = (0..n)
            .map(|j| BoxStream::generate(0, seed.wrapping_add(j as u64)).node)
            .collect();
        let first = BoxStream::generate(8, seed);
        let rays = std::array::from_fn(|i| first.rays[i]);
        PacketNodes { nodes, rays }
    }

    /// Ray `i`'s slab inputs: idir.xyz, oid.xyz, t_near, t_far.
    #[must_use]
    pub fn slabs(&self, i: usize) -> [f32; 8] {
        let f = &self.rays[i].f;
        [f[0], f[1], f[2], f[4], f[5], f[6], f[3], f[7]]
    }

    /// The packet's rows for `lanes` lanes (rays past 8 repeat).
    #[must_use]
    pub fn packet_rows(&self, lanes: usize) -> Vec<f32> {
        (0..8)
            .flat_map(|r| (0..lanes).map(move |i| (r, i)))
            .map(|(r, i)| self.slabs(i % 8)[r])
            .collect()
    }

    /// Register the nodes, the packet and the output in `m`'s address space.
    pub fn buffers<M: Machine>(&self, m: &mut M) -> (Buf, Buf, Buf) {
        let flat: Vec<f32> = self.nodes.iter().flat_map(|n| n.f).collect();
        let nodes = m.space().alloc_f32(MemKind::Nodes, "bvh4-nodes", &flat, 64);
        let rows = self.packet_rows(M::LANES);
        let packet = m.space().alloc_f32(MemKind::Rays, "packet", &rows, 64);
        let out = m
            .space()
            .alloc(MemKind::Hits, "hit-masks", 16 * self.nodes.len(), 64);
        (nodes, packet, out)
    }

    /// The child masks [`packet_nodes_stream`] stored in `out`.
    #[must_use]
    pub fn masks(&self, out: &Buf) -> Vec<u32> {
        words(out, 4 * self.nodes.len())
    }

    /// Every node's child masks by [`packet_box_ref`] for `lanes` lanes.
    #[must_use]
    pub fn reference(&self, lanes: usize, fused: bool) -> Vec<u32> {
        let slabs: Vec<[f32; 8]> = (0..8).map(|i| self.slabs(i)).collect();
        let mask = |n: &Node4, c| {
            (0..lanes)
                .filter(|&i| packet_box_ref(n, c, &slabs[i % 8], fused))
                .fold(0u32, |b, i| b | 1 << i)
        };
        let per_node = |n| (0..4).map(move |c| mask(n, c));
        self.nodes.iter().flat_map(per_node).collect()
    }
}

impl Program for PacketNodes {
    type Out = Vec<u32>;

    fn params(&self) -> Vec<(String, String)> {
        vec![("nodes".into(), self.nodes.len().to_string())]
    }

    /// Each node's 4 child masks.
    fn run<M: Machine>(&self, m: &mut M) -> Vec<u32> {
        let (nodes, packet, mut out) = self.buffers(m);
        packet_nodes_stream(m, &nodes, self.nodes.len(), &packet, &mut out);
        self.masks(&out)
    }
}

/// The ray-vs-4-boxes workload: a node and a stream of rays.
#[derive(Clone, Debug)]
pub struct BoxStream {
    /// The node.
    pub node: Node4,
    /// The rays.
    pub rays: Vec<Ray32>,
}

impl BoxStream {
    /// A seeded workload: a node with 4 boxes in the unit cube and `n` rays
    /// from outside toward it, some missing.
    #[must_use]
    pub fn generate(n: usize, seed: u64) -> BoxStream {
        let mut r = isa::rng::Rng::new(seed);
        let mut f = [0f32; 24];
        for c in 0..4 {
            for axis in 0..3 {
                let lo = r.range(-1.0, 0.6);
                let hi = lo + r.range(0.05, 0.8);
                f[8 * axis + c] = lo;
                f[8 * axis + 4 + c] = hi;
            }
        }
        let rays = (0..n)
            .map(|_| {
                let org = [r.range(-4.0, 4.0), r.range(-4.0, 4.0), r.range(3.0, 5.0)];
                // Aim near a random child box so about half the tests hit.
                let c = r.below(4) as usize;
                let target: [f32; 3] = std::array::from_fn(|a| {
                    let (lo, hi) = (f[8 * a + c], f[8 * a + 4 + c]);
                    r.range(lo - 0.3, hi + 0.3)
                });
                let dir = [target[0] - org[0], target[1] - org[1], target[2] - org[2]];
                Ray32::new(org, dir, 0.0, r.range(0.5, 2.0))
            })
            .collect();
        BoxStream {
            node: Node4 { f },
            rays,
        }
    }

    /// Register the node, rays and output buffers in `m`'s address space.
    pub fn buffers<M: Machine>(&self, m: &mut M) -> (Buf, Buf, Buf) {
        let node = m
            .space()
            .alloc_f32(MemKind::Nodes, "bvh4-node", &self.node.f, 64);
        let flat: Vec<f32> = self.rays.iter().flat_map(|r| r.f).collect();
        let rays = m.space().alloc_f32(MemKind::Rays, "rays", &flat, 64);
        let out = m
            .space()
            .alloc(MemKind::Hits, "hit-masks", self.rays.len(), 64);
        (node, rays, out)
    }
}

impl Program for BoxStream {
    type Out = Vec<u8>;

    fn params(&self) -> Vec<(String, String)> {
        vec![("rays".into(), self.rays.len().to_string())]
    }

    /// Each ray's 4 hit bits, one byte per ray.
    fn run<M: Machine>(&self, m: &mut M) -> Vec<u8> {
        let (node, rays, mut out) = self.buffers(m);
        match M::LANES {
            4 => box4_stream::<M, 4>(m, &node, &rays, self.rays.len(), &mut out),
            8 => box4_stream::<M, 8>(m, &node, &rays, self.rays.len(), &mut out),
            16 => box4_stream::<M, 16>(m, &node, &rays, self.rays.len(), &mut out),
            32 => box4_stream::<M, 32>(m, &node, &rays, self.rays.len(), &mut out),
            n => panic!("{n} lanes"),
        }
        unpack_masks(out.bytes(), M::LANES, self.rays.len())
    }
}

/// The first `n` little-endian u32 words of a buffer.
#[must_use]
pub fn words(b: &Buf, n: usize) -> Vec<u32> {
    b.bytes()[..4 * n]
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect()
}

/// Per-ray hit bits from the group masks `box4_stream` stores.
#[must_use]
pub fn unpack_masks(out: &[u8], lanes: usize, nrays: usize) -> Vec<u8> {
    let w = mask_bytes(lanes);
    let per = lanes / 4;
    (0..nrays)
        .map(|r| {
            let g = r / per;
            let v = out[w * g..w * g + w]
                .iter()
                .rev()
                .fold(0u32, |v, &b| (v << 8) | u32::from(b));
            ((v >> (4 * (r % per))) & 15) as u8
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use isa::FlavourId;

    #[test]
    fn every_flavour_matches_the_reference_traced_and_native() {
        let w = BoxStream::generate(256, 3);
        for fl in FlavourId::ALL {
            let fused = fl != FlavourId::Sse4;
            let want: Vec<u8> = w.rays.iter().map(|r| box4_ref(&w.node, r, fused)).collect();
            let (t, got) = isa::record(&w, fl, "boxtest");
            t.validate().unwrap();
            assert_eq!(got, want, "{fl} traced");
            assert_eq!(isa::run_native(&w, fl), want, "{fl} native");
        }
        let hits: usize = w
            .rays
            .iter()
            .map(|r| box4_ref(&w.node, r, true).count_ones() as usize)
            .sum();
        assert!(
            hits > 100 && hits < 900,
            "a mix of hits and misses: {hits} of 1024"
        );
    }

    #[test]
    fn packet_nodes_match_the_reference_traced_and_native() {
        let w = PacketNodes::generate(64, 9);
        for fl in FlavourId::ALL {
            let fused = fl != FlavourId::Sse4;
            let want = w.reference(fl.lanes(), fused);
            let (t, got) = isa::record(&w, fl, "packet-nodes");
            t.validate().unwrap();
            assert_eq!(got, want, "{fl} traced");
            assert_eq!(isa::run_native(&w, fl), want, "{fl} native");
        }
        let hits: u32 = w.reference(8, true).iter().map(|b| b.count_ones()).sum();
        assert!(
            hits > 64 && hits < 8 * 64 * 4 - 64,
            "a mix of hits and misses: {hits} of 2048"
        );
    }

    #[test]
    fn axis_parallel_and_degenerate_rays() {
        // +-0 direction components (1/d = +-inf), origin on a box face, a flat box.
        let mut w = BoxStream::generate(16, 5);
        w.node.f[0] = 0.0; // child 0: min_x = max_x = 0 (flat in x)
        w.node.f[4] = 0.0;
        w.rays[0] = Ray32::new([0.0, 0.1, 5.0], [0.0, 0.0, -1.0], 0.0, 100.0);
        w.rays[1] = Ray32::new([0.0, 0.1, 5.0], [-0.0, 0.0, -1.0], 0.0, 100.0);
        w.rays[2] = Ray32::new([-5.0, 0.1, 0.1], [1.0, 0.0, 0.0], 0.0, 100.0);
        for fl in FlavourId::ALL {
            let fused = fl != FlavourId::Sse4;
            let want: Vec<u8> = w.rays.iter().map(|r| box4_ref(&w.node, r, fused)).collect();
            assert_eq!(isa::run_native(&w, fl), want, "{fl}");
            assert_eq!(isa::record(&w, fl, "b").1, want, "{fl}");
        }
    }

    #[test]
    fn avx2_core_loop_is_the_drs_shape() {
        let w = BoxStream::generate(8, 1);
        let (t, _) = isa::record(&w, FlavourId::Avx2, "boxtest");
        let core: Vec<_> = t
            .ops
            .iter()
            .filter(|o| o.region == Region::CoreLoop)
            .collect();
        // 4 iterations of 2 rays: 2 loads, 2 vperm (permute2f128), 8 in-lane shuffles,
        // 6 fmsub, 12 min/max, 1 cmp, 1 movemask, 1 store of the mask, 1 shl,
        // and the loop's 2 adds, cmp, branch: 38.
        assert_eq!(core.len(), 4 * 38);
        let fmas = core
            .iter()
            .filter(|o| o.class == isa::OpClass::VFma)
            .count();
        assert_eq!(fmas, 4 * 6);
    }
}
