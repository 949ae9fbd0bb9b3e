//! `rtsim run` and `rtsim trace record|info|text`.

use crate::report::{Format, Report, Row};
use crate::{parse_isa, AppError, AppResult};
use clap::{Args, Subcommand};
use isa::{info, trace_file, trace_text, FlavourId, Trace};
use kernels::boxtest::{box4_ref, BoxStream};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// `rtsim run` arguments.
#[derive(Args)]
pub struct RunArgs {
    /// Machine to time it on (its ISA is the kernel's).
    #[command(flatten)]
    pub machine: crate::machine_cmd::MachineArgs,
    /// Record on this ISA instead and do not time it (e.g. avx512, which no
    /// shipped machine runs).
    #[arg(long, value_parser = parse_isa)]
    pub isa: Option<FlavourId>,
    /// Kernel: boxtest (ray stream vs 4 boxes), single-bvh2, single-bvh4, drs-bvh2, drs-bvh4.
    #[arg(long, default_value = "boxtest")]
    pub kernel: String,
    /// Scene for the traversal kernels (`rtsim list scenes`, a .ron or a mesh file).
    #[arg(long, default_value = "sphere")]
    pub scene: String,
    /// Ray stream for the traversal kernels: primary, bounce (the first bounce of the path
    /// tracer) or shadow (shadow rays from the primary hits, any hit).
    #[arg(long, default_value = "primary")]
    pub stream: String,
    /// Tile side in pixels (traversal kernels): the stream is one tile at the image centre.
    #[arg(long, default_value_t = 16)]
    pub tile: u32,
    /// Samples per pixel (traversal kernels).
    #[arg(long, default_value_t = 16)]
    pub spp: u32,
    /// Rays in the stream (boxtest; a multiple of 4).
    #[arg(long, default_value_t = 4096)]
    pub rays: usize,
    /// Seed of the generated node and rays.
    #[arg(long, default_value_t = 7)]
    pub seed: u64,
    /// Also write the recorded trace here (binary; `.txt` for the text form).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Output format.
    #[arg(long, value_enum, default_value = "text")]
    pub format: Format,
}

/// `rtsim trace ...`.
#[derive(Subcommand)]
pub enum TraceCmd {
    /// Record a built-in microkernel or kernel to a trace file.
    Record {
        /// A microkernel (`rtsim list micro`).
        #[arg(long, conflicts_with = "kernel", required_unless_present = "kernel")]
        micro: Option<String>,
        /// A kernel: `boxtest` (ray stream vs 4 boxes).
        #[arg(long)]
        kernel: Option<String>,
        /// ISA flavour: lrb16, avx512, avx2, sse4.
        #[arg(long, value_parser = parse_isa, default_value = "avx2")]
        isa: FlavourId,
        /// Parameters as key=value (microkernels: iters, unroll, streams, ws, seed;
        /// boxtest: rays, seed).
        #[arg(long = "param", value_name = "KEY=VALUE")]
        params: Vec<String>,
        /// Output file (binary; a name ending in `.txt` gets the text form).
        #[arg(long)]
        out: PathBuf,
    },
    /// Summarise a trace: ops per class and region, lanes, bytes per region.
    Info {
        /// A binary or text trace.
        file: PathBuf,
        /// Output format.
        #[arg(long, value_enum, default_value = "text")]
        format: Format,
    },
    /// Convert binary to text or text to binary (the input's form decides).
    Text {
        /// Input trace.
        input: PathBuf,
        /// Output trace.
        output: PathBuf,
    },
}

/// Read a binary or text trace; errors name the file and byte or line.
pub fn load_trace(path: &Path) -> AppResult<Trace> {
    load_trace_loop(path, false)
}

/// Read a trace; with `as_loop`, a source may be defined later in the body
/// (a loop-carried value), as for `rtsim sim --iterations`.
pub fn load_trace_loop(path: &Path, as_loop: bool) -> AppResult<Trace> {
    let bytes = std::fs::read(path).map_err(|e| AppError(format!("{}: {e}", path.display())))?;
    if bytes.starts_with(trace_file::MAGIC) {
        return trace_file::decode(&bytes)
            .map_err(|e| AppError(format!("{}: {e}", path.display())));
    }
    let text = std::str::from_utf8(&bytes).map_err(|e| {
        AppError(format!(
            "{}: byte {}: not an rtsim trace (no binary magic, not UTF-8 text)",
            path.display(),
            e.valid_up_to()
        ))
    })?;
    let t = trace_text::parse(text).map_err(|e| AppError(format!("{}: {e}", path.display())))?;
    let checked = if as_loop {
        t.validate_loop()
    } else {
        t.validate()
    };
    checked.map_err(|e| AppError(format!("{}: {e}", path.display())))?;
    Ok(t)
}

