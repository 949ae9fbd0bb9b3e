//! Caches and DRAM: set-associative, LRU, write-back write-allocate, any
//! number of private and shared levels, an optional next-line prefetcher, and
//! a DRAM with latency and a bandwidth queue. Counts hits and misses per level
//! and per memory region, and DRAM bytes read and written. Data TLBs
//! ([`Tlbs`]) translate every access first: a miss in the first level adds
//! the level's latency, or the page walk's, before the cache lookup.

use crate::config::{CacheConfig, MachineConfig, Prefetch, TlbConfig};
use isa::{LineAddr, MemId, Op, Trace};

/// One set-associative cache with LRU replacement. Each set keeps its
/// lines in recency order (most recent first, empty ways last), so a
/// lookup reads only the set's tags, a hit moves its line to the front and
/// the victim is the last way: exactly LRU, with no per-way time stamps to
/// read and write (on the 2 M-line eDRAM that halves the host memory a
/// lookup touches).
#[derive(Clone, Debug)]
pub struct Cache {
    sets: u64,
    ways: usize,
    /// Per way: `(line + 1) << 1 | dirty`, or [`EMPTY`].
    ways_of: Vec<u64>,
}

/// An empty way (so a lazily allocated all-zero array is an empty cache).
const EMPTY: u64 = 0;

/// A line's key in a way (the dirty bit clear).
#[inline(always)]
fn key(line: LineAddr) -> u64 {
    (line.0 + 1) << 1
}

impl Cache {
    /// An empty cache of `cfg`'s geometry.
    #[must_use]
    pub fn new(cfg: &CacheConfig) -> Cache {
        let lines = u64::from(cfg.size_kib) * 1024 / u64::from(cfg.line);
        Cache::of(lines, cfg.ways)
    }

    /// An empty cache of `entries` in sets of `ways` (a TLB: its "lines"
    /// are pages).
    #[must_use]
    pub fn of(entries: u64, ways: u32) -> Cache {
        let ways = ways as usize;
        Cache {
            sets: entries / ways as u64,
            ways,
            ways_of: vec![EMPTY; entries as usize],
        }
    }

    /// Where `line`'s set lies in [`Cache::ways_of`].
    #[inline]
    fn set_range(&self, line: LineAddr) -> std::ops::Range<usize> {
        let set = if self.sets.is_power_of_two() {
            line.0 & (self.sets - 1)
        } else {
            line.0 % self.sets
        };
        let s = set as usize * self.ways;
        s..s + self.ways
    }

    /// The ways of `line`'s set, most recent first.
    #[inline]
    fn set(&mut self, line: LineAddr) -> &mut [u64] {
        let r = self.set_range(line);
        &mut self.ways_of[r]
    }

    /// Look up a line; on a hit, make it the most recent (and mark it
    /// dirty on a write).
    #[inline]
    pub fn lookup(&mut self, line: LineAddr, write: bool) -> bool {
        let k = key(line);
        let set = self.set(line);
        for w in 0..set.len() {
            let e = set[w];
            if e & !1 == k {
                set.copy_within(0..w, 1);
                set[0] = e | u64::from(write);
                return true;
            }
            if e == EMPTY {
                return false;
            }
        }
        false
    }

    /// Whether a line is present (no LRU update).
    #[must_use]
    pub fn contains(&self, line: LineAddr) -> bool {
        let k = key(line);
        for &e in &self.ways_of[self.set_range(line)] {
            if e & !1 == k {
                return true;
            }
            if e == EMPTY {
                return false;
            }
        }
        false
    }

    /// Insert a line (not present) as the most recent; returns the evicted
    /// line (the least recent, when the set is full) if it was dirty.
    #[inline]
    pub fn insert(&mut self, line: LineAddr, dirty: bool) -> Option<LineAddr> {
        let k = key(line) | u64::from(dirty);
        let set = self.set(line);
        let last = set.len() - 1;
        let victim = set.iter().position(|&e| e == EMPTY).unwrap_or(last);
        let evicted = set[victim];
        set.copy_within(0..victim, 1);
        set[0] = k;
        (evicted & 1 == 1).then(|| LineAddr((evicted >> 1) - 1))
    }
}

