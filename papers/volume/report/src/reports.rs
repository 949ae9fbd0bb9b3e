//! `volume-fig5`: frames per second at 512^2 per dataset, "gcc", "sse" and
//! "bvh" on the Core i7 (X5550) model and "bvh" on the Core 2 Duo (Penryn),
//! the paper's rows beside ours.

use crate::images::{frames, write_png, Agreement};
use crate::measure::{
    density, measure, missing, sample, Cell, Dataset, Method, FRAME_COVERAGE, HEURISTICS,
    PIXEL_TOL, RDA_PER_DT, RES, SAMPLES_PER_VOXEL,
};
use crate::paper::{FIG5, TRAVERSAL_SHARE};
use crate::rows::{cost_rows, density_rows, fps_rows};
use repro::sampling::paired_ratio_systematic;
use repro::{AppResult, Produced, Report, ReproduceArgs, Row};
use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::Instant;
use volume_kernels::bvh::{ConstantAt, Heuristics};

/// Packets timed per cell: `--tiles`, else 16 (`--quick`) or 64.
fn groups(a: &ReproduceArgs) -> usize {
    a.tiles
        .map_or(if a.quick { 32 } else { 256 }, |t| t as usize)
}

/// One core of the report's machine, 4 lanes (Listing 2 is SSE).
pub(crate) fn one_core(a: &ReproduceArgs) -> AppResult<sim::MachineConfig> {
    a.one_core(4, "Listing 2 is 4-wide SSE")
}

/// One core of the paper's Mac mini (Core 2 Duo, Penryn), with the run's
/// `--set` overrides.
pub(crate) fn laptop_core(a: &ReproduceArgs) -> AppResult<sim::MachineConfig> {
    let mut m = sim::MachineConfig::load(LAPTOP)
        .and_then(|m| m.with_sets(&a.machine.sets))
        .map_err(|e| repro::AppError(e.to_string()))?;
    m.cores = 1;
    Ok(m)
}

/// One core of the paper's workstation (two X5550 sockets), with the run's
/// `--set` overrides.
pub(crate) fn workstation_core(a: &ReproduceArgs) -> AppResult<sim::MachineConfig> {
    let mut m = sim::MachineConfig::load(crate::MACHINE)
        .and_then(|m| m.with_sets(&a.machine.sets))
        .map_err(|e| repro::AppError(e.to_string()))?;
    m.cores = 1;
    Ok(m)
}

/// The Mac mini's machine.
pub(crate) const LAPTOP: &str = "core2-penryn-2ghz";

