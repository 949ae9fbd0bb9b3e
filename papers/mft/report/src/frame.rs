//! What every MFT report shares: the machine, a scene made ready (light,
//! BVHs, frusta sets), cycles sampled over batches of sets, the report frame.

use isa::UnitProgram;
use mft_kernels::{Frusta, FrustaRun, MftStats, PacketPrimaryRun, Shrink};
use rayon::prelude::*;
use repro::progress::Progress;
use repro::sampling::{mix, systematic_ratio_ci};
use repro::{AppError, AppResult, Report, ReproduceArgs, Row};
use scene::bvh::{BuildConfig, Bvh2};
use scene::reference::Reference;
use scene::scene::{Light, Scene};
use scene::workload::{soft_shadow_groups, SampleSplit};
use scene::Hit;
use std::collections::BTreeMap;
use std::time::Instant;

/// Simulated cycles of `sets` on one core: the frame's sets in render
/// order, `groups` seeded runs of `per` consecutive sets timed (see
/// [`sample`]); (cycles scaled to all sets, 95% CI half-width, ops simulated).
pub(crate) fn sampled_cycles<P: UnitProgram<Unit = Frusta, Out = (Vec<scene::Hit>, MftStats)>>(
    m: &sim::MachineConfig,
    sets: &[Frusta],
    groups: usize,
    per: usize,
    (seed, progress): (u64, &Progress),
    prog: impl Fn(Vec<Frusta>) -> P,
) -> AppResult<(f64, Option<f64>, u64)> {
    let s = sample(m, sets, groups, per, (seed, progress), prog)?;
    Ok((s.cycles, s.ci, s.ops))
}

/// What [`sample`] measured.
pub(crate) struct Sample {
    /// Cycles scaled to all sets.
    pub cycles: f64,
    /// Their 95% CI half-width.
    pub ci: Option<f64>,
    /// Ops simulated: every op of the timed sets, the memory and branch ops of the warmed ones.
    pub ops: u64,
    /// The timed sets' counts.
    pub stats: MftStats,
    /// Simulated instructions and cycles per region, summed over the timed groups.
    pub regions: sim::Stats,
    /// Each group's cycles scaled to all sets (one estimate per group; the
    /// methods of a report draw the same groups, so these pair).
    pub estimates: Vec<f64>,
}

impl Sample {
    /// (instructions, cycles) of `region` per `n` tests.
    pub fn per(&self, region: isa::Region, n: u64) -> (f64, f64) {
        let r = region as usize;
        let n = n.max(1) as f64;
        (
            self.regions.region_ops[r] as f64 / n,
            self.regions.region_cycles[r] as f64 / n,
        )
    }
}

/// Sets functionally warmed before each timed group besides its own: one
/// per hardware thread (the round rendered just before it).
const WARM_ROUNDS: usize = 1;

/// The sample design the MFT reports state (see [`sample`]).
pub(crate) fn design(m: &sim::MachineConfig, groups: usize, per_p: usize, per_s: usize) -> String {
    format!(
        "the frame's frusta sets in render order (primary: rows of 16x16-pixel sets; soft shadows: rows of 4x4-pixel sets with a hit) taken by the {} hardware threads of one {} core as they free up, its caches, prefetcher and predictors carried from set to set; {groups} runs of {per_p} primary / {per_s} shadow consecutive sets per scene, one at a seeded place in each of as many equal strata of the frame (a stratified sample), timed in full detail, each after functional warming of its own sets (as the previous frame left them) and of the {} set(s) rendered just before it; the same runs for every method; 95% CI over the runs (ratio estimator, variance from successive differences of neighbouring strata, Student t), paired where methods are compared",
        m.core.threads, m.name, WARM_ROUNDS * m.core.threads as usize
    )
}

/// What a recorded unit of [`sample`] is for.
#[derive(Clone, Copy, PartialEq)]
enum Phase {
    /// A timed set, first warmed (the previous frame's pass over it).
    Recall,
    /// A set rendered before the group, warmed.
    Before,
}

