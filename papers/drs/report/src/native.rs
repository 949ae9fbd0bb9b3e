//! `rtsim native`: the traversal kernels run natively on this host over one
//! tile's stream of a scene — host rays per second, median and range over
//! repeated runs, every answer checked against the reference — and, where
//! the host has Embree 3, its `rtcIntersect1`, `rtcIntersect8` and
//! `rtcIntersect1M` over exactly the same rays.

use crate::run::{stream_input, tile_stream};
use drs_kernels::methods::{Kernel, Laid, Run, Scratch};
use isa::{FlavourId, Machine, Program};
use repro::host::HostCpu;
use repro::report::Format;
use repro::{AppError, AppResult, Report, Row};
use rt::hand::{Bvh4View, NodeWidth};
use rt::layout::Bvh4Bufs;
use scene::loaded::Loaded;
use scene::workload::{RayStream, Tile};
use scene::Hit;
use std::time::Instant;

/// What `rtsim native` runs.
#[derive(Clone, Debug)]
pub struct NativeArgs {
    /// Scene name or file.
    pub scene: String,
    /// `primary`, `bounce` or `shadow`.
    pub stream: String,
    /// Tile side in pixels.
    pub tile: u32,
    /// Samples per pixel.
    pub spp: u32,
    /// Ray seed.
    pub seed: u64,
    /// Timed runs per method (after one untimed, checked run).
    pub repeat: u32,
    /// The kernels (every kernel the ISA runs when empty).
    pub kernels: Vec<Kernel>,
    /// The ISA whose semantics the native backend runs.
    pub isa: FlavourId,
    /// Extra Embree device configuration (`key=value,...`), or `None`
    /// for Embree's defaults.
    pub embree_config: Option<String>,
    /// Output format.
    pub format: Format,
}

/// One method's native timings over a stream.
#[derive(Clone, Debug)]
pub struct Timing {
    /// Kernel name, `hand-single-bvh4` or `hand-single-bvh4-ymm` (the twin), or `embree-1`, `embree-8`, `embree-1m`.
    pub method: String,
    /// Seconds of each timed run, sorted.
    pub seconds: Vec<f64>,
    /// Rays whose answer differs from the reference's.
    pub mismatches: usize,
}

impl Timing {
    /// Median seconds per run.
    #[must_use]
    pub fn median(&self) -> f64 {
        let s = &self.seconds;
        let n = s.len();
        if n % 2 == 1 {
            s[n / 2]
        } else {
            0.5 * (s[n / 2 - 1] + s[n / 2])
        }
    }
    fn of(method: &str, mut seconds: Vec<f64>, mismatches: usize) -> Timing {
        seconds.sort_by(f64::total_cmp);
        Timing {
            method: method.to_string(),
            seconds,
            mismatches,
        }
    }
}

/// Every kernel run once (its answers kept), then `repeat` rounds that
/// time each kernel once in turn, each run's buffers released after it. A
/// slow spell of the host (another tenant's load, a clock change) then
/// falls on every kernel alike instead of on whichever ran through it: run
/// back to back, one kernel's median moved up to 2x between invocations on
/// a shared 2-vCPU host. Each tree is laid out once and shared by the
/// kernels reading it, and the DRS kernels' ray lists allocated once
/// ([`Run::scratch`]).
struct Interleaved<'a> {
    runs: &'a [Run<'a>],
    /// Timed after the kernels in every round.
    peers: &'a [Peer<'a>],
    repeat: u32,
    /// Whether the kernels' hand-written twins ([`Run::trace_hand`]) are
    /// timed too (after the kernels, before the peers).
    hand: bool,
}

/// A method timed in the kernels' rounds (Embree's calls): its name, the
/// answers of its checked run that differ from the reference, and the call.
struct Peer<'a> {
    name: &'static str,
    mismatches: usize,
    call: Box<dyn Fn() + 'a>,
}

impl Interleaved<'_> {
    /// Each run's layout (one per tree, shared by the kernels reading it)
    /// and its scratch buffers, on `m`.
    fn lay_out<M: Machine>(&self, m: &mut M) -> Vec<(Laid, Scratch)> {
        let mut trees: [Option<Laid>; 2] = [None, None];
        self.runs
            .iter()
            .map(|r| {
                let t = usize::from(r.kernel.reads_bvh2());
                let laid = trees[t].get_or_insert_with(|| r.lay_out(m)).clone();
                let scratch = r.scratch(m, &laid);
                (laid, scratch)
            })
            .collect()
    }

    /// The twins this host runs: per run whose kernel has a hand-written
    /// twin, at each node width, the run's index, the width and its BVH4
    /// layout (a copy sharing the bytes, which the twin reads).
    fn twins(&self, laid: &[(Laid, Scratch)]) -> Vec<(Twin, Bvh4Bufs)> {
        if !self.hand || !rt::hand::available() {
            return Vec::new();
        }
        (self.runs.iter().zip(laid).enumerate())
            .filter(|(_, (r, _))| r.kernel == Kernel::SingleBvh4)
            .filter_map(|(i, (_, (l, _)))| Some((i, l.bvh4.clone()?)))
            .flat_map(|(i, b)| [NodeWidth::Xmm, NodeWidth::Ymm].map(|w| ((i, w), b.clone())))
            .collect()
    }
}

