//! The DRS reports' measurement: a seeded sample of tiles of a scene
//! stand-in, every method traced over the same streams, each stream
//! checked against the reference and timed on the machine.

use drs_kernels::methods::{Kernel, Run};
use isa::Region;
pub(crate) use repro::sampling::separates;
use repro::sampling::{mix, paired_ratio, ratio_ci};
use repro::{AppError, AppResult, Produced, Report, ReproduceArgs, Row};
use scene::loaded::Loaded;
use scene::reference::Reference;
use scene::workload::{path_trace_tile, StreamKind, Tile};
use std::collections::BTreeMap;
use std::time::Instant;

/// Sums over the streams of one (scene, kernel).
#[derive(Default)]
pub(crate) struct Acc {
    pub(crate) rays: u64,
    pub(crate) cycles: u64,
    pub(crate) ops: u64,
    pub(crate) core_cycles: u64,
    pub(crate) core_ops: u64,
    pub(crate) dram: u64,
    pub(crate) core_tests: u64,
    pub(crate) node_tests: u64,
    pub(crate) bad: u64,
    /// Per tile: (rays, cycles), for the confidence interval.
    pub(crate) tiles: Vec<(u64, u64)>,
    /// Per stream kind (primary, bounce, shadow): (rays, cycles).
    pub(crate) kinds: BTreeMap<&'static str, (u64, u64)>,
}

impl Acc {
    /// The sums' per-ray figures on machine `m` (chip figures: all its cores).
    pub(crate) fn per_ray(&self, m: &sim::MachineConfig) -> sim::PerRay {
        sim::PerRay::of(self.cycles, self.dram, self.rays, m.clock_ghz, m.cores)
    }
    /// Chip Mray/s and its 95% CI over the tiles (ratio rays / cycles).
    pub(crate) fn chip_mray_ci(&self, m: &sim::MachineConfig) -> (f64, Option<f64>) {
        let pairs: Vec<(f64, f64)> = self
            .tiles
            .iter()
            .map(|&(r, c)| (r as f64, c as f64))
            .collect();
        let ci = ratio_ci(&pairs).map(|h| h * chip_mray(m, 1, 1));
        (chip_mray(m, self.cycles, self.rays), ci)
    }
    /// Chip s/Gray and its 95% CI over the tiles (ratio cycles / rays).
    pub(crate) fn chip_sgray_ci(&self, m: &sim::MachineConfig) -> (f64, Option<f64>) {
        let pairs: Vec<(f64, f64)> = self
            .tiles
            .iter()
            .map(|&(r, c)| (c as f64, r as f64))
            .collect();
        let ci = ratio_ci(&pairs).map(|h| h * chip_sgray(m, 1, 1));
        (chip_sgray(m, self.cycles, self.rays), ci)
    }
}

/// Speedup of `a` over `b` on the same tiles (their cycles, b over a) and
/// its paired 95% CI: the methods trace the same rays.
pub(crate) fn paired_speedup(a: &Acc, b: &Acc) -> (f64, Option<f64>) {
    let cycles = |x: &Acc| x.tiles.iter().map(|&(_, c)| c as f64).collect::<Vec<f64>>();
    paired_ratio(&cycles(b), &cycles(a))
}

/// Chip Mray/s of `rays` in `cycles` of one core (the paper ran one
/// thread per core: the rate times the cores).
pub(crate) fn chip_mray(m: &sim::MachineConfig, cycles: u64, rays: u64) -> f64 {
    sim::PerRay::of(cycles, 0, rays, m.clock_ghz, m.cores).mray_per_s_chip
}

/// Chip s/Gray of `rays` in `cycles` of one core.
pub(crate) fn chip_sgray(m: &sim::MachineConfig, cycles: u64, rays: u64) -> f64 {
    sim::PerRay::of(cycles, 0, rays, m.clock_ghz, m.cores).s_per_gray_chip
}

