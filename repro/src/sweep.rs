//! Sweeps: the machine-config fields `rtsim sweep` varies ([`Axis`]), the
//! grid of points they make, and a paper report's cells computed at every
//! point ([`report_sweep`]: `rtsim sweep --report drs-table2 --quick --vary
//! classes.vfma.lat=3,5 --vary core.width=2,4`). Each point is the report
//! run with its values added to `--set`; points run at once and come out in
//! grid order, so the numbers do not depend on the host's threads.

use crate::options::{Given, ReportDef};
use crate::plot::{Panel, Series};
use crate::report::{Report, Row};
use crate::{AppError, AppResult};
use isa::FlavourId;
use rayon::prelude::*;
use std::path::Path;
use std::time::Instant;

/// A varied field and its values.
#[derive(Clone, Debug, PartialEq)]
pub struct Axis {
    /// Config field path (as `--set` takes it).
    pub field: String,
    /// Its values, in order.
    pub values: Vec<String>,
}

impl Axis {
    /// `FIELD=V1,V2,...`.
    ///
    /// # Errors
    /// No `=`, an empty field, no value or an empty one, a value twice.
    pub fn parse(s: &str) -> AppResult<Axis> {
        let (field, vals) = s
            .split_once('=')
            .ok_or_else(|| AppError(format!("--vary '{s}': expected FIELD=V1,V2,...")))?;
        let values: Vec<String> = vals.split(',').map(|v| v.trim().to_string()).collect();
        if field.is_empty() || values.iter().any(String::is_empty) {
            return Err(AppError(format!(
                "--vary '{s}': expected FIELD=V1,V2,... with no empty field or value"
            )));
        }
        if let Some(v) = values
            .iter()
            .find(|v| values.iter().filter(|w| w == v).count() > 1)
        {
            return Err(AppError(format!("--vary {field}: value '{v}' given twice")));
        }
        Ok(Axis {
            field: field.to_string(),
            values,
        })
    }

    /// Where value `i` sits on a plot's x axis: the number itself, an ISA's
    /// lanes, or else its position.
    #[must_use]
    pub fn x(&self, i: usize) -> f64 {
        let v = &self.values[i];
        v.parse::<f64>()
            .ok()
            .or_else(|| FlavourId::from_name(v).map(|f| f.lanes() as f64))
            .unwrap_or(i as f64)
    }

    /// The x axis label of a plot over this axis.
    #[must_use]
    pub fn label(&self) -> String {
        if self.field == "isa" {
            "isa (lanes)".to_string()
        } else {
            self.field.clone()
        }
    }
}

/// One or two `--vary` options, parsed and checked.
///
/// # Errors
/// None or more than two, a field given twice, a malformed one.
pub fn axes(vary: &[String]) -> AppResult<Vec<Axis>> {
    if vary.is_empty() || vary.len() > 2 {
        return Err(AppError(
            "sweep: give one or two --vary FIELD=V1,V2,...".into(),
        ));
    }
    let axes: Vec<Axis> = vary
        .iter()
        .map(|s| Axis::parse(s))
        .collect::<AppResult<_>>()?;
    if axes.len() == 2 && axes[0].field == axes[1].field {
        return Err(AppError(format!("--vary {}: given twice", axes[0].field)));
    }
    Ok(axes)
}

/// Every grid point as a value index per axis, the last axis fastest.
#[must_use]
pub fn grid(axes: &[Axis]) -> Vec<Vec<usize>> {
    let mut grid: Vec<Vec<usize>> = vec![Vec::new()];
    for ax in axes {
        grid = grid
            .into_iter()
            .flat_map(|g| {
                (0..ax.values.len()).map(move |i| {
                    let mut g = g.clone();
                    g.push(i);
                    g
                })
            })
            .collect();
    }
    grid
}

/// A point's `--set` overrides, `FIELD=VALUE` per axis.
#[must_use]
pub fn sets(axes: &[Axis], at: &[usize]) -> Vec<String> {
    axes.iter()
        .zip(at)
        .map(|(ax, &i)| format!("{}={}", ax.field, ax.values[i]))
        .collect()
}

