//! The command line: clap definitions, and their conversion into the
//! libraries' plain option structs.

use clap::{Args, Parser, Subcommand};
use isa::FlavourId;
use repro::report::Format;
use repro::scenes::{RenderArgs, Shade};
use repro::{AppResult, Given, MachineSpec, Opt, ReportDef};
use sim::{Fidelity, MachineConfig};
use std::path::PathBuf;

#[derive(Parser)]
#[command(
    name = "rtsim",
    version,
    about = "Cycle-level SIMD architecture simulator and the ray-tracing kernels that run on it"
)]
pub struct Cli {
    #[command(subcommand)]
    pub cmd: Cmd,
}

#[derive(Subcommand)]
pub enum Cmd {
    /// Record the default workload (a 4096-ray stream vs one BVH4 node's 4
    /// boxes, the DRS inner test) or a traversal kernel on an ISA, check every
    /// ray against the scalar reference, and report what the op stream holds.
    Run(RunCli),
    /// Compute a paper's table or figure on the models.
    Reproduce(ReproduceCli),
    /// Record, inspect and convert op traces.
    #[command(subcommand)]
    Trace(TraceCmd),
    /// Time a recorded or hand-written trace on a machine.
    Sim(SimCli),
    /// Time the traversal kernels natively on this host over one tile's stream
    /// (and Embree 3 on the same rays, where the host has it), every
    /// answer checked against the reference.
    Native(NativeCli),
    /// Check the model against this host: every traversal kernel timed natively
    /// and simulated on the model of this CPU over the same rays; Kendall tau
    /// and mean error of the times relative to single-ray BVH4.
    Validate(ValidateCli),
    /// Check the model against this host on the kernels' own instruction
    /// streams: windows of every traversal kernel's recorded trace run as
    /// x86-64 loops on this host and on the model of this CPU; Kendall tau
    /// and mean error of cycles per iteration.
    Replay(repro::replay::ReplayCli),
    /// Time one traversal kernel over one tile's stream on a grid of one or two
    /// config fields (`--vary classes.vfma.lat=3,4,5,6 --vary core.width=2,4,6`;
    /// `--vary isa=sse4,avx2` varies the lanes): a table, and a PNG with --out.
    Sweep(drs_report::sweep::SweepCli),
    /// Run the microkernels through a machine model next to what its config implies.
    Calibrate(CalibrateCli),
    /// Time one workload in every fidelity mode: host time and error against full.
    Fidelity(FidelityCli),
    /// Render primary hits of a scene with the reference intersector (PNG).
    Render(RenderCli),
    /// Cast a volume through the volume paper's casters (gcc, sse, bvh):
    /// timed on one core of a machine, the bvh frame checked against the f64
    /// reference (PNG with --out).
    Volume(VolumeCli),
    /// List what is built in.
    List {
        /// What to list.
        #[arg(value_enum)]
        what: ListWhat,
        /// Scenes only: list just these (default: every built-in scene).
        names: Vec<String>,
        /// Output format: text, json or csv.
        #[arg(long, value_parser = Format::from_name, default_value = "text")]
        format: Format,
    },
}

#[derive(Clone, Copy, clap::ValueEnum)]
pub enum ListWhat {
    /// Calibration microkernels.
    Micro,
    /// ISA flavours.
    Isa,
    /// Op classes.
    Classes,
    /// Machine configs.
    Machines,
    /// Scenes, with triangle counts, BVH build times and SAH costs.
    Scenes,
}

impl ListWhat {
    /// The name in the report's title.
    pub fn name(self) -> &'static str {
        match self {
            ListWhat::Micro => "micro",
            ListWhat::Isa => "isa",
            ListWhat::Classes => "classes",
            ListWhat::Machines => "machines",
            ListWhat::Scenes => "scenes",
        }
    }
}

/// Parse an ISA flavour name for clap.
pub fn parse_isa(s: &str) -> Result<FlavourId, String> {
    FlavourId::from_name(s).ok_or_else(|| {
        let names: Vec<&str> = FlavourId::ALL.iter().map(|f| f.name()).collect();
        format!("unknown ISA '{s}' (one of: {})", names.join(", "))
    })
}

/// Parse a fidelity name for clap.
fn parse_fidelity(s: &str) -> Result<Fidelity, String> {
    Fidelity::from_name(s).ok_or_else(|| format!("unknown fidelity '{s}' (counts, caches, full)"))
}

