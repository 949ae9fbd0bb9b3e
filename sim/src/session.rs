//! A machine whose state lives from one unit of work to the next, as a
//! renderer's does over a frame: caches, prefetchers, branch predictors and
//! the cores' clocks carry on. Each step runs units at once, one per core
//! (out-of-order machines) or hardware thread (in-order), either timed in
//! full detail or functionally warmed (SMARTS, Wunderlich et al. 2003: every
//! op updates the caches, prefetcher and predictor; no timing, no counts).

use crate::config::{CoreKind, MachineConfig};
use crate::memory::Hierarchy;
use crate::ooo::{OooCore, ThreadOps};
use crate::predictor::Predictor;
use crate::stats::Stats;
use crate::{inorder, stats};
use isa::Trace;

/// Ops an out-of-order step runs of one unit before it looks again for
/// the core furthest behind in simulated time.
pub const PIECE: usize = 256;
const _: () = assert!(
    isa::STREAM_CHUNK.is_multiple_of(PIECE),
    "streamed chunks hold whole pieces"
);

/// A unit's ops arriving in chunks ([`Session::timed_streams`]).
pub type Chunks<'a> = &'a mut dyn Iterator<Item = Trace>;

/// What one unit of a timed step ran: its own cycles (as
/// [`Session::timed_each`] gives them) and what its ops count, so a caller
/// of [`Session::timed_streams`] needs no second pass over the chunks.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct UnitTimed {
    /// Cycles from the step's common start to the unit's end.
    pub cycles: u64,
    /// Ops (trace records).
    pub records: u64,
    /// Instructions (as [`Stats::ops`] counts them).
    pub instructions: u64,
    /// Instructions per code region (as [`Stats::region_ops`]).
    pub region_instructions: [u64; isa::Region::COUNT],
}

impl UnitTimed {
    /// The counts of a whole trace (cycles left 0).
    fn of(t: &Trace) -> UnitTimed {
        let mut u = UnitTimed {
            records: t.ops.len() as u64,
            ..UnitTimed::default()
        };
        for o in &t.ops {
            let i = stats::instructions(o.class);
            u.instructions += i;
            u.region_instructions[o.region as usize] += i;
        }
        u
    }
}

/// A unit's ops in an SMT step: a whole trace, or a chunk of a streamed unit.
enum Held<'t> {
    Whole(&'t Trace),
    Chunk(Trace),
}

impl std::ops::Deref for Held<'_> {
    type Target = Trace;
    fn deref(&self) -> &Trace {
        match self {
            Held::Whole(t) => t,
            Held::Chunk(t) => t,
        }
    }
}

/// A unit on a hardware thread during an SMT step.
struct OnThread<'t> {
    core: usize,
    thread: usize,
    /// Its place in the step's unit counts.
    unit: usize,
    ops: Held<'t>,
    /// The next op to time.
    pos: usize,
    /// Whether its thread still has ops.
    live: bool,
}

/// A machine's state between steps.
pub struct Session {
    m: MachineConfig,
    mem: Hierarchy,
    /// Out-of-order machines: one per core.
    ooo: Vec<OooCore>,
    /// In-order machines: one predictor per hardware thread.
    preds: Vec<Predictor>,
    /// In-order machines: the core's clock.
    clock: u64,
    /// Out-of-order machines: hardware threads used per core (SMT).
    threads: usize,
}

impl Session {
    /// Every core (out-of-order) or hardware thread (in-order) of `m`, cold.
    #[must_use]
    pub fn new(m: &MachineConfig) -> Session {
        let (ooo, preds, cores) = match m.core.kind {
            CoreKind::OutOfOrder => (
                (0..m.cores as usize).map(|c| OooCore::new(m, c)).collect(),
                Vec::new(),
                m.cores as usize,
            ),
            CoreKind::InOrder => (
                Vec::new(),
                (0..m.core.threads)
                    .map(|_| {
                        Predictor::new(
                            m.core.history_bits,
                            m.core.predictor_bits,
                            m.core.tage.as_ref(),
                        )
                    })
                    .collect(),
                1,
            ),
        };
        Session {
            m: m.clone(),
            mem: Hierarchy::new(m, cores),
            ooo,
            preds,
            clock: 0,
            threads: 1,
        }
    }

    /// An out-of-order machine's cores with `threads` hardware threads each
    /// (simultaneous multithreading, [`crate::ooo::OooCore::run_threads`]):
    /// slot `k` is thread `k / cores` of core `k % cores`, so the first
    /// `cores` slots are one thread on every core, as an operating system
    /// places threads. One thread per core is [`Session::new`].
    pub fn with_threads(m: &MachineConfig, threads: usize) -> Result<Session, String> {
        if m.core.kind != CoreKind::OutOfOrder {
            return Err(format!(
                "{} is an in-order machine: its hardware threads are its slots already",
                m.name
            ));
        }
        if threads == 0 || threads > m.core.threads as usize {
            return Err(format!(
                "{threads} threads per core: {} has 1 to {} (core.threads)",
                m.name, m.core.threads
            ));
        }
        let mut s = Session::new(m);
        if threads > 1 {
            s.ooo = (0..m.cores as usize)
                .map(|c| OooCore::with_threads(m, c, threads))
                .collect();
        }
        s.threads = threads;
        Ok(s)
    }

