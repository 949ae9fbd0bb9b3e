//! Newtypes for what must never be mixed: value ids, simulated addresses, cache
//! line addresses, lane masks, branch sites, code regions and memory regions.

use std::fmt;

/// SSA-like id of a value produced by a recorded op. `ValId::NONE` (0) is a
/// constant or a value that is ready at time zero (hoisted out of all loops).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct ValId(pub u32);

impl ValId {
    /// A constant: no producer, no dependency.
    pub const NONE: ValId = ValId(0);
    /// Whether this id names a produced value (not a constant).
    #[must_use]
    pub fn is_some(self) -> bool {
        self.0 != 0
    }
}

/// A simulated byte address. Deterministic: assigned by [`crate::AddrSpace`],
/// never a host pointer.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Addr(pub u64);

impl Addr {
    /// The cache line holding this address, for a line of `line_bytes` (a power of two).
    #[must_use]
    pub fn line(self, line_bytes: u64) -> LineAddr {
        debug_assert!(line_bytes.is_power_of_two());
        LineAddr(self.0 / line_bytes)
    }
    /// This address plus `bytes`.
    #[must_use]
    pub fn offset(self, bytes: u64) -> Addr {
        Addr(self.0 + bytes)
    }
}

impl fmt::Display for Addr {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:#x}", self.0)
    }
}

/// A cache line number (byte address divided by the line size). Not an [`Addr`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct LineAddr(pub u64);

/// Active lanes of a vector op, bit i = lane i. At most 32 lanes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct LaneMask(pub u32);

impl LaneMask {
    /// All of `lanes` lanes active.
    #[must_use]
    pub fn full(lanes: usize) -> LaneMask {
        debug_assert!((1..=32).contains(&lanes));
        LaneMask(if lanes == 32 {
            u32::MAX
        } else {
            (1u32 << lanes) - 1
        })
    }
    /// Number of active lanes.
    #[must_use]
    pub fn count(self) -> u32 {
        self.0.count_ones()
    }
    /// Whether lane `i` is active.
    #[must_use]
    pub fn get(self, i: usize) -> bool {
        (self.0 >> i) & 1 == 1
    }
}

/// A static branch site: one per conditional branch in a kernel's source, so a
/// predictor can be indexed by it. Kernels declare them as constants.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Site(pub u32);

/// The code region an op belongs to, so statistics can be split (e.g. the DRS
/// paper's "core loop only" CPI row).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[repr(u8)]
pub enum Region {
    /// Not marked.
    #[default]
    Other = 0,
    /// Per-work-unit setup (ray stream build, initial stack items).
    Setup = 1,
    /// The optimised core loop (e.g. DRS ray-stream vs node test).
    CoreLoop = 2,
    /// Traversal outside the core loop (stack handling, node fetch).
    Traversal = 3,
    /// Leaf intersection (ray-triangle tests).
    Leaf = 4,
    /// Single-ray fallback path.
    SingleRay = 5,
    /// Shading or other per-hit work.
    Shading = 6,
    /// Volume sampling and compositing not in a finer stage (stepping,
    /// termination tests).
    Volume = 7,
    /// Volume: fetching voxels (address translation and loads).
    VoxelFetch = 8,
    /// Volume: interpolating the sample's value.
    Interpolation = 9,
    /// Volume: classification (transfer-function lookup).
    Classification = 10,
    /// Volume: front-to-back blending.
    Blending = 11,
    /// Volume: the gradient and diffuse lighting.
    Diffuse = 12,
    /// Volume: the Phong highlight.
    Phong = 13,
}

