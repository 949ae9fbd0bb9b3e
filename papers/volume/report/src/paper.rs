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
