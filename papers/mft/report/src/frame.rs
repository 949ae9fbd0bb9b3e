//! What every MFT report shares: the machine, a scene made ready (light,
//! BVHs, frusta sets), cycles sampled over batches of sets, the report frame.

use isa::Program;
use mft_kernels::{Frusta, FrustaRun, MftStats, PacketPrimaryRun, Shrink};
use repro::sampling::{mix, ratio_ci};
use repro::{AppError, AppResult, Report, ReproduceArgs, Row};
use scene::bvh::{BuildConfig, Bvh2};
use scene::reference::Reference;
use scene::scene::{Light, Scene};
use scene::workload::soft_shadow_group;
use std::collections::BTreeMap;
use std::time::Instant;

/// Simulated cycles of `sets` on one core: `batches` seeded systematic
/// samples of `per` sets spread over the image, each split round-robin over
/// the core's hardware threads; (cycles scaled to all sets, 95% CI half-width, ops simulated).
pub(crate) fn sampled_cycles<P: Program<Out = (Vec<scene::Hit>, MftStats)>>(
    m: &sim::MachineConfig,
    sets: &[Frusta],
    batches: usize,
    per: usize,
    seed: u64,
    prog: impl Fn(Vec<Frusta>) -> P,
) -> AppResult<(f64, Option<f64>, u64)> {
    let s = sample(m, sets, batches, per, seed, prog)?;
    Ok((s.cycles, s.ci, s.ops))
}

/// What [`sample`] measured.
pub(crate) struct Sample {
    /// Cycles scaled to all sets.
    pub cycles: f64,
    /// Their 95% CI half-width.
    pub ci: Option<f64>,
    /// Ops simulated.
    pub ops: u64,
    /// The sampled sets' counts.
    pub stats: MftStats,
    /// Simulated instructions and cycles per region, summed over batches.
    pub regions: sim::Stats,
    /// Each batch's cycles scaled to all sets (one estimate per batch; the
    /// methods of a report draw the same batches, so these pair).
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

/// [`sampled_cycles`], with the sample's counts and per-region statistics.
pub(crate) fn sample<P: Program<Out = (Vec<scene::Hit>, MftStats)>>(
    m: &sim::MachineConfig,
    sets: &[Frusta],
    batches: usize,
    per: usize,
    seed: u64,
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
    let per = per.min(sets.len());
    let mut pairs = Vec::new();
    // Each batch: a systematic sample over the image (every stride-th set
    // from a seeded offset), so a batch is not one patch of sky or wall.
    let stride = sets.len() / per;
    for b in 0..batches {
        let first = (mix(seed ^ mix(b as u64 + 1)) % stride as u64) as usize;
        let batch: Vec<&Frusta> = (0..per).map(|j| &sets[first + j * stride]).collect();
        let traces: Vec<isa::Trace> = (0..threads)
            .map(|t| {
                let mine: Vec<Frusta> = batch
                    .iter()
                    .skip(t)
                    .step_by(threads)
                    .map(|f| (*f).clone())
                    .collect();
                let (trace, (_, st)) = isa::record(&prog(mine), m.flavour(), "mft");
                out.stats.add(st);
                trace
            })
            .collect();
        let refs: Vec<&isa::Trace> = traces.iter().collect();
        let s = sim::simulate(m, &refs, &sim::SimOptions::default()).map_err(AppError)?;
        out.ops += traces.iter().map(|t| t.ops.len() as u64).sum::<u64>();
        out.regions.merge(&s);
        out.estimates
            .push(s.cycles as f64 / per as f64 * sets.len() as f64);
        pairs.push((s.cycles as f64, per as f64));
    }
    let (c, n) = pairs
        .iter()
        .fold((0.0, 0.0), |(a, b), &(x, y)| (a + x, b + y));
    let scale = sets.len() as f64;
    out.cycles = c / n * scale;
    out.ci = ratio_ci(&pairs).map(|h| h * scale);
    Ok(out)
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
pub(crate) struct Prepared {
    pub(crate) scene: Scene,
    pub(crate) light: [[f32; 3]; 3],
    pub(crate) shallow: Bvh2,
    deep: Bvh2,
    pub(crate) primary: Vec<Frusta>,
    pub(crate) shadow: Vec<Frusta>,
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
        let shadow = if !with_shadow {
            Vec::new()
        } else {
            let refi = Reference::with_bvh(&scene.mesh, &shallow).front_faces_only();
            (0..res / 4)
                .flat_map(|gy| (0..res / 4).map(move |gx| (4 * gx, 4 * gy)))
                .map(|(x, y)| Frusta::shadow(&soft_shadow_group(&scene, &refi, x, y), [c, e1, e2]))
                .filter(|f| f.active != 0)
                .collect()
        };
        Ok(Prepared {
            scene,
            light: [c, e1, e2],
            shallow,
            deep,
            primary,
            shadow,
        })
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
        }
    }
}
