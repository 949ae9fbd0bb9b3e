//! A gshare branch predictor (McFarling 1993): 2-bit counters indexed by the
//! branch site hashed with the global history. Stands in for the undocumented
//! predictors of the modelled machines; its sizes are config fields.

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

    /// Predict the branch at `site`, learn its outcome; true if predicted right.
    #[inline]
    pub fn predict_and_update(&mut self, site: u32, taken: bool) -> bool {
        let h = u64::from(site).wrapping_mul(0x9e37_79b9_7f4a_7c15) >> 40;
        let i = ((h ^ (self.history & self.hist_mask)) & self.mask) as usize;
        let c = &mut self.counters[i];
        let predicted = *c >= 2;
        if taken {
            *c = (*c + 1).min(3);
        } else {
            *c = c.saturating_sub(1);
        }
        self.history = (self.history << 1) | u64::from(taken);
        predicted == taken
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn learns_a_loop_and_a_short_pattern() {
        let mut g = Gshare::new(12, 14);
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
