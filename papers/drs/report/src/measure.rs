//! The DRS reports' measurement: a seeded sample of tiles of a scene
//! stand-in, every method traced over the same streams, each stream
//! checked against the reference and timed on the machine.

use drs_kernels::methods::{Kernel, Run, SharedLayouts};
use isa::Region;
use rayon::prelude::*;
pub(crate) use repro::sampling::separates;
use repro::sampling::{mix, paired_ratio, ratio_ci};
use repro::{AppError, AppResult, Produced, Report, ReproduceArgs, Row};
use scene::agreement::{mismatches_expected, Expected, F32Test};
use scene::loaded::Loaded;
use scene::reference::Reference;
use scene::workload::{path_trace_tile, StreamKind, Tile};
use std::collections::BTreeMap;
use std::time::Instant;

/// Sums over the streams of one (scene, kernel).
#[derive(Default)]
pub(crate) struct Acc {
    pub(crate) rays: u64,
    /// Each hardware thread's own cycles, summed over its units (what a
    /// per-logical-thread CPI divides).
    pub(crate) cycles: u64,
    /// Each core's cycles while any of its threads ran, summed over the
    /// steps (what a per-core CPI divides).
    pub(crate) core_time: u64,
    pub(crate) ops: u64,
    pub(crate) core_cycles: u64,
    pub(crate) core_ops: u64,
    pub(crate) dram: u64,
    pub(crate) core_tests: u64,
    pub(crate) node_tests: u64,
    /// Ray-leaf tests (a ray against a leaf's triangle block).
    pub(crate) leaf_tests: u64,
    pub(crate) bad: u64,
    /// Per tile: (rays, cycles), for the confidence interval.
    pub(crate) tiles: Vec<(u64, u64)>,
    /// Per stream kind (primary, bounce, shadow): (rays, cycles).
    pub(crate) kinds: BTreeMap<&'static str, (u64, u64)>,
    /// Per stream kind: instructions and node tests, all and the core loop's.
    pub(crate) kind_work: BTreeMap<&'static str, Work>,
    /// DRAM bytes of the timed steps by the data structure that moved them:
    /// reads by the kind of memory region missed in ([`isa::MemKind`]'s
    /// names), and "written-back" (dirty lines evicted).
    pub(crate) dram_by: BTreeMap<&'static str, u64>,
    /// Of the reads, the prefetcher's, by the kind of region whose access
    /// triggered them.
    pub(crate) prefetched_by: BTreeMap<&'static str, u64>,
}

/// Instructions and ray-node tests of the timed rays of one stream kind.
#[derive(Clone, Copy, Default)]
pub(crate) struct Work {
    pub(crate) rays: u64,
    pub(crate) instructions: u64,
    pub(crate) core_instructions: u64,
    pub(crate) node_tests: u64,
    pub(crate) core_tests: u64,
}

impl Work {
    fn add(&mut self, o: Work) {
        self.rays += o.rays;
        self.instructions += o.instructions;
        self.core_instructions += o.core_instructions;
        self.node_tests += o.node_tests;
        self.core_tests += o.core_tests;
    }
}

impl Acc {
    /// The sums' per-ray figures on the sample's machine (chip figures: all
    /// its cores and threads).
    pub(crate) fn per_ray(&self, m: &Sample) -> sim::PerRay {
        sim::PerRay::of(
            self.cycles,
            self.dram,
            self.rays,
            m.m.clock_ghz,
            m.chip_units(),
        )
    }
    /// Chip Mray/s and its 95% CI over the tiles (ratio rays / cycles).
    pub(crate) fn chip_mray_ci(&self, m: &Sample) -> (f64, Option<f64>) {
        let pairs: Vec<(f64, f64)> = self
            .tiles
            .iter()
            .map(|&(r, c)| (r as f64, c as f64))
            .collect();
        let ci = ratio_ci(&pairs).map(|h| h * chip_mray(m, 1, 1));
        (chip_mray(m, self.cycles, self.rays), ci)
    }
    /// Chip s/Gray and its 95% CI over the tiles (ratio cycles / rays).
    pub(crate) fn chip_sgray_ci(&self, m: &Sample) -> (f64, Option<f64>) {
        let pairs: Vec<(f64, f64)> = self
            .tiles
            .iter()
            .map(|&(r, c)| (c as f64, r as f64))
            .collect();
        let ci = ratio_ci(&pairs).map(|h| h * chip_sgray(m, 1, 1));
        (chip_sgray(m, self.cycles, self.rays), ci)
    }
}

