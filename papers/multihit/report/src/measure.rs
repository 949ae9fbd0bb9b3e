//! What both multi-hit reports measure: each scene at 1024x768 with one
//! pixel-centre visibility ray per pixel, traced in 16x16-pixel tiles of
//! 4x2-pixel packets by the 8-wide packet kernel with the naive and the
//! node-culling filter, for N_query from 1 to all; a stratified sample of
//! tiles timed on one core in full detail after functional warming (the
//! tile before, then the tile itself), every timed ray's hit list checked
//! against the f64 reference's.

use crate::paper::{HEIGHT, WIDTH};
use crate::scenes::Stand;
use isa::{Detail, Machine, Placed, UnitProgram};
use multihit_kernels::filters::Insertion;
use multihit_kernels::{Counters, Kernel, Method, Run, Traversal, Tree, BVH, NAIVE_CAPACITY};
use rayon::prelude::*;
use repro::progress::Progress;
use repro::sampling::{strata_with_previous, systematic_ratio_ci};
use repro::{AppError, AppResult};
use scene::multi_agreement::list_mismatches;
use scene::reference::{Ray, RefHit, Reference};
use scene::scene::{Camera, Scene};
use scene::workload::{packet_slots, RayStream, StreamKind};
use scene::Hit;
use std::sync::Arc;

/// Pixels per side of a tile.
pub(crate) const TILE: u32 = 16;

/// A scene made ready: its trees, camera at 1024x768, hit statistics and
/// the sampled tiles with their reference answers.
pub(crate) struct Prepared {
    pub(crate) stand: Stand,
    pub(crate) name: String,
    pub(crate) tree: Arc<Tree>,
    /// Hits per ray over every pixel of the frame.
    pub(crate) hits: HitStats,
    /// Per sampled run: the warmed tile before (if any) and the timed tile.
    tiles: Vec<(Option<TileRays>, TileRays)>,
    /// Embree's scene of the same mesh (on a host with Embree 3).
    pub(crate) embree: Option<crate::embree::Embree>,
}

/// One tile's rays, packet slots and (timed tiles) every ray's reference hits.
#[derive(Clone)]
struct TileRays {
    rays: Arc<RayStream>,
    slots: Arc<Vec<u32>>,
    all: Vec<Vec<RefHit>>,
}

/// Tiles per row and column of the frame.
fn tiles_wide() -> (u32, u32) {
    (WIDTH / TILE, HEIGHT / TILE)
}

/// Pixel-centre rays of tile `k` (raster order), path = pixel in the tile.
fn tile_rays(cam: &Camera, k: usize) -> RayStream {
    let (tw, _) = tiles_wide();
    pixel_rays(cam, ((k as u32 % tw) * TILE, (k as u32 / tw) * TILE), TILE)
}

/// Pixel-centre primary rays of the `size` x `size` block at `(x0, y0)`,
/// path = pixel in the block (raster order).
pub(crate) fn pixel_rays(cam: &Camera, (x0, y0): (u32, u32), size: u32) -> RayStream {
    let (mut org, mut dir) = (Vec::new(), Vec::new());
    for y in 0..size {
        for x in 0..size {
            let (o, d) = cam.ray(f64::from(x0 + x) + 0.5, f64::from(y0 + y) + 0.5);
            org.push(o.map(|c| c as f32));
            dir.push(d.map(|c| c as f32));
        }
    }
    let n = org.len();
    RayStream::from_rays(StreamKind::Primary, org, dir, vec![f32::INFINITY; n])
}

/// The sampled tiles: one at a seeded place in each of `groups` equal
/// strata of the frame's tiles in raster order, with the tile before it.
fn plan(groups: usize, seed: u64) -> Vec<(Option<usize>, usize)> {
    let (tw, th) = tiles_wide();
    strata_with_previous((tw * th) as usize, groups, seed)
}

/// Hits per pixel-centre ray (every hit the f64 reference finds) over
/// every pixel of the frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct HitStats {
    /// Mean hits per ray.
    pub(crate) mean: f64,
    /// The 95th percentile (nearest rank).
    pub(crate) p95: u32,
    /// The most hits of any ray ("the maximum number of valid
    /// ray/primitive intersections").
    pub(crate) max: u32,
    /// Rays counted (every pixel).
    pub(crate) rays: usize,
}

