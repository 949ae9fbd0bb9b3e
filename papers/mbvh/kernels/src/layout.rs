//! An MBVH of `W` children per node laid out in simulated memory, as the
//! MBVH kernels read it (`W` = the machine's lanes: 4 on SSE, 16 on LRBni
//! and AVX-512).
//!
//! | structure | record | fields |
//! |---|---|---|
//! | node | `32 W` bytes | rows of `W` f32: `min_x max_x min_y max_y min_z max_z` (the "box packet", SoA); row 6: `child[W]` u32; row 7: `valid` (bit c: child c exists), pad |
//! | triangle block | `40 W` bytes | rows of `W`: `v0x v0y v0z e1x e1y e1z e2x e2y e2z` f32, `prim` i32 (e1 = v1 - v0, e2 = v2 - v0; unused slots prim -1, zero edges) |
//!
//! A child ref is a node index, `LEAF | first block << 8 | triangles`, or
//! `EMPTY_SLOT`; a leaf's triangles fill its blocks in order. An unused
//! slot's box is the point at +inf; kernels mask hits with `valid` (a ray of
//! infinite length reaches +inf under a min/max slab test).

use isa::{Buf, Machine, MemKind};
use scene::bvh::{Bvh2, EMPTY_SLOT, LEAF};
use scene::mbvh::Mbvh;
use scene::mesh::Mesh;

/// Bit position of a leaf ref's first block.
pub const LEAF_FIRST_SHIFT: u32 = 8;
/// Mask of a leaf ref's triangle count.
pub const LEAF_COUNT_MASK: u32 = (1 << LEAF_FIRST_SHIFT) - 1;

/// Bytes of a node of width `w`.
#[must_use]
pub const fn node_bytes(w: usize) -> usize {
    32 * w
}

/// Bytes of a triangle block of width `w`.
#[must_use]
pub const fn block_bytes(w: usize) -> usize {
    40 * w
}

/// The scene's buffers in a machine's address space.
#[derive(Clone)]
pub struct MbvhBufs {
    /// Children per node (the lanes).
    pub width: usize,
    /// Nodes; node 0 is the root.
    pub nodes: Buf,
    /// Triangle blocks.
    pub tris: Buf,
    /// Levels of inner nodes (sizes the stacks).
    pub depth: usize,
    /// Leaves (refs) of the tree, for counters.
    pub leaves: usize,
}

/// Whether a child ref is a leaf.
#[must_use]
pub fn is_leaf(r: u32) -> bool {
    r != EMPTY_SLOT && r & LEAF != 0
}

/// A leaf ref's first block and triangle count.
#[must_use]
pub fn leaf_parts(r: u32) -> (u32, u32) {
    ((r & !LEAF) >> LEAF_FIRST_SHIFT, r & LEAF_COUNT_MASK)
}

/// Lay `t` (over `mesh`, leaves from `b2`) out in `m`'s memory.
///
/// # Panics
/// If the tree's width is not the machine's lanes, or a leaf holds more than
/// 255 triangles or the blocks overflow a ref.
pub fn lay_out<M: Machine>(m: &mut M, mesh: &Mesh, b2: &Bvh2, t: &Mbvh) -> MbvhBufs {
    let w = t.width;
    assert_eq!(w, M::LANES, "the MBVH's width is the machine's lanes");
    let (blocks, first) = blocks(mesh, b2, t);
    let mut words = Vec::with_capacity(t.nodes.len() * 8 * w);
    for n in &t.nodes {
        let mut rec = vec![0u32; 8 * w];
        for c in 0..w {
            let r = n.child[c];
            let (lo, hi) = if r == EMPTY_SLOT {
                ([f32::INFINITY; 3], [f32::INFINITY; 3])
            } else {
                (n.bounds[c].lo, n.bounds[c].hi)
            };
            for a in 0..3 {
                rec[(2 * a) * w + c] = lo[a].to_bits();
                rec[(2 * a + 1) * w + c] = hi[a].to_bits();
            }
            rec[6 * w + c] = if is_leaf(r) {
                let [_, count] = t.leaves[(r & !LEAF) as usize];
                let f = first[(r & !LEAF) as usize];
                assert!(count <= LEAF_COUNT_MASK && f < (1 << 23), "leaf too large");
                LEAF | f << LEAF_FIRST_SHIFT | count
            } else {
                r
            };
            if r != EMPTY_SLOT {
                rec[7 * w] |= 1 << c;
            }
        }
        words.extend_from_slice(&rec);
    }
    let sp = m.space();
    let nodes = sp.alloc_u32(MemKind::Nodes, "mbvh-nodes", &words, 64);
    let tris = sp.alloc_f32(MemKind::Triangles, "mbvh-tri-blocks", &blocks, 64);
    MbvhBufs {
        width: w,
        nodes,
        tris,
        depth: t.depth(),
        leaves: t.leaves.len(),
    }
}