/// Translations counted per TLB level.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct TlbStats {
    /// Per level: translations found there.
    pub hits: Vec<u64>,
    /// Per level: translations looked up there and not found.
    pub misses: Vec<u64>,
    /// Page walks (every level missed).
    pub walks: u64,
}

/// The data TLBs of every core: per core, one LRU set-associative array of
/// pages per level. A translation found at level `l` costs that level's
/// latency and fills the levels before it; one every level misses costs the
/// walk and fills them all. Stores start at the first level that takes
/// them (Core 2's DTLB0 is for loads).
#[derive(Clone, Debug)]
pub struct Tlbs {
    cfg: TlbConfig,
    page_shift: u32,
    /// Per core and level (`core * levels + level`).
    arrays: Vec<Cache>,
    /// Counters, over every core.
    pub stats: TlbStats,
}

impl Tlbs {
    /// Empty TLBs of `cfg` for `cores` cores.
    #[must_use]
    pub fn new(cfg: &TlbConfig, cores: usize) -> Tlbs {
        let n = cfg.levels.len();
        let arrays = (0..cores * n)
            .map(|i| {
                let l = &cfg.levels[i % n];
                Cache::of(u64::from(l.entries), l.ways)
            })
            .collect();
        Tlbs {
            cfg: cfg.clone(),
            page_shift: (u64::from(cfg.page_kib) * 1024).trailing_zeros(),
            arrays,
            stats: TlbStats {
                hits: vec![0; n],
                misses: vec![0; n],
                walks: 0,
            },
        }
    }

    /// Translate `addr` for `core`: the extra load-to-use cycles (0 on a
    /// first-level hit), the arrays updated.
    pub fn translate(&mut self, core: usize, addr: u64, write: bool) -> u64 {
        let n = self.cfg.levels.len();
        let page = LineAddr(addr >> self.page_shift);
        let first = usize::from(write && self.cfg.levels[0].loads_only);
        let base = core * n;
        for l in first..n {
            if self.arrays[base + l].lookup(page, false) {
                self.stats.hits[l] += 1;
                for k in first..l {
                    self.arrays[base + k].insert(page, false);
                }
                return u64::from(self.cfg.levels[l].latency);
            }
            self.stats.misses[l] += 1;
        }
        self.stats.walks += 1;
        for k in first..n {
            self.arrays[base + k].insert(page, false);
        }
        u64::from(self.cfg.walk)
    }

    /// Zero the counters, keeping the arrays.
    pub fn reset_counters(&mut self) {
        let n = self.cfg.levels.len();
        self.stats = TlbStats {
            hits: vec![0; n],
            misses: vec![0; n],
            walks: 0,
        };
    }
}

/// The L1 miss slots (MSHRs) of a core: when each frees.
#[derive(Clone, Debug)]
pub struct Mshrs(Vec<u64>);

impl Mshrs {
    /// `n` free slots.
    #[must_use]
    pub fn new(n: usize) -> Mshrs {
        Mshrs(vec![0; n])
    }
    /// The earliest slot: its index and the cycle it frees.
    #[must_use]
    pub fn earliest(&self) -> (usize, u64) {
        self.0
            .iter()
            .enumerate()
            .min_by_key(|(_, &v)| v)
            .map(|(j, &v)| (j, v))
            .expect("at least one slot")
    }
    /// Hold slot `j` until cycle `until`.
    pub fn hold(&mut self, j: usize, until: u64) {
        self.0[j] = until;
    }
}

/// Counters of one level.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct LevelStats {
    /// Demand hits per memory region.
    pub hits: Vec<u64>,
    /// Demand misses per memory region.
    pub misses: Vec<u64>,
    /// Dirty lines written back to the next level.
    pub writebacks: u64,
    /// Prefetches issued into this level.
    pub prefetches: u64,
}

impl LevelStats {
    fn bump(v: &mut Vec<u64>, r: MemId) {
        let i = r.0 as usize;
        if v.len() <= i {
            v.resize(i + 1, 0);
        }
        v[i] += 1;
    }
    /// All hits.
    #[must_use]
    pub fn total_hits(&self) -> u64 {
        self.hits.iter().sum()
    }
    /// All misses.
    #[must_use]
    pub fn total_misses(&self) -> u64 {
        self.misses.iter().sum()
    }
}

