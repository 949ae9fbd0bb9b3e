//! BVHs (host side, not simulated): a binned-SAH BVH2 builder (Wald 2007),
//! BVH4 by collapsing a BVH2 as the DRS paper builds it (siblings near each
//! other grouped as c0,c1 | c2,c3), and a shallow variant with larger leaves
//! (MFT). Memory layouts are the papers': a BVH2 node holds both children's
//! boxes in one 64-byte line; a BVH4 node holds the 4 children's boxes in SoA
//! form (also the MBVH RS node). Every structure has `validate()`.

use crate::mesh::Mesh;

/// An axis-aligned box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Minimum corner.
    pub lo: [f32; 3],
    /// Maximum corner.
    pub hi: [f32; 3],
}

impl Aabb {
    /// The empty box (inverted).
    pub const EMPTY: Aabb = Aabb {
        lo: [f32::INFINITY; 3],
        hi: [f32::NEG_INFINITY; 3],
    };
    /// Grow to hold `p`.
    pub fn grow(&mut self, p: [f32; 3]) {
        for a in 0..3 {
            self.lo[a] = self.lo[a].min(p[a]);
            self.hi[a] = self.hi[a].max(p[a]);
        }
    }
    /// Union.
    #[must_use]
    pub fn union(mut self, o: &Aabb) -> Aabb {
        for a in 0..3 {
            self.lo[a] = self.lo[a].min(o.lo[a]);
            self.hi[a] = self.hi[a].max(o.hi[a]);
        }
        self
    }
    /// Surface area (0 for the empty box).
    #[must_use]
    pub fn area(&self) -> f32 {
        let d = [
            self.hi[0] - self.lo[0],
            self.hi[1] - self.lo[1],
            self.hi[2] - self.lo[2],
        ];
        if d.iter().any(|&x| x < 0.0) {
            return 0.0;
        }
        2.0 * (d[0] * d[1] + d[1] * d[2] + d[2] * d[0])
    }
    /// Whether `o` lies inside (closed).
    #[must_use]
    pub fn contains(&self, o: &Aabb) -> bool {
        (0..3).all(|a| self.lo[a] <= o.lo[a] && o.hi[a] <= self.hi[a])
    }
    /// Centre.
    #[must_use]
    pub fn centre(&self) -> [f32; 3] {
        [
            0.5 * (self.lo[0] + self.hi[0]),
            0.5 * (self.lo[1] + self.hi[1]),
            0.5 * (self.lo[2] + self.hi[2]),
        ]
    }
}

/// A BVH2 node (host form).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Node {
    /// Two children (node indices).
    Inner {
        /// Bounds.
        bounds: Aabb,
        /// Left child.
        left: u32,
        /// Right child.
        right: u32,
    },
    /// Primitives `prims[first .. first + count]`.
    Leaf {
        /// Bounds.
        bounds: Aabb,
        /// First index into `prims`.
        first: u32,
        /// Count.
        count: u32,
    },
}

impl Node {
    /// Bounds.
    #[must_use]
    pub fn bounds(&self) -> &Aabb {
        match self {
            Node::Inner { bounds, .. } | Node::Leaf { bounds, .. } => bounds,
        }
    }
}

/// Builder settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BuildConfig {
    /// SAH bins per axis.
    pub bins: usize,
    /// A node with at most this many primitives may become a leaf.
    pub max_leaf: usize,
    /// Cost of a traversal step relative to one primitive test.
    pub c_trav: f32,
}

impl Default for BuildConfig {
    fn default() -> Self {
        // Embree-like defaults: 16 bins is Wald 2007's sweet spot; leaves up to 4.
        BuildConfig {
            bins: 16,
            max_leaf: 4,
            c_trav: 1.0,
        }
    }
}

impl BuildConfig {
    /// Leaves of up to 64 triangles at traversal cost 8: a tree with large
    /// leaves, for tests of leaf handling. (The papers' own presets live with
    /// their kernels: `drs_kernels::BVH`, `mft_kernels::SHALLOW_BVH`.)
    pub const LARGE_LEAVES: BuildConfig = BuildConfig {
        bins: 16,
        max_leaf: 64,
        c_trav: 8.0,
    };
}