/// The machine and tile sample of a reproduce run.
#[derive(Clone)]
pub(crate) struct Sample {
    pub(crate) m: sim::MachineConfig,
    pub(crate) fl: isa::FlavourId,
    pub(crate) ntiles: u32,
    pub(crate) bounces: u32,
    pub(crate) size: u32,
    pub(crate) spp: u32,
    /// 0: `ntiles` independent seeded tiles; k > 0: `ntiles` seeded anchor
    /// pixels, each covered by the k x k aligned tiles around it (so sweeps
    /// over the tile size look at the same parts of the image).
    pub(crate) block: u32,
}

pub(crate) fn sample(a: &ReproduceArgs) -> AppResult<Sample> {
    let m = a.machine.load()?;
    let fl = m.flavour();
    if !Kernel::DrsBvh4.supports(fl.lanes()) {
        return Err(AppError(format!(
            "--machine {}: {} needs a 4- or 8-lane ISA, {fl} has {} lanes",
            m.name,
            a.name,
            fl.lanes()
        )));
    }
    let (mut ntiles, bounces, size, mut spp) = if a.quick {
        (2, 1, 16, 16)
    } else {
        (6, 2, 16, 16)
    };
    if let Some(t) = a.tiles {
        if t == 0 || t > 1024 {
            return Err(AppError(format!("--tiles: {t} is not 1 to 1024")));
        }
        ntiles = t;
    }
    if let Some(n) = a.spp {
        if n == 0 || n > 16 {
            return Err(AppError(format!(
                "--spp: {n} is not 1 to 16 (streams hold at most 4096 rays)"
            )));
        }
        spp = n;
    }
    Ok(Sample {
        m,
        fl,
        ntiles,
        bounces,
        size,
        spp,
        block: 0,
    })
}

/// A scene stand-in and the DRS kernels' BVHs ([`drs_kernels::BVH`]).
pub(crate) fn load(scene_name: &str) -> AppResult<Loaded> {
    Loaded::load(scene_name, &drs_kernels::BVH).map_err(AppError)
}

/// Every kernel over the same sampled streams of one scene.
pub(crate) fn measure(
    a: &ReproduceArgs,
    smp: &Sample,
    scene_name: &str,
    kernels: &[Kernel],
    ops_total: &mut u64,
) -> AppResult<Vec<Acc>> {
    measure_loaded(a, smp, &load(scene_name)?, scene_name, kernels, ops_total)
}

