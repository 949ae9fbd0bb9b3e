//! Trace format version 2: operand widths, store address sources and load
//! sites round-trip through both forms; version 1 files still read.

use isa::{trace_file, trace_text};

/// `bytes` with its version set to `v` and its checksum redone.
fn as_version(mut bytes: Vec<u8>, v: u16) -> Vec<u8> {
    bytes[8..10].copy_from_slice(&v.to_le_bytes());
    let end = bytes.len() - 8;
    let sum = trace_file::fnv1a64(&bytes[..end]);
    bytes[end..].copy_from_slice(&sum.to_le_bytes());
    bytes
}

#[test]
fn operand_widths_round_trip_and_version_1_files_still_read() {
    let text = ".trace 1\n.isa avx2\n%1 = vdiv w=16\n%2 = vdiv %1\n%3 = div %2 w=4\n";
    let t = trace_text::parse(text).unwrap();
    assert_eq!((t.ops[0].bytes, t.ops[1].bytes, t.ops[2].bytes), (16, 0, 4));
    let bin = trace_file::encode(&t);
    assert_eq!(trace_file::decode(&bin).unwrap(), t);
    assert_eq!(trace_text::parse(&trace_text::write(&t)).unwrap(), t);
    // Address sources of stores and sites of loads round-trip too.
    let text = ".trace 1\n.isa avx2\n.mem 0 lut isa-lut 0x10000000 64\n%1 = alu\n%2 = alu\n\
                store %2 @0+0x8:8 addr=%1\n%3 = load @0+0x8:8 site=7\nstore %3 @0+0x0:4\n";
    let t = trace_text::parse(text).unwrap();
    assert!(t.ops[2].has_addr_src() && !t.ops[4].has_addr_src());
    assert_eq!(
        (t.ops[2].srcs[0].0, t.ops[2].srcs[1].0, t.ops[3].aux),
        (1, 2, 7)
    );
    assert_eq!(trace_file::decode(&trace_file::encode(&t)).unwrap(), t);
    assert_eq!(trace_text::parse(&trace_text::write(&t)).unwrap(), t);
    // A version-1 file (no widths) reads as before.
    let plain = trace_text::parse(".trace 1\n.isa avx2\n%1 = vdiv\n").unwrap();
    assert_eq!(
        trace_file::decode(&as_version(trace_file::encode(&plain), 1)).unwrap(),
        plain
    );
    // In version 1 the width bit is no class: a clear error.
    let e = trace_file::decode(&as_version(bin, 1)).unwrap_err();
    assert!(e.msg.contains("unknown op class"), "{e:?}");
    // Bad widths: not a power of two, wider than the flavour, on a load.
    for bad in [
        "%1 = vdiv w=12",
        "%1 = vdiv w=64",
        ".mem 0 lut isa-lut 0x10000000 64\n%1 = vload @0+0x0:4 w=4",
    ] {
        let e = trace_text::parse(&format!(".trace 1\n.isa avx2\n{bad}\n")).unwrap_err();
        assert!(e.to_string().contains("w="), "{bad}: {e}");
    }
}