/// Deepest tree the traversal stacks allow.
pub const MAX_DEPTH: usize = 64;

/// A BVH2 over a mesh's triangles.
#[derive(Clone, Debug)]
pub struct Bvh2 {
    /// Nodes; node 0 is the root.
    pub nodes: Vec<Node>,
    /// Triangle indices, leaves refer to ranges of it.
    pub prims: Vec<u32>,
    /// Build time in seconds.
    pub build_seconds: f64,
}

/// Triangle bounds.
#[must_use]
pub fn tri_bounds(mesh: &Mesh) -> Vec<Aabb> {
    (0..mesh.len())
        .map(|i| {
            let mut b = Aabb::EMPTY;
            for p in mesh.tri(i) {
                b.grow(p);
            }
            b
        })
        .collect()
}

impl Bvh2 {
    /// Build with binned SAH. The top [`PAR_LEVELS`] levels of large nodes
    /// build their two subtrees on two threads; the tree is the same node
    /// for node as one thread's (same numbering, same primitive order), on
    /// any number of cores.
    pub fn build(mesh: &Mesh, cfg: &BuildConfig) -> Result<Bvh2, String> {
        Self::build_par(mesh, cfg, (PAR_LEVELS, PAR_MIN_PRIMS))
    }

    /// [`Bvh2::build`] with subtrees split off to threads down to `levels`
    /// levels, for nodes of at least `min_prims` triangles.
    fn build_par(
        mesh: &Mesh,
        cfg: &BuildConfig,
        (levels, min_prims): (usize, usize),
    ) -> Result<Bvh2, String> {
        if mesh.is_empty() {
            return Err("empty scene: no triangles to build a BVH over".into());
        }
        let t0 = std::time::Instant::now();
        let boxes = tri_bounds(mesh);
        let centres: Vec<[f32; 3]> = boxes.iter().map(Aabb::centre).collect();
        let mut prims: Vec<u32> = (0..mesh.len() as u32).collect();
        let ctx = BuildCtx {
            boxes: &boxes,
            centres: &centres,
            cfg,
            min_prims,
        };
        let nodes = subtree(&ctx, &mut prims, (0, 0), levels);
        Ok(Bvh2 {
            nodes,
            prims,
            build_seconds: t0.elapsed().as_secs_f64(),
        })
    }

    /// SAH cost: traversal cost times inner nodes' areas plus primitive count
    /// times leaves' areas, over the root's area.
    #[must_use]
    pub fn sah_cost(&self, c_trav: f32) -> f64 {
        let root = f64::from(self.nodes[0].bounds().area()).max(f64::MIN_POSITIVE);
        self.nodes
            .iter()
            .map(|n| match n {
                Node::Inner { bounds, .. } => f64::from(c_trav) * f64::from(bounds.area()),
                Node::Leaf { bounds, count, .. } => f64::from(*count) * f64::from(bounds.area()),
            })
            .sum::<f64>()
            / root
    }

    /// Depth of the deepest leaf (root = 1).
    #[must_use]
    pub fn depth(&self) -> usize {
        let mut best = 0;
        let mut stack = vec![(0u32, 1usize)];
        while let Some((n, d)) = stack.pop() {
            best = best.max(d);
            if let Node::Inner { left, right, .. } = self.nodes[n as usize] {
                stack.push((left, d + 1));
                stack.push((right, d + 1));
            }
        }
        best
    }

