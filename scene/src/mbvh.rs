//! Multi-branching BVH (MBVH) of any width: each inner node holds the boxes
//! of up to `width` children, as Wald, Benthin and Boulos (2008) build them
//! for single-ray SIMD traversal and the MBVH ray-stream paper (Tsakok 2009)
//! uses with 4 children on SSE and 16 on Larrabee.
//!
//! Built top down from a binned-SAH BVH2 (the "traditional SAH"): a node
//! starts with its BVH2 node's two children and repeatedly opens the inner
//! child of largest surface area, replacing it by its own two children, until
//! it has `width` children or only leaves are left (Wald et al. 2008,
//! section 3.1). Leaves are the BVH2's leaves, unchanged (no multi-polygon
//! grouping: the SAH has no incentive to fill leaves to the width).

use crate::bvh::{tri_bounds, Aabb, Bvh2, Node, EMPTY_SLOT, LEAF, MAX_DEPTH};
use crate::mesh::Mesh;

/// One inner node: `width` child slots (unused: `EMPTY_SLOT`, empty box).
#[derive(Clone, Debug, PartialEq)]
pub struct MNode {
    /// Child boxes.
    pub bounds: Vec<Aabb>,
    /// Child refs: a node index, `LEAF | leaf index`, or `EMPTY_SLOT`.
    pub child: Vec<u32>,
}

/// An MBVH of `width` children per node over a BVH2's leaves.
#[derive(Clone, Debug)]
pub struct Mbvh {
    /// Children per node (4 or 16 in the papers; any width >= 2).
    pub width: usize,
    /// Inner nodes; node 0 is the root.
    pub nodes: Vec<MNode>,
    /// Leaves: (first prim, count) into the BVH2's `prims`.
    pub leaves: Vec<[u32; 2]>,
    /// Root bounds.
    pub root_bounds: Aabb,
}

impl Mbvh {
    /// Collapse `b` to `width` children per node.
    ///
    /// # Panics
    /// If `width < 2`.
    #[must_use]
    pub fn collapse(b: &Bvh2, width: usize) -> Mbvh {
        assert!(width >= 2, "an MBVH needs at least 2 children per node");
        let mut out = Mbvh {
            width,
            nodes: Vec::new(),
            leaves: Vec::new(),
            root_bounds: *b.nodes[0].bounds(),
        };
        out.emit(b, 0);
        out
    }

    /// Emit BVH2 node `n` (inner or, for a one-leaf tree, a leaf) as an inner
    /// node; returns its index.
    fn emit(&mut self, b: &Bvh2, n: u32) -> u32 {
        let me = self.nodes.len();
        self.nodes.push(MNode {
            bounds: vec![Aabb::EMPTY; self.width],
            child: vec![EMPTY_SLOT; self.width],
        });
        let slots = open_children(b, n, self.width);
        for (k, &c) in slots.iter().enumerate() {
            let r = match b.nodes[c as usize] {
                Node::Leaf { first, count, .. } => {
                    self.leaves.push([first, count]);
                    LEAF | (self.leaves.len() as u32 - 1)
                }
                Node::Inner { .. } => self.emit(b, c),
            };
            self.nodes[me].bounds[k] = *b.nodes[c as usize].bounds();
            self.nodes[me].child[k] = r;
        }
        me as u32
    }

    /// Levels of inner nodes on the longest root-to-leaf path.
    #[must_use]
    pub fn depth(&self) -> usize {
        fn go(t: &Mbvh, n: u32) -> usize {
            let node = &t.nodes[n as usize];
            1 + node
                .child
                .iter()
                .filter(|&&c| c != EMPTY_SLOT && c & LEAF == 0)
                .map(|&c| go(t, c))
                .max()
                .unwrap_or(0)
        }
        go(self, 0)
    }

