//! # rtsim kernels
//!
//! Kernels written against [`isa::Machine`] only: they never see the timing
//! model. Each has a scalar reference beside it, used by the tests.

pub mod boxtest;
pub mod mesh;
pub mod micro;
