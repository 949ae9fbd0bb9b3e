//! Single-ray BVH2's inner step over a stream: every ray of a stream
//! against the nodes of a set of BVH2 nodes in turn until one is missed
//! (a miss ends a descent), by the kernel's own step
//! ([`crate::single::bvh2_node`]), so the native backend can be timed
//! against a hand-written `std::arch` twin (`rt/benches/boxtest.rs`).
//!
//! Node, 64 bytes (as [`crate::layout::Bvh2Bufs`]): per axis
//! `[min_l, min_r, max_l, max_r]` (f32), then the children `l`, `r` (u32),
//! then padding. Rays are [`Ray32`] records, broadcast once per ray as the
//! kernel does.
//!
//! Deviation from the kernel's loop: the nodes are visited in order, not
//! by the step's choice, a miss ends the ray instead of popping the stack,
//! and no leaf is tested (the step alone, what the hand-written twin does).

use super::{words, Ray32, SITE_BVH2_NODES, SITE_BVH2_RAYS};
use crate::single::bvh2_node;
use isa::lanes::{fmax, fmin};
use isa::{At, Buf, Cmp, Machine, MemKind, Program, Region, Shift};

/// Bytes of a BVH2 node.
pub const NODE2_BYTES: usize = 64;

/// The step's answer when no child is hit.
pub const MISS: u32 = u32::MAX;

/// One BVH2 node: its two boxes and two children.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Node2 {
    /// Per axis `[min_l, min_r, max_l, max_r]`.
    pub rows: [[f32; 4]; 3],
    /// Left and right child.
    pub children: [u32; 2],
}

impl Node2 {
    /// The node's 16 words as laid out (f32 bits, children, zero padding).
    #[must_use]
    pub fn words(&self) -> [u32; 16] {
        let mut w = [0u32; 16];
        for (a, row) in self.rows.iter().enumerate() {
            for (k, &f) in row.iter().enumerate() {
                w[4 * a + k] = f.to_bits();
            }
        }
        w[12] = self.children[0];
        w[13] = self.children[1];
        w
    }
}

/// What the step does for one ray and node: the next node ([`MISS`] when
/// neither child is hit) and the stack entry pushed, if any.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Step {
    /// The next node.
    pub next: u32,
    /// The farther child and its entry distance, when both are hit.
    pub push: Option<(u32, f32)>,
}

/// Scalar reference of [`crate::single::bvh2_node`] with its arithmetic
/// (`fused`: one rounding per plane, as with FMA) and its order of min/max.
#[must_use]
pub fn bvh2_step_ref(node: &Node2, ray: &Ray32, fused: bool) -> Step {
    let f = &ray.f;
    let (mut tn, mut tf) = ([f[3]; 2], [f[7]; 2]);
    for a in 0..3 {
        let t = node.rows[a].map(|p| {
            if fused {
                p.mul_add(f[a], -f[4 + a])
            } else {
                p * f[a] - f[4 + a]
            }
        });
        for c in 0..2 {
            tn[c] = fmax(tn[c], fmin(t[c], t[c + 2]));
            tf[c] = fmin(tf[c], fmax(t[c], t[c + 2]));
        }
    }
    let [l, r] = node.children;
    match (tn[0] <= tf[0], tn[1] <= tf[1]) {
        (false, false) => Step {
            next: MISS,
            push: None,
        },
        (true, false) => Step {
            next: l,
            push: None,
        },
        (false, true) => Step {
            next: r,
            push: None,
        },
        (true, true) if tn[1] < tn[0] => Step {
            next: r,
            push: Some((l, tn[0])),
        },
        (true, true) => Step {
            next: l,
            push: Some((r, tn[1])),
        },
    }
}

