//! The two multi-hit intersection filters, each for single rays (scalar
//! code, Listing 1) and packets (the same code in SPMD form over the lanes,
//! as the paper's ispc modules: a lane's loop runs while its condition
//! holds, the packet's while any lane's does), and the buffer set-up each
//! needs before traversal. Node culling's packet insertion reads and moves
//! one SoA row per step (every lane still moving holds the same entry
//! index), as a programmer writes it for an 8-wide call; the form that
//! gathers and scatters per lane is kept as a variant ([`Insertion`]).

use crate::buffers::HitBufs;
use crate::site;
use crate::{at, each, FILTER_REGION};
use isa::{At, Cmp, IOp, Machine, Region, SOp};
use rt::filter::{Candidate1, CandidateK, Filter};

/// How node culling's packet filter moves entries.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Insertion {
    /// One row per step: the lanes still moving all hold entry index k
    /// (they start at N_query and step down together, and a lane that
    /// stops never restarts), so entry k - 1's row is one vector load and
    /// the move one masked row store; a lane that stops is placed by a
    /// masked store at the row it stopped at.
    #[default]
    Rows,
    /// Per-lane indices: each step gathers the entry below and scatters it
    /// up, and one final scatter places every lane (ispc's code for a
    /// `varying` index it cannot prove uniform).
    GatherScatter,
}

/// Listing 1's node-culling filter over N_query + 1 entries per ray.
pub struct NodeCulling {
    /// The rays' buffers.
    pub bufs: HitBufs,
    /// N_query.
    pub n_query: u32,
    /// How the packet filter moves entries.
    pub insertion: Insertion,
    /// Candidates judged.
    pub candidates: u64,
    /// Candidates accepted with t_far = the N_query-th hit.
    pub accepted: u64,
    /// Entries moved up by the insertion.
    pub moves: u64,
    /// Steps of the insertion's walk: entries (single rays) or entry rows
    /// (packets) compared with a candidate.
    pub steps: u64,
}

impl NodeCulling {
    /// The filter over `bufs` (`n_query + 1` entries per ray).
    #[must_use]
    pub fn new(bufs: HitBufs, n_query: u32) -> NodeCulling {
        assert_eq!(bufs.cap, n_query + 1, "N_query + 1 entries");
        NodeCulling {
            bufs,
            n_query,
            insertion: Insertion::default(),
            candidates: 0,
            accepted: 0,
            moves: 0,
            steps: 0,
        }
    }

    /// Before traversal, for `n` single rays: every entry's t beyond any
    /// hit (+inf, as `FLT_MAX` in the paper), no hits held.
    pub fn init_single<M: Machine>(&mut self, m: &mut M, n: usize) {
        m.region(Region::Setup);
        let (cap, b) = (self.bufs.cap as usize, &mut self.bufs);
        let inf = m.float(f32::INFINITY);
        let zero = m.int(0);
        let mut ptr = m.int(0);
        each(m, n, site::INIT_RAY, |m, ray| {
            m.s_store(&mut b.counts, At::idx(ray, 4, 0), 4, zero);
            each(m, cap, site::INIT_ENTRY, |m, _| {
                m.x_store(&mut b.entries, at(ptr, 0), inf);
                ptr = m.s_addi(ptr, 8);
            });
        });
    }

    /// Before traversal, for `np` packets: the count row zero, each entry's
    /// t row +inf.
    pub fn init_packets<M: Machine>(&mut self, m: &mut M, np: usize) {
        m.region(Region::Setup);
        let (cap, w, b) = (self.bufs.cap as usize, M::LANES, &mut self.bufs);
        let inf = m.splat(f32::INFINITY);
        let zero = m.splat(0.0);
        let mut ptr = m.int(0);
        each(m, np, site::INIT_PACKET, |m, _| {
            m.store(&mut b.entries, at(ptr, 0), zero);
            ptr = m.s_addi(ptr, 4 * w as i64);
            each(m, cap, site::INIT_ENTRY, |m, _| {
                m.store(&mut b.entries, at(ptr, 0), inf);
                ptr = m.s_addi(ptr, 8 * w as i64);
            });
        });
    }
}

