//! The machine trait kernels are written against.
//!
//! Naming: vector f32 ops are unprefixed (`add`, `fmadd`, `cmp`), vector i32
//! ops start with `i` (`iop`, `icmp`), mask ops with `k` (`kand`), scalar
//! integer ops with `s_`, scalar float ops with `x_`. Every op both computes its
//! result and, in the traced backend, records the machine instructions the
//! flavour needs for it (see `traced.rs` for each expansion).
//!
//! Constants (`splat`, `consts`, `int`, ...) are free: they model values that
//! live in registers, hoisted out of every loop. Register pressure and spills
//! are not modelled; a kernel that needs a reload writes the load.
//!
//! Kernels take host decisions only from scalar values (`Int::get`) and
//! branch outcomes; the host views at the end of the trait (`lane`, `bits`) are
//! for tests and result extraction and record nothing.

use crate::flavour::FlavourId;
use crate::lanes::{BinOp, Cmp, Fma, IOp, Shift};
use crate::mem::{AddrSpace, At, Buf};
use crate::types::{Region, Site};
use std::fmt::Debug;

/// A scalar integer machine value (64-bit), readable by the host.
pub trait Int: Copy + Debug {
    /// Its value.
    fn get(self) -> i64;
}

/// A scalar f32 machine value, readable by the host.
pub trait Float: Copy + Debug {
    /// Its value.
    fn get(self) -> f32;
}

/// Bitwise ops on float vectors and masks.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Logic {
    /// a & b
    And,
    /// a | b
    Or,
    /// a ^ b
    Xor,
    /// !a & b
    AndNot,
}

impl Logic {
    /// Apply to bits.
    #[inline(always)]
    #[must_use]
    pub fn eval(self, a: u32, b: u32) -> u32 {
        match self {
            Logic::And => a & b,
            Logic::Or => a | b,
            Logic::Xor => a ^ b,
            Logic::AndNot => !a & b,
        }
    }
    /// Apply to booleans.
    #[inline(always)]
    #[must_use]
    pub fn eval_b(self, a: bool, b: bool) -> bool {
        match self {
            Logic::And => a & b,
            Logic::Or => a | b,
            Logic::Xor => a ^ b,
            Logic::AndNot => !a & b,
        }
    }
}

/// Scalar integer binary ops.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SOp {
    /// wrapping a + b
    Add,
    /// wrapping a - b
    Sub,
    /// wrapping a * b
    Mul,
    /// a & b
    And,
    /// a | b
    Or,
    /// a ^ b
    Xor,
    /// signed min (cmp + cmov)
    Min,
    /// signed max (cmp + cmov)
    Max,
}

impl SOp {
    /// Apply.
    #[inline(always)]
    #[must_use]
    pub fn eval(self, a: i64, b: i64) -> i64 {
        match self {
            SOp::Add => a.wrapping_add(b),
            SOp::Sub => a.wrapping_sub(b),
            SOp::Mul => a.wrapping_mul(b),
            SOp::And => a & b,
            SOp::Or => a | b,
            SOp::Xor => a ^ b,
            SOp::Min => a.min(b),
            SOp::Max => a.max(b),
        }
    }
}

/// A SIMD machine of one flavour, traced or native.
pub trait Machine {
    /// Vector lanes.
    const LANES: usize;
    /// The flavour.
    const FLAVOUR: FlavourId;
    /// f32 vector.
    type F: Copy + Debug;
    /// i32 vector.
    type I: Copy + Debug;
    /// Lane mask.
    type K: Copy + Debug;
    /// Scalar integer.
    type S: Int;
    /// Scalar f32.
    type X: Float;
    /// A buffer opened for a run of scalar stores ([`Machine::open`]).
    type Open<'b>;

    // ---- memory, regions, annotations ----

    /// The address space; register every buffer a kernel touches here.
    fn space(&mut self) -> &mut AddrSpace;
    /// Mark the code region of the ops that follow.
    fn region(&mut self, r: Region);
    /// Annotate which lanes hold useful work for the ops that follow (for the
    /// SIMD utilisation statistic only; no op, no effect on results). `None`: all.
    fn active(&mut self, k: Option<Self::K>);

    // ---- constants (free) ----

