//! # rtsim timing model
//!
//! Turns op streams ([`isa::Trace`]) into cycles, CPI, cache lines and DRAM
//! bytes on a configured machine ([`MachineConfig`]). Never sees a kernel.
//!
//! Fidelity is a choice ([`Fidelity`]): `counts` (a resource bound from op
//! counts, no caches), `caches` (the same plus simulated caches and a miss
//! penalty estimate), `full` (the out-of-order or in-order core model with the
//! memory system). `rtsim fidelity` measures each faster mode against `full`.

#![warn(missing_docs)]

pub mod config;
mod frontend;
pub mod inorder;
pub mod memory;
pub mod ooo;
pub mod predictor;
pub mod session;
mod smt;
pub mod stats;

pub use config::{CoreKind, MachineConfig};
pub use memory::Hierarchy;
pub use session::{Session, UnitTimed};
pub use stats::{OpTimes, PerRay, Stall, Stats};

use isa::{OpClass, Trace, ValId};

/// How much to model.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Fidelity {
    /// Op counts and a resource bound on cycles; no caches.
    Counts,
    /// Counts plus simulated caches (exact hits, misses, DRAM bytes) and a
    /// miss-penalty estimate of cycles.
    Caches,
    /// The full core model with the memory system.
    Full,
}

impl Fidelity {
    /// Every mode, fastest first.
    pub const ALL: [Fidelity; 3] = [Fidelity::Counts, Fidelity::Caches, Fidelity::Full];
    /// Stable name.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Fidelity::Counts => "counts",
            Fidelity::Caches => "caches",
            Fidelity::Full => "full",
        }
    }
    /// The mode with this name.
    #[must_use]
    pub fn from_name(s: &str) -> Option<Fidelity> {
        Fidelity::ALL.into_iter().find(|f| f.name() == s)
    }
}

/// Options of a run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SimOptions {
    /// Fidelity.
    pub fidelity: Fidelity,
    /// Ops of each trace that only warm caches and predictors (not counted).
    pub warmup_ops: usize,
    /// Record the pipeline timeline ([`Stats::timeline`]) of the ops of
    /// the first trace from this index, this many (full fidelity,
    /// out-of-order machines).
    pub timeline: Option<(usize, usize)>,
}

impl Default for SimOptions {
    fn default() -> Self {
        SimOptions {
            fidelity: Fidelity::Full,
            warmup_ops: 0,
            timeline: None,
        }
    }
}

/// Simulate `traces` on `m`: for an out-of-order machine one trace per core
/// (at most `cores`); for an in-order machine the hardware threads of one
/// core (at most `threads`).
pub fn simulate(m: &MachineConfig, traces: &[&Trace], opt: &SimOptions) -> Result<Stats, String> {
    if traces.is_empty() {
        return Err("nothing to simulate: no trace".into());
    }
    for t in traces {
        if t.flavour != m.flavour() {
            return Err(format!(
                "the trace is {} code but machine {} runs {} code",
                t.flavour, m.name, m.isa
            ));
        }
    }
    let lanes = m.flavour().lanes();
    let mut s = Stats::new(lanes);
    let units = traces.len();
    let cores = match m.core.kind {
        CoreKind::OutOfOrder => {
            if units > m.cores as usize {
                return Err(format!(
                    "{units} traces for {} cores of {}",
                    m.cores, m.name
                ));
            }
            units
        }
        CoreKind::InOrder => {
            if units > m.core.threads as usize {
                return Err(format!(
                    "{units} traces for {} threads of {}",
                    m.core.threads, m.name
                ));
            }
            1
        }
    };
    let mut mem = Hierarchy::new(m, cores);
    match opt.fidelity {
        Fidelity::Full => match m.core.kind {
            CoreKind::OutOfOrder => full_ooo(m, traces, &mut mem, &mut s, opt),
            CoreKind::InOrder => {
                s.cycles = inorder::run(m, traces, &mut mem, &mut s, opt.warmup_ops);
                // Cycles of the counted part only: time of the warm-up removed pro rata.
                if opt.warmup_ops > 0 {
                    let total: u64 = traces
                        .iter()
                        .flat_map(|t| &t.ops)
                        .map(|o| stats::instructions(o.class))
                        .sum();
                    let counted = s.ops as f64 / total.max(1) as f64;
                    s.cycles = (s.cycles as f64 * counted).round() as u64;
                }
            }
        },
        Fidelity::Counts | Fidelity::Caches => estimate(m, traces, &mut mem, &mut s, opt),
    }
    s.levels = mem.stats.clone();
    s.level_names = m.caches.iter().map(|c| c.name.clone()).collect();
    s.dram_read = mem.dram_read;
    s.dram_written = mem.dram_written;
    s.dram_read_by_region = mem.dram_read_by_region.clone();
    s.dram_prefetched_by_region = mem.dram_prefetched_by_region.clone();
    s.tlb = mem.tlb_stats();
    Ok(s)
}

