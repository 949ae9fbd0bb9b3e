//! Op classes: the unit the timing model prices. One class is one machine
//! instruction kind (e.g. `vfma` is vfmadd*ps on AVX2, vfmadd231ps on LRBni).
//! A machine config maps each class to uops, ports and latency; this crate
//! only decides which classes a kernel op becomes on each flavour.

use std::fmt;

macro_rules! op_classes {
    ($( $(#[$doc:meta])* $v:ident = $name:literal ),* $(,)?) => {
        /// One machine instruction kind. Names are stable: trace text, machine
        /// configs and reports use them.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
        #[repr(u8)]
        pub enum OpClass { $( $(#[$doc])* $v ),* }

        impl OpClass {
            /// Every class, in id order.
            pub const ALL: &'static [OpClass] = &[ $( OpClass::$v ),* ];
            /// Stable lower-case name.
            #[must_use]
            pub fn name(self) -> &'static str {
                match self { $( OpClass::$v => $name ),* }
            }
        }
    };
}

op_classes! {
    /// Vector FP add, sub (vaddps, vsubps).
    VAdd = "vadd",
    /// Vector FP multiply (vmulps).
    VMul = "vmul",
    /// Vector fused multiply-add family (vfmadd/vfmsub/vfnmadd/vfnmsub).
    VFma = "vfma",
    /// Vector FP divide (vdivps), not pipelined on most machines.
    VDiv = "vdiv",
    /// Vector FP square root (vsqrtps).
    VSqrt = "vsqrt",
    /// Approximate reciprocal (vrcpps, vrcp14ps, LRBni/KNC vrcp23ps).
    VRcp = "vrcp",
    /// Approximate reciprocal square root (vrsqrtps, vrsqrt14ps, vrsqrt23ps).
    VRsqrt = "vrsqrt",
    /// Vector FP min, max (vminps, vmaxps).
    VMinMax = "vminmax",
    /// Vector FP compare (vcmpps into a vector on AVX2/SSE, into a mask register on LRBni/AVX-512).
    VCmp = "vcmp",
    /// Vector bitwise op in the FP domain (vandps, vorps, vxorps, vandnps); abs and neg are this.
    VLogic = "vlogic",
    /// Variable blend by a vector mask (vblendvps, blendvps).
    VBlend = "vblend",
    /// Masked move or blend by a mask register (vmovaps{k}, vblendmps).
    VMaskMov = "vmaskmov",
    /// In-128-bit-lane shuffle (vshufps, vpermilps, pshufd).
    VShuf = "vshuf",
    /// Cross-lane permute (vpermps, vperm2f128, vextractf128, vpermt2ps).
    VPerm = "vperm",
    /// Broadcast a register scalar to all lanes (vbroadcastss ymm, xmm).
    VBcast = "vbcast",
    /// Insert a scalar into a lane (insertps, vpinsrd).
    VInsert = "vinsert",
    /// Int/float conversion (vcvtdq2ps, vcvttps2dq, vcvtps2dq).
    VCvt = "vcvt",
    /// Vector integer add, sub (vpaddd, vpsubd).
    VIAdd = "viadd",
    /// Vector integer multiply low (vpmulld).
    VIMul = "vimul",
    /// Vector integer bitwise op (vpand, vpor, vpxor, vpandn).
    VILogic = "vilogic",
    /// Vector integer shift by an immediate (vpslld, vpsrld, vpsrad).
    VIShift = "vishift",
    /// Vector integer compare (vpcmpeqd, vpcmpgtd).
    VICmp = "vicmp",
    /// Mask-register logic (kandw, korw, kxorw, knotw, kandnw).
    KLogic = "klogic",
    /// Lane mask to a general register (vmovmskps, kmovw).
    MovMsk = "movmsk",
    /// Test a mask for any/all lanes, setting flags (vtestps, ptest, kortestw).
    KTest = "ktest",
    /// Vector load (vmovaps, vmovups).
    VLoad = "vload",
    /// Broadcast load of 1 or 4 elements (vbroadcastss/vbroadcastf128 m, {1to16}/{4to16}).
    VLoadBcast = "vloadbcast",
    /// Masked vector load (vmaskmovps load, vmovaps{k} m).
    VLoadMasked = "vloadmasked",
    /// Vector store (vmovaps, vmovups to memory).
    VStore = "vstore",
    /// Masked vector store (vmaskmovps store, vmovaps m{k}).
    VStoreMasked = "vstoremasked",
    /// Gather (vgatherdps; LRBni vgatherd).
    VGather = "vgather",
    /// Scatter (vscatterdps; LRBni vscatterd).
    VScatter = "vscatter",
    /// Compress-store of active lanes (vcompressps m{k}; LRBni vpackstore).
    VCompress = "vcompress",
    /// Scalar integer ALU op (add, sub, and, or, xor, shifts, lea, mov of a value).
    Alu = "alu",
    /// Scalar integer multiply (imul).
    IMul = "imul",
    /// Bit count and scan (popcnt, tzcnt).
    BitCnt = "bitcnt",
    /// Scalar compare producing a 0/1 value (cmp + setcc; cmp macro-fuses with a following branch).
    Cmp = "cmp",
    /// Conditional move (cmov), also scalar min/max.
    Cmov = "cmov",
    /// Scalar load (mov r, m; movss x, m).
    Load = "load",
    /// Scalar store (mov m, r; movss m, x).
    Store = "store",
    /// Conditional branch (jcc).
    Branch = "branch",
    /// A vector memory operand folded into the op that reads it (LRBni:
    /// full, {1to16}, {4to16}; AVX-512: full, {1to16}; AVX2, SSE: full,
    /// micro-fused); see [`crate::Machine::load_operand`].
    VLoadFold = "vloadfold",
    /// A scalar memory operand folded into the op that reads it (`add r,
    /// [m]`): micro-fused on Intel, one macro-op on AMD. Hand-written traces
    /// use it; the flavours' scalar code loads separately.
    LoadFold = "loadfold",
    /// Scalar FP divide (divss, divsd), priced apart from the vector divide.
    Div = "div",
    /// Three-component address arithmetic (`lea r, [b + i*s + d]`); a
    /// two-component LEA is `alu`.
    Lea3 = "lea3",
    /// A register-to-register move (mov r, r; vmovaps x, x), which
    /// renamers since Ivy Bridge and Zen eliminate.
    Mov = "mov",
    /// A zeroing idiom (xor r, r; vxorps x, x, x): no sources; renamers
    /// recognise it and need no execution unit.
    Zero = "zero",
}

impl OpClass {
    /// The class with this stable name.
    #[must_use]
    pub fn from_name(s: &str) -> Option<OpClass> {
        OpClass::ALL.iter().copied().find(|c| c.name() == s)
    }
    /// The class with this id.
    #[must_use]
    pub fn from_id(id: u8) -> Option<OpClass> {
        OpClass::ALL.get(id as usize).copied()
    }
    /// Whether the op reads memory.
    #[must_use]
    #[inline]
    pub fn is_load(self) -> bool {
        matches!(
            self,
            OpClass::VLoad
                | OpClass::VLoadBcast
                | OpClass::VLoadFold
                | OpClass::LoadFold
                | OpClass::VLoadMasked
                | OpClass::VGather
                | OpClass::Load
        )
    }
    /// Whether the op writes memory.
    #[must_use]
    #[inline]
    pub fn is_store(self) -> bool {
        matches!(
            self,
            OpClass::VStore
                | OpClass::VStoreMasked
                | OpClass::VScatter
                | OpClass::VCompress
                | OpClass::Store
        )
    }
    /// Whether the op is a memory operand folded into the op reading it
    /// (`vloadfold`, `loadfold`): part of that instruction, not one of its own.
    #[must_use]
    #[inline]
    pub fn is_folded(self) -> bool {
        matches!(self, OpClass::VLoadFold | OpClass::LoadFold)
    }
    /// Whether the op touches memory at all.
    #[must_use]
    #[inline]
    pub fn is_mem(self) -> bool {
        self.is_load() || self.is_store()
    }
    /// Whether the op carries one address per active lane (gather, scatter).
    #[must_use]
    #[inline]
    pub fn is_per_lane_mem(self) -> bool {
        matches!(self, OpClass::VGather | OpClass::VScatter)
    }
    /// Whether the op executes on the vector unit (counts toward SIMD utilisation).
    #[must_use]
    #[inline]
    pub fn is_vector(self) -> bool {
        !matches!(
            self,
            OpClass::Alu
                | OpClass::IMul
                | OpClass::BitCnt
                | OpClass::Cmp
                | OpClass::Cmov
                | OpClass::Load
                | OpClass::LoadFold
                | OpClass::Div
                | OpClass::Lea3
                | OpClass::Mov
                | OpClass::Zero
                | OpClass::Store
                | OpClass::Branch
                | OpClass::MovMsk
                | OpClass::KTest
                | OpClass::KLogic
        )
    }
}

impl fmt::Display for OpClass {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_and_names_round_trip() {
        for (i, c) in OpClass::ALL.iter().enumerate() {
            assert_eq!(*c as usize, i);
            assert_eq!(OpClass::from_name(c.name()), Some(*c));
            assert_eq!(OpClass::from_id(i as u8), Some(*c));
        }
        assert_eq!(OpClass::from_id(OpClass::ALL.len() as u8), None);
    }

    #[test]
    fn mem_classes() {
        assert!(OpClass::VGather.is_load() && OpClass::VGather.is_per_lane_mem());
        assert!(OpClass::VCompress.is_store() && !OpClass::VCompress.is_load());
        assert!(!OpClass::VFma.is_mem());
        assert!(OpClass::VFma.is_vector() && !OpClass::Branch.is_vector());
    }
}
