//! Report options: what a user gave, checked against what the report uses,
//! with the report's own defaults filled in; and the registry entry each
//! paper declares for each of its reports.

use crate::io::write_atomic;
use crate::report::{Format, Report};
use crate::{AppError, AppResult};
use sim::MachineConfig;
use std::path::PathBuf;

/// An option of `rtsim reproduce` that a report may use.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Opt {
    /// `--quick`: the smaller sample.
    Quick,
    /// `--machine`: another machine than the report's own.
    Machine,
    /// `--set field=value`: config overrides.
    Set,
    /// `--tiles N`: the sample size (rounds of tiles, or runs of frusta sets).
    Tiles,
    /// `--spp N`: samples per pixel.
    Spp,
    /// `--res N`: the image's width and height.
    Res,
    /// `--seed S`: the sample's seed.
    Seed,
    /// `--threads-per-core N`: hardware threads used on each core (SMT).
    ThreadsPerCore,
    /// `--out DIR`: write the report (and its figures) there too.
    Out,
    /// `--scenes a,b`: only these of the report's scenes (read by every
    /// report with more than one: [`ReportDef::uses`]).
    Scenes,
}

impl Opt {
    /// Every option.
    pub const ALL: [Opt; 10] = [
        Opt::Quick,
        Opt::Machine,
        Opt::Set,
        Opt::Tiles,
        Opt::Spp,
        Opt::Res,
        Opt::Seed,
        Opt::ThreadsPerCore,
        Opt::Out,
        Opt::Scenes,
    ];
    /// The command-line flag.
    #[must_use]
    pub fn flag(self) -> &'static str {
        match self {
            Opt::Quick => "--quick",
            Opt::Machine => "--machine",
            Opt::Set => "--set",
            Opt::Tiles => "--tiles",
            Opt::Spp => "--spp",
            Opt::Res => "--res",
            Opt::Seed => "--seed",
            Opt::ThreadsPerCore => "--threads-per-core",
            Opt::Out => "--out",
            Opt::Scenes => "--scenes",
        }
    }
}

/// A report of a paper: its name, what it computes, its own default machine,
/// the options it uses, and the function that computes it.
pub struct ReportDef {
    /// Name (`drs-table1`, ...).
    pub name: &'static str,
    /// One line saying what it computes.
    pub about: &'static str,
    /// The machine it runs on unless `--machine` says otherwise.
    pub machine: &'static str,
    /// The options it uses besides `--scenes`; any other given is an error.
    pub options: &'static [Opt],
    /// Its scenes (or datasets), in the order it runs them: what
    /// `--scenes` chooses from when there are several.
    pub scenes: &'static [&'static str],
    /// Compute it (figures written with `--out` go to the directory).
    pub run: fn(&ReproduceArgs) -> AppResult<Produced>,
}

/// What a report computed: the report, and how many rays (or hits) differed
/// from the reference (a report with any is printed, then an error).
#[derive(Debug)]
#[must_use]
pub struct Produced {
    /// The report.
    pub report: Report,
    /// Rays whose answer differed from the reference.
    pub mismatches: f64,
}

/// What the user gave on the command line (`None`, `false`, empty: not given).
#[derive(Clone, Debug, Default)]
pub struct Given {
    /// `--quick`.
    pub quick: bool,
    /// `--machine`.
    pub machine: Option<String>,
    /// `--set`.
    pub sets: Vec<String>,
    /// `--tiles`.
    pub tiles: Option<u32>,
    /// `--spp`.
    pub spp: Option<u32>,
    /// `--res`.
    pub res: Option<u32>,
    /// `--threads-per-core`.
    pub threads_per_core: Option<u32>,
    /// `--seed`.
    pub seed: Option<u64>,
    /// `--format`.
    pub format: Format,
    /// `--out`.
    pub out: Option<PathBuf>,
    /// `--scenes`.
    pub scenes: Vec<String>,
    /// `--quiet`: no progress bar.
    pub quiet: bool,
}

