//! Simulated frame rates: the distribution tracer's frame in render order
//! (tiles in raster order, each tile's streams in the order they are
//! traced) on one core of a machine, its caches, prefetchers and predictors
//! carried from stream to stream; a stratified sample of runs of
//! consecutive tiles timed in full detail after functional warming.

use crate::frame::{kind_key, Prepared};
use isa::{Detail, Machine, Placed, UnitProgram};
use mbvh_kernels::layout::{lay_out, MbvhBufs};
use mbvh_kernels::stats::Counters;
use mbvh_kernels::{Kernel, Run, Trees};
use rayon::prelude::*;
use repro::progress::Progress;
use repro::sampling::{mix, systematic_ratio_ci};
use repro::{AppError, AppResult};
use scene::agreement::{mismatches_expected, Expected, F32Test};
use scene::reference::Reference;
use scene::workload::{RayStream, Tile};
use scene::Hit;
use std::collections::BTreeMap;
use std::sync::Arc;

/// Pixels per side of a tile: a tile's streams are the renderer's batches
/// (16 x 16 pixels x 16 paths: 4096 primary rays, 16 groups of 2^8).
pub(crate) const TILE: u32 = 16;

/// One kernel over the frame's streams as units: the scene laid out once.
struct Units {
    kernel: Kernel,
    trees: Arc<Trees>,
}

impl UnitProgram for Units {
    type Laid = MbvhBufs;
    type Unit = Arc<RayStream>;
    type Out = (Vec<Hit>, Counters);

    fn lay_out<M: Machine>(&self, m: &mut M) -> MbvhBufs {
        let t = self.trees.of_width(M::LANES);
        lay_out(m, &self.trees.mesh, &self.trees.b2, t)
    }

    fn unit<M: Machine>(&self, m: &mut M, laid: &MbvhBufs, u: &Arc<RayStream>) -> Self::Out {
        let run = Run {
            kernel: self.kernel,
            trees: self.trees.clone(),
            rays: u.clone(),
        };
        run.trace_on(m, laid)
    }
}

/// What [`frame_rate`] measured.
pub(crate) struct Rate {
    /// Rays per frame (estimated from the sample; the primary rays exactly).
    pub(crate) rays: f64,
    /// Cycles per frame on one core.
    pub(crate) cycles: f64,
    /// Millions of rays per second on one core.
    pub(crate) mrays: f64,
    /// 95% CI half-width of `mrays`.
    pub(crate) ci: Option<f64>,
    /// Simulated instructions per ray (timed units).
    pub(crate) instr_per_ray: f64,
    /// Cycles per simulated instruction (timed units).
    pub(crate) cpi: f64,
    /// Per code region (`isa::Region` order): simulated instructions and
    /// cycles of the timed units.
    pub(crate) regions: [(f64, f64); isa::Region::COUNT],
    /// Each run's cycles, in sample order (runs pair across methods timed
    /// with the same seed: the same tiles and rays).
    pub(crate) run_cycles: Vec<f64>,
    /// Per stream kind of the frame ([`crate::frame::kind_key`]): timed
    /// cycles, rays, and rays that hit nothing.
    pub(crate) by_kind: BTreeMap<(u32, bool), (f64, f64, f64)>,
    /// Ops simulated for the whole sample (timed ops and warmed memory and
    /// branch ops; the same for every depth of one sample).
    pub(crate) ops: u64,
    /// Rays that differed from the reference, over the whole sample.
    pub(crate) bad: usize,
}

/// The sample design [`frame_rate`] follows, for the report's header.
pub(crate) fn design(groups: usize, per: usize) -> String {
    format!(
        "the frame's {TILE}x{TILE}-pixel tiles in raster order, each tile's streams (primary, shadow, reflection, shadow, ...) traced in turn in groups of rays on one core, its caches, prefetcher and predictors carried from stream to stream; {groups} runs of {per} consecutive tile(s), one at a seeded place in each of as many equal strata of the frame, timed in full detail after functional warming of their own streams (as the previous frame left them) and of the tile rendered just before; 95% CI over the runs (ratio estimator, successive differences)"
    )
}

/// The tiles of a run and the tile before it (warmed), by group.
fn plan(n_tiles: usize, groups: usize, per: usize, seed: u64) -> Vec<(Vec<usize>, Option<usize>)> {
    let per = per.clamp(1, n_tiles);
    let stride = (n_tiles / groups.max(1)).max(1);
    (0..groups.min(n_tiles))
        .map(|g| {
            let r = mix(seed ^ mix(g as u64 + 1));
            let offset = (r % (stride.saturating_sub(per) + 1) as u64) as usize;
            let first = (offset + g * stride).min(n_tiles - per);
            ((first..first + per).collect(), first.checked_sub(1))
        })
        .collect()
}

