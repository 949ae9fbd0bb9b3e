//! The kernel tests' shared fixture: a scene stand-in loaded with the DRS
//! kernels' BVHs, and the library's methods and agreement rule.

// Each test module uses a different subset of these.
#![allow(dead_code)]

#[allow(unused_imports)]
pub use {
    drs_kernels::methods::{Kernel, Run},
    scene::agreement::mismatches,
    scene::loaded::Loaded,
};

/// Scene `name` with the BVH2 and BVH4 every DRS method traverses.
pub fn fixture(name: &str) -> Loaded {
    Loaded::load(name, &drs_kernels::BVH).unwrap()
}
