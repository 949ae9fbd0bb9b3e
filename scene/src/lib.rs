//! # scene
//!
//! The host side of rtsim, in f64 where it matters: meshes and their loaders,
//! scene files, BVH builders with named presets, the reference intersector,
//! the hit-agreement rules every paper checks its kernels with, and the ray
//! workloads. Nothing here is simulated.

#![warn(missing_docs)]
// Component loops over x, y, z index several arrays in step.
#![allow(clippy::needless_range_loop)]

pub mod agreement;
mod boardroom;
pub mod bvh;
pub mod bvh_cache;
pub mod hit;
pub mod loaded;
pub mod mbvh;
pub mod mesh;
pub mod mesh_cache;
pub mod multi_agreement;
pub mod reference;
pub mod refine;
pub mod scene;
mod shapes;
pub mod simplify;
pub mod transfer;
pub mod volume;
pub mod volume_bvh;
pub mod volume_ref;
pub mod workload;

pub use hit::{Hit, HitPolicy};
pub use scene::Scene;
