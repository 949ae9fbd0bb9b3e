//! `rtsim run --kernel METHOD`: one of the paper's traversal methods over
//! one tile's stream of a scene, checked against the reference on both
//! backends, timed, with its test counts.

use drs_kernels::methods::{Kernel, Run};
use repro::boxrun::{finish, Recorded, RunArgs};
use repro::{AppError, AppResult, Row};
use scene::loaded::Loaded;
use scene::workload::{path_trace_tile, primary_tile, RayStream, StreamKind, Tile};
use std::time::Instant;

/// The methods `rtsim run --kernel` accepts, by name.
#[must_use]
pub fn kernel_names() -> [&'static str; 7] {
    Kernel::ALL.map(Kernel::name)
}

/// The method called `name`.
#[must_use]
pub fn kernel(name: &str) -> Option<Kernel> {
    Kernel::ALL.into_iter().find(|k| k.name() == name)
}

/// The traversal kernel called `name`, or an error listing them.
///
/// # Errors
/// No kernel has that name.
pub fn kernel_named(name: &str) -> AppResult<Kernel> {
    kernel(name).ok_or_else(|| {
        AppError(format!(
            "--kernel: unknown traversal kernel '{name}' ({})",
            kernel_names().join(", ")
        ))
    })
}

/// What a run over one tile's stream traced: `what` on `scene`, the stream,
/// the tile, samples and seed (the reports' `input`).
#[must_use]
pub fn stream_input(
    what: &str,
    scene: &str,
    stream: &str,
    tile: Tile,
    spp: u32,
    seed: u64,
) -> String {
    format!(
        "{what} on {scene}, {stream} stream of tile ({}, {}) x {spp} spp, seed {seed}",
        tile.x, tile.y
    )
}

/// Time trace `t` on one core of `m`, its caches and predictor warmed first
/// by a functional pass over the same ops (as a repeated native run finds
/// them).
///
/// # Errors
/// The trace does not suit the machine.
pub fn warm_then_time(t: &isa::Trace, m: &sim::MachineConfig) -> AppResult<sim::Stats> {
    let mut s = sim::Session::new(m);
    s.warm(&[(0, t)]).map_err(AppError)?;
    s.timed(&[(0, t)]).map_err(AppError)
}

/// `rtsim run --kernel METHOD`: a traversal method over one tile's ray stream of a scene.
pub fn run_traversal(a: &RunArgs, kernel: Kernel) -> AppResult<()> {
    let start = Instant::now();
    let m = a.machine.load()?;
    let fl = a.isa.unwrap_or_else(|| m.flavour());
    if !kernel.supports(fl.lanes()) {
        return Err(AppError(format!(
            "--kernel {}: runs on 4, 8, 16 and 32 lanes, {fl} has {} lanes",
            kernel.name(),
            fl.lanes()
        )));
    }
    if a.tile == 0 || a.tile > 256 || a.spp == 0 || a.spp > 256 {
        return Err(AppError("--tile and --spp: must be 1 to 256".into()));
    }
    let ld = Loaded::load(&a.scene, &drs_kernels::BVH).map_err(AppError)?;
    let (scene, b2, b4) = (&ld.scene, &ld.b2, &ld.b4);
    let (tile, stream) = tile_stream(&ld, &a.stream, a.tile, a.spp, a.seed)?;
    let mut run = Run::new(kernel, scene, b2, b4, stream.clone());
    run.packet_tile = Some((tile.size, a.spp));
    let (t, (traced, tests)) = isa::record(&run, fl, kernel.name());
    let (native, native_tests) = isa::run_native(&run, fl);
    if native_tests != tests {
        return Err(AppError(format!(
            "{}: traced and native backends counted different tests ({tests:?} vs {native_tests:?})",
            kernel.name()
        )));
    }
    let refi = ld.reference();
    let bad = run.mismatches(kernel.name(), &refi, &traced);
    let native_bad = traced.iter().zip(&native).filter(|(x, y)| x != y).count();
    let rays = stream.len() as u64;
    let rows = vec![
        Row::new("rays", rays as f64),
        Row::new("hit_mismatches", bad as f64).key("backend", "traced"),
        Row::new("hit_mismatches", native_bad as f64).key("backend", "native"),
        Row::new("ops_per_ray", t.ops.len() as f64 / rays as f64).unit("ops"),
        Row::new("ray_node_tests", tests.node_tests() as f64),
        Row::new("ray_node_tests", tests.core_loop as f64).key("region", "core-loop"),
        Row::new("core_loop_share", tests.core_loop_share()),
        Row::new("ray_leaf_tests", tests.leaf as f64),
        Row::new("culled_pops", tests.culled as f64),
    ];
    finish(Recorded {
        args: a,
        machine: &m,
        name: format!("run-{}", kernel.name()),
        input: stream_input(
            kernel.name(),
            &scene.config.name,
            &a.stream,
            tile,
            a.spp,
            a.seed,
        ),
        trace: t,
        rays,
        rows,
        start,
    })?;
    if bad + native_bad > 0 {
        return Err(AppError(format!(
            "{bad} rays differ from the reference, {native_bad} between traced and native"
        )));
    }
    Ok(())
}

/// The centre tile of `ld`'s camera, `size` pixels square at `spp` samples,
/// and its `stream` (primary, bounce: the path tracer's first bounce, or
/// shadow: from the primary hits, any hit) with `seed`.
///
/// # Errors
/// An unknown stream, a tile whose stream is empty or over 65536 rays.
pub fn tile_stream(
    ld: &Loaded,
    stream: &str,
    size: u32,
    spp: u32,
    seed: u64,
) -> AppResult<(Tile, RayStream)> {
    let (scene, b2) = (&ld.scene, &ld.b2);
    let cam = &scene.config.camera;
    let tile = Tile {
        x: cam.width / 2 / size,
        y: cam.height / 2 / size,
        size,
    };
    let rays = match stream {
        "primary" => primary_tile(cam, tile.x, tile.y, tile.size, spp, seed),
        "bounce" => path_trace_tile(scene, b2, tile, spp, 1, seed)
            .into_iter()
            .find(|s| s.kind == StreamKind::Bounce(1))
            .ok_or_else(|| {
                AppError("--stream bounce: no path survives the first hit in this tile".into())
            })?,
        "shadow" => path_trace_tile(scene, b2, tile, spp, 0, seed)
            .into_iter()
            .find(|s| s.kind == StreamKind::Shadow(0))
            .ok_or_else(|| AppError("--stream shadow: no primary ray hits in this tile".into()))?,
        s => {
            return Err(AppError(format!(
                "--stream: '{s}' is not primary, bounce or shadow"
            )))
        }
    };
    if rays.is_empty() || rays.len() > 65536 {
        return Err(AppError(format!(
            "the stream has {} rays (1 to 65536 needed)",
            rays.len()
        )));
    }
    Ok((tile, rays))
}
