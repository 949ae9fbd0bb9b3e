//! # mft-report
//!
//! The MFT paper's reports (Benthin and Wald 2009, "Efficient Ray Traced
//! Soft Shadows using Multi-Frusta Tracing") computed on the Larrabee model
//! (one core, 4 threads): Table 1 (frusta against 16-ray packets, primary
//! and soft-shadow rays), section 5.2 (256-ray packets), Table 2 (frustum
//! shrinking), image quality against 256 samples, and Figure 6 (light
//! size). The paper's own figures are data beside the code that computes
//! ours ([`paper`]).

#![warn(missing_docs)]

mod frame;
mod light;
mod loose;
pub mod paper;
pub mod perset;
mod quality;
pub mod replay;
mod shading;
mod table1;
pub use table1::{verdicts, Verdict};
mod table2;

use repro::{Opt, ReportDef};

/// The machine the paper measured on: one Larrabee core, 4 threads.
pub const MACHINE: &str = "larrabee";

/// What every MFT report reads (no `--spp`: the paper's sample counts are
/// fixed, 1 primary ray per pixel and 16 light samples).
const OPTIONS: &[Opt] = &[
    Opt::Quick,
    Opt::Machine,
    Opt::Set,
    Opt::Tiles,
    Opt::Res,
    Opt::Seed,
    Opt::Out,
];

/// The paper's four scenes, in its order (Figure 6 has the first three;
/// Fairy Forest is run there as the stand-in farthest from Table 1's
/// per-set counts).
const PAPER_SCENES: &[&str] = &["trex", "fern", "saloon", "fairy"];

/// The MFT paper's reports.
pub const REPORTS: [ReportDef; 6] = [
    ReportDef {
        name: "mft-table1",
        about: "MFT Table 1: frusta vs 16-ray packets, primary and soft-shadow rays",
        machine: MACHINE,
        options: OPTIONS,
        scenes: PAPER_SCENES,
        run: table1::mft_table1,
    },
    ReportDef {
        name: "mft-table2",
        about: "MFT Table 2: frustum shrinking (Ray-AABB, corner rays, intervals)",
        machine: MACHINE,
        options: OPTIONS,
        scenes: &["trex"],
        run: table2::mft_table2,
    },
    ReportDef {
        name: "mft-packet256",
        about: "MFT section 5.2: 256-ray packets against frusta",
        machine: MACHINE,
        options: OPTIONS,
        scenes: PAPER_SCENES,
        run: table1::mft_packet256,
    },
    ReportDef {
        name: "mft-quality",
        about: "MFT soft-shadow images and PSNR against 256 samples (PNGs in --out DIR)",
        machine: MACHINE,
        options: OPTIONS,
        scenes: &["trex"],
        run: quality::mft_quality,
    },
    ReportDef {
        name: "mft-loose",
        about: "MFT: why frusta access more triangles per shadow set than the paper's (drivers and one-change variants at 1024x1024, counts)",
        machine: MACHINE,
        options: &[Opt::Quick, Opt::Machine, Opt::Res, Opt::Out],
        scenes: PAPER_SCENES,
        run: loose::mft_loose,
    },
    ReportDef {
        name: "mft-fig6",
        about: "MFT Figure 6: light-size sweep (PNG in --out DIR)",
        machine: MACHINE,
        options: OPTIONS,
        scenes: PAPER_SCENES,
        run: light::mft_fig6,
    },
];
