//! The in-order, multi-threaded core (Larrabee class). Each cycle one
//! hardware thread is chosen round-robin among those that can issue; it
//! issues up to `width` ops in program order, each needing every source ready
//! (stall on use) and a free pipe from its class's set (vector ops: the U pipe
//! only; scalar ops pair on U or V). With `no_back_to_back` a thread cannot
//! issue in two consecutive cycles (Knights Corner). A mispredicted branch
//! stops its thread until it resolves plus the penalty; loads do not block
//! until their result is used.

use crate::config::MachineConfig;
use crate::memory::Hierarchy;
use crate::ooo::{class_table, ClassT, Values};
use crate::predictor::Gshare;
use crate::stats::{Stall, Stats};
use isa::{OpClass, Trace};

struct Thread<'a> {
    t: &'a Trace,
    pos: usize,
    values: Values,
    stall_until: u64,
    last_issue: Option<u64>,
    miss_until: u64,
    pred: Gshare,
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
    let classes: Vec<ClassT> = class_table(m);
    let l1 = u64::from(m.caches[0].latency);
    let penalty = u64::from(c.mispredict_penalty);
    let width = c.width as usize;
    let mut pipe_free = vec![0u64; c.ports as usize];
    let mut mshr = crate::memory::Mshrs::new(m.mshrs as usize);
    let mut th: Vec<Thread> = traces
        .iter()
        .map(|t| Thread {
            t,
            pos: 0,
            values: Values::new(),
            stall_until: 0,
            last_issue: None,
            miss_until: 0,
            pred: Gshare::new(c.history_bits, c.predictor_bits),
        })
        .collect();
    let n = th.len();
    let mut cycle = 0u64;
    let mut rr = 0usize;
    let mut last_charge = 0u64;
    let mut max_done = 0u64;
    // Earliest cycle thread `k`'s next op could issue (ignoring pipes), or None if done.
    let earliest = |t: &Thread, cycle: u64| -> Option<u64> {
        let op = t.t.ops.get(t.pos)?;
        let mut e = cycle.max(t.stall_until);
        if c.no_back_to_back {
            if let Some(l) = t.last_issue {
                e = e.max(l + 2);
            }
        }
        for &v in op.sources() {
            e = e.max(t.values.get(v));
        }
        Some(e)
    };
    loop {
        let mut issued = 0usize;
        let mut chosen = None;
        for k in 0..n {
            let i = (rr + k) % n;
            if earliest(&th[i], cycle) != Some(cycle) {
                continue;
            }
            let op = &th[i].t.ops[th[i].pos];
            let ct = &classes[op.class as usize];
            if !ct.uops.is_empty() && !any_free(ct.uops[0], &pipe_free, cycle) {
                continue;
            }
            chosen = Some(i);
            break;
        }
        if let Some(i) = chosen {
            let mut used_pipes = 0u32;
            while issued < width {
                let t = &mut th[i];
                let Some(op) = t.t.ops.get(t.pos) else { break };
                if op.sources().iter().any(|v| t.values.get(*v) > cycle) {
                    break;
                }
                let ct = &classes[op.class as usize];
                let pipe = if ct.uops.is_empty() {
                    None
                } else {
                    match first_free(ct.uops[0] & !used_pipes, &pipe_free, cycle) {
                        Some(p) => Some(p),
                        None => break,
                    }
                };
                // Execute.
                let mut occ = ct.occ;
                let mut done = cycle + ct.lat;
                let mut missed = false;
                if op.class.is_per_lane_mem() {
                    let mut lines: Vec<u64> =
                        t.t.lanes_of(op)
                            .iter()
                            .map(|a| mem.line_of(a.0).0)
                            .collect();
                    lines.sort_unstable();
                    lines.dedup();
                    occ += ct.per_line * (lines.len() as u64).saturating_sub(1);
                    let mut extra = 0;
                    for l in lines {
                        let sv =
                            mem.access(0, l * mem.line_bytes(), op.class.is_store(), op.mem, cycle);
                        extra = extra.max(sv.latency.saturating_sub(l1));
                    }
                    done += extra;
                    missed = extra > 0;
                } else if op.class.is_load() {
                    let mut start = cycle;
                    let mut slot = None;
                    if !mem.in_l1(0, op.addr.0) {
                        let (j, free) = mshr.earliest();
                        start = start.max(free);
                        slot = Some(j);
                        missed = true;
                    }
                    let sv = mem.access(0, op.addr.0, false, op.mem, start);
                    if let Some(j) = slot {
                        mshr.hold(j, start + sv.latency);
                    }
                    done = start + sv.latency;
                } else if op.class.is_store() {
                    mem.access(0, op.addr.0, true, op.mem, cycle);
                }
                if let Some(p) = pipe {
                    pipe_free[p] = cycle + occ;
                    used_pipes |= 1 << p;
                }
                if op.dst.is_some() {
                    t.values.set(op.dst, done);
                }
                max_done = max_done.max(done);
                if missed {
                    t.miss_until = t.miss_until.max(done);
                }
                if op.class == OpClass::Branch {
                    let ok = t.pred.predict_and_update(op.site().0, op.taken());
                    if t.pos >= count_from {
                        s.branches += 1;
                        s.mispredicts += u64::from(!ok);
                    }
                    if !ok {
                        t.stall_until = done + penalty;
                    }
                }
                if t.pos >= count_from {
                    s.ops += 1;
                    s.uops += ct.uops.len() as u64;
                    s.region_ops[op.region as usize] += 1;
                    s.class_ops[op.class as usize] += 1;
                    if op.class.is_vector() {
                        s.vector_ops += 1;
                        s.active_lanes += u64::from(op.mask.count());
                    }
                    if issued == 0 {
                        let delta = cycle + 1 - last_charge;
                        s.region_cycles[op.region as usize] += delta;
                        // Idle cycles before this one were charged while waiting.
                        s.stalls[Stall::Issue as usize] += 1;
                        last_charge = cycle + 1;
                    }
                }
                t.pos += 1;
                t.last_issue = Some(cycle);
                issued += 1;
                if op.class == OpClass::Branch && t.stall_until > cycle {
                    break;
                }
            }
            rr = i + 1;
        }
        if th.iter().all(|t| t.pos >= t.t.ops.len()) {
            break;
        }
        if issued > 0 {
            cycle += 1;
        } else {
            // Nothing could issue: jump to the next cycle anything can, charging the wait.
            let next_any = th
                .iter()
                .filter_map(|t| earliest(t, cycle + 1))
                .min()
                .unwrap_or(cycle + 1)
                .max(cycle + 1);
            let next = next_any;
            let waiting_on_miss = th
                .iter()
                .any(|t| t.pos < t.t.ops.len() && t.miss_until > cycle);
            let branch = th.iter().any(|t| t.stall_until > cycle);
            let why = if waiting_on_miss {
                Stall::Memory
            } else if branch {
                Stall::Branch
            } else {
                Stall::Core
            };
            s.stalls[why as usize] += next - cycle;
            cycle = next;
        }
    }
    cycle.max(max_done)
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
