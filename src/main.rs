//! `rtsim`: the command-line app. Clap and dispatch only: every command is a
//! call into `repro` or a paper's report crate, and the help texts that list
//! reports and kernels are built from their registries.

mod cli;
mod trace_cmd;

use clap::{CommandFactory, FromArgMatches};
use cli::{Cli, Cmd, ListWhat};
use isa::FlavourId;
use repro::report::{Format, Report, Row};
use repro::{AppError, AppResult, ReportDef};
use std::process::ExitCode;

/// Every paper's reports, in the order `rtsim reproduce --help` lists them.
fn reports() -> Vec<&'static ReportDef> {
    drs_report::REPORTS
        .iter()
        .chain(mft_report::REPORTS.iter())
        .chain(mbvh_report::REPORTS.iter())
        .chain(multihit_report::REPORTS.iter())
        .chain(volume_report::REPORTS.iter())
        .collect()
}

/// `rtsim fidelity --frame` options, checked: None without `--frame`; an
/// error for a frame option without it, or for `--frame` with `--trace`.
fn frame_fidelity(a: &cli::FidelityCli) -> AppResult<Option<drs_report::FrameFidelity>> {
    let frame_only = [
        ("--window", a.window.is_some()),
        ("--spp", a.spp.is_some()),
        ("--every", a.every.is_some()),
        ("--warm", a.warm.is_some()),
        ("--seed", a.seed.is_some()),
    ];
    let Some(scene) = a.frame.clone() else {
        if let Some((o, _)) = frame_only.iter().find(|o| o.1) {
            return Err(AppError(format!(
                "fidelity: {o} is only read with --frame SCENE"
            )));
        }
        return Ok(None);
    };
    if a.trace.is_some() {
        return Err(AppError(
            "fidelity: --frame and --trace exclude each other".into(),
        ));
    }
    let window = match a.window.as_deref() {
        None => (8, 8),
        Some(w) => w
            .split_once('x')
            .and_then(|(c, r)| Some((c.parse().ok()?, r.parse().ok()?)))
            .filter(|&(c, r): &(u32, u32)| c > 0 && r > 0 && c <= 256 && r <= 256)
            .ok_or_else(|| {
                AppError(format!(
                    "--window: '{w}' is not COLSxROWS of 1 to 256 tiles"
                ))
            })?,
    };
    Ok(Some(drs_report::FrameFidelity {
        scene,
        window,
        spp: a.spp.unwrap_or(4),
        every: a.every.unwrap_or(4),
        warm: a.warm.unwrap_or(1),
        seed: a.seed.unwrap_or(repro::options::DEFAULT_SEED),
    }))
}

