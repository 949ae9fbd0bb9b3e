//! The per-ray hit buffers the filters keep in simulated memory.
//!
//! An entry is 8 bytes: the hit's t (f32) and its triangle (i32). Listing 1's
//! `HitData` also holds a geometry id and the normal (24 bytes); one mesh has
//! no geometry ids and the triangle blocks carry no normal, so an entry moves
//! as one 8-byte load and store (a named deviation).
//!
//! - Single ray: ray `i`'s `E` entries at `8 E i` of [`HitBufs::entries`],
//!   its count at `4 i` of [`HitBufs::counts`].
//! - Packets (ispc's SoA layout for a `varying` struct array): packet `p`
//!   is `4 W (1 + 2 E)` bytes at `p` times that: a row of the lanes' counts,
//!   then per entry a row of the lanes' t and a row of their triangles, so an
//!   entry index the same in every lane is one vector load.

use isa::{Buf, Machine, MemKind};
use scene::Hit;

/// Hit buffers of one run.
pub struct HitBufs {
    /// Entries (single) or whole packet records (packets).
    pub entries: Buf,
    /// Counts (single rays; packets keep theirs in their record).
    pub counts: Buf,
    /// Entries per ray.
    pub cap: u32,
    /// Lanes per packet (0: single rays).
    pub lanes: usize,
}

impl HitBufs {
    /// Buffers for `n` single rays of `cap` entries each.
    pub fn single<M: Machine>(m: &mut M, n: usize, cap: u32) -> HitBufs {
        let sp = m.space();
        HitBufs {
            entries: sp.alloc(
                MemKind::Hits,
                "multihit-entries",
                n.max(1) * 8 * cap as usize,
                64,
            ),
            counts: sp.alloc(MemKind::Hits, "multihit-counts", n.max(1) * 4, 64),
            cap,
            lanes: 0,
        }
    }

    /// Buffers for `np` packets of `w` lanes, `cap` entries per lane.
    pub fn packet<M: Machine>(m: &mut M, np: usize, w: usize, cap: u32) -> HitBufs {
        let bytes = np.max(1) * packet_bytes(w, cap);
        let sp = m.space();
        HitBufs {
            entries: sp.alloc(MemKind::Hits, "multihit-packets", bytes, 64),
            counts: sp.alloc(MemKind::Hits, "multihit-unused", 4, 64),
            cap,
            lanes: w,
        }
    }

    /// Bytes of one packet's record.
    #[must_use]
    pub fn packet_bytes(&self) -> usize {
        packet_bytes(self.lanes, self.cap)
    }

    /// Single rays: each ray's first `min(count, n_query)` entries.
    #[must_use]
    pub fn lists_single(&self, n: usize, n_query: u32) -> Vec<Vec<Hit>> {
        (0..n)
            .map(|i| {
                let k = self.counts.u32_at(4 * i).min(n_query).min(self.cap);
                let base = 8 * self.cap as usize * i;
                (0..k as usize).map(|j| self.entry(base + 8 * j)).collect()
            })
            .collect()
    }

    /// Packets: the ray in each lane slot's first `min(count, n_query)` entries.
    #[must_use]
    pub fn lists_packet(&self, slot_of: &[usize], n_query: u32) -> Vec<Vec<Hit>> {
        let w = self.lanes;
        let pbytes = self.packet_bytes();
        slot_of
            .iter()
            .map(|&j| {
                let (p, l) = (j / w, j % w);
                let base = p * pbytes;
                let k = self.entries.u32_at(base + 4 * l).min(n_query).min(self.cap);
                (0..k as usize)
                    .map(|e| {
                        let row = base + 4 * w * (1 + 2 * e);
                        let t = self.entries.f32_at(row + 4 * l);
                        let prim = self.entries.u32_at(row + 4 * w + 4 * l);
                        Hit::from_record(t, prim)
                    })
                    .collect()
            })
            .collect()
    }

    fn entry(&self, off: usize) -> Hit {
        Hit::from_record(self.entries.f32_at(off), self.entries.u32_at(off + 4))
    }
}

/// Bytes of a packet record of `w` lanes and `cap` entries per lane.
#[must_use]
pub fn packet_bytes(w: usize, cap: u32) -> usize {
    4 * w * (1 + 2 * cap as usize)
}
