//! The MFT paper's figures as data (Benthin and Wald 2009, one Larrabee
//! core, 4 threads): Tables 1 and 2.

use mft_kernels::Shrink;

/// The paper's Table 1 for one scene: per method (p-packet, p-frusta,
/// s-packet, s-frusta): tris accessed (K), tris after culling (K, if given),
/// AABB tests (K), isec tests (K), cycles (M), cycles with shading (M, if given).
pub type PaperRow = (f64, Option<f64>, f64, f64, f64, Option<f64>);

/// The paper's Table 1: (scene key, the paper's scene name, its rows in the
/// order of [`METHODS`]).
pub const PAPER: [(&str, &str, [PaperRow; 4]); 4] = [
    (
        "trex",
        "T-Rex",
        [
            (399.0, None, 1218.0, 399.0, 94.1, Some(104.3)),
            (173.0, Some(42.0), 58.0, 125.0, 19.5, Some(29.6)),
            (10957.0, Some(7298.0), 36234.0, 7698.0, 2572.0, None),
            (3575.0, Some(725.0), 1518.0, 5527.0, 635.0, None),
        ],
    ),
    (
        "fern",
        "Fern",
        [
            (655.0, Some(466.0), 2408.0, 466.0, 163.9, Some(175.2)),
            (414.0, Some(156.0), 204.0, 315.0, 47.9, Some(58.6)),
            (15882.0, Some(8277.0), 34197.0, 10801.0, 3272.0, None),
            (4325.0, Some(1668.0), 2414.0, 10606.0, 977.5, None),
        ],
    ),
    (
        "saloon",
        "Saloon",
        [
            (383.0, Some(278.0), 5839.0, 278.0, 246.9, Some(257.4)),
            (204.0, Some(34.0), 388.0, 150.0, 31.5, Some(42.2)),
            (5332.0, Some(3209.0), 81023.0, 3209.0, 2672.0, None),
            (2730.0, Some(340.0), 5419.0, 2218.0, 437.0, None),
        ],
    ),
    (
        "fairy",
        "Fairy Forest",
        [
            (587.0, Some(524.0), 3651.0, 524.0, 209.0, Some(222.5)),
            (403.0, Some(111.0), 235.0, 312.0, 49.5, Some(63.2)),
            (6556.0, Some(4290.0), 51765.0, 4290.0, 2535.0, None),
            (3461.0, Some(775.0), 3121.0, 3874.0, 637.0, None),
        ],
    ),
];

/// Table 1's methods: primary packets, primary frusta, shadow packets,
/// shadow frusta.
pub const METHODS: [&str; 4] = ["p-packet", "p-frusta", "s-packet", "s-frusta"];

/// The paper's Table 2 (T-Rex, 1024 x 1024, shadow frusta only): per
/// variant, tris accessed (K), after culling (K), AABB tests (K), isec tests
/// (K), additional tests (K, CR and FS).
pub const PAPER_TABLE2: [(Shrink, [f64; 4], Option<f64>); 4] = [
    (Shrink::None, [3401.0, 613.0, 1459.0, 5402.0], None),
    (Shrink::RayAabb, [2896.0, 498.0, 3733.0, 3973.0], None),
    (
        Shrink::CornerRays,
        [3401.0, 512.0, 1459.0, 4261.0],
        Some(386.0),
    ),
    (
        Shrink::Intervals,
        [3138.0, 503.0, 1433.0, 4168.0],
        Some(386.0),
    ),
];