    /// All lanes `x`.
    fn splat(&mut self, x: f32) -> Self::F;
    /// A constant vector (`v.len() == LANES`).
    fn consts(&mut self, v: &[f32]) -> Self::F;
    /// All lanes `x`.
    fn splat_i(&mut self, x: i32) -> Self::I;
    /// A constant vector (`v.len() == LANES`).
    fn consts_i(&mut self, v: &[i32]) -> Self::I;
    /// A constant mask (bit i = lane i).
    fn mask(&mut self, bits: u32) -> Self::K;
    /// A scalar integer constant (an immediate).
    fn int(&mut self, v: i64) -> Self::S;
    /// A scalar f32 constant.
    fn float(&mut self, v: f32) -> Self::X;

    // ---- f32 vector arithmetic ----

    /// `a op b`.
    fn bin(&mut self, op: BinOp, a: Self::F, b: Self::F) -> Self::F;
    /// `k ? a op b : src`: one masked op with mask registers, op + blend without.
    fn masked(&mut self, op: BinOp, k: Self::K, src: Self::F, a: Self::F, b: Self::F) -> Self::F;
    /// Fused multiply-add family (mul then add on flavours without FMA).
    fn fma(&mut self, kind: Fma, a: Self::F, b: Self::F, c: Self::F) -> Self::F;
    /// `k ? fma(a, b, c) : c` (the accumulator form, vfmadd231ps{k}).
    fn masked_fma(&mut self, kind: Fma, k: Self::K, a: Self::F, b: Self::F, c: Self::F) -> Self::F;
    /// |a| (andps with a constant).
    fn abs(&mut self, a: Self::F) -> Self::F;
    /// -a (xorps with a constant).
    fn neg(&mut self, a: Self::F) -> Self::F;
    /// Square root.
    fn sqrt(&mut self, a: Self::F) -> Self::F;
    /// Exact 1/a (a divide).
    fn rcp(&mut self, a: Self::F) -> Self::F;
    /// Approximate 1/a at the flavour's precision.
    fn rcp_approx(&mut self, a: Self::F) -> Self::F;
    /// Exact 1/sqrt(a) (sqrt then divide).
    fn rsqrt(&mut self, a: Self::F) -> Self::F;
    /// Approximate 1/sqrt(a) at the flavour's precision.
    fn rsqrt_approx(&mut self, a: Self::F) -> Self::F;
    /// Compare into a mask.
    fn cmp(&mut self, p: Cmp, a: Self::F, b: Self::F) -> Self::K;
    /// `k ? t : f` (vblendvps, or a masked move with mask registers).
    fn select(&mut self, k: Self::K, t: Self::F, f: Self::F) -> Self::F;
    /// Per lane `b` where `s`'s sign bit is set, else `a` (AVX2 and SSE4
    /// `blendvps`: one op; flavours with mask registers move the sign bits
    /// to a mask first).
    fn blend_sign(&mut self, s: Self::F, a: Self::F, b: Self::F) -> Self::F;
    /// Bitwise op.
    fn logic(&mut self, op: Logic, a: Self::F, b: Self::F) -> Self::F;
    /// Broadcast a scalar to all lanes.
    fn broadcast(&mut self, x: Self::X) -> Self::F;
    /// Lane `i` as a scalar (lane 0 is free).
    fn extract(&mut self, a: Self::F, i: usize) -> Self::X;
    /// `r[i] = a[idx[i]]`.
    fn permute(&mut self, a: Self::F, idx: &[u8]) -> Self::F;
    /// `r[i] = (a ++ b)[idx[i]]`, idx < 2 * LANES.
    fn shuffle2(&mut self, a: Self::F, b: Self::F, idx: &[u8]) -> Self::F;
    /// Horizontal reduction (Add, Min or Max) by the halving tree.
    fn reduce(&mut self, op: BinOp, a: Self::F) -> Self::X;
    /// Convert to i32, truncating (cvttps2dq).
    fn to_int(&mut self, a: Self::F) -> Self::I;
    /// Convert to i32, round to nearest even (cvtps2dq).
    fn to_int_round(&mut self, a: Self::F) -> Self::I;
    /// Convert i32 to f32.
    fn to_float(&mut self, a: Self::I) -> Self::F;
    /// Reinterpret f32 bits as i32 (free).
    fn bits_to_i(&mut self, a: Self::F) -> Self::I;
    /// Reinterpret i32 bits as f32 (free).
    fn bits_to_f(&mut self, a: Self::I) -> Self::F;

    // ---- i32 vector ----

