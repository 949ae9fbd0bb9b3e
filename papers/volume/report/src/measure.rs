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
use scene::volume_ref::{cast_walk, Filter, Lighting, Sampling, Walk};
use std::path::Path;
use std::sync::Arc;
use volume_kernels::bvh::{ConstantAt, Heuristics};
use volume_kernels::layout::VolBufs;
use volume_kernels::naive::{GccRun, Translation};
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
    constant_at: ConstantAt::Leaves,
};

/// The paper's differential sampling growth, 2^-7 ("All approaches ...
/// use differential sampling with an initial differential step of 2^-7
/// (rda in line 31 of Listing 2)"), read as relative to the first step:
/// each step is `RDA_PER_DT * dt` longer than the last (a named
/// assumption, see the paper's README: in voxels, no first step gives ~2
/// samples per voxel on a ray longer than about 64 voxels).
pub(crate) const RDA_PER_DT: f64 = 1.0 / 128.0;

/// The sampling density the reports' first step is chosen for: the
/// paper's "~2 samples per voxel" (section 7, Figure 6).
pub(crate) const SAMPLES_PER_VOXEL: f64 = 2.0;

/// Side of the grid of rays over the frame the first step is chosen on.
const CALIBRATION_GRID: u32 = 32;

/// Samples per voxel of a frame: the samples its rays visit over the
/// voxels their steps cover (a ratio of sums over the rays that meet the
/// volume, early termination included), with the rays' share that meet
/// the box and the share of those that stop by opacity.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Density {
    pub(crate) samples_per_voxel: f64,
    pub(crate) samples_per_ray: f64,
    pub(crate) coverage: f64,
    pub(crate) terminated: f64,
}

impl Density {
    /// Over the walks of a set of rays (in a fixed order: the same sums for
    /// any number of host threads).
    pub(crate) fn of(walks: &[Walk]) -> Density {
        let (mut n, mut len, mut entered, mut stopped) = (0u64, 0f64, 0usize, 0usize);
        for w in walks {
            n += w.samples;
            len += w.length;
            entered += usize::from(w.entered);
            stopped += usize::from(w.terminated);
        }
        Density {
            samples_per_voxel: n as f64 / len.max(1e-30),
            samples_per_ray: n as f64 / walks.len().max(1) as f64,
            coverage: entered as f64 / walks.len().max(1) as f64,
            terminated: stopped as f64 / entered.max(1) as f64,
        }
    }
}

/// The reference's walks of `rays` under `s`.
fn walks(pr: &Prepared, rays: &Rays, s: &Sampling) -> Vec<Walk> {
    (0..rays.len())
        .into_par_iter()
        .map(|i| {
            let (o, d) = (rays.org[i].map(f64::from), rays.dir[i].map(f64::from));
            cast_walk(&pr.volume, &pr.tf, o, d, s).1
        })
        .collect()
}

