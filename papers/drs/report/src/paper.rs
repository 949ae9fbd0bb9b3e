//! The DRS paper's figures as data (Barringer and Akenine-Moller 2014, i7-4750HQ at
//! 2.8 GHz), and the rows and scenes its tables are made of.

use drs_kernels::methods::Kernel;

/// The paper's scenes and its Table 2: (scene, single CPI, single s/Gray,
/// ours CPI, ours s/Gray, core loop CPI, core loop s/Gray, core-loop share %).
pub const PAPER_TABLE2: [(&str, [f64; 7]); 4] = [
    ("crown", [1.40, 70.0, 1.02, 54.0, 0.61, 16.0, 76.0]),
    ("bentley", [1.28, 50.0, 0.88, 33.0, 0.61, 13.0, 88.0]),
    ("dragon", [1.29, 54.0, 0.91, 39.0, 0.60, 15.0, 86.0]),
    ("sanmiguel", [1.45, 117.0, 0.95, 81.0, 0.60, 31.0, 83.0]),
];

/// One scene of the paper's Table 1: name, (Mray/s, B/ray) per row in the
/// order of [`TABLE1_KERNELS`], traversal improvement %, ray-query share %.
pub type PaperScene1 = (&'static str, [(f64, f64); 7], f64, f64);

/// Table 1's rows: Our BVH2, Our BVH4, Single BVH2, Single BVH4, Packet BVH2,
/// Packet BVH4, Hybrid BVH4.
pub const TABLE1_KERNELS: [Kernel; 7] = [
    Kernel::DrsBvh2,
    Kernel::DrsBvh4,
    Kernel::SingleBvh2,
    Kernel::SingleBvh4,
    Kernel::PacketBvh2,
    Kernel::PacketBvh4,
    Kernel::HybridBvh4,
];

/// The paper's Table 1 (Barringer and Akenine-Moller 2014, total render speed and
/// DRAM bytes per ray, i7-4750HQ at 2.8 GHz).
pub const PAPER_TABLE1: [PaperScene1; 4] = [
    (
        "crown",
        [
            (9.9, 60.0),
            (10.6, 60.0),
            (7.8, 90.0),
            (8.7, 100.0),
            (5.2, 250.0),
            (5.4, 220.0),
            (8.3, 160.0),
        ],
        36.0,
        61.0,
    ),
    (
        "bentley",
        [
            (15.7, 40.0),
            (17.5, 40.0),
            (11.7, 80.0),
            (12.8, 70.0),
            (8.3, 100.0),
            (8.9, 120.0),
            (13.1, 90.0),
        ],
        53.0,
        64.0,
    ),
    (
        "dragon",
        [
            (13.3, 120.0),
            (15.1, 110.0),
            (9.9, 180.0),
            (11.9, 120.0),
            (8.5, 220.0),
            (8.3, 200.0),
            (11.5, 170.0),
        ],
        42.0,
        64.0,
    ),
    (
        "sanmiguel",
        [
            (7.8, 130.0),
            (9.2, 140.0),
            (5.6, 150.0),
            (6.7, 180.0),
            (4.0, 290.0),
            (4.0, 330.0),
            (6.1, 220.0),
        ],
        47.0,
        79.0,
    ),
];

/// The four scene stand-ins of the DRS paper.
pub const DRS_SCENES: [&str; 4] = ["crown", "bentley", "dragon", "sanmiguel"];