/// Where an access was served.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Served {
    /// Level index that hit, or the number of levels for DRAM.
    pub level: usize,
    /// Load-to-use latency in cycles, queueing included.
    pub latency: u64,
}

/// The memory system of a machine: per-core private levels, shared levels, DRAM.
#[derive(Clone, Debug)]
pub struct Hierarchy {
    cfg: Vec<CacheConfig>,
    /// Every cache, private and shared, once.
    caches: Vec<Cache>,
    /// Per core and level (`core * levels + level`): its cache in `caches`.
    cache_of: Vec<usize>,
    line_shift: u32,
    dram_latency: u64,
    /// DRAM cycles per line transferred.
    dram_xfer: f64,
    dram_free: f64,
    prefetch: Prefetch,
    last_private: Option<usize>,
    /// Counters per level.
    pub stats: Vec<LevelStats>,
    /// Bytes read from DRAM (demand and prefetch).
    pub dram_read: u64,
    /// Bytes written to DRAM (dirty evictions).
    pub dram_written: u64,
    /// DRAM bytes read per memory region (demand misses and their prefetches).
    pub dram_read_by_region: Vec<u64>,
    /// Of those, the prefetcher's (by the region of the access that
    /// triggered the prefetch).
    pub dram_prefetched_by_region: Vec<u64>,
    /// Per core: (last missed line, stream head: last line prefetched) of the stream prefetcher.
    streams: Vec<(u64, u64)>,
    /// Functional warming: accesses change cache contents only, not the
    /// DRAM queue's timeline (untimed accesses would pile up in it).
    pub functional: bool,
    /// The data TLBs, where the machine has them.
    pub tlbs: Option<Tlbs>,
}

impl Hierarchy {
    /// The hierarchy of `m` for `cores` simulated cores.
    #[must_use]
    pub fn new(m: &MachineConfig, cores: usize) -> Hierarchy {
        let mut caches = Vec::new();
        let mut cache_of = vec![0; cores * m.caches.len()];
        for c in 0..cores {
            for (l, cfg) in m.caches.iter().enumerate() {
                cache_of[c * m.caches.len() + l] = if cfg.shared && c > 0 {
                    cache_of[l]
                } else {
                    caches.push(Cache::new(cfg));
                    caches.len() - 1
                };
            }
        }
        let line = m.caches[0].line;
        let bytes_per_cycle = m.dram.bandwidth_gbs / m.clock_ghz;
        Hierarchy {
            cfg: m.caches.clone(),
            caches,
            cache_of,
            line_shift: line.trailing_zeros(),
            dram_latency: u64::from(m.dram.latency),
            dram_xfer: f64::from(line) / bytes_per_cycle,
            dram_free: 0.0,
            prefetch: m.prefetch,
            last_private: m.caches.iter().rposition(|l| !l.shared),
            stats: vec![LevelStats::default(); m.caches.len()],
            dram_read: 0,
            dram_written: 0,
            dram_read_by_region: Vec::new(),
            dram_prefetched_by_region: Vec::new(),
            streams: vec![(u64::MAX - 1, 0); cores],
            functional: false,
            tlbs: m.tlb.as_ref().map(|t| Tlbs::new(t, cores)),
        }
    }

    /// The distinct lines (line numbers, ascending) a per-lane access touches.
    #[must_use]
    pub fn lines_of(&self, t: &Trace, op: &Op) -> Vec<u64> {
        let mut lines: Vec<u64> = t.lanes_of(op).iter().map(|a| self.line_of(a.0).0).collect();
        lines.sort_unstable();
        lines.dedup();
        lines
    }

    /// Functional warming of `op`'s accesses by `core` (each distinct line of
    /// a per-lane access once, as the timed cores do), at cycle `now`.
    pub fn warm_op(&mut self, core: usize, t: &Trace, op: &Op, now: u64) {
        let store = op.class.is_store();
        if op.class.is_per_lane_mem() {
            for l in self.lines_of(t, op) {
                self.access(core, l * self.line_bytes(), store, op.mem, now);
            }
        } else if op.class.is_mem() {
            for a in self.span(op.addr.0, op.bytes) {
                self.access(core, a, store, op.mem, now);
            }
        }
    }