/// [`sampled_cycles`], with the sample's counts and per-region statistics.
/// The design ([`design`]): group g times the `per` consecutive sets from a
/// seeded place in the g-th of `groups` equal strata of the frame on a session of the machine (the hardware
/// threads take them as they free up: [`sim::Session::timed_queue`]), after
/// warming them and the round of sets before them; state carries over from
/// group to group.
pub(crate) fn sample<P: UnitProgram<Unit = Frusta, Out = (Vec<scene::Hit>, MftStats)>>(
    m: &sim::MachineConfig,
    sets: &[Frusta],
    groups: usize,
    per: usize,
    (seed, progress): (u64, &Progress),
    prog: impl Fn(Vec<Frusta>) -> P,
) -> AppResult<Sample> {
    let mut out = Sample {
        cycles: 0.0,
        ci: None,
        ops: 0,
        stats: MftStats::default(),
        regions: sim::Stats::default(),
        estimates: Vec::new(),
    };
    if sets.is_empty() {
        return Ok(out);
    }
    let threads = m.core.threads.max(1) as usize;
    let per = per.clamp(1, sets.len());
    // Units in order: per group its sets (recalled), then the sets before it.
    let mut plan: Vec<(Phase, bool)> = Vec::new();
    let mut units = Vec::new();
    // Stratified: group g at a seeded place in the g-th of `groups` equal
    // strata of the frame (one offset for all would align with the image's
    // rows when the stride is a row of sets: every run in one column).
    let stride = sets.len() / groups.max(1);
    for g in 0..groups {
        let r = mix(seed ^ mix(g as u64 + 1));
        let offset = (r % (stride.saturating_sub(per) + 1) as u64) as usize;
        let first = (offset + g * stride).min(sets.len() - per);
        let before = first.saturating_sub(WARM_ROUNDS * threads)..first;
        let n = per + before.len();
        for (j, i) in (first..first + per).chain(before).enumerate() {
            let phase = if j < per {
                Phase::Recall
            } else {
                Phase::Before
            };
            plan.push((phase, j + 1 == n));
            // Timed sets are recorded; the sets before them run natively,
            // their memory accesses and branches logged for warming.
            let detail = match phase {
                Phase::Recall => isa::Detail::Timed,
                Phase::Before => isa::Detail::Warmed,
            };
            let unit = isa::Placed {
                thread: j % threads,
                unit: sets[i].clone(),
            };
            units.push((unit, detail));
        }
    }
    progress.add_units(units.len() as u64);
    let mut session = sim::Session::new(m);
    let mut timed: Vec<isa::Trace> = Vec::new();
    let mut pairs = Vec::new();
    let mut next = 0usize;
    let p = prog(Vec::new());
    isa::run_units(&p, m.flavour(), "mft", units, |u, _, t, (_, st)| {
        let (phase, last) = plan[next];
        next += 1;
        progress.done(1);
        out.ops += t.ops.len() as u64;
        session.warm(&[(u.thread, &t)]).map_err(AppError)?;
        if phase == Phase::Recall {
            out.stats.add(st);
            timed.push(t);
        } else {
            isa::trace::recycle(t);
        }
        if last {
            let queue: Vec<&isa::Trace> = timed.iter().collect();
            let s = session.timed_queue(&queue).map_err(AppError)?;
            out.regions.merge(&s);
            out.estimates
                .push(s.cycles as f64 / per as f64 * sets.len() as f64);
            pairs.push((s.cycles as f64, per as f64));
            timed.drain(..).for_each(isa::trace::recycle);
        }
        Ok::<(), AppError>(())
    })?;
    let (c, n) = pairs
        .iter()
        .fold((0.0, 0.0), |(a, b), &(x, y)| (a + x, b + y));
    let scale = sets.len() as f64;
    out.cycles = c / n * scale;
    out.ci = systematic_ratio_ci(&pairs).map(|h| h * scale);
    Ok(out)
}

/// The sets counted of a frame's sets in render order, by band (runs of
/// sets whose first pixel row falls in the same 16 rows): every
/// `every`-th set (1: all), so every part of the image is in the sample.
pub(crate) fn bands(sets: &[Frusta], every: u32) -> Vec<Vec<usize>> {
    let band = |i: usize| sets[i].pixel.1 / 16;
    let mut out: Vec<Vec<usize>> = Vec::new();
    for i in (0..sets.len()).step_by(every.max(1) as usize) {
        match out.last_mut() {
            Some(b) if band(b[0]) == band(i) => b.push(i),
            _ => out.push(vec![i]),
        }
    }
    out
}