    /// Hardware threads used per core (out-of-order machines; 1 on in-order ones).
    #[must_use]
    pub fn threads_per_core(&self) -> usize {
        self.threads
    }

    /// The core and hardware thread of out-of-order slot `k`.
    fn place(&self, k: usize) -> (usize, usize) {
        (k % self.ooo.len(), k / self.ooo.len())
    }

    /// Units per step: the cores (out-of-order) or hardware threads (in-order).
    #[must_use]
    pub fn slots(&self) -> usize {
        (self.ooo.len() * self.threads).max(self.preds.len())
    }

    fn check(&self, units: &[(usize, &Trace)]) -> Result<(), String> {
        if units.is_empty() {
            return Err("nothing to simulate: no unit".into());
        }
        for (i, &(slot, t)) in units.iter().enumerate() {
            if slot >= self.slots() {
                return Err(format!(
                    "unit on slot {slot}: {} has {} cores/threads",
                    self.m.name,
                    self.slots()
                ));
            }
            if units[..i].iter().any(|u| u.0 == slot) {
                return Err(format!("two units on slot {slot} in one step"));
            }
            self.check_flavour("the trace", t)?;
        }
        Ok(())
    }

    /// Whether `t` (`what`, for the error) is the machine's code.
    fn check_flavour(&self, what: &str, t: &Trace) -> Result<(), String> {
        if t.flavour != self.m.flavour() {
            return Err(format!(
                "{what} is {} code but machine {} runs {} code",
                t.flavour, self.m.name, self.m.isa
            ));
        }
        Ok(())
    }

    /// Time `units` (slot, trace) started together, in full detail; the
    /// step's statistics (cycles: from the common start to the last unit's end).
    pub fn timed(&mut self, units: &[(usize, &Trace)]) -> Result<Stats, String> {
        self.timed_each(units).map(|(s, _)| s)
    }

    /// [`Session::timed`], and each unit's own cycles: on an out-of-order
    /// machine from the common start to its core's end (a core that ends
    /// early waits, uncounted, for the next step); on an in-order machine,
    /// whose threads share the core, the step's cycles pro rata to the units'
    /// instructions (they sum to the step's).
    pub fn timed_each(&mut self, units: &[(usize, &Trace)]) -> Result<(Stats, Vec<u64>), String> {
        self.check(units)?;
        self.mem.reset_counters();
        let mut s = Stats::new(self.m.flavour().lanes());
        let own = if self.ooo.is_empty() {
            s.cycles = self.timed_inorder(units, &[], &mut s);
            let ins: Vec<u64> = units.iter().map(|u| instructions(u.1)).collect();
            let all = ins.iter().sum::<u64>().max(1);
            let mut own: Vec<u64> = ins.iter().map(|&i| s.cycles * i / all).collect();
            own[0] += s.cycles - own.iter().sum::<u64>();
            own
        } else {
            let own = self.timed_ooo(units, &[], &mut s);
            s.cycles = own.iter().copied().max().unwrap_or(0);
            own
        };
        self.mem_stats(&mut s);
        Ok((s, own))
    }

    /// Time the units of `queue` in order on all slots, started together:
    /// slot k takes `queue[k]`, and a slot that finishes its unit takes the
    /// next one left (as a renderer's threads take work units). The step's
    /// statistics (cycles: from the common start to the last unit's end).
    pub fn timed_queue(&mut self, queue: &[&Trace]) -> Result<Stats, String> {
        let n = queue.len().min(self.slots());
        let first: Vec<(usize, &Trace)> = queue[..n].iter().copied().enumerate().collect();
        self.check(&first)?;
        if let Some(t) = queue.iter().find(|t| t.flavour != self.m.flavour()) {
            return Err(format!(
                "the trace is {} code but machine {} runs {} code",
                t.flavour, self.m.name, self.m.isa
            ));
        }
        self.mem.reset_counters();
        let mut s = Stats::new(self.m.flavour().lanes());
        s.cycles = if self.ooo.is_empty() {
            self.timed_inorder(&first, &queue[n..], &mut s)
        } else {
            let own = self.timed_ooo(&first, &queue[n..], &mut s);
            own.iter().copied().max().unwrap_or(0)
        };
        self.mem_stats(&mut s);
        Ok(s)
    }

    /// The in-order core runs `units`, then the threads take `rest` in
    /// turn; the cycles from the core's clock to the last op's end.
    fn timed_inorder(&mut self, units: &[(usize, &Trace)], rest: &[&Trace], s: &mut Stats) -> u64 {
        let traces: Vec<&Trace> = units.iter().map(|u| u.1).collect();
        let mut preds: Vec<Predictor> = units
            .iter()
            .map(|u| std::mem::replace(&mut self.preds[u.0], Predictor::new(1, 1, None)))
            .collect();
        let start = self.clock;
        let end = inorder::run_queue(
            &self.m,
            &traces,
            rest,
            &mut preds,
            &mut self.mem,
            s,
            (0, start),
        );
        for (u, p) in units.iter().zip(preds) {
            self.preds[u.0] = p;
        }
        self.clock = end;
        end - start
    }

