//! `rtsim replay`: windows of every paper's traversal kernels' recorded
//! traces run on this host as x86-64 loops (the `replay` crate) and on the
//! model of this host over the same loops; Kendall tau and mean error of
//! the model's cycles per iteration against the host's, per kernel and
//! over all windows. Each paper gives its kernels' traces on a small
//! workload of its own (`papers/*/report/src/replay.rs`).

use crate::host::HostCpu;
use crate::machine::Steady;
use crate::report::Format;
use crate::sampling::{kendall_tau, GOAL_ERROR, GOAL_TAU};
use crate::{AppError, AppResult, MachineSpec, Report, Row};
use isa::rng::Rng;
use isa::{FlavourId, Trace};
use rayon::prelude::*;
use sim::{Fidelity, MachineConfig, SimOptions};
use std::time::Instant;

/// A paper's kernels' traces on one flavour: (kernel, trace), none for a
/// flavour its kernels do not run.
pub type Traces<'a> = &'a dyn Fn(FlavourId) -> AppResult<Vec<(String, Trace)>>;

/// `rtsim replay` options.
#[derive(Clone, Debug)]
pub struct ReplayArgs {
    /// Window seed.
    pub seed: u64,
    /// Windows cut from each kernel's trace.
    pub windows: usize,
    /// Shortest and longest window, in recorded ops.
    pub ops: (usize, usize),
    /// Flavours (default: every one this host runs).
    pub flavours: Vec<FlavourId>,
    /// The model (`None`: this host's config).
    pub machine: Option<String>,
    /// Config overrides.
    pub sets: Vec<String>,
    /// Timed runs of each loop length (the minimum is kept).
    pub repeat: u32,
    /// Write each window's listing (assembly with the model's classes) here.
    pub listing: Option<std::path::PathBuf>,
    /// Output format.
    pub format: Format,
}

/// One window measured both ways.
#[derive(Clone, Debug)]
struct Point {
    kernel: String,
    flavour: FlavourId,
    recorded_ops: usize,
    insts: usize,
    host: f64,
    model: f64,
    steady: bool,
    changes: replay::Changes,
}

/// A window cut from a trace, built.
struct Window {
    kernel: String,
    built: replay::Built,
}

/// The flavours this host can run.
#[must_use]
pub fn host_flavours() -> Vec<FlavourId> {
    let mut v = vec![FlavourId::Sse4];
    if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
        v.push(FlavourId::Avx2);
    }
    if std::arch::is_x86_feature_detected!("avx512f")
        && std::arch::is_x86_feature_detected!("avx512dq")
    {
        v.push(FlavourId::Avx512);
    }
    v
}

fn model(a: &ReplayArgs, host: &HostCpu, fl: FlavourId) -> AppResult<MachineConfig> {
    let name = match &a.machine {
        Some(m) => m.clone(),
        None => host.model_config().0.map(str::to_string).ok_or_else(|| {
            AppError(format!(
                "replay: {}; pass --machine NAME",
                host.model_config().1
            ))
        })?,
    };
    let mut sets = a.sets.clone();
    sets.push(format!("isa={}", fl.name()));
    MachineSpec {
        machine: name,
        sets,
    }
    .load()
}

/// Cut `n` windows from `t` at seeded places (the first tenth, the
/// kernel's start-up, left out), build each; failures counted by reason.
fn cut(
    t: &Trace,
    kernel: &str,
    a: &ReplayArgs,
    rng: &mut Rng,
    failed: &mut Vec<(String, String)>,
) -> Vec<Window> {
    let len = t.ops.len();
    let mut out = Vec::new();
    let (lo, hi) = (a.ops.0 as f64, a.ops.1 as f64);
    let mut tries = 0;
    while out.len() < a.windows && tries < 4 * a.windows {
        tries += 1;
        let w = (lo * (hi / lo).powf(f64::from(rng.f32()))).round() as usize;
        if len < w + len / 10 + 1 {
            break;
        }
        let start = len / 10 + rng.below((len - w - len / 10) as u64) as usize;
        match replay::build(t, start..start + w) {
            Ok(built) => out.push(Window {
                kernel: kernel.to_string(),
                built,
            }),
            Err(e) => failed.push((kernel.to_string(), e)),
        }
    }
    out
}