/// A method's counts over the counted bands of a frame (natively, band by
/// band in parallel): the counted sets' hits in order, the counted sets,
/// and the counts scaled to all `total` sets with their 95% CI half-widths
/// over the bands (tris accessed, after culling, AABB tests, isec tests;
/// none when every band was counted: the counts are exact).
pub(crate) struct Counted {
    pub(crate) out: Vec<Hit>,
    pub(crate) sets: Vec<Frusta>,
    pub(crate) stats: MftStats,
    pub(crate) ci: Option<[f64; 4]>,
}

/// [`Counted`] of `prog` over the sets of `bands` ([`bands`]).
pub(crate) fn count_native<P: isa::Program<Out = (Vec<Hit>, MftStats)>>(
    fl: isa::FlavourId,
    sets: &[Frusta],
    bands: &[Vec<usize>],
    prog: impl Fn(Vec<Frusta>) -> P + Sync,
) -> Counted {
    let of = |b: &Vec<usize>| b.iter().map(|&i| sets[i].clone()).collect::<Vec<Frusta>>();
    let per: Vec<(Vec<Hit>, MftStats)> = bands
        .par_iter()
        .map(|b| isa::run_native(&prog(of(b)), fl))
        .collect();
    let counted: Vec<Frusta> = bands.iter().flat_map(of).collect();
    let n = counted.len();
    let mut c = Counted {
        out: Vec::with_capacity(n * 256),
        sets: counted,
        stats: MftStats::default(),
        ci: None,
    };
    for (o, st) in &per {
        c.out.extend_from_slice(o);
        c.stats.add(*st);
    }
    if n == sets.len() {
        return c;
    }
    let scale = sets.len() as f64 / n.max(1) as f64;
    let of = |f: fn(&MftStats) -> u64| -> (u64, Option<f64>) {
        let pairs: Vec<(f64, f64)> = per
            .iter()
            .zip(bands)
            .map(|((_, st), b)| (f(st) as f64, b.len() as f64))
            .collect();
        let ci = systematic_ratio_ci(&pairs).map(|h| h * sets.len() as f64);
        ((f(&c.stats) as f64 * scale).round() as u64, ci)
    };
    let (tris, ct) = of(|s| s.tris_accessed);
    let (after, ca) = of(|s| s.tris_after_culling);
    let (aabb, cb) = of(|s| s.aabb_tests);
    let (isec, ci) = of(|s| s.isec_tests);
    let (leaf, _) = of(|s| s.leaf_box_tests);
    let (shrinks, _) = of(|s| s.shrinks);
    c.stats = MftStats {
        aabb_tests: aabb,
        tris_accessed: tris,
        tris_after_culling: after,
        isec_tests: isec,
        shrinks,
        leaf_box_tests: leaf,
    };
    c.ci = Some([ct, ca, cb, ci].map(|x| x.unwrap_or(0.0)));
    c
}

/// Share of active shadow frusta whose direction interval holds zero on
/// some axis: they lose that axis's slab culling and rely on the
/// zero-interval fix.
pub(crate) fn zero_interval_share(shadow: &[Frusta]) -> f64 {
    let (mut lanes, mut zero) = (0u64, 0u64);
    for f in shadow {
        let rec = f.record();
        for n in (0..16).filter(|&n| f.active & (1 << n) != 0) {
            lanes += 1;
            let holds = (0..3).any(|a| {
                rec[(mft_kernels::row::DIR_LO + a) * 16 + n] <= 0.0
                    && rec[(mft_kernels::row::DIR_HI + a) * 16 + n] >= 0.0
            });
            zero += u64::from(holds);
        }
    }
    zero as f64 / lanes.max(1) as f64
}

/// A quad light centred at `centre` with edges `e1` and `e2` scaled by `s`:
/// (corner, edge 1, edge 2) in f32.
pub(crate) fn light_about(centre: [f64; 3], e1: [f32; 3], e2: [f32; 3], s: f64) -> [[f32; 3]; 3] {
    let e1s = e1.map(|x| (f64::from(x) * s) as f32);
    let e2s = e2.map(|x| (f64::from(x) * s) as f32);
    let cs = [0, 1, 2].map(|i| (centre[i] - 0.5 * f64::from(e1s[i] + e2s[i])) as f32);
    [cs, e1s, e2s]
}

