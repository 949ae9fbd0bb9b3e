//! Rows every volume report prints the same way: a view's sampling
//! density, frames per second on one core and on the whole machine, and
//! cycles per ray and per sample beside the paper's implied figures.

use crate::measure::{Cell, Dataset, Density, SAMPLES_PER_VOXEL};
use crate::paper::SCALING_AT_8;
use repro::Row;

/// A whole machine's rate from one simulated core's: linear to 4 cores,
/// the paper's measured 97% at 8 (section 7.1) beyond.
pub(crate) fn whole_machine(fps_one_core: f64, cores: u32) -> f64 {
    let eff = if cores <= 4 { 1.0 } else { SCALING_AT_8 };
    fps_one_core * f64::from(cores) * eff
}

/// A view's sampling: samples per voxel (beside the paper's ~2), the first
/// step, samples per ray, the frame's coverage and the share of its rays
/// that stop early.
pub(crate) fn density_rows(k: impl Fn(Row) -> Row, ds: &Dataset, d: &Density) -> Vec<Row> {
    let mut spv = k(Row::new("samples_per_voxel", d.samples_per_voxel));
    spv.paper = Some(SAMPLES_PER_VOXEL);
    vec![
        spv,
        k(Row::new("first_step", ds.sampling.dt).unit("voxels")),
        k(Row::new("reference_samples_per_ray", d.samples_per_ray)),
        k(Row::new("frame_coverage", ds.coverage())),
        k(Row::new("terminated_share", d.terminated)),
    ]
}

/// Cycles per ray on one core of `m` (ours from the sample; the paper's
/// implied by its whole-machine rate `paper` on `cores` at the same
/// scaling) and per visited sample, at `res` x `res`.
pub(crate) fn cost_rows(
    k: impl Fn(Row) -> Row,
    (m, cores): (&sim::MachineConfig, u32),
    (c, paper): (&Cell, Option<f64>),
    res: u32,
) -> Vec<Row> {
    let per_frame = m.clock_ghz * 1e9 / f64::from(res * res);
    let mut r = k(Row::new("cycles_per_ray", per_frame / c.fps)).unit("cycles");
    r.paper = paper.map(|p| per_frame * whole_machine(1.0, cores) / p);
    let per_sample = per_frame / c.fps / c.samples_per_ray.max(1e-9);
    vec![
        r,
        k(Row::new("cycles_per_visited_sample", per_sample)).unit("cycles"),
    ]
}

/// A cell's frames per second: on one simulated core (with its 95%
/// interval) and, if `whole` gives the machine's cores and the paper's
/// rate, on the whole machine beside the paper's.
pub(crate) fn fps_rows(
    k: impl Fn(Row) -> Row,
    c: &Cell,
    whole: Option<(u32, Option<f64>)>,
) -> Vec<Row> {
    let mut one = k(Row::new("fps", c.fps)).key("cores", 1).unit("frame/s");
    one.ci95 = c.ci;
    let mut rows = vec![one];
    if let Some((cores, paper)) = whole {
        let mut r = k(Row::new("fps", whole_machine(c.fps, cores)))
            .key("cores", cores)
            .unit("frame/s");
        r.paper = paper;
        rows.push(r);
    }
    rows
}