impl Region {
    /// Every region, in id order.
    pub const ALL: [Region; Region::COUNT] = [
        Region::Other,
        Region::Setup,
        Region::CoreLoop,
        Region::Traversal,
        Region::Leaf,
        Region::SingleRay,
        Region::Shading,
        Region::Volume,
        Region::VoxelFetch,
        Region::Interpolation,
        Region::Classification,
        Region::Blending,
        Region::Diffuse,
        Region::Phong,
    ];
    /// How many regions there are.
    pub const COUNT: usize = 14;
    /// Stable lower-case name, used in trace text and reports.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Region::Other => "other",
            Region::Setup => "setup",
            Region::CoreLoop => "core-loop",
            Region::Traversal => "traversal",
            Region::Leaf => "leaf",
            Region::SingleRay => "single-ray",
            Region::Shading => "shading",
            Region::Volume => "volume",
            Region::VoxelFetch => "voxel-fetch",
            Region::Interpolation => "interpolation",
            Region::Classification => "classification",
            Region::Blending => "blending",
            Region::Diffuse => "diffuse",
            Region::Phong => "phong",
        }
    }
    /// The region with this name.
    #[must_use]
    pub fn from_name(s: &str) -> Option<Region> {
        Region::ALL.into_iter().find(|r| r.name() == s)
    }
    /// The region with this id.
    #[must_use]
    pub fn from_id(id: u8) -> Option<Region> {
        Region::ALL.get(id as usize).copied()
    }
}

/// Index of a registered memory region (one per data structure) in an
/// [`crate::AddrSpace`]. Id 0 is the ISA layer's own lookup tables.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct MemId(pub u16);

/// What a memory region holds, so statistics can say which data structure
/// caused the traffic.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[repr(u8)]
pub enum MemKind {
    /// Anything else.
    #[default]
    Other = 0,
    /// BVH or other acceleration-structure nodes.
    Nodes = 1,
    /// Triangles or other primitives.
    Triangles = 2,
    /// Rays (ray streams, packets).
    Rays = 3,
    /// Ray index lists (DRS ray pointer lists).
    RayLists = 4,
    /// Traversal stacks.
    Stack = 5,
    /// Hit records.
    Hits = 6,
    /// Constant lookup tables (e.g. compress-store permutations).
    Lut = 7,
    /// Volume voxels and min-max hierarchies.
    Volume = 8,
    /// Frame buffers and images.
    Image = 9,
}

impl MemKind {
    /// Every kind, in id order.
    pub const ALL: [MemKind; 10] = [
        MemKind::Other,
        MemKind::Nodes,
        MemKind::Triangles,
        MemKind::Rays,
        MemKind::RayLists,
        MemKind::Stack,
        MemKind::Hits,
        MemKind::Lut,
        MemKind::Volume,
        MemKind::Image,
    ];
    /// Stable lower-case name.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            MemKind::Other => "other",
            MemKind::Nodes => "nodes",
            MemKind::Triangles => "triangles",
            MemKind::Rays => "rays",
            MemKind::RayLists => "ray-lists",
            MemKind::Stack => "stack",
            MemKind::Hits => "hits",
            MemKind::Lut => "lut",
            MemKind::Volume => "volume",
            MemKind::Image => "image",
        }
    }
    /// The kind with this name.
    #[must_use]
    pub fn from_name(s: &str) -> Option<MemKind> {
        MemKind::ALL.into_iter().find(|k| k.name() == s)
    }
    /// The kind with this id.
    #[must_use]
    pub fn from_id(id: u8) -> Option<MemKind> {
        MemKind::ALL.get(id as usize).copied()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for r in Region::ALL {
            assert_eq!(Region::from_name(r.name()), Some(r));
            assert_eq!(Region::from_id(r as u8), Some(r));
        }
        for k in MemKind::ALL {
            assert_eq!(MemKind::from_name(k.name()), Some(k));
            assert_eq!(MemKind::from_id(k as u8), Some(k));
        }
    }

    #[test]
    fn lines_and_masks() {
        assert_eq!(Addr(0x1234).line(64), LineAddr(0x48));
        assert_eq!(LaneMask::full(8).0, 0xff);
        assert_eq!(LaneMask::full(32).0, u32::MAX);
        assert_eq!(LaneMask(0b1010).count(), 2);
        assert!(LaneMask(0b1010).get(3));
    }
}