/// Share of frusta sets whose active frusta keep one sign per axis (no
/// direction interval holding zero): the sets the paper's slab test serves
/// (`mft_kernels::SlabTest::Paper`); the rest take the sign-free test.
pub(crate) fn one_sign_share(sets: &[Frusta]) -> f64 {
    let one = |f: &Frusta| {
        let rec = f.record();
        let lanes: Vec<usize> = (0..16).filter(|&n| f.active & (1 << n) != 0).collect();
        (0..3).all(|a| {
            let lo = |n: usize| rec[(mft_kernels::row::DIR_LO + a) * 16 + n];
            let hi = |n: usize| rec[(mft_kernels::row::DIR_HI + a) * 16 + n];
            lanes.iter().all(|&n| lo(n) > 0.0) || lanes.iter().all(|&n| hi(n) < 0.0)
        })
    };
    let n = sets.iter().filter(|f| one(f)).count();
    n as f64 / sets.len().max(1) as f64
}

/// The machine of a 16-lane MFT report (the report's own, Larrabee, unless
/// `--machine` names another): an error unless it has 16 lanes.
pub(crate) fn lrb_machine(a: &ReproduceArgs, name: &str) -> AppResult<sim::MachineConfig> {
    let m = a.machine.load()?;
    if m.flavour().lanes() == 16 {
        return Ok(m);
    }
    Err(AppError(format!(
        "--machine {}: {name} traces 16 frusta on 16 lanes, {} has {}",
        m.name,
        m.flavour(),
        m.flavour().lanes()
    )))
}

/// The frame every MFT report shares: name, machine, resolution, seed and
/// the start time; [`Frame::report`] fills in the rest.
pub(crate) struct Frame<'a> {
    name: &'a str,
    m: &'a sim::MachineConfig,
    res: u32,
    seed: u64,
    start: Instant,
}

impl<'a> Frame<'a> {
    pub(crate) fn new(
        name: &'a str,
        m: &'a sim::MachineConfig,
        res: u32,
        seed: u64,
        start: Instant,
    ) -> Frame<'a> {
        Frame {
            name,
            m,
            res,
            seed,
            start,
        }
    }

    /// The report: `sample` adds to the resolution and seed.
    pub(crate) fn report(
        &self,
        sample: &[(&str, String)],
        input: String,
        ops_simulated: u64,
        rows: Vec<Row>,
        notes: Vec<String>,
    ) -> Report {
        let mut s = BTreeMap::new();
        let res = self.res;
        s.insert(
            "resolution".into(),
            serde_json::json!(format!("{res}x{res}")),
        );
        for (k, v) in sample {
            s.insert((*k).to_string(), serde_json::json!(v));
        }
        s.insert("seed".into(), serde_json::json!(self.seed));
        Report {
            report: self.name.into(),
            machine: Some(self.m.name.clone()),
            isa: Some(self.m.flavour().name().into()),
            fidelity: "full".into(),
            sample: Some(s),
            input: Some(input),
            ops_simulated,
            host_seconds: self.start.elapsed().as_secs_f64(),
            rows,
            notes,
        }
    }
}

/// One scene made ready for the MFT reports: at `res` x `res`, its quad
/// light, the shallow (MFT) and deep (packet) BVHs, the primary frusta sets
/// and the soft-shadow sets with a hit.
#[derive(Clone)]
pub(crate) struct Prepared {
    pub(crate) scene: Scene,
    pub(crate) light: [[f32; 3]; 3],
    pub(crate) shallow: Bvh2,
    deep: Bvh2,
    pub(crate) primary: Vec<Frusta>,
    pub(crate) shadow: Vec<Frusta>,
    /// How each pixel's 16 light samples are drawn (the paper's nets by default).
    pub(crate) split: SampleSplit,
}

