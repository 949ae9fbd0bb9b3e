//! `rtsim run --kernel A,B,...` (by default DRS BVH4 against single-ray BVH4
//! on the crown's bounce rays): several traversal methods over the same
//! tile's stream, each checked against the reference on both backends and
//! timed on one core from empty caches, their headline figures side by side.

use crate::run::{stream_input, tile_stream};
use drs_kernels::methods::{Kernel, Run};
use repro::boxrun::RunArgs;
use repro::{AppError, AppResult, Report, Row};
use scene::loaded::Loaded;
use scene::workload::{RayStream, Tile};
use std::time::Instant;

/// The headline figures of one kernel's timed run (per ray through
/// [`sim::PerRay`], the one per-ray computation).
fn headline(s: &sim::Stats, m: &sim::MachineConfig, rays: u64, ops: usize) -> Vec<Row> {
    let p = sim::PerRay::new(s, rays, m.clock_ghz, 1);
    let r = rays.max(1) as f64;
    vec![
        Row::new("mray_per_s", p.mray_per_s_core).unit("Mray/s"),
        Row::new("cpi", s.cpi()),
        Row::new("bytes_per_ray", p.bytes_per_ray).unit("B/ray"),
        Row::new("ops_per_ray", ops as f64 / r).unit("ops"),
        Row::new("cycles_per_ray", s.cycles as f64 / r).unit("cycles"),
        Row::new("mispredicts_per_ray", s.mispredicts as f64 / r),
    ]
}

/// One kernel over the tile's stream (made once, shared by every kernel):
/// its rows keyed by kernel, and its ops.
fn one(
    a: &RunArgs,
    m: &sim::MachineConfig,
    ld: &Loaded,
    (tile, stream): (Tile, &RayStream),
    k: Kernel,
) -> AppResult<(Vec<Row>, u64)> {
    let rays = stream.len() as u64;
    let mut run = Run::new(k, &ld.scene, &ld.b2, &ld.b4, stream.clone());
    run.packet_tile = Some((tile.size, a.spp));
    let fl = m.flavour();
    let (t, (traced, tests)) = isa::record(&run, fl, k.name());
    let (native, _) = isa::run_native(&run, fl);
    let bad = run.mismatches(k.name(), &ld.reference(), &traced) as u64;
    let bad = bad + traced.iter().zip(&native).filter(|(x, y)| x != y).count() as u64;
    let s = sim::simulate(m, &[&t], &sim::SimOptions::default()).map_err(AppError)?;
    let mut rows = headline(&s, m, rays, t.ops.len());
    rows.push(Row::new(
        "node_tests_per_ray",
        tests.node_tests() as f64 / rays as f64,
    ));
    rows.push(Row::new(
        "leaf_tests_per_ray",
        tests.leaf as f64 / rays as f64,
    ));
    rows.push(Row::new("hit_mismatches", bad as f64));
    let rows = rows
        .into_iter()
        .map(|r| r.key("kernel", k.name()))
        .collect();
    Ok((rows, t.ops.len() as u64))
}

/// `rtsim run` with a list of traversal kernels.
///
/// # Errors
/// A kernel the machine's ISA cannot run, a bad scene, stream or tile, or a
/// hit that differs from the reference.
pub fn run_compare(a: &RunArgs, kernels: &[Kernel]) -> AppResult<()> {
    let start = Instant::now();
    let m = a.machine.load()?;
    if a.isa.is_some() {
        return Err(AppError(
            "--isa: a list of kernels is timed on the machine's own ISA".into(),
        ));
    }
    if let Some(k) = kernels.iter().find(|k| !k.supports(m.flavour().lanes())) {
        return Err(AppError(format!(
            "--kernel {}: runs on 4, 8, 16 and 32 lanes, {} has {} lanes",
            k.name(),
            m.flavour(),
            m.flavour().lanes()
        )));
    }
    if a.tile == 0 || a.tile > 256 || a.spp == 0 || a.spp > 256 {
        return Err(AppError("--tile and --spp: must be 1 to 256".into()));
    }
    let ld = Loaded::load(&a.scene, &drs_kernels::BVH).map_err(AppError)?;
    let (tile, stream) = tile_stream(&ld, &a.stream, a.tile, a.spp, a.seed)?;
    let (mut rows, mut ops, mut bad) = (Vec::new(), 0, 0.0);
    for &k in kernels {
        let (r, n) = one(a, &m, &ld, (tile, &stream), k)?;
        ops += n;
        bad += r
            .iter()
            .filter(|r| r.metric == "hit_mismatches")
            .map(|r| r.value)
            .sum::<f64>();
        rows.extend(r);
    }
    let names: Vec<&str> = kernels.iter().map(|k| k.name()).collect();
    let rep = Report {
        report: "run-compare".into(),
        machine: Some(m.name.clone()),
        isa: Some(m.flavour().name().into()),
        fidelity: "full".into(),
        sample: None,
        input: Some(stream_input(
            &names.join(" vs "),
            &ld.scene.config.name,
            &a.stream,
            tile,
            a.spp,
            a.seed,
        )),
        ops_simulated: ops,
        host_seconds: start.elapsed().as_secs_f64(),
        rows,
        notes: vec![
            format!("{} rays, the same for every kernel; each kernel's trace timed on one core of {} from empty caches (as rtsim run --kernel NAME times it, so the figures agree), so bytes_per_ray is the tile's first touch of the tree and triangles; Mray/s is one core at {} GHz.", stream.len(), m.name, m.clock_ghz),
            "bytes_per_ray is DRAM bytes (read and written) per ray; node and leaf tests are ray-box and ray-triangle-leaf tests per ray; hit_mismatches counts rays that differ from the f64 reference or between the traced and native backends.".into(),
            "One kernel in detail: rtsim run --kernel NAME (CPI stack, caches, op mix); the paper's tables: rtsim reproduce drs-table1 --quick.".into(),
        ],
    };
    print!("{}", rep.render(a.format));
    if bad > 0.0 {
        return Err(AppError(format!(
            "{bad} rays differ from the reference or between backends"
        )));
    }
    Ok(())
}
