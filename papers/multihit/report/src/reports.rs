//! `multihit-fig2` (millions of hits per second against N_query, naive
//! against node culling, per scene) and `multihit-summary` (node culling's
//! speed-up against N_query as a fraction of the scene's most hits).

use crate::crossover::{Crossover, Point};
use crate::measure::{measure, Cell, HitStats, Prepared};
use crate::paper::{CROSSOVER_FRACTION, SOCKETS, SPEEDUP_AT_ONE};
use crate::scenes::{chosen, Group};
use multihit_kernels::filters::Insertion;
use multihit_kernels::Method;
use rayon::prelude::*;
use repro::plot::{Panel, Series};
use repro::sampling::paired_ratio_systematic;
use repro::sampling::systematic_ratio_ci;
use repro::{AppResult, Produced, Report, ReproduceArgs, Row};
use std::collections::BTreeMap;
use std::time::Instant;

/// A scene's cells: per N_query, (naive, node culling).
struct SceneCells {
    pr: Prepared,
    cells: Vec<(u32, Cell, Cell)>,
}

/// Runs timed per cell: `--tiles`, else 32 (`--quick`) or 128.
fn groups(a: &ReproduceArgs) -> usize {
    a.tiles
        .map_or(if a.quick { 32 } else { 128 }, |t| t as usize)
}

/// The scenes a run measures: the deep group; the full run adds the
/// shallow one (`--quick` previews the deep group's verdicts); of those,
/// the ones `--scenes` names.
fn stands(a: &ReproduceArgs) -> Vec<crate::scenes::Stand> {
    chosen(!a.quick, |s| a.runs(s))
}

/// Every scene's cells, in parallel over (scene, method, N_query).
fn measure_all(a: &ReproduceArgs, m: &sim::MachineConfig) -> AppResult<Vec<SceneCells>> {
    let g = groups(a);
    let prepared: Vec<Prepared> = stands(a)
        .into_iter()
        .map(|s| Prepared::new(s, g, a.seed))
        .collect::<AppResult<_>>()?;
    let jobs: Vec<(usize, u32, Method)> = prepared
        .iter()
        .enumerate()
        .flat_map(|(i, p)| {
            p.queries()
                .into_iter()
                .flat_map(move |n| [Method::Naive, Method::NodeCulling].map(move |me| (i, n, me)))
        })
        .collect();
    let cells: Vec<Cell> = jobs
        .par_iter()
        .map(|&(i, n, me)| measure(m, &prepared[i], (me, n, Insertion::Rows), &a.progress))
        .collect::<AppResult<_>>()?;
    let mut it = cells.into_iter();
    Ok(prepared
        .into_iter()
        .map(|pr| {
            let cells = pr
                .queries()
                .into_iter()
                .map(|n| {
                    let naive = it.next().expect("a naive cell");
                    let cull = it.next().expect("a culling cell");
                    (n, naive, cull)
                })
                .collect();
            SceneCells { pr, cells }
        })
        .collect())
}

/// One core of the report's machine (`--machine`, `--set` applied), 8 lanes.
fn one_core(a: &ReproduceArgs) -> AppResult<sim::MachineConfig> {
    a.one_core(8, "the paper's kernels are 8-wide (AVX2)")
}

/// Node culling over naive at one N_query: paired over the same tiles.
fn speedup(naive: &Cell, cull: &Cell) -> (f64, Option<f64>) {
    paired_ratio_systematic(&naive.run_cycles, &cull.run_cycles)
}

/// Node culling's speed-up curve over N_query.
fn curve(sc: &SceneCells) -> Vec<Point> {
    sc.cells
        .iter()
        .map(|(n, nv, cu)| {
            let (speedup, ci) = speedup(nv, cu);
            Point {
                n: f64::from(*n),
                speedup,
                ci,
            }
        })
        .collect()
}

