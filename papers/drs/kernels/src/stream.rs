//! The ray stream's buffers, shared by the BVH4 and BVH2 kernels and their
//! core loop: 9 pre-allocated ray pointer lists of 16-bit indices, the ray
//! stream stack, the list counters and the single-ray fallback stack.

use isa::{Buf, Machine, MemKind};

/// Bytes of a stack item: node u32, list u8, octant u8, pad, start u32, count u32.
pub const ITEM_BYTES: usize = 16;

/// The ray stream's own buffers.
pub struct StreamBufs {
    /// 9 ray pointer lists of `cap` u16 entries each.
    pub lists: Buf,
    /// Entries per list.
    pub cap: usize,
    /// The ray stream stack.
    pub items: Buf,
    /// The 9 list counters (u64 each).
    pub counters: Buf,
    /// Single-ray fallback stack.
    pub stack: Buf,
    /// Ray-node and ray-leaf tests so far.
    pub tests: rt::stats::Tests,
}

impl StreamBufs {
    /// Buffers for `nrays` rays over a BVH4 of depth `depth`.
    pub fn new<M: Machine>(m: &mut M, nrays: usize, depth: usize) -> StreamBufs {
        assert!(nrays <= 65536, "16-bit ray indices");
        let cap = (nrays + 16) * (depth + 2);
        StreamBufs {
            lists: m
                .space()
                .alloc(MemKind::RayLists, "ray-lists", 9 * cap * 2, 64),
            cap,
            items: m.space().alloc(
                MemKind::Stack,
                "stream-stack",
                ITEM_BYTES * (9 * (depth + 2) + 8),
                64,
            ),
            counters: m.space().alloc(MemKind::Stack, "list-counters", 9 * 8, 64),
            stack: m.space().alloc(
                MemKind::Stack,
                "single-stack",
                rt::single::STACK_ENTRIES * 8,
                64,
            ),
            tests: rt::stats::Tests::default(),
        }
    }

    /// Ready for another trace of a stream of the same size: list counters
    /// and test counts zero (host-side, not recorded). The lists keep the
    /// last trace's indices, all of rays of the stream, so the core loop's
    /// read-ahead past an item still names rays in bounds.
    pub fn reset(&mut self) {
        self.counters.bytes_mut().fill(0);
        self.tests = rt::stats::Tests::default();
    }
}
