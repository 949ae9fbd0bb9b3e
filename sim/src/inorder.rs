//! The in-order, multi-threaded core (Larrabee class). Each cycle one
//! hardware thread is chosen round-robin among those that can issue; it
//! issues up to `width` ops in program order, each needing every source ready
//! (stall on use) and a free pipe from its class's set (vector ops: the U pipe
//! only; scalar ops pair on U or V). With `no_back_to_back` a thread cannot
//! issue in two consecutive cycles (Knights Corner). A mispredicted branch
//! stops its thread until it resolves plus the penalty; loads do not block
//! until their result is used. A memory operand folded into its op
//! (`vloadfold`, fused: 0) takes neither an issue slot nor a pipe, and on an
//! L1 hit delays its op by nothing.

use crate::config::MachineConfig;
use crate::memory::Hierarchy;
use crate::ooo::{class_table, ClassT, Values};
use crate::predictor::Predictor;
use crate::stats::{Stall, Stats};
use isa::{OpClass, Trace};

struct Thread<'a> {
    t: &'a Trace,
    pos: usize,
    values: Values,
    stall_until: u64,
    last_issue: Option<u64>,
    miss_until: u64,
    /// The level the miss it waits for went to.
    miss_why: Stall,
    pred: Predictor,
}

/// The core's shared state: class timings, pipes, miss slots.
struct Core {
    classes: Vec<ClassT>,
    /// L1 latency (a per-lane access pays its lines beyond it).
    l1: u64,
    penalty: u64,
    width: usize,
    no_back_to_back: bool,
    pipe_free: Vec<u64>,
    mshr: crate::memory::Mshrs,
}

/// Time `traces` as the hardware threads of one in-order core; stats count
/// each thread's ops from its `count_from` index on.
pub fn run(
    m: &MachineConfig,
    traces: &[&Trace],
    mem: &mut Hierarchy,
    s: &mut Stats,
    count_from: usize,
) -> u64 {
    let c = &m.core;
    let mut preds: Vec<Predictor> = traces
        .iter()
        .map(|_| Predictor::new(c.history_bits, c.predictor_bits, c.tage.as_ref()))
        .collect();
    run_from(m, traces, &mut preds, mem, s, (count_from, 0))
}

/// [`run`] from cycle `start` with thread k's branch predictor `preds[k]`
/// (kept for the next unit); the cycle the last op completes.
pub fn run_from(
    m: &MachineConfig,
    traces: &[&Trace],
    preds: &mut [Predictor],
    mem: &mut Hierarchy,
    s: &mut Stats,
    (count_from, start): (usize, u64),
) -> u64 {
    run_queue(m, traces, &[], preds, mem, s, (count_from, start))
}

/// [`run_from`] where the threads, each done with its trace in `first`, take
/// the traces of `queue` in order (a thread that finishes takes the next
/// one, as a renderer's threads take work units); each thread keeps its
/// predictor across its units.
pub fn run_queue(
    m: &MachineConfig,
    first: &[&Trace],
    queue: &[&Trace],
    preds: &mut [Predictor],
    mem: &mut Hierarchy,
    s: &mut Stats,
    (count_from, start): (usize, u64),
) -> u64 {
    let traces = first;
    let mut next = 0usize;
    let c = &m.core;
    let mut core = Core {
        classes: class_table(m),
        l1: u64::from(m.caches[0].latency),
        penalty: u64::from(c.mispredict_penalty),
        width: c.width as usize,
        no_back_to_back: c.no_back_to_back,
        pipe_free: vec![0u64; c.ports as usize],
        mshr: crate::memory::Mshrs::new(m.mshrs as usize),
    };
    let mut th: Vec<Thread> = traces
        .iter()
        .zip(preds.iter_mut())
        .map(|(t, p)| Thread {
            t,
            pos: 0,
            values: Values::new(),
            stall_until: start,
            last_issue: None,
            miss_until: start,
            miss_why: Stall::MemoryL2,
            pred: std::mem::replace(p, Predictor::new(1, 1, None)),
        })
        .collect();
    let mut cycle = start;
    let mut rr = 0usize;
    let mut last_charge = 0u64;
    let mut max_done = 0u64;
    loop {
        let mut issued = 0usize;
        if let Some(i) = core.choose(&th, rr, cycle) {
            let t = &mut th[i];
            issued = core.issue(
                t,
                cycle,
                mem,
                s,
                (count_from, &mut last_charge, &mut max_done),
            );
            rr = i + 1;
        }
        for t in th.iter_mut().filter(|t| t.pos >= t.t.ops.len()) {
            let Some(&q) = queue.get(next) else { break };
            next += 1;
            t.t = q;
            t.pos = 0;
            t.values.restart();
        }
        if th.iter().all(|t| t.pos >= t.t.ops.len()) {
            break;
        }
        if issued > 0 {
            cycle += 1;
        } else {
            cycle = core.wait(&th, cycle, s);
        }
    }
    for (t, p) in th.into_iter().zip(preds.iter_mut()) {
        *p = t.pred;
    }
    cycle.max(max_done)
}

