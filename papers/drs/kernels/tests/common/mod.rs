//! The kernel tests use the library's harness.

pub use {
    drs_kernels::methods::{Kernel, Run},
    scene::agreement::mismatches,
};
