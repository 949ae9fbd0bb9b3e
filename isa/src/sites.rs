//! The plan of branch-site numbers: one block per kernel module, so that no
//! two branches of different kernels share a predictor entry by accident. A
//! module takes its sites with [`SiteBlock::at`] (checked at compile time to
//! stay inside its block) and lists them in an `ALL` array, which the
//! workspace's layout test checks for duplicates. A new kernel module adds
//! its block here, after the last.

use crate::types::Site;

/// A block of consecutive branch-site numbers owned by one module.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SiteBlock {
    /// The owning module (`crate::module`).
    pub owner: &'static str,
    /// First site number.
    pub first: u32,
    /// Number of sites.
    pub len: u32,
}

impl SiteBlock {
    /// The block of `len` sites from `first`, owned by module `owner`.
    #[must_use]
    pub const fn new(owner: &'static str, first: u32, len: u32) -> SiteBlock {
        SiteBlock { owner, first, len }
    }
    /// Site `i` of the block (a compile-time error in a `const` beyond it).
    #[must_use]
    pub const fn at(&self, i: u32) -> Site {
        assert!(i < self.len, "branch site beyond its module's block");
        Site(self.first + i)
    }
    /// Whether `s` is in the block.
    #[must_use]
    pub const fn contains(&self, s: Site) -> bool {
        s.0 >= self.first && s.0 < self.first + self.len
    }
}

/// Calibration microkernels.
pub const MICRO: SiteBlock = SiteBlock::new("micro", 1, 9);
/// The ray-vs-4-boxes stream (`rt::boxtest`).
pub const BOXTEST: SiteBlock = SiteBlock::new("rt::boxtest", 10, 10);
/// Single-ray traversal (`rt::single`).
pub const SINGLE: SiteBlock = SiteBlock::new("rt::single", 20, 20);
/// DRS over a BVH4 (`drs_kernels::bvh4`).
pub const DRS_BVH4: SiteBlock = SiteBlock::new("drs_kernels::bvh4", 40, 10);
/// DRS over a BVH2 (`drs_kernels::bvh2`).
pub const DRS_BVH2: SiteBlock = SiteBlock::new("drs_kernels::bvh2", 50, 10);
/// Packet and hybrid traversal (`rt::packet`).
pub const PACKET: SiteBlock = SiteBlock::new("rt::packet", 60, 20);
/// Multi-frusta traversal (`mft_kernels`).
pub const MFT: SiteBlock = SiteBlock::new("mft_kernels", 80, 40);

/// MBVH ray-stream traversal (`mbvh_kernels::stream`).
pub const MBVH_RS: SiteBlock = SiteBlock::new("mbvh_kernels::stream", 120, 20);
/// Single-ray MBVH traversal (`mbvh_kernels::single`).
pub const MBVH_SINGLE: SiteBlock = SiteBlock::new("mbvh_kernels::single", 140, 10);
/// Packet traversal of an MBVH (`mbvh_kernels::packet`).
pub const MBVH_PACKET: SiteBlock = SiteBlock::new("mbvh_kernels::packet", 150, 20);
/// Multi-hit intersection filters and the post-traversal sort (`multihit_kernels`).
pub const MULTIHIT: SiteBlock = SiteBlock::new("multihit_kernels", 170, 20);
/// Volume ray casting (`volume_kernels`).
pub const VOLUME: SiteBlock = SiteBlock::new("volume_kernels", 190, 40);
/// Large packets with interval culling over an MBVH (`mbvh_kernels::large_packet`).
pub const MBVH_LARGE: SiteBlock = SiteBlock::new("mbvh_kernels::large_packet", 230, 20);

/// Every block, in order.
pub const PLAN: [SiteBlock; 13] = [
    MICRO,
    BOXTEST,
    SINGLE,
    DRS_BVH4,
    DRS_BVH2,
    PACKET,
    MFT,
    MBVH_RS,
    MBVH_SINGLE,
    MBVH_PACKET,
    MULTIHIT,
    VOLUME,
    MBVH_LARGE,
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_are_disjoint_and_in_order() {
        for w in PLAN.windows(2) {
            assert!(w[0].first + w[0].len <= w[1].first, "{w:?}");
        }
        assert!(PLAN.iter().all(|b| b.len > 0 && b.first > 0));
    }
}