/// The triangle blocks of every leaf, in leaf order, and each leaf's first block.
fn blocks(mesh: &Mesh, b2: &Bvh2, t: &Mbvh) -> (Vec<f32>, Vec<u32>) {
    let w = t.width;
    let mut out = Vec::new();
    let mut first = Vec::with_capacity(t.leaves.len());
    for &[f, count] in &t.leaves {
        first.push((out.len() / (10 * w)) as u32);
        let prims = &b2.prims[f as usize..(f + count) as usize];
        for chunk in prims.chunks(w) {
            let mut blk = vec![0f32; 10 * w];
            for l in 0..w {
                blk[9 * w + l] = f32::from_bits(u32::MAX);
            }
            for (l, &p) in chunk.iter().enumerate() {
                let [a, b, c] = mesh.tri(p as usize);
                for k in 0..3 {
                    blk[k * w + l] = a[k];
                    blk[(3 + k) * w + l] = b[k] - a[k];
                    blk[(6 + k) * w + l] = c[k] - a[k];
                }
                blk[9 * w + l] = f32::from_bits(p);
            }
            out.extend_from_slice(&blk);
        }
    }
    (out, first)
}

/// How a ray's origin and inverse direction are stored for the box test.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RayForm {
    /// Replicated across the lanes in SoA rows (the paper's choice: loads,
    /// no `_mm_set_ps1`; measured there +5%).
    Replicated,
    /// Once per ray (16 floats), broadcast into the lanes at every box test.
    Compact,
}

/// Where each field of a ray record sits (byte offsets).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RayRecord {
    /// Record size (a power of two).
    pub bytes: usize,
    /// Origin x, y, z: a row of `W` copies each (replicated) or one f32.
    pub org: [usize; 3],
    /// Inverse direction x, y, z, likewise.
    pub idir: [usize; 3],
    /// Direction x, y, z (f32 each).
    pub dir: [usize; 3],
    /// t_min (f32; +inf once a shadow ray is occluded: it is dropped).
    pub tmin: usize,
    /// Hit length (f32: t_far in, the hit distance out).
    pub length: usize,
    /// Hit triangle (i32, -1: none).
    pub prim: usize,
    /// Barycentric u, v (f32).
    pub u: usize,
    /// Barycentric v.
    pub v: usize,
}

impl RayRecord {
    /// The record of `form` at `w` lanes.
    #[must_use]
    pub fn of(form: RayForm, w: usize) -> RayRecord {
        match form {
            RayForm::Replicated => {
                // Rows 0-5 replicated; row 6: dir xyz, tmin; row 7: length, prim, u, v.
                let r = 4 * w;
                RayRecord {
                    bytes: 8 * r,
                    org: [0, r, 2 * r],
                    idir: [3 * r, 4 * r, 5 * r],
                    dir: [6 * r, 6 * r + 4, 6 * r + 8],
                    tmin: 6 * r + 12,
                    length: 7 * r,
                    prim: 7 * r + 4,
                    u: 7 * r + 8,
                    v: 7 * r + 12,
                }
            }
            RayForm::Compact => RayRecord {
                bytes: 64,
                org: [0, 4, 8],
                tmin: 12,
                idir: [16, 20, 24],
                length: 28,
                dir: [32, 36, 40],
                prim: 44,
                u: 48,
                v: 52,
            },
        }
    }

    /// The records of rays `(org, dir, tfar)`, laid out as this record says.
    #[must_use]
    pub fn records(
        &self,
        form: RayForm,
        w: usize,
        org: &[[f32; 3]],
        dir: &[[f32; 3]],
        tfar: &[f32],
    ) -> Vec<u8> {
        let mut out = vec![0u8; self.bytes * org.len()];
        for i in 0..org.len() {
            let rec = &mut out[i * self.bytes..(i + 1) * self.bytes];
            let mut put = |off: usize, x: f32| rec[off..off + 4].copy_from_slice(&x.to_le_bytes());
            let copies = if form == RayForm::Replicated { w } else { 1 };
            for a in 0..3 {
                for l in 0..copies {
                    put(self.org[a] + 4 * l, org[i][a]);
                    put(self.idir[a] + 4 * l, 1.0 / dir[i][a]);
                }
                put(self.dir[a], dir[i][a]);
            }
            put(self.tmin, 0.0);
            put(self.length, tfar[i]);
            put(self.prim, f32::from_bits(u32::MAX));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ray_fields_do_not_overlap_and_fit_the_record() {
        for (form, w) in [
            (RayForm::Replicated, 4),
            (RayForm::Replicated, 16),
            (RayForm::Compact, 4),
            (RayForm::Compact, 16),
        ] {
            let r = RayRecord::of(form, w);
            let wide = if form == RayForm::Replicated {
                4 * w
            } else {
                4
            };
            let mut spans: Vec<(usize, usize)> = Vec::new();
            for a in 0..3 {
                spans.push((r.org[a], wide));
                spans.push((r.idir[a], wide));
                spans.push((r.dir[a], 4));
            }
            for f in [r.tmin, r.length, r.prim, r.u, r.v] {
                spans.push((f, 4));
            }
            spans.sort_unstable();
            for s in spans.windows(2) {
                assert!(s[0].0 + s[0].1 <= s[1].0, "{form:?} {w}: {s:?}");
            }
            let (last, len) = spans[spans.len() - 1];
            assert!(last + len <= r.bytes && r.bytes.is_power_of_two());
        }
    }

    #[test]
    fn leaf_refs_round_trip() {
        let r = LEAF | 12345 << LEAF_FIRST_SHIFT | 7;
        assert!(is_leaf(r) && !is_leaf(EMPTY_SLOT) && !is_leaf(3));
        assert_eq!(leaf_parts(r), (12345, 7));
    }
}
