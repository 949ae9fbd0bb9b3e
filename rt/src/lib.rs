//! # rt
//!
//! Simulated ray-tracing building blocks shared by the papers' kernels,
//! written against [`isa::Machine`] only (they never see the timing model):
//! scene layouts in simulated memory, box and triangle tests, single-ray,
//! packet and hybrid traversal, the intersection-filter hook, their counters,
//! and the branch-site plan.

#![warn(missing_docs)]
// Component loops over x, y, z index several arrays in step.
#![allow(clippy::needless_range_loop)]

pub mod boxtest;
pub mod filter;
pub mod hand;
pub mod layout;
pub mod packet;
pub mod single;
pub mod stats;
