//! The out-of-order core (Haswell class), timed one op at a time in program
//! order, as ZSim's instruction-driven OoO model does:
//!
//! - dispatch: `width` fused uops per cycle, after fetch is redirected from a
//!   mispredicted branch, with a free ROB entry (the entry `rob` back must have
//!   retired) and free scheduler entries (an entry is held from dispatch until
//!   its uop issues, as Haswell's reservation station frees it);
//! - issue: a cycle after dispatch, once every source is ready, on the first free
//!   cycle of any allowed port (ports keep a booking calendar, so a later op
//!   can take an earlier free slot: out-of-order issue);
//! - execute: the class latency, or the memory system's for loads (an L1 miss
//!   also waits for one of `mshrs` miss slots), or store-to-load forwarding
//!   from the youngest older store still in the store buffer that overlaps
//!   the load; a load that store does not contain (wider, or spanning two
//!   stores), or on Core 2-class machines a load inside a wide store that
//!   does not start with it (`store_forward_wide_same_start`), cannot
//!   forward and pays `store_forward_fail_penalty`;
//! - retire: in order, `retire_width` per cycle; a store holds its store
//!   buffer entry until it retires. A two-uop store that names its address
//!   source (`addr=`) issues its address uop when the address is ready and
//!   its data uop when the data is (each frees its scheduler entry then).
//!
//! A compare immediately followed by a branch on its value is macro-fused
//! with it (`macro_fusion`): the pair is one uop, dispatched once and
//! executed once on the branch's ports as soon as the compare's sources are
//! ready.
//!
//! Memory disambiguation: a load issues before older stores whose addresses
//! are unknown. A load with a static site (`site=` in a trace) that turns out
//! to read an older store's bytes before that store's address was known
//! costs a machine clear (fetch resumes `mispredict_penalty` after the
//! address is known) and its site is then predicted dependent: it waits for
//! every older store's address from then on. Loads without a site (what
//! kernels record) are disambiguated perfectly: they never wait needlessly
//! and never clear.

use crate::config::{MachineConfig, MAX_UOPS};
use crate::memory::Hierarchy;
use crate::predictor::Predictor;
use crate::stats::{Stall, Stats};
use isa::{Op, OpClass, Trace, ValId};

/// Cycles the port calendars look ahead.
const WINDOW: u64 = 1 << 16;
/// Value ready-time ring: values older than this many ids are long complete.
const VALUES: usize = 1 << 16;
/// A store buffer entry: the bytes a store writes, when its address is
/// known, when its data is ready and when it retires (its entry is free
/// after that).
#[derive(Clone, Copy, Debug, Default)]
struct StoreEntry {
    lo: u64,
    hi: u64,
    addr: u64,
    data: u64,
    ret: u64,
}

/// Entries of the memory-dependence predictor (by load site).
const MDP: usize = 4096;
/// Slots of the store-granule filter ([`OooCore::store_near`]).
const GRANULES: usize = 512;

/// A macro-fused compare: no uop and no dispatch slot of its own; its value
/// is ready when its sources are (the branch it fuses with executes it).
const FUSED_CMP: ClassT = ClassT {
    lat: 0,
    uops: Uops {
        masks: [0; MAX_UOPS],
        n: 0,
    },
    occ: 1,
    fused: 0,
    per_line: 0,
    load: false,
    store: false,
    per_lane: false,
    vector: false,
    load_extra: 0,
    fp_uops: 0,
    cond_extra: 0,
};

/// A class's uops as port masks, inline (no pointer to chase per op).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Uops {
    masks: [u32; MAX_UOPS],
    n: u8,
}

/// What issuing an op found: its first and last uops' cycles, the cycle its
/// first uop's operands were ready, and a gather's or scatter's extra
/// latency and the deepest level its lines came from.
#[derive(Clone, Copy)]
struct Issued {
    first: u64,
    last: u64,
    operands: u64,
    gather_lat: u64,
    gather_level: usize,
    /// The port of the uop that waited longest for one after its operands.
    wait_port: u8,
    /// Each uop's port, 4 bits each, the first lowest.
    ports: u64,
}

impl std::ops::Deref for Uops {
    type Target = [u32];
    #[inline(always)]
    fn deref(&self) -> &[u32] {
        &self.masks[..self.n as usize]
    }
}

impl Uops {
    fn of(ports: &[Vec<u32>]) -> Uops {
        assert!(
            ports.len() <= MAX_UOPS,
            "validated: at most {MAX_UOPS} uops"
        );
        let mut masks = [0; MAX_UOPS];
        for (m, p) in masks.iter_mut().zip(ports) {
            *m = p.iter().fold(0u32, |a, p| a | 1 << p);
        }
        Uops {
            masks,
            n: ports.len() as u8,
        }
    }
}

/// A class's timing, prepared for the hot loop.
#[derive(Clone, Debug)]
pub(crate) struct ClassT {
    pub lat: u64,
    pub uops: Uops,
    pub occ: u64,
    pub fused: u32,
    pub per_line: u64,
    pub load: bool,
    pub store: bool,
    pub per_lane: bool,
    pub vector: bool,
    /// A load class's load-to-use latency beyond the L1's (a Zen FP load:
    /// 8 against the integer 4), added to what the cache model returns.
    pub load_extra: u64,
    /// Of its uops, those held in the second scheduler (every port of the
    /// uop in `core.fp_scheduler.ports`); the rest in the first.
    pub fp_uops: u8,
    /// How much later than through its other sources the result comes
    /// through its first source, the condition (`cond_lat - lat`).
    pub cond_extra: u64,
}

pub(crate) fn class_table(m: &MachineConfig) -> Vec<ClassT> {
    class_table_of(m, false)
}

/// Where [`OooCore`]'s class tables hold a taken branch's timing (after
/// every class's).
const TAKEN_BRANCH: usize = OpClass::ALL.len();

/// The class table, with the narrow-operand timings where a class has
/// them if `narrow`.
fn class_table_of(m: &MachineConfig, narrow: bool) -> Vec<ClassT> {
    OpClass::ALL
        .iter()
        .map(|c| {
            let t = m.class(*c);
            let (lat, occ) = match t.narrow {
                Some(n) if narrow => (n.lat, n.occ),
                _ => (t.lat, t.occ),
            };
            ClassT {
                lat: u64::from(lat),
                uops: Uops::of(&t.uops),
                occ: u64::from(occ),
                fused: t.fused,
                per_line: u64::from(t.per_line),
                load: c.is_load(),
                store: c.is_store(),
                per_lane: c.is_per_lane_mem(),
                vector: c.is_vector(),
                load_extra: if c.is_load() && !c.is_per_lane_mem() {
                    u64::from(lat.saturating_sub(m.caches[0].latency))
                } else {
                    0
                },
                fp_uops: Uops::of(&t.uops)
                    .iter()
                    .filter(|&&u| in_fp_pool(u, fp_mask(m)))
                    .count() as u8,
                cond_extra: t.cond_lat.map_or(0, |c| u64::from(c.saturating_sub(lat))),
            }
        })
        .collect()
}

