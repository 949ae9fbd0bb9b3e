//! The paper's Figure 5 rows we reproduce, as data: frames per second at
//! 512^2 (Core 2 Duo "bvh"; Core i7 8-core "gcc", "sse", "bvh"), the
//! lighting, the leaf size L and the data size.

/// One row of Figure 5.
pub struct Fig5Row {
    /// Our dataset's name.
    pub name: &'static str,
    /// The paper's dataset and its dimensions.
    pub paper: &'static str,
    /// Lighting: unlit (u), diffuse (d), Phong (p).
    pub lit: char,
    /// Leaf size L the paper used.
    pub leaf: u32,
    /// Core 2 Duo (2 cores) "bvh" fps.
    pub core2_bvh: f64,
    /// Core i7 (8 cores) "gcc", "sse", "bvh" fps.
    pub i7: [f64; 3],
}

/// Figure 5's rows for the data we have (engine exactly, neghip 66^3 for
/// 64^3, skull 64^3 for 256^3, the dense field for backpack/zebrafish).
pub const FIG5: [Fig5Row; 4] = [
    Fig5Row {
        name: "engine",
        paper: "engine 256x256x128",
        lit: 'u',
        leaf: 4,
        core2_bvh: 3.0,
        i7: [2.6, 10.0, 13.1],
    },
    Fig5Row {
        name: "neghip",
        paper: "neghip 64^3",
        lit: 'u',
        leaf: 1,
        core2_bvh: 7.6,
        i7: [5.5, 20.8, 33.0],
    },
    Fig5Row {
        name: "skull",
        paper: "skull 256^3",
        lit: 'd',
        leaf: 4,
        core2_bvh: 1.7,
        i7: [1.4, 5.7, 12.0],
    },
    Fig5Row {
        name: "dense",
        paper: "backpack 512x512x373",
        lit: 'd',
        leaf: 4,
        core2_bvh: 2.0,
        i7: [1.2, 4.5, 9.4],
    },
];

/// "we achieve 100% scalability to 4 threads and 97% scalability to 8
/// threads on our dual 4-core i7 workstation" (section 7.1).
pub const SCALING_AT_8: f64 = 0.97;

/// "BVH traversal occupies 10%-35% of CPU time" (section 7.3).
pub const TRAVERSAL_SHARE: (f64, f64) = (0.10, 0.35);

/// Section 7.3: the BVH's footprint against the volume's by leaf size L:
/// "48x and 4x for L = 1 and L = 2 on the neghip and bonsai, respectively",
/// "L = 4 creates a BVH with roughly equal footprint as the original
/// volume, and L = 8 is one eighth that size". (dataset, L, ratio)
pub const BVH_FOOTPRINT: [(&str, u32, f64); 3] =
    [("neghip", 1, 48.0), ("any", 4, 1.0), ("any", 8, 0.125)];

/// Table 1's stages, in its row order.
pub const TABLE1_STAGES: [&str; 8] = [
    "vox fetch",
    "interp",
    "classif",
    "blend",
    "BVH trav",
    "diffuse",
    "phong",
    "other",
];

/// One column of Table 1: the method, its filter and lighting, the
/// percentage of CPU time per stage (`None`: the paper leaves it blank) in
/// [`TABLE1_STAGES`] order, and the frames per second on the 8-core i7
/// (heptane, 512^2).
pub struct Table1Col {
    /// The paper's column label.
    pub label: &'static str,
    /// Percent of CPU time per stage.
    pub percent: [Option<f64>; 8],
    /// Frames per second.
    pub fps: f64,
}