/// A crossover's rows: in N_query and as fractions of the most, mean and
/// 95th-percentile hits, each with its 95% interval's ends; the paper's
/// 70% beside the fraction of the most hits.
fn crossover_rows(metric: &str, scene: &str, x: &Crossover, h: &HitStats) -> Vec<Row> {
    let mut rows = Vec::new();
    for (per, bounds) in x.normalised(h) {
        for (bound, v) in bounds {
            let mut r = Row::new(metric, v)
                .key("scene", scene)
                .key("per", per)
                .key("bound", bound);
            if per == "max_hits" && bound == "estimate" {
                r.paper = Some(CROSSOVER_FRACTION);
            }
            rows.push(r);
        }
    }
    rows
}

fn header(
    name: &str,
    (m, a, start): (&sim::MachineConfig, &ReproduceArgs, Instant),
    (scenes, rows, notes): (&[SceneCells], Vec<Row>, Vec<String>),
) -> Report {
    let mut s = BTreeMap::new();
    let g = groups(a);
    s.insert("design".into(), serde_json::json!(format!(
        "1024x768, one pixel-centre visibility ray per pixel; 16x16-pixel tiles of 4x2-pixel 8-wide packets on one core; {g} tiles, one at a seeded place in each of as many equal strata of the frame, each timed in full detail after functional warming with the tile before it and itself; every timed ray's hit list checked against the f64 reference; hits per ray over every pixel; N_query 1, 2, 4 and every 10% of the most hits; scenes: {}",
        if a.quick { "the deep group (the full run adds the shallow one)" } else { "the deep and the shallow group" }
    )));
    s.insert("seed".into(), serde_json::json!(a.seed));
    let ops = scenes
        .iter()
        .flat_map(|sc| &sc.cells)
        .map(|c| c.1.ops + c.2.ops)
        .sum();
    let mut notes = notes;
    notes.extend(depth_notes(scenes));
    if let Err(why) = embree_peer::available() {
        notes.push(format!(
            "{why}: the rows Embree traces (its hit lists checked beside ours, its native speed-up) are left out."
        ));
    }
    Report {
        report: name.into(),
        machine: Some(m.name.clone()),
        isa: Some(m.flavour().name().into()),
        fidelity: "full".into(),
        sample: Some(s),
        input: Some(
            scenes
                .iter()
                .map(|sc| sc.pr.name.as_str())
                .collect::<Vec<_>>()
                .join(", "),
        ),
        ops_simulated: ops,
        host_seconds: start.elapsed().as_secs_f64(),
        rows,
        notes,
    }
}

fn mismatches(scenes: &[SceneCells]) -> f64 {
    scenes
        .iter()
        .flat_map(|sc| &sc.cells)
        .map(|c| (c.1.bad + c.2.bad) as f64)
        .sum()
}

/// Per scene: its group, hit statistics and crossover.
fn scene_rows(sc: &SceneCells) -> Vec<Row> {
    let (s, h) = (sc.pr.name.as_str(), &sc.pr.hits);
    let k = |r: Row| r.key("scene", s).key("group", sc.pr.stand.group.label());
    let mut rows = vec![
        k(Row::new("mean_hits_per_ray", h.mean)),
        k(Row::new("p95_hits_per_ray", f64::from(h.p95))),
        k(Row::new("max_hits_per_ray", f64::from(h.max))),
        k(Row::new("rays_for_hit_statistics", h.rays as f64)),
    ];
    let x = Crossover::of(&curve(sc));
    rows.extend(crossover_rows("crossover", s, &x, h));
    rows
}

/// A note for each deep-group scene under 4 hits per ray on average.
fn depth_notes(scenes: &[SceneCells]) -> Vec<String> {
    scenes
        .iter()
        .filter(|sc| sc.pr.stand.group == Group::Deep && sc.pr.hits.mean < 4.0)
        .map(|sc| {
            format!(
                "{} is in the deep group with {:.2} hits per ray on average (the group's rule: at least 4)",
                sc.pr.name, sc.pr.hits.mean
            )
        })
        .collect()
}

/// The scene and N_query at which node culling's two insertion forms are
/// compared (the layers scene's deep lists; N_query at most its most hits).
const INSERTION_SCENE: (&str, u32) = ("layers", 64);

