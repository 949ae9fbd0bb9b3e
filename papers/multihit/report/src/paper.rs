//! What the paper states, as data (its Figure 2 is a graph without printed
//! values; its statements are these).

/// "improves performance by as much as 2x relative to naive multi-hit"
/// (abstract); averaged over the eight scenes, "a factor of 2 when
/// N_query = 1" (section 3).
pub const SPEEDUP_AT_ONE: f64 = 2.0;

/// "as N_query -> 70%, naive multi-hit begins to outperform the
/// node-culling approach" (section 3): the crossover as a fraction of the
/// maximum hits.
pub const CROSSOVER_FRACTION: f64 = 0.70;

/// Image size and samples: "1024x768 pixel resolution using visibility
/// rays from a pinhole camera and a single sample per pixel".
pub const WIDTH: u32 = 1024;
/// See [`WIDTH`].
pub const HEIGHT: u32 = 768;

/// "two Intel Xeon E5-2650 v3 processors (20 cores, 40 hardware threads)".
pub const SOCKETS: u32 = 2;
