//! Trace format version 4: the legacy decoders' complex-only and
//! macro-fusible facts round-trip through both forms; version 3 files
//! (lengths and length-changing prefixes) still read.

use crate::hex;
use isa::{trace_file, trace_text};

/// A version-3 file written by the version-3 writer (rtsim at 3a2f4d5,
/// `rtsim trace text` of [`V3_TEXT`]).
const V3_FILE: &str = "525453494d54524303000200000107076973612d6c75748080808001400500a108148309028504a6080700109080808002210902a8810202018fb4e341228f6d9b";

const V3_TEXT: &str = ".trace 1\n.isa avx2\n.mem 0 lut isa-lut 0x10000000 64\n%1 = alu len=4 lcp\n\
                       %2 = vdiv %1 w=16 len=5\n%3 = load @0+0x8:8 len=7\n%4 = alu %3\n\
                       branch %4 site=1 taken len=2\n";

#[test]
fn complex_and_fusible_round_trip() {
    let text = ".trace 1\n.isa avx2\n.mem 0 lut isa-lut 0x10000000 64\n%1 = alu len=2 complex\n\
                %2 = alu %1 len=3 fusible\n%3 = cmp %2 len=3\n%4 = vdiv w=16 len=5 lcp complex fusible\n";
    let t = trace_text::parse(text).unwrap();
    let got: Vec<(bool, bool, bool)> = t
        .ops
        .iter()
        .map(|o| (o.complex(), o.fusible(), o.lcp()))
        .collect();
    // A compare can always fuse; only the flag is written.
    assert_eq!(
        got,
        [
            (true, false, false),
            (false, true, false),
            (false, true, false),
            (true, true, true)
        ]
    );
    assert!(!trace_text::write(&t).contains("cmp %2 len=3 fusible"));
    let bin = trace_file::encode(&t);
    assert_eq!(&bin[8..10], &4u16.to_le_bytes());
    assert_eq!(trace_file::decode(&bin).unwrap(), t);
    assert_eq!(trace_text::parse(&trace_text::write(&t)).unwrap(), t);
}

#[test]
fn version_3_files_still_read() {
    let want = trace_text::parse(V3_TEXT).unwrap();
    let got = trace_file::decode(&hex(V3_FILE)).unwrap();
    assert_eq!(got, want);
    assert!(got.ops.iter().all(|o| !o.complex() && o.flags & 16 == 0));
    assert_eq!(trace_file::decode(&trace_file::encode(&got)).unwrap(), got);
}