fn full_ooo(
    m: &MachineConfig,
    traces: &[&Trace],
    mem: &mut Hierarchy,
    s: &mut Stats,
    opt: &SimOptions,
) {
    let warmup = opt.warmup_ops;
    let mut cores: Vec<ooo::OooCore> = (0..traces.len()).map(|c| ooo::OooCore::new(m, c)).collect();
    cores[0].timeline = opt
        .timeline
        .map(|(start, n)| ooo::Timeline::new(start..start.saturating_add(n)));
    let mut pos = vec![0usize; traces.len()];
    let mut start = vec![None::<u64>; traces.len()];
    // Interleave cores in chunks so shared levels and DRAM see them together.
    const CHUNK: usize = 4096;
    loop {
        let mut any = false;
        for (k, t) in traces.iter().enumerate() {
            if pos[k] >= t.ops.len() {
                continue;
            }
            any = true;
            let end = (pos[k] + CHUNK).min(t.ops.len());
            if start[k].is_none() && warmup < end {
                // Run up to the warm-up boundary first, note the time, then go on.
                let w = warmup.max(pos[k]);
                cores[k].run(t, pos[k]..w, mem, s, warmup);
                start[k] = Some(cores[k].now);
                cores[k].run(t, w..end, mem, s, warmup);
            } else {
                cores[k].run(t, pos[k]..end, mem, s, warmup);
            }
            pos[k] = end;
        }
        if !any {
            break;
        }
    }
    if let Some(tl) = cores[0].timeline.take() {
        s.timeline = tl.events;
    }
    s.cycles = cores
        .iter()
        .zip(&start)
        .map(|(c, st)| c.now - st.unwrap_or(c.now))
        .max()
        .unwrap_or(0);
}

