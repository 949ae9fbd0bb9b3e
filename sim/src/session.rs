//! A machine whose state lives from one unit of work to the next, as a
//! renderer's does over a frame: caches, prefetchers, branch predictors and
//! the cores' clocks carry on. Each step runs units at once, one per core
//! (out-of-order machines) or hardware thread (in-order), either timed in
//! full detail or functionally warmed (SMARTS, Wunderlich et al. 2003: every
//! op updates the caches, prefetcher and predictor; no timing, no counts).

use crate::config::{CoreKind, MachineConfig};
use crate::memory::Hierarchy;
use crate::ooo::OooCore;
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
        }
    }

    /// Units per step: the cores (out-of-order) or hardware threads (in-order).
    #[must_use]
    pub fn slots(&self) -> usize {
        self.ooo.len().max(self.preds.len())
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
            if t.flavour != self.m.flavour() {
                return Err(format!(
                    "the trace is {} code but machine {} runs {} code",
                    t.flavour, self.m.name, self.m.isa
                ));
            }
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
                        if !len.is_multiple_of(PIECE) {
                            return Err(format!("a chunk of {len} ops is followed by another: chunks but the last hold a multiple of {PIECE} ops"));
                        }
                        if n.flavour != self.m.flavour() {
                            return Err(format!(
                                "a chunk is {} code but machine {} runs {} code",
                                n.flavour, self.m.name, self.m.isa
                            ));
                        }
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

    /// Functional warming of `units` (slot, trace): caches, prefetchers and
    /// predictors see every op; nothing is timed or counted.
    pub fn warm(&mut self, units: &[(usize, &Trace)]) -> Result<(), String> {
        self.check(units)?;
        self.mem.functional = true;
        for &(slot, t) in units {
            if self.ooo.is_empty() {
                inorder::warm(t, &mut self.preds[slot], &mut self.mem, self.clock);
            } else {
                self.ooo[slot].warm(t, &mut self.mem);
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
}
