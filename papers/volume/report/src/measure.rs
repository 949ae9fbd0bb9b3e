//! What the volume reports measure: a dataset at 512^2 seen from its view,
//! its 8x8-pixel packets as units (the "sse" caster on the packet's rays, or
//! the "bvh" caster on the packet), a stratified sample of packets timed on
//! one core in full detail after functional warming (the packet before, then
//! itself), every timed pixel checked against the f64 reference.

use isa::{Detail, Machine, Placed, UnitProgram};
use rayon::prelude::*;
use repro::progress::Progress;
use repro::sampling::{strata_with_previous, systematic_ratio_ci};
use repro::{AppError, AppResult};
use scene::transfer::Transfer;
use scene::volume::Volume;
use scene::volume_bvh::MinMaxBvh;
use scene::volume_ref::{cast, Filter, Lighting, Sampling};
use std::path::Path;
use std::sync::Arc;
use volume_kernels::bvh::Heuristics;
use volume_kernels::layout::VolBufs;
use volume_kernels::naive::GccRun;
use volume_kernels::{BvhRun, Prepared, Rays, Run};

/// Image side (the paper's 512^2).
pub(crate) const RES: u32 = 512;

/// A pixel counts as differing from the reference above this difference in
/// a channel (one sample's contribution moved across a voxel boundary by f32
/// rounding stays below it; see the paper's README).
pub(crate) const PIXEL_TOL: f64 = 0.3;

/// The paper's heuristics' defaults: delta_c < 1e-3, delta_p = 1.5,
/// delta_sv < 1e-4 ("Relatively small delta_sv < 1e-4 consistently produce
/// good results").
pub(crate) const HEURISTICS: Heuristics = Heuristics {
    delta_c: 1e-3,
    delta_p: 1.5,
    delta_sv: 1e-4,
};

/// The paper's differential sampling step growth, 2^-7 ("All approaches
/// ... use differential sampling with an initial differential step of
/// 2^-7 (rda in line 31 of Listing 2)"), in voxels as Listing 2 takes it.
pub(crate) const RDA: f64 = 1.0 / 128.0;

/// The first step: 0.5 voxels (the paper's "~2 samples per voxel").
pub(crate) const DT: f64 = 0.5;

/// A dataset made ready: its volume, transfer function, tree, view and
/// lighting.
#[derive(Clone)]
pub(crate) struct Dataset {
    pub(crate) prepared: Arc<Prepared>,
    pub(crate) tree: Arc<MinMaxBvh>,
    pub(crate) eye: [f64; 3],
    /// Vertical field of view (degrees) that frames the volume.
    pub(crate) fov: f64,
    pub(crate) sampling: Sampling,
    /// Host seconds the tree took to build (varies run to run).
    pub(crate) build_seconds: f64,
    /// Image side in pixels.
    pub(crate) res: u32,
    /// The BVH caster's heuristics (eqs. 5-7).
    pub(crate) heuristics: Heuristics,
}

fn lighting(c: char) -> Lighting {
    match c {
        'd' => Lighting::Diffuse,
        'p' => Lighting::Phong,
        _ => Lighting::Unlit,
    }
}

/// The data file of dataset `name` (none for the generated ones).
fn data_file(name: &str) -> Option<&'static str> {
    match name {
        "engine" => Some("engine_256x256x128_uint8.raw.gz"),
        "neghip" => Some("neghip_66x66x66_uint8.raw.gz"),
        "skull" => Some("skull_64x64x64_float32le.raw.gz"),
        _ => None,
    }
}

/// Why dataset `name` cannot be loaded from this data folder: its file is
/// not there (the hint says how to get it), or `None`.
pub(crate) fn missing(name: &str) -> Option<String> {
    let f = data_file(name)?;
    let data = scene::scene::data_root().join("volumes");
    (!data.join(f).exists()).then(|| scene::scene::missing_data_hint(&Path::new("volumes").join(f)))
}

