//! What the MBVH reports share: the scene at the paper's 512x512 with a
//! thin lens, a systematic sample of its tiles, the distribution tracer's
//! streams for a tile, and the kernels run over them with every ray checked
//! against the reference.

use isa::FlavourId;
use mbvh_kernels::stats::Counters;
use mbvh_kernels::{Kernel, Run, Trees, BVH};
use rayon::prelude::*;
use repro::progress::Progress;
use repro::{AppError, AppResult};
use scene::agreement::{mismatches_expected, Expected, F32Test};
use scene::reference::Reference;
use scene::scene::Scene;
use scene::workload::{distribution_tile, scene_size, Lens, RayStream, StreamKind, Tile};
use std::collections::BTreeMap;
use std::sync::Arc;

/// Paths per pixel (the paper's 16).
pub(crate) const PATHS: u32 = 16;

/// A scene made ready: camera at `res` x `res`, its MBVHs, its lens.
pub(crate) struct Prepared {
    pub(crate) name: String,
    pub(crate) scene: Scene,
    pub(crate) trees: Arc<Trees>,
    pub(crate) lens: Lens,
    pub(crate) res: u32,
}

impl Prepared {
    /// Load `name` at `res` x `res` with its SAH BVH2 (through the cache).
    pub(crate) fn new(name: &str, res: u32) -> AppResult<Prepared> {
        let mut scene = Scene::load(name)?;
        scene.config.camera.width = res;
        scene.config.camera.height = res;
        let (b2, _) = scene::bvh_cache::build(&scene.mesh, &BVH).map_err(AppError)?;
        let cam = &scene.config.camera;
        let d: f64 = (0..3)
            .map(|a| f64::from(cam.target[a] - cam.eye[a]).powi(2))
            .sum::<f64>()
            .sqrt();
        // Depth of field focused on the camera's target; the paper gives no
        // aperture: a small one (0.2% of the scene's size), so paths of a
        // pixel stay near each other as its images show.
        let lens = Lens {
            aperture: 0.002 * scene_size(&scene),
            focus: d,
        };
        let trees = Trees::new(Arc::new(scene.mesh.clone()), Arc::new(b2));
        for w in [4, 16] {
            trees.of_width(w);
        }
        Ok(Prepared {
            name: name.into(),
            scene,
            trees: Arc::new(trees),
            lens,
            res,
        })
    }

    /// `n` tiles of `size` pixels, a systematic sample of the frame's tiles
    /// in raster order from a seeded start.
    pub(crate) fn tiles(&self, size: u32, n: usize, seed: u64) -> Vec<Tile> {
        let per_row = self.res / size;
        let total = (per_row * per_row) as usize;
        let n = n.clamp(1, total);
        let stride = total as f64 / n as f64;
        let start = (repro::sampling::mix(seed) % 1_000_000) as f64 / 1e6 * stride;
        (0..n)
            .map(|i| {
                let k = ((start + i as f64 * stride) as usize).min(total - 1) as u32;
                Tile {
                    x: k % per_row,
                    y: k / per_row,
                    size,
                }
            })
            .collect()
    }

    /// The distribution tracer's streams of one tile to `bounces`.
    pub(crate) fn streams(&self, tile: Tile, bounces: u32, seed: u64) -> Vec<RayStream> {
        distribution_tile(
            &self.scene,
            &self.trees.b2,
            tile,
            PATHS,
            self.lens,
            bounces,
            seed,
        )
    }
}

/// A stream kind as a sortable key: (bounce depth, shadow?).
pub(crate) fn kind_key(k: StreamKind) -> (u32, bool) {
    match k {
        StreamKind::Primary => (0, false),
        StreamKind::Bounce(b) => (b, false),
        StreamKind::Shadow(b) => (b, true),
    }
}

/// Ray-type label of a stream key.
pub(crate) fn ray_type((depth, shadow): (u32, bool)) -> &'static str {
    match (depth, shadow) {
        (_, true) => "shadow",
        (0, false) => "primary",
        _ => "reflection",
    }
}

/// One method of a report: its label, kernel and flavour.
pub(crate) struct Method {
    pub(crate) label: String,
    pub(crate) kernel: Kernel,
    pub(crate) flavour: FlavourId,
}

/// Counters per (method index, stream key), summed over tiles.
pub(crate) type Tally = BTreeMap<(usize, (u32, bool)), Counters>;

/// Run every method natively on every stream of every tile (tiles in
/// parallel), each ray checked against the reference; the counters, and
/// how many rays differed.
pub(crate) fn measure(
    pr: &Prepared,
    tiles: &[Tile],
    (bounces, seed): (u32, u64),
    methods: &[Method],
    progress: &Progress,
) -> (Tally, usize) {
    progress.add_units(tiles.len() as u64);
    let per_tile: Vec<(Tally, usize)> = tiles
        .par_iter()
        .map(|&t| {
            let out = measure_tile(pr, t, (bounces, seed), methods);
            progress.done(1);
            out
        })
        .collect();
    let mut tally = Tally::new();
    let mut bad = 0;
    for (t, b) in per_tile {
        bad += b;
        for (k, c) in t {
            tally.entry(k).or_default().add(&c);
        }
    }
    (tally, bad)
}

fn measure_tile(
    pr: &Prepared,
    tile: Tile,
    (bounces, seed): (u32, u64),
    methods: &[Method],
) -> (Tally, usize) {
    let refi = Reference::with_bvh(&pr.trees.mesh, &pr.trees.b2);
    let mut tally = Tally::new();
    let mut bad = 0;
    for st in pr.streams(tile, bounces, seed) {
        if st.is_empty() {
            continue;
        }
        let want = Expected::of(&refi, &st);
        let key = kind_key(st.kind);
        let rays = Arc::new(st);
        for (i, m) in methods.iter().enumerate() {
            let run = Run {
                kernel: m.kernel,
                trees: pr.trees.clone(),
                rays: rays.clone(),
            };
            let (hits, c) = isa::run_native(&run, m.flavour);
            let label = format!(
                "{} {} tile ({}, {}) {:?}",
                pr.name, m.label, tile.x, tile.y, rays.kind
            );
            bad += mismatches_expected(F32Test::MollerTrumbore, &label, &refi, &rays, &want, &hits);
            tally.entry((i, key)).or_default().add(&c);
        }
    }
    (tally, bad)
}
