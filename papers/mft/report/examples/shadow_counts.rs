//! Soft-shadow counts per set of 16 frusta against the paper's Table 1, no
//! simulation: the tool the stand-ins' lights were matched with.
//!
//! `cargo run --release -p mft-report --example shadow_counts -- SCENE [RES] [EVERY] [nets|strips] [per-sample|per-frustum]`
//! (SCENE: a built-in name or a `.ron` file; defaults 1024, every 8th set,
//! nets, packets of the 4 x 4 pixels' k-th rays).

use mft_kernels::PacketGrouping;
use mft_report::perset::{paper_per_set, shadow_per_set};
use scene::workload::SampleSplit;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let fail = |m: String| -> ! {
        eprintln!("shadow_counts: {m}");
        std::process::exit(2)
    };
    let Some(scene) = args.first() else {
        fail(
            "usage: shadow_counts SCENE [RES] [EVERY] [nets|strips] [per-sample|per-frustum]"
                .into(),
        )
    };
    let num = |i: usize, d: u32| -> u32 {
        args.get(i).map_or(d, |s| {
            s.parse()
                .unwrap_or_else(|_| fail(format!("argument {}: not a number: {s}", i + 1)))
        })
    };
    let (res, every) = (num(1, 1024), num(2, 8));
    let split = match args.get(3).map(String::as_str) {
        None | Some("nets") => SampleSplit::Nets,
        Some("strips") => SampleSplit::Strips,
        Some(s) => fail(format!("argument 4: {s}: not nets or strips")),
    };
    let grouping = match args.get(4).map(String::as_str) {
        None | Some("per-sample") => PacketGrouping::PerSample,
        Some("per-frustum") => PacketGrouping::PerFrustum,
        Some(s) => fail(format!("argument 5: {s}: not per-sample or per-frustum")),
    };
    if args.len() > 5 {
        fail(format!("argument 6: {}: unused", args[5]));
    }
    let c = shadow_per_set(scene, res, every, (split, grouping)).unwrap_or_else(|e| fail(e.0));
    let paper = paper_per_set(&c.name);
    println!(
        "{} at {res}x{res}, {} split, packets {grouping:?}, every {every}th set: {} of {} groups have a hit; zero-interval frusta {:.0}%",
        c.name,
        split.name(),
        c.sets,
        c.groups,
        100.0 * c.zero_share
    );
    for (method, ours, theirs) in [
        ("s-packet", c.packets, paper.map(|p| p.0)),
        ("s-frusta", c.frusta, paper.map(|p| p.1)),
    ] {
        for ((metric, v), p) in ours.named().into_iter().zip(
            theirs
                .map(|t| t.named().map(|x| Some(x.1)))
                .unwrap_or([None; 4]),
        ) {
            match p {
                Some(p) => println!(
                    "{method:9} {metric:19} {v:9.1}  paper {p:8.1}  x{:.2}",
                    v / p
                ),
                None => println!("{method:9} {metric:19} {v:9.1}"),
            }
        }
    }
    println!(
        "frusta/packets tris accessed {:.2} (paper {})",
        c.frusta.tris_accessed / c.packets.tris_accessed.max(1e-9),
        paper.map_or("-".into(), |p| format!(
            "{:.2}",
            p.1.tris_accessed / p.0.tris_accessed
        ))
    );
}