impl Dataset {
    /// Load dataset `name` (lighting `lit`, leaves of `leaf`^3); `quick`
    /// makes the generated dense field 64^3 instead of 128^3. `mixingN`
    /// is the seeded mixing layer at N^3.
    pub(crate) fn load(name: &str, (lit, leaf): (char, u32), quick: bool) -> AppResult<Dataset> {
        let data = scene::scene::data_root().join("volumes");
        let file = |f: &str| {
            if let Some(hint) = missing(name) {
                return Err(AppError(format!("dataset {name}: {hint}")));
            }
            Volume::load(&data.join(f)).map_err(|e| AppError(e.to_string()))
        };
        let (vol, tf) = match (name, data_file(name)) {
            ("engine", Some(f)) => (
                file(f)?,
                include_str!("../../../../configs/transfer/engine.ron"),
            ),
            ("neghip", Some(f)) => (
                file(f)?,
                include_str!("../../../../configs/transfer/neghip.ron"),
            ),
            ("skull", Some(f)) => (
                file(f)?,
                include_str!("../../../../configs/transfer/skull.ron"),
            ),
            ("dense", _) => (
                Volume::noisy(if quick { 64 } else { 128 }, 5),
                include_str!("../../../../configs/transfer/dense.ron"),
            ),
            _ => {
                let n = name
                    .strip_prefix("mixing")
                    .and_then(|n| n.parse().ok())
                    .ok_or_else(|| AppError(format!("unknown volume dataset '{name}'")))?;
                (
                    Volume::mixing_layer(n, MIXING_SEED),
                    include_str!("../../../../configs/transfer/mixing.ron"),
                )
            }
        };
        let tf =
            Transfer::parse(tf).map_err(|e| AppError(format!("{name} transfer function: {e}")))?;
        Ok(Dataset::new(vol, tf, (lit, leaf)))
    }

    /// `vol` classified by `tf`, its tree, seen from the default view.
    pub(crate) fn new(vol: Volume, tf: Transfer, (lit, leaf): (char, u32)) -> Dataset {
        let t0 = std::time::Instant::now();
        let tree = MinMaxBvh::build(&vol, leaf);
        let build_seconds = t0.elapsed().as_secs_f64();
        let c = vol.dims.map(f64::from);
        let eye = [c[0] * 1.6, -c[1] * 0.9, c[2] * 1.8];
        // Frame the volume: its bounding sphere just inside the view, as
        // the paper's images fill theirs.
        let centre = c.map(|x| (x - 1.0) / 2.0);
        let dist = (0..3)
            .map(|a| (eye[a] - centre[a]).powi(2))
            .sum::<f64>()
            .sqrt();
        let radius = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt() / 2.0;
        let fov = 2.0 * (radius / dist).asin().to_degrees();
        let light = [c[0] * 2.0, -c[1], c[2] * 3.0];
        let sampling = Sampling {
            filter: Filter::Trilinear,
            dt: DT,
            rda: RDA,
            lighting: lighting(lit),
            light,
            light_threshold: 0.01,
        };
        Dataset {
            fov,
            prepared: Arc::new(Prepared::new(vol, tf)),
            tree: Arc::new(tree),
            eye,
            sampling,
            build_seconds,
            res: RES,
            heuristics: HEURISTICS,
        }
    }

    /// The same dataset sampled and shaded by `s`.
    pub(crate) fn with_sampling(&self, s: Sampling) -> Dataset {
        Dataset {
            sampling: s,
            ..self.clone()
        }
    }

    /// The same dataset rendered at `res` x `res`, the eye moved towards
    /// the volume's centre to `closer` of its distance (1: the default
    /// view), the field of view kept.
    pub(crate) fn with_view(&self, res: u32, closer: f64) -> Dataset {
        let c = self
            .prepared
            .volume
            .dims
            .map(|x| (f64::from(x) - 1.0) / 2.0);
        let eye = std::array::from_fn(|a| c[a] + (self.eye[a] - c[a]) * closer);
        Dataset {
            eye,
            res,
            ..self.clone()
        }
    }
}