impl HitStats {
    /// The statistics of per-ray hit counts.
    pub(crate) fn of(mut counts: Vec<u32>) -> HitStats {
        counts.sort_unstable();
        let n = counts.len();
        let mean = counts.iter().map(|&c| f64::from(c)).sum::<f64>() / n.max(1) as f64;
        // Nearest rank: the smallest count at or above 95% of the rays.
        let rank = (0.95 * n as f64).ceil() as usize;
        HitStats {
            mean,
            p95: counts.get(rank.max(1) - 1).copied().unwrap_or(0),
            max: counts.last().copied().unwrap_or(0),
            rays: n,
        }
    }

    /// What an N_query is read against: the most, mean and 95th-percentile
    /// hits per ray, each at least the smallest positive value.
    pub(crate) fn scales(&self) -> [(&'static str, f64); 3] {
        [
            ("max_hits", f64::from(self.max.max(1))),
            ("mean_hits", self.mean.max(f64::MIN_POSITIVE)),
            ("p95_hits", f64::from(self.p95.max(1))),
        ]
    }

    /// Count every pixel's hits with the reference.
    fn over_every_pixel(cam: &Camera, refi: &Reference) -> HitStats {
        let counts: Vec<u32> = (0..HEIGHT)
            .into_par_iter()
            .flat_map_iter(|y| {
                (0..WIDTH).map(move |x| {
                    let (o, d) = cam.ray(f64::from(x) + 0.5, f64::from(y) + 0.5);
                    let ray = Ray::new(o.map(|c| c as f32 as f64), d.map(|c| c as f32 as f64));
                    refi.all(&ray).len() as u32
                })
            })
            .collect();
        HitStats::of(counts)
    }
}

impl Prepared {
    /// Load `stand`'s scene at 1024x768 from its viewpoint with its trees,
    /// count every pixel's hits, and plan `groups` runs.
    pub(crate) fn new(stand: Stand, groups: usize, seed: u64) -> AppResult<Prepared> {
        let mut scene = Scene::load(stand.scene)?;
        let cam = &mut scene.config.camera;
        if let Some(v) = stand.view {
            (cam.eye, cam.target, cam.fov) = (v.eye, v.target, v.fov);
        }
        (cam.width, cam.height) = (WIDTH, HEIGHT);
        let (b2, _) = scene::bvh_cache::build(&scene.mesh, &BVH).map_err(AppError)?;
        let b4 = scene::bvh::Bvh4::collapse(&b2);
        let tree = Arc::new(Tree {
            mesh: scene.mesh.clone(),
            b2,
            b4,
        });
        let cam = scene.config.camera.clone();
        let refi = Reference::with_bvh(&tree.mesh, &tree.b2);
        let hits = HitStats::over_every_pixel(&cam, &refi);
        let with = |k: usize, timed: bool| {
            let rays = tile_rays(&cam, k);
            let slots = packet_slots(&rays, TILE, 1, 8);
            let all = if timed {
                (0..rays.len())
                    .into_par_iter()
                    .map(|i| refi.all(&rays.ray(i)))
                    .collect()
            } else {
                Vec::new()
            };
            TileRays {
                rays: Arc::new(rays),
                slots: Arc::new(slots),
                all,
            }
        };
        let tiles: Vec<_> = plan(groups, seed)
            .into_iter()
            .map(|(before, k)| (before.map(|b| with(b, false)), with(k, true)))
            .collect();
        Ok(Prepared {
            embree: match embree_peer::available() {
                Ok(()) => Some(crate::embree::Embree::new(&tree.mesh).map_err(AppError)?),
                Err(_) => None,
            },
            stand,
            name: stand.name.into(),
            tree,
            hits,
            tiles,
        })
    }

    /// The most hits, at least 1.
    pub(crate) fn max_hits(&self) -> u32 {
        self.hits.max.max(1)
    }