/// Functional warming of thread `pred`'s unit `t`: its accesses update the
/// caches and prefetcher, its branches the thread's predictor; untimed.
pub fn warm(t: &Trace, pred: &mut Predictor, mem: &mut Hierarchy, now: u64) {
    for op in &t.ops {
        mem.warm_op(0, t, op, now);
        if op.class == OpClass::Branch {
            pred.predict_and_update(op.site().0, op.taken());
        }
    }
}

impl Core {
    /// Earliest cycle thread `t`'s next op could issue (ignoring pipes), or
    /// None if it is done.
    fn earliest(&self, t: &Thread, cycle: u64) -> Option<u64> {
        let op = t.t.ops.get(t.pos)?;
        let mut e = cycle.max(t.stall_until);
        if self.no_back_to_back {
            if let Some(l) = t.last_issue {
                e = e.max(l + 2);
            }
        }
        for &v in op.sources() {
            e = e.max(t.values.get(v));
        }
        Some(e)
    }

    /// The thread that issues this cycle: round-robin from `rr` among those
    /// whose next op is ready and has a free pipe.
    fn choose(&self, th: &[Thread], rr: usize, cycle: u64) -> Option<usize> {
        let n = th.len();
        for k in 0..n {
            let i = (rr + k) % n;
            if self.earliest(&th[i], cycle) != Some(cycle) {
                continue;
            }
            let op = &th[i].t.ops[th[i].pos];
            let ct = &self.classes[op.class as usize];
            if !ct.uops.is_empty() && !any_free(ct.uops[0], &self.pipe_free, cycle) {
                continue;
            }
            return Some(i);
        }
        None
    }

    /// Issue up to `width` ops of thread `t` in order this cycle (each with
    /// its sources ready and a free pipe); the number issued.
    fn issue(
        &mut self,
        t: &mut Thread,
        cycle: u64,
        mem: &mut Hierarchy,
        s: &mut Stats,
        (count_from, last_charge, max_done): (usize, &mut u64, &mut u64),
    ) -> usize {
        let mut issued = 0usize;
        let mut used_pipes = 0u32;
        while issued < self.width {
            let Some(op) = t.t.ops.get(t.pos) else { break };
            if op.sources().iter().any(|v| t.values.get(*v) > cycle) {
                break;
            }
            let ct = &self.classes[op.class as usize];
            let pipe = if ct.uops.is_empty() {
                None
            } else {
                match first_free(ct.uops[0] & !used_pipes, &self.pipe_free, cycle) {
                    Some(p) => Some(p),
                    None => break,
                }
            };
            let nuops = ct.uops.len();
            // A folded memory operand (fused: 0) takes no issue slot.
            let slot = ct.fused > 0;
            let (done, occ, missed) = self.execute(t.t, op, cycle, mem);
            if let Some(p) = pipe {
                self.pipe_free[p] = cycle + occ;
                used_pipes |= 1 << p;
            }
            if op.dst.is_some() {
                t.values.set(op.dst, done);
            }
            *max_done = (*max_done).max(done);
            if let Some(why) = missed {
                if done > t.miss_until {
                    t.miss_until = done;
                    t.miss_why = why;
                }
            }
            if op.class == OpClass::Branch {
                let ok = t.pred.predict_and_update(op.site().0, op.taken());
                if t.pos >= count_from {
                    s.branches += 1;
                    s.mispredicts += u64::from(!ok);
                }
                if !ok {
                    t.stall_until = done + self.penalty;
                }
            }
            if t.pos >= count_from {
                count(s, op, nuops, (issued, cycle, last_charge));
            }
            t.pos += 1;
            if slot {
                t.last_issue = Some(cycle);
                issued += 1;
            }
            if op.class == OpClass::Branch && t.stall_until > cycle {
                break;
            }
        }
        issued
    }

