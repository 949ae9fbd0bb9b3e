//! ISA flavours: what a vector machine has natively. An op a flavour lacks is
//! expanded (in the traced backend) into the ops that flavour really needs.
//!
//! | flavour  | lanes | FMA | masks           | gather | scatter | compress | approx rcp/rsqrt |
//! |----------|-------|-----|-----------------|--------|---------|----------|------------------|
//! | `lrb16`  | 16    | yes | 16-bit k regs   | yes    | yes     | yes      | 23 bits (see below) |
//! | `avx512` | 16    | yes | 16-bit k regs   | yes    | yes     | yes      | 14 bits (vrcp14ps) |
//! | `avx2`   | 8     | yes | vector (blendv) | yes    | no      | no       | 12 bits (vrcpps) |
//! | `sse4`   | 4     | no  | vector (blendv) | no     | no      | no       | 12 bits (rcpps)  |
//! | `wide32` | 32    | yes | 32-bit k regs   | yes    | yes     | yes      | 14 bits (as AVX-512) |
//!
//! `wide32` is a what-if with no hardware behind it: AVX-512's ops on
//! 1024-bit vectors (32 lanes), for lane-width experiments ("what if 32
//! lanes"). Its ops cost what the machine config gives the vector classes
//! (a full-width datapath), and a 128-byte vector access touches two lines.
//!
//! Approximate reciprocal precision. AVX2/SSE `rcpps`/`rsqrtps`: relative error
//! at most 1.5 * 2^-12 (Intel SDM, RCPPS); AVX-512 `vrcp14ps`: less than 2^-14
//! (Intel SDM, VRCP14PS). Larrabee: LRBni's precision is not public. We model
//! its successor Knights Corner's `vrcp23ps`/`vrsqrt23ps` (the KNC ISA reference
//! manual gives 23-bit results), because Larrabee's renderer relied on
//! full-precision reciprocals for its slab tests and KNC kept the LRBni
//! encoding space. rtsim implements "k-bit approximate" deterministically: the
//! correctly rounded f32 result with its mantissa truncated to k bits, so the
//! relative error is below 2^-k on every host (hardware tables differ between
//! Intel and AMD, and results must be identical on every run and machine).

use std::fmt;

/// Which flavour, as a value (for trace headers, reports, CLI).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[repr(u8)]
pub enum FlavourId {
    /// Larrabee LRBni, 16 lanes.
    Lrb16 = 0,
    /// AVX-512, 16 lanes.
    Avx512 = 1,
    /// AVX2 + FMA, 8 lanes.
    Avx2 = 2,
    /// SSE4.1, 4 lanes.
    Sse4 = 3,
    /// AVX-512's ops at 32 lanes (a what-if, no hardware).
    Wide32 = 4,
}

impl FlavourId {
    /// Every flavour.
    pub const ALL: [FlavourId; 5] = [
        FlavourId::Lrb16,
        FlavourId::Avx512,
        FlavourId::Avx2,
        FlavourId::Sse4,
        FlavourId::Wide32,
    ];
    /// Stable name (`lrb16`, `avx512`, `avx2`, `sse4`, `wide32`).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            FlavourId::Lrb16 => "lrb16",
            FlavourId::Avx512 => "avx512",
            FlavourId::Avx2 => "avx2",
            FlavourId::Sse4 => "sse4",
            FlavourId::Wide32 => "wide32",
        }
    }
    /// The flavour with this name.
    #[must_use]
    pub fn from_name(s: &str) -> Option<FlavourId> {
        FlavourId::ALL.into_iter().find(|f| f.name() == s)
    }
    /// The flavour with this id.
    #[must_use]
    pub fn from_id(id: u8) -> Option<FlavourId> {
        FlavourId::ALL.get(id as usize).copied()
    }
    /// Vector lanes (32-bit elements).
    #[must_use]
    pub fn lanes(self) -> usize {
        match self {
            FlavourId::Lrb16 | FlavourId::Avx512 => 16,
            FlavourId::Avx2 => 8,
            FlavourId::Sse4 => 4,
            FlavourId::Wide32 => 32,
        }
    }
}