    /// Every primitive reachable exactly once, child boxes inside parents,
    /// leaves' boxes holding their triangles, depth within [`MAX_DEPTH`].
    pub fn validate(&self, mesh: &Mesh) -> Result<(), String> {
        let boxes = tri_bounds(mesh);
        let mut seen = vec![0u8; mesh.len()];
        let mut stack = vec![(0u32, 1usize)];
        let mut visited = 0;
        while let Some((n, d)) = stack.pop() {
            visited += 1;
            if d > MAX_DEPTH {
                return Err(format!("node {n} at depth {d} beyond {MAX_DEPTH}"));
            }
            match self
                .nodes
                .get(n as usize)
                .ok_or_else(|| format!("node {n} does not exist"))?
            {
                Node::Inner {
                    bounds,
                    left,
                    right,
                } => {
                    for c in [*left, *right] {
                        let cb = self
                            .nodes
                            .get(c as usize)
                            .ok_or_else(|| format!("child {c} does not exist"))?
                            .bounds();
                        if !bounds.contains(cb) {
                            return Err(format!(
                                "child {c} box {cb:?} outside parent {n} {bounds:?}"
                            ));
                        }
                        stack.push((c, d + 1));
                    }
                }
                Node::Leaf {
                    bounds,
                    first,
                    count,
                } => {
                    for &p in &self.prims[*first as usize..(*first + *count) as usize] {
                        if !bounds.contains(&boxes[p as usize]) {
                            return Err(format!("triangle {p} outside leaf {n}"));
                        }
                        seen[p as usize] += 1;
                    }
                }
            }
        }
        if visited != self.nodes.len() {
            return Err(format!("{} nodes unreachable", self.nodes.len() - visited));
        }
        if let Some(p) = seen.iter().position(|&c| c != 1) {
            return Err(format!("triangle {p} reached {} times", seen[p]));
        }
        Ok(())
    }
}

/// Levels of the build whose large nodes split their subtrees onto two
/// threads (up to 2^levels at once; more than a 2-core machine needs, so
/// uneven SAH splits still keep both cores busy).
const PAR_LEVELS: usize = 4;

/// Smallest node whose subtrees are built on two threads.
const PAR_MIN_PRIMS: usize = 1 << 16;

/// What every step of one build reads.
struct BuildCtx<'a> {
    boxes: &'a [Aabb],
    centres: &'a [[f32; 3]],
    cfg: &'a BuildConfig,
    min_prims: usize,
}

/// One node's outcome: a leaf, or an inner node whose primitives were
/// partitioned at `mid` (left part first).
enum Step {
    Leaf(Aabb),
    Split(Aabb, usize),
}

/// Decide the node over `prims` at `depth`, partitioning them if it splits.
fn step(ctx: &BuildCtx, prims: &mut [u32], depth: usize) -> Step {
    let bounds = prims
        .iter()
        .fold(Aabb::EMPTY, |b, &p| b.union(&ctx.boxes[p as usize]));
    let n = prims.len();
    let split = if depth + 1 >= MAX_DEPTH {
        None
    } else {
        sah_split(prims, ctx.boxes, ctx.centres, &bounds, ctx.cfg)
    };
    let leaf_cost = n as f32;
    // A leaf when small enough and no split is cheaper; a node that is
    // too big but cannot be split by SAH (identical centroids) is split
    // in half so leaves stay within max_leaf.
    let make_leaf = n <= 1
        || depth + 1 >= MAX_DEPTH
        || (n <= ctx.cfg.max_leaf && split.is_none_or(|(_, _, cost)| leaf_cost <= cost));
    if make_leaf {
        return Step::Leaf(bounds);
    }
    let (axis, pos, _) = split.unwrap_or((0, f32::NAN, 0.0));
    // Partition by centroid bin.
    let mut mid = 0;
    for i in 0..n {
        if ctx.centres[prims[i] as usize][axis] < pos {
            prims.swap(i, mid);
            mid += 1;
        }
    }
    if mid == 0 || mid == n {
        mid = n / 2; // all centroids in one bin: split the list in half
    }
    Step::Split(bounds, mid)
}

