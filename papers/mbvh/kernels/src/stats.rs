//! The counters of the paper's Figures 4-8, counted on the host while a
//! kernel runs (kernels execute on real values, so the counts are exact and
//! the same on every backend).

/// What one kernel did over its rays.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counters {
    /// Rays traced.
    pub rays: u64,
    /// SIMD box tests: one ray against a node's box packet (MBVH RS and
    /// single-ray MBVH) or one packet against one box (packets).
    pub box_tests: u64,
    /// Box fetches: one per inner-node task for MBVH RS (shared by its active
    /// rays), one per box test for single-ray MBVH and packets.
    pub box_fetches: u64,
    /// SIMD primitive tests: a packet of rays against one triangle (MBVH RS
    /// leaves, packets) or one ray against a block of triangles (single ray).
    pub prim_tests: u64,
    /// Active lanes summed over the primitive tests (the efficiency's numerator).
    pub prim_lanes: u64,
    /// Traversal tasks popped (MBVH RS; stack entries popped otherwise).
    pub tasks: u64,
}

impl Counters {
    /// Add `o`.
    pub fn add(&mut self, o: &Counters) {
        self.rays += o.rays;
        self.box_tests += o.box_tests;
        self.box_fetches += o.box_fetches;
        self.prim_tests += o.prim_tests;
        self.prim_lanes += o.prim_lanes;
        self.tasks += o.tasks;
    }
    /// `x` per ray (0 with no rays).
    #[must_use]
    pub fn per_ray(&self, x: u64) -> f64 {
        if self.rays == 0 {
            0.0
        } else {
            x as f64 / self.rays as f64
        }
    }
    /// SIMD efficiency of primitive tests at `lanes` lanes: active lanes over lanes.
    #[must_use]
    pub fn prim_efficiency(&self, lanes: usize) -> f64 {
        if self.prim_tests == 0 {
            0.0
        } else {
            self.prim_lanes as f64 / (self.prim_tests * lanes as u64) as f64
        }
    }
}
