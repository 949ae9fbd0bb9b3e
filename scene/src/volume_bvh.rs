//! The volume paper's data structures: the bricked layout (bricks of 4^3
//! voxels addressed through x, y and z offset tables, section 6.1) and the
//! implicit min-max BVH (section 5.1): leaves of L^3 cells with the minimum
//! and maximum over their trilinear stencil (the +1 neighbours), empty
//! leaves discarded, a top-down median split on the axis of largest extent,
//! each node's min-max over its children.

use crate::volume::Volume;

/// Voxels per side of a brick (64 bytes: one cache line per brick row set).
pub const BRICK: u32 = 4;

/// A volume in bricks: voxel (x, y, z) is `data[off[0][x] + off[1][y] +
/// off[2][z]]`. Each table has one entry past the volume's last voxel,
/// repeating it, so the interpolation stencil's `+1` needs no test.
#[derive(Clone, Debug, PartialEq)]
pub struct Bricked {
    /// Voxels, brick by brick (x fastest within a brick, bricks x fastest).
    pub data: Vec<u8>,
    /// Offset tables along x, y, z.
    pub off: [Vec<u32>; 3],
}

impl Bricked {
    /// Lay `v` out in bricks (its sides padded to whole bricks with zeros).
    #[must_use]
    pub fn new(v: &Volume) -> Bricked {
        let nb = v.dims.map(|d| d.div_ceil(BRICK));
        let brick = BRICK * BRICK * BRICK;
        let stride = [brick, nb[0] * brick, nb[0] * nb[1] * brick];
        let within = [1, BRICK, BRICK * BRICK];
        let off: [Vec<u32>; 3] = std::array::from_fn(|a| {
            (0..=v.dims[a])
                .map(|i| {
                    let i = i.min(v.dims[a] - 1);
                    (i / BRICK) * stride[a] + (i % BRICK) * within[a]
                })
                .collect()
        });
        let mut data = vec![0u8; (nb[0] * nb[1] * nb[2] * brick) as usize];
        for z in 0..v.dims[2] {
            for y in 0..v.dims[1] {
                for x in 0..v.dims[0] {
                    let o = off[0][x as usize] + off[1][y as usize] + off[2][z as usize];
                    data[o as usize] = v.at(x, y, z);
                }
            }
        }
        Bricked { data, off }
    }

    /// The value at voxel (x, y, z) (each at most its side: the extra
    /// table entry repeats the last voxel).
    #[must_use]
    pub fn at(&self, x: u32, y: u32, z: u32) -> u8 {
        let o = self.off[0][x as usize] + self.off[1][y as usize] + self.off[2][z as usize];
        self.data[o as usize]
    }
}

/// A node of the min-max BVH: its box in voxel coordinates (cells `lo` to
/// `hi`, i.e. the box `[lo, hi]`), the value range over it (stencil
/// included), and its children or (leaf) none.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct VNode {
    /// Lower corner (voxel coordinates).
    pub lo: [u32; 3],
    /// Upper corner.
    pub hi: [u32; 3],
    /// Least value over the node's voxels.
    pub min: u8,
    /// Greatest value.
    pub max: u8,
    /// Children (indices), or `None` for a leaf.
    pub children: Option<[u32; 2]>,
    /// The axis an inner node splits on (its first child is the lower
    /// side); 0 for a leaf.
    pub axis: u8,
}

/// The implicit min-max BVH of a volume; node 0 is the root (none when
/// every leaf is empty).
#[derive(Clone, Debug, PartialEq)]
pub struct MinMaxBvh {
    /// Nodes, parents before children.
    pub nodes: Vec<VNode>,
    /// Cells per leaf side (L).
    pub leaf: u32,
}

/// Bytes of one node as the kernels lay it out (box, range, child index).
pub const VNODE_BYTES: usize = 32;

impl MinMaxBvh {
    /// Build over `v` with leaves of `leaf`^3 cells.
    ///
    /// # Panics
    /// If `leaf` is 0.
    #[must_use]
    pub fn build(v: &Volume, leaf: u32) -> MinMaxBvh {
        assert!(leaf >= 1, "leaves of at least one cell");
        let mut leaves = leaf_nodes(v, leaf);
        let mut nodes = Vec::with_capacity(2 * leaves.len());
        if !leaves.is_empty() {
            nodes.push(leaves[0]);
            split(&mut nodes, 0, &mut leaves);
        }
        MinMaxBvh { nodes, leaf }
    }

    /// Leaves in the tree.
    #[must_use]
    pub fn leaves(&self) -> usize {
        self.nodes.iter().filter(|n| n.children.is_none()).count()
    }

