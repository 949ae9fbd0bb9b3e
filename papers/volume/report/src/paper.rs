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
