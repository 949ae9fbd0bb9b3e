//! # volume-report
//!
//! The volume-rendering paper's reports (Knoll et al. 2011): frames per
//! second per dataset against the paper's Figure 5 ([`paper`]), computed on
//! the simulated kernels with every timed pixel checked against the f64
//! reference.

#![warn(missing_docs)]

mod assumptions;
mod bvh_sizes;
mod custom;
mod images;
mod measure;
pub mod paper;
pub mod replay;
mod reports;
mod rows;
mod scaling;
mod table1;

pub use custom::{volume, VolumeArgs};
use repro::{Opt, ReportDef};

/// The paper's workstation, two X5550 sockets (one core of it is
/// simulated; its whole-machine rows take its 8 cores).
pub const MACHINE: &str = "nehalem-x5550-dual";

const OPTIONS: &[Opt] = &[
    Opt::Quick,
    Opt::Machine,
    Opt::Set,
    Opt::Tiles,
    Opt::Seed,
    Opt::Out,
];

/// Figure 5's datasets, in its order.
const FIG5_DATASETS: [&str; paper::FIG5.len()] = repro::names_of!(paper::FIG5);

/// The volume paper's reports.
pub const REPORTS: [ReportDef; 5] = [
    ReportDef {
        name: "volume-fig5",
        about: "Volume rendering Figure 5: fps at 512^2 per dataset, gcc, sse and bvh on the 8-core X5550 workstation and bvh on the 2-core Core 2 Duo (PNG per dataset in --out DIR)",
        machine: MACHINE,
        options: OPTIONS,
        scenes: &FIG5_DATASETS,
        run: reports::volume_fig5,
    },
    ReportDef {
        name: "volume-table1",
        about: "Volume rendering Table 1: CPU time by stage (voxel fetch, interpolation, classification, blending, BVH traversal, diffuse, Phong, other) for gcc and sse, nearest and trilinear, with the BVH and lit, on the Core 2 Duo (the paper's Table 1 machine), with the 8-core X5550 fps beside",
        machine: reports::LAPTOP,
        options: OPTIONS,
        scenes: &["engine"],
        run: table1::volume_table1,
    },
    ReportDef {
        name: "volume-fig6",
        about: "Volume rendering Figure 6: the mixing layer (Richtmyer-Meshkov stand-in) at 256^3, 512^3, 1024^3 (256^3 at --quick), far / medium / close views at 1024^2, gcc / sse / bvh on the X5550 and bvh on the Core 2 Duo",
        machine: MACHINE,
        options: OPTIONS,
        scenes: &["mixing"],
        run: scaling::volume_fig6,
    },
    ReportDef {
        name: "volume-fig7",
        about: "Volume rendering Figure 7: differential sampling rda = 2^-8 .. 2^-5 on the mixing layer, fps (bvh, X5550) and image error against uniform sampling",
        machine: MACHINE,
        options: OPTIONS,
        scenes: &["mixing"],
        run: scaling::volume_fig7,
    },
    ReportDef {
        name: "volume-bvh",
        about: "Volume rendering section 7.3: the implicit BVH by leaf size L = 1, 2, 4, 8 (size against the volume, build time, fps on one core of the X5550 workstation)",
        machine: MACHINE,
        options: OPTIONS,
        scenes: &["neghip", "engine"],
        run: bvh_sizes::volume_bvh,
    },
];
