//! `mbvh-fig2`, `mbvh-fig3` and `mbvh-table1-2`: simulated rays per second
//! of MBVH RS over the distribution tracer's frames, one core of the Core 2
//! (Figures 2 and 3) and whole Dunnington and Core i7 machines (Tables 1-2).

use crate::frame::{ray_type, Prepared};
use crate::paper::*;
use crate::timing::{design, frame_rates, Rate};
use mbvh_kernels::layout::RayForm;
use mbvh_kernels::stream::{Order, StreamConfig};
use mbvh_kernels::Kernel;
use rayon::prelude::*;
use repro::plot::{Panel, Series};
use repro::sampling::paired_ratio_systematic;
use repro::{AppError, AppResult, Produced, Report, ReproduceArgs, Row};
use std::collections::BTreeMap;
use std::time::Instant;

/// One core of the report's machine (`--machine`, `--set` applied).
fn one_core(a: &ReproduceArgs) -> AppResult<sim::MachineConfig> {
    a.one_core(4, "the paper's frame rates are 4-wide (SSE)")
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

/// Where a frame's cycles go: per code region, the share of the cycles,
/// instructions per ray and CPI.
fn region_rows(r: &Rate, bounces: u32) -> Vec<Row> {
    let total: f64 = r.regions.iter().map(|x| x.1).sum();
    let rays_timed = r.regions.iter().map(|x| x.0).sum::<f64>() / r.instr_per_ray;
    let mut rows = Vec::new();
    for (reg, &(ops, cyc)) in isa::Region::ALL.iter().zip(&r.regions) {
        if cyc == 0.0 && ops == 0.0 {
            continue;
        }
        let row = |metric: &str, v: f64| {
            Row::new(metric, v)
                .key("scene", "conference")
                .key("bounces", bounces)
                .key("region", reg.name())
        };
        rows.push(row("cycle_share", cyc / total.max(1.0)));
        rows.push(row("instructions_per_ray", ops / rays_timed.max(1.0)));
        rows.push(row("cpi", cyc / ops.max(1.0)));
    }
    rows
}

/// Cycles per ray and the share of rays that hit nothing, per stream of a
/// frame (bounce 0: primary; shadow k: from the hits of bounce k).
fn kind_rows(scene: &str, r: &Rate) -> Vec<Row> {
    let mut rows = Vec::new();
    for (&(depth, shadow), &(cyc, rays, misses)) in &r.by_kind {
        let kind = ray_type((depth, shadow));
        let row = |metric: &str, v: f64| {
            Row::new(metric, v)
                .key("scene", scene)
                .key("stream_bounce", depth)
                .key("rays", kind)
        };
        rows.push(row("cycles_per_ray", cyc / rays.max(1.0)).unit("cycles"));
        let what = if shadow {
            "unoccluded_fraction"
        } else {
            "miss_fraction"
        };
        rows.push(row(what, misses / rays.max(1.0)));
    }
    rows
}

/// The rate of the deepest frame of [`frame_rates`] (a frame of its own).
fn last(mut v: Vec<Rate>) -> Rate {
    v.pop().expect("at least one bounce")
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
        row("instructions_per_ray", r.instr_per_ray),
        row("cpi", r.cpi),
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
    // The paper's two design measurements and its group sizes, at 3 bounces.
    let b3 = 3;
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
    let groups = [16usize, 64, 1024, 4096];
    // Every run is independent (its own session): all at once, in order.
    let jobs: Vec<(Kernel, u32)> = (1..=max)
        .map(|b| (rs, b))
        .chain(variants.iter().map(|v| (Kernel::Stream(v.1), b3)))
        .chain(groups.iter().map(|&group| {
            let cfg = StreamConfig {
                group,
                ..StreamConfig::default()
            };
            (Kernel::Stream(cfg), b3)
        }))
        .collect();
    let mut runs = jobs
        .par_iter()
        .map(|&(k, b)| frame_rates(&m, &pr, k, (b, g, per, 1), (a.seed, &a.progress)))
        .collect::<AppResult<Vec<_>>>()?
        .into_iter();
    let mut base = None;
    let mut own = Vec::new();
    let mut deepest = Vec::new();
    for b in 1..=max {
        let mut all = runs.next().expect("a run per depth");
        let r = all.pop().expect("at least one bounce");
        ops += r.ops;
        bad += r.bad;
        points.push((f64::from(b), r.mrays));
        rows.extend(rate_rows("conference", b, "MBVH RS", &r));
        own.push(r.mrays);
        if b == max {
            deepest = all;
        }
        if b == 3 {
            base = Some(r);
        }
    }
    // Figure 2 and the tables take shallower frames from the deepest one:
    // here each depth also has its own frame, so the shortcut is measured.
    let mut worst = 0f64;
    for (b, r) in (1..).zip(&deepest) {
        let mut row = Row::new("mrays_per_second_from_deepest_frame", r.mrays)
            .key("scene", "conference")
            .key("bounces", b)
            .key("method", "MBVH RS")
            .unit("Mray/s");
        row.ci95 = r.ci;
        rows.push(row);
        worst = worst.max((r.mrays / own[b as usize - 1] - 1.0).abs());
    }
    let b = b3;
    // The paper's configuration at 3 bounces is the loop's frame (same sample).
    let base = base.expect("the loop reaches 3 bounces");
    rows.extend(region_rows(&base, b));
    let mut notes = vec![format!(
        "frames to fewer bounces read off the {max}-bounce frame (as mbvh-fig2 and the tables do) differ from their own frames by at most {:.1}%",
        100.0 * worst
    )];
    for (label, _, paper) in variants {
        let r = last(runs.next().expect("a run per variant"));
        ops += r.ops;
        bad += r.bad;
        rows.extend(rate_rows("conference", b, &format!("MBVH RS {label}"), &r));
        // Same tiles and rays: the speed-up is the cycles' paired ratio.
        let (ratio, ci) = paired_ratio_systematic(&r.run_cycles, &base.run_cycles);
        let mut sp = Row::new("speedup_of_paper_choice", ratio)
            .key("scene", "conference")
            .key("bounces", b)
            .key("method", format!("MBVH RS over {label}"));
        sp.paper = Some(paper);
        sp.ci95 = ci;
        rows.push(sp);
        notes.push(format!(
            "{label}: {:.2} Mray/s against {:.2} (the paper's choice {:+.1}%{}; the paper: {:+.0}%)",
            r.mrays,
            base.mrays,
            100.0 * (ratio - 1.0),
            ci.map_or(String::new(), |h| format!(" +- {:.1}%, paired over the runs", 100.0 * h)),
            100.0 * (paper - 1.0)
        ));
    }
    // The paper's group-size choice (2^8 best overall), at 3 bounces: the
    // tile's 4096 primary rays bound the group.
    let mut best = (base.mrays, 256usize);
    for group in groups {
        let r = last(runs.next().expect("a run per group size"));
        ops += r.ops;
        bad += r.bad;
        rows.extend(rate_rows(
            "conference",
            b,
            &format!("MBVH RS group {group}"),
            &r,
        ));
        if r.mrays > best.0 {
            best = (r.mrays, group);
        }
    }
    let mut bg = Row::new("best_group_size", best.1 as f64)
        .key("scene", "conference")
        .key("bounces", b);
    bg.paper = Some(BEST_GROUP as f64);
    rows.push(bg);
    notes.push(format!(
        "group sizes 2^4, 2^6, 2^8, 2^10, 2^12 at {b} bounces: the fastest is {} ({:.2} Mray/s; the paper: 2^8)",
        best.1, best.0
    ));
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

/// The scenes of Figure 2 and Tables 1-2, in the paper's order.
pub(crate) const SCENES: [&str; 3] = ["bmw", "conference", "ferrari"];

/// Deepest frame of Figure 2 and Tables 1-2.
const TABLE_BOUNCES: u32 = 4;

/// `rtsim reproduce mbvh-fig2`: Mrays/s per scene against bounces, one
/// Core 2 core.
pub fn mbvh_fig2(a: &ReproduceArgs) -> AppResult<Produced> {
    let name = "mbvh-fig2";
    let start = Instant::now();
    let m = one_core(a)?;
    let res = a.res.unwrap_or(512);
    let (g, per) = sample_size(a);
    let rs = Kernel::Stream(StreamConfig::default());
    let (mut rows, mut notes, mut series) = (Vec::new(), Vec::new(), Vec::new());
    let (mut ops, mut bad) = (0, 0);
    // The scenes are independent runs: all at once, results in order.
    let per_scene = a
        .scenes
        .par_iter()
        .map(|&scene| {
            let pr = Prepared::new(scene, res)?;
            let rates = frame_rates(
                &m,
                &pr,
                rs,
                (TABLE_BOUNCES, g, per, 1),
                (a.seed, &a.progress),
            )?;
            Ok((pr.scene.mesh.len(), rates))
        })
        .collect::<AppResult<Vec<_>>>()?;
    for (&scene, (triangles, rates)) in a.scenes.iter().zip(per_scene) {
        ops += rates[0].ops;
        bad += rates[0].bad;
        for (b, r) in (1..).zip(&rates) {
            rows.extend(rate_rows(scene, b, "MBVH RS", r));
        }
        rows.extend(kind_rows(scene, &rates[rates.len() - 1]));
        let first = rates[0].mrays;
        let lastr = rates[rates.len() - 1].mrays;
        notes.push(format!(
            "{scene} ({triangles} triangles): {first:.2} Mray/s at 1 bounce, {lastr:.2} at {TABLE_BOUNCES} ({:+.0}%)",
            100.0 * (lastr / first - 1.0)
        ));
        series.push(Series {
            label: scene.into(),
            points: (1..)
                .zip(&rates)
                .map(|(b, r)| (f64::from(b), r.mrays))
                .collect(),
        });
    }
    rows.insert(0, Row::new("hit_mismatches", bad as f64));
    notes.push(format!(
        "the paper's plot gives no numbers; its text: BMW and Ferrari stay level or rise slightly with bounces (bounced rays reach simpler parts of the scene), Conference drops slightly (similar complexity everywhere, coherence lost). Frames to 1-{TABLE_BOUNCES} bounces from one sampled frame to {TABLE_BOUNCES} (see the sample design); one core of {}",
        m.name
    ));
    repro::plot::write(
        &a.png_path(name)?,
        &[Panel {
            title: "Fig. 2: one core",
            x: "glossy bounces",
            y: "Mrays/s",
            series,
        }],
    )?;
    Ok(Produced {
        report: header(
            name,
            (&m, a, res, start),
            (a.scenes.join(", "), ops, rows, notes),
        ),
        mismatches: bad as f64,
    })
}

/// `rtsim reproduce mbvh-table1-2`: frames per second at 512x512, 16 paths
/// per pixel, 1-4 bounces, on the Dunnington (Table 1) and Core i7 (Table
/// 2) models: one core simulated, times the cores.
pub fn mbvh_table1_2(a: &ReproduceArgs) -> AppResult<Produced> {
    let name = "mbvh-table1-2";
    let start = Instant::now();
    let res = 512;
    let (g, per) = sample_size(a);
    let rs = Kernel::Stream(StreamConfig::default());
    let machines = [
        ("table1", "dunnington-x7460", &TABLE1_FPS),
        ("table2", "nehalem-w5580", &TABLE2_FPS),
    ];
    let (mut rows, mut notes) = (Vec::new(), Vec::new());
    let (mut ops, mut bad) = (0, 0);
    let mut core_m = None;
    for &scene in &a.scenes {
        let pr = Prepared::new(scene, res)?;
        // The two machines are independent runs: at once, results in order.
        let per_machine = machines
            .par_iter()
            .map(|&(_, mname, _)| {
                let mut m = sim::MachineConfig::load(mname).map_err(|e| AppError(e.to_string()))?;
                let cores = m.cores;
                m.cores = 1;
                // Every hardware thread of a core busy, as the paper ran
                // the Core i7 ("with hyperthreading"): runs of one tile per
                // thread.
                let threads = m.core.threads as usize;
                let design = (TABLE_BOUNCES, g, per * threads, threads);
                let rates = frame_rates(&m, &pr, rs, design, (a.seed, &a.progress))?;
                Ok((m, cores, rates))
            })
            .collect::<AppResult<Vec<_>>>()?;
        for ((table, mname, paper), (m, cores, rates)) in machines.into_iter().zip(per_machine) {
            ops += rates[0].ops;
            bad += rates[0].bad;
            let pfps = paper.iter().find(|p| p.0 == scene).map(|p| p.1);
            for (b, r) in (1..).zip(&rates) {
                let row = |metric: &str, v: f64| {
                    Row::new(metric, v)
                        .key("table", table)
                        .key("machine", mname)
                        .key("scene", scene)
                        .key("bounces", b)
                };
                let paper_fps = pfps.map(|p| p[b as usize - 1]);
                let paper_rays = RAYS_PER_FRAME_M[b as usize - 1] * 1e6;
                // Rays per second per core first: the paper's from its frame
                // rate, its ray count and its cores.
                let mut c = row("mrays_per_second_per_core", r.mrays).unit("Mray/s");
                c.ci95 = r.ci;
                c.paper = paper_fps.map(|f| f * paper_rays / f64::from(cores) / 1e6);
                rows.push(c);
                if table == "table2" && scene == "conference" && b == 4 {
                    // Section 5.4's own figure for this cell.
                    let mut t = row("mrays_per_second_per_core", r.mrays)
                        .key("paper_source", "section 5.4 text")
                        .unit("Mray/s");
                    t.paper = Some(I7_RAYS_PER_CORE_4_BOUNCES / 1e6);
                    rows.push(t);
                }
                // Frames at the paper's ray count, then at ours.
                let per_frame = |rays: f64| 1e6 * f64::from(cores) / rays;
                let mut fp = row(
                    "frames_per_second_at_papers_rays",
                    r.mrays * per_frame(paper_rays),
                );
                fp.paper = paper_fps;
                fp.ci95 = r.ci.map(|c| c * per_frame(paper_rays));
                rows.push(fp);
                let mut f = row("frames_per_second", r.mrays * per_frame(r.rays));
                f.paper = paper_fps;
                f.ci95 = r.ci.map(|c| c * per_frame(r.rays));
                rows.push(f);
                let mut n = row("rays_per_frame", r.rays);
                n.paper = Some(paper_rays);
                rows.push(n);
            }
            core_m = Some(m);
        }
    }
    rows.insert(0, Row::new("hit_mismatches", bad as f64));
    notes.push("mrays_per_second_per_core beside the paper's: its frame rate times its rays per frame over its cores (24, 8); frames_per_second_at_papers_rays: our rate per core times the cores over the paper's rays per frame ((2n+1) x 4.19 M), the like-for-like frame rate; frames_per_second: over our own rays per frame".into());
    notes.push("whole-machine rates are one simulated core's times the cores (the paper: close to linear speed-up with core count): shared-cache and memory contention between cores is not simulated; the Core i7's cores run two hardware threads (its hyper-threading, as the paper ran it): each timed run is two consecutive tiles, their same streams timed together on the core's two threads; the Dunnington's Penryn cores have one".into());
    notes.push(format!(
        "frames to 1-{TABLE_BOUNCES} bounces from one sampled frame to {TABLE_BOUNCES} per scene and machine; rays per frame estimated from the sample (the paper's row is the same for every scene: (2n+1) x 4.19 M, every path assumed to stay in the scene)"
    ));
    let m = core_m.expect("two machines");
    let mut report = header(
        name,
        (&m, a, res, start),
        (a.scenes.join(", "), ops, rows, notes),
    );
    report.machine = Some(machines.map(|x| x.1).join(", "));
    Ok(Produced {
        report,
        mismatches: bad as f64,
    })
}