    /// Zero the counters (hits, misses, DRAM bytes), keeping every cache's
    /// contents and the prefetchers' state: the start of a measured unit.
    pub fn reset_counters(&mut self) {
        for l in &mut self.stats {
            *l = LevelStats::default();
        }
        self.dram_read = 0;
        self.dram_written = 0;
        self.dram_read_by_region.clear();
        self.dram_prefetched_by_region.clear();
        if let Some(t) = &mut self.tlbs {
            t.reset_counters();
        }
    }

    /// Extra cycles to translate `addr` for `core` (0 without TLBs).
    #[inline]
    fn translate(&mut self, core: usize, addr: u64, write: bool) -> u64 {
        match &mut self.tlbs {
            Some(t) => t.translate(core, addr, write),
            None => 0,
        }
    }

    /// The TLB counters (none without TLBs).
    #[must_use]
    pub fn tlb_stats(&self) -> Option<TlbStats> {
        self.tlbs.as_ref().map(|t| t.stats.clone())
    }

    /// Cache levels (a served level equal to this is DRAM).
    #[must_use]
    pub fn levels(&self) -> usize {
        self.cfg.len()
    }

    /// Line size in bytes.
    #[must_use]
    pub fn line_bytes(&self) -> u64 {
        1 << self.line_shift
    }

    /// The line of a byte address.
    #[must_use]
    pub fn line_of(&self, addr: u64) -> LineAddr {
        LineAddr(addr >> self.line_shift)
    }

    #[inline]
    fn cache(&mut self, core: usize, level: usize) -> &mut Cache {
        let i = self.cache_of[core * self.cfg.len() + level];
        &mut self.caches[i]
    }

    fn dram(&mut self, now: u64, region: MemId) -> u64 {
        let bytes = self.line_bytes();
        self.dram_read += bytes;
        let i = region.0 as usize;
        if self.dram_read_by_region.len() <= i {
            self.dram_read_by_region.resize(i + 1, 0);
        }
        self.dram_read_by_region[i] += bytes;
        if self.functional {
            return self.dram_latency;
        }
        let start = self.dram_free.max(now as f64);
        self.dram_free = start + self.dram_xfer;
        (start - now as f64) as u64 + self.dram_latency
    }

    /// Put a line into `level` (and write back its dirty victim below).
    fn fill(&mut self, core: usize, level: usize, line: LineAddr, dirty: bool) {
        if let Some(victim) = self.cache(core, level).insert(line, dirty) {
            self.stats[level].writebacks += 1;
            self.write_back(core, level + 1, victim);
        }
    }

    fn write_back(&mut self, core: usize, level: usize, line: LineAddr) {
        if level >= self.cfg.len() {
            self.dram_written += self.line_bytes();
            return;
        }
        if !self.cache(core, level).lookup(line, true) {
            self.fill(core, level, line, true);
        }
    }

    /// A load by `core` issuing at cycle `at`: an L1 miss first waits for
    /// the earliest of `mshrs` (the access starts then and holds the slot
    /// until its data arrives). The cycle the data is ready, and the level
    /// that served it (0: the L1; [`Hierarchy::levels`]: DRAM).
    #[inline]
    pub fn load(
        &mut self,
        core: usize,
        addr: u64,
        region: MemId,
        at: u64,
        mshrs: &mut Mshrs,
    ) -> (u64, usize) {
        let at = at + self.translate(core, addr, false);
        let line = self.line_of(addr);
        if self.l1(core, line, false, region, at) {
            return (at + u64::from(self.cfg[0].latency), 0);
        }
        let (j, free) = mshrs.earliest();
        let start = at.max(free);
        let sv = self.below_l1(core, line, false, region, start);
        mshrs.hold(j, start + sv.latency);
        (start + sv.latency, sv.level)
    }