/// The ports of the second scheduler (`core.fp_scheduler`) as a mask; 0:
/// one scheduler.
pub(crate) fn fp_mask(m: &MachineConfig) -> u32 {
    m.core
        .fp_scheduler
        .as_ref()
        .map_or(0, |f| f.ports.iter().fold(0, |a, p| a | 1 << p))
}

/// Whether a uop that may issue on `mask` waits in the second scheduler.
#[inline(always)]
fn in_fp_pool(mask: u32, fp: u32) -> bool {
    fp != 0 && mask != 0 && mask & !fp == 0
}

/// One scheduler's entries: uops held from dispatch until they issue,
/// counted by their issue cycle in a ring of [`WINDOW`] cycles.
pub(crate) struct Pool {
    /// Entries.
    size: usize,
    /// Uops that issue in each cycle (mod [`WINDOW`]), for cycles after `cursor`.
    count: Box<[u16; WINDOW as usize]>,
    /// Uops held at cycle `cursor` (issuing later).
    held: usize,
    /// Every uop issuing at or before this cycle has left.
    cursor: u64,
    /// Issue cycles of held uops a whole ring or more past `cursor` (a uop
    /// waiting on a long queue of misses), kept apart from the ring.
    far: Vec<u64>,
}

impl Pool {
    fn new(size: usize) -> Pool {
        Pool {
            size,
            count: vec![0u16; WINDOW as usize]
                .into_boxed_slice()
                .try_into()
                .expect("WINDOW entries"),
            held: 0,
            cursor: 0,
            far: Vec::new(),
        }
    }

    /// Free the entries of uops issuing up to cycle `to`.
    #[inline(always)]
    fn free_until(&mut self, to: u64) {
        if to <= self.cursor {
            return;
        }
        if !self.far.is_empty() {
            let before = self.far.len();
            self.far.retain(|&c| c > to);
            self.held -= before - self.far.len();
        }
        let in_ring = self.held - self.far.len();
        if in_ring == 0 || to - self.cursor >= WINDOW {
            if in_ring > 0 {
                self.count.fill(0);
                self.held = self.far.len();
            }
            self.cursor = to;
            return;
        }
        let mut c = self.cursor;
        while c < to {
            c += 1;
            let k = slot(c);
            self.held -= usize::from(self.count[k]);
            self.count[k] = 0;
        }
        self.cursor = to;
    }

    /// The first cycle from `d` with `n` entries free, if later than `d`.
    #[inline(always)]
    fn room_for(&mut self, n: usize, d: u64) -> Option<u64> {
        self.free_until(d);
        let room = self.size.saturating_sub(n);
        let mut later = None;
        while self.held > room {
            self.free_until(self.cursor + 1);
            later = Some(self.cursor);
        }
        later
    }

    /// Hold an entry until cycle `c`.
    #[inline(always)]
    fn hold(&mut self, c: u64) {
        // With SMT a thread may dispatch behind the cursor another moved
        // on: an entry issuing by then has already left.
        if c <= self.cursor {
            return;
        }
        self.held += 1;
        if c - self.cursor >= WINDOW {
            self.far.push(c);
            return;
        }
        self.count[(c & (WINDOW - 1)) as usize] += 1;
    }
}

/// Per-cycle booking of future ports: a ring of [`WINDOW`] cycles, each a
/// bit set of the ports busy in it (at most 16 ports, as the config
/// checks). Cycles the booking base passes are cleared as it passes them,
/// so the ring only ever holds cycles in `base..base + WINDOW`. One read
/// answers "which of these ports is free in this cycle" for every port of
/// a uop at once.
pub(crate) struct Calendar {
    busy: Box<[u16; WINDOW as usize]>,
    base: u64,
    uses: [u64; 16],
    /// The port the latest booking took.
    last: u8,
}

/// A cycle's slot in the ring.
#[inline(always)]
fn slot(c: u64) -> usize {
    (c & (WINDOW - 1)) as usize
}

impl Calendar {
    pub fn new(ports: usize) -> Calendar {
        assert!(ports <= 16, "validated: at most 16 ports");
        Calendar {
            busy: vec![0u16; WINDOW as usize]
                .into_boxed_slice()
                .try_into()
                .expect("WINDOW entries"),
            base: 0,
            uses: [0; 16],
            last: 0,
        }
    }

    /// Cycles before `to` will not be booked again (their slots are
    /// cleared for the cycles a window later).
    #[inline]
    pub fn advance(&mut self, to: u64) {
        if to <= self.base {
            return;
        }
        if to - self.base >= WINDOW {
            self.busy.fill(0);
        } else {
            let mut c = self.base;
            while c < to {
                self.busy[slot(c)] = 0;
                c += 1;
            }
        }
        self.base = to;
    }

    /// The busy-port sets of the four cycles from ring slot `i` (at most
    /// `WINDOW - 4`), one per 16-bit lane, the first lowest.
    #[inline(always)]
    fn four(&self, i: usize) -> u64 {
        let b = &self.busy[i..i + 4];
        u64::from(b[0]) | u64::from(b[1]) << 16 | u64::from(b[2]) << 32 | u64::from(b[3]) << 48
    }

    /// Whether port `p` is free in cycle `c`.
    #[inline]
    fn free(&self, p: usize, c: u64) -> bool {
        self.busy[slot(c)] >> p & 1 == 0
    }

    /// The ports of `mask` free for the `occ` cycles from `c`.
    #[inline(always)]
    fn free_ports(&self, mask: u32, c: u64, occ: u64) -> u32 {
        let mut cand = mask & !u32::from(self.busy[slot(c)]);
        let mut k = 1;
        while cand != 0 && k < occ {
            cand &= !u32::from(self.busy[slot(c + k)]);
            k += 1;
        }
        cand
    }

    /// Of ports `cand` (not empty), the least used (the lowest on a tie).
    #[inline(always)]
    fn least_used(&self, cand: u32) -> usize {
        let mut best = cand.trailing_zeros() as usize;
        let mut m = cand & (cand - 1);
        while m != 0 {
            let p = m.trailing_zeros() as usize;
            m &= m - 1;
            if self.uses[p] < self.uses[best] {
                best = p;
            }
        }
        best
    }

    #[inline]
    fn mark(&mut self, p: usize, c: u64, occ: u64) {
        self.last = p as u8;
        if c + occ > self.base + WINDOW {
            return;
        }
        for k in c..c + occ {
            self.busy[slot(k)] |= 1 << p;
        }
        self.uses[p] += 1;
    }