/// The subtree over `prims` (the whole list's from index `offset`) at
/// `depth`, its root at index 0: built by [`sequential`], or, `levels`
/// above the bottom and large enough, its two subtrees on two threads and
/// joined in [`sequential`]'s numbering.
fn subtree(
    ctx: &BuildCtx,
    prims: &mut [u32],
    (offset, depth): (usize, usize),
    levels: usize,
) -> Vec<Node> {
    if levels == 0 || prims.len() < ctx.min_prims {
        return sequential(ctx, prims, (offset, depth));
    }
    match step(ctx, prims, depth) {
        Step::Leaf(bounds) => vec![leaf(bounds, offset, prims.len())],
        Step::Split(bounds, mid) => {
            let (lp, rp) = prims.split_at_mut(mid);
            let (l, r) = std::thread::scope(|s| {
                let right = s.spawn(|| subtree(ctx, rp, (offset + mid, depth + 1), levels - 1));
                let l = subtree(ctx, lp, (offset, depth + 1), levels - 1);
                let r = right
                    .join()
                    .unwrap_or_else(|e| std::panic::resume_unwind(e));
                (l, r)
            });
            join_subtrees(bounds, l, r)
        }
    }
}

/// A leaf over `count` primitives from index `first`.
fn leaf(bounds: Aabb, first: usize, count: usize) -> Node {
    Node::Leaf {
        bounds,
        first: first as u32,
        count: count as u32,
    }
}

/// The subtree over `prims` on this thread, depth first (left child first),
/// each node's two children numbered when it splits.
fn sequential(ctx: &BuildCtx, prims: &mut [u32], (offset, depth0): (usize, usize)) -> Vec<Node> {
    let mut nodes = vec![leaf(Aabb::EMPTY, 0, 0)];
    // (node index, start, end, depth)
    let mut work = vec![(0usize, 0usize, prims.len(), depth0)];
    while let Some((ni, s, e, depth)) = work.pop() {
        match step(ctx, &mut prims[s..e], depth) {
            Step::Leaf(bounds) => nodes[ni] = leaf(bounds, offset + s, e - s),
            Step::Split(bounds, m) => {
                let l = nodes.len();
                nodes.extend([leaf(Aabb::EMPTY, 0, 0); 2]);
                nodes[ni] = Node::Inner {
                    bounds,
                    left: l as u32,
                    right: l as u32 + 1,
                };
                work.push((l + 1, s + m, e, depth + 1));
                work.push((l, s, s + m, depth + 1));
            }
        }
    }
    nodes
}

/// An inner node over subtrees `l` and `r` (each rooted at its index 0),
/// numbered as [`sequential`] numbers them: the root, its two children,
/// then the left child's descendants, then the right child's.
fn join_subtrees(bounds: Aabb, l: Vec<Node>, r: Vec<Node>) -> Vec<Node> {
    let nl = l.len();
    let renumber = |node: Node, at: &dyn Fn(u32) -> u32| match node {
        Node::Inner {
            bounds,
            left,
            right,
        } => Node::Inner {
            bounds,
            left: at(left),
            right: at(right),
        },
        leaf => leaf,
    };
    let in_l = |k: u32| if k == 0 { 1 } else { k + 2 };
    let in_r = |k: u32| if k == 0 { 2 } else { nl as u32 + 1 + k };
    let mut out = Vec::with_capacity(1 + nl + r.len());
    out.push(Node::Inner {
        bounds,
        left: 1,
        right: 2,
    });
    out.push(renumber(l[0], &in_l));
    out.push(renumber(r[0], &in_r));
    out.extend(l[1..].iter().map(|&n| renumber(n, &in_l)));
    out.extend(r[1..].iter().map(|&n| renumber(n, &in_r)));
    out
}