/// Node culling's packet insertion as rows (the report's) and as per-lane
/// gathers and scatters, on [`INSERTION_SCENE`]: instructions per ray,
/// Mhit/s and the filter's share of the cycles of each.
fn insertion_rows(
    a: &ReproduceArgs,
    m: &sim::MachineConfig,
    scenes: &[SceneCells],
) -> AppResult<Vec<Row>> {
    let (name, want) = INSERTION_SCENE;
    let Some(sc) = scenes.iter().find(|sc| sc.pr.name == name) else {
        return Ok(Vec::new());
    };
    let n = want.min(sc.pr.max_hits());
    let Some((_, _, rows_cell)) = sc.cells.iter().find(|c| c.0 == n) else {
        return Ok(Vec::new());
    };
    let gathered = measure(
        m,
        &sc.pr,
        (Method::NodeCulling, n, Insertion::GatherScatter),
        &a.progress,
    )?;
    let mut out = Vec::new();
    for (form, c) in [("rows", rows_cell), ("gather/scatter", &gathered)] {
        let k = |r: Row| {
            r.key("scene", name)
                .key("method", "node culling")
                .key("n_query", n)
                .key("insertion", form)
        };
        out.push(k(Row::new("instructions_per_ray", c.instr_per_ray)));
        out.push(k(Row::new("mhits_per_second", c.mhits).unit("Mhit/s")));
        out.push(k(Row::new("filter_and_sort_cycle_share", c.filter_share)));
        out.push(k(Row::new("hit_mismatches", c.bad as f64)));
    }
    Ok(out)
}

/// `multihit-fig2`.
pub(crate) fn multihit_fig2(a: &ReproduceArgs) -> AppResult<Produced> {
    let start = Instant::now();
    let m = one_core(a)?;
    let scenes = measure_all(a, &m)?;
    let chip = f64::from(SOCKETS) * f64::from(a.machine.load()?.cores);
    let mut rows = Vec::new();
    for sc in &scenes {
        rows.extend(scene_rows(sc));
        for (n, naive, cull) in &sc.cells {
            for (me, c) in [("naive", naive), ("node culling", cull)] {
                let k = |r: Row| {
                    r.key("scene", &sc.pr.name)
                        .key("method", me)
                        .key("n_query", n)
                };
                let mut r = k(Row::new("mhits_per_second", c.mhits).unit("Mhit/s"));
                r.ci95 = c.ci;
                rows.push(r.key("cores", 1));
                rows.push(
                    k(Row::new("mhits_per_second", c.mhits * chip).unit("Mhit/s"))
                        .key("cores", chip),
                );
                rows.push(k(Row::new("hits_per_ray", c.hits_per_ray)));
                rows.push(k(Row::new("filter_calls_per_ray", c.candidates_per_ray)));
                rows.push(k(Row::new("node_tests_per_ray", c.nodes_per_ray)));
                rows.push(k(Row::new("filter_walk_steps_per_ray", c.steps_per_ray)));
                rows.push(k(Row::new("instructions_per_ray", c.instr_per_ray)));
                rows.push(k(Row::new("cpi", c.cpi)));
                rows.push(k(Row::new("filter_and_sort_cycle_share", c.filter_share)));
            }
            let (s, ci) = speedup(naive, cull);
            let mut r = Row::new("speedup_node_culling_over_naive", s)
                .key("scene", &sc.pr.name)
                .key("n_query", n);
            r.ci95 = ci;
            rows.push(r);
        }
    }
    rows.extend(embree_rows(&scenes));
    rows.extend(insertion_rows(a, &m, &scenes)?);
    plot_fig2(a, &scenes)?;
    let notes = vec![
        format!("The paper's machine is two 10-core E5-2650 v3 (40 threads); the {chip}-core rows are the simulated one-core rate times {chip}: tiles are independent, and the assumption leaves out shared-L3 and DRAM contention and the second hardware thread per core."),
        "The paper's Figure 2 shows its truck scene without printed values; its statements (up to 2x at N_query = 1, naive ahead from about 70% of the most hits) stand beside ours in multihit-summary.".into(),
        "Stand-in scenes: rtsim's scenes from viewpoints where a ray meets at least 4 surfaces on average (the deep group; papers/multihit/README.md); the paper's truck and seven others are not available.".into(),
    ];
    Ok(Produced {
        mismatches: mismatches(&scenes),
        report: header("multihit-fig2", (&m, a, start), (&scenes, rows, notes)),
    })
}