/// Answers of a method's checked run and the seconds of its timed runs.
type Timed = (Vec<Hit>, Vec<f64>);

/// A hand-written twin: its kernel's run (an index) and its node width.
type Twin = (usize, NodeWidth);

/// Per kernel its [`Timed`]; per twin its [`Twin`] and [`Timed`]; per peer
/// its timed seconds.
type Rounds = (Vec<Timed>, Vec<(Twin, Timed)>, Vec<Vec<f64>>);

impl Program for Interleaved<'_> {
    type Out = Rounds;
    fn run<M: Machine>(&self, m: &mut M) -> Rounds {
        let mut laid = self.lay_out(m);
        let mark = m.space().mark();
        let mut ours: Vec<(Vec<Hit>, Vec<f64>)> = (self.runs.iter().zip(&mut laid))
            .map(|(r, (l, s))| {
                let (first, _) = r.trace_in(m, l, s);
                m.space().release(mark);
                (first, Vec::new())
            })
            .collect();
        let twin_bufs = self.twins(&laid);
        let views: Vec<(Twin, Bvh4View)> = (twin_bufs.iter())
            .map(|(t, b)| (*t, Bvh4View::new(b).expect("a BVH4 as rt lays it out")))
            .collect();
        let hand_trace = |(i, w): Twin, v: &Bvh4View| {
            self.runs[i].trace_hand(v, w).expect("a kernel with a twin")
        };
        let mut hand: Vec<(Twin, Timed)> = (views.iter())
            .map(|(t, v)| (*t, (hand_trace(*t, v), Vec::new())))
            .collect();
        let records: Vec<(Vec<f32>, Vec<f32>)> = (views.iter())
            .map(|((i, _), _)| self.runs[*i].hand_records())
            .collect();
        let mut theirs = vec![Vec::new(); self.peers.len()];
        for _ in 0..self.repeat {
            for ((r, (l, s)), (_, secs)) in self.runs.iter().zip(&mut laid).zip(&mut ours) {
                // Only the kernel is timed: its rays laid out before, its
                // answers read back after (host work the model does not see).
                let mut staged = r.stage(m);
                let t = Instant::now();
                let tests = r.trace_staged(m, l, &mut staged, s);
                secs.push(t.elapsed().as_secs_f64());
                std::hint::black_box((staged.answers(), tests));
                m.space().release(mark);
            }
            for ((((i, w), v), (_, (_, secs))), (trav, isect)) in
                views.iter().zip(&mut hand).zip(&records)
            {
                let t = Instant::now();
                let recs = self.runs[*i].trace_hand_records(v, (trav, isect), *w);
                secs.push(t.elapsed().as_secs_f64());
                std::hint::black_box(recs);
            }
            for (p, secs) in self.peers.iter().zip(&mut theirs) {
                let t = Instant::now();
                (p.call)();
                secs.push(t.elapsed().as_secs_f64());
            }
        }
        (ours, hand, theirs)
    }
}

/// `kernels` natively on `fl` over `rays` (a tile of `tile` at `spp`) and,
/// where the host has Embree 3, its three calls on the same rays,
/// all in the same rounds on this thread ([`Interleaved`]): the kernels'
/// timings, then Embree's.
///
/// # Errors
/// When Embree cannot build the scene.
pub fn time_methods(
    ld: &Loaded,
    (tile, spp): (Tile, u32),
    rays: &RayStream,
    kernels: &[Kernel],
    fl: FlavourId,
    repeat: u32,
    embree_config: &str,
) -> AppResult<(Vec<Timing>, Vec<Timing>)> {
    let refi = ld.reference();
    let runs: Vec<Run> = kernels
        .iter()
        .map(|&k| {
            let mut run = Run::new(k, &ld.scene, &ld.b2, &ld.b4, rays.clone());
            run.packet_tile = Some((tile.size, spp));
            run
        })
        .collect();
    let embree = embree_setup(ld, (tile, spp), rays, embree_config)?;
    let peers = embree_peers(embree.as_ref(), ld, rays);
    let (timed, hand, peer_secs) = isa::run_native(
        &Interleaved {
            runs: &runs,
            peers: &peers,
            repeat,
            hand: fl == FlavourId::Avx2,
        },
        fl,
    );
    let ours = runs
        .iter()
        .zip(timed)
        .map(|(run, (first, secs))| {
            let name = run.kernel.name();
            Timing::of(name, secs, run.mismatches(name, &refi, &first))
        })
        .collect();
    let twins = hand.into_iter().map(|((i, w), (first, secs))| {
        let name = format!("hand-{}{}", runs[i].kernel.name(), w.suffix());
        let bad = runs[i].mismatches(&name, &refi, &first);
        Timing::of(&name, secs, bad)
    });
    let embree =
        (peers.iter().zip(peer_secs)).map(|(p, secs)| Timing::of(p.name, secs, p.mismatches));
    let theirs = twins.chain(embree).collect();
    Ok((ours, theirs))
}

