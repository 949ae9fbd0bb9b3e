//! The kernel tests use the library's harness.

pub use kernels::harness::{mismatches, Kernel, Run};