    /// The out-of-order cores run `units`, a core that finishes taking the
    /// next of `rest`; each slot's cycles from the common start to its end.
    fn timed_ooo(&mut self, units: &[(usize, &Trace)], rest: &[&Trace], s: &mut Stats) -> Vec<u64> {
        if self.threads > 1 {
            let firsts = units.iter().map(|&(k, t)| (k, Held::Whole(t))).collect();
            let (own, _) = self
                .timed_smt(firsts, &mut |_| None, rest, s)
                .expect("whole traces of the machine's flavour, checked");
            return own;
        }
        // The units start together: every core's clock at the latest.
        let start = self.ooo.iter().map(|c| c.now).max().unwrap_or(0);
        for c in &mut self.ooo {
            c.advance_to(start);
        }
        // The core furthest behind in simulated time runs next, a piece at a
        // time, so the shared levels and the DRAM queue see the cores' accesses
        // in about the order of their times.
        const CHUNK: usize = PIECE;
        let mut cur: Vec<(usize, &Trace, usize)> = units.iter().map(|&(c, t)| (c, t, 0)).collect();
        let mut next = 0usize;
        loop {
            for u in cur.iter_mut().filter(|u| u.2 >= u.1.ops.len()) {
                let Some(&q) = rest.get(next) else { break };
                next += 1;
                *u = (u.0, q, 0);
            }
            let Some(k) = (0..cur.len())
                .filter(|&k| cur[k].2 < cur[k].1.ops.len())
                .min_by_key(|&k| (self.ooo[cur[k].0].now, k))
            else {
                break;
            };
            let (slot, t, pos) = cur[k];
            let end = (pos + CHUNK).min(t.ops.len());
            self.ooo[slot].run(t, pos..end, &mut self.mem, s, 0);
            cur[k].2 = end;
        }
        units.iter().map(|u| self.ooo[u.0].now - start).collect()
    }