/// Every ray of `rays` (`nrays` [`Ray32`] records) against the `nnodes`
/// nodes of `nodes` in turn up to the first it misses: the step's next
/// node ([`MISS`] for the miss) is stored as u32 `nnodes * ray + node` of
/// `out` (the words after a miss are left as they are); its pushes go to
/// `stack` (8-byte entries: node, entry distance) one after another over
/// the whole run.
pub fn bvh2_nodes_stream<M: Machine>(
    m: &mut M,
    (nodes, nnodes): (&Buf, usize),
    (rays, nrays): (&Buf, usize),
    stack: &mut Buf,
    out: &mut Buf,
) {
    assert!(nnodes > 0 && nrays > 0, "no nodes or rays");
    m.region(Region::Setup);
    let (count, ray_count) = (m.int(nnodes as i64), m.int(nrays as i64));
    let (mut i, mut rb, mut sp) = (m.int(0), m.int(0), m.int(0));
    m.region(Region::CoreLoop);
    // The answers' buffer opened once for the loop's stores.
    let mut out = m.open(out);
    loop {
        let ro = m.s_shift(Shift::Shl, i, 5);
        let bc = |m: &mut M, k: usize| m.load_bcast(rays, At::idx(ro, 1, 4 * k));
        let idir = [bc(m, 0), bc(m, 1), bc(m, 2)];
        let oid = [bc(m, 4), bc(m, 5), bc(m, 6)];
        let (tnear, tfar) = (bc(m, 3), bc(m, 7));
        let (mut j, mut nb, mut ob) = (m.int(0), m.int(0), rb);
        loop {
            let step = bvh2_node(m, nodes, nb, (&idir, &oid, tnear, tfar), stack, &mut sp);
            let Some(next) = step else {
                // A miss ends the descent.
                let miss = m.int(i64::from(MISS));
                m.s_store_open(&mut out, At::idx(ob, 1, 0), 4, miss);
                break;
            };
            m.s_store_open(&mut out, At::idx(ob, 1, 0), 4, next);
            ob = m.s_addi(ob, 4);
            nb = m.s_addi(nb, NODE2_BYTES as i64);
            j = m.s_addi(j, 1);
            if !m.branch_if(SITE_BVH2_NODES, Cmp::Lt, j, count) {
                break;
            }
        }
        rb = m.s_addi(rb, 4 * nnodes as i64);
        i = m.s_addi(i, 1);
        if !m.branch_if(SITE_BVH2_RAYS, Cmp::Lt, i, ray_count) {
            break;
        }
    }
    m.region(Region::Other);
}

/// The BVH2-step workload: nodes and a stream of rays.
#[derive(Clone, Debug)]
pub struct Bvh2Nodes {
    /// The nodes.
    pub nodes: Vec<Node2>,
    /// The rays.
    pub rays: Vec<Ray32>,
}

impl Bvh2Nodes {
    /// A seeded workload of `nnodes` nodes, two boxes each inside
    /// `[-1, 1]^3` (so their overlaps vary), and `nrays` rays from above
    /// toward random points near its centre, reaching through it: a node
    /// test misses about one time in twenty, two in three hit both children.
    #[must_use]
    pub fn generate(nnodes: usize, nrays: usize, seed: u64) -> Bvh2Nodes {
        let mut r = isa::rng::Rng::new(seed);
        let nodes = (0..nnodes)
            .map(|j| {
                let mut rows = [[0f32; 4]; 3];
                for row in &mut rows {
                    for c in 0..2 {
                        let lo = r.range(-1.0, -0.1);
                        row[c] = lo;
                        row[c + 2] = r.range(0.1, 1.0);
                    }
                }
                let j = j as u32;
                Node2 {
                    rows,
                    children: [2 * j + 1, 2 * j + 2],
                }
            })
            .collect();
        let rays = (0..nrays)
            .map(|_| {
                let org = [r.range(-2.0, 2.0), r.range(-2.0, 2.0), r.range(3.0, 5.0)];
                let dir = [
                    r.range(-0.6, 0.6) - org[0],
                    r.range(-0.6, 0.6) - org[1],
                    r.range(-0.6, 0.6) - org[2],
                ];
                Ray32::new(org, dir, 0.0, r.range(1.0, 3.0))
            })
            .collect();
        Bvh2Nodes { nodes, rays }
    }

    /// Ray records as one flat array (8 floats per ray).
    #[must_use]
    pub fn ray_floats(&self) -> Vec<f32> {
        self.rays.iter().flat_map(|r| r.f).collect()
    }

    /// Node words as one flat array (16 per node).
    #[must_use]
    pub fn node_words(&self) -> Vec<u32> {
        self.nodes.iter().flat_map(Node2::words).collect()
    }