    /// Every primitive reachable once, child boxes inside their parent's box
    /// for them, depth within [`MAX_DEPTH`], no empty inner node.
    pub fn validate(&self, b: &Bvh2, mesh: &Mesh) -> Result<(), String> {
        let boxes = tri_bounds(mesh);
        let mut seen = vec![0u8; mesh.len()];
        let mut stack = vec![(0u32, self.root_bounds, 1usize)];
        while let Some((n, pb, d)) = stack.pop() {
            if d > MAX_DEPTH {
                return Err(format!("MBVH node {n} beyond depth {MAX_DEPTH}"));
            }
            let node = self
                .nodes
                .get(n as usize)
                .ok_or_else(|| format!("MBVH node {n} does not exist"))?;
            if node.child.len() != self.width || node.bounds.len() != self.width {
                return Err(format!("MBVH node {n} has not {} slots", self.width));
            }
            if node.child.iter().all(|&c| c == EMPTY_SLOT) {
                return Err(format!("MBVH node {n} has no children"));
            }
            for (c, &r) in node.child.iter().enumerate() {
                if r == EMPTY_SLOT {
                    continue;
                }
                let cb = node.bounds[c];
                if !pb.contains(&cb) {
                    return Err(format!("MBVH node {n} child {c} outside its parent"));
                }
                if r & LEAF == 0 {
                    stack.push((r, cb, d + 1));
                    continue;
                }
                let [first, count] = *self
                    .leaves
                    .get((r & !LEAF) as usize)
                    .ok_or_else(|| format!("MBVH node {n} names a missing leaf"))?;
                for &p in &b.prims[first as usize..(first + count) as usize] {
                    if !cb.contains(&boxes[p as usize]) {
                        return Err(format!("triangle {p} outside its MBVH leaf box"));
                    }
                    seen[p as usize] += 1;
                }
            }
        }
        match seen.iter().position(|&s| s != 1) {
            Some(p) => Err(format!("triangle {p} reached {} times", seen[p])),
            None => Ok(()),
        }
    }
}

/// The children of BVH2 node `n` after opening, largest surface area first,
/// inner children until there are `width` (a leaf root is its own only child).
fn open_children(b: &Bvh2, n: u32, width: usize) -> Vec<u32> {
    let mut slots = match b.nodes[n as usize] {
        Node::Inner { left, right, .. } => vec![left, right],
        Node::Leaf { .. } => return vec![n],
    };
    while slots.len() < width {
        // The inner child of largest area (the first of equals: deterministic).
        let mut best: Option<(usize, f32)> = None;
        for (k, &c) in slots.iter().enumerate() {
            if let Node::Inner { bounds, .. } = b.nodes[c as usize] {
                let a = bounds.area();
                if best.is_none_or(|(_, ba)| a > ba) {
                    best = Some((k, a));
                }
            }
        }
        let Some((k, _)) = best else { break };
        let Node::Inner { left, right, .. } = b.nodes[slots[k] as usize] else {
            unreachable!("an inner child")
        };
        slots[k] = left;
        slots.insert(k + 1, right);
    }
    slots
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::BuildConfig;
    use crate::mesh::Mesh;

    fn grid(n: usize) -> Mesh {
        let mut mesh = Mesh {
            positions: Vec::new(),
            tris: Vec::new(),
        };
        for i in 0..n {
            let x = i as f32;
            let y = (i * 7 % 13) as f32;
            let k = mesh.positions.len() as u32;
            mesh.positions
                .extend([[x, y, 0.0], [x + 0.5, y, 0.0], [x, y + 0.5, 0.3]]);
            mesh.tris.push([k, k + 1, k + 2]);
        }
        mesh
    }

    #[test]
    fn collapsed_trees_hold_every_triangle_once_at_widths_2_4_16() {
        for n in [1, 3, 100, 1000] {
            let mesh = grid(n);
            let b2 = Bvh2::build(&mesh, &BuildConfig::default()).unwrap();
            for w in [2, 4, 16] {
                let t = Mbvh::collapse(&b2, w);
                t.validate(&b2, &mesh).unwrap();
                assert!(t.depth() <= b2.depth().max(1), "{n} {w}");
            }
        }
    }

    #[test]
    fn wider_nodes_make_shallower_trees_with_full_nodes() {
        let mesh = grid(4000);
        let b2 = Bvh2::build(&mesh, &BuildConfig::default()).unwrap();
        let (t4, t16) = (Mbvh::collapse(&b2, 4), Mbvh::collapse(&b2, 16));
        assert!(t16.depth() < t4.depth(), "{} {}", t16.depth(), t4.depth());
        assert_eq!(t4.leaves.len(), t16.leaves.len());
        let full = |t: &Mbvh| {
            let used: usize = t
                .nodes
                .iter()
                .map(|n| n.child.iter().filter(|&&c| c != EMPTY_SLOT).count())
                .sum();
            used as f64 / (t.nodes.len() * t.width) as f64
        };
        // Slots stay empty only where every child is a leaf.
        assert!(
            full(&t4) > 0.7 && full(&t16) > 0.5,
            "{} {}",
            full(&t4),
            full(&t16)
        );
        assert!(3 * t16.nodes.len() < t4.nodes.len());
    }

    #[test]
    fn validate_finds_a_missing_triangle() {
        let mesh = grid(50);
        let b2 = Bvh2::build(&mesh, &BuildConfig::default()).unwrap();
        let mut t = Mbvh::collapse(&b2, 4);
        t.leaves[0][1] -= 1;
        assert!(t.validate(&b2, &mesh).is_err());
    }
}