/// Best binned-SAH split of `prims`: (axis, position, cost relative to a
/// primitive test), or None if no split beats keeping them together.
fn sah_split(
    prims: &[u32],
    boxes: &[Aabb],
    centres: &[[f32; 3]],
    bounds: &Aabb,
    cfg: &BuildConfig,
) -> Option<(usize, f32, f32)> {
    let mut cb = Aabb::EMPTY;
    for &p in prims {
        cb.grow(centres[p as usize]);
    }
    let area = bounds.area().max(f32::MIN_POSITIVE);
    let nb = cfg.bins;
    let mut best: Option<(usize, f32, f32)> = None;
    for axis in 0..3 {
        let (lo, hi) = (cb.lo[axis], cb.hi[axis]);
        if hi <= lo || !(hi - lo).is_finite() {
            continue;
        }
        let scale = nb as f32 / (hi - lo);
        let mut bin_box = vec![Aabb::EMPTY; nb];
        let mut bin_n = vec![0usize; nb];
        for &p in prims {
            let b = (((centres[p as usize][axis] - lo) * scale) as usize).min(nb - 1);
            bin_box[b] = bin_box[b].union(&boxes[p as usize]);
            bin_n[b] += 1;
        }
        // Sweep: right-to-left areas, then left-to-right.
        let mut right_area = vec![0f32; nb];
        let mut right_n = vec![0usize; nb];
        let (mut acc, mut cnt) = (Aabb::EMPTY, 0);
        for b in (1..nb).rev() {
            acc = acc.union(&bin_box[b]);
            cnt += bin_n[b];
            right_area[b] = acc.area();
            right_n[b] = cnt;
        }
        let (mut acc, mut cnt) = (Aabb::EMPTY, 0);
        for b in 1..nb {
            acc = acc.union(&bin_box[b - 1]);
            cnt += bin_n[b - 1];
            if cnt == 0 || right_n[b] == 0 {
                continue;
            }
            let cost =
                cfg.c_trav + (acc.area() * cnt as f32 + right_area[b] * right_n[b] as f32) / area;
            if best.is_none_or(|x| cost < x.2) {
                best = Some((axis, lo + b as f32 / scale, cost));
            }
        }
    }
    best
}

/// BVH2 memory layout, one 64-byte line per inner node (DRS: "both
/// children's boxes in one line"), each axis as the DRS Appendix A reads it,
/// `[min_l, min_r, max_l, max_r]`, one 16-byte load (broadcast to both
/// 128-bit halves on AVX2):
///
/// | bytes | field |
/// |---|---|
/// | 0..16 | x: min_l, min_r, max_l, max_r (f32) |
/// | 16..32 | y: the same |
/// | 32..48 | z: the same |
/// | 48..52 | left child ref |
/// | 52..56 | right child ref |
/// | 56..64 | padding |
///
/// A child ref is a node index, or `LEAF | (blocks - 1) << LEAF_BLOCKS_SHIFT
/// | first block`: the leaf's triangles in `blocks` consecutive 8-triangle
/// blocks (one block for leaves of up to 8 triangles, where the first block
/// is the leaf's index in the leaf table of (`first`, `count`) u32 pairs). The root's own box is stored
/// beside the tree (`root_bounds`).
#[derive(Clone, Debug)]
pub struct Bvh2Layout {
    /// Inner nodes, 64 bytes each.
    pub nodes: Vec<[u32; 16]>,
    /// Leaves: (first prim, count).
    pub leaves: Vec<[u32; 2]>,
    /// Each leaf's box.
    pub leaf_bounds: Vec<Aabb>,
    /// Root bounds.
    pub root_bounds: Aabb,
    /// Reference to the root (a node, or a leaf for a one-leaf tree).
    pub root: u32,
    /// Triangle blocks the leaves take (8 triangles a block).
    pub blocks: u32,
}

/// Flag marking a child ref as a leaf.
pub const LEAF: u32 = 1 << 31;
/// Bit position of a BVH2 leaf ref's block count minus one (7 bits).
pub const LEAF_BLOCKS_SHIFT: u32 = 24;
/// Mask of a BVH2 leaf ref's first block.
pub const LEAF_FIRST_MASK: u32 = (1 << LEAF_BLOCKS_SHIFT) - 1;
/// Most blocks in one BVH2 leaf (7 bits of count): 1024 triangles.
pub const LEAF_MAX_BLOCKS: u32 = 128;

const _: () = assert!(std::mem::size_of::<[u32; 16]>() == 64);

impl Bvh2Layout {
    /// Lay out a built BVH2.
    #[must_use]
    pub fn new(b: &Bvh2) -> Bvh2Layout {
        let mut out = Bvh2Layout {
            nodes: Vec::new(),
            leaves: Vec::new(),
            leaf_bounds: Vec::new(),
            root_bounds: *b.nodes[0].bounds(),
            root: 0,
            blocks: 0,
        };
        out.root = out.emit(b, 0);
        out
    }