impl Given {
    /// Whether option `o` was given.
    #[must_use]
    pub fn has(&self, o: Opt) -> bool {
        match o {
            Opt::Quick => self.quick,
            Opt::Machine => self.machine.is_some(),
            Opt::Set => !self.sets.is_empty(),
            Opt::Tiles => self.tiles.is_some(),
            Opt::Spp => self.spp.is_some(),
            Opt::Res => self.res.is_some(),
            Opt::Seed => self.seed.is_some(),
            Opt::ThreadsPerCore => self.threads_per_core.is_some(),
            Opt::Out => self.out.is_some(),
            Opt::Scenes => !self.scenes.is_empty(),
        }
    }
}

/// A machine by name or RON path, with `--set` overrides.
#[derive(Clone, Debug)]
pub struct MachineSpec {
    /// Built-in name or path to a RON config.
    pub machine: String,
    /// `field=value` overrides.
    pub sets: Vec<String>,
}

impl MachineSpec {
    /// Load, apply the overrides, validate.
    pub fn load(&self) -> AppResult<MachineConfig> {
        let m = MachineConfig::load(&self.machine).map_err(|e| AppError(e.to_string()))?;
        m.with_sets(&self.sets).map_err(|e| AppError(e.to_string()))
    }
}

/// The options a report runs with: checked, the report's defaults filled in.
#[derive(Clone, Debug)]
pub struct ReproduceArgs {
    /// The report's name.
    pub name: String,
    /// The smaller sample.
    pub quick: bool,
    /// The machine (the report's own unless `--machine` was given).
    pub machine: MachineSpec,
    /// Sample size override (at least 1).
    pub tiles: Option<u32>,
    /// Samples per pixel override (at least 1).
    pub spp: Option<u32>,
    /// Image width and height override (a multiple of 16, 64 to 4096).
    pub res: Option<u32>,
    /// Hardware threads per core (checked against the machine by the report).
    pub threads_per_core: Option<u32>,
    /// Sample seed (default 7).
    pub seed: u64,
    /// Output format.
    pub format: Format,
    /// Also write the report to this directory.
    pub out: Option<PathBuf>,
    /// The scenes to run, in the report's order (all of its own unless
    /// `--scenes` chose some).
    pub scenes: Vec<&'static str>,
    /// The run's progress bar (hidden with `--quiet` or off a terminal).
    pub progress: crate::progress::Progress,
}

impl ReproduceArgs {
    /// One core of the report's machine (`--machine`, `--set` applied),
    /// which must have `lanes` lanes (`why`: the kernels' width, for the
    /// error).
    ///
    /// # Errors
    /// The machine's own, or a machine of another width.
    pub fn one_core(&self, lanes: usize, why: &str) -> AppResult<sim::MachineConfig> {
        let mut m = self.machine.load()?;
        if m.flavour().lanes() != lanes {
            return Err(AppError(format!(
                "--machine {}: {why}; {} has {} lanes",
                m.name,
                m.flavour(),
                m.flavour().lanes()
            )));
        }
        m.cores = 1;
        Ok(m)
    }

    /// Whether scene (or dataset) `name` is among those to run.
    #[must_use]
    pub fn runs(&self, name: &str) -> bool {
        self.scenes.contains(&name)
    }

    /// Where a figure's PNG goes: `--out DIR`, else the current directory.
    pub fn png_path(&self, name: &str) -> AppResult<PathBuf> {
        let dir = self.out.clone().unwrap_or_else(|| PathBuf::from("."));
        std::fs::create_dir_all(&dir).map_err(|e| AppError(format!("{}: {e}", dir.display())))?;
        Ok(dir.join(format!("{name}.png")))
    }
}

/// The seed of a sample unless `--seed` is given.
pub const DEFAULT_SEED: u64 = 7;

/// Most tiles (or batches) a report samples.
pub const MAX_TILES: u32 = 1024;