    /// Where each line of an access of `bytes` at `addr` starts. An access
    /// wider than a line (a 32-lane vector: 128 bytes) touches every line it
    /// spans; a narrower one is its first line (a load or store that crosses
    /// a line boundary is not modelled as split).
    pub fn span(&self, addr: u64, bytes: u32) -> std::iter::StepBy<std::ops::Range<u64>> {
        let lb = self.line_bytes();
        if u64::from(bytes) > lb {
            (addr & !(lb - 1)..addr + u64::from(bytes)).step_by(lb as usize)
        } else {
            (addr..addr + 1).step_by(lb as usize)
        }
    }

    /// [`Hierarchy::load`] of every line of [`Hierarchy::span`]: the latest
    /// ready, and the level that served it.
    #[inline]
    pub fn load_span(
        &mut self,
        core: usize,
        (addr, bytes): (u64, u32),
        region: MemId,
        at: u64,
        mshrs: &mut Mshrs,
    ) -> (u64, usize) {
        let mut r = self.load(core, addr, region, at, mshrs);
        if u64::from(bytes) > self.line_bytes() {
            for a in self.span(addr, bytes).skip(1) {
                let x = self.load(core, a, region, at, mshrs);
                if x.0 > r.0 {
                    r = x;
                }
            }
        }
        r
    }

    /// A store of `bytes` at `addr` by `core` at cycle `now`: an access to
    /// every line of [`Hierarchy::span`].
    #[inline]
    pub fn store_span(&mut self, core: usize, (addr, bytes): (u64, u32), region: MemId, now: u64) {
        self.access(core, addr, true, region, now);
        if u64::from(bytes) > self.line_bytes() {
            for a in self.span(addr, bytes).skip(1) {
                self.access(core, a, true, region, now);
            }
        }
    }

    /// A demand access by `core` at cycle `now` to the line of `addr`.
    pub fn access(
        &mut self,
        core: usize,
        addr: u64,
        write: bool,
        region: MemId,
        now: u64,
    ) -> Served {
        let tr = self.translate(core, addr, write);
        let line = self.line_of(addr);
        if self.l1(core, line, write, region, now + tr) {
            return Served {
                level: 0,
                latency: tr + u64::from(self.cfg[0].latency),
            };
        }
        let mut sv = self.below_l1(core, line, write, region, now + tr);
        sv.latency += tr;
        sv
    }

    /// An access's L1 step: the lookup, its counter, and on a hit the
    /// prefetcher's part; whether it hit.
    #[inline]
    fn l1(&mut self, core: usize, line: LineAddr, write: bool, region: MemId, now: u64) -> bool {
        let hit = self.cache(core, 0).lookup(line, write);
        let l0 = &mut self.stats[0];
        LevelStats::bump(if hit { &mut l0.hits } else { &mut l0.misses }, region);
        if hit {
            self.after(core, line, 0, region, now);
        }
        hit
    }

    /// The rest of an access that missed the L1: the levels below, DRAM,
    /// the fills on the way back and the prefetcher.
    fn below_l1(
        &mut self,
        core: usize,
        line: LineAddr,
        write: bool,
        region: MemId,
        now: u64,
    ) -> Served {
        let n = self.cfg.len();
        let mut hit_level = n;
        for l in 1..n {
            if self.cache(core, l).lookup(line, false) {
                LevelStats::bump(&mut self.stats[l].hits, region);
                hit_level = l;
                break;
            }
            LevelStats::bump(&mut self.stats[l].misses, region);
        }
        let latency = if hit_level == n {
            self.dram(now, region)
        } else {
            u64::from(self.cfg[hit_level].latency)
        };
        for l in (0..hit_level).rev() {
            self.fill(core, l, line, write && l == 0);
        }
        self.after(core, line, hit_level, region, now);
        Served {
            level: hit_level,
            latency,
        }
    }