    /// [`Session::timed_each`] over units whose ops arrive in chunks while
    /// they are timed (a recorder on another host thread: no unit's whole
    /// trace is held). Each chunk is a trace of the unit's next ops with
    /// lane-address indices of its own; every chunk but a unit's last holds
    /// a multiple of [`PIECE`] ops. Cycles and statistics are exactly those
    /// of [`Session::timed_each`] on the whole traces.
    pub fn timed_streams(
        &mut self,
        units: &mut [(usize, Chunks<'_>)],
    ) -> Result<(Stats, Vec<UnitTimed>), String> {
        let mut firsts = Vec::with_capacity(units.len());
        for (slot, it) in units.iter_mut() {
            firsts.push((
                *slot,
                it.next()
                    .unwrap_or_else(|| Trace::new(self.m.flavour(), "")),
            ));
        }
        let step: Vec<(usize, &Trace)> = firsts.iter().map(|(c, t)| (*c, t)).collect();
        self.check(&step)?;
        if self.ooo.is_empty() {
            // The in-order core takes whole traces: join the chunks.
            let mut whole = firsts;
            for ((_, t), (_, it)) in whole.iter_mut().zip(units.iter_mut()) {
                for c in it {
                    t.append(&c);
                }
            }
            let step: Vec<(usize, &Trace)> = whole.iter().map(|(c, t)| (*c, t)).collect();
            let (s, own) = self.timed_each(&step)?;
            let each = step
                .iter()
                .zip(own)
                .map(|(u, cycles)| UnitTimed {
                    cycles,
                    ..UnitTimed::of(u.1)
                })
                .collect();
            return Ok((s, each));
        }
        self.mem.reset_counters();
        let mut s = Stats::new(self.m.flavour().lanes());
        let own = self.timed_ooo_streams(firsts, units, &mut s)?;
        s.cycles = own.iter().map(|u| u.cycles).max().unwrap_or(0);
        self.mem_stats(&mut s);
        Ok((s, own))
    }

    /// [`Session::timed_ooo`] with each unit's ops in chunks: the same
    /// pieces of [`PIECE`] ops from each unit's start, in the same order.
    fn timed_ooo_streams(
        &mut self,
        firsts: Vec<(usize, Trace)>,
        units: &mut [(usize, Chunks<'_>)],
        s: &mut Stats,
    ) -> Result<Vec<UnitTimed>, String> {
        if self.threads > 1 {
            let firsts = firsts
                .into_iter()
                .map(|(k, t)| (k, Held::Chunk(t)))
                .collect();
            let mut next = |k: usize| units[k].1.next();
            return self
                .timed_smt(firsts, &mut next, &[], s)
                .map(|(_, each)| each);
        }
        let start = self.ooo.iter().map(|c| c.now).max().unwrap_or(0);
        for c in &mut self.ooo {
            c.advance_to(start);
        }
        let mut cur: Vec<(usize, Option<Trace>, usize)> =
            firsts.into_iter().map(|(c, t)| (c, Some(t), 0)).collect();
        let mut each = vec![UnitTimed::default(); cur.len()];
        loop {
            for (u, (_, it)) in cur.iter_mut().zip(units.iter_mut()) {
                while let Some(t) = u.1.as_ref().filter(|t| u.2 >= t.ops.len()) {
                    let len = t.ops.len();
                    u.1 = it.next();
                    u.2 = 0;
                    if let Some(n) = &u.1 {
                        self.check_next_chunk(len, n)?;
                    }
                }
            }
            let Some(k) = (0..cur.len())
                .filter(|&k| cur[k].1.is_some())
                .min_by_key(|&k| (self.ooo[cur[k].0].now, k))
            else {
                break;
            };
            let (slot, pos) = (cur[k].0, cur[k].2);
            let t = cur[k].1.as_ref().expect("a unit with ops left");
            let end = (pos + PIECE).min(t.ops.len());
            let (ops, regions) = (s.ops, s.region_ops);
            self.ooo[slot].run(t, pos..end, &mut self.mem, s, 0);
            let u = &mut each[k];
            u.records += (end - pos) as u64;
            u.instructions += s.ops - ops;
            for (r, (now, before)) in u
                .region_instructions
                .iter_mut()
                .zip(s.region_ops.iter().zip(regions))
            {
                *r += now - before;
            }
            cur[k].2 = end;
        }
        for (u, c) in each.iter_mut().zip(&cur) {
            u.cycles = self.ooo[c.0].now - start;
        }
        Ok(each)
    }

    /// An SMT step: the units (slot, first ops) started together, each
    /// unit's further chunks from `more` (by its place in `firsts`), a
    /// thread that finishes its unit taking the next of `rest`. Each core
    /// furthest behind in simulated time runs its threads op by op until
    /// one reaches the end of a piece ([`PIECE`] ops from its unit's
    /// start). Each first unit's cycles to its end, and every unit's counts.
    fn timed_smt<'t>(
        &mut self,
        firsts: Vec<(usize, Held<'t>)>,
        more: &mut dyn FnMut(usize) -> Option<Trace>,
        rest: &[&'t Trace],
        s: &mut Stats,
    ) -> Result<(Vec<u64>, Vec<UnitTimed>), String> {
        let start = self.ooo.iter().map(|c| c.now).max().unwrap_or(0);
        let mut running = vec![0u32; self.ooo.len()];
        let mut on: Vec<OnThread<'t>> = Vec::with_capacity(firsts.len());
        for (u, (slot, ops)) in firsts.into_iter().enumerate() {
            let (core, thread) = self.place(slot);
            running[core] |= 1 << thread;
            on.push(OnThread {
                core,
                thread,
                unit: u,
                ops,
                pos: 0,
                live: true,
            });
        }
        for (c, bits) in self.ooo.iter_mut().zip(&running) {
            c.advance_to(start);
            c.start_step(&self.m, *bits);
        }
        let mut each = vec![UnitTimed::default(); on.len()];
        let mut next = 0usize;
        loop {
            for r in on.iter_mut().filter(|r| r.live && r.pos >= r.ops.ops.len()) {
                self.refill(r, more, (rest, &mut next), &mut each, start)?;
            }
            let Some(core) = on
                .iter()
                .filter(|r| r.live)
                .map(|r| (self.ooo[r.core].thread_now(r.thread), r.core))
                .min()
                .map(|(_, c)| c)
            else {
                break;
            };
            let mine: Vec<usize> = (0..on.len())
                .filter(|&k| on[k].live && on[k].core == core)
                .collect();
            let mut ops: Vec<ThreadOps<'_>> = mine
                .iter()
                .map(|&k| {
                    let r = &on[k];
                    let end = ((r.pos / PIECE + 1) * PIECE).min(r.ops.ops.len());
                    ThreadOps {
                        thread: r.thread,
                        trace: &r.ops,
                        pos: r.pos,
                        end,
                    }
                })
                .collect();
            self.ooo[core].run_threads(&mut ops, &mut self.mem, s);
            let moved: Vec<usize> = ops.iter().map(|o| o.pos).collect();
            drop(ops);
            for (&k, pos) in mine.iter().zip(moved) {
                let r = &mut on[k];
                let u = &mut each[r.unit];
                for o in &r.ops.ops[r.pos..pos] {
                    let i = stats::instructions(o.class);
                    u.records += 1;
                    u.instructions += i;
                    u.region_instructions[o.region as usize] += i;
                }
                r.pos = pos;
            }
        }
        let first = on.len().min(each.len());
        let own = each[..first].iter().map(|u| u.cycles).collect();
        Ok((own, each))
    }

    /// A unit whose ops so far are timed: its next chunk, else the next
    /// unit of `rest` on its thread, else its thread stops (its cycles noted).
    fn refill<'t>(
        &mut self,
        r: &mut OnThread<'t>,
        more: &mut dyn FnMut(usize) -> Option<Trace>,
        (rest, next): (&[&'t Trace], &mut usize),
        each: &mut Vec<UnitTimed>,
        start: u64,
    ) -> Result<(), String> {
        while r.live && r.pos >= r.ops.ops.len() {
            let len = r.ops.ops.len();
            if let Some(n) = more(r.unit) {
                self.check_next_chunk(len, &n)?;
                (r.ops, r.pos) = (Held::Chunk(n), 0);
                continue;
            }
            each[r.unit].cycles = self.ooo[r.core].thread_now(r.thread) - start;
            if let Some(&q) = rest.get(*next) {
                *next += 1;
                each.push(UnitTimed::default());
                (r.unit, r.ops, r.pos) = (each.len() - 1, Held::Whole(q), 0);
            } else {
                r.live = false;
                self.ooo[r.core].stop_thread(r.thread);
            }
        }
        Ok(())
    }

    /// Whether chunk `n` may follow a chunk of `len` ops: that one held
    /// whole pieces, and `n` is the machine's code.
    fn check_next_chunk(&self, len: usize, n: &Trace) -> Result<(), String> {
        if !len.is_multiple_of(PIECE) {
            return Err(format!("a chunk of {len} ops is followed by another: chunks but the last hold a multiple of {PIECE} ops"));
        }
        self.check_flavour("a chunk", n)
    }

    /// Functional warming of `units` (slot, trace): caches, prefetchers and
    /// predictors see every op; nothing is timed or counted.
    pub fn warm(&mut self, units: &[(usize, &Trace)]) -> Result<(), String> {
        self.check(units)?;
        self.mem.functional = true;
        for &(slot, t) in units {
            if self.ooo.is_empty() {
                inorder::warm(t, &mut self.preds[slot], &mut self.mem, self.clock);
            } else {
                let (core, thread) = self.place(slot);
                self.ooo[core].warm_thread(thread, t, &mut self.mem);
            }
        }
        self.mem.functional = false;
        Ok(())
    }

    fn mem_stats(&self, s: &mut Stats) {
        s.levels = self.mem.stats.clone();
        s.level_names = self.m.caches.iter().map(|c| c.name.clone()).collect();
        s.dram_read = self.mem.dram_read;
        s.dram_written = self.mem.dram_written;
        s.dram_read_by_region = self.mem.dram_read_by_region.clone();
        s.dram_prefetched_by_region = self.mem.dram_prefetched_by_region.clone();
        s.tlb = self.mem.tlb_stats();
    }
}

/// Ops a step counts as instructions (for CPI), as [`Stats::ops`] does.
#[must_use]
pub fn instructions(t: &Trace) -> u64 {
    t.ops.iter().map(|o| stats::instructions(o.class)).sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::MachineConfig;
    use isa::{Addr, MemId, Op, OpClass, Region, ValId};

    /// `n` loads of distinct lines, each feeding the next (a pointer chase).
    fn chase(n: u64) -> Trace {
        let mut t = Trace::new(isa::FlavourId::Avx2, "test");
        for i in 0..n {
            let mut op = Op::new(OpClass::Load, Region::Other);
            op.addr = Addr(0x10_0000 + i * 64);
            op.bytes = 8;
            op.mem = MemId(0);
            if i > 0 {
                op.push_src(ValId(i as u32));
            }
            op.dst = ValId(i as u32 + 1);
            t.ops.push(op);
        }
        t
    }

    /// Loads in a chain, gathers, and compares fused with their branches,
    /// `n` groups of them; `seed` varies the addresses.
    fn mixed(n: u32, seed: u64) -> Trace {
        let mut t = Trace::new(isa::FlavourId::Avx2, "test");
        let mut v = 0u32;
        let mut r = isa::rng::Rng::new(seed);
        for i in 0..n {
            let mut ld = Op::new(OpClass::Load, Region::CoreLoop);
            ld.addr = Addr(0x10_0000 + 64 * r.below(4096));
            ld.bytes = 8;
            if v > 0 {
                ld.push_src(ValId(v));
            }
            v += 1;
            ld.dst = ValId(v);
            let mut g = Op::new(OpClass::VGather, Region::CoreLoop);
            g.mask = isa::LaneMask(0x5f);
            g.bytes = 4;
            g.aux = t.lane_addrs.len() as u32;
            g.addr = Addr(0x80_0000);
            for _ in 0..6 {
                t.lane_addrs.push(Addr(0x80_0000 + 4 * r.below(1 << 16)));
            }
            g.push_src(ValId(v));
            v += 1;
            g.dst = ValId(v);
            let mut cmp = Op::new(OpClass::Cmp, Region::Traversal);
            cmp.push_src(ValId(v));
            v += 1;
            cmp.dst = ValId(v);
            let mut br = Op::new(OpClass::Branch, Region::CoreLoop);
            br.push_src(ValId(v));
            br.aux = 1 + i % 3;
            br.flags = u8::from(r.below(4) == 0) * isa::trace::FLAG_TAKEN;
            t.ops.extend([ld, g, cmp, br]);
        }
        t
    }

    /// `t` cut into traces of `size` ops, each with its own lane addresses.
    fn chunks(t: &Trace, size: usize) -> Vec<Trace> {
        let chunk = |ops: &[Op]| {
            let mut c = Trace::new(t.flavour, "chunk");
            for o in ops {
                let mut o = *o;
                if o.class.is_per_lane_mem() {
                    let lanes = t.lanes_of(&o).to_vec();
                    o.aux = c.lane_addrs.len() as u32;
                    c.lane_addrs.extend(lanes);
                }
                c.ops.push(o);
            }
            c
        };
        t.ops.chunks(size).map(chunk).collect()
    }

    #[test]
    fn units_timed_from_chunks_give_the_whole_traces_figures() {
        let m = MachineConfig::load("haswell-i7-4750hq").unwrap();
        let traces = [mixed(700, 1), mixed(129, 2), mixed(0, 3), mixed(400, 4)];
        let whole: Vec<(usize, &Trace)> = traces.iter().enumerate().collect();
        let mut a = Session::new(&m);
        let mut b = Session::new(&m);
        for step in 0..2 {
            let want = a.timed_each(&whole).unwrap();
            let mut cut: Vec<std::vec::IntoIter<Trace>> =
                traces.iter().map(|t| chunks(t, 512).into_iter()).collect();
            let mut units: Vec<(usize, Chunks<'_>)> = cut
                .iter_mut()
                .enumerate()
                .map(|(k, c)| (k, c as Chunks<'_>))
                .collect();
            let (s, each) = b.timed_streams(&mut units).unwrap();
            let cycles: Vec<u64> = each.iter().map(|u| u.cycles).collect();
            assert_eq!((s, cycles), want, "step {step}");
            for (u, t) in each.iter().zip(&traces) {
                let whole = UnitTimed::of(t);
                assert_eq!(
                    (u.records, u.instructions, u.region_instructions),
                    (whole.records, whole.instructions, whole.region_instructions),
                    "step {step}: a unit's counts are its trace's"
                );
            }
        }
        // Joined again, the chunks are the trace.
        let parts = chunks(&traces[0], 300);
        let mut joined = parts[0].clone();
        for p in &parts[1..] {
            joined.append(p);
        }
        assert_eq!(
            (joined.ops, joined.lane_addrs),
            (traces[0].ops.clone(), traces[0].lane_addrs.clone())
        );
        // A chunk that is not a whole number of pieces cannot be followed.
        let mut cut = chunks(&traces[0], 300).into_iter();
        let err = b
            .timed_streams(&mut [(0, &mut cut as Chunks<'_>)])
            .unwrap_err();
        assert!(err.contains("multiple of 256"), "{err}");
    }

    #[test]
    fn state_carries_from_unit_to_unit_and_warming_is_untimed() {
        let m = MachineConfig::load("haswell-i7-4750hq").unwrap();
        let t = chase(256);
        let mut cold = Session::new(&m);
        let first = cold.timed(&[(0, &t)]).unwrap();
        let again = cold.timed(&[(0, &t)]).unwrap();
        assert!(first.levels[0].total_misses() >= 256);
        assert_eq!(again.levels[0].total_misses(), 0, "the lines stay in L1");
        // A unit's cycles are its own: from the previous unit's end to its
        // end (its first ops may run under the previous unit's tail).
        assert!(
            again.cycles * 5 < first.cycles,
            "{} vs {}",
            again.cycles,
            first.cycles
        );
        let mut warmed = Session::new(&m);
        warmed.warm(&[(0, &t)]).unwrap();
        let after = warmed.timed(&[(0, &t)]).unwrap();
        assert_eq!(
            after.levels, again.levels,
            "warming leaves the caches as timing does"
        );
        // 256 dependent L1 hits of 4 cycles, nothing in flight before them.
        assert_eq!(after.cycles, 256 * 4 + 1);
        // Another core's private L1 is cold; the shared L3 is warm.
        let other = warmed.timed(&[(1, &t)]).unwrap();
        assert!(other.levels[0].total_misses() >= 256);
        let l3 = other.level_names.iter().position(|n| n == "l3").unwrap();
        assert_eq!(other.levels[l3].total_misses(), 0);
    }

    #[test]
    fn steps_are_checked() {
        let m = MachineConfig::load("haswell-i7-4750hq").unwrap();
        let t = chase(4);
        let mut s = Session::new(&m);
        assert!(s.timed(&[]).is_err());
        assert!(s.timed(&[(9, &t)]).unwrap_err().contains("slot 9"));
        assert!(s
            .timed(&[(1, &t), (1, &t)])
            .unwrap_err()
            .contains("two units"));
    }

    #[test]
    fn a_queue_of_one_unit_per_slot_is_a_step() {
        for (name, fl) in [
            ("haswell-i7-4750hq", isa::FlavourId::Avx2),
            ("larrabee", isa::FlavourId::Lrb16),
        ] {
            let m = MachineConfig::load(name).unwrap();
            let mut t = chase(300);
            t.flavour = fl;
            let mut a = Session::new(&m);
            let mut b = Session::new(&m);
            let step = a.timed(&[(0, &t), (1, &t)]).unwrap();
            let queued = b.timed_queue(&[&t, &t]).unwrap();
            assert_eq!(step.cycles, queued.cycles, "{name}");
            assert_eq!(step.levels, queued.levels, "{name}");
        }
    }

    #[test]
    fn a_thread_that_finishes_takes_the_next_unit() {
        let m = MachineConfig::load("larrabee").unwrap();
        let (mut long, mut short) = (chase(800), chase(100));
        long.flavour = isa::FlavourId::Lrb16;
        short.flavour = isa::FlavourId::Lrb16;
        let threads = m.core.threads as usize;
        let mut queue = vec![&long];
        queue.extend(std::iter::repeat_n(&short, 2 * threads - 1));
        // Warm first, so every unit's loads hit and the times are the chains'.
        let mut q = Session::new(&m);
        q.warm(&[(0, &long)]).unwrap();
        let queued = q.timed_queue(&queue).unwrap();
        let mut r = Session::new(&m);
        r.warm(&[(0, &long)]).unwrap();
        let rounds = r.timed(
            &queue[..threads]
                .iter()
                .copied()
                .enumerate()
                .collect::<Vec<_>>(),
        );
        let rounds2 = r.timed(
            &queue[threads..]
                .iter()
                .copied()
                .enumerate()
                .collect::<Vec<_>>(),
        );
        let in_rounds = rounds.unwrap().cycles + rounds2.unwrap().cycles;
        assert_eq!(queued.ops, 800 + (2 * threads as u64 - 1) * 100);
        // The other threads run every short unit while the long one runs.
        assert!(
            queued.cycles < in_rounds,
            "{} vs {in_rounds}",
            queued.cycles
        );
        let mut alone = Session::new(&m);
        alone.warm(&[(0, &long)]).unwrap();
        let alone = alone.timed(&[(0, &long)]).unwrap().cycles;
        assert!(
            queued.cycles * 100 <= alone * 105,
            "{} vs the long unit alone {alone}",
            queued.cycles
        );
    }

    #[test]
    fn in_order_threads_keep_their_predictors() {
        let m = MachineConfig::load("larrabee").unwrap();
        let mut t = Trace::new(isa::FlavourId::Lrb16, "test");
        let mut r = isa::rng::Rng::new(7);
        for i in 0..2000u32 {
            let mut op = Op::new(OpClass::Branch, Region::Other);
            op.aux = i % 8;
            if r.next_u64() & 1 == 1 {
                op.flags |= isa::trace::FLAG_TAKEN;
            }
            t.ops.push(op);
        }
        let mut s = Session::new(&m);
        let first = s.timed(&[(0, &t)]).unwrap();
        let again = s.timed(&[(0, &t)]).unwrap();
        let other = s.timed(&[(1, &t)]).unwrap();
        assert!(again.mispredicts < first.mispredicts / 2, "{again:?}");
        assert!(
            other.mispredicts > first.mispredicts / 2,
            "thread 1 is cold"
        );
    }

    /// `n` ops of `class`, each reading the one before if `chain`.
    fn ops(class: OpClass, n: u32, chain: bool) -> Trace {
        let mut t = Trace::new(isa::FlavourId::Avx2, "test");
        for i in 0..n {
            let mut op = Op::new(class, Region::Other);
            if chain && i > 0 {
                op.push_src(ValId(i));
            }
            op.dst = ValId(i + 1);
            t.ops.push(op);
        }
        t
    }

    /// A long op (a load from DRAM), then `t`'s ops.
    fn behind_a_miss(t: &Trace) -> Trace {
        let mut out = chase(1);
        let base = 1;
        for o in &t.ops {
            let mut o = *o;
            o.dst = ValId(o.dst.0 + base);
            if o.nsrc > 0 {
                o.srcs[0] = ValId(o.srcs[0].0 + base);
            }
            out.ops.push(o);
        }
        out
    }

    /// Each unit's own cycles on a fresh Haswell session with `threads`
    /// per core, units on `slots`; with thread 0's pipeline times.
    fn smt_run(threads: usize, units: &[(usize, &Trace)]) -> (Vec<u64>, Vec<crate::OpTimes>) {
        let m = MachineConfig::load("haswell-i7-4750hq").unwrap();
        let mut s = Session::with_threads(&m, threads).unwrap();
        s.ooo[0].timeline = Some(crate::ooo::Timeline::new(0..10_000));
        let (_, own) = s.timed_each(units).unwrap();
        let tl = s.ooo[0].timeline.take().unwrap().events;
        (own, tl)
    }

    #[test]
    fn two_threads_take_turns_at_dispatch_when_both_can() {
        // Independent one-cycle ops: alone, 4 a cycle; two threads on one
        // core (slots 0 and 4 of 4 cores) alternate whole cycles.
        let t = ops(OpClass::Alu, 64, false);
        let (_, alone) = smt_run(1, &[(0, &t)]);
        let d: Vec<u64> = alone.iter().map(|e| e.dispatch).collect();
        assert_eq!(&d[..9], &[0, 0, 0, 0, 1, 1, 1, 1, 2]);
        let (own, both) = smt_run(2, &[(0, &t), (4, &t)]);
        let d: Vec<u64> = both.iter().map(|e| e.dispatch).collect();
        assert_eq!(
            &d[..9],
            &[0, 0, 0, 0, 2, 2, 2, 2, 4],
            "thread 0 takes every other cycle"
        );
        assert_eq!(both[4].stall, crate::Stall::Thread);
        // 64 ops in 16 dispatch cycles each: the pair ends one cycle apart.
        assert_eq!(own[1], own[0] + 1, "{own:?}");
    }

    #[test]
    fn a_thread_that_cannot_dispatch_leaves_every_cycle_to_the_other() {
        let t = ops(OpClass::Alu, 64, false);
        let one = ops(OpClass::Alu, 1, false);
        let (_, tl) = smt_run(2, &[(0, &t), (4, &one)]);
        let d: Vec<u64> = tl.iter().map(|e| e.dispatch).collect();
        // Thread 1 takes cycle 1 for its one op, then has nothing left.
        assert_eq!(&d[..13], &[0, 0, 0, 0, 2, 2, 2, 2, 3, 3, 3, 3, 4]);
    }

    /// 200 ops of `class` on one thread alone and on both threads of core 0.
    fn alone_and_paired(class: OpClass, chain: bool) -> (Vec<u64>, Vec<u64>) {
        let t = ops(class, 200, chain);
        (smt_run(1, &[(0, &t)]).0, smt_run(2, &[(0, &t), (4, &t)]).0)
    }

    #[test]
    fn two_dependent_chains_interleave() {
        // Chains of one-cycle ops: each needs one dispatch a cycle and
        // gets two on average, so two threads finish as one does, give or
        // take their retirement turns.
        assert_eq!(
            alone_and_paired(OpClass::Alu, true),
            (vec![201], vec![202, 203])
        );
    }

    #[test]
    fn a_throughput_bound_pair_halves() {
        // Independent adds on port 1 only: one a cycle for the core. The
        // 400 adds take the port 400 cycles; the threads share it.
        assert_eq!(
            alone_and_paired(OpClass::VAdd, false),
            (vec![203], vec![400, 403]),
            "each thread at half the rate"
        );
    }

    #[test]
    fn a_partitioned_rob_holds_half_the_ops_behind_a_long_one() {
        let t = behind_a_miss(&ops(OpClass::Alu, 250, false));
        let one = ops(OpClass::Alu, 1, false);
        let (_, alone) = smt_run(2, &[(0, &t)]);
        let (_, split) = smt_run(2, &[(0, &t), (4, &one)]);
        let head = |tl: &[crate::OpTimes]| tl[0].retire;
        // Alone the whole ROB (192): the op 192 places on waits for the head.
        assert!(alone[191].dispatch < head(&alone));
        assert_eq!(alone[192].dispatch, head(&alone));
        // With the other thread running, its half (96).
        assert!(split[95].dispatch < head(&split));
        assert_eq!(split[96].dispatch, head(&split));
        assert_eq!(split[96].stall, crate::Stall::Resources);
    }

    #[test]
    fn a_partitioned_store_buffer_holds_half_the_stores() {
        let mut stores = Trace::new(isa::FlavourId::Avx2, "test");
        for i in 0..60u64 {
            let mut op = Op::new(OpClass::Store, Region::Other);
            op.addr = Addr(0x10_0000 + 64 * i);
            op.bytes = 8;
            stores.ops.push(op);
        }
        let t = behind_a_miss(&stores);
        let one = ops(OpClass::Alu, 1, false);
        let (_, alone) = smt_run(2, &[(0, &t)]);
        let (_, split) = smt_run(2, &[(0, &t), (4, &one)]);
        // Store k sits at op 1 + k; it needs the entry of store k - size.
        assert_eq!(alone[1 + 42].dispatch, alone[1].retire + 1, "42 entries");
        assert!(alone[1 + 41].dispatch < alone[1].retire);
        assert_eq!(split[1 + 21].dispatch, split[1].retire + 1, "21 entries");
        assert!(split[1 + 20].dispatch < split[1].retire);
    }

    #[test]
    fn one_thread_per_core_is_today_s_core() {
        let m = MachineConfig::load("haswell-i7-4750hq").unwrap();
        let traces = [mixed(700, 1), mixed(129, 2), mixed(300, 3), mixed(400, 4)];
        let units: Vec<(usize, &Trace)> = traces.iter().enumerate().collect();
        let mut one = Session::new(&m);
        let mut smt = Session::with_threads(&m, 2).unwrap();
        for step in 0..2 {
            assert_eq!(
                one.timed_each(&units).unwrap(),
                smt.timed_each(&units).unwrap(),
                "step {step}: units on the first thread of each core"
            );
        }
        assert!(Session::with_threads(&m, 3)
            .err()
            .unwrap()
            .contains("1 to 2"));
    }

    #[test]
    fn smt_units_from_chunks_give_the_whole_traces_figures() {
        let m = MachineConfig::load("haswell-i7-4750hq").unwrap();
        let traces = [
            mixed(700, 1),
            mixed(129, 2),
            mixed(0, 3),
            mixed(400, 4),
            mixed(333, 5),
        ];
        let slots = [0, 4, 1, 5, 2];
        let whole: Vec<(usize, &Trace)> = slots.iter().copied().zip(&traces).collect();
        let mut a = Session::with_threads(&m, 2).unwrap();
        let mut b = Session::with_threads(&m, 2).unwrap();
        for step in 0..2 {
            let want = a.timed_each(&whole).unwrap();
            let mut cut: Vec<std::vec::IntoIter<Trace>> =
                traces.iter().map(|t| chunks(t, 512).into_iter()).collect();
            let mut units: Vec<(usize, Chunks<'_>)> = cut
                .iter_mut()
                .zip(slots)
                .map(|(c, k)| (k, c as Chunks<'_>))
                .collect();
            let (s, each) = b.timed_streams(&mut units).unwrap();
            let cycles: Vec<u64> = each.iter().map(|u| u.cycles).collect();
            assert_eq!((s, cycles), want, "step {step}");
            for (u, t) in each.iter().zip(&traces) {
                assert_eq!(u.instructions, UnitTimed::of(t).instructions);
            }
        }
    }

    #[test]
    fn smt_threads_share_the_core_s_caches() {
        let m = MachineConfig::load("haswell-i7-4750hq").unwrap();
        let t = chase(256);
        let mut s = Session::with_threads(&m, 2).unwrap();
        s.timed(&[(0, &t)]).unwrap();
        let other = s.timed(&[(4, &t)]).unwrap();
        assert_eq!(
            other.levels[0].total_misses(),
            0,
            "thread 1 of core 0 finds thread 0's lines"
        );
        let core1 = s.timed(&[(1, &t)]).unwrap();
        assert!(
            core1.levels[0].total_misses() >= 256,
            "core 1's L1 is its own"
        );
    }
}
