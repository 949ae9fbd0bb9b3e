//! The op stream: what the traced backend records and the timing model reads.

use crate::class::OpClass;
use crate::flavour::FlavourId;
use crate::mem::MemRegion;
use crate::types::{Addr, LaneMask, MemId, Region, Site, ValId};

/// Maximum source operands of one op (a masked FMA: a, b, c, k).
pub const MAX_SRCS: usize = 4;

/// One recorded machine instruction.
///
/// Layout (48 bytes): class, region, flags, nsrc (4 x u8); mask (u32);
/// dst (u32); srcs (4 x u32); addr (u64); bytes (u32); mem (u16); pad (u16);
/// aux (u32: branch site, a load's static site (0: none), or the first index
/// into [`Trace::lane_addrs`] of a gather or scatter).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Op {
    /// Instruction kind.
    pub class: OpClass,
    /// Code region it belongs to.
    pub region: Region,
    /// `FLAG_*` bits.
    pub flags: u8,
    /// Number of sources in `srcs`.
    pub nsrc: u8,
    /// Active lanes (1 for scalar ops).
    pub mask: LaneMask,
    /// The value it produces, or `ValId::NONE`.
    pub dst: ValId,
    /// Values it reads (constants are not listed).
    pub srcs: [ValId; MAX_SRCS],
    /// First byte accessed (memory ops; for gather/scatter the first active lane's).
    pub addr: Addr,
    /// Bytes accessed (per lane for gather/scatter); for other ops the
    /// operand width in bytes (an xmm op on AVX2: 16), 0 for the flavour's
    /// full width (what every recorded op has).
    pub bytes: u32,
    /// Memory region accessed.
    pub mem: MemId,
    /// Instruction length in bytes (1 to 15) for the legacy decoders of a
    /// machine's front end; 0 (what recorded kernels have): unknown, the
    /// op's uops come from the uop cache.
    pub ilen: u8,
    /// Branch site, a load's static site (0: none; a memory-dependence
    /// predictor learns per site), or first lane address index for
    /// gather/scatter.
    pub aux: u32,
}

const _: () = assert!(std::mem::size_of::<Op>() == 48);

/// `Op::flags`: a branch that was taken.
pub const FLAG_TAKEN: u8 = 1;
/// `Op::flags`: a store's first source is its address (the rest its data);
/// without it a store's address is known when it dispatches.
pub const FLAG_ADDR: u8 = 2;
/// `Op::flags`: the instruction has a length-changing prefix (a 16-bit
/// immediate after `66h`): the legacy predecoder takes its slow path.
pub const FLAG_LCP: u8 = 4;
/// `Op::flags`: the instruction needs the legacy decoders' complex decoder
/// and ends its decode group (`pop r12`, `pop rsp` on Haswell).
pub const FLAG_COMPLEX: u8 = 8;
/// `Op::flags`: the instruction can macro-fuse with a following branch
/// (cmp, test, add, sub, and, inc, dec), whether or not it does: a legacy
/// decode fact (a `cmp` op always can).
pub const FLAG_FUSIBLE: u8 = 16;
/// Longest x86 instruction, in bytes.
pub const MAX_ILEN: u8 = 15;

impl Op {
    /// A blank op of `class` in `region`.
    #[must_use]
    pub fn new(class: OpClass, region: Region) -> Op {
        Op {
            class,
            region,
            flags: 0,
            nsrc: 0,
            mask: LaneMask(1),
            dst: ValId::NONE,
            srcs: [ValId::NONE; MAX_SRCS],
            addr: Addr(0),
            bytes: 0,
            mem: MemId(0),
            ilen: 0,
            aux: 0,
        }
    }
    /// The sources.
    #[must_use]
    #[inline]
    pub fn sources(&self) -> &[ValId] {
        &self.srcs[..self.nsrc as usize]
    }
    /// Add a source (ignored if it is a constant).
    pub fn push_src(&mut self, v: ValId) {
        if v.is_some() {
            assert!((self.nsrc as usize) < MAX_SRCS, "too many sources");
            self.srcs[self.nsrc as usize] = v;
            self.nsrc += 1;
        }
    }
    /// Branch site (branches only).
    #[must_use]
    #[inline]
    pub fn site(&self) -> Site {
        Site(self.aux)
    }
    /// Whether a branch was taken.
    #[must_use]
    #[inline]
    pub fn taken(&self) -> bool {
        self.flags & FLAG_TAKEN != 0
    }
    /// Whether the instruction has a length-changing prefix ([`FLAG_LCP`]).
    #[must_use]
    #[inline]
    pub fn lcp(&self) -> bool {
        self.flags & FLAG_LCP != 0
    }
    /// Whether the instruction needs the complex decoder ([`FLAG_COMPLEX`]).
    #[must_use]
    #[inline]
    pub fn complex(&self) -> bool {
        self.flags & FLAG_COMPLEX != 0
    }
    /// Whether the instruction can macro-fuse ([`FLAG_FUSIBLE`], or a
    /// compare).
    #[must_use]
    #[inline]
    pub fn fusible(&self) -> bool {
        self.flags & FLAG_FUSIBLE != 0 || self.class == OpClass::Cmp
    }
    /// Whether a store's first source is its address ([`FLAG_ADDR`]).
    #[must_use]
    #[inline]
    pub fn has_addr_src(&self) -> bool {
        self.flags & FLAG_ADDR != 0
    }
    /// Whether the op is a load that may carry a static site (not a gather).
    #[must_use]
    pub fn is_sited_load(&self) -> bool {
        self.class.is_load() && !self.class.is_per_lane_mem()
    }
}

