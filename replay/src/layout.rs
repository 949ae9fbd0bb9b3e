//! The replay buffer: every 4 KiB page a window touches, packed in address
//! order at [`BUFFER_BASE`], each byte at its recorded page offset (so L1
//! sets and line splits are the recorded ones), with spill slots after.

use crate::program::BUFFER_BASE;
use isa::{Op, Trace};
use std::collections::BTreeMap;

const PAGE: u64 = 4096;

/// Where each recorded page lands in the buffer.
#[derive(Clone, Debug)]
pub struct Layout {
    pages: BTreeMap<u64, u64>,
    /// First byte of the spill slots.
    pub spill_base: u64,
}

impl Layout {
    /// The pages `ops` touch (a gather's or scatter's first lane only:
    /// replayed, its lanes all read that address).
    #[must_use]
    pub fn of(trace: &Trace, ops: &[Op]) -> Layout {
        let mut pages = BTreeMap::new();
        for o in ops.iter().filter(|o| o.class.is_mem()) {
            let a = first_addr(trace, o);
            let end = a + u64::from(o.bytes.max(1)) - 1;
            for p in a / PAGE..=end / PAGE {
                pages.insert(p, 0);
            }
        }
        for (n, v) in pages.values_mut().enumerate() {
            *v = n as u64;
        }
        let spill_base = BUFFER_BASE + pages.len() as u64 * PAGE;
        Layout { pages, spill_base }
    }

    /// The host address of recorded address `a`.
    #[must_use]
    pub fn host(&self, a: u64) -> u64 {
        let n = self.pages.get(&(a / PAGE)).copied().unwrap_or(0);
        BUFFER_BASE + n * PAGE + a % PAGE
    }

    /// Bytes the buffer spans with `slots` 64-byte spill slots.
    #[must_use]
    pub fn bytes(&self, slots: usize) -> u64 {
        let end = self.spill_base + 64 * slots as u64 - BUFFER_BASE;
        end.div_ceil(PAGE) * PAGE + PAGE
    }
}

/// The first byte a memory op touches (a gather's first active lane).
#[must_use]
pub fn first_addr(trace: &Trace, o: &Op) -> u64 {
    if o.class.is_per_lane_mem() {
        trace.lanes_of(o).first().map_or(o.addr.0, |a| a.0)
    } else {
        o.addr.0
    }
}