    fn emit(&mut self, b: &Bvh2, n: u32) -> u32 {
        match b.nodes[n as usize] {
            Node::Leaf {
                first,
                count,
                bounds,
            } => {
                self.leaves.push([first, count]);
                self.leaf_bounds.push(bounds);
                let n = count.div_ceil(8).max(1);
                assert!(
                    n <= LEAF_MAX_BLOCKS && self.blocks + n <= LEAF_FIRST_MASK,
                    "leaf of {count} triangles at block {}: beyond the leaf ref's fields",
                    self.blocks
                );
                let r = LEAF | ((n - 1) << LEAF_BLOCKS_SHIFT) | self.blocks;
                self.blocks += n;
                r
            }
            Node::Inner { left, right, .. } => {
                let me = self.nodes.len();
                self.nodes.push([0; 16]);
                let l = self.emit(b, left);
                let r = self.emit(b, right);
                let mut rec = [0u32; 16];
                for (k, c) in [left, right].iter().enumerate() {
                    let bx = b.nodes[*c as usize].bounds();
                    for a in 0..3 {
                        rec[4 * a + k] = bx.lo[a].to_bits();
                        rec[4 * a + 2 + k] = bx.hi[a].to_bits();
                    }
                }
                rec[12] = l;
                rec[13] = r;
                self.nodes[me] = rec;
                me as u32
            }
        }
    }

    /// Bytes of the node array.
    #[must_use]
    pub fn node_bytes(&self) -> usize {
        self.nodes.len() * 64
    }
}

/// A BVH4 node (host form), children in order c0, c1, c2, c3.
#[derive(Clone, Debug, PartialEq)]
pub struct Node4 {
    /// Child boxes (EMPTY for an unused slot).
    pub bounds: [Aabb; 4],
    /// Child refs: a node index, `LEAF | leaf index`, or `EMPTY_SLOT`.
    pub child: [u32; 4],
}

/// An unused BVH4 child slot.
pub const EMPTY_SLOT: u32 = u32::MAX;

/// BVH4 (also the MBVH ray-stream paper's node: 4 child boxes in SoA) made by collapsing a BVH2: a node's children are its BVH2 child's
/// children (c0, c1 from the left, c2, c3 from the right), so siblings that
/// are near each other stay grouped as the DRS paper's 2-level order needs.
/// Memory layout per node (128 bytes, two lines):
///
/// | bytes | field |
/// |---|---|
/// | 0..96 | SoA boxes: min_x[4] max_x[4] min_y[4] max_y[4] min_z[4] max_z[4] (f32) |
/// | 96..112 | child refs[4] (u32) |
/// | 112..116 | valid-children mask (bit c: child c exists) |
/// | 116..128 | padding |
#[derive(Clone, Debug)]
pub struct Bvh4 {
    /// Nodes; node 0 is the root.
    pub nodes: Vec<Node4>,
    /// Leaves: (first prim, count) into the BVH2's `prims`.
    pub leaves: Vec<[u32; 2]>,
    /// Root bounds.
    pub root_bounds: Aabb,
}

/// Bytes of a laid-out BVH4 node.
pub const NODE4_BYTES: usize = 128;

const _: () = assert!(std::mem::size_of::<[u32; 32]>() == NODE4_BYTES);

impl Bvh4 {
    /// Collapse a BVH2.
    #[must_use]
    pub fn collapse(b: &Bvh2) -> Bvh4 {
        let mut out = Bvh4 {
            nodes: Vec::new(),
            leaves: Vec::new(),
            root_bounds: *b.nodes[0].bounds(),
        };
        match b.nodes[0] {
            Node::Leaf { .. } => {
                // A single leaf: a root with one child.
                out.nodes.push(Node4 {
                    bounds: [Aabb::EMPTY; 4],
                    child: [EMPTY_SLOT; 4],
                });
                let r = out.child_ref(b, 0);
                out.nodes[0].bounds[0] = *b.nodes[0].bounds();
                out.nodes[0].child[0] = r;
            }
            Node::Inner { .. } => {
                out.emit(b, 0);
            }
        }
        out
    }