/// Bytes of the renderer's frame buffer per pixel and frame: an RGBA f32
/// accumulator read and written once a frame (the 16 samples of a pixel
/// accumulate in cache while its tile renders).
const FRAME_BUFFER_BYTES_PER_PIXEL: f64 = 2.0 * 16.0;

/// DRAM bytes per ray by the data structure that moved them (rows of
/// `row`, keyed `structure`), the prefetcher's part of each, then the
/// frame buffer's share, computed (not
/// simulated: the renderer's accumulation is not traced) from the timed
/// rays per pixel; and ray-leaf tests per ray (each fetches a triangle
/// block).
pub(crate) fn structure_rows(ac: &Acc, smp: &Sample, row: &dyn Fn(&str, f64) -> Row) -> Vec<Row> {
    let rays = ac.rays.max(1) as f64;
    let per_structure = |metric: &'static str, by: &BTreeMap<&'static str, u64>| {
        by.iter()
            .filter(|(_, &b)| b > 0)
            .map(|(k, &b)| {
                row(metric, b as f64 / rays)
                    .key("structure", k)
                    .unit("B/ray")
            })
            .collect::<Vec<Row>>()
    };
    let mut rows = per_structure("bytes_per_ray", &ac.dram_by);
    rows.extend(per_structure("prefetched_bytes_per_ray", &ac.prefetched_by));
    let pixels = (ac.tiles.len() as u64 * u64::from(smp.size * smp.size)) as f64;
    rows.push(
        row(
            "bytes_per_ray",
            FRAME_BUFFER_BYTES_PER_PIXEL * pixels / rays,
        )
        .key("structure", "frame-buffer (computed)")
        .unit("B/ray"),
    );
    rows.push(row("leaf_tests_per_ray", ac.leaf_tests as f64 / rays));
    rows
}

/// Where Our BVH4 (`ours`) moves more DRAM bytes per ray than Single BVH4
/// (`single`), a note naming the data structure with the largest
/// difference and how much of each method's bytes the prefetcher read;
/// `None` where it moves no more (the paper's claim holds).
pub(crate) fn bytes_note(scene: &str, single: &Acc, ours: &Acc) -> Option<String> {
    let per_ray = |a: &Acc, b: u64| b as f64 / a.rays.max(1) as f64;
    let total = |a: &Acc| per_ray(a, a.dram_by.values().sum());
    if total(ours) <= total(single) {
        return None;
    }
    let of = |a: &Acc, k: &str| per_ray(a, a.dram_by.get(k).copied().unwrap_or(0));
    let (worst, diff) = ours
        .dram_by
        .keys()
        .map(|k| (*k, of(ours, k) - of(single, k)))
        .max_by(|x, y| x.1.total_cmp(&y.1))?;
    let prefetched = |a: &Acc| {
        100.0 * a.prefetched_by.values().sum::<u64>() as f64
            / a.dram_by.values().sum::<u64>().max(1) as f64
    };
    Some(format!(
        "{scene}: Our BVH4 moves {:.1} B/ray against Single BVH4's {:.1}, most of the difference in {worst} (+{diff:.1} B/ray); the prefetcher read {:.0}% of Our BVH4's bytes and {:.0}% of Single BVH4's (prefetched_bytes_per_ray; the bytes without it: --set prefetch=None; papers/drs/README.md, B/ray by structure)",
        total(ours),
        total(single),
        prefetched(ours),
        prefetched(single),
    ))
}

/// Speedup of `a` over `b` on the same tiles (their cycles, b over a) and
/// its paired 95% CI: the methods trace the same rays.
pub(crate) fn paired_speedup(a: &Acc, b: &Acc) -> (f64, Option<f64>) {
    let cycles = |x: &Acc| x.tiles.iter().map(|&(_, c)| c as f64).collect::<Vec<f64>>();
    paired_ratio(&cycles(b), &cycles(a))
}

/// Chip Mray/s of `rays` in `cycles` of one hardware thread (every thread
/// of every core runs at once: the rate times the threads).
pub(crate) fn chip_mray(m: &Sample, cycles: u64, rays: u64) -> f64 {
    sim::PerRay::of(cycles, 0, rays, m.m.clock_ghz, m.chip_units()).mray_per_s_chip
}

