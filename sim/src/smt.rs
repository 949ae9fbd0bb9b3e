//! Simultaneous multithreading on the out-of-order core: how a core's
//! hardware threads share it (Intel's Hyper-Threading, as Nehalem and
//! Haswell have it). Sources:
//!
//! - [IA-32 opt.] Intel, IA-32 Intel Architecture Optimization Reference
//!   Manual, "Microarchitecture Pipeline and Hyper-Threading Technology":
//!   "all selection points alternate between the two logical processors
//!   unless one logical processor cannot make use of a pipeline stage. In
//!   this case, the other logical processor has full use of every cycle of
//!   the pipeline stage"; "Processor Resources and Hyper-Threading
//!   Technology": partitioned resources are limited to half their entries
//!   per logical processor; the return stack is replicated.
//! - [Marr] Marr et al., "Hyper-Threading Technology Architecture and
//!   Microarchitecture", Intel Technology Journal 6(1), 2002: the re-order
//!   buffer, load and store buffers are partitioned; the schedulers take
//!   uops of either thread; the retirement logic alternates between the
//!   logical processors; caches are shared.
//! - [Intel SNB/HSW] Intel 64 and IA-32 Architectures Optimization
//!   Reference Manual, Sandy Bridge chapter (kept in Haswell): with two
//!   threads active the ROB, load and store buffers are statically
//!   partitioned, the scheduler (reservation station) is competitively
//!   shared, the branch predictor's tables and the caches are shared.
//!
//! The rules as modelled, each with an exact-cycle test in `ooo.rs`:
//!
//! 1. Dispatch (rename/allocate) and retirement are selection points: a
//!    cycle of either belongs to one thread. A thread takes a cycle the
//!    other has not taken; the threads run op by op in the order of their
//!    next dispatch cycles, so when both can dispatch they alternate, and
//!    one that cannot (a mispredict's redirect, a full partition) leaves
//!    every cycle to the other [IA-32 opt.]. (The uop cache and legacy
//!    decoders before dispatch are per thread here: recorded kernels carry
//!    no instruction lengths, so the front end they reach is the dispatch
//!    width.)
//! 2. The ROB and the store buffer are partitioned: with n threads running
//!    on a core, each has `rob / n` and `store_buffer / n` entries for the
//!    whole step [Marr, Intel SNB/HSW]. (The load buffer is not modelled
//!    for one thread either.)
//! 3. Ports, the scheduler entries, the miss slots (fill buffers), the
//!    caches, the prefetcher, the memory-dependence predictor and the
//!    branch predictor's tables are shared, first come first served; each
//!    thread keeps its own global branch history [Intel SNB/HSW].

/// Cycles a turn ledger looks ahead (as the port calendar does).
const WINDOW: u64 = 1 << 16;

/// Which thread took each cycle of one selection point: a ring of
/// [`WINDOW`] cycles, each the taker's index plus one (0: free).
pub(crate) struct Ledger {
    owner: Box<[u8]>,
    /// Cycles before this are cleared (no thread takes them again).
    base: u64,
}

impl Ledger {
    fn new() -> Ledger {
        Ledger {
            owner: vec![0u8; WINDOW as usize].into_boxed_slice(),
            base: 0,
        }
    }

    #[inline(always)]
    fn slot(c: u64) -> usize {
        (c & (WINDOW - 1)) as usize
    }

    /// The first cycle from `c` that no other thread than `thread` took;
    /// it is `thread`'s from now on.
    #[inline]
    pub(crate) fn take(&mut self, thread: usize, c: u64) -> u64 {
        let me = thread as u8 + 1;
        let mut c = c.max(self.base);
        loop {
            if c >= self.base + WINDOW {
                // Beyond the ring: no turns are kept that far ahead.
                return c;
            }
            let o = &mut self.owner[Ledger::slot(c)];
            if *o == 0 || *o == me {
                *o = me;
                return c;
            }
            c += 1;
        }
    }

    /// No thread takes a cycle before `to` again.
    pub(crate) fn advance(&mut self, to: u64) {
        if to <= self.base {
            return;
        }
        if to - self.base >= WINDOW {
            self.owner.fill(0);
        } else {
            for c in self.base..to {
                self.owner[Ledger::slot(c)] = 0;
            }
        }
        self.base = to;
    }
}

/// The selection points a core's running threads take turns at.
pub(crate) struct Turns {
    /// Rename/allocate: the cycle a thread's uops enter the window.
    pub dispatch: Ledger,
    /// Retirement.
    pub retire: Ledger,
}

impl Turns {
    pub(crate) fn new() -> Turns {
        Turns {
            dispatch: Ledger::new(),
            retire: Ledger::new(),
        }
    }

    /// No thread dispatches or retires before cycle `to` again.
    pub(crate) fn advance(&mut self, to: u64) {
        self.dispatch.advance(to);
        self.retire.advance(to);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cycle_belongs_to_the_thread_that_took_it() {
        let mut l = Ledger::new();
        assert_eq!(l.take(0, 5), 5);
        assert_eq!(l.take(0, 5), 5, "the taker keeps its cycle");
        assert_eq!(l.take(1, 5), 6, "the other thread waits a cycle");
        assert_eq!(l.take(0, 6), 7);
        assert_eq!(l.take(1, 3), 3, "an earlier free cycle is free");
        l.advance(7);
        assert_eq!(l.take(1, 7), 8, "7 stays thread 0's");
        l.advance(9);
        assert_eq!(l.take(0, 2), 9, "cleared cycles are not taken again");
    }
}