    /// The rays of the timed tiles, with their packet slots.
    pub(crate) fn timed_rays(&self) -> impl Iterator<Item = (&RayStream, &[u32])> {
        self.tiles
            .iter()
            .map(|t| (&*t.1.rays, t.1.slots.as_slice()))
    }

    /// Rays of a timed tile where Embree's hits (`rtcIntersect1` and
    /// `rtcIntersect8`, the same filter) differ from ours or from the
    /// reference's (none without Embree).
    fn embree_mismatches(
        &self,
        (tile, rays, refi): (&TileRays, &[Ray], &Reference),
        (method, n_query): (Method, u32),
        ours: &[Vec<Hit>],
    ) -> usize {
        use crate::embree::Call;
        let Some(embree) = &self.embree else {
            return 0;
        };
        let mut bad = 0;
        for call in [Call::One, Call::Eight] {
            let theirs = embree.trace(&tile.rays, (method, n_query), call, &tile.slots);
            let label = format!("{} embree {call:?} {method:?}", self.name);
            bad += list_mismatches(&label, refi, rays, &tile.all, n_query, &theirs);
            let test = scene::agreement::F32Test::MollerTrumbore;
            let differ: Vec<usize> = (0..rays.len())
                .filter(|&i| {
                    let (t, o) = (&theirs[i], &ours[i]);
                    !scene::multi_agreement::same_up_to_cracks(
                        test,
                        refi,
                        &rays[i],
                        &tile.all[i],
                        t,
                        o,
                    )
                })
                .collect();
            if let Some(&i) = differ.first() {
                eprintln!(
                    "{label} N={n_query} ray {i}: embree {:?} ours {:?}",
                    theirs[i], ours[i]
                );
            }
            bad += differ.len();
        }
        bad
    }

    /// N_query values: 1, 2, 4 and every 10% of the scene's most hits
    /// (rounded to the nearest, at least 1), in order, each once.
    pub(crate) fn queries(&self) -> Vec<u32> {
        queries(self.max_hits())
    }
}

/// [`Prepared::queries`] for a scene whose most hits is `max`.
pub(crate) fn queries(max: u32) -> Vec<u32> {
    let tenths = (1..=10).map(|k| ((f64::from(max) * f64::from(k) / 10.0).round() as u32).max(1));
    let mut q: Vec<u32> = [1, 2, 4]
        .into_iter()
        .filter(|&n| n <= max)
        .chain(tenths)
        .collect();
    q.sort_unstable();
    q.dedup();
    q
}

/// The kernel over tiles as units: the scene laid out once.
struct Units {
    kernel: Kernel,
    n_query: u32,
    insertion: Insertion,
    tree: Arc<Tree>,
}

impl UnitProgram for Units {
    type Laid = rt::layout::Bvh4Bufs;
    type Unit = (Arc<RayStream>, Arc<Vec<u32>>);
    type Out = (Vec<Vec<Hit>>, Counters);

    fn lay_out<M: Machine>(&self, m: &mut M) -> Self::Laid {
        self.tree.lay_out(m)
    }