/// `row` keyed by a point's values.
#[must_use]
pub fn keyed(row: Row, axes: &[Axis], at: &[usize]) -> Row {
    axes.iter()
        .zip(at)
        .fold(row, |r, (ax, &i)| r.key(&ax.field, &ax.values[i]))
}

/// What a report sweep computes.
pub struct ReportSweep<'a> {
    /// The report.
    pub def: &'a ReportDef,
    /// Its options as given (`--quick`, `--machine`, `--set`, ...).
    pub given: Given,
    /// One or two `FIELD=V1,V2,...`.
    pub vary: Vec<String>,
    /// The metric whose cells are swept (default: the report's first with
    /// the paper's figure beside it, else its first).
    pub metric: Option<String>,
    /// Where the PNG goes.
    pub out: Option<std::path::PathBuf>,
    /// No progress bar over the points.
    pub quiet: bool,
}

/// One point's report.
struct PointReport {
    at: Vec<usize>,
    report: Report,
}

/// A report's cells of one metric at every point of a grid of one or two
/// config fields: the report computed with each point's values set.
///
/// # Errors
/// Bad `--vary`, options the report does not use (`--set` among them: a
/// report whose machine cannot be set cannot be swept), a value the config
/// rejects, an unknown metric, a point whose rays differ from the
/// reference, an unwritable `--out`.
pub fn report_sweep(s: &ReportSweep) -> AppResult<Report> {
    let start = Instant::now();
    let axes = axes(&s.vary)?;
    if !s.def.options.contains(&crate::Opt::Set) {
        return Err(AppError(format!(
            "sweep --report {}: the report takes no --set (its figures do not depend on the machine), so there is nothing to vary",
            s.def.name
        )));
    }
    // Every point's options and machine checked before any point runs.
    let points = grid(&axes);
    for at in &points {
        let mut g = s.given.clone();
        g.sets.extend(sets(&axes, at));
        s.def.resolve(g)?.machine.load()?;
    }
    let bar = crate::progress::Progress::for_terminal(&format!("sweep {}", s.def.name), s.quiet);
    bar.add_units(points.len() as u64);
    // The first failing point in grid order, whichever failed first.
    let points: AppResult<Vec<PointReport>> = points
        .into_par_iter()
        .map(|at| {
            let p = point(s, &axes, at);
            bar.done(1);
            p
        })
        .collect::<Vec<_>>()
        .into_iter()
        .collect::<AppResult<_>>();
    bar.finish();
    let points = points?;
    let metric = match &s.metric {
        Some(m) => m.clone(),
        None => {
            let rows = &points[0].report.rows;
            rows.iter()
                .find(|r| r.paper.is_some())
                .or_else(|| rows.first())
                .map(|r| r.metric.clone())
        }
        .ok_or_else(|| AppError(format!("sweep: {} has no rows", s.def.name)))?,
    };
    let rows = cells(&points, &axes, &metric);
    if rows.is_empty() {
        let mut names: Vec<&str> = points[0]
            .report
            .rows
            .iter()
            .map(|r| r.metric.as_str())
            .collect();
        names.sort_unstable();
        names.dedup();
        return Err(AppError(format!(
            "--metric: {} has no metric '{metric}' ({})",
            s.def.name,
            names.join(", ")
        )));
    }
    if let Some(dir) = &s.out {
        plot(dir, s.def.name, &axes, &metric, &rows)?;
    }
    let head = &points[0].report;
    Ok(Report {
        report: format!("sweep-{}", s.def.name),
        machine: head.machine.clone(),
        isa: head.isa.clone(),
        fidelity: head.fidelity.clone(),
        sample: head.sample.clone(),
        input: Some(format!(
            "{}'s {metric} cells; varied: {}",
            s.def.name,
            s.vary.join(" ")
        )),
        ops_simulated: points.iter().map(|p| p.report.ops_simulated).sum(),
        host_seconds: start.elapsed().as_secs_f64(),
        rows,
        notes: vec![format!(
            "each point is rtsim reproduce {} with its values added to --set (every other option as given); cells as the report computes them, the paper's figure beside where it has one",
            s.def.name
        )],
    })
}