/// `multihit-summary`.
pub(crate) fn multihit_summary(a: &ReproduceArgs) -> AppResult<Produced> {
    let start = Instant::now();
    let m = one_core(a)?;
    let scenes = measure_all(a, &m)?;
    let mut rows = Vec::new();
    for sc in &scenes {
        rows.extend(scene_rows(sc));
        for (n, naive, cull) in &sc.cells {
            let (s, ci) = speedup(naive, cull);
            let k = |r: Row| r.key("scene", &sc.pr.name).key("n_query", n);
            let mut r = k(Row::new("speedup_node_culling_over_naive", s));
            r.ci95 = ci;
            rows.push(r);
            for (per, by) in sc.pr.hits.scales() {
                rows.push(k(Row::new(
                    &format!("fraction_of_{per}"),
                    f64::from(*n) / by,
                )));
            }
        }
    }
    rows.extend(group_rows(&scenes));
    rows.extend(embree_rows(&scenes));
    plot_summary(a, &scenes)?;
    let notes = vec![
        "Speed-ups are paired over the same tiles (ratio of summed cycles; 95% CI over the tiles). The paper's 'up to 2x at N_query = 1' is its mean over eight scenes; its crossover 'as N_query -> 70%' of the most hits.".into(),
        "crossover: the N_query at which node culling's speed-up first falls to 1, linear between the two N_query measured around it; low95 and high95 are the crossings of the speed-up's 95% band's lower and upper edges; NaN: naive never catches up. per: in N_query, or as a fraction of the scene's most, mean or 95th-percentile hits per ray (over every pixel).".into(),
        "Group means are over the deep group only (the shallow scenes, full runs only, are an extra).".into(),
    ];
    Ok(Produced {
        mismatches: mismatches(&scenes),
        report: header("multihit-summary", (&m, a, start), (&scenes, rows, notes)),
    })
}

/// The deep group's means: node culling's speed-up at N_query = 1 and at
/// all hits, the scenes it is faster in at 1, and the scenes where naive
/// catches up.
fn group_rows(scenes: &[SceneCells]) -> Vec<Row> {
    let deep: Vec<&SceneCells> = scenes
        .iter()
        .filter(|sc| sc.pr.stand.group == Group::Deep)
        .collect();
    let label = format!("mean of {} deep", deep.len());
    let mean = |f: &dyn Fn(&SceneCells) -> f64| {
        deep.iter().map(|sc| f(sc)).sum::<f64>() / deep.len().max(1) as f64
    };
    let first = |sc: &SceneCells| speedup(&sc.cells[0].1, &sc.cells[0].2).0;
    let last = |sc: &SceneCells| {
        let c = sc.cells.last().expect("N = all");
        speedup(&c.1, &c.2).0
    };
    let mut at_one = Row::new("mean_speedup_at_n_query_1", mean(&first)).key("scene", &label);
    at_one.paper = Some(SPEEDUP_AT_ONE);
    let mut at_all = Row::new("mean_speedup_at_all_hits", mean(&last)).key("scene", &label);
    at_all.paper = Some(1.0);
    let faster = deep.iter().filter(|sc| first(sc) > 1.0).count();
    let crossing = deep
        .iter()
        .filter(|sc| Crossover::of(&curve(sc)).at.is_some())
        .count();
    vec![
        at_one,
        at_all,
        Row::new(
            "deep_scenes_node_culling_faster_at_n_query_1",
            faster as f64,
        ),
        Row::new("deep_scenes_where_naive_catches_up", crossing as f64),
    ]
}