/// A machine and its overrides.
#[derive(Args)]
pub struct MachineCli {
    /// A built-in machine (`rtsim list machines`) or a path to a RON config.
    #[arg(long, default_value = "haswell-i7-4750hq")]
    pub machine: String,
    /// Override a config field: `--set core.width=6 --set l2.size_kib=128`.
    #[arg(long = "set", value_name = "FIELD=VALUE")]
    pub sets: Vec<String>,
}

impl MachineCli {
    fn spec(&self) -> MachineSpec {
        MachineSpec {
            machine: self.machine.clone(),
            sets: self.sets.clone(),
        }
    }
    /// Load, apply overrides, validate.
    pub fn load(&self) -> AppResult<MachineConfig> {
        self.spec().load()
    }
}

/// The kernels `rtsim run` accepts.
pub fn kernel_names() -> Vec<&'static str> {
    let mut v = vec!["boxtest"];
    v.extend(drs_report::run::kernel_names());
    v
}

/// `rtsim run` arguments.
#[derive(Args)]
pub struct RunCli {
    /// Machine to time it on (its ISA is the kernel's).
    #[command(flatten)]
    pub machine: MachineCli,
    /// Record on this ISA instead and do not time it (to time the 16-lane
    /// AVX-512 flavour, give a machine that runs it: `--machine zen4-avx512`).
    #[arg(long, value_parser = parse_isa)]
    pub isa: Option<FlavourId>,
    /// Kernel, or traversal kernels separated by commas to set side by side
    /// (the list is set from the registry in `with_registries`).
    #[arg(long, default_value = "drs-bvh4,single-bvh4")]
    pub kernel: String,
    /// Scene for the traversal kernels (`rtsim list scenes`, a .ron or a mesh file).
    #[arg(long, default_value = "crown")]
    pub scene: String,
    /// Ray stream for the traversal kernels: primary, bounce (the first bounce of the path
    /// tracer) or shadow (shadow rays from the primary hits, any hit).
    #[arg(long, default_value = "bounce")]
    pub stream: String,
    /// Tile side in pixels (traversal kernels): the stream is one tile at the image centre.
    #[arg(long, default_value_t = 16)]
    pub tile: u32,
    /// Samples per pixel (traversal kernels).
    #[arg(long, default_value_t = 16)]
    pub spp: u32,
    /// Rays in the stream (boxtest only; a multiple of 4) [default: 4096].
    #[arg(long)]
    pub rays: Option<usize>,
    /// Seed of the generated node and rays.
    #[arg(long, default_value_t = 7)]
    pub seed: u64,
    /// Also write the recorded trace here (binary; `.txt` for the text form), for every kernel.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Output format: text, json or csv.
    #[arg(long, value_parser = Format::from_name, default_value = "text")]
    pub format: Format,
}

impl RunCli {
    /// The library's options.
    pub fn into_args(self) -> repro::boxrun::RunArgs {
        repro::boxrun::RunArgs {
            machine: self.machine.spec(),
            isa: self.isa,
            kernel: self.kernel,
            scene: self.scene,
            stream: self.stream,
            tile: self.tile,
            spp: self.spp,
            rays: self.rays.unwrap_or(4096),
            seed: self.seed,
            out: self.out,
            format: self.format,
        }
    }
}

/// `rtsim reproduce` arguments.
#[derive(Args)]
pub struct ReproduceCli {
    /// Report (set from the registry in `with_registries`).
    pub name: String,
    /// Smaller sample for a run of about a minute.
    #[arg(long)]
    pub quick: bool,
    /// A built-in machine (`rtsim list machines`) or a path to a RON config
    /// (default: the report's own machine).
    #[arg(long)]
    pub machine: Option<String>,
    /// Override a config field of the report's machine: `--set core.width=6`.
    #[arg(long = "set", value_name = "FIELD=VALUE")]
    pub sets: Vec<String>,
    /// Rounds of tiles per scene, or runs of frusta sets (overrides the sample size).
    #[arg(long)]
    pub tiles: Option<u32>,
    /// Image width and height in pixels (MFT reports; a multiple of 16 from
    /// 64 to 4096; default: the report's, the paper's 1024 for mft-table1).
    #[arg(long)]
    pub res: Option<u32>,
    /// Samples per pixel (DRS reports; overrides 16).
    #[arg(long)]
    pub spp: Option<u32>,
    /// Hardware threads per core (DRS tables: 1 or 2, default 2, the
    /// paper's 8 threads on 4 cores; see papers/drs/README.md).
    #[arg(long, value_name = "N")]
    pub threads_per_core: Option<u32>,
    /// Sample seed (default 7).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Output format: text, json or csv.
    #[arg(long, value_parser = Format::from_name, default_value = "text")]
    pub format: Format,
    /// Also write the report (and its figures) to DIR.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Only these of the report's scenes or datasets, comma-separated
    /// (`rtsim reproduce --help` names them).
    #[arg(long, value_name = "A,B", value_delimiter = ',')]
    pub scenes: Vec<String>,
    /// No progress bar on standard error (there is none when it is not a terminal).
    #[arg(long)]
    pub quiet: bool,
}