/// Embree 3's scene (built once, not timed) and the packets the packet
/// kernels form (slots of 8 rays).
type EmbreeSetup = (embree_peer::Embree, Vec<u32>);

/// Embree's scene over `ld`'s mesh, or `None` on a host without Embree.
fn embree_setup(
    ld: &Loaded,
    (tile, spp): (Tile, u32),
    rays: &RayStream,
    config: &str,
) -> AppResult<Option<EmbreeSetup>> {
    if embree_peer::available().is_err() {
        return Ok(None);
    }
    let e = embree_peer::Embree::with_config(&ld.scene.mesh, None, config)
        .map_err(|e| AppError(format!("--embree-config: {e}")))?;
    Ok(Some((
        e,
        scene::workload::packet_slots(rays, tile.size, spp, 8),
    )))
}

/// Embree's `rtcIntersect1`, `rtcIntersect8` and `rtcIntersect1M` over
/// `rays`, each run once and checked against the reference.
fn embree_peers<'a>(
    setup: Option<&'a EmbreeSetup>,
    ld: &Loaded,
    rays: &'a RayStream,
) -> Vec<Peer<'a>> {
    let Some((e, slots)) = setup else {
        return Vec::new();
    };
    let refi = ld.reference();
    embree_peer::Call::ALL
        .iter()
        .map(|&call| {
            let mut first = e.trace(rays, call, slots);
            e.witnesses(rays, &mut first);
            let bad = drs_kernels::methods::stream_mismatches(call.name(), &refi, rays, &first);
            Peer {
                name: call.name(),
                mismatches: bad,
                call: Box::new(move || {
                    std::hint::black_box(e.trace(rays, call, slots));
                }),
            }
        })
        .collect()
}

/// The Embree device settings `--embree-config` may set (Embree ignores
/// keys it does not know, so a misspelt one would silently change nothing):
/// the triangle acceleration structure, its builder and traverser, and the
/// instruction set. `threads` stays 1 (the kernels run on one thread) and
/// `verbose` would print into the report.
pub const EMBREE_KEYS: [&str; 6] = [
    "tri_accel",
    "tri_builder",
    "tri_traverser",
    "isa",
    "max_isa",
    "frequency_level",
];

/// `--embree-config`: comma-separated `key=value` pairs, every key one of
/// [`EMBREE_KEYS`], every value non-empty.
///
/// # Errors
/// Naming the first pair that is not.
pub fn check_embree_config(c: &str) -> AppResult<()> {
    let bad = |what: String| Err(AppError(format!("--embree-config {c:?}: {what}")));
    if c.trim().is_empty() {
        return bad("empty".into());
    }
    for pair in c.split(',') {
        let Some((k, v)) = pair.split_once('=') else {
            return bad(format!("{pair:?} is not key=value"));
        };
        if !EMBREE_KEYS.contains(&k) {
            return bad(format!(
                "unknown key {k:?} (one of {})",
                EMBREE_KEYS.join(", ")
            ));
        }
        if v.is_empty() || v.contains(['=', ' ']) {
            return bad(format!("{k}: value {v:?}"));
        }
    }
    Ok(())
}

/// Rows of `timings` over `rays` rays: Mray/s median, slowest and fastest
/// run, time relative to the first timing named `base`, mismatches.
#[must_use]
pub fn timing_rows(timings: &[Timing], rays: usize, base: &str) -> Vec<Row> {
    let base = timings
        .iter()
        .find(|t| t.method == base)
        .map(Timing::median);
    let mray = |s: f64| rays as f64 / s / 1e6;
    let mut rows = Vec::new();
    for t in timings {
        let (lo, hi) = (t.seconds[t.seconds.len() - 1], t.seconds[0]);
        let m = |metric: &str, v: f64| Row::new(metric, v).key("method", &t.method);
        rows.push(m("mray_per_s", mray(t.median())).unit("Mray/s"));
        rows.push(m("mray_per_s_slowest", mray(lo)).unit("Mray/s"));
        rows.push(m("mray_per_s_fastest", mray(hi)).unit("Mray/s"));
        if let Some(b) = base {
            rows.push(m("time_vs_base", t.median() / b));
        }
        rows.push(m("hit_mismatches", t.mismatches as f64));
    }
    rows
}