/// The model's steady cycles per iteration of `body`, doubling the
/// iterations until successive windows agree ([`Steady`]).
fn simulate(m: &MachineConfig, body: &Trace) -> AppResult<(f64, bool)> {
    let opt = SimOptions {
        fidelity: Fidelity::Full,
        warmup_ops: 0,
        timeline: None,
    };
    let mut runs = Vec::new();
    let mut n = 4;
    loop {
        let t = sim::repeat(body, n);
        let s = sim::simulate(m, &[&t], &opt).map_err(AppError)?;
        runs.push((n, s.cycles));
        let st = Steady::of(&runs);
        let budget = n * body.ops.len() > 4_000_000;
        if (runs.len() >= 4 && st.converged_after.is_some()) || budget || n >= 4096 {
            return Ok((st.per_iteration, st.converged_after.is_some()));
        }
        n *= 2;
    }
}

/// `rtsim replay`.
///
/// # Errors
/// No model for this host, a scene that does not load, or no window built.
pub fn replay_report(a: &ReplayArgs, papers: &[(&str, Traces)]) -> AppResult<Report> {
    let start = Instant::now();
    if a.windows == 0 || a.ops.0 < 16 || a.ops.0 > a.ops.1 || a.repeat == 0 {
        return Err(AppError(
            "replay: --windows and --repeat at least 1, --min-ops at least 16 and at most --max-ops".into(),
        ));
    }
    let host = HostCpu::detect();
    let cpt = replay::cycles_per_tick().map_err(AppError)?;
    let mut points = Vec::new();
    let mut failed = Vec::new();
    let mut ops_simulated = 0u64;
    let mut mname = String::new();
    for &fl in &a.flavours {
        let m = model(a, &host, fl)?;
        mname.clone_from(&m.name);
        let mut rng = Rng::new(a.seed ^ fl as u64);
        let mut windows = Vec::new();
        for (paper, traces) in papers {
            for (k, t) in traces(fl)? {
                let k = format!("{paper}/{k}");
                windows.extend(cut(&t, &k, a, &mut rng, &mut failed));
            }
        }
        let mut timed = Vec::new();
        for (n, w) in windows.into_iter().enumerate() {
            if let Some(dir) = &a.listing {
                std::fs::create_dir_all(dir)?;
                let f = dir.join(format!(
                    "{}-{}-{n:03}.asm",
                    w.kernel.replace('/', "-"),
                    fl.name()
                ));
                crate::io::write_atomic(&f, replay::listing(&w.built).as_bytes())?;
            }
            let p = &w.built.program;
            match replay::host::time(
                &w.built.code,
                &p.init_mem,
                p.buffer_bytes,
                a.repeat,
                2_000_000,
            ) {
                Ok(h) => timed.push((w, h.ticks_per_iteration * cpt)),
                Err(e) => failed.push((w.kernel.clone(), e)),
            }
        }
        let sims: Vec<AppResult<(f64, bool)>> = timed
            .par_iter()
            .map(|(w, _)| simulate(&m, &w.built.body))
            .collect();
        for ((w, hc), s) in timed.into_iter().zip(sims) {
            let (model, steady) = s?;
            ops_simulated += w.built.body.ops.len() as u64;
            let p = &w.built.program;
            points.push(Point {
                kernel: w.kernel,
                flavour: fl,
                recorded_ops: p.recorded_ops,
                insts: p.insts.len() + 2,
                host: hc,
                model,
                steady,
                changes: p.changes,
            });
        }
    }
    if points.is_empty() {
        return Err(AppError(format!(
            "replay: no window ran ({} failed: {:?})",
            failed.len(),
            failed.first()
        )));
    }
    let cpt_after = replay::cycles_per_tick().map_err(AppError)?;
    let rows = rows(&points, &failed);
    Ok(Report {
        report: "replay".into(),
        machine: Some(mname),
        isa: Some(a.flavours.iter().map(|f| f.name()).collect::<Vec<_>>().join(",")),
        fidelity: "full".into(),
        sample: None,
        input: Some(format!(
            "{} windows of {}-{} recorded ops (seed {}) from each traversal kernel's trace on its paper's replay workload ({}), on host {} (core clock {:.3} / {:.3} cycles per TSC tick before / after)",
            a.windows, a.ops.0, a.ops.1, a.seed,
            papers.iter().map(|p| p.0).collect::<Vec<_>>().join(", "),
            host.describe_build(), cpt, cpt_after
        )),
        ops_simulated,
        host_seconds: start.elapsed().as_secs_f64(),
        rows,
        notes: notes(&points, &failed),
    })
}