    fn unit<M: Machine>(&self, m: &mut M, laid: &Self::Laid, u: &Self::Unit) -> Self::Out {
        let run = Run {
            kernel: self.kernel,
            n_query: self.n_query,
            capacity: NAIVE_CAPACITY.max(self.n_query),
            tree: self.tree.clone(),
            rays: u.0.clone(),
            slots: Some(u.1.clone()),
            insertion: self.insertion,
        };
        run.trace_on(m, laid)
    }
}

/// One method at one N_query on one scene.
pub(crate) struct Cell {
    /// Millions of hits per second on one core.
    pub(crate) mhits: f64,
    /// 95% CI half-width of `mhits`.
    pub(crate) ci: Option<f64>,
    /// Each run's cycles, in sample order (the same tiles for every cell).
    pub(crate) run_cycles: Vec<f64>,
    /// Hits returned per ray (timed tiles).
    pub(crate) hits_per_ray: f64,
    /// Simulated instructions per ray and cycles per instruction.
    pub(crate) instr_per_ray: f64,
    pub(crate) cpi: f64,
    /// Share of the cycles in the filter and sort (`Region::Shading`).
    pub(crate) filter_share: f64,
    /// Filter calls per ray, and node tests per ray.
    pub(crate) candidates_per_ray: f64,
    /// Steps of node culling's insertion walk or naive's sort walk per ray
    /// (entry rows: one step serves a packet's lanes).
    pub(crate) steps_per_ray: f64,
    pub(crate) nodes_per_ray: f64,
    /// Ops simulated (timed and warmed).
    pub(crate) ops: u64,
    /// Rays whose list differed from the reference.
    pub(crate) bad: usize,
}

/// Time `method` at `n_query` over the sampled tiles of `pr` on one core of `m`.
pub(crate) fn measure(
    m: &sim::MachineConfig,
    pr: &Prepared,
    (method, n_query, insertion): (Method, u32, Insertion),
    progress: &Progress,
) -> AppResult<Cell> {
    let kernel = Kernel::new(Traversal::Packet, method);
    let prog = Units {
        kernel,
        n_query,
        insertion,
        tree: pr.tree.clone(),
    };
    let mut units = Vec::new();
    for (before, tile) in &pr.tiles {
        if let Some(b) = before {
            units.push((b, Detail::Warmed, false));
        }
        units.push((tile, Detail::Warmed, false));
        units.push((tile, Detail::Timed, true));
    }
    progress.add_units(units.len() as u64);
    let placed = units.iter().map(|(t, d, _)| {
        let unit = (t.rays.clone(), t.slots.clone());
        (Placed { thread: 0, unit }, *d)
    });
    let mut session = sim::Session::new(m);
    let (mut ops, mut bad, mut next) = (0u64, 0usize, 0usize);
    let (mut pairs, mut c) = (Vec::new(), Counters::default());
    let (mut instr, mut filter_cycles) = (0f64, 0f64);
    isa::run_units(
        &prog,
        m.flavour(),
        "multihit",
        placed,
        |_, _, t, (lists, cn)| {
            let (tile, _, timed) = units[next];
            next += 1;
            progress.done(1);
            ops += t.ops.len() as u64;
            if !timed {
                session.warm(&[(0, &t)]).map_err(AppError)?;
                isa::trace::recycle(t);
                return Ok(());
            }
            let rays: Vec<Ray> = (0..tile.rays.len()).map(|i| tile.rays.ray(i)).collect();
            let refi = Reference::with_bvh(&pr.tree.mesh, &pr.tree.b2);
            let label = format!("{} {}", pr.name, kernel.name());
            bad += list_mismatches(&label, &refi, &rays, &tile.all, n_query, &lists);
            bad += pr.embree_mismatches((tile, &rays, &refi), (method, n_query), &lists);
            let st = session.timed_queue(&[&t]).map_err(AppError)?;
            isa::trace::recycle(t);
            pairs.push((cn.hits as f64, st.cycles as f64));
            instr += st.ops as f64;
            filter_cycles += st.region_cycles[isa::Region::Shading as usize] as f64;
            add(&mut c, &cn);
            Ok::<(), AppError>(())
        },
    )?;
    let hz = m.clock_ghz * 1e9;
    let (hits, cycles) = pairs.iter().fold((0.0, 0.0), |a, p| (a.0 + p.0, a.1 + p.1));
    let rays = c.rays.max(1) as f64;
    Ok(Cell {
        mhits: hits / (cycles / hz) / 1e6,
        ci: systematic_ratio_ci(&pairs).map(|h| h * hz / 1e6),
        run_cycles: pairs.iter().map(|p| p.1).collect(),
        hits_per_ray: hits / rays,
        instr_per_ray: instr / rays,
        cpi: cycles / instr.max(1.0),
        filter_share: filter_cycles / cycles.max(1.0),
        candidates_per_ray: c.candidates as f64 / rays,
        steps_per_ray: c.steps as f64 / rays,
        nodes_per_ray: c.tests.other as f64 / rays,
        ops,
        bad,
    })
}

/// Sum the counters a cell reports.
fn add(c: &mut Counters, d: &Counters) {
    c.rays += d.rays;
    c.hits += d.hits;
    c.candidates += d.candidates;
    c.steps += d.steps;
    c.tests.other += d.tests.other;
}
