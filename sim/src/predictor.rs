//! Conditional branch predictors: gshare (McFarling 1993: 2-bit counters
//! indexed by the branch site hashed with the global history) and TAGE
//! (Seznec and Michaud 2006: tagged tables indexed by geometric lengths of
//! global history, gshare as the base). They stand in for the undocumented
//! predictors of the modelled machines; their sizes are config fields.

use crate::config::{Tage as TageConfig, MAX_TAGE_TABLES as MAX_TABLES};

/// Gshare.
#[derive(Clone, Debug)]
pub struct Gshare {
    counters: Vec<u8>,
    history: u64,
    hist_mask: u64,
    mask: u64,
}

impl Gshare {
    /// `history_bits` of global history, `2^table_bits` counters.
    #[must_use]
    pub fn new(history_bits: u32, table_bits: u32) -> Gshare {
        Gshare {
            counters: vec![1; 1 << table_bits],
            history: 0,
            hist_mask: (1u64 << history_bits) - 1,
            mask: (1u64 << table_bits) - 1,
        }
    }

    /// The counter `site` reads under the current history.
    #[inline]
    fn slot(&self, site: u32) -> usize {
        let h = u64::from(site).wrapping_mul(0x9e37_79b9_7f4a_7c15) >> 40;
        ((h ^ (self.history & self.hist_mask)) & self.mask) as usize
    }

    /// Predict the branch at `site`, learn its outcome; true if predicted right.
    #[inline]
    pub fn predict_and_update(&mut self, site: u32, taken: bool) -> bool {
        self.step(site, taken, true) == taken
    }

    /// The prediction for `site`; its counter learns `taken` if `train`, and
    /// the history always shifts.
    #[inline]
    fn step(&mut self, site: u32, taken: bool, train: bool) -> bool {
        let i = self.slot(site);
        let c = &mut self.counters[i];
        let predicted = *c >= 2;
        if train {
            *c = if taken {
                (*c + 1).min(3)
            } else {
                c.saturating_sub(1)
            };
        }
        self.history = (self.history << 1) | u64::from(taken);
        predicted
    }
}

/// A history of up to `len` bits folded into `width` bits by XOR, kept up to
/// date one outcome at a time (Seznec's circular shift register).
#[derive(Clone, Debug)]
struct Folded {
    value: u32,
    len: u32,
    width: u32,
}

impl Folded {
    fn new(len: u32, width: u32) -> Folded {
        Folded {
            value: 0,
            len,
            width,
        }
    }
    /// Shift in `new`; `old` is the bit `len` outcomes back, now leaving.
    #[inline]
    fn push(&mut self, new: bool, old: bool) {
        let w = self.width;
        let mut v = (self.value << 1) | u32::from(new);
        v ^= u32::from(old) << (self.len % w);
        v ^= v >> w;
        self.value = v & ((1 << w) - 1);
    }
}

/// One tagged entry: a 3-bit signed counter, a partial tag, a 2-bit
/// usefulness.
#[derive(Clone, Copy, Debug, Default)]
struct Entry {
    ctr: i8,
    tag: u16,
    useful: u8,
}

/// One tagged table and the folded histories that index and tag it.
#[derive(Clone, Debug)]
struct Table {
    entries: Vec<Entry>,
    index: Folded,
    tag_a: Folded,
    tag_b: Folded,
}

/// TAGE: a base predictor (here the config's gshare) and tagged tables over
/// geometrically longer global histories; the longest matching table
/// predicts, a misprediction allocates an entry in a longer one.
#[derive(Clone, Debug)]
pub struct Tage {
    base: Gshare,
    tables: Vec<Table>,
    /// The last `ring.len()` outcomes, newest at `head`.
    ring: Vec<bool>,
    head: usize,
    table_bits: u32,
    tag_bits: u32,
    /// Branches since the usefulness bits were last aged.
    since_reset: u32,
    /// Allocation choice (a deterministic xorshift).
    rng: u64,
}

/// Branches between two halvings of every entry's usefulness (Seznec and
/// Michaud 2006 reset them periodically; 256 K branches as in their paper).
const USEFUL_PERIOD: u32 = 1 << 18;

impl Tage {
    /// TAGE over `base` with `c.tables` tagged tables of `2^c.table_bits`
    /// entries, history lengths from `c.min_history` to `c.max_history` in a
    /// geometric series.
    #[must_use]
    pub fn new(base: Gshare, c: &TageConfig) -> Tage {
        let n = c.tables.clamp(1, MAX_TABLES as u32);
        let lens: Vec<u32> = (0..n)
            .map(|i| {
                let r = f64::from(c.max_history) / f64::from(c.min_history);
                let e = if n == 1 {
                    1.0
                } else {
                    f64::from(i) / f64::from(n - 1)
                };
                (f64::from(c.min_history) * r.powf(e)).round() as u32
            })
            .collect();
        let tables = lens
            .iter()
            .map(|&l| Table {
                entries: vec![Entry::default(); 1 << c.table_bits],
                index: Folded::new(l, c.table_bits),
                tag_a: Folded::new(l, c.tag_bits),
                tag_b: Folded::new(l, c.tag_bits - 1),
            })
            .collect();
        Tage {
            base,
            tables,
            ring: vec![false; c.max_history as usize + 1],
            head: 0,
            table_bits: c.table_bits,
            tag_bits: c.tag_bits,
            since_reset: 0,
            rng: 0x2545_f491_4f6c_dd1d,
        }
    }

