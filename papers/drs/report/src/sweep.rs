//! `rtsim sweep`: one traversal kernel over one tile's stream of a scene,
//! timed on every point of a grid of one or two machine-config fields
//! (`--vary classes.vfma.lat=3,4,5,6 --vary core.width=2,4,6`; `isa=` varies
//! the lane width: sse4, avx2, avx512). Each point is its own machine, warmed
//! by a functional pass over the stream and then timed; points run at once
//! and come out in grid order. A table and, with `--out DIR`, a PNG.

use crate::run::{stream_input, tile_stream, warm_then_time};
use drs_kernels::methods::{Kernel, Run};
use rayon::prelude::*;
use repro::report::Format;
use repro::sweep::{axes, grid, keyed, sets, Axis};
use repro::{AppError, AppResult, Given, MachineSpec, Report, Row};
use scene::loaded::Loaded;
use sim::MachineConfig;
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Instant;

/// What `rtsim sweep` runs.
#[derive(Clone, Debug)]
pub struct SweepArgs {
    /// The kernel.
    pub kernel: Kernel,
    /// Scene name or file.
    pub scene: String,
    /// `primary`, `bounce` or `shadow`.
    pub stream: String,
    /// Tile side in pixels.
    pub tile: u32,
    /// Samples per pixel.
    pub spp: u32,
    /// Ray seed.
    pub seed: u64,
    /// The base machine and overrides every point shares.
    pub machine: MachineSpec,
    /// One or two `FIELD=V1,V2,...`.
    pub vary: Vec<String>,
    /// Where the PNG goes.
    pub out: Option<PathBuf>,
    /// Output format.
    pub format: Format,
}

/// One grid point: the value index per axis, its machine and its timing.
struct Point {
    at: Vec<usize>,
    machine: MachineConfig,
    cycles: u64,
    instructions: u64,
}

/// The grid's machines, in order (the last axis fastest), each checked.
fn machines(a: &SweepArgs, axes: &[Axis]) -> AppResult<Vec<(Vec<usize>, MachineConfig)>> {
    let base = a.machine.load()?;
    grid(axes)
        .into_iter()
        .map(|at| {
            let sets = sets(axes, &at);
            let m = base
                .with_sets(&sets)
                .map_err(|e| AppError(format!("--vary: {e}")))?;
            if !a.kernel.supports(m.flavour().lanes()) {
                return Err(AppError(format!(
                    "--vary {}: {} runs on 4, 8, 16 and 32 lanes, {} has {} lanes",
                    sets.join(" "),
                    a.kernel.name(),
                    m.isa,
                    m.flavour().lanes()
                )));
            }
            Ok((at, m))
        })
        .collect()
}

/// `rtsim sweep`.
///
/// # Errors
/// Bad options or values, an unloadable scene, a kernel whose answers
/// differ from the reference, an unwritable `--out`.
pub fn sweep_report(a: &SweepArgs) -> AppResult<Report> {
    let start = Instant::now();
    let axes = axes(&a.vary)?;
    let grid = machines(a, &axes)?;
    let ld = Loaded::load(&a.scene, &drs_kernels::BVH).map_err(AppError)?;
    let (tile, rays) = tile_stream(&ld, &a.stream, a.tile, a.spp, a.seed)?;
    let mut run = Run::new(a.kernel, &ld.scene, &ld.b2, &ld.b4, rays.clone());
    run.packet_tile = Some((tile.size, a.spp));
    // One recording per ISA the grid runs (the trace does not depend on timing).
    let mut traces = BTreeMap::new();
    for (_, m) in &grid {
        if let std::collections::btree_map::Entry::Vacant(e) = traces.entry(m.isa.clone()) {
            let (t, (hits, _)) = isa::record(&run, m.flavour(), a.kernel.name());
            let bad = run.mismatches(a.kernel.name(), &ld.reference(), &hits);
            if bad > 0 {
                return Err(AppError(format!(
                    "{} on {}: {bad} rays differ from the reference",
                    a.kernel.name(),
                    m.isa
                )));
            }
            e.insert(t);
        }
    }
    let points: Vec<Point> = grid
        .into_par_iter()
        .map(|(at, machine)| {
            let t = &traces[&machine.isa];
            let st = warm_then_time(t, &machine)?;
            Ok(Point {
                at,
                machine,
                cycles: st.cycles,
                instructions: st.ops,
            })
        })
        .collect::<AppResult<_>>()?;
    let ops: u64 = points
        .iter()
        .map(|p| traces[&p.machine.isa].ops.len() as u64)
        .sum();
    let rows = rows(&points, &axes, rays.len());
    if let Some(dir) = &a.out {
        plot(dir, a, &axes, &points, rays.len())?;
    }
    Ok(Report {
        report: "sweep".into(),
        machine: Some(a.machine.machine.clone()),
        isa: None,
        fidelity: "full".into(),
        sample: None,
        input: Some(format!(
            "{}; varied: {}",
            stream_input(
                a.kernel.name(),
                &ld.scene.config.name,
                &a.stream,
                tile,
                a.spp,
                a.seed,
            ),
            a.vary.join(" ")
        )),
        ops_simulated: ops,
        host_seconds: start.elapsed().as_secs_f64(),
        rows,
        notes: vec![format!(
            "each point is the base machine with its values set, one core warmed by a functional pass over the {} rays, then timed in full detail; Mray/s at the point's clock",
            rays.len()
        )],
    })
}

