//! A scene laid out in a machine's simulated memory, as the DRS kernels
//! read it: BVH4 nodes, 8-wide triangle blocks, rays and hits.
//!
//! | structure | record | bytes | fields |
//! |---|---|---|---|
//! | BVH4 node | 128 | `min_x[4] max_x[4] min_y[4] max_y[4] min_z[4] max_z[4]` f32, `child[4]` u32, `valid` u32, pad | child: node index, `LEAF \| block`, or `EMPTY_SLOT`; valid: bit c if child c exists |
//! | triangle block | 320 | `v0x[8] v0y[8] v0z[8] e1x[8] e1y[8] e1z[8] e2x[8] e2y[8] e2z[8]` f32, `prim[8]` i32 | e1 = v1 - v0, e2 = v2 - v0; unused slots: prim = -1, zero edges |
//! | traversal ray | 32 | `idir.xyz, t_near, org.xyz * idir.xyz, t_far` | as the DRS paper |
//! | intersection ray | 32 | `org.xyz, 0, dir.xyz, 0` | |
//! | hit | 16 | `t` f32, `u` f32, `v` f32, `prim` i32 | prim = -1: no hit |
//! | vertex ([`IndexedTris`]) | 16 | `x, y, z, 0` f32 | the mesh's vertices |
//! | indexed triangle | 12 | `v0, v1, v2` u32 | vertex indices, by prim id |
//!
//! Deviation: leaves hold at most 8 triangles (one block), so a BVH4 leaf ref
//! names one block; the paper's Embree leaves are triangle4 lists.

use isa::{Buf, Machine, MemKind};
use scene::bvh::{Bvh2, Bvh4, EMPTY_SLOT, LEAF};
use scene::mesh::Mesh;

/// Bytes of a triangle block.
pub const BLOCK_BYTES: usize = 320;
/// Triangles per block.
pub const BLOCK: usize = 8;
/// Bytes of a BVH4 node record.
pub const NODE_BYTES: usize = 128;
/// Bytes of a hit record.
pub const HIT_BYTES: usize = 16;

/// The scene's buffers in a machine's address space.
#[derive(Clone)]
pub struct Bvh4Bufs {
    /// BVH4 nodes.
    pub nodes: Buf,
    /// Triangle blocks.
    pub tris: Buf,
    /// Bounds of the root.
    pub root_bounds: scene::bvh::Aabb,
}

/// Lay a BVH4 (built over `mesh` with leaves of at most 8 triangles) into `m`'s memory.
pub fn lay_out_bvh4<M: Machine>(m: &mut M, mesh: &Mesh, b2: &Bvh2, b4: &Bvh4) -> Bvh4Bufs {
    let mut node_words: Vec<u32> = Vec::with_capacity(b4.nodes.len() * 32);
    for i in 0..b4.nodes.len() {
        node_words.extend_from_slice(&b4.record(i));
    }
    let block_bytes = blocks(mesh, b2, &b4.leaves, false);
    let nodes = m
        .space()
        .alloc_u32(MemKind::Nodes, "bvh4-nodes", &node_words, 64);
    let tris = m
        .space()
        .alloc_bytes(MemKind::Triangles, "tri-blocks", block_bytes, 64);
    Bvh4Bufs {
        nodes,
        tris,
        root_bounds: b4.root_bounds,
    }
}