    /// Bytes the tree takes as laid out.
    #[must_use]
    pub fn bytes(&self) -> usize {
        self.nodes.len() * VNODE_BYTES
    }

    /// Check the tree against `v`: every inner node's box and range hold its
    /// children's, every leaf's range is its stencil's, no leaf is empty,
    /// and the leaves cover every cell whose stencil holds a non-zero value
    /// exactly once.
    ///
    /// # Errors
    /// The first rule broken, naming the node.
    pub fn validate(&self, v: &Volume) -> Result<(), String> {
        let mut covered = vec![0u8; cells(v.dims).iter().map(|&c| c as usize).product()];
        for (i, n) in self.nodes.iter().enumerate() {
            match n.children {
                Some(ch) => {
                    let (a, b) = (
                        self.nodes.get(ch[0] as usize),
                        self.nodes.get(ch[1] as usize),
                    );
                    if let (Some(a), Some(b)) = (a, b) {
                        let ax = n.axis as usize;
                        if a.hi[ax] > b.lo[ax] {
                            return Err(format!("node {i}: children overlap along axis {ax}"));
                        }
                    }
                    for c in ch {
                        let c = self
                            .nodes
                            .get(c as usize)
                            .ok_or(format!("node {i}: child {c} missing"))?;
                        let inside = (0..3).all(|a| n.lo[a] <= c.lo[a] && c.hi[a] <= n.hi[a]);
                        if !inside || c.min < n.min || c.max > n.max {
                            return Err(format!("node {i}: a child outside its box or range"));
                        }
                    }
                }
                None => {
                    let (min, max) = stencil_range(v, n.lo, n.hi);
                    if (min, max) != (n.min, n.max) || max == 0 {
                        return Err(format!(
                            "leaf {i}: range ({}, {}) but its voxels ({min}, {max})",
                            n.min, n.max
                        ));
                    }
                    for_cells(n.lo, n.hi, |c| covered[cell_index(v.dims, c)] += 1);
                }
            }
        }
        let c = cells(v.dims);
        let mut bad = None;
        for_cells([0; 3], c, |p| {
            let want = u8::from(stencil_range(v, p, p.map(|x| x + 1)).1 > 0);
            let got = covered[cell_index(v.dims, p)];
            if bad.is_none() && !(got == want || (want == 0 && got == 1)) {
                bad = Some(format!("cell {p:?} covered {got} times"));
            }
        });
        bad.map_or(Ok(()), Err)
    }
}

/// Cells along each axis (at least one, for a volume one voxel thick).
fn cells(dims: [u32; 3]) -> [u32; 3] {
    dims.map(|d| (d - 1).max(1))
}

fn cell_index(dims: [u32; 3], p: [u32; 3]) -> usize {
    let c = cells(dims);
    ((p[2] * c[1] + p[1]) * c[0] + p[0]) as usize
}

/// Call `f` with every cell in `[lo, hi)`.
fn for_cells(lo: [u32; 3], hi: [u32; 3], mut f: impl FnMut([u32; 3])) {
    for z in lo[2]..hi[2] {
        for y in lo[1]..hi[1] {
            for x in lo[0]..hi[0] {
                f([x, y, z]);
            }
        }
    }
}

/// The value range over the voxels of cells `[lo, hi)`: voxels `lo` to
/// `hi` inclusive (the trilinear stencil's +1), clamped to the volume.
fn stencil_range(v: &Volume, lo: [u32; 3], hi: [u32; 3]) -> (u8, u8) {
    let (mut min, mut max) = (u8::MAX, 0u8);
    for z in lo[2]..=hi[2] {
        for y in lo[1]..=hi[1] {
            for x in lo[0]..=hi[0] {
                let s = v.at(x, y, z);
                min = min.min(s);
                max = max.max(s);
            }
        }
    }
    (min, max)
}

/// The non-empty leaves of `leaf`^3 cells, in raster order.
fn leaf_nodes(v: &Volume, leaf: u32) -> Vec<VNode> {
    let c = cells(v.dims);
    let n = c.map(|x| x.div_ceil(leaf));
    let mut out = Vec::new();
    for_cells([0; 3], n, |b| {
        let lo = b.map(|x| x * leaf);
        let hi: [u32; 3] = std::array::from_fn(|a| (lo[a] + leaf).min(c[a]));
        let (min, max) = stencil_range(v, lo, hi);
        if max > 0 {
            out.push(VNode {
                lo,
                hi,
                min,
                max,
                children: None,
                axis: 0,
            });
        }
    });
    out
}