/// Embree natively on this host (`rtcIntersect8` over the timed tiles'
/// packets, each tile the best of 3 passes): per scene and N_query each
/// method's Mhit/s and node culling's speed-up, paired over the tiles
/// with its 95% CI as the simulated one is, and the crossover with its
/// interval and normalisations.
fn embree_rows(scenes: &[SceneCells]) -> Vec<Row> {
    let mut rows = Vec::new();
    for sc in scenes {
        let Some(embree) = &sc.pr.embree else {
            continue;
        };
        let tiles: Vec<_> = sc.pr.timed_rays().collect();
        let mut points = Vec::new();
        for (n, _, _) in &sc.cells {
            let time = |me: Method| embree.time_tiles(&tiles, (me, *n), 3);
            let (naive, cull) = (time(Method::Naive), time(Method::NodeCulling));
            let k = |r: Row| r.key("scene", &sc.pr.name).key("n_query", n);
            for (me, t) in [("naive", &naive), ("node culling", &cull)] {
                let (secs, hits) = t.iter().fold((0.0, 0.0), |a, p| (a.0 + p.0, a.1 + p.1));
                let mut r = k(Row::new(
                    "embree_native_mhits_per_second",
                    hits / secs / 1e6,
                ));
                r.ci95 = systematic_ratio_ci(&t.iter().map(|p| (p.1, p.0)).collect::<Vec<_>>())
                    .map(|h| h / 1e6);
                rows.push(r.key("method", me).unit("host-measured"));
            }
            let secs = |t: &[(f64, f64)]| t.iter().map(|p| p.0).collect::<Vec<_>>();
            let (speedup, ci) = paired_ratio_systematic(&secs(&naive), &secs(&cull));
            let mut r = k(Row::new(
                "embree_native_speedup_node_culling_over_naive",
                speedup,
            ));
            r.ci95 = ci;
            rows.push(r.unit("host-measured"));
            points.push(Point {
                n: f64::from(*n),
                speedup,
                ci,
            });
        }
        let x = Crossover::of(&points);
        let cross = crossover_rows("embree_native_crossover", &sc.pr.name, &x, &sc.pr.hits);
        rows.extend(cross.into_iter().map(|r| r.unit("host-measured")));
    }
    rows
}

fn plot_fig2(a: &ReproduceArgs, scenes: &[SceneCells]) -> AppResult<()> {
    let titles: Vec<String> = scenes.iter().map(|sc| sc.pr.name.clone()).collect();
    let panels: Vec<Panel> = scenes
        .iter()
        .zip(&titles)
        .map(|(sc, t)| {
            let line = |label: &str, pick: fn(&(u32, Cell, Cell)) -> f64| Series {
                label: label.into(),
                points: sc
                    .cells
                    .iter()
                    .map(|c| (f64::from(c.0).log2(), pick(c)))
                    .collect(),
            };
            Panel {
                title: t,
                x: "log2 N_query",
                y: "Mhit/s, one core",
                series: vec![
                    line("naive", |c| c.1.mhits),
                    line("node culling", |c| c.2.mhits),
                ],
            }
        })
        .collect();
    repro::plot::write(&a.png_path("multihit-fig2")?, &panels)
}

fn plot_summary(a: &ReproduceArgs, scenes: &[SceneCells]) -> AppResult<()> {
    let series = scenes
        .iter()
        .map(|sc| Series {
            label: sc.pr.name.clone(),
            points: sc
                .cells
                .iter()
                .map(|(n, nv, cu)| {
                    (
                        f64::from(*n) / f64::from(sc.pr.max_hits()),
                        speedup(nv, cu).0,
                    )
                })
                .collect(),
        })
        .collect();
    let panel = Panel {
        title: "node culling over naive",
        x: "N_query / most hits",
        y: "speed-up",
        series,
    };
    repro::plot::write(&a.png_path("multihit-summary")?, &[panel])
}