/// The timed streams of a run, as the core's hardware threads take them:
/// one thread, each stream alone; two (hyper-threading), each stream
/// beside the next one of the same kind (the same stream of the run's next
/// tile: two threads rendering a tile each, stream by stream), a stream
/// with no partner alone. Indices into `timed`, in order of first.
fn hardware_thread_sets(timed: &[((u32, bool), u64, usize)], threads: usize) -> Vec<Vec<usize>> {
    let mut used = vec![false; timed.len()];
    let mut sets = Vec::new();
    for i in 0..timed.len() {
        if used[i] {
            continue;
        }
        used[i] = true;
        let mut set = vec![i];
        for j in i + 1..timed.len() {
            if set.len() == threads {
                break;
            }
            if !used[j] && timed[j].0 == timed[i].0 {
                used[j] = true;
                set.push(j);
            }
        }
        sets.push(set);
    }
    sets
}

/// The smallest bounce depth whose frame traces the stream of key
/// ([`kind_key`]) `(d, shadow)`: primary rays 1, bounce d's rays d, the
/// shadow rays from bounce d's hits d + 1.
fn frame_depth((d, shadow): (u32, bool)) -> u32 {
    if shadow {
        d + 1
    } else {
        d.max(1)
    }
}

/// Rays per second of `kernel` over the frames of `pr` to 1, 2, ...,
/// `bounces` bounces on one core of `m` (its `cores` set to 1 by the
/// caller), from one sampled frame to `bounces`: a depth-b frame's streams
/// are the first of the deeper frame's in every tile, each timed on its own
/// in render order, so its rate is theirs (the deeper streams between tiles
/// are in the caches, which a depth-b frame would not have: the last depth's
/// figure is exact, the others an approximation `mbvh-fig3` checks).
pub(crate) fn frame_rates(
    m: &sim::MachineConfig,
    pr: &Prepared,
    kernel: Kernel,
    (bounces, groups, per, threads): (u32, usize, usize, usize),
    (seed, progress): (u64, &Progress),
) -> AppResult<Vec<Rate>> {
    let per_row = pr.res / TILE;
    let n_tiles = (per_row * per_row) as usize;
    let tile = |k: usize| Tile {
        x: k as u32 % per_row,
        y: k as u32 / per_row,
        size: TILE,
    };
    let groups_plan = plan(n_tiles, groups, per, seed);
    // Every tile the sample touches, its streams and (timed tiles) the
    // reference's answers, in parallel.
    let mut need: Vec<(usize, bool)> = Vec::new();
    for (run, before) in &groups_plan {
        need.extend(run.iter().map(|&k| (k, true)));
        need.extend(before.map(|k| (k, false)));
    }
    let refi = Reference::with_bvh(&pr.trees.mesh, &pr.trees.b2);
    let prepared: Vec<Vec<(Arc<RayStream>, Option<Expected>)>> = need
        .par_iter()
        .map(|&(k, timed)| {
            pr.streams(tile(k), bounces, seed)
                .into_iter()
                .filter(|s| !s.is_empty())
                .map(|s| {
                    let want = timed.then(|| Expected::of(&refi, &s));
                    (Arc::new(s), want)
                })
                .collect()
        })
        .collect();
    let mut units = Vec::new();
    // Per unit: (timed?, last unit of its group?, index into `prepared`).
    let mut roles = Vec::new();
    let mut at = 0;
    for (run, before) in &groups_plan {
        let n_units: usize = (0..run.len() + usize::from(before.is_some()))
            .map(|j| prepared[at + j].len())
            .sum();
        let mut j = 0;
        for t in 0..run.len() + usize::from(before.is_some()) {
            let timed = t < run.len();
            for (s, (stream, _)) in prepared[at + t].iter().enumerate() {
                j += 1;
                let d = if timed { Detail::Timed } else { Detail::Warmed };
                units.push((
                    Placed {
                        thread: 0,
                        unit: stream.clone(),
                    },
                    d,
                ));
                roles.push((timed, j == n_units, at + t, s));
            }
        }
        at += run.len() + usize::from(before.is_some());
    }
    progress.add_units(units.len() as u64);
    let prog = Units {
        kernel,
        trees: pr.trees.clone(),
    };
    let mut session = sim::Session::with_threads(m, threads).map_err(AppError)?;
    let (mut ops, mut bad) = (0u64, 0usize);
    let depths = bounces as usize;
    // Per depth, per group: (cycles, rays) of the frame to that depth.
    let mut pairs: Vec<Vec<(f64, f64)>> = vec![Vec::new(); depths];
    // Per depth: simulated instructions of the timed units, and per region.
    let mut instr = vec![0f64; depths];
    let mut regions = vec![[(0f64, 0f64); isa::Region::COUNT]; depths];
    // Per stream kind: (cycles, rays, misses) of the timed units.
    let mut by_kind: BTreeMap<(u32, bool), (f64, f64, f64)> = BTreeMap::new();
    // The group's timed traces and each one's (stream key, rays, misses).
    let (mut timed, mut timed_of) = (Vec::new(), Vec::new());
    let mut next = 0;
    isa::run_units(&prog, m.flavour(), "mbvh", units, |_, _, t, (hits, c)| {
        let (is_timed, last, k, s) = roles[next];
        next += 1;
        progress.done(1);
        ops += t.ops.len() as u64;
        session.warm(&[(0, &t)]).map_err(AppError)?;
        if is_timed {
            let (stream, want) = &prepared[k][s];
            let want = want.as_ref().expect("timed streams have answers");
            let label = format!("{} {} {:?}", pr.name, kernel.name(), stream.kind);
            bad += mismatches_expected(F32Test::MollerTrumbore, &label, &refi, stream, want, &hits);
            let misses = hits.iter().filter(|h| !h.is_hit()).count();
            timed_of.push((kind_key(stream.kind), c.rays, misses));
            timed.push(t);
        } else {
            isa::trace::recycle(t);
        }
        if last {
            let mut per = vec![(0.0, 0.0); depths];
            for set in hardware_thread_sets(&timed_of, threads) {
                let key = timed_of[set[0]].0;
                let rays: u64 = set.iter().map(|&i| timed_of[i].1).sum();
                let misses: usize = set.iter().map(|&i| timed_of[i].2).sum();
                let d = frame_depth(key);
                let refs: Vec<&isa::Trace> = set.iter().map(|&i| &timed[i]).collect();
                let st = session.timed_queue(&refs).map_err(AppError)?;
                let k = by_kind.entry(key).or_default();
                k.0 += st.cycles as f64;
                k.1 += rays as f64;
                k.2 += misses as f64;
                for (b, p) in per.iter_mut().enumerate() {
                    if d as usize <= b + 1 {
                        p.0 += st.cycles as f64;
                        p.1 += rays as f64;
                        instr[b] += st.ops as f64;
                        for (r, reg) in regions[b].iter_mut().enumerate() {
                            reg.0 += st.region_ops[r] as f64;
                            reg.1 += st.region_cycles[r] as f64;
                        }
                    }
                }
            }
            for (b, p) in per.into_iter().enumerate() {
                pairs[b].push(p);
            }
            timed.drain(..).for_each(isa::trace::recycle);
            timed_of.clear();
        }
        Ok::<(), AppError>(())
    })?;
    let tiles_timed = groups_plan.iter().map(|g| g.0.len()).sum::<usize>() as f64;
    let hz = m.clock_ghz * 1e9;
    Ok(pairs
        .iter()
        .zip(&instr)
        .enumerate()
        .map(|(b, (pairs, &ins))| {
            let (cyc, rays) = pairs
                .iter()
                .fold((0.0, 0.0), |(a, b), &(x, y)| (a + x, b + y));
            // Rays per cycle per run, a ratio of sums; its CI scaled to Mray/s.
            let per_cycle: Vec<(f64, f64)> = pairs.iter().map(|&(c, r)| (r, c)).collect();
            Rate {
                rays: rays / tiles_timed * n_tiles as f64,
                cycles: cyc / tiles_timed * n_tiles as f64,
                mrays: rays / (cyc / hz) / 1e6,
                ci: systematic_ratio_ci(&per_cycle).map(|h| h * hz / 1e6),
                instr_per_ray: ins / rays,
                cpi: cyc / ins,
                regions: regions[b],
                run_cycles: pairs.iter().map(|p| p.0).collect(),
                by_kind: by_kind
                    .iter()
                    .filter(|(k, _)| frame_depth(**k) <= b as u32 + 1)
                    .map(|(k, v)| (*k, *v))
                    .collect(),
                ops,
                bad,
            }
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hyper_threads_pair_the_same_stream_of_two_tiles() {
        let k = |d: u32, s: bool| ((d, s), 1u64, 0usize);
        let run = [
            k(0, false),
            k(0, true),
            k(1, false),
            k(0, false),
            k(0, true),
        ];
        assert_eq!(
            hardware_thread_sets(&run, 2),
            vec![vec![0, 3], vec![1, 4], vec![2]]
        );
        assert_eq!(
            hardware_thread_sets(&run, 1),
            (0..5).map(|i| vec![i]).collect::<Vec<_>>()
        );
    }

    #[test]
    fn runs_fall_in_their_strata_and_stay_in_the_frame() {
        for (n, g, per) in [(1024, 24, 1), (1024, 64, 2), (10, 24, 1), (5, 2, 3)] {
            let p = plan(n, g, per, 7);
            assert_eq!(p.len(), g.min(n));
            for (i, (run, before)) in p.iter().enumerate() {
                assert!(run.iter().all(|&k| k < n) && !run.is_empty());
                assert_eq!(*before, run[0].checked_sub(1));
                if n >= g * per {
                    let stride = n / g;
                    assert!(
                        run[0] >= i * stride && run[0] < (i + 1) * stride,
                        "{n} {g} {i}"
                    );
                }
            }
        }
        assert_eq!(plan(1024, 24, 1, 7), plan(1024, 24, 1, 7));
        assert_ne!(plan(1024, 24, 1, 7), plan(1024, 24, 1, 8));
    }
}
