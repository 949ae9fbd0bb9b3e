//! The ISA crate's tests, one module per concern, in one test binary (the
//! flavours' generic code instantiated and linked once, not once per file).

mod expansions;
mod format_v2;
mod format_v3;
mod format_v4;
mod ops;
mod props;

/// Bytes from hex digits (a trace file written by an older writer).
fn hex(s: &str) -> Vec<u8> {
    (0..s.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&s[i..i + 2], 16).unwrap())
        .collect()
}