fn summary(pts: &[&Point]) -> (Option<f64>, f64, f64) {
    let h: Vec<f64> = pts.iter().map(|p| p.host).collect();
    let m: Vec<f64> = pts.iter().map(|p| p.model).collect();
    let hc: Vec<f64> = pts.iter().map(|p| p.host / p.insts as f64).collect();
    let mc: Vec<f64> = pts.iter().map(|p| p.model / p.insts as f64).collect();
    let err = pts
        .iter()
        .map(|p| (p.model - p.host).abs() / p.host)
        .sum::<f64>()
        / pts.len().max(1) as f64;
    let tau = kendall_tau(&h, &m);
    (tau, kendall_tau(&hc, &mc).unwrap_or(f64::NAN), err)
}

fn rows(points: &[Point], failed: &[(String, String)]) -> Vec<Row> {
    let mut rows = Vec::new();
    let mut groups: Vec<(String, FlavourId)> = points
        .iter()
        .map(|p| (p.kernel.clone(), p.flavour))
        .collect();
    groups.sort_by_key(|(k, f)| (k.clone(), f.name()));
    groups.dedup();
    let push = |rows: &mut Vec<Row>, kernel: &str, isa: &str, pts: &[&Point]| {
        let (tau, tau_cpi, err) = summary(pts);
        let key = |r: Row| r.key("kernel", kernel).key("isa", isa);
        rows.push(key(Row::new("windows", pts.len() as f64)));
        rows.push(key(Row::new("kendall_tau", tau.unwrap_or(f64::NAN))));
        rows.push(key(Row::new("kendall_tau_per_instruction", tau_cpi)));
        rows.push(key(Row::new("mean_abs_error", err).unit("fraction")));
        let hc = pts.iter().map(|p| p.host / p.insts as f64).sum::<f64>() / pts.len() as f64;
        let mc = pts.iter().map(|p| p.model / p.insts as f64).sum::<f64>() / pts.len() as f64;
        rows.push(key(Row::new("host_cycles_per_instruction", hc)));
        rows.push(key(Row::new("model_cycles_per_instruction", mc)));
    };
    for (k, f) in &groups {
        let pts: Vec<&Point> = points
            .iter()
            .filter(|p| &p.kernel == k && p.flavour == *f)
            .collect();
        push(&mut rows, k, f.name(), &pts);
    }
    let all: Vec<&Point> = points.iter().collect();
    push(&mut rows, "all", "all", &all);
    rows.push(Row::new("windows_failed", failed.len() as f64).key("kernel", "all"));
    let n = points.len() as f64;
    let added = points
        .iter()
        .map(|p| p.changes.added as f64 / p.insts as f64)
        .sum::<f64>()
        / n;
    let dropped = points
        .iter()
        .map(|p| p.changes.dropped_address_deps)
        .sum::<usize>() as f64;
    let unknown = points
        .iter()
        .map(|p| p.changes.unknown_branches)
        .sum::<usize>() as f64;
    let unsteady = points.iter().filter(|p| !p.steady).count() as f64;
    let recorded = points.iter().map(|p| p.recorded_ops as f64).sum::<f64>() / n;
    rows.push(Row::new("recorded_ops_per_window", recorded).key("kernel", "all"));
    rows.push(Row::new("added_instruction_share", added).key("kernel", "all"));
    rows.push(Row::new("dropped_address_dependencies", dropped).key("kernel", "all"));
    rows.push(Row::new("branches_of_unknown_direction", unknown).key("kernel", "all"));
    rows.push(Row::new("model_not_steady_windows", unsteady).key("kernel", "all"));
    rows
}

