//! `rtsim`: the command-line app. Thin glue over the `isa`, `sim` and
//! `kernels` crates.

mod machine_cmd;
mod mft_light;
mod mft_quality;
mod mft_report;
mod plot;
mod png;
mod report;
mod reproduce;
mod scene_cmd;
mod trace_cmd;

use clap::{Parser, Subcommand};
use isa::FlavourId;
use report::Format;
use std::process::ExitCode;

/// A user-facing error: printed as `rtsim: error: ...`, exit code 2.
#[derive(Debug)]
pub struct AppError(pub String);

impl<T: std::fmt::Display> From<T> for AppError {
    fn from(e: T) -> Self {
        AppError(e.to_string())
    }
}

/// Result of a command.
pub type AppResult<T> = Result<T, AppError>;

#[derive(Parser)]
#[command(
    name = "rtsim",
    version,
    about = "Cycle-level SIMD architecture simulator and the ray-tracing kernels that run on it"
)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Record the default workload (a 4096-ray stream vs one BVH4 node's 4
    /// boxes, the DRS inner test) on an ISA, check every ray against the
    /// scalar reference, and report what the op stream holds.
    Run(trace_cmd::RunArgs),
    /// Compute a paper's table on the models (drs-table2).
    Reproduce(reproduce::ReproduceArgs),
    /// Record, inspect and convert op traces.
    #[command(subcommand)]
    Trace(trace_cmd::TraceCmd),
    /// Time a recorded or hand-written trace on a machine.
    Sim(machine_cmd::SimArgs),
    /// Run the microkernels through a machine model next to what its config implies.
    Calibrate(machine_cmd::CalibrateArgs),
    /// Time one workload in every fidelity mode: host time and error against full.
    Fidelity(machine_cmd::FidelityArgs),
    /// Render primary hits of a scene with the reference intersector (PNG).
    Render(scene_cmd::RenderArgs),
    /// List what is built in.
    List {
        /// What to list.
        #[arg(value_enum)]
        what: ListWhat,
        /// Output format.
        #[arg(long, value_enum, default_value = "text")]
        format: Format,
    },
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum ListWhat {
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

/// Parse an ISA flavour name for clap.
pub fn parse_isa(s: &str) -> Result<FlavourId, String> {
    FlavourId::from_name(s).ok_or_else(|| {
        let names: Vec<&str> = FlavourId::ALL.iter().map(|f| f.name()).collect();
        format!("unknown ISA '{s}' (one of: {})", names.join(", "))
    })
}

fn list(what: ListWhat, format: Format) -> AppResult<()> {
    use report::{Report, Row};
    let rows: Vec<Row> = match what {
        ListWhat::Micro => kernels::micro::list()
            .into_iter()
            .map(|m| {
                Row::new("available", 1.0)
                    .key("name", &m.name)
                    .key("what", &m.what)
            })
            .collect(),
        ListWhat::Isa => FlavourId::ALL
            .iter()
            .map(|f| Row::new("lanes", f.lanes() as f64).key("name", f.name()))
            .collect(),
        ListWhat::Classes => isa::OpClass::ALL
            .iter()
            .map(|c| {
                Row::new("class_id", f64::from(*c as u8))
                    .key("name", c.name())
                    .key("memory", if c.is_mem() { "yes" } else { "no" })
                    .key("vector", if c.is_vector() { "yes" } else { "no" })
            })
            .collect(),
        ListWhat::Machines => machine_cmd::machine_rows(),
        ListWhat::Scenes => return scene_cmd::list_scenes(format),
    };
    let rep = Report {
        report: format!(
            "list-{}",
            match what {
                ListWhat::Micro => "micro",
                ListWhat::Isa => "isa",
                ListWhat::Classes => "classes",
                ListWhat::Machines => "machines",
                ListWhat::Scenes => "scenes",
            }
        ),
        machine: None,
        isa: None,
        fidelity: "none".into(),
        sample: None,
        input: None,
        ops_simulated: 0,
        host_seconds: 0.0,
        rows,
        notes: Vec::new(),
    };
    print!("{}", rep.render(format));
    Ok(())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let r = match cli.cmd {
        Cmd::Run(a) => trace_cmd::run(&a),
        Cmd::Reproduce(a) => reproduce::reproduce(&a),
        Cmd::Trace(t) => trace_cmd::trace(t),
        Cmd::Sim(a) => machine_cmd::sim_cmd(&a),
        Cmd::Calibrate(a) => machine_cmd::calibrate_cmd(&a),
        Cmd::Fidelity(a) => machine_cmd::fidelity_cmd(&a),
        Cmd::Render(a) => scene_cmd::render(&a),
        Cmd::List { what, format } => list(what, format),
    };
    match r {
        Ok(()) => ExitCode::SUCCESS,
        Err(AppError(msg)) => {
            eprintln!("rtsim: error: {msg}");
            ExitCode::from(2)
        }
    }
}