/// Chip s/Gray of `rays` in `cycles` of one hardware thread.
pub(crate) fn chip_sgray(m: &Sample, cycles: u64, rays: u64) -> f64 {
    sim::PerRay::of(cycles, 0, rays, m.m.clock_ghz, m.chip_units()).s_per_gray_chip
}

/// The machine and tile sample of a reproduce run.
#[derive(Clone)]
pub(crate) struct Sample {
    pub(crate) m: sim::MachineConfig,
    pub(crate) fl: isa::FlavourId,
    pub(crate) ntiles: u32,
    /// Rounds of tiles (one per core) functionally warmed before each sampled round.
    pub(crate) warm: u32,
    pub(crate) bounces: u32,
    pub(crate) size: u32,
    pub(crate) spp: u32,
    /// 0: `ntiles` independent seeded tiles; k > 0: `ntiles` seeded anchor
    /// pixels, each covered by the k x k aligned tiles around it (so sweeps
    /// over the tile size look at the same parts of the image).
    pub(crate) block: u32,
    /// The run's progress bar: a unit per stream recorded or warmed.
    pub(crate) progress: repro::progress::Progress,
    /// Hardware threads used per core (out-of-order machines; SMT).
    pub(crate) threads: u32,
}

/// Threads per core of the DRS reports unless `--threads-per-core` says
/// otherwise: every hardware thread, as the paper's renderer (Embree's
/// example path tracer, one render thread per logical CPU) ran on the
/// i7-4750HQ's 8 (papers/drs/README.md, "Threads").
pub(crate) fn default_threads(m: &sim::MachineConfig) -> u32 {
    m.core.threads
}

impl Sample {
    /// Units a frame round places at once: every hardware thread of every
    /// core (out-of-order), the cores (in-order, whose threads share a
    /// core's time).
    pub(crate) fn round_slots(&self) -> usize {
        self.chip_units() as usize
    }
    /// What a unit's own cycles are multiplied by for the chip's rate.
    pub(crate) fn chip_units(&self) -> u32 {
        self.m.cores * self.threads
    }
    /// A fresh session of the machine with the sample's threads per core.
    pub(crate) fn session(&self) -> AppResult<sim::Session> {
        if self.m.core.kind == sim::CoreKind::OutOfOrder {
            sim::Session::with_threads(&self.m, self.threads as usize).map_err(AppError)
        } else {
            Ok(sim::Session::new(&self.m))
        }
    }
    /// "4 cores x 2 threads" for notes and the sample's design.
    pub(crate) fn layout(&self) -> String {
        format!("{} cores x {} thread(s)", self.m.cores, self.threads)
    }
}