/// One event of [`Trace::warming_view`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum WarmEvent {
    /// A memory op: whether it stores, its region, its addresses.
    Mem(bool, MemId, Vec<Addr>),
    /// A branch: its site and whether it was taken.
    Branch(u32, bool),
}

/// A recorded run: header facts and the ops.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Trace {
    /// ISA flavour.
    pub flavour: FlavourId,
    /// What produced it (e.g. `micro:fma-chain`).
    pub source: String,
    /// Parameters of the producer, as key/value text.
    pub params: Vec<(String, String)>,
    /// Memory regions (their ids are `MemId`s in ops).
    pub regions: Vec<MemRegion>,
    /// The ops, in program order.
    pub ops: Vec<Op>,
    /// Per-lane addresses of gathers and scatters (active lanes, in lane order).
    pub lane_addrs: Vec<Addr>,
}

impl Trace {
    /// An empty trace.
    #[must_use]
    pub fn new(flavour: FlavourId, source: &str) -> Trace {
        Trace {
            flavour,
            source: source.to_string(),
            params: Vec::new(),
            regions: Vec::new(),
            ops: Vec::new(),
            lane_addrs: Vec::new(),
        }
    }
    /// Append `next`'s ops (the same unit's next ops, recorded as their own
    /// chunk): gathers' and scatters' lane-address indices move past this
    /// trace's own.
    pub fn append(&mut self, next: &Trace) {
        let base = self.lane_addrs.len() as u32;
        self.ops.extend(next.ops.iter().map(|o| {
            let mut o = *o;
            if o.class.is_per_lane_mem() {
                o.aux += base;
            }
            o
        }));
        self.lane_addrs.extend_from_slice(&next.lane_addrs);
    }
    /// The per-lane addresses of gather/scatter `op`.
    #[must_use]
    pub fn lanes_of(&self, op: &Op) -> &[Addr] {
        if op.class.is_per_lane_mem() {
            let s = op.aux as usize;
            &self.lane_addrs[s..s + op.mask.count() as usize]
        } else {
            &[]
        }
    }
    /// Every address an op touches with its byte count: one for ordinary
    /// memory ops, one per active lane for gather and scatter.
    pub fn accesses<'a>(&'a self, op: &'a Op) -> impl Iterator<Item = (Addr, u32)> + 'a {
        let single =
            (op.class.is_mem() && !op.class.is_per_lane_mem()).then_some((op.addr, op.bytes));
        single
            .into_iter()
            .chain(self.lanes_of(op).iter().map(move |&a| (a, op.bytes)))
    }
    /// What functional warming reads of the trace, in order: each memory op
    /// as (store?, region, addresses: one, or one per active lane of a gather
    /// or scatter) and each branch as (site, taken). Two runs warm caches and
    /// predictors alike exactly when their views are equal.
    #[must_use]
    pub fn warming_view(&self) -> Vec<WarmEvent> {
        self.ops
            .iter()
            .filter_map(|op| {
                if op.class == OpClass::Branch {
                    Some(WarmEvent::Branch(op.site().0, op.taken()))
                } else if op.class.is_mem() {
                    let addrs = if op.class.is_per_lane_mem() {
                        self.lanes_of(op).to_vec()
                    } else {
                        vec![op.addr]
                    };
                    Some(WarmEvent::Mem(op.class.is_store(), op.mem, addrs))
                } else {
                    None
                }
            })
            .collect()
    }
    /// As [`Trace::validate`], but a source may be defined anywhere in the
    /// trace (a loop body whose later values are carried to the next iteration).
    pub fn validate_loop(&self) -> Result<(), String> {
        self.check(true)
    }

    /// Check internal consistency: sources defined before use, lane address
    /// ranges in bounds, memory ops inside their region, ids in range.
    pub fn validate(&self) -> Result<(), String> {
        self.check(false)
    }