impl ReportDef {
    /// Check `g` against this report (an option it does not use, a value out
    /// of range: an error naming the option) and fill in its defaults.
    pub fn resolve(&self, g: Given) -> AppResult<ReproduceArgs> {
        if let Some(o) = Opt::ALL.into_iter().find(|&o| g.has(o) && !self.uses(o)) {
            let uses = self.flags();
            return Err(AppError(format!(
                "{}: {} does not use this option (it uses {})",
                o.flag(),
                self.name,
                uses.join(", ")
            )));
        }
        if let Some(t) = g.tiles {
            if t == 0 || t > MAX_TILES {
                return Err(AppError(format!("--tiles: {t} is not 1 to {MAX_TILES}")));
            }
        }
        if let Some(r) = g.res {
            if !(64..=4096).contains(&r) || !r.is_multiple_of(16) {
                return Err(AppError(format!(
                    "--res: {r} is not a multiple of 16 from 64 to 4096"
                )));
            }
        }
        if g.spp == Some(0) {
            return Err(AppError("--spp: 0 samples per pixel".into()));
        }
        let scenes = self.chosen_scenes(&g.scenes)?;
        Ok(ReproduceArgs {
            name: self.name.into(),
            quick: g.quick,
            machine: MachineSpec {
                machine: g.machine.unwrap_or_else(|| self.machine.into()),
                sets: g.sets,
            },
            tiles: g.tiles,
            spp: g.spp,
            res: g.res,
            threads_per_core: g.threads_per_core,
            seed: g.seed.unwrap_or(DEFAULT_SEED),
            format: g.format,
            out: g.out,
            scenes,
            progress: crate::progress::Progress::for_terminal(self.name, g.quiet),
        })
    }

    /// Whether it reads option `o`: its own, and `--scenes` when it has
    /// more than one scene.
    #[must_use]
    pub fn uses(&self, o: Opt) -> bool {
        self.options.contains(&o) || o == Opt::Scenes && self.scenes.len() > 1
    }

    /// The flags of the options it reads, in [`Opt::ALL`]'s order.
    #[must_use]
    pub fn flags(&self) -> Vec<&'static str> {
        Opt::ALL
            .into_iter()
            .filter(|&o| self.uses(o))
            .map(Opt::flag)
            .collect()
    }

    /// The scenes `--scenes` names (all of the report's when none), in the
    /// report's order; an unknown or repeated name is an error naming it.
    fn chosen_scenes(&self, given: &[String]) -> AppResult<Vec<&'static str>> {
        for (i, s) in given.iter().enumerate() {
            if !self.scenes.contains(&s.as_str()) {
                return Err(AppError(format!(
                    "--scenes: '{s}' is not a scene of {} ({})",
                    self.name,
                    self.scenes.join(", ")
                )));
            }
            if given[..i].contains(s) {
                return Err(AppError(format!("--scenes: '{s}' given twice")));
            }
        }
        Ok(self
            .scenes
            .iter()
            .copied()
            .filter(|s| given.is_empty() || given.iter().any(|g| g == s))
            .collect())
    }
}

impl ReportDef {
    /// Check `g` and compute the report (nothing printed): what a
    /// library-level test of a paper's report reads.
    pub fn compute(&self, g: Given) -> AppResult<Produced> {
        (self.run)(&self.resolve(g)?)
    }

    /// Compute the report on a pool of `threads` host threads: its JSON with
    /// what the host measures left out (host time, rows in unit
    /// `host-measured`), for tests that the figures do not depend on the
    /// thread count.
    ///
    /// # Errors
    /// As [`ReportDef::compute`].
    ///
    /// # Panics
    /// If the thread pool cannot be built.
    pub fn on_threads(&self, threads: usize, g: Given) -> AppResult<serde_json::Value> {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("a thread pool");
        let p = pool.install(|| self.compute(g))?;
        let mut j = serde_json::to_value(&p.report).expect("a report is JSON");
        if let Some(o) = j.as_object_mut() {
            o.remove("host_seconds");
            if let Some(rows) = o.get_mut("rows").and_then(|r| r.as_array_mut()) {
                rows.retain(|r| r["unit"] != "host-measured");
            }
        }
        Ok(j)
    }