pub(crate) fn sample(a: &ReproduceArgs) -> AppResult<Sample> {
    let m = a.machine.load()?;
    let fl = m.flavour();
    if !Kernel::DrsBvh4.supports(fl.lanes()) {
        return Err(AppError(format!(
            "--machine {}: {} needs a 4, 8, 16 or 32-lane ISA, {fl} has {} lanes",
            m.name,
            a.name,
            fl.lanes()
        )));
    }
    let (mut ntiles, bounces, size, mut spp) = if a.quick {
        (2, 1, 16, 16)
    } else {
        (4, 2, 16, 16)
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
    let threads = match (m.core.kind, a.threads_per_core) {
        (sim::CoreKind::InOrder, Some(_)) => {
            return Err(AppError(format!(
                "--threads-per-core: {} is an in-order machine; its hardware threads share a core's time and every run uses them",
                m.name
            )))
        }
        (sim::CoreKind::InOrder, None) => 1,
        (_, Some(n)) if n == 0 || n > m.core.threads => {
            return Err(AppError(format!(
                "--threads-per-core: {n} is not 1 to {} ({} has {} hardware thread(s) per core, core.threads)",
                m.core.threads, m.name, m.core.threads
            )))
        }
        (_, Some(n)) => n,
        (_, None) => default_threads(&m),
    };
    Ok(Sample {
        threads,
        m,
        fl,
        ntiles,
        warm: 1,
        bounces,
        size,
        spp,
        block: 0,
        progress: a.progress.clone(),
    })
}

/// A scene stand-in and the DRS kernels' BVHs ([`drs_kernels::BVH`]).
pub(crate) fn load(scene_name: &str) -> AppResult<Loaded> {
    Loaded::load(scene_name, &drs_kernels::BVH).map_err(AppError)
}

/// Scenes in order, loaded one ahead: taking a scene starts loading the
/// next on a host thread of its own while the current one is measured
/// (loading a paper-size scene is mostly reading cached files and first
/// touches of memory, seconds in which the measuring threads would
/// otherwise wait).
pub(crate) struct LoadAhead {
    names: std::vec::IntoIter<&'static str>,
    next: Option<std::thread::JoinHandle<AppResult<Loaded>>>,
}

impl LoadAhead {
    /// The scenes `names`, the first loading from now.
    pub(crate) fn over(names: impl IntoIterator<Item = &'static str>) -> LoadAhead {
        let mut names = names.into_iter().collect::<Vec<_>>().into_iter();
        let next = names.next().map(load_on_a_thread);
        LoadAhead { names, next }
    }
}

impl Iterator for LoadAhead {
    type Item = AppResult<Loaded>;
    fn next(&mut self) -> Option<AppResult<Loaded>> {
        let h = self.next.take()?;
        let ld = h.join().unwrap_or_else(|e| std::panic::resume_unwind(e));
        self.next = self.names.next().map(load_on_a_thread);
        Some(ld)
    }
}

fn load_on_a_thread(name: &'static str) -> std::thread::JoinHandle<AppResult<Loaded>> {
    std::thread::spawn(move || load(name))
}

/// Every kernel over the same sampled streams of one loaded scene: each
/// method renders the sampled parts of one frame in render order on all the
/// machine's cores ([`frame_plan`]), its scene laid out once (in `shared`,
/// which every run over the same scene geometry may share: a layout does
/// not depend on the camera or the sample) and the machine's state carried
/// from unit to unit.
pub(crate) fn measure_loaded(
    a: &ReproduceArgs,
    smp: &Sample,
    (ld, shared): (&Loaded, &SharedLayouts),
    scene_name: &str,
    kernels: &[Kernel],
    ops_total: &mut u64,
) -> AppResult<Vec<Acc>> {
    let (scene, b2) = (&ld.scene, &ld.b2);
    let refi = Reference::with_bvh(&scene.mesh, b2);
    let plan = frame_plan(a, smp, ld, &refi);
    let streams = trace_streams(ld, &plan, smp, a.seed);
    let streams = with_expected(&refi, streams);
    let units: usize = plan
        .iter()
        .flat_map(|r| &r.tiles)
        .map(|t| streams[&(t.x, t.y)].len())
        .sum();
    smp.progress.add_units((units * kernels.len()) as u64);
    // Methods are independent runs: one host thread each, results in order,
    // the scene's two layouts shared. The layouts are made first (both at
    // once where the methods read both trees), so no method's thread waits
    // on another's.
    let lay = |k: Option<&Kernel>| {
        if let Some(&k) = k {
            let none =
                scene::workload::RayStream::from_rays(StreamKind::Primary, vec![], vec![], vec![]);
            let mut r = Run::new(k, &ld.scene, &ld.b2, &ld.b4, none);
            r.shared = Some(shared);
            let _ = r.lay_out(&mut isa::Native::<isa::Sse4, 4>::new());
        }
    };
    rayon::join(
        || lay(kernels.iter().find(|k| k.reads_bvh2())),
        || lay(kernels.iter().find(|k| !k.reads_bvh2())),
    );
    let runs = kernels
        .par_iter()
        .map(|&k| measure_kernel(smp, (ld, shared), &refi, (&plan, &streams), k, scene_name))
        .collect::<AppResult<Vec<(Acc, u64)>>>()?;
    *ops_total += runs.iter().map(|r| r.1).sum::<u64>();
    Ok(runs.into_iter().map(|r| r.0).collect())
}

/// The ray streams of each tile (by column, row), in the order they are traced.
pub(crate) type Streams = BTreeMap<(u32, u32), Vec<scene::workload::RayStream>>;

/// The ray streams of each tile with the reference's answers for their rays.
pub(crate) type Checked = BTreeMap<(u32, u32), Vec<(scene::workload::RayStream, Expected)>>;

/// `streams` with the reference's answers, asked once for every method and
/// in parallel here, outside the methods' tasks (a thread waiting inside
/// one may steal another method's task, and with it hold a second
/// method's traces).
pub(crate) fn with_expected(refi: &Reference, streams: Streams) -> Checked {
    streams
        .into_iter()
        .map(|(k, v)| {
            let v = v
                .into_iter()
                .map(|s| {
                    let e = Expected::of(refi, &s);
                    (s, e)
                })
                .collect();
            (k, v)
        })
        .collect()
}

/// The streams of every tile `plan` touches, path-traced once for all methods.
pub(crate) fn trace_streams(ld: &Loaded, plan: &[Round], smp: &Sample, seed: u64) -> Streams {
    let mut tiles: Vec<Tile> = plan.iter().flat_map(|r| r.tiles.iter().copied()).collect();
    tiles.sort_by_key(|t| (t.y, t.x));
    tiles.dedup_by_key(|t| (t.x, t.y));
    tiles
        .par_iter()
        .map(|&tile| {
            let st = path_trace_tile(&ld.scene, &ld.b2, tile, smp.spp, smp.bounces, seed)
                .into_iter()
                .filter(|s| !s.is_empty())
                .collect();
            ((tile.x, tile.y), st)
        })
        .collect()
}

/// One round of a frame plan: up to one tile per core, started together.
pub(crate) struct Round {
    /// The tiles, core k taking `tiles[k]`.
    pub(crate) tiles: Vec<Tile>,
    /// Timed (a sampled unit) or functionally warmed (the tiles before it).
    pub(crate) timed: bool,
    /// Sampled group (for the confidence interval): the index of the tile
    /// sample each timed tile belongs to.
    pub(crate) group: usize,
}

/// The frame's tiles in render order (rows of tiles, left to right), the
/// machine's cores taking them in turn as the paper's threads did; the
/// sample: `ntiles` groups (seeded), each timed in full detail after
/// functional warming of its own tiles (the previous frame's pass over them:
/// the `recall` design of `rtsim fidelity --frame`) and then of the `warm`
/// rounds of tiles rendered just before it.
pub(crate) fn frame_plan(
    a: &ReproduceArgs,
    smp: &Sample,
    ld: &Loaded,
    refi: &Reference,
) -> Vec<Round> {
    let cam = &ld.scene.config.camera;
    let size = smp.size;
    let (tw, th) = (cam.width / size, cam.height / size);
    let cores = smp.round_slots().max(1);
    let n_tiles = (tw * th) as usize;
    let tile_at = |i: usize| Tile {
        x: (i % tw as usize) as u32,
        y: (i / tw as usize) as u32,
        size,
    };
    let mut plan = Vec::new();
    for g in 0..smp.ntiles as usize {
        let r = mix(a.seed ^ mix(g as u64 + 1));
        let timed: Vec<usize> = if smp.block == 0 {
            // A round of `cores` consecutive tiles at a seeded place.
            let first = (r % n_tiles as u64) as usize / cores * cores;
            (first..(first + cores).min(n_tiles)).collect()
        } else {
            block_tiles(smp, cam, refi, r, (tw, th))
                .into_iter()
                .map(|t| (t.y * tw + t.x) as usize)
                .collect()
        };
        // The timed tiles as the previous frame left them (their own rays,
        // functionally), then the rounds rendered just before them.
        for chunk in timed.chunks(cores) {
            plan.push(Round {
                tiles: chunk.iter().map(|&i| tile_at(i)).collect(),
                timed: false,
                group: g,
            });
        }
        let first = timed[0];
        let warm_from = first.saturating_sub(smp.warm as usize * cores);
        for chunk in (warm_from..first).collect::<Vec<_>>().chunks(cores) {
            plan.push(Round {
                tiles: chunk.iter().map(|&i| tile_at(i)).collect(),
                timed: false,
                group: g,
            });
        }
        for chunk in timed.chunks(cores) {
            plan.push(Round {
                tiles: chunk.iter().map(|&i| tile_at(i)).collect(),
                timed: true,
                group: g,
            });
        }
    }
    plan
}

/// The k x k aligned tiles around an anchor pixel on the geometry: the
/// first of up to 64 seeded candidates whose centre ray hits (so sweeps over
/// the tile size look at the same parts of the image).
fn block_tiles(
    smp: &Sample,
    cam: &scene::scene::Camera,
    refi: &Reference,
    r: u64,
    (tw, th): (u32, u32),
) -> Vec<Tile> {
    let (k, size) = (smp.block, smp.size);
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
}

/// Where a recorded stream belongs: its round, the core, its tile and the
/// reference's answers for its rays.
struct Slot<'a> {
    round: usize,
    core: usize,
    tile: Tile,
    /// The reference's answers for the stream's rays.
    want: &'a Expected,
}