/// `volume-fig5`.
pub(crate) fn volume_fig5(a: &ReproduceArgs) -> AppResult<Produced> {
    let start = Instant::now();
    let m = one_core(a)?;
    let mac = laptop_core(a)?;
    let chip = a.machine.load()?.cores;
    let mac_cores = sim::MachineConfig::load(LAPTOP)
        .map_err(|e| repro::AppError(e.to_string()))?
        .cores;
    let g = groups(a);
    let mut rows = Vec::new();
    let (mut ops, mut bad) = (0u64, 0usize);
    let mut skipped = Vec::new();
    for row in FIG5.iter().filter(|r| a.runs(r.name)) {
        if let Some(why) = missing(row.name) {
            skipped.push(format!("The {} row is left out: {why}.", row.name));
            continue;
        }
        let ds = Arc::new(Dataset::load(row.name, (row.lit, row.leaf), a.quick)?);
        let smp = sample(&ds, g, a.seed);
        rows.extend(density_rows(
            |r| r.key("dataset", row.name),
            &ds,
            &density(&smp),
        ));
        for (how, spv) in ["one sequence per ray", "restarting per leaf"]
            .into_iter()
            .zip(restart_density(&ds))
        {
            rows.push(
                Row::new("samples_per_voxel_without_termination", spv)
                    .key("dataset", row.name)
                    .key("differential_step", how),
            );
        }
        let runs = [
            (&m, Method::Gcc, chip, row.i7[0]),
            (&m, Method::Sse, chip, row.i7[1]),
            (&m, Method::Bvh, chip, row.i7[2]),
            (&mac, Method::Bvh, mac_cores, row.core2_bvh),
        ];
        let cells: Vec<Cell> = runs
            .iter()
            .map(|&(mm, me, _, _)| measure(mm, &ds, &smp, me, &a.progress))
            .collect::<AppResult<_>>()?;
        for (&(mm, me, cores, paper), c) in runs.iter().zip(&cells) {
            ops += c.ops;
            bad += c.mismatches();
            let k = |r: Row| {
                r.key("dataset", row.name)
                    .key("method", me.name())
                    .key("machine", mm.name.clone())
            };
            rows.extend(fps_rows(k, c, Some((cores, Some(paper)))));
            rows.push(k(Row::new("samples_per_ray", c.samples_per_ray)));
            rows.push(k(Row::new(
                "classified_samples_per_ray",
                c.classified_per_ray,
            )));
            rows.extend(cost_rows(k, (mm, cores), (c, Some(paper)), RES));
            rows.push(k(Row::new("instructions_per_ray", c.instr_per_ray)));
            rows.push(k(Row::new("cpi", c.cpi)));
            rows.push(k(Row::new("psnr_vs_reference", c.psnr).unit("dB")));
            rows.push(k(Row::new("pixels_off_reference", c.bad as f64)));
            if me == Method::Bvh {
                rows.push(k(Row::new("bvh_nodes_per_packet", c.nodes_per_packet)));
                rows.push(k(Row::new("leaf_rays_per_ray", c.leaf_rays_per_ray)));
                rows.push(k(Row::new(
                    "constant_subvolume_sample_share",
                    c.constant_share,
                )));
                let mut r = k(Row::new("traversal_cycle_share", c.traversal_share));
                r.paper = Some(TRAVERSAL_SHARE.1);
                rows.push(r);
            }
        }
        // (slower, faster): the faster's speed-up is the slower's cycles over
        // its own, paired over the same packets.
        for (slow, fast, name, paper) in [
            (1, 2, "speedup_bvh_over_sse", row.i7[2] / row.i7[1]),
            (0, 1, "speedup_sse_over_gcc", row.i7[1] / row.i7[0]),
        ] {
            let (x, y) = (&cells[slow], &cells[fast]);
            let (s, ci) = paired_ratio_systematic(&x.run_cycles, &y.run_cycles);
            let mut r = Row::new(name, s).key("dataset", row.name);
            r.ci95 = ci;
            r.paper = Some(paper);
            rows.push(r);
        }
        // The frame with the paper's heuristics (the PNG), and with eqs. 5-7
        // off (every node descended, nothing culled, pruned or taken as
        // constant): what the heuristics change.
        let res = if a.quick { RES / 2 } else { RES };
        let [fr, fx]: [Agreement; 2] = frames(&ds, res, PIXEL_TOL, &[ds.heuristics, EXACT])
            .try_into()
            .unwrap_or_else(|_| unreachable!("two variants, two frames"));
        write_png(
            &a.png_path(&format!("volume-fig5-{}", row.name))?,
            res,
            &fr.rgb,
        )?;
        bad += fr.mismatches() + fx.mismatches();
        let k = |r: Row| {
            r.key("dataset", row.name)
                .key("method", "bvh")
                .key("frame", format!("{res}x{res}"))
        };
        rows.push(k(Row::new("frame_psnr_vs_reference", fr.psnr).unit("dB")));
        rows.push(k(Row::new("frame_max_difference", fr.max)));
        rows.push(k(Row::new("frame_pixels_off_reference", fr.bad as f64)));
        rows.push(k(Row::new("frame_share_off_by_0.05", fr.off)));
        rows.push(
            k(Row::new("frame_psnr_vs_reference", fx.psnr).unit("dB")).key("heuristics", "off"),
        );
        rows.push(
            Row::new(
                "samples_per_ray_without_termination",
                untermined_samples(&ds),
            )
            .key("dataset", row.name),
        );
        let t = &ds.tree;
        let vox = ds.prepared.volume.len() as f64;
        rows.push(
            Row::new("bvh_bytes_over_volume_bytes", t.bytes() as f64 / vox)
                .key("dataset", row.name),
        );
        rows.push(
            Row::new("bvh_nodes", t.nodes.len() as f64)
                .key("dataset", row.name)
                .key("leaf", t.leaf),
        );
        rows.push(
            Row::new("bvh_build_seconds", ds.build_seconds)
                .key("dataset", row.name)
                .unit("host-measured"),
        );
    }
    rows.extend(crate::assumptions::assumption_rows(
        a,
        &m,
        (chip, g),
        &mut ops,
        &mut bad,
    )?);
    let mut s = BTreeMap::new();
    s.insert("design".into(), serde_json::json!(format!(
        "{RES}x{RES} from each dataset's view (the volume's box filling {:.0}% of the frame), differential sampling: each step {RDA_PER_DT} of the first step longer than the last (the paper's rda = 2^-7, read as relative), the first step chosen per dataset and view for {SAMPLES_PER_VOXEL} samples per voxel over a 32x32 grid of the view's rays (the paper's ~2); 8x8-pixel packets as units; {g} packets, one at a seeded place in each of as many equal strata of the frame, each timed in full detail on one core after functional warming with the packet before it and itself; every timed pixel checked against the f64 reference (off if a channel differs by more than {PIXEL_TOL}); eq. 5 delta_c {}, eq. 6 delta_p {}, eq. 7 delta_sv {}",
        FRAME_COVERAGE * 100.0, HEURISTICS.delta_c, HEURISTICS.delta_p, HEURISTICS.delta_sv
    )));
    s.insert("seed".into(), serde_json::json!(a.seed));
    let mut notes = skipped;
    notes.extend([
        format!("The paper's Core i7 is two 4-core X5550 (16 threads), the machine {}; the {chip}-core rows are the simulated one-core rate times {chip} times the paper's measured 97% scaling at 8 threads. A simulated core runs {} packets at once, one per hardware thread (simultaneous multithreading as the DRS reports model it; `--set core.threads=1` for one), each packet charged an equal share of their cycles.", a.machine.machine, crate::measure::smt_threads(&m)),
        "Each dataset's whole frame (512^2; 256^2 at --quick) is rendered by the bvh caster natively (the same code, not timed) and compared pixel by pixel with the f64 reference (frame_* rows; its pixels off count as mismatches); the PNGs are those frames.".into(),
        format!("The Core 2 column is one simulated core of {LAPTOP} (the paper's Mac mini) times its 2 cores."),
        "gcc is the naive scalar caster as gcc 4.x builds it (papers/volume/kernels/src/naive.rs): the same samples, eight address translations per stencil (nothing shared between corners), eq. 8 and 9 term by term, the spills and reloads of 16 xmm registers.".into(),
        "The assumption rows measure the choices the paper leaves open on the engine: the view (the bounding sphere instead of the box just inside the frame, the first step chosen again) and the transfer function's opacity (every point's scaled by 0.5 and 2, the first step kept); fps_over_reports_setting is each fps over the reports' setting's.".into(),
        "samples_per_voxel_without_termination: samples over the voxels of the chords of a 32x32 grid of the view's rays that never stop, with one differential sequence per ray from the box's entry (the reports' casters: the bvh caster only removes samples) and with the step restarted at every L^3 leaf cell, as Listing 2's per-leaf call with a fresh dt would; the same first step.".into(),
        "samples_per_voxel is the samples the timed rays' reference walks visit over the voxels their steps cover (early termination included): the paper's ~2 (section 7); frame_coverage is the share of the frame's pixels whose rays meet the volume's box; terminated_share the share of those rays that stop by opacity.".into(),
        "Datasets: the engine is the paper's; neghip is 66^3 (the paper's 64^3); the skull is a 64^3 float CT (the paper's is 256^3); the dense field is a seeded noisy 128^3 volume (64^3 at --quick) standing in for the backpack. Transfer functions are ours (configs/transfer/), smooth ramps over each histogram as the paper describes its own.".into(),
    ]);
    Ok(Produced {
        mismatches: bad as f64,
        report: Report {
            report: "volume-fig5".into(),
            machine: Some(m.name.clone()),
            isa: Some(m.flavour().name().into()),
            fidelity: "full".into(),
            sample: Some(s),
            input: Some(
                (a.scenes.iter())
                    .filter(|n| missing(n).is_none())
                    .copied()
                    .collect::<Vec<_>>()
                    .join(", "),
            ),
            ops_simulated: ops,
            host_seconds: start.elapsed().as_secs_f64(),
            rows,
            notes,
        },
    })
}