/// Triangle blocks of `leaves` ((first, count) into `b2.prims`): one per
/// leaf, or with `multi` as many consecutive blocks as a leaf needs (the
/// last one padded); little-endian bytes, written once (a paper-size
/// scene's blocks are most of a gigabyte). Sequential on purpose: layouts
/// are made inside a method's task under a `OnceLock`, where a parallel
/// loop's waiting thread could steal another method's task that waits on
/// the same lock.
fn blocks(mesh: &Mesh, b2: &Bvh2, leaves: &[[u32; 2]], multi: bool) -> Vec<u8> {
    let chunks: Vec<(u32, u32)> = leaves
        .iter()
        .flat_map(|&[first, count]| {
            assert!(
                multi || count as usize <= BLOCK,
                "leaf of {count} triangles: build with max_leaf <= 8"
            );
            let n = count.div_ceil(BLOCK as u32).max(1);
            (0..n).map(move |i| {
                let f = first + BLOCK as u32 * i;
                (f, (count - BLOCK as u32 * i).min(BLOCK as u32))
            })
        })
        .collect();
    let len = chunks.len() * BLOCK_BYTES;
    // Room for the buffer's padding, so placing the bytes in a machine's
    // memory pads them in place ([`isa::AddrSpace::alloc_bytes`]) instead
    // of copying most of a gigabyte into a fresh allocation.
    let mut bytes = vec![0u8; len + isa::PAD];
    bytes.truncate(len);
    let (words, _) = bytes.as_chunks_mut::<4>();
    for (out, &(first, count)) in words.chunks_exact_mut(BLOCK_BYTES / 4).zip(&chunks) {
        for (o, x) in out.iter_mut().zip(block(mesh, b2, first, count)) {
            *o = x.to_le_bytes();
        }
    }
    bytes
}

/// One block's words: `count` triangles from `b2.prims[first..]` as v0,
/// e1 = v1 - v0, e2 = v2 - v0 (8 lanes of each component), then the
/// primitive ids (-1 for an empty slot).
fn block(mesh: &Mesh, b2: &Bvh2, first: u32, count: u32) -> [u32; 80] {
    let mut w = [0u32; 80];
    for k in 0..BLOCK {
        if (k as u32) < count {
            let p = b2.prims[(first + k as u32) as usize];
            let [v0, v1, v2] = mesh.tri(p as usize);
            for a in 0..3 {
                w[a * 8 + k] = v0[a].to_bits();
                w[(3 + a) * 8 + k] = (v1[a] - v0[a]).to_bits();
                w[(6 + a) * 8 + k] = (v2[a] - v0[a]).to_bits();
            }
            w[72 + k] = p;
        } else {
            w[72 + k] = u32::MAX; // -1: no triangle
        }
    }
    w
}

/// A BVH2 laid into a machine's memory ([`scene::bvh::Bvh2Layout`] nodes,
/// the same triangle blocks); `root` is the root's ref.
#[derive(Clone)]
pub struct Bvh2Bufs {
    /// BVH2 nodes, 64 bytes each.
    pub nodes: Buf,
    /// Triangle blocks.
    pub tris: Buf,
    /// The root's ref (a node, or a leaf for a one-leaf tree).
    pub root: u32,
    /// [`lay_out_bvh2_multi`] only: each leaf's box at 32 x its first block
    /// (`lo.xyz, 0, hi.xyz, 0` f32), for per-ray leaf tests.
    pub leaf_boxes: Option<Buf>,
}

/// Lay a BVH2 (leaves of at most 8 triangles) into `m`'s memory.
pub fn lay_out_bvh2<M: Machine>(m: &mut M, mesh: &Mesh, b2: &Bvh2) -> Bvh2Bufs {
    lay_out_bvh2_with(m, mesh, b2, false)
}

/// Lay a BVH2 with leaves of any size (up to [`scene::bvh::LEAF_MAX_BLOCKS`]
/// blocks) into `m`'s memory: a leaf ref names its first block and block
/// count (the MFT kernel's shallow BVH).
pub fn lay_out_bvh2_multi<M: Machine>(m: &mut M, mesh: &Mesh, b2: &Bvh2) -> Bvh2Bufs {
    lay_out_bvh2_with(m, mesh, b2, true)
}