fn notes(points: &[Point], failed: &[(String, String)]) -> Vec<String> {
    let all: Vec<&Point> = points.iter().collect();
    let mut why: Vec<(String, usize)> = Vec::new();
    for (k, e) in failed {
        // The reason without the instruction's details.
        let short: String = e
            .split(" : ")
            .next()
            .unwrap_or(e)
            .chars()
            .take(60)
            .collect();
        let r = format!("{k}: {short}");
        match why.iter_mut().find(|(w, _)| *w == r) {
            Some(w) => w.1 += 1,
            None => why.push((r, 1)),
        }
    }
    let (tau, _, err) = summary(&all);
    let tau = tau.unwrap_or(f64::NAN);
    let met = |ok: bool| if ok { "met" } else { "not met" };
    vec![
        format!(
            "Over all {} windows: Kendall tau {tau:.3} (goal {GOAL_TAU}: {}), mean absolute error {:.1}% (goal {:.0}%: {}).",
            points.len(),
            met(tau >= GOAL_TAU),
            100.0 * err,
            100.0 * GOAL_ERROR,
            met(err <= GOAL_ERROR)
        ),
        "Each window is the recorded ops as the instructions their classes name (AVX2 and SSE4 as VEX forms, AVX-512 as EVEX with mask registers), registers allocated from the trace's values (linear scan; spills and reloads as a compiler's), memory at the recorded page offsets in one zero-filled buffer, every branch going the recorded way to the next instruction; host cycles are the minimum over repeated runs of n and 2n iterations, differenced (BHive's method), TSC ticks converted by a dependent-add chain; the model runs the same loop as a trace until successive windows agree within 0.5%.".into(),
        format!(
            "{} windows not run: {}",
            failed.len(),
            if why.is_empty() { "none".to_string() } else { why.iter().map(|(w, n)| format!("{w} ({n})")).collect::<Vec<_>>().join("; ") }
        ),
        "Added instructions (copies for two-operand forms and merges, flag tests, spills, moves between register files) are in both the host's loop and the model's trace; a folded memory operand is replayed as its own load and priced so.".into(),
    ]
}

/// `rtsim replay` arguments.
#[derive(clap::Args, Debug)]
pub struct ReplayCli {
    /// Papers whose kernels to replay (repeat the flag; default: all five):
    /// drs, mft, mbvh, multihit, volume.
    #[arg(long = "paper")]
    pub papers: Vec<String>,
    /// Window seed.
    #[arg(long, default_value_t = 7)]
    pub seed: u64,
    /// Windows cut from each recorded trace.
    #[arg(long, default_value_t = 2)]
    pub windows: usize,
    /// Shortest window, in recorded ops.
    #[arg(long, default_value_t = 200)]
    pub min_ops: usize,
    /// Longest window, in recorded ops.
    #[arg(long, default_value_t = 2000)]
    pub max_ops: usize,
    /// Flavours (repeat the flag; default: every one this host runs).
    #[arg(long = "isa", value_parser = parse_flavour)]
    pub isa: Vec<FlavourId>,
    /// The model (default: the built-in config of this host's CPU).
    #[arg(long)]
    pub machine: Option<String>,
    /// Override a config field of the model: `--set core.rob=256`.
    #[arg(long = "set", value_name = "FIELD=VALUE")]
    pub sets: Vec<String>,
    /// Timed runs of each loop length (the minimum is kept).
    #[arg(long, default_value_t = 15)]
    pub repeat: u32,
    /// Write each window's listing (assembly, each line with the class the
    /// model prices it as and its inputs' steady values, `+` where the
    /// replay added it) into this folder.
    #[arg(long, value_name = "DIR")]
    pub listing: Option<std::path::PathBuf>,
    /// Output format: text, json or csv.
    #[arg(long, value_parser = Format::from_name, default_value = "text")]
    pub format: Format,
}

impl ReplayCli {
    /// The library's options.
    #[must_use]
    pub fn args(self) -> ReplayArgs {
        ReplayArgs {
            seed: self.seed,
            windows: self.windows,
            ops: (self.min_ops, self.max_ops),
            flavours: if self.isa.is_empty() {
                host_flavours()
            } else {
                self.isa
            },
            machine: self.machine,
            sets: self.sets,
            repeat: self.repeat,
            listing: self.listing,
            format: self.format,
        }
    }
}

fn parse_flavour(s: &str) -> Result<FlavourId, String> {
    FlavourId::from_name(s)
        .ok_or_else(|| format!("unknown isa '{s}' (sse4, avx2, avx512 run on x86-64 hosts)"))
}

/// The papers `--paper` names (all of `all` when none), or which name is
/// unknown.
///
/// # Errors
/// A name that is not one of `all`'s.
pub fn choose<'a>(
    all: &[(&'a str, Traces<'a>)],
    names: &[String],
) -> AppResult<Vec<(&'a str, Traces<'a>)>> {
    for n in names {
        if !all.iter().any(|(p, _)| p == n) {
            let known: Vec<&str> = all.iter().map(|p| p.0).collect();
            return Err(AppError(format!(
                "--paper {n}: unknown ({})",
                known.join(", ")
            )));
        }
    }
    Ok(all
        .iter()
        .filter(|(p, _)| names.is_empty() || names.iter().any(|n| n == p))
        .copied()
        .collect())
}
