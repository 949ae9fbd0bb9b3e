//! # multihit-report
//!
//! The node-culling multi-hit paper's reports (Gribble, Wald, Amstutz 2016,
//! "Implementing Node Culling Multi-Hit BVH Traversal in Embree"): hits per
//! second of the 8-wide naive and node-culling kernels against N_query per
//! scene (its Figure 2), and node culling's speed-up against N_query as a
//! fraction of a scene's most hits over eight scenes (its section 3). The
//! paper's statements are data beside the code ([`paper`]).

#![warn(missing_docs)]

mod crossover;
mod embree;
mod measure;
pub mod paper;
pub mod replay;
mod reports;
mod scenes;

use repro::{Opt, ReportDef};

/// The paper's machine (one core of it is simulated).
pub const MACHINE: &str = "haswell-e5-2650v3";

const OPTIONS: &[Opt] = &[
    Opt::Quick,
    Opt::Machine,
    Opt::Set,
    Opt::Tiles,
    Opt::Seed,
    Opt::Out,
];

/// The multi-hit paper's reports.
pub const REPORTS: [ReportDef; 2] = [
    ReportDef {
        name: "multihit-fig2",
        about: "Multi-hit Figure 2: Mhit/s vs N_query, naive vs node culling, 8 scenes at 1024x768 on one E5-2650 v3 core (PNG in --out DIR)",
        machine: MACHINE,
        options: OPTIONS,
        scenes: &scenes::NAMES,
        run: reports::multihit_fig2,
    },
    ReportDef {
        name: "multihit-summary",
        about: "Multi-hit summary: node culling's speed-up over naive vs N_query as a fraction of the most hits, 8 scenes (PNG in --out DIR)",
        machine: MACHINE,
        options: OPTIONS,
        scenes: &scenes::NAMES,
        run: reports::multihit_summary,
    },
];