/// Samples per voxel along rays that never stop (a 32x32 grid of the
/// view's rays, samples over the voxels of their chords through the box)
/// when each ray keeps one differential sequence from the box's entry (the
/// reports' casters), and when the step restarts at every leaf cell of the
/// implicit BVH (`L`^3, Listing 2 called per leaf with a fresh `dt`).
pub(crate) fn restart_density(ds: &Dataset) -> [f64; 2] {
    let dims = ds.prepared.volume.dims;
    let rays = volume_kernels::Rays::camera(dims, ds.eye, ds.fov, (32, 32));
    let s = ds.sampling;
    let leaf = f64::from(ds.tree.leaf);
    // Samples of a sequence started at `from` up to `to` (included only
    // at the ray's exit: a sample on a cell's far side belongs to the next).
    let count = |from: f64, to: f64, last: bool| {
        let (mut t, mut step, mut n) = (from, s.dt, 0u64);
        while t < to || (last && t == to) {
            n += 1;
            t += step;
            step += s.rda;
        }
        n
    };
    let (mut one, mut restart, mut len) = (0u64, 0u64, 0f64);
    for i in 0..rays.len() {
        let (o, d) = (rays.org[i].map(f64::from), rays.dir[i].map(f64::from));
        let Some((t0, t1)) = scene::volume_ref::enter_exit(dims, o, d) else {
            continue;
        };
        one += count(t0, t1, true);
        len += t1 - t0;
        let mut cuts = vec![t0, t1];
        for a in (0..3).filter(|&a| d[a] != 0.0) {
            let (lo, hi) = (o[a] + t0 * d[a], o[a] + t1 * d[a]);
            let (k0, k1) = (
                (lo.min(hi) / leaf).ceil() as i64,
                (lo.max(hi) / leaf).floor() as i64,
            );
            cuts.extend(
                (k0..=k1)
                    .map(|k| (k as f64 * leaf - o[a]) / d[a])
                    .filter(|&t| t > t0 && t < t1),
            );
        }
        cuts.sort_by(f64::total_cmp);
        restart += cuts
            .windows(2)
            .map(|w| count(w[0], w[1], w[1] == t1))
            .sum::<u64>();
    }
    let len = len.max(1e-30);
    [one as f64 / len, restart as f64 / len]
}

