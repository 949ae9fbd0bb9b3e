//! `rtsim fidelity --frame SCENE`: how far the sampled measurement the DRS
//! reports use is from full detail, on a window of a frame small enough to
//! time whole. The window's tiles run in render order on all the machine's
//! cores (one tile per core per round), after the same window rendered once
//! before (functionally warmed: a renderer's previous frame). Modes:
//!
//! - `full`: every round timed (the truth);
//! - `smarts`: every `every`-th round timed, every other round functionally
//!   warmed (SMARTS, Wunderlich et al. 2003);
//! - `recall`: the reports' design: each timed round's own tiles warmed
//!   first (as the previous frame left them), then the `warm` rounds before
//!   it, the rest skipped;
//! - `window`: (the reports' design before `recall`) no previous frame, only the `warm` rounds before each timed
//!   round warmed, the rest skipped;
//! - `none`: no warming at all (state left by the previous timed round).

use crate::measure::{measure_kernel, trace_streams, with_expected, Acc, Round, Sample};
use drs_kernels::methods::Kernel;
use repro::report::{Report, Row};
use repro::sampling::ratio_ci;
use repro::{AppError, AppResult};
use scene::loaded::Loaded;
use scene::reference::Reference;
use scene::workload::Tile;
use std::collections::BTreeMap;
use std::time::Instant;

/// The experiment's shape.
#[derive(Clone, Debug)]
pub struct FrameFidelity {
    /// Built-in scene (or scene file).
    pub scene: String,
    /// Window of tiles (columns, rows) at the frame's centre.
    pub window: (u32, u32),
    /// Samples per pixel.
    pub spp: u32,
    /// Time every `every`-th round.
    pub every: u32,
    /// Rounds warmed before each timed round (`window` mode).
    pub warm: u32,
    /// Path-tracing seed.
    pub seed: u64,
}

/// Which rounds a mode times and warms.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Mode {
    Full,
    Smarts,
    Recall,
    Window,
    None,
}

impl Mode {
    const ALL: [Mode; 5] = [
        Mode::Full,
        Mode::Smarts,
        Mode::Recall,
        Mode::Window,
        Mode::None,
    ];
    fn name(self) -> &'static str {
        match self {
            Mode::Full => "full",
            Mode::Smarts => "smarts",
            Mode::Recall => "recall",
            Mode::Window => "window",
            Mode::None => "none",
        }
    }
}

/// The window's rounds of `cores` tiles, in render order.
fn window_rounds(ld: &Loaded, f: &FrameFidelity, size: u32, cores: usize) -> Vec<Vec<Tile>> {
    let cam = &ld.scene.config.camera;
    let (tw, th) = (cam.width / size, cam.height / size);
    let (w, h) = (f.window.0.min(tw), f.window.1.min(th));
    let (x0, y0) = ((tw - w) / 2, (th - h) / 2);
    let tiles: Vec<Tile> = (0..w * h)
        .map(|i| Tile {
            x: x0 + i % w,
            y: y0 + i / w,
            size,
        })
        .collect();
    tiles.chunks(cores).map(<[Tile]>::to_vec).collect()
}

/// The plan of `mode` over `rounds`.
fn plan(mode: Mode, rounds: &[Vec<Tile>], f: &FrameFidelity) -> Vec<Round> {
    let every = f.every.max(1) as usize;
    let warm = f.warm as usize;
    let sampled = |i: usize| i >= warm && (i - warm).is_multiple_of(every);
    let round = |i: usize, timed: bool| Round {
        tiles: rounds[i].clone(),
        timed,
        group: i,
    };
    let previous_frame = || (0..rounds.len()).map(|i| round(i, false));
    match mode {
        Mode::Full => previous_frame()
            .chain((0..rounds.len()).map(|i| round(i, true)))
            .collect(),
        Mode::Smarts => previous_frame()
            .chain((0..rounds.len()).map(|i| round(i, sampled(i))))
            .collect(),
        Mode::Recall => (0..rounds.len())
            .filter(|&i| sampled(i))
            .flat_map(|i| {
                std::iter::once(round(i, false))
                    .chain((i.saturating_sub(warm)..i).map(|w| round(w, false)))
                    .chain(std::iter::once(round(i, true)))
            })
            .collect(),
        Mode::Window => (0..rounds.len())
            .filter(|&i| sampled(i) || (i + 1..=i + warm).any(sampled))
            .map(|i| round(i, sampled(i)))
            .collect(),
        Mode::None => (0..rounds.len())
            .filter(|&i| sampled(i))
            .map(|i| round(i, true))
            .collect(),
    }
}

/// Figures of one mode: cycles per ray (and its 95% CI over timed tiles),
/// CPI, DRAM bytes per ray.
fn figures(ac: &Acc) -> (f64, Option<f64>, f64, f64) {
    let rays = ac.rays.max(1) as f64;
    let pairs: Vec<(f64, f64)> = ac
        .tiles
        .iter()
        .map(|&(r, c)| (c as f64, r as f64))
        .collect();
    (
        ac.cycles as f64 / rays,
        ratio_ci(&pairs),
        ac.cycles as f64 / ac.ops.max(1) as f64,
        ac.dram as f64 / rays,
    )
}

