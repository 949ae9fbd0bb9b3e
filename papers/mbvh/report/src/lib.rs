//! # mbvh-report
//!
//! The MBVH ray-stream paper's reports (Tsakok 2009, "Faster Incoherent
//! Rays: Multi-BVH Ray Stream Tracing"): the traversal counters of its
//! Figures 4-6 (box tests, box fetches and primitive tests per ray against
//! glossy bounces) and the SIMD efficiency of primitive tests against the
//! ray group size at 4 and 16 lanes (Figures 7 and 8), on the Conference
//! stand-in traced by the paper's distribution ray tracer. The paper's own
//! figures are data beside the code ([`paper`]).

#![warn(missing_docs)]

mod counters;
mod frame;
pub mod paper;
mod rates;
pub mod replay;
mod timing;

use repro::{Opt, ReportDef};

/// The machine the paper measured its single-core figures on.
pub const MACHINE: &str = "core2-q6600";

/// What the counter reports read: the sample, its seed, the output (the
/// counters do not depend on a machine, so no `--machine` or `--set`).
const COUNTER_OPTIONS: &[Opt] = &[Opt::Quick, Opt::Tiles, Opt::Res, Opt::Seed, Opt::Out];

/// What the frame-rate reports read.
const RATE_OPTIONS: &[Opt] = &[
    Opt::Quick,
    Opt::Machine,
    Opt::Set,
    Opt::Tiles,
    Opt::Res,
    Opt::Seed,
    Opt::Out,
];

/// What the whole-machine tables read (their machines are the paper's two).
const TABLE_OPTIONS: &[Opt] = &[Opt::Quick, Opt::Tiles, Opt::Seed, Opt::Out];

/// The MBVH paper's reports.
pub const REPORTS: [ReportDef; 5] = [
    ReportDef {
        name: "mbvh-fig2",
        about: "MBVH RS Figure 2: Mrays/s per scene (BMW, Conference, Ferrari) on one Core 2 core, 1-4 bounces (PNG in --out DIR)",
        machine: MACHINE,
        options: RATE_OPTIONS,
        scenes: &rates::SCENES,
        run: rates::mbvh_fig2,
    },
    ReportDef {
        name: "mbvh-fig3",
        about: "MBVH RS Figure 3: Conference Mrays/s on one Core 2 core, 1 to 7 bounces; ordering and ray layout measured (PNG in --out DIR)",
        machine: MACHINE,
        options: RATE_OPTIONS,
        scenes: &["conference"],
        run: rates::mbvh_fig3,
    },
    ReportDef {
        name: "mbvh-fig4-6",
        about: "MBVH RS Figures 4-6: box tests, box fetches, primitive tests per ray vs glossy bounces (PNG in --out DIR)",
        machine: MACHINE,
        options: COUNTER_OPTIONS,
        scenes: &["conference"],
        run: counters::mbvh_fig4_6,
    },
    ReportDef {
        name: "mbvh-fig7-8",
        about: "MBVH RS Figures 7-8: SIMD efficiency of primitive tests vs ray group size, 4 and 16 lanes (PNG in --out DIR)",
        machine: MACHINE,
        options: COUNTER_OPTIONS,
        scenes: &["conference"],
        run: counters::mbvh_fig7_8,
    },
    ReportDef {
        name: "mbvh-table1-2",
        about: "MBVH RS Tables 1-2: frames per second at 512x512, 16 paths, 1-4 bounces, on the 24-core Dunnington and 8-core Core i7 models",
        machine: "dunnington-x7460",
        options: TABLE_OPTIONS,
        scenes: &rates::SCENES,
        run: rates::mbvh_table1_2,
    },
];