impl Prepared {
    pub(crate) fn new(
        scene_name: &str,
        res: u32,
        report: &str,
        with_shadow: bool,
    ) -> AppResult<Prepared> {
        let mut scene = Scene::load(scene_name).map_err(|e| AppError(e.0))?;
        scene.config.camera.width = res;
        scene.config.camera.height = res;
        let cam = scene.config.camera.clone();
        let Some(Light::Quad(c, e1, e2, _)) = scene.config.lights.first().cloned() else {
            return Err(AppError(format!(
                "{scene_name}: {report} needs a quad light for soft shadows"
            )));
        };
        // A shallow BVH for the frusta, a deep one for packets (the paper's
        // setup; it gives no leaf sizes): see `mft_kernels::SHALLOW_BVH`.
        let build = |cfg| scene::bvh_cache::build(&scene.mesh, cfg).map(|(b, _)| b);
        let shallow = build(&mft_kernels::SHALLOW_BVH).map_err(AppError)?;
        let deep = build(&BuildConfig::default()).map_err(AppError)?;
        let primary: Vec<Frusta> = (0..res / 16)
            .flat_map(|by| (0..res / 16).map(move |bx| (bx, by)))
            .map(|(bx, by)| Frusta::primary(&cam, bx, by))
            .collect();
        let mut pr = Prepared {
            scene,
            light: [c, e1, e2],
            shallow,
            deep,
            primary,
            shadow: Vec::new(),
            split: SampleSplit::default(),
        };
        if with_shadow {
            pr.shadow = pr.shadow_frusta(SampleSplit::default());
        }
        Ok(pr)
    }

    /// The same scene with its soft-shadow sets drawn by `split`.
    pub(crate) fn with_split(&self, split: SampleSplit) -> Prepared {
        let mut pr = self.clone();
        pr.shadow = pr.shadow_frusta(split);
        pr.split = split;
        pr
    }

    /// The same scene under `light` (corner, edge 1, edge 2), its sets as
    /// they were: the shadow rays' samples come from the scene's light.
    pub(crate) fn with_light(&self, light: [[f32; 3]; 3]) -> Prepared {
        let mut pr = self.clone();
        pr.light = light;
        if let Some(Light::Quad(lc, l1, l2, _)) = pr.scene.config.lights.first_mut() {
            [*lc, *l1, *l2] = light;
        }
        pr
    }

    /// The same scene with its light's edges scaled by `s` about its
    /// centre, the soft-shadow sets drawn again.
    pub(crate) fn with_light_scaled(&self, s: f64) -> Prepared {
        let [c, e1, e2] = self.light;
        let centre = [0, 1, 2].map(|i| f64::from(c[i]) + 0.5 * f64::from(e1[i] + e2[i]));
        let mut pr = self.with_light(light_about(centre, e1, e2, s));
        pr.shadow = pr.shadow_frusta(pr.split);
        pr
    }

    /// The soft-shadow frusta sets with a hit over the image, in render
    /// order, each pixel's samples from `split`.
    fn shadow_frusta(&self, split: SampleSplit) -> Vec<Frusta> {
        let res = self.scene.config.camera.width;
        let refi = self.reference();
        let groups: Vec<(u32, u32)> = (0..res / 4)
            .flat_map(|gy| (0..res / 4).map(move |gx| (4 * gx, 4 * gy)))
            .collect();
        soft_shadow_groups(&self.scene, &refi, &groups, split)
            .iter()
            .map(|g| Frusta::shadow(g, self.light))
            .filter(|f| f.active != 0)
            .collect()
    }

    /// The front-faces-only reference (both kernels cull back faces).
    pub(crate) fn reference(&self) -> Reference<'_> {
        Reference::with_bvh(&self.scene.mesh, &self.shallow).front_faces_only()
    }

    /// MFT over `sets` on the shallow BVH.
    pub(crate) fn frusta(
        &self,
        sets: Vec<Frusta>,
        packets256: bool,
        shrink: Shrink,
    ) -> FrustaRun<'_> {
        FrustaRun {
            scene: &self.scene,
            bvh: &self.shallow,
            sets,
            cull_back: true,
            packets256,
            shrink,
            plane_noise: mft_kernels::PlaneNoise::Reject,
            slab: mft_kernels::SlabTest::Paper,
        }
    }

    /// 16-ray packets over `sets` on the deep BVH.
    pub(crate) fn packets(&self, sets: Vec<Frusta>) -> PacketPrimaryRun<'_> {
        PacketPrimaryRun {
            scene: &self.scene,
            bvh: &self.deep,
            sets,
            cull_back: true,
            leaves: mft_kernels::PacketLeaves::Indexed,
            plane_noise: mft_kernels::PlaneNoise::Reject,
            grouping: mft_kernels::PacketGrouping::PerSample,
        }
    }
}
