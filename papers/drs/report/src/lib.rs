//! # drs-report
//!
//! The DRS paper's reports (Barringer and Akenine-Moller 2014, "Dynamic Ray
//! Stream Traversal") computed on the Haswell model:
//! Table 1 (all seven methods), Table 2 (CPI and s/Gray of the core loop),
//! Figure 5 (tile size) and Figure 6 (field of view), and `rtsim run` of one
//! of its traversal methods over one tile's stream, and `rtsim native` of
//! them (beside Embree 3 where the host has it). The paper's own figures
//! are data in [`paper`].

#![warn(missing_docs)]

pub mod compare;
mod fidelity;
mod figures;
mod measure;
pub mod native;
pub mod paper;
pub mod replay;
pub mod run;
pub mod sweep;
mod table1;
mod table2;
pub mod validate;

pub use fidelity::{fidelity_frame, FrameFidelity};
use repro::{Opt, ReportDef};

/// The machine the paper measured on.
pub const MACHINE: &str = "haswell-i7-4750hq";

/// What every DRS report reads.
const OPTIONS: &[Opt] = &[
    Opt::Quick,
    Opt::Machine,
    Opt::Set,
    Opt::Tiles,
    Opt::Spp,
    Opt::Seed,
    Opt::ThreadsPerCore,
    Opt::Out,
];

/// The DRS paper's reports.
pub const REPORTS: [ReportDef; 4] = [
    ReportDef {
        name: "drs-table1",
        about: "DRS Table 1: render speed and DRAM bytes per ray of the seven methods",
        machine: MACHINE,
        options: OPTIONS,
        scenes: &paper::DRS_SCENES,
        run: table1::drs_table1,
    },
    ReportDef {
        name: "drs-table2",
        about: "DRS Table 2: CPI and s/Gray of Single BVH4, Our BVH4 and its core loop",
        machine: MACHINE,
        options: OPTIONS,
        scenes: &paper::DRS_SCENES,
        run: table2::drs_table2,
    },
    ReportDef {
        name: "drs-fig5",
        about: "DRS Figure 5: Our BVH4 against the tile size (PNG in --out DIR)",
        machine: MACHINE,
        options: OPTIONS,
        scenes: &paper::DRS_SCENES,
        run: figures::drs_fig5,
    },
    ReportDef {
        name: "drs-fig6",
        about: "DRS Figure 6: three methods against the field of view (PNG in --out DIR)",
        machine: MACHINE,
        options: OPTIONS,
        scenes: &["dragon"],
        run: figures::drs_fig6,
    },
];