    /// `a op b`.
    fn iop(&mut self, op: IOp, a: Self::I, b: Self::I) -> Self::I;
    /// Shift by an immediate.
    fn ishift(&mut self, s: Shift, a: Self::I, n: u32) -> Self::I;
    /// Signed compare (Eq, Ne, Lt, Le, Gt, Ge) into a mask.
    fn icmp(&mut self, p: Cmp, a: Self::I, b: Self::I) -> Self::K;
    /// `k ? t : f`.
    fn iselect(&mut self, k: Self::K, t: Self::I, f: Self::I) -> Self::I;
    /// `k ? a : 0` (`andps` with a compare's mask on SSE/AVX, a zero-masking
    /// move on mask-register ISAs): one op, where a select is a blend.
    fn keep(&mut self, k: Self::K, a: Self::F) -> Self::F;
    /// `k ? a : 0` on integer lanes (`pand` with a mask; zero-masking move).
    fn keep_i(&mut self, k: Self::K, a: Self::I) -> Self::I;

    // ---- masks ----

    /// Mask logic.
    fn klogic(&mut self, op: Logic, a: Self::K, b: Self::K) -> Self::K;
    /// !a.
    fn knot(&mut self, a: Self::K) -> Self::K;
    /// Bits of the mask in a scalar (movmskps, kmovw).
    fn movemask(&mut self, k: Self::K) -> Self::S;
    /// A mask from the low LANES bits of a scalar: one move with mask
    /// registers (LRBni, AVX-512 `kmovw k, r32`); without them a broadcast,
    /// an and with each lane's bit and a compare.
    fn kmov(&mut self, bits: Self::S) -> Self::K;
    /// Number of active lanes.
    fn popcnt(&mut self, k: Self::K) -> Self::S;
    /// Lowest active lane, or LANES if none.
    fn bitscan(&mut self, k: Self::K) -> Self::S;
    /// 1 if any lane is active, else 0 (vtestps, kortestw).
    fn any(&mut self, k: Self::K) -> Self::S;
    /// 1 if every lane is active, else 0.
    fn all(&mut self, k: Self::K) -> Self::S;

    // ---- vector memory ----

    /// Aligned load of LANES f32 (the address must be LANES*4-aligned).
    fn load(&mut self, buf: &Buf, at: At<Self::S>) -> Self::F;
    /// Unaligned load.
    fn loadu(&mut self, buf: &Buf, at: At<Self::S>) -> Self::F;
    /// Load one f32 into every lane (vbroadcastss m, {1to16}).
    fn load_bcast(&mut self, buf: &Buf, at: At<Self::S>) -> Self::F;
    /// Load `n` f32 and repeat them across the lanes (n = 4: vbroadcastf128, {4to16}).
    fn load_repeat(&mut self, buf: &Buf, at: At<Self::S>, n: usize) -> Self::F;
    /// A memory operand of the next op: `n` floats at `at` repeated across
    /// the lanes (1: a broadcast, LANES: a full vector). Folded into the op
    /// that reads it where the flavour allows (recorded as `vloadfold`, which
    /// the machine prices: no issue slot on Larrabee, a micro-fused uop on
    /// Haswell), else a separate load as [`Machine::load_repeat`]. For
    /// operands read by one op only.
    #[inline(always)]
    fn load_operand(&mut self, buf: &Buf, at: At<Self::S>, n: usize) -> Self::F {
        self.load_repeat(buf, at, n)
    }
    /// `k ? mem : src` (vmaskmovps; load + blend on SSE4).
    fn load_masked(&mut self, k: Self::K, src: Self::F, buf: &Buf, at: At<Self::S>) -> Self::F;
    /// Aligned store.
    fn store(&mut self, buf: &mut Buf, at: At<Self::S>, v: Self::F);
    /// Unaligned store.
    fn storeu(&mut self, buf: &mut Buf, at: At<Self::S>, v: Self::F);
    /// Store active lanes only.
    fn store_masked(&mut self, k: Self::K, buf: &mut Buf, at: At<Self::S>, v: Self::F);
    /// `r[i] = k[i] ? f32 at (at + idx[i] * scale) : src[i]`.
    fn gather(
        &mut self,
        k: Self::K,
        src: Self::F,
        buf: &Buf,
        at: At<Self::S>,
        idx: Self::I,
        scale: u8,
    ) -> Self::F;
    /// Store active lanes of `v` to `at + idx[i] * scale` (in lane order).
    fn scatter(
        &mut self,
        k: Self::K,
        buf: &mut Buf,
        at: At<Self::S>,
        idx: Self::I,
        scale: u8,
        v: Self::F,
    );
    /// Store the active lanes of `v` contiguously at `at`; returns how many.
    /// Without compress-store, full LANES*4 bytes are written (the real idiom's
    /// store), the tail beyond the count holding unspecified lanes.
    fn compress_store(&mut self, k: Self::K, buf: &mut Buf, at: At<Self::S>, v: Self::F)
        -> Self::S;

