//! The DRS kernels' tests, one module per concern, in one test binary: the
//! kernels' generic code (every kernel on every flavour, traced and
//! native) is instantiated and linked once, not once per file.

mod common;
mod drs;
mod hand;
mod packet;
mod shadow;
mod single_ray;
mod warm;