impl NodeCulling {
    /// [`Insertion::Rows`]: from entry N_query down, one row at a time.
    fn insert_rows<M: Machine>(&mut self, m: &mut M, c: &CandidateK<M>, base: M::S) {
        let (w, n) = (M::LANES, self.n_query as i64);
        let e = &mut self.bufs.entries;
        let row = 8 * w as i64;
        let prim = c.prim;
        let zero = m.int(0);
        let mut k = m.int(n);
        // Entry k's t row (its triangle row is 4W bytes on).
        let mut ptr = m.s_addi(base, 4 * w as i64 + row * n);
        let mut active = c.valid;
        let mut reached_zero = true;
        loop {
            if !m.branch_if(site::CULL_PK_ROW, Cmp::Gt, k, zero) {
                break;
            }
            let prev = m.s_addi(ptr, -row);
            self.steps += 1;
            let pt = m.load(e, at(prev, 0));
            let closer = m.cmp(Cmp::Lt, c.t, pt);
            // Lanes not nearer than entry k - 1 go at entry k.
            let stays = m.knot(closer);
            let place = m.kand(active, stays);
            m.store_masked(place, e, at(ptr, 0), c.t);
            m.store_masked(place, e, at(ptr, 4 * w), prim);
            active = m.kand(active, closer);
            let any = m.any(active);
            if !m.branch(site::CULL_PK_SHIFT, any) {
                reached_zero = false;
                break;
            }
            self.moves += u64::from(m.bits(active).count_ones());
            let pp = m.load(e, at(prev, 4 * w));
            m.store_masked(active, e, at(ptr, 0), pt);
            m.store_masked(active, e, at(ptr, 4 * w), pp);
            ptr = prev;
            k = m.s_addi(k, -1);
        }
        if reached_zero {
            // Nearer than every entry held: entry 0.
            m.store_masked(active, e, at(ptr, 0), c.t);
            m.store_masked(active, e, at(ptr, 4 * w), prim);
        }
    }

    /// [`Insertion::GatherScatter`]: per-lane indices, gathered and scattered.
    fn insert_gathered<M: Machine>(&mut self, m: &mut M, c: &CandidateK<M>, base: M::S) {
        let (w, n) = (M::LANES, self.n_query as usize);
        let e = &mut self.bufs.entries;
        let ix = EntryIndex::new(m);
        let (one, zero_i) = (m.splat_i(1), m.splat_i(0));
        let inf = m.splat(f32::INFINITY);
        let mut idx = m.splat_i(n as i32);
        let mut active = c.valid;
        loop {
            let pos = m.icmp(Cmp::Gt, idx, zero_i);
            active = m.kand(active, pos);
            let below = m.iop(IOp::Sub, idx, one);
            let from = ix.t(m, below);
            self.steps += 1;
            let pt = m.gather(active, inf, e, at(base, 0), from, 4);
            let closer = m.cmp(Cmp::Lt, c.t, pt);
            active = m.kand(active, closer);
            let any = m.any(active);
            if !m.branch(site::CULL_PK_SHIFT, any) {
                break;
            }
            self.moves += u64::from(m.bits(active).count_ones());
            let pp = m.gather(active, inf, e, at(base, 4 * w), from, 4);
            let to = ix.t(m, idx);
            m.scatter(active, e, at(base, 0), to, 4, pt);
            m.scatter(active, e, at(base, 4 * w), to, 4, pp);
            idx = m.iselect(active, below, idx);
        }
        let to = ix.t(m, idx);
        m.scatter(c.valid, e, at(base, 0), to, 4, c.t);
        m.scatter(c.valid, e, at(base, 4 * w), to, 4, c.prim);
    }
}