/// `rtsim native`: the report, or an error when an answer differs from the
/// reference's.
///
/// # Errors
/// Bad options, an unloadable scene, Embree failing, or mismatches.
pub fn native_report(a: &NativeArgs) -> AppResult<Report> {
    let start = Instant::now();
    if a.tile == 0 || a.tile > 256 || a.spp == 0 || a.spp > 256 {
        return Err(AppError("--tile and --spp: must be 1 to 256".into()));
    }
    if a.repeat == 0 || a.repeat > 1000 {
        return Err(AppError("--repeat: must be 1 to 1000".into()));
    }
    if a.embree_config.is_some() {
        embree_peer::available().map_err(|e| AppError(format!("--embree-config: {e}")))?;
    }
    if let Some(c) = &a.embree_config {
        check_embree_config(c)?;
    }
    let kernels: Vec<Kernel> = if a.kernels.is_empty() {
        Kernel::ALL
            .into_iter()
            .filter(|k| k.supports(a.isa.lanes()))
            .collect()
    } else {
        a.kernels.clone()
    };
    if let Some(k) = kernels.iter().find(|k| !k.supports(a.isa.lanes())) {
        return Err(AppError(format!(
            "--kernel {}: runs on 4, 8, 16 and 32 lanes, {} has {} lanes",
            k.name(),
            a.isa,
            a.isa.lanes()
        )));
    }
    let ld = Loaded::load(&a.scene, &drs_kernels::BVH).map_err(AppError)?;
    let (tile, rays) = tile_stream(&ld, &a.stream, a.tile, a.spp, a.seed)?;
    let config = a.embree_config.as_deref().unwrap_or("");
    let (mut timings, embree) =
        time_methods(&ld, (tile, a.spp), &rays, &kernels, a.isa, a.repeat, config)?;
    timings.extend(embree);
    let bad: usize = timings.iter().map(|t| t.mismatches).sum();
    let mut rows = vec![Row::new("rays", rays.len() as f64)];
    rows.extend(timing_rows(&timings, rays.len(), Kernel::SingleBvh4.name()));
    let host = HostCpu::detect();
    let rep = Report {
        report: "native".into(),
        machine: None,
        isa: Some(a.isa.name().into()),
        fidelity: "native".into(),
        sample: None,
        input: Some(format!(
            "{}; host {}",
            stream_input(
                &timings
                    .iter()
                    .map(|t| t.method.as_str())
                    .collect::<Vec<_>>()
                    .join(", "),
                &ld.scene.config.name,
                &a.stream,
                tile,
                a.spp,
                a.seed,
            ),
            host.describe_build()
        )),
        ops_simulated: 0,
        host_seconds: start.elapsed().as_secs_f64(),
        rows,
        notes: vec![format!(
            "each method ran once untimed (its answers checked against the reference), then {} \
             timed runs on one host thread (every method in turn, round by round, Embree's calls \
             after the kernels, so a slow spell of the host falls on all); Mray/s of the median run, and of the slowest and \
             fastest; time_vs_base: median time over single-bvh4's; a kernel's time (and its \
             twin's) is its traversal alone, its rays laid out in its records or packets before \
             and its answers read back after, untimed, as the timing model sees it; Embree's \
             include filling its ray structs; the kernels run on the \
             native backend (the {} semantics; vector ops as {}); hand-single-bvh4 (avx2 \
             only, on a host with AVX2 and FMA) is single-bvh4's hand-written std::arch twin \
             (rt::hand: same algorithm, layout and answers, bit for bit, its node test in 4-lane \
             SSE registers as Embree 2.0's), hand-single-bvh4-ymm the same with the node test in \
             8-lane registers as the kernel runs it on an 8-lane machine, both timed after the \
             kernels and before Embree; Embree \
             rows (where the host has Embree 3: {}) build the scene robust at the default \
             quality, untimed (Embree device config: threads=1{}), and trace primary rays with \
             the coherent hint",
            a.repeat,
            a.isa,
            isa::host::describe(a.isa.lanes()),
            embree_peer::available().map_or_else(|e| e, |()| "found".into()),
            a.embree_config
                .as_ref()
                .map_or(String::new(), |c| format!(",{c}"))
        )],
    };
    if bad > 0 {
        print!("{}", rep.render(a.format));
        return Err(AppError(format!("{bad} answers differ from the reference")));
    }
    Ok(rep)
}
