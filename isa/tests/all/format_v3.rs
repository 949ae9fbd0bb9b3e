//! Trace format version 3: instruction lengths and length-changing
//! prefixes (what a front end's legacy decoders need) round-trip through
//! both forms (written as version 4 now); version 2 files still read.

use crate::hex;
use isa::{trace_file, trace_text};

/// A version-2 file written by the version-2 writer (rtsim at 0b4df53,
/// `rtsim trace text` of [`V2_TEXT`]): operand widths, a store's address
/// source, a load's site.
const V2_FILE: &str = "525453494d54524302000200000107076973612d6c75748080808001400500830810ab090204210827020204001190808080022608001100072bd40567e2750334";

const V2_TEXT: &str = ".trace 1\n.isa avx2\n.mem 0 lut isa-lut 0x10000000 64\n%1 = vdiv w=16\n\
                       %2 = div %1 w=4\n%3 = alu\nstore %2 @0+0x8:8 addr=%3\n%4 = load @0+0x8:8 site=7\n";

#[test]
fn instruction_lengths_and_lcp_round_trip() {
    let text = ".trace 1\n.isa avx2\n.mem 0 lut isa-lut 0x10000000 64\n%1 = alu len=4 lcp\n\
                %2 = vdiv %1 w=16 len=5\n%3 = load @0+0x8:8 len=7\n%4 = alu %3\n\
                branch %4 site=1 taken len=2\n";
    let t = trace_text::parse(text).unwrap();
    let got: Vec<(u8, bool, u32)> = t.ops.iter().map(|o| (o.ilen, o.lcp(), o.bytes)).collect();
    assert_eq!(
        got,
        [
            (4, true, 0),
            (5, false, 16),
            (7, false, 8),
            (0, false, 0),
            (2, false, 0)
        ]
    );
    let bin = trace_file::encode(&t);
    assert_eq!(&bin[8..10], &trace_file::VERSION.to_le_bytes());
    assert_eq!(trace_file::decode(&bin).unwrap(), t);
    assert_eq!(trace_text::parse(&trace_text::write(&t)).unwrap(), t);
}

#[test]
fn version_2_files_still_read() {
    let want = trace_text::parse(V2_TEXT).unwrap();
    let got = trace_file::decode(&hex(V2_FILE)).unwrap();
    assert_eq!(got, want);
    assert!(got.ops.iter().all(|o| o.ilen == 0 && !o.lcp()));
    // Written again, it is the current version and reads back the same.
    assert_eq!(trace_file::decode(&trace_file::encode(&got)).unwrap(), got);
}

#[test]
fn bad_lengths_are_named() {
    for (bad, says) in [
        ("%1 = alu len=0", "len=0"),
        ("%1 = alu len=16", "len=16"),
        ("%1 = alu len=x", "len=x"),
        ("%1 = alu lcp", "need len=N"),
        ("%1 = alu complex", "need len=N"),
        ("%1 = alu fusible", "need len=N"),
    ] {
        let e = trace_text::parse(&format!(".trace 1\n.isa avx2\n{bad}\n")).unwrap_err();
        assert!(e.to_string().contains(says), "{bad}: {e}");
    }
}