/// Units in order, a step per round and stream index (the cores that have
/// that stream, started together), with each unit's slot.
fn frame_steps<'a>(
    plan: &[Round],
    streams: &'a Checked,
) -> (Vec<isa::Step<scene::workload::RayStream>>, Vec<Slot<'a>>) {
    let (mut steps, mut slots) = (Vec::new(), Vec::new());
    for (ri, round) in plan.iter().enumerate() {
        let of = |c: usize| &streams[&(round.tiles[c].x, round.tiles[c].y)];
        let most = (0..round.tiles.len())
            .map(|c| of(c).len())
            .max()
            .unwrap_or(0);
        let detail = if round.timed {
            isa::Detail::Timed
        } else {
            isa::Detail::Warmed
        };
        for j in 0..most {
            let mut step = isa::Step {
                units: Vec::new(),
                detail,
            };
            for c in (0..round.tiles.len()).filter(|&c| j < of(c).len()) {
                slots.push(Slot {
                    round: ri,
                    core: c,
                    tile: round.tiles[c],
                    want: &of(c)[j].1,
                });
                step.units.push(isa::Placed {
                    thread: c,
                    unit: of(c)[j].0.clone(),
                });
            }
            steps.push(step);
        }
    }
    (steps, slots)
}

/// Keep the kinds of `t`'s memory regions (by id; a later unit's regions
/// replace an earlier one's of the same id).
fn note_kinds(kinds: &mut Vec<isa::MemKind>, t: &isa::Trace) {
    for r in &t.regions {
        let i = r.id.0 as usize;
        if kinds.len() <= i {
            kinds.resize(i + 1, isa::MemKind::Other);
        }
        kinds[i] = r.kind;
    }
}

