//! # repro
//!
//! What every report shares, from op stream to printed rows: the report
//! schema ([`report`]), report options checked against what a report uses
//! and the registry entry each paper declares ([`options`]), sampling and
//! confidence intervals ([`sampling`]), machine-level reports and the
//! statistics rows of a timed run ([`machine`]), trace files ([`traces`]),
//! the default `rtsim run` workload ([`boxrun`]), scene listing and
//! rendering ([`scenes`]), sweeps over config fields ([`sweep`]), plots and PNG images, and files written whole or
//! not at all ([`io`]). It never holds a paper's figures: those live in each
//! paper's report crate.

#![warn(missing_docs)]

pub mod boxrun;
pub mod host;
pub mod io;
pub mod machine;
pub mod options;
pub mod plot;
pub mod png;
pub mod progress;
pub mod replay;
pub mod report;
pub mod sampling;
pub mod scenes;
pub mod sweep;
pub mod text;
pub mod timeline;
pub mod traces;

/// The `name` fields of a const table of structs, as a const array (for a
/// [`ReportDef`]'s scenes): `const NAMES: [&str; T.len()] = names_of!(T);`.
#[macro_export]
macro_rules! names_of {
    ($table:expr) => {{
        let mut names = [""; $table.len()];
        let mut i = 0;
        while i < names.len() {
            names[i] = $table[i].name;
            i += 1;
        }
        names
    }};
}

pub use options::{Given, MachineSpec, Opt, Produced, ReportDef, ReproduceArgs};
pub use report::{Format, Report, Row};

/// A user-facing error: the app prints it as `rtsim: error: ...` and exits
/// with code 2.
#[derive(Debug)]
pub struct AppError(pub String);

impl<T: std::fmt::Display> From<T> for AppError {
    fn from(e: T) -> Self {
        AppError(e.to_string())
    }
}

/// Result of a command or report.
pub type AppResult<T> = Result<T, AppError>;