    /// Stack words the run can need (2 per push, at most one push per step).
    #[must_use]
    pub fn stack_words(&self) -> usize {
        2 * self.nodes.len() * self.rays.len()
    }

    /// Register nodes, rays, stack and output in `m`'s address space.
    pub fn buffers<M: Machine>(&self, m: &mut M) -> [Buf; 4] {
        let nodes = m
            .space()
            .alloc_u32(MemKind::Nodes, "bvh2-nodes", &self.node_words(), 64);
        let rays = m
            .space()
            .alloc_f32(MemKind::Rays, "rays", &self.ray_floats(), 64);
        let stack = m
            .space()
            .alloc(MemKind::Stack, "stack", 4 * self.stack_words(), 64);
        let out = m.space().alloc(
            MemKind::Hits,
            "next-nodes",
            4 * self.nodes.len() * self.rays.len(),
            64,
        );
        [nodes, rays, stack, out]
    }

    /// The steps by [`bvh2_step_ref`] on zeroed buffers: every ray's next
    /// node per node up to its miss, and the pushes in order as the
    /// stack's words.
    #[must_use]
    pub fn reference(&self, fused: bool) -> (Vec<u32>, Vec<u32>) {
        let mut stack = vec![0u32; self.stack_words()];
        let mut next = vec![0u32; self.nodes.len() * self.rays.len()];
        let mut sp = 0;
        let steps = next.chunks_mut(self.nodes.len());
        for (r, next) in self.rays.iter().zip(steps) {
            for (n, next) in self.nodes.iter().zip(next) {
                let s = bvh2_step_ref(n, r, fused);
                *next = s.next;
                if s.next == MISS {
                    break;
                }
                if let Some((c, d)) = s.push {
                    stack[2 * sp] = c;
                    stack[2 * sp + 1] = d.to_bits();
                    sp += 1;
                }
            }
        }
        (next, stack)
    }
}

impl Program for Bvh2Nodes {
    type Out = (Vec<u32>, Vec<u32>);

    fn params(&self) -> Vec<(String, String)> {
        vec![
            ("nodes".into(), self.nodes.len().to_string()),
            ("rays".into(), self.rays.len().to_string()),
        ]
    }

    /// Every step's next node, and the stack's words.
    fn run<M: Machine>(&self, m: &mut M) -> (Vec<u32>, Vec<u32>) {
        let [nodes, rays, mut stack, mut out] = self.buffers(m);
        let (nn, nr) = (self.nodes.len(), self.rays.len());
        bvh2_nodes_stream(m, (&nodes, nn), (&rays, nr), &mut stack, &mut out);
        (words(&out, nn * nr), words(&stack, self.stack_words()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use isa::FlavourId;

    #[test]
    fn every_flavour_matches_the_reference_traced_and_native() {
        let mut w = Bvh2Nodes::generate(8, 32, 11);
        // Degenerate cases: +-0 direction components (1/d = +-inf), a box
        // flat in x with the ray in its plane.
        w.nodes[0].rows[0] = [0.0, -0.5, 0.0, 0.5];
        w.rays[0] = Ray32::new([0.0, 0.1, 5.0], [0.0, 0.0, -1.0], 0.0, 100.0);
        w.rays[1] = Ray32::new([0.0, 0.1, 5.0], [-0.0, 0.0, -1.0], 0.0, 100.0);
        for fl in FlavourId::ALL {
            let want = w.reference(fl != FlavourId::Sse4);
            let (t, got) = isa::record(&w, fl, "bvh2-nodes");
            t.validate().unwrap();
            assert_eq!(got, want, "{fl} traced");
            assert_eq!(isa::run_native(&w, fl), want, "{fl} native");
        }
        let (next, stack) = w.reference(true);
        let miss = next.iter().filter(|&&n| n == MISS).count();
        let both = stack.chunks(2).filter(|e| e[0] != 0).count();
        let steps = next.iter().filter(|&&n| n != 0).count();
        assert!(
            miss > 8 && both > steps / 4 && steps - miss - both > steps / 8,
            "misses {miss}, both children {both} of {steps} steps"
        );
    }
}