/// Per point: cycles, instructions, CPI, Mray/s, keyed by the varied fields.
fn rows(points: &[Point], axes: &[Axis], rays: usize) -> Vec<Row> {
    let mut rows = Vec::new();
    for p in points {
        let row = |metric: &str, v: f64| keyed(Row::new(metric, v), axes, &p.at);
        let secs = p.cycles as f64 / (p.machine.clock_ghz * 1e9);
        rows.push(row("cycles", p.cycles as f64).unit("cycles"));
        rows.push(row("instructions", p.instructions as f64));
        rows.push(row("cpi", p.cycles as f64 / p.instructions.max(1) as f64));
        rows.push(row("mray_per_s", rays as f64 / secs / 1e6).unit("Mray/s"));
    }
    rows
}

/// `DIR/sweep.png`: Mray/s and CPI against the first axis, a line per value
/// of the second.
fn plot(
    dir: &std::path::Path,
    a: &SweepArgs,
    axes: &[Axis],
    points: &[Point],
    rays: usize,
) -> AppResult<()> {
    std::fs::create_dir_all(dir).map_err(|e| AppError(format!("{}: {e}", dir.display())))?;
    let lines = axes.get(1).map_or(1, |ax| ax.values.len());
    let series = |f: &dyn Fn(&Point) -> f64| -> Vec<repro::plot::Series> {
        (0..lines)
            .map(|l| repro::plot::Series {
                label: axes.get(1).map_or_else(
                    || a.kernel.name().to_string(),
                    |ax| format!("{}={}", ax.field, ax.values[l]),
                ),
                points: points
                    .iter()
                    .filter(|p| p.at.get(1).is_none_or(|&i| i == l))
                    .map(|p| (axes[0].x(p.at[0]), f(p)))
                    .collect(),
            })
            .collect()
    };
    let mray = |p: &Point| rays as f64 / (p.cycles as f64 / (p.machine.clock_ghz * 1e9)) / 1e6;
    let cpi = |p: &Point| p.cycles as f64 / p.instructions.max(1) as f64;
    let title = format!("{} on {}, {} rays", a.kernel.name(), a.scene, a.stream);
    let x = axes[0].label();
    repro::plot::write(
        &dir.join("sweep.png"),
        &[
            repro::plot::Panel {
                title: &title,
                x: &x,
                y: "Mray/s",
                series: series(&mray),
            },
            repro::plot::Panel {
                title: &title,
                x: &x,
                y: "CPI",
                series: series(&cpi),
            },
        ],
    )
}