    fn child_ref(&mut self, b: &Bvh2, n: u32) -> u32 {
        match b.nodes[n as usize] {
            Node::Leaf { first, count, .. } => {
                self.leaves.push([first, count]);
                LEAF | (self.leaves.len() as u32 - 1)
            }
            Node::Inner { .. } => self.emit(b, n),
        }
    }

    /// Emit BVH2 inner node `n` as a BVH4 node; returns its index.
    fn emit(&mut self, b: &Bvh2, n: u32) -> u32 {
        let me = self.nodes.len();
        self.nodes.push(Node4 {
            bounds: [Aabb::EMPTY; 4],
            child: [EMPTY_SLOT; 4],
        });
        let Node::Inner { left, right, .. } = b.nodes[n as usize] else {
            unreachable!("inner")
        };
        let mut slots: Vec<u32> = Vec::with_capacity(4);
        for side in [left, right] {
            match b.nodes[side as usize] {
                Node::Inner {
                    left: l, right: r, ..
                } => {
                    slots.push(l);
                    slots.push(r);
                }
                Node::Leaf { .. } => slots.push(side),
            }
        }
        for (k, &c) in slots.iter().enumerate() {
            let r = self.child_ref(b, c);
            self.nodes[me].bounds[k] = *b.nodes[c as usize].bounds();
            self.nodes[me].child[k] = r;
        }
        me as u32
    }

    /// The 128-byte record of node `i` as u32 words. An unused slot's box is
    /// the point (+inf, +inf, +inf) (an inverted box would become an infinite
    /// slab under a min/max slab test), and kernels mask their hit bits with
    /// the valid-children word: a ray with t_far = inf still "reaches" +inf.
    #[must_use]
    pub fn record(&self, i: usize) -> [u32; 32] {
        let n = &self.nodes[i];
        let mut r = [0u32; 32];
        for c in 0..4 {
            let (lo, hi) = if n.child[c] == EMPTY_SLOT {
                ([f32::INFINITY; 3], [f32::INFINITY; 3])
            } else {
                (n.bounds[c].lo, n.bounds[c].hi)
            };
            for a in 0..3 {
                r[8 * a + c] = lo[a].to_bits();
                r[8 * a + 4 + c] = hi[a].to_bits();
            }
            r[24 + c] = n.child[c];
            if n.child[c] != EMPTY_SLOT {
                r[28] |= 1 << c;
            }
        }
        r
    }