/// Table 1 (heptane): "CPU time profile for individual algorithmic stages
/// of the naive (gcc) and hand-tuned (sse) methods".
pub const TABLE1: [Table1Col; 7] = [
    Table1Col {
        label: "gcc NN",
        percent: [
            Some(51.7),
            None,
            Some(4.5),
            Some(39.9),
            None,
            None,
            None,
            Some(3.9),
        ],
        fps: 1.4,
    },
    Table1Col {
        label: "gcc tril",
        percent: [
            Some(24.8),
            Some(61.2),
            Some(4.0),
            Some(8.2),
            None,
            None,
            None,
            Some(1.8),
        ],
        fps: 0.7,
    },
    Table1Col {
        label: "sse NN",
        percent: [
            Some(39.6),
            None,
            Some(18.1),
            Some(28.3),
            None,
            None,
            None,
            Some(14.0),
        ],
        fps: 3.9,
    },
    Table1Col {
        label: "sse tril",
        percent: [
            Some(22.3),
            Some(33.7),
            Some(8.5),
            Some(28.3),
            None,
            None,
            None,
            Some(7.2),
        ],
        fps: 3.0,
    },
    Table1Col {
        label: "sse tril BVH",
        percent: [
            Some(10.7),
            Some(36.6),
            Some(10.2),
            Some(21.0),
            Some(18.0),
            None,
            None,
            Some(3.5),
        ],
        fps: 5.5,
    },
    Table1Col {
        label: "sse tril BVH diff.",
        percent: [
            Some(9.7),
            Some(29.0),
            Some(9.4),
            Some(18.1),
            Some(15.8),
            Some(15.2),
            None,
            Some(2.7),
        ],
        fps: 4.4,
    },
    Table1Col {
        label: "sse tril BVH diff. phong",
        percent: [
            Some(8.9),
            Some(27.7),
            Some(8.6),
            Some(17.0),
            Some(14.8),
            Some(13.9),
            Some(6.5),
            Some(2.6),
        ],
        fps: 4.0,
    },
];

/// One row of Figure 6 (the Richtmyer-Meshkov data at 1024^2, Phong,
/// rda 2^-7): resolution, leaf size L, view, Core 2 Duo "bvh" (None: not
/// run) and Core i7 8-core "gcc", "sse", "bvh" frames per second.
pub struct Fig6Row {
    /// Voxels per side.
    pub n: u32,
    /// Leaf size L.
    pub leaf: u32,
    /// far, medium or close.
    pub view: &'static str,
    /// Core 2 Duo "bvh".
    pub core2_bvh: Option<f64>,
    /// Core i7 "gcc", "sse", "bvh".
    pub i7: [f64; 3],
}

const fn f6(n: u32, leaf: u32, view: &'static str, core2: Option<f64>, i7: [f64; 3]) -> Fig6Row {
    Fig6Row {
        n,
        leaf,
        view,
        core2_bvh: core2,
        i7,
    }
}

/// Figure 6's rows.
pub const FIG6: [Fig6Row; 12] = [
    f6(2048, 8, "far", None, [0.124, 0.59, 6.6]),
    f6(2048, 8, "medium", None, [0.091, 0.37, 3.5]),
    f6(2048, 8, "close", None, [0.104, 0.29, 2.4]),
    f6(1024, 8, "far", Some(1.5), [0.20, 0.92, 10.8]),
    f6(1024, 8, "medium", Some(0.71), [0.11, 0.62, 4.6]),
    f6(1024, 8, "close", Some(0.38), [0.088, 2.2, 2.4]),
    f6(512, 4, "far", Some(1.9), [0.64, 2.2, 12.9]),
    f6(512, 4, "medium", Some(1.0), [0.18, 1.0, 5.1]),
    f6(512, 4, "close", Some(0.86), [0.19, 0.82, 3.7]),
    f6(256, 2, "far", Some(2.0), [1.2, 5.3, 14.0]),
    f6(256, 2, "medium", Some(0.98), [0.44, 1.8, 5.6]),
    f6(256, 2, "close", Some(0.90), [0.36, 1.5, 4.0]),
];

/// Figure 7: differential sampling steps rda = 2^-8 .. 2^-5 and the
/// frames per second (2k^3 Richtmyer-Meshkov at 512^2, 8-core i7).
pub const FIG7: [(i32, f64); 4] = [(-8, 6.2), (-7, 10.0), (-6, 11.1), (-5, 15.8)];

/// Section 7.1: "Doubling the sampling rate typically incurs only
/// 1.2x-1.8x decrease in performance."
pub const DOUBLING_COST: (f64, f64) = (1.2, 1.8);