    /// Compute the report with `a`, print it, and with `--out` write it to
    /// DIR/NAME.{txt,json,csv}; an error if any ray differed from the reference.
    pub fn produce(&self, a: &ReproduceArgs) -> AppResult<()> {
        let p = (self.run)(a);
        a.progress.finish();
        let p = p?;
        let text = p.report.render(a.format);
        if let Some(dir) = &a.out {
            std::fs::create_dir_all(dir)
                .map_err(|e| AppError(format!("{}: {e}", dir.display())))?;
            let ext = a.format.ext();
            write_atomic(&dir.join(format!("{}.{ext}", self.name)), text.as_bytes())?;
        }
        print!("{text}");
        if p.mismatches > 0.0 {
            return Err(AppError(format!(
                "{} rays differ from the reference",
                p.mismatches
            )));
        }
        Ok(())
    }
}

/// The report called `name`, or an error listing them all.
pub fn find<'a>(defs: &'a [&'a ReportDef], name: &str) -> AppResult<&'a ReportDef> {
    defs.iter()
        .copied()
        .find(|d| d.name == name)
        .ok_or_else(|| {
            let names: Vec<&str> = defs.iter().map(|d| d.name).collect();
            AppError(format!(
                "reproduce: unknown report '{name}' ({})",
                names.join(", ")
            ))
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn nothing(_: &ReproduceArgs) -> AppResult<Produced> {
        Err(AppError("not computed".into()))
    }

    const DEF: ReportDef = ReportDef {
        name: "t",
        about: "a test report",
        machine: "larrabee",
        options: &[Opt::Quick, Opt::Tiles, Opt::Set],
        scenes: &["a", "b", "c"],
        run: nothing,
    };

    #[test]
    fn scenes_are_the_reports_own_in_its_order() {
        let with = |s: &[&str]| {
            DEF.resolve(Given {
                scenes: s.iter().map(|s| (*s).to_string()).collect(),
                ..Given::default()
            })
        };
        assert_eq!(with(&[]).unwrap().scenes, ["a", "b", "c"]);
        let a = with(&["c", "a"]).unwrap();
        assert_eq!(a.scenes, ["a", "c"]);
        assert!(a.runs("c") && !a.runs("b"));
        let e = with(&["d"]).unwrap_err().0;
        assert_eq!(e, "--scenes: 'd' is not a scene of t (a, b, c)");
        let e = with(&["a", "a"]).unwrap_err().0;
        assert_eq!(e, "--scenes: 'a' given twice");
        let one = ReportDef {
            scenes: &["a"],
            ..DEF
        };
        let e = one
            .resolve(Given {
                scenes: vec!["a".into()],
                ..Given::default()
            })
            .unwrap_err()
            .0;
        assert!(e.starts_with("--scenes: t does not use"), "{e}");
    }

    #[test]
    fn an_unused_option_is_an_error_naming_it() {
        let g = Given {
            spp: Some(4),
            ..Given::default()
        };
        let e = DEF.resolve(g).unwrap_err().0;
        assert!(e.starts_with("--spp: t does not use"), "{e}");
    }

    #[test]
    fn zero_tiles_is_an_error_and_defaults_are_the_reports() {
        let g = Given {
            tiles: Some(0),
            ..Given::default()
        };
        assert!(DEF.resolve(g).unwrap_err().0.starts_with("--tiles: 0"));
        let a = DEF
            .resolve(Given {
                sets: vec!["core.ports=2".into()],
                ..Given::default()
            })
            .unwrap();
        assert_eq!(a.machine.machine, "larrabee");
        assert_eq!(a.seed, DEFAULT_SEED);
        assert!(a.machine.load().is_ok());
    }
}