/// The seed of the generated mixing layer.
pub(crate) const MIXING_SEED: u64 = 11;

/// Which caster.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Method {
    /// The naive scalar baseline.
    Gcc,
    /// Listing 2 per pixel, no acceleration structure.
    Sse,
    /// Coherent BVH traversal.
    Bvh,
}

impl Method {
    pub(crate) fn name(self) -> &'static str {
        match self {
            Method::Gcc => "gcc",
            Method::Sse => "sse",
            Method::Bvh => "bvh",
        }
    }
}

/// A packet's rays as a unit.
struct Units {
    method: Method,
    ds: Arc<Dataset>,
}

impl UnitProgram for Units {
    type Laid = (VolBufs, isa::Buf);
    type Unit = Arc<Rays>;
    type Out = (Vec<[f32; 4]>, volume_kernels::dvr::Counters);

    fn lay_out<M: Machine>(&self, m: &mut M) -> Self::Laid {
        let pr = &self.ds.prepared;
        let v = volume_kernels::layout::lay_out(m, &pr.bricked, pr.volume.dims, &pr.tf);
        let nodes = volume_kernels::bvh::lay_out_nodes(m, &self.ds.tree);
        (v, nodes)
    }

    fn unit<M: Machine>(&self, m: &mut M, laid: &Self::Laid, rays: &Arc<Rays>) -> Self::Out {
        let (pr, s) = (self.ds.prepared.clone(), self.ds.sampling);
        match self.method {
            Method::Gcc => GccRun {
                prepared: pr,
                rays: rays.clone(),
                sampling: s,
            }
            .trace_on(m, &laid.0),
            Method::Sse => Run {
                prepared: pr,
                rays: rays.clone(),
                sampling: s,
            }
            .trace_on(m, &laid.0),
            Method::Bvh => BvhRun {
                prepared: pr,
                tree: self.ds.tree.clone(),
                rays: rays.clone(),
                sampling: s,
                heuristics: self.ds.heuristics,
            }
            .trace_on(m, &laid.0, &laid.1),
        }
    }
}

/// The sampled packets: one at a seeded place in each of `groups` equal
/// strata of the frame's packets in raster order, with the packet before.
pub(crate) fn plan(res: u32, groups: usize, seed: u64) -> Vec<(Option<usize>, usize)> {
    strata_with_previous(((res / 8) * (res / 8)) as usize, groups, seed)
}

/// One method on one dataset.
pub(crate) struct Cell {
    /// Frames per second on one core (the frame's cycles from the sample).
    pub(crate) fps: f64,
    /// 95% CI half-width of `fps`.
    pub(crate) ci: Option<f64>,
    /// Each timed packet's cycles, in sample order.
    pub(crate) run_cycles: Vec<f64>,
    /// Sample positions visited and samples classified per ray (timed
    /// packets).
    pub(crate) samples_per_ray: f64,
    pub(crate) classified_per_ray: f64,
    /// BVH nodes popped per packet and rays integrated through a leaf per
    /// ray (timed packets; 0 without the BVH).
    pub(crate) nodes_per_packet: f64,
    pub(crate) leaf_rays_per_ray: f64,
    /// Share of the visited samples the constant-subvolume routine took.
    pub(crate) constant_share: f64,
    /// Instructions per ray and CPI of the timed packets.
    pub(crate) instr_per_ray: f64,
    pub(crate) cpi: f64,
    /// Share of the cycles in traversal (`Region::Traversal`).
    pub(crate) traversal_share: f64,
    /// Cycles per code region (timed packets), by region id.
    pub(crate) region_cycles: [f64; isa::Region::COUNT],
    /// PSNR of the timed pixels against the reference.
    pub(crate) psnr: f64,
    /// Ops simulated.
    pub(crate) ops: u64,
    /// Pixels differing from the reference by more than [`PIXEL_TOL`].
    pub(crate) bad: usize,
}