    /// Book the earliest slot >= `t` with `occ` free cycles on any port in
    /// `mask` (on a tie, the least used port, then the lowest); returns the
    /// cycle.
    #[inline]
    pub fn book(&mut self, mask: u32, t: u64, occ: u64) -> u64 {
        let limit = self.base + WINDOW - occ;
        let mut c = t.max(self.base);
        if occ == 1 {
            // Four cycles per step: each 16-bit lane of `free` holds the
            // mask's ports free in one cycle, the first non-zero lane is
            // the first cycle with one (a step per cycle mispredicts its
            // exit).
            let m4 = u64::from(mask) * 0x0001_0001_0001_0001;
            while c + 4 <= limit && slot(c) <= WINDOW as usize - 4 {
                let free = (self.four(slot(c)) & m4) ^ m4;
                if free != 0 {
                    let k = free.trailing_zeros() / 16;
                    let cand = (free >> (16 * k)) as u32 & 0xFFFF;
                    let c = c + u64::from(k);
                    let p = self.least_used(cand);
                    self.mark(p, c, 1);
                    return c;
                }
                c += 4;
            }
        }
        while c < limit {
            let cand = self.free_ports(mask, c, occ);
            if cand != 0 {
                let p = self.least_used(cand);
                self.mark(p, c, occ);
                return c;
            }
            c += 1;
        }
        self.book_beyond(mask, t, occ)
    }

    /// [`Calendar::book`] when no port of `mask` is free before the
    /// window's end: each port gives the cycle its search stops at (a
    /// search skips runs of busy cycles a 64-cycle block at a time and
    /// stops at the first cycle past the window's end), the earliest wins.
    #[cold]
    fn book_beyond(&mut self, mask: u32, t: u64, occ: u64) -> u64 {
        let limit = self.base + WINDOW - occ;
        let mut best = (u64::MAX, u64::MAX, 0usize);
        let mut m = mask;
        while m != 0 {
            let p = m.trailing_zeros() as usize;
            m &= m - 1;
            let mut c = t.max(self.base);
            while c < limit {
                let mut busy = 0;
                while !self.free(p, c + busy) && (busy == 0 || !(c + busy).is_multiple_of(64)) {
                    busy += 1;
                }
                if busy > 0 {
                    c += busy;
                    continue;
                }
                if (1..occ).all(|k| self.free(p, c + k)) {
                    break;
                }
                c += 1;
            }
            if (c, self.uses[p]) < (best.0, best.1) {
                best = (c, self.uses[p], p);
            }
        }
        self.mark(best.2, best.0, occ);
        best.0
    }
}

/// Ready times of values, by id modulo the ring size: each entry the tag
/// it holds (the id, and the unit it belongs to) and its ready cycle side
/// by side (one host cache line read).
pub(crate) struct Values {
    ring: Box<[(u64, u64); VALUES]>,
    /// The current unit's tag bits (above the id's 32).
    unit: u64,
}

impl Values {
    pub fn new() -> Values {
        Values {
            ring: vec![(0u64, 0u64); VALUES]
                .into_boxed_slice()
                .try_into()
                .expect("VALUES entries"),
            unit: 0,
        }
    }
    /// Forget every value (a new unit numbers its values from 0 again):
    /// entries of earlier units no longer match, without clearing the ring.
    pub fn restart(&mut self) {
        self.unit += 1 << 32;
    }
    #[inline]
    pub fn get(&self, v: ValId) -> u64 {
        let (tag, at) = self.ring[v.0 as usize & (VALUES - 1)];
        if tag == self.unit | u64::from(v.0) {
            at
        } else {
            0
        }
    }
    #[inline]
    pub fn set(&mut self, v: ValId, t: u64) {
        self.ring[v.0 as usize & (VALUES - 1)] = (self.unit | u64::from(v.0), t);
    }
}

/// `table` with a taken branch's timing appended (at [`TAKEN_BRANCH`]):
/// the branch class's, its uops on `core.taken_branch_ports` if given.
fn with_taken_branch(mut table: Vec<ClassT>, m: &MachineConfig) -> Vec<ClassT> {
    let mut t = table[OpClass::Branch as usize].clone();
    let ports = &m.core.taken_branch_ports;
    if !ports.is_empty() {
        let each: Vec<Vec<u32>> = vec![ports.clone(); t.uops.len()];
        t.uops = Uops::of(&each);
    }
    table.push(t);
    table
}

/// What one hardware thread of a core holds of its own: its values, its
/// part of the ROB and store buffer, its front end's place, its retirement.
/// (Everything else of [`OooCore`] its threads share; see [`crate::smt`].)
pub(crate) struct Thread {
    values: Values,
    /// Retire cycle of each fused uop by its place in program order,
    /// modulo a power of two at least the full ROB's size (so the entry
    /// `rob` back is found with a mask, and a place not yet written reads 0).
    rob_ring: Vec<u64>,
    rob_seq: u64,
    /// This thread's ROB entries (the whole ROB, or its partition).
    rob: u64,
    /// This thread's store buffer (the whole buffer, or its partition).
    stores: Vec<StoreEntry>,
    store_seq: usize,
    /// Per 8-byte granule (hashed): the youngest store to write it, as its
    /// place in the store sequence plus one (0: none).
    granules: Box<[usize; GRANULES]>,
    /// The legacy decoders' place, for ops with an instruction length.
    legacy: Option<crate::frontend::Legacy>,
    /// The conditional predictor's global history while another thread
    /// runs (the tables are the core's).
    history: Option<crate::predictor::History>,
    d: u64,
    dcount: u32,
    fetch_block: u64,
    last_ret: u64,
    ret_count: u32,
    /// Cycle of this thread's last retirement.
    now: u64,
    /// Whether it has ops in the current step (SMT).
    running: bool,
}

impl Thread {
    fn new(m: &MachineConfig, share: u32) -> Thread {
        let c = &m.core;
        let share = share.max(1);
        Thread {
            values: Values::new(),
            rob_ring: vec![0; (c.rob as usize).next_power_of_two()],
            rob_seq: 0,
            rob: u64::from(c.rob / share),
            stores: vec![StoreEntry::default(); (c.store_buffer / share).max(1) as usize],
            store_seq: 0,
            granules: Box::new([0; GRANULES]),
            legacy: c
                .legacy_decode
                .map(|l| crate::frontend::Legacy::new(l, share)),
            history: None,
            d: 0,
            dcount: 0,
            fetch_block: 0,
            last_ret: 0,
            ret_count: 0,
            now: 0,
            running: false,
        }
    }
}

