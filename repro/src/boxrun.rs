//! `rtsim run`: one workload recorded on an ISA, checked against its
//! reference, and timed when the ISA is the machine's. The default
//! workload is here (a ray stream against one BVH4 node's 4 boxes, the DRS
//! core loop's inner test); the traversal kernels' runs are their paper's
//! and finish through [`finish`].

use crate::machine::{region_rows, stats_rows};
use crate::options::MachineSpec;
use crate::report::{Format, Row};
use crate::traces::{base_report, boxstream, info_rows, save_trace};
use crate::{AppError, AppResult};
use isa::{FlavourId, Trace};
use rt::boxtest::box4_ref;
use std::path::PathBuf;
use std::time::Instant;

/// `rtsim run` options.
#[derive(Clone, Debug)]
pub struct RunArgs {
    /// Machine to time it on (its ISA is the kernel's).
    pub machine: MachineSpec,
    /// Record on this ISA instead and do not time it.
    pub isa: Option<FlavourId>,
    /// Kernel name.
    pub kernel: String,
    /// Scene of the traversal kernels.
    pub scene: String,
    /// Ray stream of the traversal kernels (primary, bounce, shadow).
    pub stream: String,
    /// Tile side in pixels (traversal kernels).
    pub tile: u32,
    /// Samples per pixel (traversal kernels).
    pub spp: u32,
    /// Rays of the boxtest stream.
    pub rays: usize,
    /// Seed of the generated node and rays.
    pub seed: u64,
    /// Also write the recorded trace here.
    pub out: Option<PathBuf>,
    /// Output format.
    pub format: Format,
}

/// A recorded run and its checks, ready to be finished into a report.
pub struct Recorded<'a> {
    /// The options.
    pub args: &'a RunArgs,
    /// The machine `args` named, loaded.
    pub machine: &'a sim::MachineConfig,
    /// Report name (`run-boxtest`, `run-drs-bvh4`, ...).
    pub name: String,
    /// What was run on what.
    pub input: String,
    /// The recorded op stream.
    pub trace: Trace,
    /// Rays (for per-ray figures).
    pub rays: u64,
    /// The kernel's own rows (counts, mismatches).
    pub rows: Vec<Row>,
    /// When the run started.
    pub start: Instant,
}

/// Finish a run: write the trace with `--out`, time it when the ISA is the
/// machine's (else describe the trace), print the report.
pub fn finish(r: Recorded<'_>) -> AppResult<()> {
    let (a, m) = (r.args, r.machine);
    let fl = a.isa.unwrap_or_else(|| m.flavour());
    let mut rows = r.rows;
    let t = &r.trace;
    if let Some(out) = &a.out {
        let n = save_trace(t, out)?;
        rows.push(Row::new("trace_bytes", n as f64).unit("B"));
        rows.push(Row::new("trace_bytes_per_op", n as f64 / t.ops.len().max(1) as f64).unit("B"));
    }
    let timed = fl == m.flavour();
    if timed {
        let s = sim::simulate(m, &[t], &sim::SimOptions::default()).map_err(AppError)?;
        rows.extend(stats_rows(&s, m, Some(r.rays)));
        rows.extend(region_rows(&s, t));
    } else {
        rows.extend(info_rows(t));
    }
    let mut rep = base_report(&r.name, t, r.input, r.start.elapsed().as_secs_f64(), rows);
    if timed {
        rep.machine = Some(m.name.clone());
        rep.fidelity = "full".into();
    }
    print!("{}", rep.render(a.format));
    Ok(())
}

/// `rtsim run --kernel boxtest`: the ray-vs-4-boxes workload.
pub fn run_boxtest(a: &RunArgs) -> AppResult<()> {
    let start = Instant::now();
    let w = boxstream(a.rays, a.seed)?;
    let m = a.machine.load()?;
    let fl = a.isa.unwrap_or_else(|| m.flavour());
    let (t, got) = isa::record(&w, fl, "kernel:boxtest");
    let native = isa::run_native(&w, fl);
    let fused = fl != FlavourId::Sse4;
    let want: Vec<u8> = w.rays.iter().map(|r| box4_ref(&w.node, r, fused)).collect();
    let traced_bad = got.iter().zip(&want).filter(|(g, w)| g != w).count();
    let native_bad = native.iter().zip(&want).filter(|(g, w)| g != w).count();
    let rows = vec![
        Row::new("rays", a.rays as f64),
        Row::new("box_hits", want.iter().map(|b| b.count_ones() as f64).sum()),
        Row::new("hit_mismatches", traced_bad as f64).key("backend", "traced"),
        Row::new("hit_mismatches", native_bad as f64).key("backend", "native"),
        Row::new("ops_per_ray", t.ops.len() as f64 / a.rays as f64).unit("ops"),
    ];
    finish(Recorded {
        args: a,
        machine: &m,
        name: "run-boxtest".into(),
        input: format!("{} rays vs 4 boxes, seed {}", a.rays, a.seed),
        trace: t,
        rays: a.rays as u64,
        rows,
        start,
    })?;
    if traced_bad + native_bad > 0 {
        return Err(AppError(format!(
            "{traced_bad} traced and {native_bad} native rays differ from the scalar reference"
        )));
    }
    Ok(())
}