/// The first step (voxels) giving [`SAMPLES_PER_VOXEL`] on a
/// `CALIBRATION_GRID`^2 grid of the view's rays, each step `RDA_PER_DT`
/// of it longer than the last: bisection on its logarithm, 16 rounds.
pub(crate) fn calibrate_dt(pr: &Prepared, eye: [f64; 3], fov: f64, s: Sampling) -> f64 {
    let g = CALIBRATION_GRID;
    let rays = Rays::camera(pr.volume.dims, eye, fov, (g, g));
    let spv = |dt: f64| {
        let s = Sampling {
            dt,
            rda: RDA_PER_DT * dt,
            ..s
        };
        Density::of(&walks(pr, &rays, &s)).samples_per_voxel
    };
    let (mut lo, mut hi) = ((1.0f64 / 512.0).log2(), 1.0f64.log2());
    for _ in 0..16 {
        let mid = 0.5 * (lo + hi);
        if spv(mid.exp2()) > SAMPLES_PER_VOXEL {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    (0.5 * (lo + hi)).exp2()
}

/// The vertical field of view (degrees) that just holds the volume's box
/// seen from `eye` looking at its centre (square frames): the paper's
/// images show the data filling the frame.
pub(crate) fn box_fov(dims: [u32; 3], eye: [f64; 3]) -> f64 {
    let hi = dims.map(|d| f64::from(d.max(1) - 1));
    let centre = hi.map(|x| x / 2.0);
    let fwd = unit(std::array::from_fn(|a| centre[a] - eye[a]));
    let right = unit(cross(fwd, [0.0, 0.0, 1.0]));
    let up = cross(right, fwd);
    let mut half = 0f64;
    for k in 0..8 {
        let c: [f64; 3] = std::array::from_fn(|a| if k >> a & 1 == 1 { hi[a] } else { 0.0 });
        let v: [f64; 3] = std::array::from_fn(|a| c[a] - eye[a]);
        let z = dot(v, fwd);
        half = half.max((dot(v, right).abs() / z).atan());
        half = half.max((dot(v, up).abs() / z).atan());
    }
    2.0 * half.to_degrees() * 1.02
}

/// The share of the frame the reports' views fill with the volume: the
/// paper's images show the data filling the frame (a named assumption,
/// its effect measured against [`Framing::Sphere`] in `volume-fig5`).
pub(crate) const FRAME_COVERAGE: f64 = 0.88;

/// The share of a `g` x `g` grid of the view's rays that meet the box.
fn grid_coverage(dims: [u32; 3], eye: [f64; 3], fov: f64, g: u32) -> f64 {
    let rays = Rays::camera(dims, eye, fov, (g, g));
    let hit = (0..rays.len())
        .filter(|&i| {
            let (o, d) = (rays.org[i].map(f64::from), rays.dir[i].map(f64::from));
            scene::volume_ref::enter_exit(dims, o, d).is_some()
        })
        .count();
    hit as f64 / rays.len().max(1) as f64
}

/// The field of view at which the box covers [`FRAME_COVERAGE`] of a
/// 64x64 grid of the view's rays (bisection between 1 degree and the
/// view holding the whole box).
pub(crate) fn filling_fov(dims: [u32; 3], eye: [f64; 3]) -> f64 {
    let (mut lo, mut hi) = (1.0, box_fov(dims, eye));
    for _ in 0..24 {
        let mid = 0.5 * (lo + hi);
        if grid_coverage(dims, eye, mid, 64) > FRAME_COVERAGE {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// The field of view that holds the volume's bounding sphere (the framing
/// before issue 53, kept as the view assumption's other setting).
pub(crate) fn sphere_fov(dims: [u32; 3], eye: [f64; 3]) -> f64 {
    let c = dims.map(f64::from);
    let centre = c.map(|x| (x - 1.0) / 2.0);
    let dist = (0..3)
        .map(|a| (eye[a] - centre[a]).powi(2))
        .sum::<f64>()
        .sqrt();
    let radius = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt() / 2.0;
    2.0 * (radius / dist).asin().to_degrees()
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn unit(a: [f64; 3]) -> [f64; 3] {
    let l = dot(a, a).sqrt();
    a.map(|x| x / l)
}

/// How a view frames the volume.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Framing {
    /// The box filling [`FRAME_COVERAGE`] of the frame (the reports' view).
    Fill,
    /// The bounding sphere just inside the frame (the volume covers less).
    Sphere,
}

/// A dataset made ready: its volume, transfer function, tree, view and
/// lighting.
#[derive(Clone)]
pub(crate) struct Dataset {
    pub(crate) prepared: Arc<Prepared>,
    pub(crate) tree: Arc<MinMaxBvh>,
    /// The tree's nodes as laid out in simulated memory (made once).
    pub(crate) node_words: Arc<Vec<u32>>,
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
    /// makes the generated dense field [`DENSE_QUICK`] instead of [`DENSE`]. `mixingN`
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
                Volume::noisy_box(if quick { DENSE_QUICK } else { DENSE }, 5),
                include_str!("../../../../configs/transfer/dense.ron"),
            ),
            _ => {
                let n = name
                    .strip_prefix("mixing")
                    .and_then(|n| n.parse().ok())
                    .ok_or_else(|| AppError(format!("unknown volume dataset '{name}'")))?;
                (Volume::mixing_layer(n, MIXING_SEED), MIXING_TF)
            }
        };
        let tf =
            Transfer::parse(tf).map_err(|e| AppError(format!("{name} transfer function: {e}")))?;
        Ok(Dataset::new(vol, tf, (lit, leaf)))
    }

    /// `vol` classified by `tf`, its tree, seen from the default view with
    /// the box filling the frame, its first step chosen for
    /// [`SAMPLES_PER_VOXEL`].
    pub(crate) fn new(vol: Volume, tf: Transfer, (lit, leaf): (char, u32)) -> Dataset {
        let t0 = std::time::Instant::now();
        let tree = MinMaxBvh::build(&vol, leaf);
        let build_seconds = t0.elapsed().as_secs_f64();
        let c = vol.dims.map(f64::from);
        let sampling = Sampling {
            filter: Filter::Trilinear,
            dt: 0.5,
            rda: RDA_PER_DT * 0.5,
            lighting: lighting(lit),
            light: [c[0] * 2.0, -c[1], c[2] * 3.0],
            light_threshold: 0.01,
        };
        Dataset {
            fov: 0.0,
            prepared: Arc::new(Prepared::new(vol, tf)),
            node_words: Arc::new(volume_kernels::bvh::node_words(&tree)),
            tree: Arc::new(tree),
            eye: [c[0] * 1.6, -c[1] * 0.9, c[2] * 1.8],
            sampling,
            build_seconds,
            res: RES,
            heuristics: HEURISTICS,
        }
        .reframed(Framing::Fill)
    }

    /// The same dataset with its view framed by `framing`, the first step
    /// chosen again for [`SAMPLES_PER_VOXEL`] (the tree kept: it does not
    /// depend on the view).
    pub(crate) fn reframed(&self, framing: Framing) -> Dataset {
        let dims = self.prepared.volume.dims;
        let fov = match framing {
            Framing::Fill => filling_fov(dims, self.eye),
            Framing::Sphere => sphere_fov(dims, self.eye),
        };
        let dt = calibrate_dt(&self.prepared, self.eye, fov, self.sampling);
        Dataset {
            fov,
            sampling: Sampling {
                dt,
                rda: RDA_PER_DT * dt,
                ..self.sampling
            },
            ..self.clone()
        }
    }

    /// The same dataset classified by `tf`, its view, sampling and tree kept
    /// (the tree's min-max ranges do not depend on the transfer function).
    pub(crate) fn with_transfer(&self, tf: Transfer) -> Dataset {
        Dataset {
            prepared: Arc::new(Prepared::new(self.prepared.volume.clone(), tf)),
            ..self.clone()
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
    /// view), the field of view kept; a new view's first step is chosen
    /// again for [`SAMPLES_PER_VOXEL`].
    pub(crate) fn with_view(&self, res: u32, closer: f64) -> Dataset {
        let c = self
            .prepared
            .volume
            .dims
            .map(|x| (f64::from(x) - 1.0) / 2.0);
        let eye = std::array::from_fn(|a| c[a] + (self.eye[a] - c[a]) * closer);
        let mut sampling = self.sampling;
        if closer != 1.0 {
            let dt = calibrate_dt(&self.prepared, eye, self.fov, sampling);
            let per_dt = sampling.rda / sampling.dt;
            sampling.dt = dt;
            sampling.rda = per_dt * dt;
        }
        Dataset {
            eye,
            res,
            sampling,
            ..self.clone()
        }
    }

    /// The share of the frame's pixels whose rays meet the volume's box.
    pub(crate) fn coverage(&self) -> f64 {
        grid_coverage(self.prepared.volume.dims, self.eye, self.fov, self.res)
    }
}

/// The dense stand-in's size: the paper's backpack, 512x512x373.
pub(crate) const DENSE: [u32; 3] = [512, 512, 373];

/// Its size at `--quick`: the backpack's shape at a quarter of each side.
pub(crate) const DENSE_QUICK: [u32; 3] = [128, 128, 93];

/// The mixing layer's transfer function.
pub(crate) const MIXING_TF: &str = include_str!("../../../../configs/transfer/mixing.ron");

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
        let nodes = volume_kernels::bvh::lay_out_node_words(m, &self.ds.node_words);
        (v, nodes)
    }

    fn unit<M: Machine>(&self, m: &mut M, laid: &Self::Laid, rays: &Arc<Rays>) -> Self::Out {
        let (pr, s) = (self.ds.prepared.clone(), self.ds.sampling);
        match self.method {
            Method::Gcc => GccRun {
                prepared: pr,
                rays: rays.clone(),
                sampling: s,
                translation: Translation::Arithmetic,
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
    /// Whether eq. 7 was on (the bvh caster with delta_sv > 0): its
    /// constant nodes' colours leave the reference by design.
    pub(crate) approximate: bool,
}

impl Cell {
    /// The pixels off that count as mismatches: none when eq. 7
    /// approximates the colours (reported as `pixels_off_reference`), all
    /// of them otherwise.
    pub(crate) fn mismatches(&self) -> usize {
        if self.approximate {
            0
        } else {
            self.bad
        }
    }
}

/// The reference's colour and walk for every ray of `rays`.
fn reference(ds: &Dataset, rays: &Rays) -> (Vec<[f64; 4]>, Vec<Walk>) {
    (0..rays.len())
        .into_par_iter()
        .map(|i| {
            let (o, d) = (rays.org[i].map(f64::from), rays.dir[i].map(f64::from));
            cast_walk(&ds.prepared.volume, &ds.prepared.tf, o, d, &ds.sampling)
        })
        .unzip()
}

/// The sampled packets: the packet before (warming), the timed packet's
/// rays, the reference's colours and walks for them.
pub(crate) type Sample = Vec<(Option<Arc<Rays>>, Arc<Rays>, Vec<[f64; 4]>, Vec<Walk>)>;

/// The sampling density over the timed rays of `smp`.
pub(crate) fn density(smp: &Sample) -> Density {
    let walks: Vec<Walk> = smp.iter().flat_map(|p| p.3.iter().copied()).collect();
    Density::of(&walks)
}

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
            let (want, walks) = reference(ds, &timed);
            (before.map(packet), timed, want, walks)
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
    for (g, (before, timed, _, _)) in smp.iter().enumerate() {
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
    let threads = smt_threads(m);
    let mut session = if threads > 1 {
        sim::Session::with_threads(m, threads).map_err(AppError)?
    } else {
        sim::Session::new(m)
    };
    let mut pending: Vec<isa::Trace> = Vec::new();
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
            pending.push(t);
            if pending.len() == threads {
                time_together(
                    &mut session,
                    &mut pending,
                    (&mut cycles, &mut instr, &mut regions),
                )?;
            }
            Ok::<(), AppError>(())
        },
    )?;
    if !pending.is_empty() {
        time_together(
            &mut session,
            &mut pending,
            (&mut cycles, &mut instr, &mut regions),
        )?;
    }
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
        approximate: method == Method::Bvh && ds.heuristics.delta_sv > 0.0,
    })
}

/// Hardware threads a core of `m` runs packets on: the machine's
/// (`core.threads`: two on the X5550, whose Hyper-Threading the paper's 16
/// threads used), one on an in-order machine. `--set core.threads=1`
/// measures one thread per core.
pub(crate) fn smt_threads(m: &sim::MachineConfig) -> usize {
    if m.core.kind == sim::CoreKind::OutOfOrder {
        m.core.threads.max(1) as usize
    } else {
        1
    }
}

/// Time the pending packets' traces together, one per hardware thread of
/// the core (as a renderer's threads take packets): each packet is charged
/// an equal share of the step's cycles.
fn time_together(
    session: &mut sim::Session,
    pending: &mut Vec<isa::Trace>,
    (cycles, instr, regions): (&mut Vec<f64>, &mut f64, &mut [f64; isa::Region::COUNT]),
) -> AppResult<()> {
    let refs: Vec<&isa::Trace> = pending.iter().collect();
    let st = session.timed_queue(&refs).map_err(AppError)?;
    let n = pending.len();
    for _ in 0..n {
        cycles.push(st.cycles as f64 / n as f64);
    }
    *instr += st.ops as f64;
    for (r, &c) in regions.iter_mut().zip(&st.region_cycles) {
        *r += c as f64;
    }
    for t in pending.drain(..) {
        isa::trace::recycle(t);
    }
    Ok(())
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
    let placed = smp.iter().map(|(_, timed, _, _)| {
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