fn lay_out_bvh2_with<M: Machine>(m: &mut M, mesh: &Mesh, b2: &Bvh2, multi: bool) -> Bvh2Bufs {
    let lay = scene::bvh::Bvh2Layout::new(b2);
    let words: Vec<u32> = lay.nodes.iter().flatten().copied().collect();
    let words = if words.is_empty() {
        vec![0u32; 16]
    } else {
        words
    };
    let nodes = m
        .space()
        .alloc_u32(MemKind::Nodes, "bvh2-nodes", &words, 64);
    let tris = m.space().alloc_bytes(
        MemKind::Triangles,
        "tri-blocks",
        blocks(mesh, b2, &lay.leaves, multi),
        64,
    );
    let leaf_boxes = multi.then(|| {
        let mut words = vec![0u32; 8 * lay.blocks.max(1) as usize];
        let mut blk = 0usize;
        for (&[_, count], bx) in lay.leaves.iter().zip(&lay.leaf_bounds) {
            for a in 0..3 {
                words[8 * blk + a] = bx.lo[a].to_bits();
                words[8 * blk + 4 + a] = bx.hi[a].to_bits();
            }
            blk += count.div_ceil(BLOCK as u32).max(1) as usize;
        }
        m.space()
            .alloc_u32(MemKind::Nodes, "bvh2-leaf-boxes", &words, 64)
    });
    Bvh2Bufs {
        nodes,
        tris,
        root: lay.root,
        leaf_boxes,
    }
}

/// Whether a BVH4 child ref names a leaf block.
#[must_use]
pub fn is_leaf(r: u32) -> bool {
    r != EMPTY_SLOT && r & LEAF != 0
}

/// Triangles as a mesh holds them: vertex indices into a vertex array (the
/// MFT paper's packet baseline reads these at leaves).
#[derive(Clone)]
pub struct IndexedTris {
    /// Vertices, 16 bytes each: `x, y, z, 0` f32.
    pub verts: Buf,
    /// Triangles, 12 bytes each: three u32 vertex indices.
    pub idx: Buf,
}

/// Bytes of a vertex of [`IndexedTris`].
pub const VERTEX_BYTES: usize = 16;

/// Lay `mesh`'s vertices and vertex indices into `m`'s memory.
pub fn lay_out_indexed<M: Machine>(m: &mut M, mesh: &Mesh) -> IndexedTris {
    let verts: Vec<f32> = mesh
        .positions
        .iter()
        .flat_map(|p| [p[0], p[1], p[2], 0.0])
        .collect();
    let idx: Vec<u32> = mesh.tris.iter().flatten().copied().collect();
    let sp = m.space();
    IndexedTris {
        verts: sp.alloc_f32(MemKind::Triangles, "vertices", &verts, 64),
        idx: sp.alloc_u32(MemKind::Triangles, "tri-indices", &idx, 64),
    }
}

/// Traversal and intersection ray records for rays (org, dir, t_far).
#[must_use]
pub fn ray_records(org: &[[f32; 3]], dir: &[[f32; 3]], tfar: &[f32]) -> (Vec<f32>, Vec<f32>) {
    let mut trav = Vec::with_capacity(org.len() * 8);
    let mut isect = Vec::with_capacity(org.len() * 8);
    for i in 0..org.len() {
        let (o, d) = (org[i], dir[i]);
        let id = d.map(|c| 1.0 / c);
        trav.extend_from_slice(&[
            id[0],
            id[1],
            id[2],
            0.0,
            o[0] * id[0],
            o[1] * id[1],
            o[2] * id[2],
            tfar[i],
        ]);
        isect.extend_from_slice(&[o[0], o[1], o[2], 0.0, d[0], d[1], d[2], 0.0]);
    }
    (trav, isect)
}

/// Initial hit records of `n` rays: t = infinity, u = v = 0, prim = -1.
#[must_use]
pub fn hit_records(n: usize) -> Vec<u8> {
    let mut b = Vec::with_capacity(n * 16);
    for _ in 0..n {
        b.extend(f32::INFINITY.to_le_bytes());
        b.extend(0f32.to_le_bytes());
        b.extend(0f32.to_le_bytes());
        b.extend((-1i32).to_le_bytes());
    }
    b
}

