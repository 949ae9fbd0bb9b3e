//! Named statistics counters of the traversal kernels, counted on the host
//! while a kernel runs (kernels execute on real values, so the counts are
//! exact and the same on every backend).

/// Ray-node and ray-leaf tests of one kernel run. A ray-node test is one ray
/// against one inner node's child boxes (2 for BVH2, 4 for BVH4); a ray-leaf
/// test is one ray against one leaf's triangle block.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Tests {
    /// Ray-node tests inside a ray stream core loop (padding not counted).
    pub core_loop: u64,
    /// Ray-node tests elsewhere (single-ray traversal and fallback).
    pub other: u64,
    /// Ray-leaf tests.
    pub leaf: u64,
    /// Stack entries popped and culled (entry farther than the hit so far)
    /// before any test.
    pub culled: u64,
}

impl Tests {
    /// All ray-node tests.
    #[must_use]
    pub fn node_tests(&self) -> u64 {
        self.core_loop + self.other
    }
    /// Share of ray-node tests done in the core loop (the DRS paper's 76-88%).
    #[must_use]
    pub fn core_loop_share(&self) -> f64 {
        if self.node_tests() == 0 {
            0.0
        } else {
            self.core_loop as f64 / self.node_tests() as f64
        }
    }
}

/// Frustum and packet counters of the MFT paper's Table 1 (its frusta and
/// its 16-ray packet baseline count the same things).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MftStats {
    /// 16-wide AABB tests (one per child box per visited node).
    pub aabb_tests: u64,
    /// Triangles fetched at leaves (once per leaf visit for all frusta).
    pub tris_accessed: u64,
    /// Triangles left for intersection after back-face and corner culling.
    pub tris_after_culling: u64,
    /// 16-wide ray-triangle tests (one per frustum per surviving triangle).
    pub isec_tests: u64,
    /// Frustum shrinks (CR, FS: the paper's "# addl. tests").
    pub shrinks: u64,
    /// Per-frustum ray-packet tests against leaf boxes (Ray-AABB; also
    /// counted in `aabb_tests`, as the paper's Table 2 does).
    pub leaf_box_tests: u64,
}

impl MftStats {
    /// Add `o`'s counts.
    pub fn add(&mut self, o: MftStats) {
        self.aabb_tests += o.aabb_tests;
        self.tris_accessed += o.tris_accessed;
        self.tris_after_culling += o.tris_after_culling;
        self.isec_tests += o.isec_tests;
        self.shrinks += o.shrinks;
        self.leaf_box_tests += o.leaf_box_tests;
    }
}
