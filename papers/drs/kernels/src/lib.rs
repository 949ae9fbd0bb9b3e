//! # drs-kernels
//!
//! The DRS paper's simulated code (Barringer and Akenine-Moller 2014,
//! "Dynamic Ray Stream Traversal"): dynamic ray stream traversal over a BVH4
//! ([`bvh4`]) and a BVH2 ([`bvh2`]), their shared software-pipelined core
//! loop ([`pipeline`]), and [`methods`],
//! the seven traversal methods its Table 1 compares, run over one ray stream.

#![warn(missing_docs)]
// Component loops over x, y, z index several arrays in step.
#![allow(clippy::needless_range_loop)]

pub mod bvh2;
pub mod bvh4;
pub mod methods;
mod pipeline;
pub mod stream;

/// The BVH the DRS kernels traverse: binned SAH with leaves of up to 8
/// triangles (one 8-wide triangle block per leaf), traversal cost 1; the
/// BVH4 is collapsed from it. Every method of Table 1 uses the same trees.
pub const BVH: scene::bvh::BuildConfig = scene::bvh::BuildConfig {
    bins: 16,
    max_leaf: 8,
    c_trav: 1.0,
};
