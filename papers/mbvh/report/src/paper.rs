//! The paper's own figures, as its text gives them (Tsakok 2009). Its
//! Figures 2-8 are plots without printed values: nothing here is read off
//! a plot.

/// Section 5.2: MBVH RS box fetches per ray stay below this at 7 bounces,
/// reflection and shadow rays alike.
pub const RS_FETCHES_AT_7_BELOW: f64 = 3.0;
/// Section 5.2: single-ray MBVH box fetches per ray "can reach up to" this.
pub const MBVH_FETCHES_UP_TO: f64 = 15.0;
/// Section 5.2: "around two primitive tests per ray" for primary rays (MBVH
/// RS and packets alike).
pub const PRIMARY_PRIM_TESTS: f64 = 2.0;
/// Section 5.3: 16-wide primitive-test efficiency at a 2^12 group, Conference.
pub const EFFICIENCY_16_AT_4096: f64 = 0.60;
/// Section 6: the best group size.
pub const BEST_GROUP: usize = 256;
/// Section 4: the ordered heuristic's speed-up.
pub const ORDERED_SPEEDUP: f64 = 1.18;
/// Section 4.1: replicated SoA ray data's speed-up.
pub const REPLICATED_SPEEDUP: f64 = 1.05;
/// Sections 5.4 and 6: rays per second per Core i7 core, Conference, 4 bounces.
pub const I7_RAYS_PER_CORE_4_BOUNCES: f64 = 4.0e6;

/// Tables 1 and 2: millions of rays per 512x512 frame at 16 paths per
/// pixel, for 1 to 4 bounces.
pub const RAYS_PER_FRAME_M: [f64; 4] = [12.6, 21.0, 29.0, 38.0];

/// Table 1: frames per second on the 24-core Dunnington, 1-4 bounces.
pub const TABLE1_FPS: [(&str, [f64; 4]); 3] = [
    ("bmw", [5.3, 3.3, 2.4, 1.8]),
    ("conference", [4.8, 2.7, 1.8, 1.3]),
    ("ferrari", [4.3, 2.6, 1.8, 1.3]),
];
/// Table 2: frames per second on the 8-core Core i7 with hyper-threading.
pub const TABLE2_FPS: [(&str, [f64; 4]); 3] = [
    ("bmw", [3.4, 2.1, 1.5, 1.1]),
    ("conference", [3.1, 1.8, 1.2, 0.9]),
    ("ferrari", [2.7, 1.7, 1.2, 0.9]),
];