/// One hardware thread's ops for [`OooCore::run_threads`].
pub struct ThreadOps<'t> {
    /// The thread.
    pub thread: usize,
    /// Its ops.
    pub trace: &'t Trace,
    /// The next op to time.
    pub pos: usize,
    /// Where its ops end for now (a piece's end).
    pub end: usize,
}

/// An out-of-order core's state between ops.
pub struct OooCore {
    /// Ops whose pipeline times to keep, and those kept (thread 0's).
    pub timeline: Option<Timeline>,
    core: usize,
    classes: Vec<ClassT>,
    /// The class table for ops on operands of at most 16 bytes.
    narrow: Vec<ClassT>,
    /// A taken branch ends its dispatch group.
    taken_ends_issue: bool,
    width: u32,
    retire_width: u32,
    l1_latency: u64,
    sf_latency: u64,
    sf_fail: u64,
    sf_same_start: bool,
    sf_waits_commit: bool,
    macro_fusion: bool,
    penalty: u64,
    cal: Calendar,
    /// The scheduler, and the second one where the config splits them
    /// (`pools[1]`, for the uops of `fp_mask`'s ports).
    pools: [Pool; 2],
    fp_mask: u32,
    mshr: crate::memory::Mshrs,
    pred: Predictor,
    /// Per load site: the load once issued before an older store to its
    /// bytes had its address, so it now waits for every older store's
    /// address (Intel's memory disambiguation predictor).
    mdp: Vec<bool>,
    /// The running hardware thread's own state.
    th: Thread,
    /// The core's other hardware threads (SMT), each with its index.
    parked: Vec<(usize, Thread)>,
    /// The running thread's index.
    cur: usize,
    /// The selection points the threads take turns at, while more than one
    /// thread runs (`None`: one thread, today's single-thread core).
    smt: Option<crate::smt::Turns>,
    /// Cycle of the last retirement (of any of its threads).
    pub now: u64,
}

impl OooCore {
    /// A core of machine `m` with index `core` (its private caches), one
    /// hardware thread.
    #[must_use]
    pub fn new(m: &MachineConfig, core: usize) -> OooCore {
        let c = &m.core;
        OooCore {
            timeline: None,
            core,
            classes: with_taken_branch(class_table(m), m),
            narrow: with_taken_branch(class_table_of(m, true), m),
            taken_ends_issue: c.taken_branch_ends_issue,
            width: c.width,
            retire_width: c.retire_width,
            l1_latency: u64::from(m.caches[0].latency),
            sf_latency: u64::from(c.store_forward_latency),
            sf_fail: u64::from(c.store_forward_fail_penalty),
            sf_same_start: c.store_forward_wide_same_start,
            sf_waits_commit: c.store_forward_fail_waits_commit,
            macro_fusion: c.fuses(),
            penalty: u64::from(c.mispredict_penalty),
            cal: Calendar::new(c.ports as usize),
            pools: [
                Pool::new(c.scheduler as usize),
                Pool::new(c.fp_scheduler.as_ref().map_or(0, |f| f.entries as usize)),
            ],
            fp_mask: fp_mask(m),
            mshr: crate::memory::Mshrs::new(m.mshrs as usize),
            pred: Predictor::new(c.history_bits, c.predictor_bits, c.tage.as_ref()),
            mdp: vec![false; MDP],
            th: Thread::new(m, 1),
            parked: Vec::new(),
            cur: 0,
            smt: None,
            now: 0,
        }
    }

    /// A core of machine `m` with `threads` hardware threads (SMT; at most
    /// `core.threads`), thread 0 running.
    #[must_use]
    pub fn with_threads(m: &MachineConfig, core: usize, threads: usize) -> OooCore {
        let mut c = OooCore::new(m, core);
        let fresh = c.pred.history();
        c.parked = (1..threads.max(1))
            .map(|k| {
                let mut t = Thread::new(m, 1);
                t.history = Some(fresh.clone());
                (k, t)
            })
            .collect();
        c
    }

    /// Hardware threads.
    #[must_use]
    pub fn threads(&self) -> usize {
        1 + self.parked.len()
    }

    /// Cycle of thread `k`'s last retirement.
    #[must_use]
    pub fn thread_now(&self, k: usize) -> u64 {
        if k == self.cur {
            self.th.now
        } else {
            self.parked
                .iter()
                .find(|p| p.0 == k)
                .map_or(self.now, |p| p.1.now)
        }
    }

    /// Start a step in which the threads `running` (a bit per thread) have
    /// ops, every op in flight before it retired: with several, the ROB and
    /// the store buffer are split evenly among them and they take turns at
    /// dispatch and retirement ([`crate::smt`]); with one, it has them whole.
    pub fn start_step(&mut self, m: &MachineConfig, running: u32) {
        if self.parked.is_empty() {
            return;
        }
        let n = running.count_ones().max(1);
        let rob = u64::from(m.core.rob / n);
        let sb = (m.core.store_buffer / n).max(1) as usize;
        let threads = std::iter::once((self.cur, &mut self.th))
            .chain(self.parked.iter_mut().map(|p| (p.0, &mut p.1)));
        for (k, th) in threads {
            th.running = running >> k & 1 == 1;
            th.rob = rob;
            if th.stores.len() != sb {
                // Every store has retired: the buffer starts empty.
                th.stores = vec![StoreEntry::default(); sb];
                th.store_seq = 0;
                th.granules.fill(0);
            }
        }
        self.smt = (n > 1).then(crate::smt::Turns::new);
        if let Some(turns) = &mut self.smt {
            turns.advance(self.now);
        }
    }

    /// Thread `k` has no more ops this step: it no longer holds the
    /// booking calendars back.
    pub fn stop_thread(&mut self, k: usize) {
        if k == self.cur {
            self.th.running = false;
        } else if let Some(p) = self.parked.iter_mut().find(|p| p.0 == k) {
            p.1.running = false;
        }
    }

    /// Make thread `k` the running one (its global branch history into
    /// the predictor, the other's out).
    fn switch(&mut self, k: usize) {
        if k == self.cur {
            return;
        }
        let j = self
            .parked
            .iter()
            .position(|p| p.0 == k)
            .expect("a thread of this core");
        std::mem::swap(&mut self.th, &mut self.parked[j].1);
        self.parked[j].0 = self.cur;
        self.cur = k;
        let mut h = self.th.history.take().expect("a parked thread's history");
        self.pred.swap_history(&mut h);
        self.parked[j].1.history = Some(h);
    }

    /// The first cycle the running thread's next op could dispatch in, as
    /// far as its own state says.
    fn next_dispatch(&self, t: &Thread) -> u64 {
        (t.d + u64::from(t.dcount >= self.width)).max(t.fetch_block)
    }