/// The report at one grid point (no progress bar, nothing written).
fn point(s: &ReportSweep, axes: &[Axis], at: Vec<usize>) -> AppResult<PointReport> {
    let mut g = s.given.clone();
    g.sets.extend(sets(axes, &at));
    g.out = None;
    g.quiet = true;
    let p = s.def.compute(g)?;
    if p.mismatches > 0.0 {
        return Err(AppError(format!(
            "{} at {}: {} rays differ from the reference",
            s.def.name,
            sets(axes, &at).join(" "),
            p.mismatches
        )));
    }
    Ok(PointReport {
        at,
        report: p.report,
    })
}

/// Every point's rows of `metric`, keyed by the point's values: cell by
/// cell (in the report's order), each at every point in grid order.
fn cells(points: &[PointReport], axes: &[Axis], metric: &str) -> Vec<Row> {
    let of = |p: &PointReport| -> Vec<Row> {
        p.report
            .rows
            .iter()
            .filter(|r| r.metric == metric)
            .map(|r| keyed(r.clone(), axes, &p.at))
            .collect()
    };
    let each: Vec<Vec<Row>> = points.iter().map(of).collect();
    let n = each.iter().map(Vec::len).max().unwrap_or(0);
    (0..n)
        .flat_map(|c| each.iter().filter_map(move |rows| rows.get(c).cloned()))
        .collect()
}

/// A cell's name: its own keys (not the axes'), `k=v` joined.
fn cell_label(r: &Row, axes: &[Axis]) -> String {
    r.keys
        .iter()
        .filter(|(k, _)| !axes.iter().any(|a| &a.field == *k))
        .map(|(_, v)| v.as_str())
        .collect::<Vec<_>>()
        .join(" ")
}

/// `DIR/sweep.png`: the metric against the first axis, a line per cell
/// (and per value of the second axis).
fn plot(dir: &Path, name: &str, axes: &[Axis], metric: &str, rows: &[Row]) -> AppResult<()> {
    std::fs::create_dir_all(dir).map_err(|e| AppError(format!("{}: {e}", dir.display())))?;
    let mut series: Vec<Series> = Vec::new();
    for r in rows {
        let mut label = cell_label(r, axes);
        if let Some(ax) = axes.get(1) {
            label = format!("{label} {}={}", ax.field, r.keys[&ax.field]);
        }
        let i = axes[0]
            .values
            .iter()
            .position(|v| *v == r.keys[&axes[0].field])
            .expect("a point's own value");
        let xy = (axes[0].x(i), r.value);
        match series.iter_mut().find(|s| s.label == label) {
            Some(s) => s.points.push(xy),
            None => series.push(Series {
                label,
                points: vec![xy],
            }),
        }
    }
    let title = format!("{name}: {metric}");
    let x = axes[0].label();
    crate::plot::write(
        &dir.join("sweep.png"),
        &[Panel {
            title: &title,
            x: &x,
            y: metric,
            series,
        }],
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axes_parse_and_place_their_values() {
        let a = Axis::parse("core.width=2,4,6").unwrap();
        assert_eq!(a.values, ["2", "4", "6"]);
        assert_eq!(a.x(2), 6.0);
        let isa = Axis::parse("isa=sse4,avx2,avx512,wide32").unwrap();
        assert_eq!(
            (isa.x(0), isa.x(1), isa.x(2), isa.x(3)),
            (4.0, 8.0, 16.0, 32.0)
        );
        for bad in ["core.width", "=1,2", "core.width=1,,2", "core.width=2,2"] {
            assert!(Axis::parse(bad).is_err(), "{bad}");
        }
        assert!(axes(&[]).is_err());
        assert!(axes(&["a=1".into(), "a=2".into()]).is_err());
        assert!(axes(&["a=1".into(), "b=1".into(), "c=1".into()]).is_err());
    }

    #[test]
    fn the_grid_runs_the_last_axis_fastest() {
        let ax = axes(&["a=1,2".into(), "b=x,y,z".into()]).unwrap();
        let g = grid(&ax);
        assert_eq!(g.len(), 6);
        assert_eq!(g[1], [0, 1]);
        assert_eq!(g[3], [1, 0]);
        assert_eq!(sets(&ax, &g[5]), ["a=2", "b=z"]);
        let r = keyed(Row::new("m", 1.0).key("scene", "s"), &ax, &g[5]);
        assert_eq!(cell_label(&r, &ax), "s");
        assert_eq!(r.keys["b"], "z");
    }
}