/// `rtsim sweep` arguments: one kernel over one tile's stream, or with
/// `--report` a paper report's cells.
#[derive(clap::Args)]
pub struct SweepCli {
    /// Sweep this paper report's cells instead of one kernel (`rtsim reproduce --help` lists them).
    #[arg(long)]
    pub report: Option<String>,
    /// With --report: the metric whose cells are swept [default: the report's first].
    #[arg(long)]
    pub metric: Option<String>,
    /// With --report: the report's smaller sample.
    #[arg(long)]
    pub quick: bool,
    /// With --report: rounds of tiles per scene, or runs of frusta sets.
    #[arg(long)]
    pub tiles: Option<u32>,
    /// With --report: image width and height in pixels (MFT reports).
    #[arg(long)]
    pub res: Option<u32>,
    /// Traversal kernel [default: drs-bvh4].
    #[arg(long)]
    pub kernel: Option<String>,
    /// Scene (`rtsim list scenes`, a .ron or a mesh file) [default: conference].
    #[arg(long)]
    pub scene: Option<String>,
    /// Ray stream: primary, bounce or shadow [default: bounce].
    #[arg(long)]
    pub stream: Option<String>,
    /// Tile side in pixels: the stream is one tile at the image centre [default: 16].
    #[arg(long)]
    pub tile: Option<u32>,
    /// Samples per pixel [default: 16; with --report the report's].
    #[arg(long)]
    pub spp: Option<u32>,
    /// Ray seed [default: 7].
    #[arg(long)]
    pub seed: Option<u64>,
    /// The machine every point starts from [default: haswell-i7-4750hq; with --report the report's].
    #[arg(long)]
    pub machine: Option<String>,
    /// Override a config field at every point: `--set core.width=6`.
    #[arg(long = "set", value_name = "FIELD=VALUE")]
    pub sets: Vec<String>,
    /// A config field and its values, `FIELD=V1,V2,...` (once or twice; `isa=sse4,avx2` varies the lanes).
    #[arg(long, required = true)]
    pub vary: Vec<String>,
    /// Also write DIR/sweep.png.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Output format: text, json or csv.
    #[arg(long, value_parser = Format::from_name, default_value = "text")]
    pub format: Format,
    /// With --report: no progress bar over the points (there is none when
    /// standard error is not a terminal).
    #[arg(long)]
    pub quiet: bool,
}

/// What `rtsim sweep` was asked for, its options checked against the form.
pub enum Sweep {
    /// One kernel over one tile's stream.
    Kernel(SweepArgs),
    /// A report's cells: its name, its options, the metric, the axes,
    /// whether to hide the progress bar.
    Report(String, Given, Option<String>, Vec<String>, bool),
}

impl SweepCli {
    /// The library's options: an option the chosen form does not read is
    /// an error naming it (the kernel name checked).
    pub fn args(self) -> AppResult<Sweep> {
        let named = |flags: &[(&str, bool)], why: &str| -> AppResult<()> {
            match flags.iter().find(|f| f.1) {
                Some((f, _)) => Err(AppError(format!("sweep: {f} {why}"))),
                None => Ok(()),
            }
        };
        if let Some(report) = self.report {
            named(
                &[
                    ("--kernel", self.kernel.is_some()),
                    ("--scene", self.scene.is_some()),
                    ("--stream", self.stream.is_some()),
                    ("--tile", self.tile.is_some()),
                ],
                "is not read with --report (the report chooses its kernels and scenes)",
            )?;
            let given = Given {
                quick: self.quick,
                machine: self.machine,
                sets: self.sets,
                tiles: self.tiles,
                res: self.res,
                spp: self.spp,
                threads_per_core: None,
                seed: self.seed,
                format: self.format,
                out: None,
                scenes: Vec::new(),
                quiet: true,
            };
            return Ok(Sweep::Report(
                report,
                given,
                self.metric,
                self.vary,
                self.quiet,
            ));
        }
        named(
            &[
                ("--metric", self.metric.is_some()),
                ("--quick", self.quick),
                ("--tiles", self.tiles.is_some()),
                ("--res", self.res.is_some()),
                ("--quiet", self.quiet),
            ],
            "is only read with --report NAME",
        )?;
        let kernel = crate::run::kernel_named(self.kernel.as_deref().unwrap_or("drs-bvh4"))?;
        Ok(Sweep::Kernel(SweepArgs {
            kernel,
            scene: self.scene.unwrap_or_else(|| "conference".into()),
            stream: self.stream.unwrap_or_else(|| "bounce".into()),
            tile: self.tile.unwrap_or(16),
            spp: self.spp.unwrap_or(16),
            seed: self.seed.unwrap_or(7),
            machine: MachineSpec {
                machine: self.machine.unwrap_or_else(|| "haswell-i7-4750hq".into()),
                sets: self.sets,
            },
            vary: self.vary,
            out: self.out,
            format: self.format,
        }))
    }
}