    /// Time the threads' ops op by op, each next op from the thread whose
    /// next dispatch cycle is earliest (on a tie, the one that dispatched
    /// less recently, then the lowest), until one thread's ops run out
    /// (`pos == end`); returns its place in `ops`.
    pub fn run_threads(
        &mut self,
        ops: &mut [ThreadOps<'_>],
        mem: &mut Hierarchy,
        s: &mut Stats,
    ) -> usize {
        let classes = std::mem::take(&mut self.classes);
        let narrow = std::mem::take(&mut self.narrow);
        let timeline = self.timeline.is_some();
        // Each thread's (next dispatch cycle, last dispatch cycle, index):
        // only the thread that ran changes its own.
        let mut keys: Vec<(u64, u64, usize)> = ops
            .iter()
            .map(|o| {
                let th = if o.thread == self.cur {
                    &self.th
                } else {
                    &self
                        .parked
                        .iter()
                        .find(|p| p.0 == o.thread)
                        .expect("a thread of this core")
                        .1
                };
                (self.next_dispatch(th), th.d, o.thread)
            })
            .collect();
        let done = loop {
            if let Some(k) = ops.iter().position(|o| o.pos >= o.end) {
                break k;
            }
            let pick = (0..keys.len())
                .min_by_key(|&k| keys[k])
                .expect("some thread's ops");
            self.switch(ops[pick].thread);
            let o = &mut ops[pick];
            self.step(
                o.trace,
                (o.pos, o.end),
                (&classes, &narrow),
                mem,
                s,
                (0, timeline),
            );
            o.pos += 1;
            keys[pick] = (self.next_dispatch(&self.th), self.th.d, o.thread);
        };
        self.classes = classes;
        self.narrow = narrow;
        done
    }

    /// Time ops `range` of `t`, counting into `s` (stats only for ops at or after `count_from`).
    pub fn run(
        &mut self,
        t: &Trace,
        range: std::ops::Range<usize>,
        mem: &mut Hierarchy,
        s: &mut Stats,
        count_from: usize,
    ) {
        // The class table is read while the core's state changes.
        let classes = std::mem::take(&mut self.classes);
        let narrow = std::mem::take(&mut self.narrow);
        let timeline = self.timeline.is_some();
        let end = range.end;
        for i in range {
            self.step(
                t,
                (i, end),
                (&classes, &narrow),
                mem,
                s,
                (count_from, timeline),
            );
        }
        self.classes = classes;
        self.narrow = narrow;
    }

    /// Time op `i` of `t` (`end`: where the ops given end) on the running
    /// thread.
    #[inline(always)]
    fn step(
        &mut self,
        t: &Trace,
        (i, end): (usize, usize),
        (classes, narrow): (&[ClassT], &[ClassT]),
        mem: &mut Hierarchy,
        s: &mut Stats,
        (count_from, timeline): (usize, bool),
    ) {
        let op = &t.ops[i];
        let fused = self.macro_fusion
            && op.class == OpClass::Cmp
            && i + 1 < end
            && fuses(op, &t.ops[i + 1]);
        let taken_branch = op.class == OpClass::Branch && op.taken();
        let ct = if fused {
            &FUSED_CMP
        } else if taken_branch {
            &classes[TAKEN_BRANCH]
        } else if op.bytes != 0 && op.bytes <= 16 && !op.class.is_per_lane_mem() {
            // A gather's or scatter's bytes are per lane: never narrow.
            &narrow[op.class as usize]
        } else {
            &classes[op.class as usize]
        };
        let counted = i >= count_from;
        let decoded = if op.ilen == 0 {
            0
        } else {
            self.legacy_decoded(op, ct.fused, taken_branch)
        };
        let (d, f, mut why) = self.dispatch(ct, decoded);
        if op.ilen != 0 {
            self.legacy_dispatched(d, ct.fused);
        }
        if taken_branch && self.taken_ends_issue {
            // The next op dispatches in the next cycle.
            self.th.dcount = self.width;
        }
        let Issued {
            first,
            last,
            operands,
            gather_lat,
            gather_level,
            wait_port,
            ports,
        } = self.issue(t, op, ct, d, mem);
        let mut done = if fused {
            first
        } else {
            // (An op with no uops — an eliminated move, a zero idiom —
            // has `last` one before `first`: done at `first + lat`.)
            (first + ct.lat).max(last + 1)
        };
        if ct.per_lane {
            done += gather_lat;
            if gather_lat > 0 {
                why = Stall::memory(gather_level, mem.levels()).unwrap_or(why);
            }
        } else {
            done = self.execute(op, ct, (d, first, done), mem, (s, counted), &mut why);
        }
        if why == Stall::Issue && done > d + 1 + ct.lat + 1 {
            // Late: charged to the longer of the wait for operands
            // (after dispatch) and the wait for a port (after them).
            why = if first.saturating_sub(operands) > operands.saturating_sub(d + 1) {
                Stall::Ports
            } else {
                Stall::Dependency
            };
        }
        if op.dst.is_some() {
            self.th.values.set(op.dst, done);
        }
        if op.class == OpClass::Branch {
            self.branch(op, done, (s, counted));
        }
        let ret = self.retire(f, done);
        if ct.store && !ct.per_lane {
            let k = (self.th.store_seq - 1) % self.th.stores.len();
            self.th.stores[k].ret = ret;
        }
        if counted {
            count(s, op, ct, why, ret - self.th.last_ret);
            count_ports(s, op, ct, (why, ret - self.th.last_ret), (wait_port, ports));
        }
        if timeline && self.cur == 0 {
            self.note_timeline(i, op, (d, first, done, ret), why);
        }
        self.th.last_ret = ret;
        self.th.now = ret;
        self.now = self.now.max(ret);
    }

    /// Keep op `i`'s pipeline times when it is in the timeline's window.
    /// Out of line: only `rtsim sim --timeline` asks for them.
    #[inline(never)]
    #[cold]
    fn note_timeline(&mut self, i: usize, op: &Op, times: (u64, u64, u64, u64), why: Stall) {
        if let Some(tl) = &mut self.timeline {
            tl.note(i, op, times, why);
        }
    }

    /// The first cycle an op with an instruction length may dispatch,
    /// from the legacy decoders (0 without them). Out of line: recorded
    /// kernels carry no lengths.
    #[inline(never)]
    fn legacy_decoded(&mut self, op: &Op, fused: u32, taken: bool) -> u64 {
        let (d, redirect) = (self.th.d, self.th.fetch_block);
        match &mut self.th.legacy {
            Some(l) => l.decode(op, fused, taken, (d, redirect)),
            None => 0,
        }
    }

    /// When an op with a slower condition may issue: its result comes
    /// `lat` after its other sources and `cond_lat` after its first (the
    /// flags: a select's condition), so the condition counts `cond_lat -
    /// lat` later.
    #[inline(never)]
    fn cond_ready(&self, op: &Op, ct: &ClassT, d: u64) -> u64 {
        let src = op.sources();
        let mut r = d + 1;
        if let Some((&cond, rest)) = src.split_first() {
            for &s in rest {
                r = r.max(self.th.values.get(s));
            }
            r = r.max(self.th.values.get(cond) + ct.cond_extra);
        }
        r
    }

    /// A legacy-decoded op's uops left the decoded-uop queue in cycle `d`.
    #[inline(never)]
    fn legacy_dispatched(&mut self, d: u64, fused: u32) {
        if let Some(l) = &mut self.th.legacy {
            l.dispatched(d, fused);
        }
    }

    /// Functional warming: `t`'s ops update the caches, the prefetcher and
    /// the branch predictor in program order, untimed; the core's clock moves
    /// on by the ops' dispatch bound (fused uops / width) so the memory
    /// system's clock keeps going.
    pub fn warm(&mut self, t: &Trace, mem: &mut Hierarchy) {
        self.warm_thread(0, t, mem);
    }

    /// [`OooCore::warm`] as hardware thread `k` (its branch history).
    pub fn warm_thread(&mut self, k: usize, t: &Trace, mem: &mut Hierarchy) {
        self.switch(k);
        let width = u64::from(self.width.max(1));
        let mut fused = 0u64;
        for op in &t.ops {
            let ct = &self.classes[op.class as usize];
            mem.warm_op(self.core, t, op, self.now + fused / width);
            if op.class == OpClass::Branch {
                self.pred.predict_and_update(op.site().0, op.taken());
            }
            fused += u64::from(ct.fused);
        }
        self.advance_to(self.now + fused / width);
    }

    /// Move the core's clock on to cycle `t` (nothing in flight after it):
    /// the start of a unit that begins with the other cores'.
    pub fn advance_to(&mut self, t: u64) {
        if t <= self.now && self.parked.is_empty() {
            return;
        }
        let threads = std::iter::once(&mut self.th).chain(self.parked.iter_mut().map(|p| &mut p.1));
        for th in threads {
            th.d = th.d.max(t);
            th.dcount = 0;
            th.last_ret = th.last_ret.max(t);
            th.now = th.now.max(t);
        }
        self.now = self.now.max(t);
        self.cal.advance(t);
        if let Some(turns) = &mut self.smt {
            turns.advance(t);
        }
        for p in &mut self.pools {
            p.free_until(t);
        }
    }

    /// Dispatch: the cycle the op enters the window (after the width, a
    /// mispredict's redirect, a free ROB entry and free scheduler entries);
    /// (cycle, fused-domain uops, stall reason so far).
    #[inline(always)]
    fn dispatch(&mut self, ct: &ClassT, decoded: u64) -> (u64, u32, Stall) {
        let f = ct.fused;
        let mut d = self.th.d;
        if self.th.dcount + f > self.width {
            d += 1;
        }
        let mut why = Stall::Issue;
        if self.th.fetch_block > d {
            d = self.th.fetch_block;
            why = Stall::Branch;
        }
        if decoded > d {
            d = decoded;
            why = Stall::FrontEnd;
        }
        if f > 0 {
            let back = (self.th.rob_seq + u64::from(f) - 1).wrapping_sub(self.th.rob);
            let need = self.th.rob_ring[back as usize & (self.th.rob_ring.len() - 1)];
            if need > d {
                d = need;
                why = Stall::Resources;
            }
        }
        if ct.store && !ct.per_lane {
            // The entry this store takes is free once its last store retired.
            let free = self.th.stores[self.th.store_seq % self.th.stores.len()].ret + 1;
            if free > d && self.th.store_seq >= self.th.stores.len() {
                d = free;
                why = Stall::Resources;
            }
        }
        let nuops = ct.uops.len();
        let fp = usize::from(ct.fp_uops);
        // Entries whose uops issued by cycle d are free; wait for the
        // earliest-issuing others until each scheduler has room.
        for (pool, n) in [(0, nuops - fp), (1, fp)] {
            if n > 0 {
                if let Some(later) = self.pools[pool].room_for(n, d) {
                    d = later;
                    why = Stall::Resources;
                }
            }
        }
        if let Some(turns) = &mut self.smt {
            // Rename takes one thread's uops a cycle (crate::smt, rule 1).
            let c = turns.dispatch.take(self.cur, d);
            if c > d {
                d = c;
                why = Stall::Thread;
            }
        }
        if d > self.th.d {
            self.th.dcount = 0;
            let floor = self.floor(d);
            self.cal.advance(floor);
            if let Some(turns) = &mut self.smt {
                turns.advance(floor);
            }
        }
        self.th.d = d;
        self.th.dcount += f;
        (d, f, why)
    }

    /// Issue: every uop on the first free cycle of an allowed port after the
    /// sources are ready; per-lane accesses pay their distinct lines. (first
    /// and last issue cycle, the slowest line's latency beyond L1).
    #[inline(always)]
    fn issue(&mut self, t: &Trace, op: &Op, ct: &ClassT, d: u64, mem: &mut Hierarchy) -> Issued {
        let nuops = ct.uops.len();
        let mut r = d + 1;
        for &src in op.sources() {
            r = r.max(self.th.values.get(src));
        }
        if ct.cond_extra > 0 {
            r = self.cond_ready(op, ct, d);
        }
        if ct.load && op.aux != 0 && !ct.per_lane && self.mdp[mdp_slot(op)] {
            r = r.max(self.older_store_addresses(r));
        }
        let mut first = u64::MAX;
        let mut last = 0;
        let mut extra_occ = 0;
        let mut gather_lat = 0u64;
        let mut gather_level = 0;
        let (mut wait, mut wait_port, mut ports) = (0, 0, 0u64);
        if ct.per_lane {
            // Distinct lines cost port cycles (per_line) and their latency.
            let lines = mem.lines_of(t, op);
            extra_occ = ct.per_line * (lines.len() as u64).saturating_sub(1);
            for l in lines {
                let sv = mem.access(
                    self.core,
                    l * mem.line_bytes(),
                    op.class.is_store(),
                    op.mem,
                    r,
                );
                gather_lat = gather_lat.max(sv.latency.saturating_sub(self.l1_latency));
                gather_level = gather_level.max(sv.level);
            }
        }
        // A two-uop store that names its address source issues its address
        // uop when the address is ready and its data uop when the data is.
        let (r_first, r_rest) = if ct.store && nuops == 2 && op.has_addr_src() {
            self.store_ready(op, d)
        } else {
            (r, r)
        };
        for (k, &mask) in ct.uops.iter().enumerate() {
            let (occ, ready) = if k == 0 {
                (ct.occ + extra_occ, r_first)
            } else {
                (ct.occ, r_rest)
            };
            let c = self.cal.book(mask, ready, occ);
            let p = self.cal.last;
            ports |= u64::from(p) << (4 * k);
            if c.saturating_sub(ready) > wait || k == 0 {
                (wait, wait_port) = (c.saturating_sub(ready), p);
            }
            first = first.min(c);
            last = last.max(c);
            let pool = usize::from(in_fp_pool(mask, self.fp_mask));
            self.pools[pool].hold(c);
        }
        if nuops == 0 {
            // Done at rename: ready when its sources are, plus its latency.
            first = r;
            last = r - 1;
        }
        Issued {
            first,
            last,
            operands: r_first,
            gather_lat,
            gather_level,
            wait_port,
            ports,
        }
    }

    /// Execute a load (store forwarding, or a miss slot then the hierarchy)
    /// or a store (into the hierarchy and the store buffer); the cycle the
    /// result is ready.
    #[inline(always)]
    fn execute(
        &mut self,
        op: &Op,
        ct: &ClassT,
        (d, first, mut done): (u64, u64, u64),
        mem: &mut Hierarchy,
        (s, counted): (&mut Stats, bool),
        why: &mut Stall,
    ) -> u64 {
        if ct.load {
            let lo = op.addr.0;
            let hi = lo + u64::from(op.bytes);
            if let Some((st, whole)) = self.forwarding(lo, hi, first) {
                if op.aux != 0 && st.addr > first {
                    // Issued before the store's address was known: a
                    // memory-ordering machine clear; the site now waits.
                    self.mdp[mdp_slot(op)] = true;
                    self.th.fetch_block = self.th.fetch_block.max(st.addr + self.penalty);
                    s.ordering_clears += u64::from(counted);
                }
                done = first.max(st.data).max(st.addr) + self.sf_latency;
                if whole {
                    s.forwarded += u64::from(counted);
                } else {
                    done += self.sf_fail;
                    if self.sf_waits_commit && st.ret < u64::MAX - 1 {
                        // The store writes the L1 the cycle after it
                        // retires; the load reads it there.
                        done = done.max(st.ret + 1 + self.l1_latency);
                    }
                    s.forward_fails += u64::from(counted);
                    *why = Stall::Forwarding;
                }
            } else {
                // An L1 miss first waits for a miss slot; the access starts then.
                let (ready, level) =
                    mem.load_span(self.core, (lo, op.bytes), op.mem, first, &mut self.mshr);
                if let Some(w) = Stall::memory(level, mem.levels()) {
                    *why = w;
                }
                done = ready + ct.load_extra;
            }
        } else if ct.store {
            mem.store_span(self.core, (op.addr.0, op.bytes), op.mem, first);
            let (addr, data) = self.store_ready(op, d);
            let k = self.th.store_seq % self.th.stores.len();
            self.th.stores[k] = StoreEntry {
                lo: op.addr.0,
                hi: op.addr.0 + u64::from(op.bytes),
                addr,
                data,
                ret: u64::MAX - 1,
            };
            self.th.store_seq += 1;
            let hi = op.addr.0 + u64::from(op.bytes);
            for g in op.addr.0 >> 3..=(hi.max(op.addr.0 + 1) - 1) >> 3 {
                self.th.granules[g as usize % GRANULES] = self.th.store_seq;
            }
        }
        done
    }

    /// When a store's address is known and when its data is ready (each at
    /// least a cycle after its dispatch `d`): its first source is the
    /// address if it names one ([`Op::has_addr_src`]), the rest its data.
    #[inline(always)]
    fn store_ready(&self, op: &Op, d: u64) -> (u64, u64) {
        let (addr, data) = op.sources().split_at(usize::from(op.has_addr_src()));
        let at = |vs: &[ValId]| {
            vs.iter()
                .map(|v| self.th.values.get(*v))
                .fold(d + 1, u64::max)
        };
        (at(addr), at(data))
    }

    /// The stores still in the buffer at cycle `at`, youngest first.
    /// Entries retire in program order, so the walk stops at the first
    /// retired one.
    #[inline(always)]
    fn buffered(&self, at: u64) -> impl Iterator<Item = &StoreEntry> {
        let n = self.th.stores.len();
        (1..=self.th.store_seq.min(n))
            .map(move |j| &self.th.stores[(self.th.store_seq - j) % n])
            .take_while(move |st| st.ret >= at)
    }

    /// The youngest store in the buffer when a load of bytes `lo..hi`
    /// executes at `at` that overlaps it, and whether it can forward: it
    /// holds every byte of the load and (`store_forward_wide_same_start`, for
    /// a store wider than 8 bytes) starts where the load does.
    #[inline(always)]
    fn forwarding(&self, lo: u64, hi: u64, at: u64) -> Option<(StoreEntry, bool)> {
        if !self.store_near(lo, hi) {
            return None;
        }
        self.buffered(at)
            .find(|st| st.lo < hi && lo < st.hi)
            .map(|st| {
                let contained = st.lo <= lo && hi <= st.hi;
                let start = !self.sf_same_start || st.hi - st.lo <= 8 || st.lo == lo;
                (*st, contained && start)
            })
    }

    /// Whether a store the buffer may still hold wrote a granule (8 bytes,
    /// hashed) of bytes `lo..hi`: if not, no buffered store overlaps them
    /// and the walk is skipped. (A granule's slot holds the youngest store
    /// to it or to a granule hashed alike; younger stores leave the buffer
    /// later, so the slot is never older than an overlapping store.)
    #[inline(always)]
    fn store_near(&self, lo: u64, hi: u64) -> bool {
        let oldest = self.th.store_seq.saturating_sub(self.th.stores.len());
        (lo >> 3..=(hi.max(lo + 1) - 1) >> 3).any(|g| {
            let v = self.th.granules[g as usize % GRANULES];
            v > oldest
        })
    }

    /// The latest time an older store still in the buffer at `at` has its
    /// address known (what a load predicted to depend on a store waits for).
    fn older_store_addresses(&self, at: u64) -> u64 {
        self.buffered(at).map(|st| st.addr).max().unwrap_or(0)
    }

    /// Predict a branch, update the predictor; a mispredict blocks fetch
    /// until it resolves plus the penalty.
    #[inline(always)]
    fn branch(&mut self, op: &Op, done: u64, (s, counted): (&mut Stats, bool)) {
        let taken = op.taken();
        let ok = self.pred.predict_and_update(op.site().0, taken);
        if counted {
            s.branches += 1;
            s.mispredicts += u64::from(!ok);
        }
        if !ok {
            self.th.fetch_block = done + self.penalty;
        }
    }

    /// The first cycle from `c` this thread may retire in (every cycle
    /// with one thread).
    #[inline(always)]
    fn retire_turn(&mut self, c: u64) -> u64 {
        match &mut self.smt {
            Some(turns) => turns.retire.take(self.cur, c),
            None => c,
        }
    }

    /// The earliest cycle any running thread may still dispatch in, with
    /// the running thread at `d`: booking calendars are cleared only
    /// before it.
    #[inline(always)]
    fn floor(&self, d: u64) -> u64 {
        if self.smt.is_none() {
            return d;
        }
        self.parked
            .iter()
            .filter(|(_, t)| t.running)
            .fold(d, |f, (_, t)| f.min(t.d))
    }

    /// Retire in order at the retire width; the op's retire cycle.
    #[inline(always)]
    fn retire(&mut self, f: u32, done: u64) -> u64 {
        let mut ret = done.max(self.th.last_ret);
        if f > 0 {
            ret = self.retire_turn(ret);
        }
        if ret > self.th.last_ret {
            self.th.ret_count = 0;
        }
        if self.th.ret_count + f > self.retire_width {
            ret = self.retire_turn(ret + 1);
            self.th.ret_count = 0;
        }
        self.th.ret_count += f;
        for _ in 0..f {
            let k = self.th.rob_seq as usize & (self.th.rob_ring.len() - 1);
            self.th.rob_ring[k] = ret;
            self.th.rob_seq += 1;
        }
        ret
    }
}

/// The pipeline times of a window of ops (`rtsim sim --timeline`).
#[derive(Clone, Debug)]
pub struct Timeline {
    window: std::ops::Range<usize>,
    /// The ops of the window timed so far, in order.
    pub events: Vec<crate::stats::OpTimes>,
}

impl Timeline {
    /// Keep the times of the ops with trace indices in `window`.
    #[must_use]
    pub fn new(window: std::ops::Range<usize>) -> Timeline {
        Timeline {
            window,
            events: Vec::new(),
        }
    }