/// `rtsim fidelity --frame SCENE` on machine `m`: every mode's host time,
/// its figures and their error against `full`.
pub fn fidelity_frame(m: &sim::MachineConfig, f: &FrameFidelity) -> AppResult<Report> {
    let start = Instant::now();
    let fl = m.flavour();
    let kernel = Kernel::DrsBvh4;
    if !kernel.supports(fl.lanes()) {
        return Err(AppError(format!(
            "--frame: runs Our BVH4 (drs-bvh4), which needs a 4, 8, 16 or 32-lane ISA; {} has {} lanes",
            m.name,
            fl.lanes()
        )));
    }
    if f.window.0 == 0 || f.window.1 == 0 || f.spp == 0 || f.spp > 16 || f.every == 0 {
        return Err(AppError(
            "--window COLSxROWS, --every: at least 1; --spp: 1 to 16".into(),
        ));
    }
    let ld = Loaded::load(&f.scene, &drs_kernels::BVH).map_err(AppError)?;
    let smp = Sample {
        m: m.clone(),
        fl,
        ntiles: 0,
        warm: f.warm,
        bounces: 1,
        size: 16,
        spp: f.spp,
        block: 0,
        progress: repro::progress::Progress::hidden(),
        // One thread per core: the design is measured on the cores alone.
        threads: 1,
    };
    let refi = Reference::with_bvh(&ld.scene.mesh, &ld.b2);
    let rounds = window_rounds(&ld, f, smp.size, m.cores.max(1) as usize);
    let all: Vec<Round> = plan(Mode::Full, &rounds, f);
    let streams = with_expected(&refi, trace_streams(&ld, &all, &smp, f.seed));
    let mut results = BTreeMap::new();
    let mut ops_total = 0;
    // The scene laid out before any mode is timed, so none pays for it.
    let shared = drs_kernels::methods::SharedLayouts::default();
    let empty = scene::workload::RayStream::from_rays(
        scene::workload::StreamKind::Primary,
        vec![],
        vec![],
        vec![],
    );
    let mut first = drs_kernels::methods::Run::new(kernel, &ld.scene, &ld.b2, &ld.b4, empty);
    first.shared = Some(&shared);
    let _ = first.lay_out(&mut isa::Native::<isa::Sse4, 4>::new());
    for mode in Mode::ALL {
        let t0 = Instant::now();
        let p = plan(mode, &rounds, f);
        let (ac, ops) = measure_kernel(
            &smp,
            (&ld, &shared),
            &refi,
            (&p, &streams),
            kernel,
            &f.scene,
        )?;
        ops_total += ops;
        results.insert(mode.name(), (ac, ops, t0.elapsed().as_secs_f64()));
    }
    let full = figures(&results["full"].0);
    let full_secs = results["full"].2;
    let mut rows = Vec::new();
    for mode in Mode::ALL {
        let (ac, ops, secs) = &results[mode.name()];
        let (cpr, ci, cpi, bpr) = figures(ac);
        let err = |a: f64, b: f64| if b == 0.0 { 0.0 } else { 100.0 * (a - b) / b };
        let k = |r: Row| r.key("mode", mode.name());
        rows.push(k(Row::new("host_seconds", *secs).unit("s")));
        rows.push(k(Row::new("speedup", full_secs / secs.max(1e-9))));
        rows.push(k(Row::new(
            "mops_per_host_second",
            *ops as f64 / secs.max(1e-9) / 1e6,
        )
        .unit("Mops/s")));
        rows.push(k(Row::new("rays_timed", ac.rays as f64)));
        let mut r = Row::new("cycles_per_ray", cpr);
        r.ci95 = ci;
        rows.push(k(r));
        rows.push(k(
            Row::new("cycles_per_ray_error", err(cpr, full.0)).unit("%")
        ));
        rows.push(k(Row::new("cpi", cpi)));
        rows.push(k(Row::new("cpi_error", err(cpi, full.2)).unit("%")));
        rows.push(k(Row::new("bytes_per_ray", bpr).unit("B/ray")));
        rows.push(k(
            Row::new("bytes_per_ray_error", err(bpr, full.3)).unit("%")
        ));
        rows.push(k(Row::new("hit_mismatches", ac.bad as f64)));
    }
    let mut sample = BTreeMap::new();
    sample.insert(
        "design".into(),
        serde_json::json!(format!(
            "a {}x{} window of 16x16 tiles at the frame's centre, {} spp, 1 bounce, rendered in rounds of one tile per core on {} cores after the same window rendered once before (warmed); every {}-th round timed from round {}; window mode warms the {} round(s) before each",
            f.window.0, f.window.1, f.spp, m.cores, f.every, f.warm, f.warm
        )),
    );
    sample.insert("rounds".into(), serde_json::json!(rounds.len()));
    sample.insert("seed".into(), serde_json::json!(f.seed));
    Ok(Report {
        report: "fidelity-frame".into(),
        machine: Some(m.name.clone()),
        isa: Some(fl.name().into()),
        fidelity: "full".into(),
        sample: Some(sample),
        input: Some(format!("{} on {}", kernel.name(), f.scene)),
        ops_simulated: ops_total,
        host_seconds: start.elapsed().as_secs_f64(),
        rows,
        notes: vec![
            "errors are against full: every round timed after a warmed previous frame; ci95 is over the timed tiles (Student t)".into(),
        ],
    })
}
