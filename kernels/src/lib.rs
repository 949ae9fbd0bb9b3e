//! # rtsim kernels
//!
//! Kernels written against [`isa::Machine`] only: they never see the timing
//! model. Each has a scalar reference beside it, used by the tests.

// Component loops over x, y, z index several arrays in step.
#![allow(clippy::needless_range_loop)]

pub mod boxtest;
pub mod bvh;
pub mod drs;
pub mod drs2;
pub mod harness;
pub mod layout;
pub mod mesh;
pub mod mft;
pub mod micro;
pub mod packet;
pub mod reference;
pub mod scene;
pub mod shade;
pub mod single;
pub mod stats;
pub mod workload;