    /// Execute one op issued at `cycle`: (result cycle, pipe occupancy,
    /// whether it missed L1).
    fn execute(
        &mut self,
        tr: &Trace,
        op: &isa::Op,
        cycle: u64,
        mem: &mut Hierarchy,
    ) -> (u64, u64, Option<Stall>) {
        let ct = &self.classes[op.class as usize];
        let (l1, mshr) = (self.l1, &mut self.mshr);
        let mut occ = ct.occ;
        let mut done = cycle + ct.lat;
        let mut missed = None;
        if op.class.is_per_lane_mem() {
            let lines = mem.lines_of(tr, op);
            occ += ct.per_line * (lines.len() as u64).saturating_sub(1);
            let (mut extra, mut level) = (0, 0);
            for l in lines {
                let sv = mem.access(0, l * mem.line_bytes(), op.class.is_store(), op.mem, cycle);
                extra = extra.max(sv.latency.saturating_sub(l1));
                level = level.max(sv.level);
            }
            done += extra;
            if extra > 0 {
                missed = Stall::memory(level, mem.levels());
            }
        } else if op.class.is_load() {
            let (ready, level) = mem.load_span(0, (op.addr.0, op.bytes), op.mem, cycle, mshr);
            missed = Stall::memory(level, mem.levels());
            // A class slower than the L1 (a vector load) adds its difference.
            done = ready + ct.lat.saturating_sub(l1);
            if op.class.is_folded() {
                // A memory operand is read in the pipeline stages before
                // execute: an L1 hit adds nothing to the op that reads it.
                done = done.saturating_sub(l1).max(cycle);
            }
        } else if op.class.is_store() {
            mem.store_span(0, (op.addr.0, op.bytes), op.mem, cycle);
        }
        (done, occ, missed)
    }

    /// Nothing could issue: the next cycle anything can, the wait charged
    /// to its reason (a miss, a mispredict, or the core).
    fn wait(&self, th: &[Thread], cycle: u64, s: &mut Stats) -> u64 {
        let next_any = th
            .iter()
            .filter_map(|t| self.earliest(t, cycle + 1))
            .min()
            .unwrap_or(cycle + 1)
            .max(cycle + 1);
        let next = next_any;
        // The deepest level any waiting thread's miss went to.
        let waiting_on_miss = th
            .iter()
            .filter(|t| t.pos < t.t.ops.len() && t.miss_until > cycle)
            .map(|t| t.miss_why)
            .max_by_key(|&w| w as usize);
        let branch = th.iter().any(|t| t.stall_until > cycle);
        let why = if let Some(w) = waiting_on_miss {
            w
        } else if branch {
            Stall::Branch
        } else {
            Stall::Dependency
        };
        s.stalls[why as usize] += next - cycle;
        next
    }
}

/// Count an issued op into the statistics; the first op a thread issues in
/// a cycle charges the cycles since the last charge to its region.
fn count(
    s: &mut Stats,
    op: &isa::Op,
    uops: usize,
    (issued, cycle, last_charge): (usize, u64, &mut u64),
) {
    s.ops += crate::stats::instructions(op.class);
    s.uops += uops as u64;
    s.region_ops[op.region as usize] += crate::stats::instructions(op.class);
    s.class_ops[op.class as usize] += 1;
    if op.class.is_vector() {
        s.vector_ops += 1;
        s.active_lanes += u64::from(op.mask.count());
    }
    if issued == 0 {
        let delta = cycle + 1 - *last_charge;
        s.region_cycles[op.region as usize] += delta;
        // Idle cycles before this one were charged while waiting.
        s.stalls[Stall::Issue as usize] += 1;
        *last_charge = cycle + 1;
    }
}

fn any_free(mask: u32, pipe_free: &[u64], cycle: u64) -> bool {
    first_free(mask, pipe_free, cycle).is_some()
}

fn first_free(mut mask: u32, pipe_free: &[u64], cycle: u64) -> Option<usize> {
    while mask != 0 {
        let p = mask.trailing_zeros() as usize;
        mask &= mask - 1;
        if pipe_free[p] <= cycle {
            return Some(p);
        }
    }
    None
}
