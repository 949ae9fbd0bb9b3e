//! The ISA crate's tests, one module per concern, in one test binary (the
//! flavours' generic code instantiated and linked once, not once per file).

mod expansions;
mod format_v2;
mod format_v3;
mod format_v4;
mod ops;
mod props;