fn list(what: ListWhat, names: &[String], format: Format) -> AppResult<()> {
    if !names.is_empty() && !matches!(what, ListWhat::Scenes) {
        return Err(AppError(format!(
            "list {}: takes no names (only `list scenes NAME...` does)",
            what.name()
        )));
    }
    let rows: Vec<Row> = match what {
        ListWhat::Micro => repro::machine::micro_rows(),
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
        ListWhat::Machines => repro::machine::machine_rows(),
        ListWhat::Scenes => return repro::scenes::list_scenes(names, format),
    };
    let rep = Report {
        report: format!("list-{}", what.name()),
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

fn reproduce(a: cli::ReproduceCli) -> AppResult<()> {
    let all = reports();
    let def = repro::options::find(&all, &a.name)?;
    let args = def.resolve(a.given())?;
    def.produce(&args)
}

fn run(a: cli::RunCli) -> AppResult<()> {
    let rays_given = a.rays.is_some();
    let args = a.into_args();
    if args.kernel == "boxtest" {
        return repro::boxrun::run_boxtest(&args);
    }
    if rays_given {
        return Err(AppError(
            "--rays: only the boxtest kernel takes it (a traversal kernel traces one tile's stream: --tile, --spp)".into(),
        ));
    }
    if args.kernel.contains(',') {
        let ks = args
            .kernel
            .split(',')
            .map(drs_report::run::kernel_named)
            .collect::<AppResult<Vec<_>>>()?;
        return drs_report::compare::run_compare(&args, &ks);
    }
    match drs_report::run::kernel(&args.kernel) {
        Some(k) => drs_report::run::run_traversal(&args, k),
        None => Err(AppError(format!(
            "--kernel: unknown kernel '{}' ({})",
            args.kernel,
            cli::kernel_names().join(", ")
        ))),
    }
}

fn dispatch(cmd: Cmd) -> AppResult<()> {
    let show = |r: Report, f: Format| -> AppResult<()> {
        print!("{}", r.render(f));
        Ok(())
    };
    match cmd {
        Cmd::Run(a) => run(a),
        Cmd::Reproduce(a) => reproduce(a),
        Cmd::Trace(t) => trace_cmd::trace(t),
        Cmd::Sim(a) => {
            let m = a.machine.load()?;
            let (r, timeline) = repro::machine::sim_report(
                &m,
                &a.trace,
                a.iterations,
                a.fidelity,
                a.timeline.as_deref(),
            )?;
            if let Some(png) = &a.timeline_png {
                repro::timeline::png(png, &timeline)?;
            }
            show(r, a.format)?;
            if a.format == Format::Text && !timeline.is_empty() {
                print!("\n{}", repro::timeline::view(&timeline));
            }
            Ok(())
        }
        Cmd::Calibrate(a) => {
            let m = a.machine.load()?;
            show(repro::machine::calibrate_report(&m)?, a.format)
        }
        Cmd::Fidelity(a) => {
            let m = a.machine.load()?;
            let r = match frame_fidelity(&a)? {
                Some(f) => drs_report::fidelity_frame(&m, &f)?,
                None => repro::machine::fidelity_report(&m, a.trace.as_deref(), a.rays)?,
            };
            show(r, a.format)
        }
        Cmd::Native(a) => {
            let f = a.format;
            show(drs_report::native::native_report(&a.args()?)?, f)
        }
        Cmd::Replay(a) => {
            let f = a.format;
            let all: [(&str, repro::replay::Traces); 5] = [
                ("drs", &drs_report::replay::traces),
                ("mft", &mft_report::replay::traces),
                ("mbvh", &mbvh_report::replay::traces),
                ("multihit", &multihit_report::replay::traces),
                ("volume", &volume_report::replay::traces),
            ];
            let chosen = repro::replay::choose(&all, &a.papers)?;
            show(repro::replay::replay_report(&a.args(), &chosen)?, f)
        }
        Cmd::Validate(a) => {
            let f = a.format;
            show(drs_report::validate::validate_report(&a.args())?, f)
        }
        Cmd::Sweep(a) => {
            let (f, out) = (a.format, a.out.clone());
            match a.args()? {
                drs_report::sweep::Sweep::Kernel(k) => {
                    show(drs_report::sweep::sweep_report(&k)?, f)
                }
                drs_report::sweep::Sweep::Report(name, given, metric, vary, quiet) => {
                    let all = reports();
                    let def = repro::options::find(&all, &name)?;
                    let s = repro::sweep::ReportSweep {
                        def,
                        given,
                        vary,
                        metric,
                        out,
                        quiet,
                    };
                    show(repro::sweep::report_sweep(&s)?, f)
                }
            }
        }
        Cmd::Render(a) => repro::scenes::render(&a.into_args()),
        Cmd::Volume(a) => {
            let (r, bad) = volume_report::volume(&a.args())?;
            show(r, a.format)?;
            if bad > 0 {
                return Err(AppError(format!(
                    "{bad} pixels differ from the f64 reference by more than the tolerance"
                )));
            }
            Ok(())
        }
        Cmd::List {
            what,
            names,
            format,
        } => list(what, &names, format),
    }
}

fn main() -> ExitCode {
    let missing = repro::host::missing_features();
    if !missing.is_empty() {
        eprintln!(
            "rtsim: error: this binary was built for instruction sets this CPU lacks ({}): it was built on another machine; rebuild it here (`cargo clean`, then build)",
            missing.join(", ")
        );
        return ExitCode::from(2);
    }
    let matches = cli::with_registries(Cli::command(), &reports()).get_matches();
    let cli = Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    match dispatch(cli.cmd) {
        Ok(()) => ExitCode::SUCCESS,
        Err(AppError(msg)) => {
            eprintln!("rtsim: error: {msg}");
            ExitCode::from(2)
        }
    }
}