    /// The prefetcher's part of a demand access to `line` served at
    /// `hit_level`.
    #[inline]
    fn after(&mut self, core: usize, line: LineAddr, hit_level: usize, region: MemId, now: u64) {
        if let Some(lp) = self.last_private {
            match self.prefetch {
                Prefetch::None => {}
                Prefetch::NextLine => {
                    if hit_level > lp {
                        self.prefetch_line(core, lp, LineAddr(line.0 + 1), region, now);
                    }
                }
                Prefetch::Stream(degree) => {
                    let (last_miss, head) = self.streams[core];
                    let d = u64::from(degree);
                    let in_stream = line.0 <= head && line.0 + d > head;
                    let starts = hit_level > lp && line.0 == last_miss.wrapping_add(1);
                    if hit_level > lp {
                        self.streams[core].0 = line.0;
                    }
                    if in_stream || starts {
                        let from = if in_stream { head + 1 } else { line.0 + 1 };
                        for l in from..=line.0 + d {
                            self.prefetch_line(core, lp, LineAddr(l), region, now);
                        }
                        self.streams[core].1 = line.0 + d;
                    }
                }
            }
        }
    }

    fn prefetch_line(
        &mut self,
        core: usize,
        level: usize,
        line: LineAddr,
        region: MemId,
        now: u64,
    ) {
        if self.cache(core, level).contains(line) {
            return;
        }
        self.stats[level].prefetches += 1;
        let n = self.cfg.len();
        let found = (level + 1..n).any(|l| self.cache(core, l).contains(line));
        if !found {
            self.dram(now, region);
            let i = region.0 as usize;
            if self.dram_prefetched_by_region.len() <= i {
                self.dram_prefetched_by_region.resize(i + 1, 0);
            }
            self.dram_prefetched_by_region[i] += self.line_bytes();
            for l in level + 1..n {
                self.fill(core, l, line, false);
            }
        }
        self.fill(core, level, line, false);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg(size_kib: u32, ways: u32) -> CacheConfig {
        CacheConfig {
            name: "t".into(),
            size_kib,
            ways,
            line: 64,
            latency: 4,
            shared: false,
        }
    }

    /// LRU written plainly: per set a list of (line, dirty, last use).
    #[test]
    fn recency_ordered_sets_behave_as_plain_lru_on_seeded_accesses() {
        let mut c = Cache::new(&cfg(4, 4)); // 16 sets of 4 ways
        let mut plain: Vec<Vec<(u64, bool, u64)>> = vec![Vec::new(); 16];
        let mut x = 0x2545_F491_4F6C_DD1Du64;
        for clock in 0..50_000u64 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let line = x % 200; // 200 lines over 64 ways: hits and evictions
            let write = x >> 40 & 3 == 0;
            let set = &mut plain[(line % 16) as usize];
            let hit = c.lookup(LineAddr(line), write);
            if let Some(e) = set.iter_mut().find(|e| e.0 == line) {
                assert!(hit, "access {clock}: line {line} should hit");
                e.1 |= write;
                e.2 = clock;
                continue;
            }
            assert!(!hit, "access {clock}: line {line} should miss");
            assert!(!c.contains(LineAddr(line)));
            let evicted = c.insert(LineAddr(line), write);
            let want = if set.len() == 4 {
                let (i, _) = set.iter().enumerate().min_by_key(|(_, e)| e.2).unwrap();
                let v = set.remove(i);
                v.1.then_some(LineAddr(v.0))
            } else {
                None
            };
            assert_eq!(evicted, want, "access {clock}: victim");
            set.push((line, write, clock));
        }
    }

    #[test]
    fn lru_evicts_the_oldest_and_reports_dirty_victims() {
        // 1 KiB, 2 ways, 64 B lines: 8 sets; lines 0, 8, 16 map to set 0.
        let mut c = Cache::new(&cfg(1, 2));
        assert!(!c.lookup(LineAddr(0), false));
        assert_eq!(c.insert(LineAddr(0), true), None);
        assert_eq!(c.insert(LineAddr(8), false), None);
        assert!(c.lookup(LineAddr(0), false)); // 8 is now the LRU
        assert_eq!(
            c.insert(LineAddr(16), false),
            None,
            "clean 8 evicted silently"
        );
        assert!(!c.contains(LineAddr(8)));
        assert!(c.lookup(LineAddr(16), false));
        assert_eq!(
            c.insert(LineAddr(24), false),
            Some(LineAddr(0)),
            "dirty 0 written back"
        );
    }
}