/// The reference's colour for every ray of `rays`.
fn reference(ds: &Dataset, rays: &Rays) -> Vec<[f64; 4]> {
    (0..rays.len())
        .into_par_iter()
        .map(|i| {
            let (o, d) = (rays.org[i].map(f64::from), rays.dir[i].map(f64::from));
            cast(&ds.prepared.volume, &ds.prepared.tf, o, d, &ds.sampling)
        })
        .collect()
}

/// The sampled packets' rays and (timed packets) the reference's colours.
pub(crate) type Sample = Vec<(Option<Arc<Rays>>, Arc<Rays>, Vec<[f64; 4]>)>;

/// Rays and reference answers of the plan's packets.
pub(crate) fn sample(ds: &Dataset, groups: usize, seed: u64) -> Sample {
    let dims = ds.prepared.volume.dims;
    let (res, per_row) = (ds.res, ds.res / 8);
    let packet = |k: usize| {
        let (px, py) = (k as u32 % per_row, k as u32 / per_row);
        Arc::new(Rays::packet(dims, ds.eye, ds.fov, (res, res), (px, py)))
    };
    plan(res, groups, seed)
        .into_iter()
        .map(|(before, k)| {
            let timed = packet(k);
            let want = reference(ds, &timed);
            (before.map(packet), timed, want)
        })
        .collect()
}

/// Time `method` over the sample on one core of `m`.
pub(crate) fn measure(
    m: &sim::MachineConfig,
    ds: &Arc<Dataset>,
    smp: &Sample,
    method: Method,
    progress: &Progress,
) -> AppResult<Cell> {
    let prog = Units {
        method,
        ds: ds.clone(),
    };
    let mut units = Vec::new();
    for (g, (before, timed, _)) in smp.iter().enumerate() {
        if let Some(b) = before {
            units.push((b.clone(), Detail::Warmed, None));
        }
        units.push((timed.clone(), Detail::Warmed, None));
        units.push((timed.clone(), Detail::Timed, Some(g)));
    }
    progress.add_units(units.len() as u64);
    let placed: Vec<_> = units
        .iter()
        .map(|(r, d, _)| {
            (
                Placed {
                    thread: 0,
                    unit: r.clone(),
                },
                *d,
            )
        })
        .collect();
    let mut session = sim::Session::new(m);
    let (mut ops, mut bad, mut next) = (0u64, 0usize, 0usize);
    let (mut cycles, mut instr) = (Vec::new(), 0f64);
    let mut regions = [0f64; isa::Region::COUNT];
    let (mut se, mut n_px) = (0f64, 0usize);
    let (mut samples, mut classified) = (0u64, 0u64);
    let (mut nodes, mut leaf_rays, mut constant) = (0u64, 0u64, 0u64);
    isa::run_units(
        &prog,
        m.flavour(),
        "volume",
        placed,
        |_, _, t, (img, cn)| {
            let g = units[next].2;
            next += 1;
            progress.done(1);
            ops += t.ops.len() as u64;
            let Some(g) = g else {
                session.warm(&[(0, &t)]).map_err(AppError)?;
                isa::trace::recycle(t);
                return Ok(());
            };
            for (px, want) in img.iter().zip(&smp[g].2) {
                let d = (0..4)
                    .map(|c| (f64::from(px[c]) - want[c]).abs())
                    .fold(0.0, f64::max);
                bad += usize::from(d > PIXEL_TOL);
                se += (0..4)
                    .map(|c| (f64::from(px[c]) - want[c]).powi(2))
                    .sum::<f64>();
                n_px += 4;
            }
            samples += cn.samples;
            classified += cn.classified;
            nodes += cn.nodes;
            leaf_rays += cn.leaf_rays;
            constant += cn.constant_samples;
            let st = session.timed_queue(&[&t]).map_err(AppError)?;
            isa::trace::recycle(t);
            cycles.push(st.cycles as f64);
            instr += st.ops as f64;
            for (r, &c) in regions.iter_mut().zip(&st.region_cycles) {
                *r += c as f64;
            }
            Ok::<(), AppError>(())
        },
    )?;
    let hz = m.clock_ghz * 1e9;
    let packets = ((ds.res / 8) * (ds.res / 8)) as f64;
    let total: f64 = cycles.iter().sum();
    let frame_cycles = total / cycles.len() as f64 * packets;
    // Frames per cycle per packet as a ratio of sums: (1 / packets, cycles).
    let pairs: Vec<(f64, f64)> = cycles.iter().map(|&c| (1.0 / packets, c)).collect();
    let rays = 64.0 * cycles.len() as f64;
    Ok(Cell {
        fps: hz / frame_cycles,
        ci: systematic_ratio_ci(&pairs).map(|h| h * hz),
        run_cycles: cycles,
        samples_per_ray: samples as f64 / rays,
        classified_per_ray: classified as f64 / rays,
        nodes_per_packet: nodes as f64 / (rays / 64.0).max(1.0),
        leaf_rays_per_ray: leaf_rays as f64 / rays,
        constant_share: constant as f64 / samples.max(1) as f64,
        instr_per_ray: instr / rays,
        cpi: total / instr.max(1.0),
        traversal_share: regions[isa::Region::Traversal as usize] / total.max(1.0),
        region_cycles: regions,
        psnr: 10.0 * (1.0 / (se / n_px.max(1) as f64).max(1e-30)).log10(),
        ops,
        bad,
    })
}