    // ---- scalar integer ----

    /// `a op b`.
    fn s_op(&mut self, op: SOp, a: Self::S, b: Self::S) -> Self::S;
    /// Shift by an immediate.
    fn s_shift(&mut self, s: Shift, a: Self::S, n: u32) -> Self::S;
    /// 1 if `a p b` (signed) else 0.
    fn s_cmp(&mut self, p: Cmp, a: Self::S, b: Self::S) -> Self::S;
    /// `c != 0 ? a : b` (cmov).
    fn s_select(&mut self, c: Self::S, a: Self::S, b: Self::S) -> Self::S;
    /// Population count.
    fn s_popcnt(&mut self, a: Self::S) -> Self::S;
    /// Trailing zero count (64 for 0).
    fn s_tzcnt(&mut self, a: Self::S) -> Self::S;
    /// Load an integer of `width` bytes (1, 2, 4, 8), zero- or sign-extended.
    fn s_load(&mut self, buf: &Buf, at: At<Self::S>, width: u8, signed: bool) -> Self::S;
    /// Store the low `width` bytes.
    fn s_store(&mut self, buf: &mut Buf, at: At<Self::S>, width: u8, v: Self::S);
    /// `buf` opened for a run of [`Machine::s_store_open`]s, as a
    /// hand-written loop keeps a buffer's pointer and end in registers (no
    /// op: the traced backend records the stores alone).
    fn open<'b>(&mut self, buf: &'b mut Buf) -> Self::Open<'b>;
    /// [`Machine::s_store`] into an opened buffer: the same op, the same
    /// bytes.
    fn s_store_open(&mut self, buf: &mut Self::Open<'_>, at: At<Self::S>, width: u8, v: Self::S);

    // ---- scalar f32 (SSE scalar ops; timed as their vector class, one lane) ----

    /// `a op b`.
    fn x_op(&mut self, op: BinOp, a: Self::X, b: Self::X) -> Self::X;
    /// Fused multiply-add family.
    fn x_fma(&mut self, kind: Fma, a: Self::X, b: Self::X, c: Self::X) -> Self::X;
    /// Square root.
    fn x_sqrt(&mut self, a: Self::X) -> Self::X;
    /// 1 if `a p b` else 0 (ucomiss + setcc).
    fn x_cmp(&mut self, p: Cmp, a: Self::X, b: Self::X) -> Self::S;
    /// Load an f32.
    fn x_load(&mut self, buf: &Buf, at: At<Self::S>) -> Self::X;
    /// Store an f32.
    fn x_store(&mut self, buf: &mut Buf, at: At<Self::S>, v: Self::X);
    /// The integer as an f32 (cvtsi2ss).
    fn x_from_int(&mut self, a: Self::S) -> Self::X;
    /// The f32 truncated toward zero to an integer (cvttss2si; saturating
    /// here, where the hardware returns the "integer indefinite").
    fn x_to_int(&mut self, a: Self::X) -> Self::S;

    // ---- control ----

    /// A conditional branch at `site`, taken when `c != 0`; returns whether taken.
    fn branch(&mut self, site: Site, c: Self::S) -> bool;

    // ---- host views (record nothing) ----

    /// Lane `i` of a float vector.
    fn lane(&self, a: Self::F, i: usize) -> f32;
    /// Lane `i` of an int vector.
    fn lane_i(&self, a: Self::I, i: usize) -> i32;
    /// Bits of a mask.
    fn bits(&self, k: Self::K) -> u32;

    // ---- conveniences (provided) ----

    /// a + b
    #[inline(always)]
    fn add(&mut self, a: Self::F, b: Self::F) -> Self::F {
        self.bin(BinOp::Add, a, b)
    }
    /// a - b
    #[inline(always)]
    fn sub(&mut self, a: Self::F, b: Self::F) -> Self::F {
        self.bin(BinOp::Sub, a, b)
    }
    /// a * b
    #[inline(always)]
    fn mul(&mut self, a: Self::F, b: Self::F) -> Self::F {
        self.bin(BinOp::Mul, a, b)
    }
    /// a / b
    #[inline(always)]
    fn div(&mut self, a: Self::F, b: Self::F) -> Self::F {
        self.bin(BinOp::Div, a, b)
    }
    /// x86 min
    #[inline(always)]
    fn min(&mut self, a: Self::F, b: Self::F) -> Self::F {
        self.bin(BinOp::Min, a, b)
    }
    /// x86 max
    #[inline(always)]
    fn max(&mut self, a: Self::F, b: Self::F) -> Self::F {
        self.bin(BinOp::Max, a, b)
    }
    /// a * b + c
    #[inline(always)]
    fn fmadd(&mut self, a: Self::F, b: Self::F, c: Self::F) -> Self::F {
        self.fma(Fma::MAdd, a, b, c)
    }
    /// a * b - c
    #[inline(always)]
    fn fmsub(&mut self, a: Self::F, b: Self::F, c: Self::F) -> Self::F {
        self.fma(Fma::MSub, a, b, c)
    }
    /// -(a * b) + c
    #[inline(always)]
    fn fnmadd(&mut self, a: Self::F, b: Self::F, c: Self::F) -> Self::F {
        self.fma(Fma::NMAdd, a, b, c)
    }
    /// -(a * b) - c
    #[inline(always)]
    fn fnmsub(&mut self, a: Self::F, b: Self::F, c: Self::F) -> Self::F {
        self.fma(Fma::NMSub, a, b, c)
    }
    /// a & b
    #[inline(always)]
    fn and(&mut self, a: Self::F, b: Self::F) -> Self::F {
        self.logic(Logic::And, a, b)
    }
    /// a | b
    #[inline(always)]
    fn or(&mut self, a: Self::F, b: Self::F) -> Self::F {
        self.logic(Logic::Or, a, b)
    }
    /// a ^ b
    #[inline(always)]
    fn xor(&mut self, a: Self::F, b: Self::F) -> Self::F {
        self.logic(Logic::Xor, a, b)
    }
    /// !a & b
    #[inline(always)]
    fn andnot(&mut self, a: Self::F, b: Self::F) -> Self::F {
        self.logic(Logic::AndNot, a, b)
    }
    /// Horizontal min.
    #[inline(always)]
    fn hmin(&mut self, a: Self::F) -> Self::X {
        self.reduce(BinOp::Min, a)
    }
    /// Horizontal max.
    #[inline(always)]
    fn hmax(&mut self, a: Self::F) -> Self::X {
        self.reduce(BinOp::Max, a)
    }
    /// Horizontal sum.
    #[inline(always)]
    fn hsum(&mut self, a: Self::F) -> Self::X {
        self.reduce(BinOp::Add, a)
    }
    /// a & b (masks)
    #[inline(always)]
    fn kand(&mut self, a: Self::K, b: Self::K) -> Self::K {
        self.klogic(Logic::And, a, b)
    }
    /// a | b (masks)
    #[inline(always)]
    fn kor(&mut self, a: Self::K, b: Self::K) -> Self::K {
        self.klogic(Logic::Or, a, b)
    }
    /// a + b
    #[inline(always)]
    fn s_add(&mut self, a: Self::S, b: Self::S) -> Self::S {
        self.s_op(SOp::Add, a, b)
    }
    /// a - b
    #[inline(always)]
    fn s_sub(&mut self, a: Self::S, b: Self::S) -> Self::S {
        self.s_op(SOp::Sub, a, b)
    }
    /// a & b
    #[inline(always)]
    fn s_and(&mut self, a: Self::S, b: Self::S) -> Self::S {
        self.s_op(SOp::And, a, b)
    }
    /// a + imm
    #[inline(always)]
    fn s_addi(&mut self, a: Self::S, imm: i64) -> Self::S {
        let b = self.int(imm);
        self.s_op(SOp::Add, a, b)
    }
    /// Branch if `a p b`, compare and jump (macro-fused on x86).
    #[inline(always)]
    fn branch_if(&mut self, site: Site, p: Cmp, a: Self::S, b: Self::S) -> bool {
        let c = self.s_cmp(p, a, b);
        self.branch(site, c)
    }
}