impl ReproduceCli {
    /// What was given, for the report to check.
    pub fn given(self) -> Given {
        Given {
            quick: self.quick,
            machine: self.machine,
            sets: self.sets,
            tiles: self.tiles,
            res: self.res,
            spp: self.spp,
            threads_per_core: self.threads_per_core,
            seed: self.seed,
            format: self.format,
            out: self.out,
            scenes: self.scenes,
            quiet: self.quiet,
        }
    }
}

/// `rtsim sim` arguments.
#[derive(Args)]
pub struct SimCli {
    /// Machine.
    #[command(flatten)]
    pub machine: MachineCli,
    /// A recorded or hand-written trace (binary or text).
    #[arg(long)]
    pub trace: PathBuf,
    /// Repeat the trace as a loop body this many times (loop-carried values
    /// are sources defined later in the body); cycles per iteration is then
    /// the steady state, (cycles(N) - cycles(N/2)) / (N - N/2), with whether
    /// runs of N/2, N/4, ... agree within 0.5% (the report says when not).
    #[arg(long, default_value_t = 1)]
    pub iterations: usize,
    /// Fidelity: counts, caches, full.
    #[arg(long, value_parser = parse_fidelity, default_value = "full")]
    pub fidelity: Fidelity,
    /// The pipeline timeline of a window of ops (out-of-order machines):
    /// START:LEN trace indices, or REGION:START:LEN from the START-th op of
    /// a code region (e.g. core-loop:0:40); of the repeated trace with --iterations.
    #[arg(long, value_name = "WINDOW")]
    pub timeline: Option<String>,
    /// Also draw the timeline to this PNG.
    #[arg(long, value_name = "FILE.png", requires = "timeline")]
    pub timeline_png: Option<PathBuf>,
    /// Output format: text, json or csv.
    #[arg(long, value_parser = Format::from_name, default_value = "text")]
    pub format: Format,
}

/// `rtsim calibrate` arguments.
#[derive(Args)]
pub struct CalibrateCli {
    /// Machine.
    #[command(flatten)]
    pub machine: MachineCli,
    /// Output format: text, json or csv.
    #[arg(long, value_parser = Format::from_name, default_value = "text")]
    pub format: Format,
}

/// `rtsim fidelity` arguments.
#[derive(Args)]
pub struct FidelityCli {
    /// Machine.
    #[command(flatten)]
    pub machine: MachineCli,
    /// A trace to time; default: the ray-vs-4-boxes workload recorded on the machine's ISA.
    #[arg(long)]
    pub trace: Option<PathBuf>,
    /// Rays of the default workload.
    #[arg(long, default_value_t = 16384)]
    pub rays: usize,
    /// Instead: a window of SCENE's frame rendered by Our BVH4 in full detail
    /// and with each sampling design (SMARTS warming, the reports' warming
    /// window, none): host time and error against full.
    #[arg(long, value_name = "SCENE")]
    pub frame: Option<String>,
    /// --frame: the window, in 16x16 tiles (default 8x8).
    #[arg(long, value_name = "COLSxROWS")]
    pub window: Option<String>,
    /// --frame: samples per pixel (default 4).
    #[arg(long)]
    pub spp: Option<u32>,
    /// --frame: time every N-th round of tiles (default 4).
    #[arg(long)]
    pub every: Option<u32>,
    /// --frame: rounds warmed before each timed round in window mode (default 1).
    #[arg(long)]
    pub warm: Option<u32>,
    /// --frame: path-tracing seed (default 7).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Output format: text, json or csv.
    #[arg(long, value_parser = Format::from_name, default_value = "text")]
    pub format: Format,
}