    fn check(&self, as_loop: bool) -> Result<(), String> {
        let lanes = self.flavour.lanes();
        let full = LaneMask::full(lanes).0;
        let top = self.ops.iter().map(|o| o.dst.0).max().unwrap_or(0);
        let mut defined = IdSet::up_to(top, self.ops.len());
        let mut all = IdSet::up_to(if as_loop { top } else { 0 }, self.ops.len());
        if as_loop {
            for o in self.ops.iter().filter(|o| o.dst.is_some()) {
                all.insert(o.dst);
            }
        }
        let mut lane_next = 0usize;
        for (i, op) in self.ops.iter().enumerate() {
            let at = |m: String| format!("op {i} ({}): {m}", op.class);
            for s in op.sources() {
                if !defined.contains(s) && !all.contains(s) {
                    return Err(at(format!("source %{} is not defined before use", s.0)));
                }
            }
            if op.class.is_store() && op.has_addr_src() && op.nsrc == 0 {
                return Err(at("an address source named, but no source".into()));
            }
            if op.mask.0 & !full != 0 {
                return Err(at(format!(
                    "mask {:#x} has lanes beyond {lanes}",
                    op.mask.0
                )));
            }
            if !op.class.is_mem() && op.bytes != 0 {
                let w = op.bytes;
                if !w.is_power_of_two() || w > 4 * lanes as u32 {
                    return Err(at(format!(
                        "operand width {w} bytes: not a power of two up to {}",
                        4 * lanes
                    )));
                }
            }
            if op.class.is_mem() {
                let r = self
                    .regions
                    .get(op.mem.0 as usize)
                    .ok_or_else(|| at(format!("memory region {} does not exist", op.mem.0)))?;
                if op.class.is_per_lane_mem() {
                    if op.aux as usize != lane_next {
                        return Err(at("lane addresses out of order".into()));
                    }
                    lane_next += op.mask.count() as usize;
                    if lane_next > self.lane_addrs.len() {
                        return Err(at("lane addresses missing".into()));
                    }
                }
                for (a, n) in self.accesses(op) {
                    if a.0 < r.base.0 || a.0 + u64::from(n) > r.base.0 + r.size {
                        return Err(at(format!("access {a}+{n} outside region {}", r.name)));
                    }
                }
            }
            if op.dst.is_some() && !defined.insert(op.dst) {
                return Err(at(format!("value %{} defined twice", op.dst.0)));
            }
        }
        if lane_next != self.lane_addrs.len() {
            return Err("unreferenced lane addresses at the end".into());
        }
        Ok(())
    }
}

std::thread_local! {
    /// Op and lane-address buffers of traces given back ([`recycle`]).
    static POOL: std::cell::RefCell<Vec<(Vec<Op>, Vec<Addr>)>> =
        const { std::cell::RefCell::new(Vec::new()) };
}

/// Buffers kept for reuse per host thread (a DRS step holds 12 units: 4
/// cores' primary, bounce and shadow streams).
const POOL_SIZE: usize = 16;

/// Give `t`'s buffers back for the next unit [`crate::Traced::take`] records
/// on this host thread. A frame's units are recorded and dropped by the
/// thousand; without reuse each large buffer goes back to the OS on drop and
/// the kernel zeroes its pages again for the next (a third of a DRS report's
/// host time went to page clearing).
pub fn recycle(t: Trace) {
    let (mut ops, mut lanes) = (t.ops, t.lane_addrs);
    ops.clear();
    lanes.clear();
    POOL.with(|p| {
        let mut p = p.borrow_mut();
        if p.len() < POOL_SIZE {
            p.push((ops, lanes));
        }
    });
}

/// Empty buffers for a trace: the largest recycled ones if this host thread
/// has any (a small shadow stream's buffer would be grown again, and grown
/// pages are fresh pages the OS zeroes).
pub(crate) fn pooled_buffers() -> (Vec<Op>, Vec<Addr>) {
    POOL.with(|p| {
        let mut p = p.borrow_mut();
        let largest = (0..p.len()).max_by_key(|&i| p[i].0.capacity())?;
        Some(p.swap_remove(largest))
    })
    .unwrap_or_default()
}

/// A set of value ids for [`Trace::validate`]: a bit per id when the ids are
/// dense (a recorded trace's are consecutive), a hash set when a
/// hand-written trace names ids far beyond its length. The bit set keeps
/// the check from hashing every id of a long trace.
enum IdSet {
    Dense(Vec<u64>),
    Sparse(std::collections::HashSet<ValId>),
}

impl IdSet {
    /// An empty set for ids up to `top` in a trace of `ops` ops.
    fn up_to(top: u32, ops: usize) -> IdSet {
        let words = top as usize / 64 + 1;
        if words <= ops / 8 + 1024 {
            IdSet::Dense(vec![0; words])
        } else {
            IdSet::Sparse(std::collections::HashSet::new())
        }
    }

    /// Whether `v` is in the set.
    fn contains(&self, v: &ValId) -> bool {
        match self {
            IdSet::Dense(w) => w
                .get(v.0 as usize / 64)
                .is_some_and(|x| x >> (v.0 % 64) & 1 != 0),
            IdSet::Sparse(h) => h.contains(v),
        }
    }

    /// Add `v`; whether it was new.
    fn insert(&mut self, v: ValId) -> bool {
        match self {
            IdSet::Dense(w) => {
                let (k, bit) = (v.0 as usize / 64, 1u64 << (v.0 % 64));
                let new = w[k] & bit == 0;
                w[k] |= bit;
                new
            }
            IdSet::Sparse(h) => h.insert(v),
        }
    }
}