    /// Op `i` dispatched at `d`, issued at `first`, done at `done`, retired at `ret`.
    fn note(&mut self, i: usize, op: &Op, (d, first, done, ret): (u64, u64, u64, u64), why: Stall) {
        if self.window.contains(&i) {
            self.events.push(crate::stats::OpTimes {
                index: i,
                class: op.class,
                region: op.region,
                dispatch: d,
                // An op with no uops (an eliminated move) issues nowhere.
                issue: first.min(done),
                complete: done,
                retire: ret,
                stall: why,
            });
        }
    }
}

/// The memory-dependence predictor entry of a load's site.
#[inline(always)]
fn mdp_slot(op: &Op) -> usize {
    op.aux as usize % MDP
}

/// Whether compare `cmp` macro-fuses with `next`: a branch on its value.
#[inline(always)]
fn fuses(cmp: &Op, next: &Op) -> bool {
    next.class == OpClass::Branch && next.nsrc == 1 && next.srcs[0] == cmp.dst && cmp.dst.is_some()
}

/// Count a timed op into the statistics: `delta` cycles to its retire.
#[inline(always)]
fn count(s: &mut Stats, op: &Op, ct: &ClassT, why: Stall, delta: u64) {
    s.ops += crate::stats::instructions(op.class);
    s.uops += ct.uops.len() as u64;
    s.region_ops[op.region as usize] += crate::stats::instructions(op.class);
    s.region_cycles[op.region as usize] += delta;
    s.stalls[why as usize] += delta;
    s.region_stalls[op.region as usize][why as usize] += delta;
    s.class_ops[op.class as usize] += 1;
    if ct.vector {
        s.vector_ops += 1;
        s.active_lanes += u64::from(op.mask.count());
    }
}

/// An op's uops on their ports, and its port-pressure cycles on the port
/// its longest-waiting uop took.
#[inline(always)]
fn count_ports(
    s: &mut Stats,
    op: &Op,
    ct: &ClassT,
    (why, delta): (Stall, u64),
    (wait_port, ports): (u8, u64),
) {
    let r = op.region as usize;
    for k in 0..ct.uops.len() {
        s.region_port_uops[r][(ports >> (4 * k)) as usize & 15] += 1;
    }
    if why == Stall::Ports {
        s.region_port_stalls[r][usize::from(wait_port)] += delta;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The calendar's rule, written plainly: per port a set of busy cycles;
    /// the earliest cycle >= max(t, base) where some port of `mask` is free
    /// for `occ` cycles, on a tie the least used port, then the lowest.
    struct Plain {
        busy: Vec<std::collections::BTreeSet<u64>>,
        uses: Vec<u64>,
        base: u64,
    }

    impl Plain {
        fn book(&mut self, mask: u32, t: u64, occ: u64) -> u64 {
            let mut c = t.max(self.base);
            loop {
                let free: Vec<usize> = (0..16)
                    .filter(|&p| mask >> p & 1 != 0)
                    .filter(|&p| (c..c + occ).all(|k| !self.busy[p].contains(&k)))
                    .collect();
                if let Some(&p) = free.iter().min_by_key(|&&p| (self.uses[p], p)) {
                    self.busy[p].extend(c..c + occ);
                    self.uses[p] += 1;
                    return c;
                }
                c += 1;
            }
        }
    }

    #[test]
    fn a_scheduler_entry_held_past_the_ring_is_freed_when_it_issues() {
        let mut p = Pool::new(2);
        p.hold(5);
        p.hold(WINDOW + 10);
        // One free entry after the uop issuing at 5 leaves.
        assert_eq!(p.room_for(1, 1), Some(5));
        // Both free only when the far one issues, a ring later.
        assert_eq!(p.room_for(2, 6), Some(WINDOW + 10));
        assert_eq!(p.room_for(2, WINDOW + 11), None);
    }

    #[test]
    fn calendar_books_as_the_plain_rule_on_seeded_bookings() {
        let mut cal = Calendar::new(8);
        let mut plain = Plain {
            busy: vec![Default::default(); 16],
            uses: vec![0; 16],
            base: 0,
        };
        let mut x = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        };
        // Masks as machine configs have them: one port, two, four.
        let masks = [
            0b1,
            0b10,
            0b11,
            0b1100_0011,
            0b110_0011,
            0b1000_0000,
            0b1_0000,
        ];
        // Start near the ring's end, so bookings wrap around it.
        let mut base = WINDOW - 1_500;
        cal.advance(base);
        plain.base = base;
        for i in 0..20_000 {
            if i % 7 == 0 {
                base += next() % 3;
                cal.advance(base);
                plain.base = base;
            }
            let mask = masks[(next() % masks.len() as u64) as usize];
            let t = base + next() % 12;
            let occ = if next() % 10 == 0 { 1 + next() % 6 } else { 1 };
            assert_eq!(
                cal.book(mask, t, occ),
                plain.book(mask, t, occ),
                "booking {i}"
            );
        }
    }
}