/// The stream kind's name in the report.
fn kind_name(k: StreamKind) -> &'static str {
    match k {
        StreamKind::Primary => "primary",
        StreamKind::Bounce(_) => "bounce",
        StreamKind::Shadow(_) => "shadow",
    }
}

/// One method's running sums over a frame plan.
struct Measuring {
    session: sim::Session,
    /// The kind of each memory region by id, as the traces so far declare them.
    kinds: Vec<isa::MemKind>,
    ac: Acc,
    ops_total: u64,
    /// Per (sampled group, core): the observations of the confidence interval.
    group_sums: BTreeMap<(usize, usize), (u64, u64)>,
    /// Units handed over so far (the next unit's slot).
    next: usize,
}

/// One method over a frame plan on a session of the machine: warmed units
/// run natively and warm the session one by one; a timed step's units are
/// recorded on their own host threads and timed as their ops arrive.
pub(crate) fn measure_kernel(
    smp: &Sample,
    (ld, shared): (&Loaded, &drs_kernels::methods::SharedLayouts),
    refi: &Reference,
    (plan, streams): (&[Round], &Checked),
    k: Kernel,
    scene_name: &str,
) -> AppResult<(Acc, u64)> {
    let (scene, b2, b4) = (&ld.scene, &ld.b2, &ld.b4);
    let (steps, slots) = frame_steps(plan, streams);
    let mut prog = Run::new(
        k,
        scene,
        b2,
        b4,
        scene::workload::RayStream::from_rays(StreamKind::Primary, vec![], vec![], vec![]),
    );
    prog.packet_tile = Some((smp.size, smp.spp));
    prog.shared = Some(shared);
    let st = std::cell::RefCell::new(Measuring {
        session: smp.session()?,
        kinds: Vec::new(),
        ac: Acc::default(),
        ops_total: 0,
        group_sums: BTreeMap::new(),
        next: 0,
    });
    let check =
        |m: &mut Measuring, slot: &Slot, u: &scene::workload::RayStream, hits: &[scene::Hit]| {
            smp.progress.done(1);
            let (x, y) = (slot.tile.x, slot.tile.y);
            let label = format!("{scene_name} tile ({x}, {y}) {:?} {}", u.kind, k.name());
            let test = F32Test::MollerTrumbore;
            m.ac.bad += mismatches_expected(test, &label, refi, u, slot.want, hits) as u64;
        };
    isa::run_steps(
        &prog,
        smp.fl,
        k.name(),
        steps,
        |u, t, (hits, _)| {
            let m = &mut *st.borrow_mut();
            let slot = &slots[m.next];
            m.next += 1;
            check(m, slot, &u.unit, &hits);
            m.ops_total += t.ops.len() as u64;
            note_kinds(&mut m.kinds, &t);
            m.session.warm(&[(slot.core, &t)]).map_err(AppError)?;
            isa::trace::recycle(t);
            Ok(())
        },
        |units, rxs| {
            let m = &mut *st.borrow_mut();
            let mut chunks: Vec<_> = rxs.iter_mut().map(|rx| rx.iter().peekable()).collect();
            for c in &mut chunks {
                if let Some(t) = c.peek() {
                    note_kinds(&mut m.kinds, t);
                }
            }
            let mut step: Vec<(usize, sim::session::Chunks<'_>)> = units
                .iter()
                .zip(&mut chunks)
                .map(|(u, c)| (u.thread, c as sim::session::Chunks<'_>))
                .collect();
            let timed = m.session.timed_streams(&mut step).map_err(AppError)?;
            drop(step);
            drop(chunks);
            Ok(timed)
        },
        |units, outs, (s, own)| {
            let m = &mut *st.borrow_mut();
            m.ac.ops += s.ops;
            m.ac.core_cycles += s.region_cycles[Region::CoreLoop as usize];
            m.ac.core_ops += s.region_ops[Region::CoreLoop as usize];
            m.ac.dram += s.dram_read + s.dram_written;
            for (id, &bytes) in s.dram_read_by_region.iter().enumerate() {
                let kind = m.kinds.get(id).copied().unwrap_or_default();
                *m.ac.dram_by.entry(kind.name()).or_default() += bytes;
            }
            *m.ac.dram_by.entry("written-back").or_default() += s.dram_written;
            for (id, &bytes) in s.dram_prefetched_by_region.iter().enumerate() {
                let kind = m.kinds.get(id).copied().unwrap_or_default();
                *m.ac.prefetched_by.entry(kind.name()).or_default() += bytes;
            }
            let cores = smp.m.cores.max(1) as usize;
            let mut busy = vec![0u64; cores];
            for (u, t) in units.iter().zip(own.iter()) {
                let c = u.thread % cores;
                busy[c] = busy[c].max(t.cycles);
            }
            m.ac.core_time += busy.iter().sum::<u64>();
            for ((u, (hits, tests)), tally) in units.iter().zip(outs).zip(own) {
                let slot = &slots[m.next];
                m.next += 1;
                check(m, slot, &u.unit, &hits);
                m.ops_total += tally.records;
                let c = tally.cycles;
                m.ac.core_tests += tests.core_loop;
                m.ac.node_tests += tests.node_tests();
                m.ac.leaf_tests += tests.leaf;
                let rays = u.unit.len() as u64;
                let work = Work {
                    rays,
                    instructions: tally.instructions,
                    core_instructions: tally.region_instructions[Region::CoreLoop as usize],
                    node_tests: tests.node_tests(),
                    core_tests: tests.core_loop,
                };
                let kind = kind_name(u.unit.kind);
                m.ac.kind_work.entry(kind).or_default().add(work);
                m.ac.rays += rays;
                m.ac.cycles += c;
                let e = m.ac.kinds.entry(kind).or_default();
                e.0 += rays;
                e.1 += c;
                let g = m
                    .group_sums
                    .entry((plan[slot.round].group, slot.core))
                    .or_default();
                g.0 += rays;
                g.1 += c;
            }
            Ok::<(), AppError>(())
        },
    )?;
    let mut m = st.into_inner();
    m.ac.tiles = m.group_sums.into_values().collect();
    Ok((m.ac, m.ops_total))
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
    sample.insert("rounds_per_scene".into(), serde_json::json!(smp.ntiles));
    sample.insert(
        "design".into(),
        serde_json::json!(format!(
            "each scene camera's whole frame in render order, one {}x{} tile per hardware thread on {}; {} seeded round(s) of tiles timed in full detail, each after functional warming (caches, prefetchers, predictors) of its own tiles (as the previous frame left them) and then of the {} round(s) rendered before it; state carried from unit to unit, scene laid out once per method (rtsim fidelity --frame measures this design, 'recall', against full detail)",
            smp.size, smp.size, smp.layout(), smp.ntiles, smp.warm
        )),
    );
    sample.insert("warm_rounds".into(), serde_json::json!(smp.warm));
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
            "{ci_of} (each timed tile one observation), paired where methods are compared, Student t"
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