/// The mean over the frame's pixels of the samples a ray would visit if it
/// never became opaque (its sample sequence through the volume's box): an
/// upper bound on the brute-force caster's samples per ray at this view.
pub(crate) fn untermined_samples(ds: &Dataset) -> f64 {
    use rayon::prelude::*;
    let dims = ds.prepared.volume.dims;
    let res = ds.res;
    let rays = volume_kernels::Rays::camera(dims, ds.eye, ds.fov, (res, res));
    let s = ds.sampling;
    let total: u64 = (0..rays.len())
        .into_par_iter()
        .map(|i| {
            let (o, d) = (rays.org[i].map(f64::from), rays.dir[i].map(f64::from));
            scene::volume_ref::enter_exit(dims, o, d).map_or(0, |(t0, t1)| {
                let (mut t, mut step, mut n) = (t0, s.dt, 0u64);
                while t <= t1 {
                    n += 1;
                    t += step;
                    step += s.rda;
                }
                n
            })
        })
        .sum();
    total as f64 / rays.len() as f64
}

/// The BVH caster with eqs. 5-7 off: every node descended, nothing culled,
/// pruned or taken as constant.
pub(crate) const EXACT: Heuristics = Heuristics {
    delta_c: 0.0,
    delta_p: f32::INFINITY,
    delta_sv: 0.0,
    constant_at: ConstantAt::Leaves,
};
