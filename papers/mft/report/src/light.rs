//! `rtsim reproduce mft-fig6`: the impact of the light's size on multi-frusta
//! soft shadows (Benthin and Wald's Figure 6: triangles accessed and
//! intersection tests grow linearly with the light's size), with the 16-ray
//! packet baseline beside it, so the light size where frusta stop paying is
//! measured rather than assumed.

use crate::frame::{
    light_about, lrb_machine, sampled_cycles, zero_interval_share, Frame, Prepared,
};
use crate::shading::{pixel_hits, shadow_sets, Hits};
use mft_kernels::{mismatches_of, Frusta, MftStats, Shrink};
use rayon::prelude::*;
use repro::progress::Progress;
use repro::AppResult;
use repro::Produced;
use repro::ReproduceArgs;
use repro::Row;
use scene::agreement::F32Test;
use scene::Hit;
use std::time::Instant;

/// Light sizes, as multiples of each scene's own light's edges.
const SCALES: [f64; 5] = [0.125, 0.25, 0.5, 1.0, 2.0];

/// Light offsets: the light moved sideways along its first edge by these
/// multiples of the scene's half extent. Its placement, which the paper
/// does not give, drives the share of shadow frusta whose direction
/// interval holds zero: a hit point under the light's footprint has one.
/// (Moving it along the line through the scene's centre changes no share:
/// the footprint stays where it is; measured.)
const OFFSETS: [f64; 4] = [0.0, 0.5, 1.0, 2.0];

/// `rtsim reproduce mft-fig6`.
pub fn mft_fig6(a: &ReproduceArgs) -> AppResult<Produced> {
    let name = "mft-fig6";
    let start = Instant::now();
    let m = lrb_machine(a, name)?;
    let fl = m.flavour();
    let res: u32 = a.res.unwrap_or(if a.quick { 128 } else { 512 });
    // Runs of one round of the core's 4 threads (see frame::sample).
    let batches = a.tiles.map_or(8, |t| t as usize);
    let per = 4;
    // Every ray checked at --quick; every 8th set of the full run.
    let check_every = if a.quick { 1 } else { 8 };
    let mut rows = Vec::new();
    let mut notes = Vec::new();
    let (mut ops_total, mut bad_total) = (0u64, 0usize);
    let mut s_tris = Vec::new();
    let mut s_isec = Vec::new();
    let mut s_ratio = Vec::new();
    for &scene_name in &a.scenes {
        let pr = Prepared::new(scene_name, res, name, false)?;
        let (pout, _) = isa::run_native(&pr.frusta(pr.primary.clone(), false, Shrink::None), fl);
        let hits = pixel_hits(&pr.primary, &pout, res as usize);
        let [c, e1, e2] = pr.light;
        let centre = [0, 1, 2].map(|i| f64::from(c[i]) + 0.5 * f64::from(e1[i] + e2[i]));
        let (mut tris, mut isec, mut ratio) = (Vec::new(), Vec::new(), Vec::new());
        // The light sizes are independent runs: all at once, in order.
        let points = SCALES
            .par_iter()
            .map(|&s| {
                light_point(
                    &m,
                    (&pr, scene_name, res),
                    &hits,
                    (centre, e1, e2, s),
                    (batches, per, check_every, (a.seed, &a.progress)),
                )
            })
            .collect::<AppResult<Vec<_>>>()?;
        for (s, p) in SCALES.into_iter().zip(points) {
            let (fst, pst, cf, cp) = (p.frusta, p.packets, p.frusta_cycles, p.packet_cycles);
            bad_total += p.bad;
            ops_total += p.ops;
            let row = |method: &str, metric: &str, v: f64| {
                Row::new(metric, v)
                    .key("scene", scene_name)
                    .key("method", method)
                    .key("light_scale", s)
            };
            for (method, st, cyc) in [("s-frusta", fst, cf), ("s-packet", pst, cp)] {
                rows.push(row(method, "tris_accessed", st.tris_accessed as f64));
                rows.push(row(method, "isec_tests", st.isec_tests as f64));
                rows.push(row(method, "aabb_tests", st.aabb_tests as f64));
                rows.push(row(method, "cycles", cyc).unit("cycles"));
            }
            let r = |x: u64, y: u64| x as f64 / y.max(1) as f64;
            rows.push(row("", "aabb_reduction", r(pst.aabb_tests, fst.aabb_tests)));
            rows.push(row("", "cycle_reduction", cp / cf.max(1.0)));
            tris.push((s, fst.tris_accessed as f64));
            isec.push((s, fst.isec_tests as f64));
            ratio.push((s, cp / cf.max(1.0)));
        }
        // Linearity of the paper's two curves: the least-squares line's R^2.
        for (metric, pts) in [("tris_accessed", &tris), ("isec_tests", &isec)] {
            rows.push(
                Row::new(&format!("{metric}_linear_r2"), r2(pts))
                    .key("scene", scene_name)
                    .key("method", "s-frusta"),
            );
        }
        let (point, placed) = placement_sweep(
            &m,
            (&pr, scene_name, res),
            &hits,
            (centre, e1, e2),
            (batches, per, check_every, (a.seed, &a.progress)),
        )?;
        rows.extend(placed);
        bad_total += point.bad;
        ops_total += point.ops;
        notes.push(point.note);
        let cross = ratio.iter().rev().find(|p| p.1 >= 1.0).map(|p| p.0);
        notes.push(format!(
            "{scene_name}: frusta take fewer simulated shadow cycles than packets up to light scale {} (cycle reduction {} at scales {})",
            cross.map_or("none of those tried".into(), |x| format!("{x}")),
            ratio.iter().map(|p| format!("{:.2}", p.1)).collect::<Vec<_>>().join(" / "),
            SCALES.map(|x| x.to_string()).join(" / ")
        ));
        // Plotted relative to the scene's own light (scale 1), so the four
        // scenes' very different totals share one axis.
        let rel = |pts: &[(f64, f64)]| {
            let one = pts
                .iter()
                .find(|p| p.0 == 1.0)
                .map_or(1.0, |p| p.1.max(1.0));
            pts.iter().map(|p| (p.0, p.1 / one)).collect::<Vec<_>>()
        };
        s_tris.push(repro::plot::Series {
            label: scene_name.into(),
            points: rel(&tris),
        });
        s_isec.push(repro::plot::Series {
            label: scene_name.into(),
            points: rel(&isec),
        });
        s_ratio.push(repro::plot::Series {
            label: scene_name.into(),
            points: ratio,
        });
    }
    let png = a.png_path(name)?;
    write_plot(&png, s_tris, s_isec, s_ratio)?;
    notes.push(format!("plot: {}", png.display()));
    notes.push(format!(
        "shadow rays only, {res}x{res}, 16 samples per pixel, each scene's quad light scaled about its centre, and (light_offset rows) its own light moved sideways along its first edge by {} times half the scene's extent; counts exact (hits checked against the f64 reference on {}), cycles from {batches} systematic runs of {per} consecutive sets per point, in steady state (the frame design of mft-table1); the paper's Figure 6 gives curves, not numbers: both counts grow linearly with the light's size (the r2 rows measure how linearly here)",
        OFFSETS.map(|x| x.to_string()).join(", "),
        if check_every == 1 { "every ray".to_string() } else { format!("every {check_every}th set") }
    ));
    let rep = Frame::new(name, &m, res, a.seed, start).report(
        &[],
        format!(
            "S-Frusta and S-Packet on the T-Rex, Fern, Saloon (the paper's Figure 6) and Fairy Forest stand-ins at {res}x{res}, light edges x {}, one {} core",
            SCALES.map(|x| x.to_string()).join(", "),
            m.name
        ),
        ops_total,
        rows,
        notes,
    );
    Ok(Produced {
        report: rep,
        mismatches: bad_total as f64,
    })
}