/// Write a file whole or not at all: a temporary beside it, then a rename.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> AppResult<()> {
    let name = path
        .file_name()
        .ok_or_else(|| AppError(format!("{}: not a file name", path.display())))?;
    let tmp = path.with_file_name(format!(
        ".{}.tmp-{}",
        name.to_string_lossy(),
        std::process::id()
    ));
    let r = std::fs::write(&tmp, bytes).and_then(|()| std::fs::rename(&tmp, path));
    if let Err(e) = r {
        let _ = std::fs::remove_file(&tmp);
        return Err(AppError(format!("{}: {e}", path.display())));
    }
    Ok(())
}

fn is_text_name(p: &Path) -> bool {
    p.extension().is_some_and(|e| e == "txt")
}

/// Encode a trace in the form the file name asks for.
fn save_trace(t: &Trace, path: &Path) -> AppResult<usize> {
    let bytes = if is_text_name(path) {
        trace_text::write(t).into_bytes()
    } else {
        trace_file::encode(t)
    };
    write_atomic(path, &bytes)?;
    Ok(bytes.len())
}

fn split_params(params: &[String]) -> AppResult<Vec<(String, String)>> {
    params
        .iter()
        .map(|p| {
            p.split_once('=')
                .map(|(k, v)| (k.trim().to_string(), v.trim().to_string()))
                .ok_or_else(|| AppError(format!("--param '{p}': expected KEY=VALUE")))
        })
        .collect()
}

/// Rows describing a trace's contents.
#[must_use]
pub fn info_rows(t: &Trace) -> Vec<Row> {
    let i = info::info(t);
    let mut rows = vec![
        Row::new("ops", i.ops as f64).unit("ops"),
        Row::new("values", i.values as f64),
        Row::new("vector_ops", i.vector_ops as f64).unit("ops"),
        Row::new("lane_utilisation", i.lane_utilisation),
        Row::new("branches", i.branches as f64),
        Row::new("branches_taken", i.taken as f64),
    ];
    for (c, n) in &i.per_class {
        rows.push(Row::new("ops", *n as f64).key("class", c).unit("ops"));
    }
    for (r, n) in &i.per_region {
        rows.push(Row::new("ops", *n as f64).key("region", r).unit("ops"));
    }
    for m in &i.mem {
        let row = |metric: &str, v: u64, unit: &str| {
            Row::new(metric, v as f64)
                .key("mem", &m.name)
                .key("kind", &m.kind)
                .unit(unit)
        };
        rows.push(row("loads", m.loads, "accesses"));
        rows.push(row("stores", m.stores, "accesses"));
        rows.push(row("bytes_read", m.bytes_read, "B"));
        rows.push(row("bytes_written", m.bytes_written, "B"));
        rows.push(row("lines_touched", m.lines, "64B lines"));
    }
    rows
}

fn base_report(name: &str, t: &Trace, input: String, secs: f64, rows: Vec<Row>) -> Report {
    Report {
        report: name.into(),
        machine: None,
        isa: Some(t.flavour.name().into()),
        fidelity: "counts".into(),
        sample: None,
        input: Some(input),
        ops_simulated: t.ops.len() as u64,
        host_seconds: secs,
        rows,
        notes: Vec::new(),
    }
}

pub fn boxstream(rays: usize, seed: u64) -> AppResult<BoxStream> {
    if rays == 0 || !rays.is_multiple_of(4) {
        return Err(AppError(format!(
            "rays: {rays} is not a positive multiple of 4 (every ISA tests LANES/4 rays per step)"
        )));
    }
    Ok(BoxStream::generate(rays, seed))
}

/// `rtsim run`.
pub fn run(a: &RunArgs) -> AppResult<()> {
    match a.kernel.as_str() {
        "boxtest" => run_boxtest(a),
        k => match kernels::harness::Kernel::ALL.iter().find(|t| t.name() == k) {
            Some(&t) => run_traversal(a, t),
            None => Err(AppError(format!(
                "--kernel: unknown kernel '{k}' (boxtest, {})",
                kernels::harness::Kernel::ALL.map(|k| k.name()).join(", ")
            ))),
        },
    }
}