/// Rows of a packet record.
pub mod row {
    /// Origin x (y, z follow).
    pub const ORG: usize = 0;
    /// Direction x (y, z follow).
    pub const DIR: usize = 3;
    /// Reciprocal direction x (y, z follow).
    pub const IDIR: usize = 6;
    /// Entry distance.
    pub const TNEAR: usize = 9;
    /// Ray limit, then hit distance.
    pub const TFAR: usize = 10;
    /// Hit u.
    pub const U: usize = 11;
    /// Hit v.
    pub const V: usize = 12;
    /// Hit triangle id.
    pub const PRIM: usize = 13;
    /// Rows per record.
    pub const ROWS: usize = 16;
}

/// Byte offset of row `r` in a packet record of `w` lanes.
#[must_use]
pub fn row(w: usize, r: usize) -> usize {
    4 * w * r
}

/// Bytes of one packet record of `w` lanes.
#[must_use]
pub fn packet_bytes(w: usize) -> usize {
    row(w, row::ROWS)
}

#[cfg(test)]
mod tests {
    use super::*;
    use scene::bvh::{BuildConfig, LEAF_BLOCKS_SHIFT, LEAF_FIRST_MASK};

    /// A strip of `n` small triangles along x.
    fn strip(n: u32) -> Mesh {
        let mut m = Mesh::default();
        for i in 0..n {
            let x = i as f32;
            m.positions
                .extend([[x, 0.0, 0.0], [x + 0.5, 0.0, 0.0], [x, 0.5, 0.0]]);
            m.tris.push([3 * i, 3 * i + 1, 3 * i + 2]);
        }
        m
    }

    #[test]
    fn large_leaves_take_consecutive_blocks() {
        let m = strip(20);
        // One leaf of 20 triangles: 3 blocks, the last with 4 empty slots.
        let b = Bvh2::build(
            &m,
            &BuildConfig {
                max_leaf: 32,
                c_trav: 1000.0,
                ..BuildConfig::default()
            },
        )
        .unwrap();
        let lay = scene::bvh::Bvh2Layout::new(&b);
        assert_eq!(lay.blocks, 3);
        assert_eq!(lay.root & LEAF, LEAF);
        assert_eq!((lay.root & !LEAF) >> LEAF_BLOCKS_SHIFT, 2, "3 blocks");
        assert_eq!(lay.root & LEAF_FIRST_MASK, 0);
        let bytes = blocks(&m, &b, &lay.leaves, true);
        let words: Vec<u32> = bytes
            .chunks_exact(4)
            .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        assert_eq!(words.len(), 3 * 80);
        let prims: Vec<u32> = (0..3)
            .flat_map(|k| words[80 * k + 72..80 * k + 80].to_vec())
            .collect();
        let mut seen: Vec<u32> = prims.iter().copied().filter(|&p| p != u32::MAX).collect();
        seen.sort_unstable();
        assert_eq!(seen, (0..20).collect::<Vec<u32>>());
        assert!(prims[20..].iter().all(|&p| p == u32::MAX));
        // Leaves of at most 8: one block each, the ref is the leaf index.
        let b = Bvh2::build(&m, &BuildConfig::default()).unwrap();
        let lay = scene::bvh::Bvh2Layout::new(&b);
        assert_eq!(lay.blocks as usize, lay.leaves.len());
    }

    #[test]
    #[should_panic(expected = "max_leaf <= 8")]
    fn one_block_layouts_refuse_large_leaves() {
        let m = strip(20);
        let b = Bvh2::build(
            &m,
            &BuildConfig {
                max_leaf: 32,
                c_trav: 1000.0,
                ..BuildConfig::default()
            },
        )
        .unwrap();
        let lay = scene::bvh::Bvh2Layout::new(&b);
        let _ = blocks(&m, &b, &lay.leaves, false);
    }
}