/// R^2 of the least-squares line through `pts`.
fn r2(pts: &[(f64, f64)]) -> f64 {
    let n = pts.len() as f64;
    let (mx, my) = (
        pts.iter().map(|p| p.0).sum::<f64>() / n,
        pts.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let syy: f64 = pts.iter().map(|p| (p.1 - my).powi(2)).sum();
    if sxx == 0.0 || syy == 0.0 {
        return 1.0;
    }
    sxy * sxy / (sxx * syy)
}

/// What [`placement_sweep`] adds up: mismatches, ops, the scene's note.
struct Swept {
    bad: usize,
    ops: u64,
    note: String,
}

/// The scene's own light (size 1) moved by each of [`OFFSETS`]: counts,
/// cycles, reductions and the zero-interval share per offset.
fn placement_sweep(
    m: &sim::MachineConfig,
    (pr, scene_name, res): (&Prepared, &str, u32),
    hits: &Hits,
    (centre, e1, e2): ([f64; 3], [f32; 3], [f32; 3]),
    sample: (usize, usize, usize, (u64, &Progress)),
) -> AppResult<(Swept, Vec<Row>)> {
    let half = 0.5 * scene::workload::scene_size(&pr.scene);
    let len = e1
        .iter()
        .map(|&x| f64::from(x).powi(2))
        .sum::<f64>()
        .sqrt()
        .max(1e-9);
    let dir = e1.map(|x| f64::from(x) / len);
    let (mut rows, mut parts) = (Vec::new(), Vec::new());
    let mut out = Swept {
        bad: 0,
        ops: 0,
        note: String::new(),
    };
    // The placements are independent runs: all at once, in order.
    let points = OFFSETS
        .par_iter()
        .map(|&h| {
            let at = [0, 1, 2].map(|i| centre[i] + h * half * dir[i]);
            light_point(m, (pr, scene_name, res), hits, (at, e1, e2, 1.0), sample)
        })
        .collect::<AppResult<Vec<_>>>()?;
    for (h, p) in OFFSETS.into_iter().zip(points) {
        out.bad += p.bad;
        out.ops += p.ops;
        let row = |metric: &str, v: f64| {
            Row::new(metric, v)
                .key("scene", scene_name)
                .key("light_offset", h)
        };
        let r = |x: u64, y: u64| x as f64 / y.max(1) as f64;
        let cyc = p.packet_cycles / p.frusta_cycles.max(1.0);
        let tris = r(p.frusta.tris_accessed, p.packets.tris_accessed);
        rows.push(row("zero_interval_share", p.zero));
        rows.push(row("tris_accessed_frusta_over_packets", tris));
        rows.push(row(
            "aabb_reduction",
            r(p.packets.aabb_tests, p.frusta.aabb_tests),
        ));
        rows.push(row("cycle_reduction", cyc));
        parts.push(format!(
            "x{h}: {:.0}% zero-interval, tris {tris:.2}x, cycles {cyc:.2}",
            100.0 * p.zero
        ));
    }
    out.note = format!(
        "{scene_name}, light placement (its own light moved sideways along its first edge by x half the scene's extent; frusta triangles over packets', packet cycles over frusta): {}",
        parts.join("; ")
    );
    Ok((out, rows))
}

/// One light size's measurements on one scene.
struct Point {
    /// Share of shadow frusta whose direction interval holds zero.
    zero: f64,
    frusta: MftStats,
    packets: MftStats,
    frusta_cycles: f64,
    packet_cycles: f64,
    bad: usize,
    ops: u64,
}

/// Scale the scene's quad light by `s` about its centre, trace the shadow
/// sets with frusta and packets (exact counts, hits checked on every
/// `check_every`-th set), and sample both methods' cycles.
fn light_point(
    m: &sim::MachineConfig,
    (pr, scene_name, res): (&Prepared, &str, u32),
    hits: &Hits,
    (centre, e1, e2, s): ([f64; 3], [f32; 3], [f32; 3], f64),
    (batches, per, check_every, seed): (usize, usize, usize, (u64, &Progress)),
) -> AppResult<Point> {
    let fl = m.flavour();
    // A copy of the scene under this light (the points run at once; the
    // scenes are small).
    let pr = &pr.with_light(light_about(centre, e1, e2, s));
    let sets = shadow_sets(pr, hits, res, 0);
    let (fout, fst) = isa::run_native(&pr.frusta(sets.clone(), false, Shrink::None), fl);
    let (pkout, pst) = isa::run_native(&pr.packets(sets.clone()), fl);
    let mut bad = 0;
    {
        let refi = pr.reference();
        let idx: Vec<usize> = (0..sets.len()).step_by(check_every).collect();
        let pick = |v: &[Hit]| -> Vec<Hit> {
            idx.iter()
                .flat_map(|&i| v[256 * i..256 * i + 256].iter().copied())
                .collect()
        };
        let sub: Vec<Frusta> = idx.iter().map(|&i| sets[i].clone()).collect();
        let label = format!("{scene_name} light x{s}");
        bad += mismatches_of(F32Test::Pluecker, &label, &refi, &sub, &pick(&fout));
        bad += mismatches_of(F32Test::MollerTrumbore, &label, &refi, &sub, &pick(&pkout));
    }
    let fr = |v: Vec<Frusta>| pr.frusta(v, false, Shrink::None);
    let pk = |v: Vec<Frusta>| pr.packets(v);
    let (cf, _, o1) = sampled_cycles(m, &sets, batches, per, seed, fr)?;
    let (cp, _, o2) = sampled_cycles(m, &sets, batches, per, seed, pk)?;
    Ok(Point {
        zero: zero_interval_share(&sets),
        frusta: fst,
        packets: pst,
        frusta_cycles: cf,
        packet_cycles: cp,
        bad,
        ops: o1 + o2,
    })
}

/// The three panels of Figure 6 (counts relative to the scene's light, and
/// packets over frusta) as one PNG.
fn write_plot(
    png: &std::path::Path,
    s_tris: Vec<repro::plot::Series>,
    s_isec: Vec<repro::plot::Series>,
    s_ratio: Vec<repro::plot::Series>,
) -> AppResult<()> {
    repro::plot::write(
        png,
        &[
            repro::plot::Panel {
                title: "MFT soft shadows: triangles accessed",
                x: "light size (x the scene's light)",
                y: "triangles accessed (x at the scene's light)",
                series: s_tris,
            },
            repro::plot::Panel {
                title: "MFT soft shadows: 16-wide intersection tests",
                x: "light size (x the scene's light)",
                y: "intersection tests (x at the scene's light)",
                series: s_isec,
            },
            repro::plot::Panel {
                title: "16-ray packets over MFT: simulated cycles",
                x: "light size (x the scene's light)",
                y: "cycle reduction (packets / frusta)",
                series: s_ratio,
            },
        ],
    )
}