/// Cores running packets at once against one alone: the packets of `smp`
/// (timed ones) cast by `method`, each timed alone on one core of `m`, then
/// in steps of `k` at once on `k` cores (shared caches and memory), each
/// session warmed with every packet first. Per `k`: the packets' cycles
/// alone over their cycles beside the others (1: no contention; load
/// balance is not part of it).
pub(crate) fn contention(
    m: &sim::MachineConfig,
    ds: &Arc<Dataset>,
    smp: &Sample,
    method: Method,
    cores: &[u32],
) -> AppResult<Vec<(u32, f64, u64)>> {
    let prog = Units {
        method,
        ds: ds.clone(),
    };
    let placed = smp.iter().map(|(_, timed, _)| {
        (
            Placed {
                thread: 0,
                unit: timed.clone(),
            },
            Detail::Timed,
        )
    });
    let mut traces = Vec::new();
    isa::run_units(&prog, m.flavour(), "volume", placed, |_, _, t, _| {
        traces.push(t);
        Ok::<(), AppError>(())
    })?;
    let time = |k: u32| -> AppResult<(Vec<u64>, u64)> {
        let mut mk = m.clone();
        mk.cores = k;
        let mut s = sim::Session::new(&mk);
        let mut ops = 0u64;
        for t in &traces {
            s.warm(&[(0, t)]).map_err(AppError)?;
        }
        let mut own = Vec::new();
        for chunk in traces.chunks(k as usize) {
            let units: Vec<(usize, &isa::Trace)> = chunk.iter().enumerate().collect();
            let (_, each) = s.timed_each(&units).map_err(AppError)?;
            own.extend(each);
            ops += chunk.iter().map(|t| t.ops.len() as u64).sum::<u64>();
        }
        Ok((own, ops))
    };
    let (alone, ops1) = time(1)?;
    let total_alone: u64 = alone.iter().sum();
    let mut out = vec![(1, 1.0, ops1)];
    for &k in cores.iter().filter(|&&k| k > 1) {
        let (beside, ops) = time(k)?;
        out.push((
            k,
            total_alone as f64 / beside.iter().sum::<u64>() as f64,
            ops,
        ));
    }
    Ok(out)
}