impl<M: Machine> Filter<M> for NodeCulling {
    fn one(&mut self, m: &mut M, c: Candidate1<M>) -> Option<M::X> {
        m.region(FILTER_REGION);
        self.candidates += 1;
        let n = i64::from(self.n_query);
        let e = &mut self.bufs.entries;
        let stride = m.int(8 * (n + 1));
        let base = m.s_op(SOp::Mul, c.ray, stride);
        // Find the index: from N_query down while the entry below is farther,
        // moving each such entry up one.
        let zero = m.int(0);
        let mut idx = m.int(n);
        let mut ptr = m.s_addi(base, 8 * n);
        loop {
            if !m.branch_if(site::CULL_IDX, Cmp::Gt, idx, zero) {
                break;
            }
            let prev = m.s_addi(ptr, -8);
            self.steps += 1;
            let pt = m.x_load(e, at(prev, 0));
            let closer = m.x_cmp(Cmp::Lt, c.t, pt);
            if !m.branch(site::CULL_CLOSER, closer) {
                break;
            }
            let entry = m.s_load(e, at(prev, 0), 8, false);
            m.s_store(e, at(ptr, 0), 8, entry);
            self.moves += 1;
            ptr = prev;
            idx = m.s_addi(idx, -1);
        }
        // Store it, possibly at index N_query (beyond the N closest).
        m.x_store(e, at(ptr, 0), c.t);
        m.s_store(e, at(ptr, 4), 4, c.prim);
        // nhits += nhits < N_query.
        let counts = &mut self.bufs.counts;
        let held = m.s_load(counts, At::idx(c.ray, 4, 0), 4, false);
        let nq = m.int(n);
        let below = m.s_cmp(Cmp::Lt, held, nq);
        let held = m.s_add(held, below);
        m.s_store(counts, At::idx(c.ray, 4, 0), 4, held);
        if m.branch_if(site::CULL_HELD, Cmp::Lt, held, nq) {
            return None;
        }
        // Accept with t_far = the N_query-th hit's t: farther nodes are culled.
        self.accepted += 1;
        let t_far = m.x_load(&self.bufs.entries, at(base, 8 * (n as usize - 1)));
        Some(t_far)
    }

    fn packet(&mut self, m: &mut M, c: CandidateK<M>) -> (M::K, M::F) {
        m.region(FILTER_REGION);
        let (w, n) = (M::LANES, self.n_query as usize);
        self.candidates += u64::from(m.bits(c.valid).count_ones());
        let pbytes = m.int(self.bufs.packet_bytes() as i64);
        let base = m.s_op(SOp::Mul, c.packet, pbytes);
        match self.insertion {
            Insertion::Rows => self.insert_rows(m, &c, base),
            Insertion::GatherScatter => self.insert_gathered(m, &c, base),
        }
        let e = &mut self.bufs.entries;
        let one = m.splat_i(1);
        // nhits += nhits < N_query, in the lanes that hit.
        let held_f = m.load(e, at(base, 0));
        let held = m.bits_to_i(held_f);
        let nq = m.splat_i(n as i32);
        let below = m.icmp(Cmp::Lt, held, nq);
        let inc = m.kand(below, c.valid);
        let plus = m.iop(IOp::Add, held, one);
        let held = m.iselect(inc, plus, held);
        let held_f = m.bits_to_f(held);
        m.store(e, at(base, 0), held_f);
        let full = m.icmp(Cmp::Ge, held, nq);
        let acc = m.kand(full, c.valid);
        self.accepted += u64::from(m.bits(acc).count_ones());
        // The N_query-th entry is the same row in every lane: one load.
        let t_far = m.load(e, at(base, 4 * w * (1 + 2 * (n - 1))));
        (acc, t_far)
    }
}

/// The naive filter: append every hit (while there is room), reject.
pub struct Naive {
    /// The rays' buffers.
    pub bufs: HitBufs,
    /// Candidates judged.
    pub candidates: u64,
    /// Hits with no room left.
    pub overflowed: u64,
}

impl Naive {
    /// The filter over `bufs`.
    #[must_use]
    pub fn new(bufs: HitBufs) -> Naive {
        Naive {
            bufs,
            candidates: 0,
            overflowed: 0,
        }
    }

    /// Before traversal, for `n` single rays: no hits held.
    pub fn init_single<M: Machine>(&mut self, m: &mut M, n: usize) {
        m.region(Region::Setup);
        let zero = m.int(0);
        let counts = &mut self.bufs.counts;
        each(m, n, site::INIT_RAY, |m, ray| {
            m.s_store(counts, At::idx(ray, 4, 0), 4, zero);
        });
    }