/// Counts (and caches): cycles = max(dispatch bound, busiest port) plus, with
/// caches, the latency beyond L1 of every miss divided by the miss slots.
fn estimate(
    m: &MachineConfig,
    traces: &[&Trace],
    mem: &mut Hierarchy,
    s: &mut Stats,
    opt: &SimOptions,
) {
    let classes = ooo::class_table(m);
    let ports = m.core.ports as usize;
    let l1 = u64::from(m.caches[0].latency);
    let mut worst = 0f64;
    for t in traces {
        let mut busy = vec![0u64; ports];
        let mut fused = 0u64;
        let mut miss_cycles = 0u64;
        let mut branches = 0u64;
        for (i, op) in t.ops.iter().enumerate() {
            let ct = &classes[op.class as usize];
            if opt.fidelity == Fidelity::Caches && op.class.is_mem() {
                let now = fused / u64::from(m.core.width);
                for (a, bytes) in t.accesses(op) {
                    for a in mem.span(a.0, bytes) {
                        let sv = mem.access(0, a, op.class.is_store(), op.mem, now);
                        if op.class.is_load() {
                            miss_cycles += sv.latency.saturating_sub(l1);
                        }
                    }
                }
            }
            if i < opt.warmup_ops {
                continue;
            }
            for &mask in ct.uops.iter() {
                let p = (0..ports)
                    .filter(|p| mask >> p & 1 == 1)
                    .min_by_key(|&p| busy[p])
                    .expect("a port");
                busy[p] += ct.occ;
            }
            fused += u64::from(ct.fused);
            s.ops += crate::stats::instructions(op.class);
            s.uops += ct.uops.len() as u64;
            s.region_ops[op.region as usize] += crate::stats::instructions(op.class);
            s.class_ops[op.class as usize] += 1;
            branches += u64::from(op.class == OpClass::Branch);
            if op.class.is_vector() {
                s.vector_ops += 1;
                s.active_lanes += u64::from(op.mask.count());
            }
        }
        s.branches += branches;
        let threads = if m.core.kind == CoreKind::InOrder {
            traces.len() as f64
        } else {
            1.0
        };
        let issue = fused as f64 / f64::from(m.core.width);
        let port = busy.iter().copied().max().unwrap_or(0) as f64;
        let mem_stall = miss_cycles as f64 / f64::from(m.mshrs) / threads;
        worst = worst.max(issue.max(port) + mem_stall);
    }
    let total = if m.core.kind == CoreKind::InOrder {
        // Threads share the core: their bounds add up.
        worst * traces.len() as f64
    } else {
        worst
    };
    s.cycles = total.round() as u64;
    let per_op = s.cycles as f64 / s.ops.max(1) as f64;
    for r in 0..isa::Region::COUNT {
        s.region_cycles[r] = (s.region_ops[r] as f64 * per_op).round() as u64;
    }
    s.stalls[Stall::Issue as usize] = s.cycles;
}

/// Repeat a loop body `n` times, renaming values so iteration k's ops read
/// iteration k's values; a source defined later in the body (or by the op
/// itself) is loop-carried and reads the previous iteration's value. In
/// the first iteration a carried value is ready from the start: it is
/// dropped, and a store whose address was it computes its address at
/// dispatch (its address flag cleared, so its data is not taken for it).
#[must_use]
pub fn repeat(body: &Trace, n: usize) -> Trace {
    let stride = body.ops.iter().map(|o| o.dst.0).max().unwrap_or(0);
    let mut defined_at = std::collections::HashMap::new();
    for (i, o) in body.ops.iter().enumerate() {
        if o.dst.is_some() {
            defined_at.entry(o.dst).or_insert(i);
        }
    }
    let mut t = Trace {
        ops: Vec::with_capacity(body.ops.len() * n),
        lane_addrs: Vec::with_capacity(body.lane_addrs.len() * n),
        ..body.clone()
    };
    t.params.push(("iterations".into(), n.to_string()));
    for k in 0..n as u32 {
        let base = k * stride;
        for (i, o) in body.ops.iter().enumerate() {
            let mut op = *o;
            if op.dst.is_some() {
                op.dst = ValId(o.dst.0 + base);
            }
            op.nsrc = 0;
            for (j, &src) in o.sources().iter().enumerate() {
                let carried = defined_at.get(&src).is_none_or(|&at| at >= i);
                let renamed = match (carried, defined_at.contains_key(&src)) {
                    (false, _) => ValId(src.0 + base),
                    (true, true) if k > 0 => ValId(src.0 + base - stride),
                    _ => ValId::NONE, // first iteration: the carried value is ready
                };
                if j == 0 && o.has_addr_src() && !renamed.is_some() {
                    op.flags &= !isa::trace::FLAG_ADDR;
                }
                op.push_src(renamed);
            }
            if op.class.is_per_lane_mem() {
                let lanes = body.lanes_of(o);
                op.aux = t.lane_addrs.len() as u32;
                t.lane_addrs.extend_from_slice(lanes);
            }
            t.ops.push(op);
        }
    }
    t
}