/// Make node `at` the root of `leaves`: a leaf if there is one, else a
/// split at the median centroid on the axis along which the centroids
/// spread most, leaves left of the plane to the first child. Leaves are a
/// grid of bricks, so the children do not overlap along the split axis and
/// the traversal's near-first order along it is front to back.
fn split(nodes: &mut Vec<VNode>, at: usize, leaves: &mut [VNode]) {
    let (mut lo, mut hi) = ([u32::MAX; 3], [0u32; 3]);
    let (mut clo, mut chi) = ([u32::MAX; 3], [0u32; 3]);
    for l in leaves.iter() {
        for a in 0..3 {
            lo[a] = lo[a].min(l.lo[a]);
            hi[a] = hi[a].max(l.hi[a]);
            clo[a] = clo[a].min(l.lo[a] + l.hi[a]);
            chi[a] = chi[a].max(l.lo[a] + l.hi[a]);
        }
    }
    let min = leaves.iter().map(|l| l.min).min().unwrap_or(0);
    let max = leaves.iter().map(|l| l.max).max().unwrap_or(0);
    if leaves.len() == 1 {
        nodes[at] = leaves[0];
        return;
    }
    let axis = (0..3)
        .max_by_key(|&a| (chi[a] - clo[a], 2 - a))
        .unwrap_or(0);
    let c = |l: &VNode| l.lo[axis] + l.hi[axis];
    leaves.sort_by_key(|l| (c(l), l.lo));
    // The plane at the median centroid; ties go right unless that empties
    // the left side (distinct leaves of a grid spread on the chosen axis).
    let median = c(&leaves[leaves.len() / 2]);
    let mut cut = leaves.partition_point(|l| c(l) < median);
    if cut == 0 {
        cut = leaves.partition_point(|l| c(l) <= median);
    }
    let (left, right) = leaves.split_at_mut(cut);
    let first = nodes.len() as u32;
    nodes.extend([left[0], right[0]]);
    nodes[at] = VNode {
        lo,
        hi,
        min,
        max,
        children: Some([first, first + 1]),
        axis: axis as u8,
    };
    split(nodes, first as usize, left);
    split(nodes, first as usize + 1, right);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bricks_hold_every_voxel_where_the_tables_say() {
        let v = Volume::mixing_layer(13, 2);
        let b = Bricked::new(&v);
        for (x, y, z) in [(0, 0, 0), (12, 12, 12), (5, 9, 3), (4, 4, 4)] {
            assert_eq!(b.at(x, y, z), v.at(x, y, z));
        }
        // The extra entry repeats the last voxel (the stencil's +1).
        assert_eq!(b.at(13, 13, 13), v.at(12, 12, 12));
        assert_eq!(b.off[0][4] - b.off[0][3], 64 - 3, "the next brick along x");
        assert_eq!(b.data.len(), 4 * 4 * 4 * 64);
    }

    #[test]
    fn trees_of_every_leaf_size_validate_and_skip_empty_space() {
        let v = Volume::mixing_layer(24, 5);
        let mut sizes = Vec::new();
        for l in [1, 2, 4, 8] {
            let t = MinMaxBvh::build(&v, l);
            t.validate(&v).unwrap_or_else(|e| panic!("L = {l}: {e}"));
            assert_eq!(t.nodes.len(), 2 * t.leaves() - 1);
            // The empty quarter on top is not in the tree.
            let top = (0.75 * 23.0) as u32 + 2;
            assert!(
                t.nodes
                    .iter()
                    .all(|n| n.children.is_some() || n.lo[2] < top),
                "L = {l}"
            );
            sizes.push(t.bytes());
        }
        assert!(sizes.windows(2).all(|w| w[0] > w[1]), "{sizes:?}");
        // A broken tree is caught.
        let mut t = MinMaxBvh::build(&v, 4);
        let leaf = t.nodes.iter().position(|n| n.children.is_none()).unwrap();
        t.nodes[leaf].max = t.nodes[leaf].max.wrapping_add(1);
        assert!(t.validate(&v).is_err());
    }

    #[test]
    fn degenerate_volumes_build() {
        let zero = Volume {
            dims: [5, 5, 5],
            spacing: [1.0; 3],
            data: vec![0; 125],
            range: (0.0, 0.0),
        };
        let t = MinMaxBvh::build(&zero, 4);
        assert!(t.nodes.is_empty());
        t.validate(&zero).unwrap();
        let one = Volume {
            dims: [1, 1, 1],
            spacing: [1.0; 3],
            data: vec![7],
            range: (0.0, 255.0),
        };
        let t = MinMaxBvh::build(&one, 2);
        assert_eq!(t.leaves(), 1);
        t.validate(&one).unwrap();
    }
}