    /// Table `t`'s slot and tag for `site` under the current history.
    #[inline]
    fn slot(&self, t: usize, site: u32) -> (usize, u16) {
        let tb = &self.tables[t];
        let pc = site.wrapping_mul(0x9e37_79b9).rotate_right(7 + t as u32);
        let mask = (1u32 << self.table_bits) - 1;
        let i = (pc ^ (pc >> self.table_bits) ^ tb.index.value) & mask;
        let tag = (pc ^ tb.tag_a.value ^ (tb.tag_b.value << 1)) & ((1 << self.tag_bits) - 1);
        (i as usize, tag as u16)
    }

    /// Predict the branch at `site`, learn its outcome; true if predicted right.
    pub fn predict_and_update(&mut self, site: u32, taken: bool) -> bool {
        let n = self.tables.len();
        let mut slots = [(0usize, 0u16); MAX_TABLES];
        for (t, s) in slots.iter_mut().enumerate().take(n) {
            *s = self.slot(t, site);
        }
        let matches = |t: &usize| self.tables[*t].entries[slots[*t].0].tag == slots[*t].1;
        let mut hits = (0..n).rev().filter(matches);
        let (provider, alt) = (hits.next(), hits.next());
        let predict = |tage: &Tage, t: usize| tage.tables[t].entries[slots[t].0].ctr >= 0;
        // The base trains only when it provides; its history always shifts.
        let base = self.base.step(site, taken, provider.is_none());
        let pred = provider.map_or(base, |p| predict(self, p));
        if let Some(p) = provider {
            let alt_pred = alt.map_or(base, |a| predict(self, a));
            let e = &mut self.tables[p].entries[slots[p].0];
            if alt_pred != pred {
                e.useful = if pred == taken {
                    (e.useful + 1).min(3)
                } else {
                    e.useful.saturating_sub(1)
                };
            }
            e.ctr = if taken {
                (e.ctr + 1).min(3)
            } else {
                (e.ctr - 1).max(-4)
            };
        }
        if pred != taken {
            self.allocate(&slots[..n], provider.map_or(0, |p| p + 1), taken);
        }
        self.age();
        self.push_history(taken);
        pred == taken
    }

    /// After a misprediction, one entry in a table longer than the
    /// provider's (`from` up): the first free one after a random skip, else
    /// every candidate's usefulness decays.
    fn allocate(&mut self, slots: &[(usize, u16)], from: usize, taken: bool) {
        if from >= self.tables.len() {
            return;
        }
        self.rng ^= self.rng << 13;
        self.rng ^= self.rng >> 7;
        self.rng ^= self.rng << 17;
        let start = (from + (self.rng & 1) as usize).min(self.tables.len() - 1);
        let free = (start..self.tables.len())
            .chain(from..start)
            .find(|&t| self.tables[t].entries[slots[t].0].useful == 0);
        match free {
            Some(t) => {
                self.tables[t].entries[slots[t].0] = Entry {
                    ctr: if taken { 0 } else { -1 },
                    tag: slots[t].1,
                    useful: 0,
                };
            }
            None => {
                for (t, s) in self.tables.iter_mut().zip(slots).skip(from) {
                    let e = &mut t.entries[s.0];
                    e.useful = e.useful.saturating_sub(1);
                }
            }
        }
    }

    /// Halve every usefulness counter once a period.
    fn age(&mut self) {
        self.since_reset += 1;
        if self.since_reset == USEFUL_PERIOD {
            self.since_reset = 0;
            for e in self.tables.iter_mut().flat_map(|t| t.entries.iter_mut()) {
                e.useful >>= 1;
            }
        }
    }

    /// Shift `taken` into the global history and every folded copy.
    fn push_history(&mut self, taken: bool) {
        let n = self.ring.len();
        self.head = (self.head + 1) % n;
        self.ring[self.head] = taken;
        for t in &mut self.tables {
            let old = self.ring[(self.head + n - t.index.len as usize) % n];
            t.index.push(taken, old);
            t.tag_a.push(taken, old);
            t.tag_b.push(taken, old);
        }
    }
}

/// A core's conditional branch predictor, as its config names it.
#[derive(Clone, Debug)]
pub enum Predictor {
    /// Gshare alone.
    Gshare(Gshare),
    /// TAGE over a gshare base.
    Tage(Box<Tage>),
}