/// A traversal kernel over one tile's ray stream of a scene.
fn run_traversal(a: &RunArgs, kernel: kernels::harness::Kernel) -> AppResult<()> {
    use kernels::bvh::{BuildConfig, Bvh2, Bvh4};
    use kernels::workload::{path_trace_tile, primary_tile, StreamKind, Tile};
    let start = Instant::now();
    let m = a.machine.load()?;
    let fl = a.isa.unwrap_or_else(|| m.flavour());
    if !kernel.supports(fl.lanes()) {
        return Err(AppError(format!(
            "--kernel {}: runs on 4- and 8-lane ISAs, {fl} has {} lanes",
            kernel.name(),
            fl.lanes()
        )));
    }
    if a.tile == 0 || a.tile > 256 || a.spp == 0 || a.spp > 256 {
        return Err(AppError("--tile and --spp: must be 1 to 256".into()));
    }
    let scene = kernels::scene::Scene::load(&a.scene).map_err(|e| AppError(e.0))?;
    let b2 = Bvh2::build(
        &scene.mesh,
        &BuildConfig {
            max_leaf: 8,
            ..BuildConfig::default()
        },
    )
    .map_err(AppError)?;
    let b4 = Bvh4::collapse(&b2);
    let cam = &scene.config.camera;
    let tile = Tile {
        x: cam.width / 2 / a.tile,
        y: cam.height / 2 / a.tile,
        size: a.tile,
    };
    let stream = match a.stream.as_str() {
        "primary" => primary_tile(cam, tile.x, tile.y, tile.size, a.spp, a.seed),
        "bounce" => path_trace_tile(&scene, &b2, tile, a.spp, 1, a.seed)
            .into_iter()
            .find(|s| s.kind == StreamKind::Bounce(1))
            .ok_or_else(|| {
                AppError("--stream bounce: no path survives the first hit in this tile".into())
            })?,
        "shadow" => path_trace_tile(&scene, &b2, tile, a.spp, 0, a.seed)
            .into_iter()
            .find(|s| s.kind == StreamKind::Shadow(0))
            .ok_or_else(|| AppError("--stream shadow: no primary ray hits in this tile".into()))?,
        s => {
            return Err(AppError(format!(
                "--stream: '{s}' is not primary, bounce or shadow"
            )))
        }
    };
    if stream.is_empty() || stream.len() > 65536 {
        return Err(AppError(format!(
            "the stream has {} rays (1 to 65536 needed)",
            stream.len()
        )));
    }
    let mut run = kernels::harness::Run::new(kernel, &scene, &b2, &b4, stream.clone());
    run.packet_tile = Some((tile.size, a.spp));
    let (t, (traced, tests)) = isa::record(&run, fl, kernel.name());
    let (native, native_tests) = isa::run_native(&run, fl);
    if native_tests != tests {
        return Err(AppError(format!(
            "{}: traced and native backends counted different tests ({tests:?} vs {native_tests:?})",
            kernel.name()
        )));
    }
    let refi = kernels::reference::Reference::with_bvh(&scene.mesh, &b2);
    let bad = run.mismatches(kernel.name(), &refi, &traced);
    let native_bad = traced.iter().zip(&native).filter(|(x, y)| x != y).count();
    let rays = stream.len() as u64;
    let mut rows = vec![
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
    let timed = fl == m.flavour();
    if timed {
        let s = sim::simulate(&m, &[&t], &sim::SimOptions::default()).map_err(AppError)?;
        rows.extend(crate::machine_cmd::stats_rows(&s, &m, Some(rays)));
        rows.extend(crate::machine_cmd::region_rows(&s, &t));
    } else {
        rows.extend(info_rows(&t));
    }
    let mut rep = base_report(
        &format!("run-{}", kernel.name()),
        &t,
        format!(
            "{} on {}, {} stream of tile ({}, {}) x {} spp, seed {}",
            kernel.name(),
            scene.config.name,
            a.stream,
            tile.x,
            tile.y,
            a.spp,
            a.seed
        ),
        start.elapsed().as_secs_f64(),
        rows,
    );
    if timed {
        rep.machine = Some(m.name.clone());
        rep.fidelity = "full".into();
    }
    print!("{}", rep.render(a.format));
    if bad + native_bad > 0 {
        return Err(AppError(format!(
            "{bad} rays differ from the reference, {native_bad} between traced and native"
        )));
    }
    Ok(())
}

/// The ray-vs-4-boxes workload.
fn run_boxtest(a: &RunArgs) -> AppResult<()> {
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
    let mut rows = vec![
        Row::new("rays", a.rays as f64),
        Row::new("box_hits", want.iter().map(|b| b.count_ones() as f64).sum()),
        Row::new("hit_mismatches", traced_bad as f64).key("backend", "traced"),
        Row::new("hit_mismatches", native_bad as f64).key("backend", "native"),
        Row::new("ops_per_ray", t.ops.len() as f64 / a.rays as f64).unit("ops"),
    ];
    if let Some(out) = &a.out {
        let n = save_trace(&t, out)?;
        rows.push(Row::new("trace_bytes", n as f64).unit("B"));
        rows.push(Row::new("trace_bytes_per_op", n as f64 / t.ops.len() as f64).unit("B"));
    }
    let timed = fl == m.flavour();
    if timed {
        let s = sim::simulate(&m, &[&t], &sim::SimOptions::default()).map_err(AppError)?;
        rows.extend(crate::machine_cmd::stats_rows(&s, &m, Some(a.rays as u64)));
        rows.extend(crate::machine_cmd::region_rows(&s, &t));
    } else {
        rows.extend(info_rows(&t));
    }
    let mut rep = base_report(
        "run-boxtest",
        &t,
        format!("{} rays vs 4 boxes, seed {}", a.rays, a.seed),
        start.elapsed().as_secs_f64(),
        rows,
    );
    if timed {
        rep.machine = Some(m.name.clone());
        rep.fidelity = "full".into();
    }
    print!("{}", rep.render(a.format));
    if traced_bad + native_bad > 0 {
        return Err(AppError(format!(
            "{traced_bad} traced and {native_bad} native rays differ from the scalar reference"
        )));
    }
    Ok(())
}

/// `rtsim trace ...`.
pub fn trace(cmd: TraceCmd) -> AppResult<()> {
    match cmd {
        TraceCmd::Record {
            micro,
            kernel,
            isa: fl,
            params,
            out,
        } => {
            let params = split_params(&params)?;
            let (t, source) = if let Some(name) = micro {
                let k = kernels::micro::build(&name, &params)?;
                let src = format!("micro:{name}");
                (isa::record(&k, fl, &src).0, src)
            } else {
                let name = kernel.expect("clap requires one");
                if name != "boxtest" {
                    return Err(AppError(format!(
                        "unknown kernel '{name}' (built in: boxtest)"
                    )));
                }
                let (mut rays, mut seed) = (4096usize, 7u64);
                for (k, v) in &params {
                    let bad = || AppError(format!("--param {k}={v}: not a whole number"));
                    match k.as_str() {
                        "rays" => rays = v.parse().map_err(|_| bad())?,
                        "seed" => seed = v.parse().map_err(|_| bad())?,
                        _ => {
                            return Err(AppError(format!(
                                "unknown boxtest parameter '{k}' (rays, seed)"
                            )))
                        }
                    }
                }
                let w = boxstream(rays, seed)?;
                let mut t = isa::record(&w, fl, "kernel:boxtest").0;
                t.params.push(("seed".into(), seed.to_string()));
                (t, "kernel:boxtest".to_string())
            };
            let n = save_trace(&t, &out)?;
            println!(
                "wrote {}: {source} on {fl}, {} ops, {n} bytes ({:.2} bytes/op)",
                out.display(),
                t.ops.len(),
                n as f64 / t.ops.len().max(1) as f64
            );
            Ok(())
        }
        TraceCmd::Info { file, format } => {
            let start = Instant::now();
            let t = load_trace(&file)?;
            let size = std::fs::metadata(&file)?.len();
            let mut rows = vec![
                Row::new("file_bytes", size as f64).unit("B"),
                Row::new("bytes_per_op", size as f64 / t.ops.len().max(1) as f64).unit("B"),
            ];
            rows.extend(info_rows(&t));
            let mut rep = base_report(
                "trace-info",
                &t,
                format!("{} ({})", file.display(), t.source),
                start.elapsed().as_secs_f64(),
                rows,
            );
            rep.sample = None;
            print!("{}", rep.render(format));
            Ok(())
        }
        TraceCmd::Text { input, output } => {
            let t = load_trace(&input)?;
            let binary_in = std::fs::read(&input)?.starts_with(trace_file::MAGIC);
            let bytes = if binary_in {
                trace_text::write(&t).into_bytes()
            } else {
                trace_file::encode(&t)
            };
            write_atomic(&output, &bytes)?;
            println!(
                "wrote {} ({} form, {} ops, {} bytes)",
                output.display(),
                if binary_in { "text" } else { "binary" },
                t.ops.len(),
                bytes.len()
            );
            Ok(())
        }
    }
}