    /// Every primitive reachable once, child boxes inside the box the parent
    /// holds for them, depth within [`MAX_DEPTH`].
    pub fn validate(&self, b: &Bvh2, mesh: &Mesh) -> Result<(), String> {
        let boxes = tri_bounds(mesh);
        let mut seen = vec![0u8; mesh.len()];
        let mut stack = vec![(0u32, self.root_bounds, 1usize)];
        while let Some((n, pb, d)) = stack.pop() {
            if d > MAX_DEPTH {
                return Err(format!("BVH4 node {n} beyond depth {MAX_DEPTH}"));
            }
            let node = self
                .nodes
                .get(n as usize)
                .ok_or_else(|| format!("BVH4 node {n} does not exist"))?;
            for c in 0..4 {
                let r = node.child[c];
                if r == EMPTY_SLOT {
                    continue;
                }
                let cb = node.bounds[c];
                if !pb.contains(&cb) {
                    return Err(format!("BVH4 node {n} child {c} outside its parent"));
                }
                if r & LEAF != 0 {
                    let [first, count] = self.leaves[(r & !LEAF) as usize];
                    for &p in &b.prims[first as usize..(first + count) as usize] {
                        if !cb.contains(&boxes[p as usize]) {
                            return Err(format!("triangle {p} outside its BVH4 leaf box"));
                        }
                        seen[p as usize] += 1;
                    }
                } else {
                    stack.push((r, cb, d + 1));
                }
            }
        }
        if let Some(p) = seen.iter().position(|&c| c != 1) {
            return Err(format!(
                "triangle {p} reached {} times in the BVH4",
                seen[p]
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A seeded soup of small triangles.
    fn soup(n: usize, seed: u64) -> Mesh {
        let mut r = isa::rng::Rng::new(seed);
        let mut m = Mesh::default();
        for i in 0..n {
            let c = [
                r.range(-10.0, 10.0),
                r.range(-10.0, 10.0),
                r.range(-10.0, 10.0),
            ];
            for _ in 0..3 {
                m.positions.push([
                    c[0] + r.range(-0.5, 0.5),
                    c[1] + r.range(-0.5, 0.5),
                    c[2] + r.range(-0.5, 0.5),
                ]);
            }
            m.tris
                .push([3 * i as u32, 3 * i as u32 + 1, 3 * i as u32 + 2]);
        }
        m
    }

    #[test]
    fn subtrees_on_threads_give_the_one_thread_tree_node_for_node() {
        // Degenerate cases too: one triangle, identical centroids (split in
        // half), and leaves too deep for MAX_DEPTH never reached here.
        let mut same = soup(300, 5);
        for p in &mut same.positions {
            *p = [1.0, 2.0, 3.0];
        }
        for (m, cfg) in [
            (soup(1, 9), BuildConfig::default()),
            (soup(5000, 11), BuildConfig::default()),
            (soup(5000, 11), BuildConfig::LARGE_LEAVES),
            (same, BuildConfig::default()),
        ] {
            let one = Bvh2::build_par(&m, &cfg, (0, 0)).unwrap();
            for split in [(1, 2), (3, 64), (6, 2)] {
                let par = Bvh2::build_par(&m, &cfg, split).unwrap();
                assert_eq!(par.nodes, one.nodes, "{split:?}");
                assert_eq!(par.prims, one.prims, "{split:?}");
                par.validate(&m).unwrap();
            }
        }
    }

    #[test]
    fn builds_validate_and_collapse() {
        for (n, cfg) in [
            (1, BuildConfig::default()),
            (2, BuildConfig::default()),
            (1000, BuildConfig::default()),
            (1000, BuildConfig::LARGE_LEAVES),
        ] {
            let m = soup(n, 3);
            let b = Bvh2::build(&m, &cfg).unwrap();
            b.validate(&m).unwrap();
            let b4 = Bvh4::collapse(&b);
            b4.validate(&b, &m).unwrap();
            let lay = Bvh2Layout::new(&b);
            assert_eq!(lay.leaves.len() + lay.nodes.len(), b.nodes.len());
            assert!(b.sah_cost(cfg.c_trav) > 0.0);
        }
        let m = soup(1000, 3);
        let deep = Bvh2::build(&m, &BuildConfig::default()).unwrap();
        let shallow = Bvh2::build(&m, &BuildConfig::LARGE_LEAVES).unwrap();
        assert!(
            shallow.depth() < deep.depth(),
            "shallow {} < deep {}",
            shallow.depth(),
            deep.depth()
        );
    }

    #[test]
    fn identical_centroids_still_split_and_validate() {
        let mut m = Mesh::default();
        for i in 0..100u32 {
            m.positions
                .extend([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
            m.tris.push([3 * i, 3 * i + 1, 3 * i + 2]);
        }
        let b = Bvh2::build(&m, &BuildConfig::default()).unwrap();
        b.validate(&m).unwrap();
        Bvh4::collapse(&b).validate(&b, &m).unwrap();
    }

    #[test]
    fn empty_mesh_is_an_error_and_validate_catches_damage() {
        assert!(Bvh2::build(&Mesh::default(), &BuildConfig::default())
            .unwrap_err()
            .contains("empty"));
        let m = soup(50, 1);
        let mut b = Bvh2::build(&m, &BuildConfig::default()).unwrap();
        b.prims[0] = b.prims[1];
        assert!(
            b.validate(&m).is_err(),
            "a triangle reached twice is caught"
        );
    }
}