    /// Before traversal, for `np` packets: the count rows zero.
    pub fn init_packets<M: Machine>(&mut self, m: &mut M, np: usize) {
        m.region(Region::Setup);
        let zero = m.splat(0.0);
        let step = self.bufs.packet_bytes() as i64;
        let e = &mut self.bufs.entries;
        let mut ptr = m.int(0);
        each(m, np, site::INIT_PACKET, |m, _| {
            m.store(e, at(ptr, 0), zero);
            ptr = m.s_addi(ptr, step);
        });
    }
}

impl<M: Machine> Filter<M> for Naive {
    fn one(&mut self, m: &mut M, c: Candidate1<M>) -> Option<M::X> {
        m.region(FILTER_REGION);
        self.candidates += 1;
        let counts = &mut self.bufs.counts;
        let held = m.s_load(counts, At::idx(c.ray, 4, 0), 4, false);
        let cap = m.int(i64::from(self.bufs.cap));
        if !m.branch_if(site::NAIVE_ROOM, Cmp::Lt, held, cap) {
            self.overflowed += 1;
            return None;
        }
        let stride = m.int(8 * i64::from(self.bufs.cap));
        let base = m.s_op(SOp::Mul, c.ray, stride);
        let slot = m.s_shift(isa::Shift::Shl, held, 3);
        let ptr = m.s_add(base, slot);
        let e = &mut self.bufs.entries;
        m.x_store(e, at(ptr, 0), c.t);
        m.s_store(e, at(ptr, 4), 4, c.prim);
        let held = m.s_addi(held, 1);
        m.s_store(counts, At::idx(c.ray, 4, 0), 4, held);
        None
    }

    fn packet(&mut self, m: &mut M, c: CandidateK<M>) -> (M::K, M::F) {
        m.region(FILTER_REGION);
        let w = M::LANES;
        self.candidates += u64::from(m.bits(c.valid).count_ones());
        let pbytes = m.int(self.bufs.packet_bytes() as i64);
        let e = &mut self.bufs.entries;
        let base = m.s_op(SOp::Mul, c.packet, pbytes);
        let held_f = m.load(e, at(base, 0));
        let held = m.bits_to_i(held_f);
        let cap = m.splat_i(self.bufs.cap as i32);
        let room = m.icmp(Cmp::Lt, held, cap);
        let room = m.kand(room, c.valid);
        self.overflowed += u64::from((m.bits(c.valid) & !m.bits(room)).count_ones());
        let ix = EntryIndex::new(m);
        let to = ix.t(m, held);
        m.scatter(room, e, at(base, 0), to, 4, c.t);
        m.scatter(room, e, at(base, 4 * w), to, 4, c.prim);
        let one = m.splat_i(1);
        let plus = m.iop(IOp::Add, held, one);
        let held = m.iselect(room, plus, held);
        let held_f = m.bits_to_f(held);
        m.store(e, at(base, 0), held_f);
        let none = m.mask(0);
        (none, c.t)
    }
}

/// Gather/scatter indices (4-byte units from a packet record's start) of
/// an entry's t in each lane: `W (1 + 2 e) + lane`; its triangle is `W`
/// further.
pub(crate) struct EntryIndex<M: Machine> {
    lane_w: M::I,
}

impl<M: Machine> EntryIndex<M> {
    /// The lane constant (a vector constant, as a compiler hoists it).
    pub(crate) fn new(m: &mut M) -> Self {
        let w = M::LANES as i32;
        let lanes: Vec<i32> = (0..w).map(|l| w + l).collect();
        EntryIndex {
            lane_w: m.consts_i(&lanes),
        }
    }
    /// Index of entry `e` (per lane)'s t: a shift (2W is a power of two)
    /// and an add.
    pub(crate) fn t(&self, m: &mut M, e: M::I) -> M::I {
        let rows = m.ishift(isa::Shift::Shl, e, (2 * M::LANES).trailing_zeros());
        m.iop(IOp::Add, rows, self.lane_w)
    }
}