/// `rtsim render` arguments.
#[derive(Args)]
pub struct RenderCli {
    /// A built-in scene (`rtsim list scenes`), a scene .ron, or a mesh file.
    #[arg(long)]
    pub scene: String,
    /// PNG to write.
    #[arg(long)]
    pub out: PathBuf,
    /// Shading: normals, depth or hits (surfaces crossed).
    #[arg(long, value_parser = Shade::from_name, default_value = "normals")]
    pub shade: Shade,
    /// Image width (default: the scene camera's).
    #[arg(long)]
    pub width: Option<u32>,
    /// Image height (default: the scene camera's, scaled with --width).
    #[arg(long)]
    pub height: Option<u32>,
}

impl RenderCli {
    /// The library's options.
    pub fn into_args(self) -> RenderArgs {
        RenderArgs {
            scene: self.scene,
            out: self.out,
            shade: self.shade,
            width: self.width,
            height: self.height,
        }
    }
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
        /// ISA flavour: lrb16, avx512, avx2, sse4, wide32.
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
        #[arg(long, value_parser = Format::from_name, default_value = "text")]
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

/// Help texts built from the registries: the reports (name, what it
/// computes, its machine, the options it reads) and the kernels.
pub fn with_registries(cmd: clap::Command, reports: &[&ReportDef]) -> clap::Command {
    let list: Vec<String> = reports
        .iter()
        .map(|d| {
            let opts = d.flags();
            let scenes = if d.uses(Opt::Scenes) {
                format!("; scenes {}", d.scenes.join(","))
            } else {
                String::new()
            };
            format!(
                "  {}: {} [machine {}; {}{scenes}]",
                d.name,
                d.about,
                d.machine,
                opts.join(" ")
            )
        })
        .collect();
    let names: Vec<&str> = reports.iter().map(|d| d.name).collect();
    let report_help = format!("Report: {}\n{}", names.join(", "), list.join("\n"));
    let kernel_help = format!(
        "Kernel, or traversal kernels separated by commas to set side by side: {}",
        kernel_names().join(", ")
    );
    cmd.mut_subcommand("reproduce", |c| {
        c.about(format!(
            "Compute a paper's table or figure on the models ({})",
            names.join(", ")
        ))
        .mut_arg("name", |a| a.help(report_help))
    })
    .mut_subcommand("run", |c| c.mut_arg("kernel", |a| a.help(kernel_help)))
}

#[derive(Args)]
pub struct VolumeCli {
    /// A raw volume named `name_WxHxD_type.raw[.gz]` (type uint8, uint16,
    /// int16 or float32, le or be) or a RON sidecar (file, dims, voxel).
    #[arg(long)]
    pub volume: PathBuf,
    /// Transfer function (RON: `(points: [(value: 0.0, rgba: (r, g, b, a)), ...])`).
    #[arg(long)]
    pub transfer: PathBuf,
    /// Lighting: unlit, diffuse or phong.
    #[arg(long, default_value = "unlit")]
    pub lighting: String,
    /// Leaf size L of the implicit BVH (1, 2, 4 or 8).
    #[arg(long, default_value_t = 4)]
    pub leaf: u32,
    /// Image side in pixels (a multiple of 8).
    #[arg(long, default_value_t = 512)]
    pub res: u32,
    /// 8x8 packets timed per caster.
    #[arg(long, default_value_t = 16)]
    pub packets: u32,
    /// A built-in machine or a RON config, 4 lanes (the paper's X5550 by default).
    #[arg(long, default_value = "nehalem-x5550")]
    pub machine: String,
    /// Override a machine config field: `--set core.width=6`.
    #[arg(long = "set", value_name = "FIELD=VALUE")]
    pub sets: Vec<String>,
    /// Sample seed.
    #[arg(long, default_value_t = 7)]
    pub seed: u64,
    /// PNG of the bvh caster's frame.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Output format: text, json or csv.
    #[arg(long, value_parser = Format::from_name, default_value = "text")]
    pub format: Format,
}

impl VolumeCli {
    /// The library's options.
    pub fn args(&self) -> volume_report::VolumeArgs {
        volume_report::VolumeArgs {
            volume: self.volume.clone(),
            transfer: self.transfer.clone(),
            lighting: self.lighting.clone(),
            leaf: self.leaf,
            res: self.res,
            packets: self.packets,
            machine: repro::MachineSpec {
                machine: self.machine.clone(),
                sets: self.sets.clone(),
            },
            seed: self.seed,
            out: self.out.clone(),
        }
    }
}

/// `rtsim native` arguments.
#[derive(Args)]
pub struct NativeCli {
    /// Traversal kernels to time (repeat the flag; default: every kernel the ISA runs).
    #[arg(long = "kernel")]
    pub kernels: Vec<String>,
    /// Scene (`rtsim list scenes`, a .ron or a mesh file).
    #[arg(long, default_value = "conference")]
    pub scene: String,
    /// Ray stream: primary, bounce (the path tracer's first bounce) or shadow (any hit).
    #[arg(long, default_value = "primary")]
    pub stream: String,
    /// Tile side in pixels: the stream is one tile at the image centre.
    #[arg(long, default_value_t = 32)]
    pub tile: u32,
    /// Samples per pixel.
    #[arg(long, default_value_t = 16)]
    pub spp: u32,
    /// Ray seed.
    #[arg(long, default_value_t = 7)]
    pub seed: u64,
    /// Timed runs per method, after one untimed run whose answers are checked.
    #[arg(long, default_value_t = 11)]
    pub repeat: u32,
    /// The ISA whose semantics the native backend runs.
    #[arg(long, value_parser = parse_isa, default_value = "avx2")]
    pub isa: FlavourId,
    /// Extra Embree device configuration, e.g. `tri_accel=bvh4.triangle4`
    /// (Embree's BVH4 and Moller test instead of its default for the host);
    /// needs Embree 3 on the host (Debian: libembree3-3).
    #[arg(long, value_name = "KEY=VALUE,...")]
    pub embree_config: Option<String>,
    /// Output format: text, json or csv.
    #[arg(long, value_parser = Format::from_name, default_value = "text")]
    pub format: Format,
}

impl NativeCli {
    /// The library's options (kernel names checked).
    pub fn args(self) -> AppResult<drs_report::native::NativeArgs> {
        let kernels = self
            .kernels
            .iter()
            .map(|k| drs_report::run::kernel_named(k))
            .collect::<AppResult<Vec<_>>>()?;
        Ok(drs_report::native::NativeArgs {
            scene: self.scene,
            stream: self.stream,
            tile: self.tile,
            spp: self.spp,
            seed: self.seed,
            repeat: self.repeat,
            kernels,
            isa: self.isa,
            embree_config: self.embree_config,
            format: self.format,
        })
    }
}

/// `rtsim validate` arguments.
#[derive(Args)]
pub struct ValidateCli {
    /// Scenes (repeat the flag).
    #[arg(long = "scene", default_values_t = ["conference".to_string(), "ferrari".to_string(), "bentley".to_string()])]
    pub scenes: Vec<String>,
    /// Streams: primary, bounce, shadow (repeat the flag).
    #[arg(long = "stream", default_values_t = ["primary".to_string(), "bounce".to_string(), "shadow".to_string()])]
    pub streams: Vec<String>,
    /// Tile side in pixels: each stream is the centre tile's.
    #[arg(long, default_value_t = 16)]
    pub tile: u32,
    /// Samples per pixel.
    #[arg(long, default_value_t = 16)]
    pub spp: u32,
    /// Ray seed.
    #[arg(long, default_value_t = 7)]
    pub seed: u64,
    /// Timed native runs per kernel.
    #[arg(long, default_value_t = 11)]
    pub repeat: u32,
    /// The model to check (default: the built-in config of this host's CPU).
    #[arg(long)]
    pub machine: Option<String>,
    /// Override a config field of the model: `--set core.rob=256`.
    #[arg(long = "set", value_name = "FIELD=VALUE")]
    pub sets: Vec<String>,
    /// Output format: text, json or csv.
    #[arg(long, value_parser = Format::from_name, default_value = "text")]
    pub format: Format,
}

impl ValidateCli {
    /// The library's options.
    pub fn args(self) -> drs_report::validate::ValidateArgs {
        drs_report::validate::ValidateArgs {
            scenes: self.scenes,
            streams: self.streams,
            tile: self.tile,
            spp: self.spp,
            seed: self.seed,
            repeat: self.repeat,
            machine: self.machine,
            sets: self.sets,
            format: self.format,
        }
    }
}