/// [`measure`] on a loaded scene.
pub(crate) fn measure_loaded(
    a: &ReproduceArgs,
    smp: &Sample,
    ld: &Loaded,
    scene_name: &str,
    kernels: &[Kernel],
    ops_total: &mut u64,
) -> AppResult<Vec<Acc>> {
    let (m, fl, ntiles, bounces, size, spp) =
        (&smp.m, smp.fl, smp.ntiles, smp.bounces, smp.size, smp.spp);
    let (scene, b2, b4) = (&ld.scene, &ld.b2, &ld.b4);
    let refi = Reference::with_bvh(&scene.mesh, b2);
    let cam = &scene.config.camera;
    let (tw, th) = (cam.width / size, cam.height / size);
    let mut acc: Vec<Acc> = kernels.iter().map(|_| Acc::default()).collect();
    for i in 0..ntiles {
        let r = mix(a.seed ^ mix(i as u64 + 1));
        let tiles: Vec<Tile> = if smp.block == 0 {
            vec![Tile {
                x: (r % u64::from(tw)) as u32,
                y: ((r >> 32) % u64::from(th)) as u32,
                size,
            }]
        } else {
            let k = smp.block;
            // An anchor pixel on the geometry: the first of up to 64 seeded
            // candidates whose centre ray hits (where the render time goes).
            let pixel = |r: u64| {
                (
                    (r % u64::from(cam.width)) as u32,
                    ((r >> 32) % u64::from(cam.height)) as u32,
                )
            };
            let hits = |&(x, y): &(u32, u32)| {
                let (o, d) = cam.ray(f64::from(x) + 0.5, f64::from(y) + 0.5);
                refi.closest(&scene::reference::Ray::new(o, d)).is_some()
            };
            let (ax, ay) = (0..64u64)
                .map(|j| pixel(mix(r ^ mix(j + 1))))
                .find(hits)
                .unwrap_or_else(|| pixel(r));
            let first = |p: u32, n: u32| {
                (p / size)
                    .saturating_sub((k - 1) / 2)
                    .min(n.saturating_sub(k))
            };
            let (x0, y0) = (first(ax, tw), first(ay, th));
            (0..k * k)
                .map(|j| Tile {
                    x: x0 + j % k,
                    y: y0 + j / k,
                    size,
                })
                .filter(|t| t.x < tw && t.y < th)
                .collect()
        };
        let mut tile_sums = vec![(0u64, 0u64); kernels.len()];
        for tile in tiles {
            let streams = path_trace_tile(scene, b2, tile, spp, bounces, a.seed);
            for st in streams.iter().filter(|s| !s.is_empty()) {
                for (ki, &k) in kernels.iter().enumerate() {
                    let mut run = Run::new(k, scene, b2, b4, st.clone());
                    run.packet_tile = Some((size, spp));
                    let (t, (hits, tests)) = isa::record(&run, fl, k.name());
                    let label = format!(
                        "{scene_name} tile ({}, {}) {:?} {}",
                        tile.x,
                        tile.y,
                        st.kind,
                        k.name()
                    );
                    let bad = run.mismatches(&label, &refi, &hits);
                    let s =
                        sim::simulate(m, &[&t], &sim::SimOptions::default()).map_err(AppError)?;
                    let ac = &mut acc[ki];
                    ac.rays += st.len() as u64;
                    ac.cycles += s.cycles;
                    ac.ops += s.ops;
                    ac.core_cycles += s.region_cycles[Region::CoreLoop as usize];
                    ac.core_ops += s.region_ops[Region::CoreLoop as usize];
                    ac.dram += s.dram_read + s.dram_written;
                    ac.core_tests += tests.core_loop;
                    ac.node_tests += tests.node_tests();
                    ac.bad += bad as u64;
                    *ops_total += t.ops.len() as u64;
                    tile_sums[ki].0 += st.len() as u64;
                    tile_sums[ki].1 += s.cycles;
                    let kind = match st.kind {
                        StreamKind::Primary => "primary",
                        StreamKind::Bounce(_) => "bounce",
                        StreamKind::Shadow(_) => "shadow",
                    };
                    let e = ac.kinds.entry(kind).or_default();
                    e.0 += st.len() as u64;
                    e.1 += s.cycles;
                }
            }
        }
        for (ki, ts) in tile_sums.into_iter().enumerate() {
            if ts.0 > 0 {
                acc[ki].tiles.push(ts);
            }
        }
    }
    Ok(acc)
}

/// Print (and with `--out`, write) a reproduce report; an error if any ray
/// differed from the reference.
#[allow(clippy::too_many_arguments)]
pub(crate) fn finish(
    a: &ReproduceArgs,
    name: &str,
    input: &str,
    ci_of: &str,
    smp: &Sample,
    start: Instant,
    ops_total: u64,
    rows: Vec<Row>,
    notes: Vec<String>,
) -> AppResult<Produced> {
    let bad: f64 = rows
        .iter()
        .filter(|r| r.metric == "hit_mismatches")
        .map(|r| r.value)
        .sum();
    let mut sample = BTreeMap::new();
    sample.insert("tiles_per_scene".into(), serde_json::json!(smp.ntiles));
    sample.insert(
        "tile".into(),
        serde_json::json!(format!("{0}x{0} px x {1} spp", smp.size, smp.spp)),
    );
    sample.insert("bounces".into(), serde_json::json!(smp.bounces));
    sample.insert(
        "streams".into(),
        serde_json::json!(
            "primary, bounce and shadow streams of the path tracer (shadow rays: any hit)"
        ),
    );
    sample.insert("seed".into(), serde_json::json!(a.seed));
    sample.insert(
        "ci95".into(),
        serde_json::json!(format!(
            "{ci_of}, paired where methods are compared, Student t"
        )),
    );
    let rep = Report {
        report: name.into(),
        machine: Some(smp.m.name.clone()),
        isa: Some(smp.fl.name().into()),
        fidelity: "full".into(),
        sample: Some(sample),
        input: Some(input.into()),
        ops_simulated: ops_total,
        host_seconds: start.elapsed().as_secs_f64(),
        rows,
        notes,
    };
    Ok(Produced {
        report: rep,
        mismatches: bad,
    })
}
