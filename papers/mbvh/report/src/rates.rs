//! `mbvh-fig2`, `mbvh-fig3` and `mbvh-table1-2`: simulated rays per second
//! of MBVH RS over the distribution tracer's frames, one core of the Core 2
//! (Figures 2 and 3) and whole Dunnington and Core i7 machines (Tables 1-2).

use crate::frame::Prepared;
use crate::paper::*;
use crate::timing::{design, frame_rate, Rate};
use mbvh_kernels::layout::RayForm;
use mbvh_kernels::stream::{Order, StreamConfig};
use mbvh_kernels::Kernel;
use repro::plot::{Panel, Series};
use repro::{AppError, AppResult, Produced, Report, ReproduceArgs, Row};
use std::collections::BTreeMap;
use std::time::Instant;

/// One core of the report's machine (`--machine`, `--set` applied).
fn one_core(a: &ReproduceArgs) -> AppResult<sim::MachineConfig> {
    let mut m = a.machine.load()?;
    if m.flavour().lanes() != 4 {
        return Err(AppError(format!(
            "--machine {}: the paper's frame rates are 4-wide (SSE); {} has {} lanes",
            m.name,
            m.flavour(),
            m.flavour().lanes()
        )));
    }
    m.cores = 1;
    Ok(m)
}

/// Runs timed per frame: (groups, tiles per run).
fn sample_size(a: &ReproduceArgs) -> (usize, usize) {
    let g = a.tiles.map_or(if a.quick { 8 } else { 32 }, |t| t as usize);
    (g, 1)
}

/// The report around `rows`: `ctx` is (machine, options, resolution, start),
/// `body` (input, ops simulated, rows, notes).
fn header(
    name: &str,
    (m, a, res, start): (&sim::MachineConfig, &ReproduceArgs, u32, Instant),
    (input, ops, rows, notes): (String, u64, Vec<Row>, Vec<String>),
) -> Report {
    let (g, per) = sample_size(a);
    let mut s = BTreeMap::new();
    s.insert("design".into(), serde_json::json!(design(g, per)));
    s.insert(
        "resolution".into(),
        serde_json::json!(format!("{res}x{res}")),
    );
    s.insert("seed".into(), serde_json::json!(a.seed));
    Report {
        report: name.into(),
        machine: Some(m.name.clone()),
        isa: Some(m.flavour().name().into()),
        fidelity: "full".into(),
        sample: Some(s),
        input: Some(input),
        ops_simulated: ops,
        host_seconds: start.elapsed().as_secs_f64(),
        rows,
        notes,
    }
}

fn rate_rows(scene: &str, bounces: u32, method: &str, r: &Rate) -> Vec<Row> {
    let row = |metric: &str, v: f64| {
        Row::new(metric, v)
            .key("scene", scene)
            .key("bounces", bounces)
            .key("method", method)
    };
    let mut mr = row("mrays_per_second", r.mrays).unit("Mray/s");
    mr.ci95 = r.ci;
    vec![
        mr,
        row("rays_per_frame", r.rays),
        row("cycles_per_frame", r.cycles).unit("cycles"),
    ]
}

/// `rtsim reproduce mbvh-fig3`: Conference, 1 to 7 glossy bounces, one
/// Core 2 core; and the ordered heuristic and replicated rays measured.
pub fn mbvh_fig3(a: &ReproduceArgs) -> AppResult<Produced> {
    let name = "mbvh-fig3";
    let start = Instant::now();
    let m = one_core(a)?;
    let res = a.res.unwrap_or(512);
    let (g, per) = sample_size(a);
    let pr = Prepared::new("conference", res)?;
    let max = if a.quick { 4 } else { 7 };
    let mut rows = Vec::new();
    let (mut ops, mut bad) = (0, 0);
    let mut points = Vec::new();
    let rs = Kernel::Stream(StreamConfig::default());
    for b in 1..=max {
        let r = frame_rate(&m, &pr, rs, (b, g, per), (a.seed, &a.progress))?;
        ops += r.ops;
        bad += r.bad;
        points.push((f64::from(b), r.mrays));
        rows.extend(rate_rows("conference", b, "MBVH RS", &r));
    }
    // The paper's two design measurements, at 3 bounces.
    let b = 3;
    let base = frame_rate(&m, &pr, rs, (b, g, per), (a.seed, &a.progress))?;
    let variants = [
        (
            "unordered",
            StreamConfig {
                order: Order::Unordered,
                ..StreamConfig::default()
            },
            ORDERED_SPEEDUP,
        ),
        (
            "compact rays",
            StreamConfig {
                form: RayForm::Compact,
                ..StreamConfig::default()
            },
            REPLICATED_SPEEDUP,
        ),
    ];
    let mut notes = Vec::new();
    for (label, cfg, paper) in variants {
        let r = frame_rate(
            &m,
            &pr,
            Kernel::Stream(cfg),
            (b, g, per),
            (a.seed, &a.progress),
        )?;
        ops += r.ops;
        bad += r.bad;
        rows.extend(rate_rows("conference", b, &format!("MBVH RS {label}"), &r));
        let mut sp = Row::new("speedup_of_paper_choice", base.mrays / r.mrays)
            .key("scene", "conference")
            .key("bounces", b)
            .key("method", format!("MBVH RS over {label}"));
        sp.paper = Some(paper);
        rows.push(sp);
        notes.push(format!(
            "{label}: {:.2} Mray/s against {:.2} (the paper's choice {:+.1}%; the paper: {:+.0}%)",
            r.mrays,
            base.mrays,
            100.0 * (base.mrays / r.mrays - 1.0),
            100.0 * (paper - 1.0)
        ));
    }
    rows.insert(0, Row::new("hit_mismatches", bad as f64));
    notes.push(format!(
        "conference stand-in ({} triangles) at {res}x{res}, {} paths per pixel, MBVH RS ordered with replicated rays, groups of 2^8, on one core of {} ({} GHz); the paper's plot gives no numbers (its text: over 1 M rays/s per core at 7 bounces, 1 M less than at 1 bounce)",
        pr.scene.mesh.len(),
        crate::frame::PATHS,
        m.name,
        m.clock_ghz
    ));
    let path = a.png_path(name)?;
    repro::plot::write(
        &path,
        &[Panel {
            title: "Fig. 3: Conference, one core",
            x: "glossy bounces",
            y: "Mrays/s",
            series: vec![Series {
                label: "MBVH RS".into(),
                points,
            }],
        }],
    )?;
    Ok(Produced {
        report: header(
            name,
            (&m, a, res, start),
            ("conference".into(), ops, rows, notes),
        ),
        mismatches: bad as f64,
    })
}