impl Predictor {
    /// The predictor of a core config: gshare of `history_bits` and
    /// `2^predictor_bits` counters, under TAGE when `tage` is set.
    #[must_use]
    pub fn new(history_bits: u32, predictor_bits: u32, tage: Option<&TageConfig>) -> Predictor {
        let g = Gshare::new(history_bits, predictor_bits);
        match tage {
            None => Predictor::Gshare(g),
            Some(c) => Predictor::Tage(Box::new(Tage::new(g, c))),
        }
    }

    /// Predict the branch at `site`, learn its outcome; true if predicted right.
    #[inline]
    pub fn predict_and_update(&mut self, site: u32, taken: bool) -> bool {
        match self {
            Predictor::Gshare(g) => g.predict_and_update(site, taken),
            Predictor::Tage(t) => t.predict_and_update(site, taken),
        }
    }
}

/// A hardware thread's global branch history, kept while another thread
/// uses the predictor (SMT: the tables are shared, the histories are not).
#[derive(Clone, Debug, Default)]
pub struct History {
    gshare: u64,
    ring: Vec<bool>,
    head: usize,
    /// Each tagged table's folded index and tags.
    folded: Vec<[u32; 3]>,
}

impl Predictor {
    /// The current global history (a fresh predictor's: none yet).
    #[must_use]
    pub fn history(&self) -> History {
        let mut h = History::default();
        let mut me = self.clone();
        me.swap_history(&mut h);
        h
    }

    /// Put history `h` in and take the current one out into `h`.
    pub fn swap_history(&mut self, h: &mut History) {
        match self {
            Predictor::Gshare(g) => std::mem::swap(&mut g.history, &mut h.gshare),
            Predictor::Tage(t) => {
                std::mem::swap(&mut t.base.history, &mut h.gshare);
                if h.ring.len() != t.ring.len() {
                    // A history never taken out: a fresh one.
                    h.ring = vec![false; t.ring.len()];
                    h.head = 0;
                    h.folded = vec![[0; 3]; t.tables.len()];
                }
                std::mem::swap(&mut t.ring, &mut h.ring);
                std::mem::swap(&mut t.head, &mut h.head);
                for (tb, f) in t.tables.iter_mut().zip(&mut h.folded) {
                    let now = [tb.index.value, tb.tag_a.value, tb.tag_b.value];
                    [tb.index.value, tb.tag_a.value, tb.tag_b.value] = *f;
                    *f = now;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_history_swapped_out_and_back_leaves_the_predictor_as_it_was() {
        for mut p in [Predictor::new(12, 14, None), tage()] {
            let mut other = p.clone();
            let mut h = p.history();
            for i in 0..300u32 {
                p.predict_and_update(i % 7, i % 3 == 0);
                other.predict_and_update(i % 7, i % 3 == 0);
            }
            // A second thread's branches in between, on its own history.
            p.swap_history(&mut h);
            for i in 0..50u32 {
                p.predict_and_update(100 + i % 5, i % 2 == 0);
            }
            p.swap_history(&mut h);
            // The first thread's history is back: what it predicts for a
            // branch the second thread never ran is unchanged.
            for i in 0..200u32 {
                assert_eq!(
                    p.predict_and_update(i % 7, i % 3 == 0),
                    other.predict_and_update(i % 7, i % 3 == 0),
                    "branch {i}"
                );
            }
        }
    }

    fn tage() -> Predictor {
        let c = TageConfig {
            tables: 6,
            table_bits: 10,
            tag_bits: 9,
            min_history: 4,
            max_history: 200,
        };
        Predictor::new(12, 14, Some(&c))
    }

    #[test]
    fn learns_a_loop_and_a_short_pattern() {
        for mut g in [Predictor::new(12, 14, None), tage()] {
            let mut wrong = 0;
            for i in 0..4000 {
                wrong += usize::from(!g.predict_and_update(1, i % 4 != 3));
            }
            assert!(wrong < 40, "T,T,T,N is learned: {wrong} wrong");
            let mut r = isa::rng::Rng::new(3);
            let mut wrong = 0;
            for _ in 0..4000 {
                wrong += usize::from(!g.predict_and_update(2, r.next_u64() & 1 == 1));
            }
            assert!(
                (1600..2400).contains(&wrong),
                "random is half wrong: {wrong}"
            );
        }
    }

    /// A branch whose outcome repeats one taken in 40: beyond gshare's 12
    /// history bits (it sees 12 not-takens either way), within TAGE's 200.
    #[test]
    fn tage_learns_a_period_beyond_the_gshare_history() {
        let run = |mut p: Predictor| {
            (0..40_000)
                .filter(|&i| !p.predict_and_update(5, i % 40 == 39))
                .filter(|&i| i >= 20_000)
                .count()
        };
        let g = run(Predictor::new(12, 14, None));
        let t = run(tage());
        assert!(g >= 450, "gshare misses most of the period's ends: {g}");
        assert!(t <= 25, "TAGE learns them: {t}");
    }
}