impl fmt::Display for FlavourId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// What a flavour has natively. Implemented by the marker types below for
/// their lane count `N` only, so `Traced<Avx2, 16>` does not compile.
pub trait Flavour<const N: usize>: Copy + Default + fmt::Debug + 'static {
    /// This flavour as a value.
    const ID: FlavourId;
    /// Fused multiply-add (else mul + add, two roundings).
    const FMA: bool;
    /// Mask registers and masked ops (else masks are vectors and masking is a blend).
    const MASK_REGS: bool;
    /// Hardware gather (else per-lane extract, scalar load, insert).
    const GATHER: bool;
    /// Hardware scatter (else per-lane extracts and scalar stores).
    const SCATTER: bool;
    /// Compress-store of active lanes (else movemask, LUT, permute, store, popcount).
    const COMPRESS: bool;
    /// Masked vector load and store (vmaskmovps on AVX2; SSE4 has none).
    const MASKED_MEM: bool;
    /// Any-lane permutes of one source in one op (vpermps); SSE4 has only in-lane shuffles.
    const CROSS_PERMUTE: bool;
    /// Two-source arbitrary permute in one op (vpermt2ps, LRBni shuffles).
    const PERMUTE2: bool;
    /// Mantissa bits of the approximate reciprocal and rsqrt.
    const RCP_BITS: u32;
    /// A vector divide. Without one (LRBni), `div` is a reciprocal of
    /// [`Flavour::RCP_BITS`] bits and a multiply, and `rcp` the reciprocal.
    const DIV: bool;

    /// Whether a memory operand of `n` floats repeated across the lanes
    /// folds into the op that reads it (see [`crate::Machine::load_operand`]).
    fn folds(n: usize) -> bool {
        match Self::ID {
            // {1to16}, {4to16} and full operands [Abrash].
            FlavourId::Lrb16 => matches!(n, 1 | 4) || n == N,
            // m32bcst and full operands (Intel SDM, EVEX embedded broadcast).
            FlavourId::Avx512 | FlavourId::Wide32 => n == 1 || n == N,
            // Full operands; on AVX2 also 4, standing for a 128-bit op's m128
            // (the single-ray kernels run 4-wide tests in wider lanes).
            FlavourId::Avx2 => n == 4 || n == N,
            FlavourId::Sse4 => n == N,
        }
    }

    /// `op` on two lanes as this flavour computes it (divide: see [`Flavour::DIV`]).
    #[inline(always)]
    #[must_use]
    fn eval(op: crate::BinOp, x: f32, y: f32) -> f32 {
        if op == crate::BinOp::Div && !Self::DIV {
            x * crate::lanes::rcp_approx(y, Self::RCP_BITS)
        } else {
            op.eval(x, y)
        }
    }
}

/// Larrabee LRBni (Seiler et al. 2008; Abrash, "A First Look at the Larrabee New Instructions").
#[derive(Clone, Copy, Debug, Default)]
pub struct Lrb16;
/// AVX-512F (Intel SDM).
#[derive(Clone, Copy, Debug, Default)]
pub struct Avx512;
/// AVX2 + FMA3 (Haswell).
#[derive(Clone, Copy, Debug, Default)]
pub struct Avx2;
/// SSE4.1 (Core 2 Penryn / Nehalem).
#[derive(Clone, Copy, Debug, Default)]
pub struct Sse4;
/// AVX-512's ops on 32 lanes: a what-if flavour with no hardware behind it.
#[derive(Clone, Copy, Debug, Default)]
pub struct Wide32;

impl Flavour<16> for Lrb16 {
    const ID: FlavourId = FlavourId::Lrb16;
    const FMA: bool = true;
    const MASK_REGS: bool = true;
    const GATHER: bool = true;
    const SCATTER: bool = true;
    const COMPRESS: bool = true; // vpackstoreps
    const MASKED_MEM: bool = true;
    const CROSS_PERMUTE: bool = true;
    const PERMUTE2: bool = true;
    const RCP_BITS: u32 = 23;
    const DIV: bool = false; // no divide in LRBni [Abrash]: vrcp23ps and a multiply
}

impl Flavour<16> for Avx512 {
    const ID: FlavourId = FlavourId::Avx512;
    const FMA: bool = true;
    const MASK_REGS: bool = true;
    const GATHER: bool = true;
    const SCATTER: bool = true;
    const COMPRESS: bool = true;
    const MASKED_MEM: bool = true;
    const CROSS_PERMUTE: bool = true;
    const PERMUTE2: bool = true;
    const RCP_BITS: u32 = 14;
    const DIV: bool = true; // vdivps
}

impl Flavour<8> for Avx2 {
    const ID: FlavourId = FlavourId::Avx2;
    const FMA: bool = true;
    const MASK_REGS: bool = false;
    const GATHER: bool = true;
    const SCATTER: bool = false;
    const COMPRESS: bool = false;
    const MASKED_MEM: bool = true;
    const CROSS_PERMUTE: bool = true;
    const PERMUTE2: bool = false;
    const RCP_BITS: u32 = 12;
    const DIV: bool = true; // vdivps
}

impl Flavour<4> for Sse4 {
    const ID: FlavourId = FlavourId::Sse4;
    const FMA: bool = false;
    const MASK_REGS: bool = false;
    const GATHER: bool = false;
    const SCATTER: bool = false;
    const COMPRESS: bool = false;
    const MASKED_MEM: bool = false;
    const CROSS_PERMUTE: bool = true; // 4 lanes are one 128-bit lane: pshufd reaches all
    const PERMUTE2: bool = false;
    const RCP_BITS: u32 = 12;
    const DIV: bool = true; // vdivps
}

impl Flavour<32> for Wide32 {
    const ID: FlavourId = FlavourId::Wide32;
    const FMA: bool = true;
    const MASK_REGS: bool = true;
    const GATHER: bool = true;
    const SCATTER: bool = true;
    const COMPRESS: bool = true;
    const MASKED_MEM: bool = true;
    const CROSS_PERMUTE: bool = true;
    const PERMUTE2: bool = true;
    const RCP_BITS: u32 = 14;
    const DIV: bool = true;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_and_lanes() {
        for f in FlavourId::ALL {
            assert_eq!(FlavourId::from_name(f.name()), Some(f));
            assert_eq!(FlavourId::from_id(f as u8), Some(f));
        }
        assert_eq!(FlavourId::Avx2.lanes(), 8);
        assert_eq!(<Lrb16 as Flavour<16>>::ID.lanes(), 16);
        assert_eq!(<Wide32 as Flavour<32>>::ID.lanes(), 32);
    }
}
