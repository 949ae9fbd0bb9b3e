//! The host's SIMD instructions for the native backend's vector ops: each
//! op on `N` lanes as `std::arch` intrinsics where the binary is built with
//! the instruction set — AVX-512 (F + DQ) on 16-lane chunks (16 and 32
//! lanes), else AVX2 (+ FMA for the fused forms) on 8-lane chunks (16 and 32
//! lanes are two or four chunks), SSE4.1 on 4 lanes — and `None`
//! elsewhere, where the caller runs the portable lane loop of [`crate::lanes`].
//!
//! Every function computes exactly what the lane loop computes (the
//! semantics in [`crate::lanes`]: x86's own min/max, truncating and
//! round-to-nearest-even conversions, shift counts of 32 or more), so
//! results stay bit-identical to the traced backend's; the property test in
//! `isa/tests` holds native against traced on every flavour. Masks come out
//! canonical (-1 or 0 per lane), as the lane loop makes them.
//!
//! Chosen when building (`target_feature` cfgs), not at run time:
//! `ARCHITECTURE.md` says why. Gathers, scatters, compresses, reductions and
//! masked memory ops stay lane loops (their lanes go through the buffer's
//! checked offsets one by one).

// Without AVX2 the 8-lane bodies compile away and leave their operands unused.
#![cfg_attr(
    not(all(target_arch = "x86_64", target_feature = "avx2")),
    allow(unused_variables)
)]

use crate::lanes::{BinOp, Cmp, Fma, IOp, Shift, Vf, Vi, Vk};
use crate::machine::Logic;

/// Run `$body` with `$w` bound to the module of the widest instruction set
/// that divides `$n` lanes, or give `None`.
macro_rules! simd {
    ($n:expr, |$w:ident| $body:expr) => {{
        #[cfg(all(
            target_arch = "x86_64",
            target_feature = "avx512f",
            target_feature = "avx512dq"
        ))]
        if $n.is_multiple_of(16) {
            #[allow(unused_imports)]
            use self::avx512 as $w;
            // SAFETY: the binary is built with AVX-512F and DQ (the cfg
            // above); every access is within the lane arrays.
            #[allow(unused_unsafe)]
            return Some(unsafe { $body });
        }
        #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
        if $n.is_multiple_of(8) {
            #[allow(unused_imports)]
            use self::avx2 as $w;
            // SAFETY: the binary is built with AVX2 (the cfg above); every
            // access is within the lane arrays, whose chunks are aligned.
            #[allow(unused_unsafe)]
            return Some(unsafe { $body });
        }
        #[cfg(all(target_arch = "x86_64", target_feature = "sse4.1"))]
        if $n == 4 {
            #[allow(unused_imports)]
            use self::sse41 as $w;
            // SAFETY: as above, with SSE4.1.
            #[allow(unused_unsafe)]
            return Some(unsafe { $body });
        }
        None
    }};
}

/// Whether this binary runs the vector ops of `N` lanes as `std::arch`
/// intrinsics (true) or as the portable lane loop.
#[must_use]
pub fn intrinsics_for(n: usize) -> bool {
    let avx2 = cfg!(all(target_arch = "x86_64", target_feature = "avx2"));
    let sse41 = cfg!(all(target_arch = "x86_64", target_feature = "sse4.1"));
    (avx512() && n.is_multiple_of(16)) || (avx2 && n.is_multiple_of(8)) || (sse41 && n == 4)
}

/// Whether this binary is built with AVX-512 F and DQ (16-lane chunks).
const fn avx512() -> bool {
    cfg!(all(
        target_arch = "x86_64",
        target_feature = "avx512f",
        target_feature = "avx512dq"
    ))
}

/// How this binary runs the vector ops of `n` lanes, for reports.
#[must_use]
pub fn describe(n: usize) -> &'static str {
    let fma = cfg!(target_feature = "fma");
    if avx512() && n.is_multiple_of(16) {
        return "std::arch AVX-512 intrinsics on 16-lane chunks";
    }
    match (intrinsics_for(n), n.is_multiple_of(8), fma) {
        (true, true, true) => "std::arch AVX2 + FMA intrinsics on 8-lane chunks",
        (true, true, false) => {
            "std::arch AVX2 intrinsics on 8-lane chunks (fused forms as lane loops)"
        }
        (true, false, true) => "std::arch SSE4.1 + FMA intrinsics",
        (true, false, false) => "std::arch SSE4.1 intrinsics (fused forms as lane loops)",
        _ => "portable lane loops (this binary has no SIMD instruction set for this width)",
    }
}

/// `op` lane-wise (Div is the IEEE divide: callers with an approximate
/// divide do not come here).
#[inline(always)]
#[must_use]
pub fn bin<const N: usize>(op: BinOp, a: Vf<N>, b: Vf<N>) -> Option<Vf<N>> {
    simd!(N, |w| w::ff(&a, &b, |x, y| match op {
        BinOp::Add => w::add(x, y),
        BinOp::Sub => w::sub(x, y),
        BinOp::Mul => w::mul(x, y),
        BinOp::Div => w::div(x, y),
        BinOp::Min => w::min(x, y),
        BinOp::Max => w::max(x, y),
    }))
}

/// `kind` lane-wise, fused (one rounding) or as a multiply then an add.
#[inline(always)]
#[must_use]
pub fn fma<const N: usize>(kind: Fma, fused: bool, a: Vf<N>, b: Vf<N>, c: Vf<N>) -> Option<Vf<N>> {
    if fused && !cfg!(target_feature = "fma") {
        return None;
    }
    simd!(N, |w| w::fff(&a, &b, &c, |x, y, z| {
        if fused {
            w::fused(kind, x, y, z)
        } else {
            let p = w::mul(x, y);
            match kind {
                Fma::MAdd => w::add(p, z),
                Fma::MSub => w::sub(p, z),
                Fma::NMAdd => w::sub(z, p),
                Fma::NMSub => w::sub(w::neg(p), z),
            }
        }
    }))
}

/// A unary float op lane-wise.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Unary {
    /// clear the sign bit
    Abs,
    /// flip the sign bit
    Neg,
    /// IEEE square root
    Sqrt,
    /// 1 / x (IEEE divide)
    Rcp,
    /// 1 / sqrt(x), two roundings
    Rsqrt,
}

/// `op` lane-wise.
#[inline(always)]
#[must_use]
pub fn unary<const N: usize>(op: Unary, a: Vf<N>) -> Option<Vf<N>> {
    simd!(N, |w| w::f(&a, |x| match op {
        Unary::Abs => w::abs(x),
        Unary::Neg => w::neg(x),
        Unary::Sqrt => w::sqrt(x),
        Unary::Rcp => w::div(w::one(), x),
        Unary::Rsqrt => w::div(w::one(), w::sqrt(x)),
    }))
}

/// Keep the top `bits` of each lane's mantissa ([`crate::lanes::truncate_mantissa`]).
#[inline(always)]
#[must_use]
pub fn truncate_mantissa<const N: usize>(a: Vf<N>, bits: u32) -> Option<Vf<N>> {
    if bits >= 23 {
        return Some(a);
    }
    let keep = !((1u32 << (23 - bits)) - 1) as i32;
    simd!(N, |w| w::f(&a, |x| w::and(x, w::splat_bits(keep))))
}

/// Compare lane-wise into a canonical mask.
#[inline(always)]
#[must_use]
pub fn cmp<const N: usize>(p: Cmp, a: Vf<N>, b: Vf<N>) -> Option<Vk<N>> {
    simd!(N, |w| w::fk(&a, &b, |x, y| w::cmp(p, x, y)))
}

/// Active lanes of `k` (sign bit set) from `t`, the others from `f`.
#[inline(always)]
#[must_use]
pub fn select<const N: usize>(k: Vk<N>, t: Vf<N>, f: Vf<N>) -> Option<Vf<N>> {
    simd!(N, |w| w::kff(&k, &f, &t, |m, x, y| w::blend(x, y, m)))
}

/// [`select`] on int lanes.
#[inline(always)]
#[must_use]
pub fn select_i<const N: usize>(k: Vk<N>, t: Vi<N>, f: Vi<N>) -> Option<Vi<N>> {
    simd!(N, |w| w::kii(&k, &f, &t, |m, x, y| w::iblend(x, y, m)))
}

/// Lanes of `a` where the sign of `s` is clear, of `b` where it is set.
#[inline(always)]
#[must_use]
pub fn blend_sign<const N: usize>(s: Vf<N>, a: Vf<N>, b: Vf<N>) -> Option<Vf<N>> {
    simd!(N, |w| w::fff(&a, &b, &s, |x, y, z| w::blend(x, y, z)))
}

/// Bitwise `op` on float lanes.
#[inline(always)]
#[must_use]
pub fn logic<const N: usize>(op: Logic, a: Vf<N>, b: Vf<N>) -> Option<Vf<N>> {
    simd!(N, |w| w::ff(&a, &b, |x, y| w::logic(op, x, y)))
}

/// A float-to-int conversion lane-wise.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ToInt {
    /// cvttps2dq
    Trunc,
    /// cvtps2dq (round to nearest even: the MXCSR default)
    Round,
}

/// Convert floats to ints (`i32::MIN` for NaN and out of range).
#[inline(always)]
#[must_use]
pub fn to_int<const N: usize>(how: ToInt, a: Vf<N>) -> Option<Vi<N>> {
    simd!(N, |w| w::fi(&a, |x| match how {
        ToInt::Trunc => w::cvtt(x),
        ToInt::Round => w::cvt(x),
    }))
}

/// Convert ints to floats (round to nearest even).
#[inline(always)]
#[must_use]
pub fn to_float<const N: usize>(a: Vi<N>) -> Option<Vf<N>> {
    simd!(N, |w| w::if_(&a, |x| w::cvtdq(x)))
}

/// Integer `op` lane-wise.
#[inline(always)]
#[must_use]
pub fn iop<const N: usize>(op: IOp, a: Vi<N>, b: Vi<N>) -> Option<Vi<N>> {
    simd!(N, |w| w::ii(&a, &b, |x, y| w::iop(op, x, y)))
}

/// Integer shift by `n` lane-wise (counts of 32 or more saturate).
#[inline(always)]
#[must_use]
pub fn ishift<const N: usize>(s: Shift, a: Vi<N>, n: u32) -> Option<Vi<N>> {
    simd!(N, |w| w::ii(&a, &a, |x, _| w::shift(s, x, n)))
}

/// Signed integer compare lane-wise into a canonical mask.
#[inline(always)]
#[must_use]
pub fn icmp<const N: usize>(p: Cmp, a: Vi<N>, b: Vi<N>) -> Option<Vk<N>> {
    simd!(N, |w| w::ik(&a, &b, |x, y| w::icmp(p, x, y)))
}

/// Mask logic on the sign bits, canonical result.
#[inline(always)]
#[must_use]
pub fn klogic<const N: usize>(op: Logic, a: Vk<N>, b: Vk<N>) -> Option<Vk<N>> {
    simd!(N, |w| w::kk(&a, &b, |x, y| w::canon(w::ilogic(op, x, y))))
}

/// Mask with every sign bit flipped, canonical.
#[inline(always)]
#[must_use]
pub fn knot<const N: usize>(a: Vk<N>) -> Option<Vk<N>> {
    simd!(N, |w| w::kk(&a, &a, |x, _| w::canon(w::inot(x))))
}

/// Bit i = sign of lane i (movmskps per chunk).
#[inline(always)]
#[must_use]
pub fn mask_bits<const N: usize>(k: Vk<N>) -> Option<u32> {
    simd!(N, |w| w::movemask(&k))
}

/// Generates a width module: the same functions over `$v`/`$vi` vectors of
/// `$w` lanes, so the ops above are written once. Defined only where a
/// width module is (every one needs SSE4.1 at least).
#[cfg(all(target_arch = "x86_64", target_feature = "sse4.1"))]
macro_rules! chunk_helpers {
    ($w:expr, $v:ty, $vi:ty, $ldf:ident, $stf:ident, $ldi:ident, $sti:ident) => {
        /// Lanes per chunk.
        pub const W: usize = $w;

        /// Chunk `c` of a float array.
        #[inline(always)]
        pub unsafe fn lf<const N: usize>(a: &Vf<N>, c: usize) -> $v {
            $ldf(a.0.as_ptr().add(W * c))
        }
        /// Chunk `c` of an int array.
        #[inline(always)]
        pub unsafe fn li<const N: usize>(a: &Vi<N>, c: usize) -> $vi {
            $ldi(a.0.as_ptr().add(W * c) as *const _)
        }
        /// Chunk `c` of a mask as floats (for blends).
        #[inline(always)]
        pub unsafe fn kf<const N: usize>(a: &Vk<N>, c: usize) -> $v {
            $ldf(a.0.as_ptr().add(W * c) as *const f32)
        }
        /// Chunk `c` of a mask as ints.
        #[inline(always)]
        pub unsafe fn ki<const N: usize>(a: &Vk<N>, c: usize) -> $vi {
            $ldi(a.0.as_ptr().add(W * c) as *const _)
        }
        /// Float lanes from float lanes.
        #[inline(always)]
        pub unsafe fn f<const N: usize>(a: &Vf<N>, op: impl Fn($v) -> $v) -> Vf<N> {
            let mut r = Vf([0.0; N]);
            for c in 0..N / W {
                $stf(r.0.as_mut_ptr().add(W * c), op(lf(a, c)));
            }
            r
        }
        /// Float lanes from two float arrays.
        #[inline(always)]
        pub unsafe fn ff<const N: usize>(a: &Vf<N>, b: &Vf<N>, op: impl Fn($v, $v) -> $v) -> Vf<N> {
            let mut r = Vf([0.0; N]);
            for c in 0..N / W {
                $stf(r.0.as_mut_ptr().add(W * c), op(lf(a, c), lf(b, c)));
            }
            r
        }
        /// Float lanes from three float arrays.
        #[inline(always)]
        pub unsafe fn fff<const N: usize>(
            a: &Vf<N>,
            b: &Vf<N>,
            d: &Vf<N>,
            op: impl Fn($v, $v, $v) -> $v,
        ) -> Vf<N> {
            let mut r = Vf([0.0; N]);
            for c in 0..N / W {
                let x = op(lf(a, c), lf(b, c), lf(d, c));
                $stf(r.0.as_mut_ptr().add(W * c), x);
            }
            r
        }
        /// Float lanes from a mask and two float arrays.
        #[inline(always)]
        pub unsafe fn kff<const N: usize>(
            k: &Vk<N>,
            a: &Vf<N>,
            b: &Vf<N>,
            op: impl Fn($v, $v, $v) -> $v,
        ) -> Vf<N> {
            let mut r = Vf([0.0; N]);
            for c in 0..N / W {
                let x = op(kf(k, c), lf(a, c), lf(b, c));
                $stf(r.0.as_mut_ptr().add(W * c), x);
            }
            r
        }
        /// Int lanes from a mask and two int arrays.
        #[inline(always)]
        pub unsafe fn kii<const N: usize>(
            k: &Vk<N>,
            a: &Vi<N>,
            b: &Vi<N>,
            op: impl Fn($vi, $vi, $vi) -> $vi,
        ) -> Vi<N> {
            let mut r = Vi([0; N]);
            for c in 0..N / W {
                let x = op(ki(k, c), li(a, c), li(b, c));
                $sti(r.0.as_mut_ptr().add(W * c) as *mut _, x);
            }
            r
        }
        /// A mask from two float arrays.
        #[inline(always)]
        pub unsafe fn fk<const N: usize>(a: &Vf<N>, b: &Vf<N>, op: impl Fn($v, $v) -> $v) -> Vk<N> {
            let mut r = Vk([0; N]);
            for c in 0..N / W {
                $stf(
                    r.0.as_mut_ptr().add(W * c) as *mut f32,
                    op(lf(a, c), lf(b, c)),
                );
            }
            r
        }
        /// Int lanes from float lanes.
        #[inline(always)]
        pub unsafe fn fi<const N: usize>(a: &Vf<N>, op: impl Fn($v) -> $vi) -> Vi<N> {
            let mut r = Vi([0; N]);
            for c in 0..N / W {
                $sti(r.0.as_mut_ptr().add(W * c) as *mut _, op(lf(a, c)));
            }
            r
        }
        /// Float lanes from int lanes.
        #[inline(always)]
        pub unsafe fn if_<const N: usize>(a: &Vi<N>, op: impl Fn($vi) -> $v) -> Vf<N> {
            let mut r = Vf([0.0; N]);
            for c in 0..N / W {
                $stf(r.0.as_mut_ptr().add(W * c), op(li(a, c)));
            }
            r
        }
        /// Int lanes from two int arrays.
        #[inline(always)]
        pub unsafe fn ii<const N: usize>(
            a: &Vi<N>,
            b: &Vi<N>,
            op: impl Fn($vi, $vi) -> $vi,
        ) -> Vi<N> {
            let mut r = Vi([0; N]);
            for c in 0..N / W {
                $sti(
                    r.0.as_mut_ptr().add(W * c) as *mut _,
                    op(li(a, c), li(b, c)),
                );
            }
            r
        }
        /// A mask from two int arrays.
        #[inline(always)]
        pub unsafe fn ik<const N: usize>(
            a: &Vi<N>,
            b: &Vi<N>,
            op: impl Fn($vi, $vi) -> $vi,
        ) -> Vk<N> {
            let mut r = Vk([0; N]);
            for c in 0..N / W {
                $sti(
                    r.0.as_mut_ptr().add(W * c) as *mut _,
                    op(li(a, c), li(b, c)),
                );
            }
            r
        }
        /// A mask from two masks.
        #[inline(always)]
        pub unsafe fn kk<const N: usize>(
            a: &Vk<N>,
            b: &Vk<N>,
            op: impl Fn($vi, $vi) -> $vi,
        ) -> Vk<N> {
            let mut r = Vk([0; N]);
            for c in 0..N / W {
                $sti(
                    r.0.as_mut_ptr().add(W * c) as *mut _,
                    op(ki(a, c), ki(b, c)),
                );
            }
            r
        }
    };
}

/// AVX2 (+ FMA) on 8-lane chunks.
#[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
mod avx2 {
    use super::*;
    use std::arch::x86_64::*;

    chunk_helpers!(
        8,
        __m256,
        __m256i,
        _mm256_load_ps,
        _mm256_store_ps,
        _mm256_load_si256,
        _mm256_store_si256
    );

    #[inline(always)]
    pub unsafe fn add(a: __m256, b: __m256) -> __m256 {
        _mm256_add_ps(a, b)
    }
    #[inline(always)]
    pub unsafe fn sub(a: __m256, b: __m256) -> __m256 {
        _mm256_sub_ps(a, b)
    }
    #[inline(always)]
    pub unsafe fn mul(a: __m256, b: __m256) -> __m256 {
        _mm256_mul_ps(a, b)
    }
    #[inline(always)]
    pub unsafe fn div(a: __m256, b: __m256) -> __m256 {
        _mm256_div_ps(a, b)
    }
    #[inline(always)]
    pub unsafe fn min(a: __m256, b: __m256) -> __m256 {
        _mm256_min_ps(a, b)
    }
    #[inline(always)]
    pub unsafe fn max(a: __m256, b: __m256) -> __m256 {
        _mm256_max_ps(a, b)
    }
    #[inline(always)]
    pub unsafe fn sqrt(a: __m256) -> __m256 {
        _mm256_sqrt_ps(a)
    }
    #[inline(always)]
    pub unsafe fn one() -> __m256 {
        _mm256_set1_ps(1.0)
    }
    #[inline(always)]
    pub unsafe fn splat_bits(x: i32) -> __m256 {
        _mm256_castsi256_ps(_mm256_set1_epi32(x))
    }
    #[inline(always)]
    pub unsafe fn and(a: __m256, b: __m256) -> __m256 {
        _mm256_and_ps(a, b)
    }
    #[inline(always)]
    pub unsafe fn abs(a: __m256) -> __m256 {
        _mm256_and_ps(a, splat_bits(i32::MAX))
    }
    #[inline(always)]
    pub unsafe fn neg(a: __m256) -> __m256 {
        _mm256_xor_ps(a, splat_bits(i32::MIN))
    }
    /// The fused form of `kind` (the binary is built with FMA: callers check).
    #[inline(always)]
    pub unsafe fn fused(kind: Fma, a: __m256, b: __m256, c: __m256) -> __m256 {
        #[cfg(target_feature = "fma")]
        {
            match kind {
                Fma::MAdd => _mm256_fmadd_ps(a, b, c),
                Fma::MSub => _mm256_fmsub_ps(a, b, c),
                Fma::NMAdd => _mm256_fnmadd_ps(a, b, c),
                Fma::NMSub => _mm256_fnmsub_ps(a, b, c),
            }
        }
        #[cfg(not(target_feature = "fma"))]
        {
            let _ = (kind, a, b, c);
            unreachable!("fused multiply-add without FMA: the caller runs the lane loop")
        }
    }
    /// Take `b` where the sign of `m` is set, else `a`.
    #[inline(always)]
    pub unsafe fn blend(a: __m256, b: __m256, m: __m256) -> __m256 {
        _mm256_blendv_ps(a, b, m)
    }
    #[inline(always)]
    pub unsafe fn iblend(a: __m256i, b: __m256i, m: __m256i) -> __m256i {
        _mm256_castps_si256(_mm256_blendv_ps(
            _mm256_castsi256_ps(a),
            _mm256_castsi256_ps(b),
            _mm256_castsi256_ps(m),
        ))
    }
    #[inline(always)]
    pub unsafe fn logic(op: Logic, a: __m256, b: __m256) -> __m256 {
        match op {
            Logic::And => _mm256_and_ps(a, b),
            Logic::Or => _mm256_or_ps(a, b),
            Logic::Xor => _mm256_xor_ps(a, b),
            Logic::AndNot => _mm256_andnot_ps(a, b),
        }
    }
    #[inline(always)]
    pub unsafe fn cmp(p: Cmp, a: __m256, b: __m256) -> __m256 {
        match p {
            Cmp::Lt => _mm256_cmp_ps::<_CMP_LT_OQ>(a, b),
            Cmp::Le => _mm256_cmp_ps::<_CMP_LE_OQ>(a, b),
            Cmp::Gt => _mm256_cmp_ps::<_CMP_GT_OQ>(a, b),
            Cmp::Ge => _mm256_cmp_ps::<_CMP_GE_OQ>(a, b),
            Cmp::Eq => _mm256_cmp_ps::<_CMP_EQ_OQ>(a, b),
            Cmp::Ne => _mm256_cmp_ps::<_CMP_NEQ_UQ>(a, b),
            Cmp::Ord => _mm256_cmp_ps::<_CMP_ORD_Q>(a, b),
            Cmp::Unord => _mm256_cmp_ps::<_CMP_UNORD_Q>(a, b),
        }
    }
    #[inline(always)]
    pub unsafe fn cvtt(a: __m256) -> __m256i {
        _mm256_cvttps_epi32(a)
    }
    #[inline(always)]
    pub unsafe fn cvt(a: __m256) -> __m256i {
        _mm256_cvtps_epi32(a)
    }
    #[inline(always)]
    pub unsafe fn cvtdq(a: __m256i) -> __m256 {
        _mm256_cvtepi32_ps(a)
    }
    #[inline(always)]
    pub unsafe fn iop(op: IOp, a: __m256i, b: __m256i) -> __m256i {
        match op {
            IOp::Add => _mm256_add_epi32(a, b),
            IOp::Sub => _mm256_sub_epi32(a, b),
            IOp::Mul => _mm256_mullo_epi32(a, b),
            IOp::And => _mm256_and_si256(a, b),
            IOp::Or => _mm256_or_si256(a, b),
            IOp::Xor => _mm256_xor_si256(a, b),
            IOp::AndNot => _mm256_andnot_si256(a, b),
            IOp::Min => _mm256_min_epi32(a, b),
            IOp::Max => _mm256_max_epi32(a, b),
        }
    }
    #[inline(always)]
    pub unsafe fn ilogic(op: Logic, a: __m256i, b: __m256i) -> __m256i {
        match op {
            Logic::And => _mm256_and_si256(a, b),
            Logic::Or => _mm256_or_si256(a, b),
            Logic::Xor => _mm256_xor_si256(a, b),
            Logic::AndNot => _mm256_andnot_si256(a, b),
        }
    }
    #[inline(always)]
    pub unsafe fn inot(a: __m256i) -> __m256i {
        _mm256_xor_si256(a, _mm256_set1_epi32(-1))
    }
    /// -1 where the sign bit is set, else 0.
    #[inline(always)]
    pub unsafe fn canon(a: __m256i) -> __m256i {
        _mm256_srai_epi32::<31>(a)
    }
    #[inline(always)]
    pub unsafe fn shift(s: Shift, a: __m256i, n: u32) -> __m256i {
        let count = _mm_cvtsi32_si128(n as i32);
        match s {
            Shift::Shl => _mm256_sll_epi32(a, count),
            Shift::Shr => _mm256_srl_epi32(a, count),
            Shift::Sar => _mm256_sra_epi32(a, count),
        }
    }
    #[inline(always)]
    pub unsafe fn icmp(p: Cmp, a: __m256i, b: __m256i) -> __m256i {
        match p {
            Cmp::Lt => _mm256_cmpgt_epi32(b, a),
            Cmp::Le => inot(_mm256_cmpgt_epi32(a, b)),
            Cmp::Gt => _mm256_cmpgt_epi32(a, b),
            Cmp::Ge => inot(_mm256_cmpgt_epi32(b, a)),
            Cmp::Eq => _mm256_cmpeq_epi32(a, b),
            Cmp::Ne => inot(_mm256_cmpeq_epi32(a, b)),
            Cmp::Ord => _mm256_set1_epi32(-1),
            Cmp::Unord => _mm256_setzero_si256(),
        }
    }
    /// Bit i = sign of lane i, over every chunk.
    #[inline(always)]
    pub unsafe fn movemask<const N: usize>(k: &Vk<N>) -> u32 {
        let mut bits = 0u32;
        for c in 0..N / W {
            bits |= (_mm256_movemask_ps(kf(k, c)) as u32) << (W * c);
        }
        bits
    }
}

/// SSE4.1 on 4 lanes.
#[cfg(all(target_arch = "x86_64", target_feature = "sse4.1"))]
mod sse41 {
    use super::*;
    use std::arch::x86_64::*;

    chunk_helpers!(
        4,
        __m128,
        __m128i,
        _mm_load_ps,
        _mm_store_ps,
        _mm_load_si128,
        _mm_store_si128
    );

    #[inline(always)]
    pub unsafe fn add(a: __m128, b: __m128) -> __m128 {
        _mm_add_ps(a, b)
    }
    #[inline(always)]
    pub unsafe fn sub(a: __m128, b: __m128) -> __m128 {
        _mm_sub_ps(a, b)
    }
    #[inline(always)]
    pub unsafe fn mul(a: __m128, b: __m128) -> __m128 {
        _mm_mul_ps(a, b)
    }
    #[inline(always)]
    pub unsafe fn div(a: __m128, b: __m128) -> __m128 {
        _mm_div_ps(a, b)
    }
    #[inline(always)]
    pub unsafe fn min(a: __m128, b: __m128) -> __m128 {
        _mm_min_ps(a, b)
    }
    #[inline(always)]
    pub unsafe fn max(a: __m128, b: __m128) -> __m128 {
        _mm_max_ps(a, b)
    }
    #[inline(always)]
    pub unsafe fn sqrt(a: __m128) -> __m128 {
        _mm_sqrt_ps(a)
    }
    #[inline(always)]
    pub unsafe fn one() -> __m128 {
        _mm_set1_ps(1.0)
    }
    #[inline(always)]
    pub unsafe fn splat_bits(x: i32) -> __m128 {
        _mm_castsi128_ps(_mm_set1_epi32(x))
    }
    #[inline(always)]
    pub unsafe fn and(a: __m128, b: __m128) -> __m128 {
        _mm_and_ps(a, b)
    }
    #[inline(always)]
    pub unsafe fn abs(a: __m128) -> __m128 {
        _mm_and_ps(a, splat_bits(i32::MAX))
    }
    #[inline(always)]
    pub unsafe fn neg(a: __m128) -> __m128 {
        _mm_xor_ps(a, splat_bits(i32::MIN))
    }
    /// The fused form of `kind` (the binary is built with FMA: callers check).
    #[inline(always)]
    pub unsafe fn fused(kind: Fma, a: __m128, b: __m128, c: __m128) -> __m128 {
        #[cfg(target_feature = "fma")]
        {
            match kind {
                Fma::MAdd => _mm_fmadd_ps(a, b, c),
                Fma::MSub => _mm_fmsub_ps(a, b, c),
                Fma::NMAdd => _mm_fnmadd_ps(a, b, c),
                Fma::NMSub => _mm_fnmsub_ps(a, b, c),
            }
        }
        #[cfg(not(target_feature = "fma"))]
        {
            let _ = (kind, a, b, c);
            unreachable!("fused multiply-add without FMA: the caller runs the lane loop")
        }
    }
    /// Take `b` where the sign of `m` is set, else `a`.
    #[inline(always)]
    pub unsafe fn blend(a: __m128, b: __m128, m: __m128) -> __m128 {
        _mm_blendv_ps(a, b, m)
    }
    #[inline(always)]
    pub unsafe fn iblend(a: __m128i, b: __m128i, m: __m128i) -> __m128i {
        _mm_castps_si128(_mm_blendv_ps(
            _mm_castsi128_ps(a),
            _mm_castsi128_ps(b),
            _mm_castsi128_ps(m),
        ))
    }
    #[inline(always)]
    pub unsafe fn logic(op: Logic, a: __m128, b: __m128) -> __m128 {
        match op {
            Logic::And => _mm_and_ps(a, b),
            Logic::Or => _mm_or_ps(a, b),
            Logic::Xor => _mm_xor_ps(a, b),
            Logic::AndNot => _mm_andnot_ps(a, b),
        }
    }
    #[inline(always)]
    pub unsafe fn cmp(p: Cmp, a: __m128, b: __m128) -> __m128 {
        match p {
            Cmp::Lt => _mm_cmplt_ps(a, b),
            Cmp::Le => _mm_cmple_ps(a, b),
            Cmp::Gt => _mm_cmpgt_ps(a, b),
            Cmp::Ge => _mm_cmpge_ps(a, b),
            Cmp::Eq => _mm_cmpeq_ps(a, b),
            Cmp::Ne => _mm_cmpneq_ps(a, b),
            Cmp::Ord => _mm_cmpord_ps(a, b),
            Cmp::Unord => _mm_cmpunord_ps(a, b),
        }
    }
    #[inline(always)]
    pub unsafe fn cvtt(a: __m128) -> __m128i {
        _mm_cvttps_epi32(a)
    }
    #[inline(always)]
    pub unsafe fn cvt(a: __m128) -> __m128i {
        _mm_cvtps_epi32(a)
    }
    #[inline(always)]
    pub unsafe fn cvtdq(a: __m128i) -> __m128 {
        _mm_cvtepi32_ps(a)
    }
    #[inline(always)]
    pub unsafe fn iop(op: IOp, a: __m128i, b: __m128i) -> __m128i {
        match op {
            IOp::Add => _mm_add_epi32(a, b),
            IOp::Sub => _mm_sub_epi32(a, b),
            IOp::Mul => _mm_mullo_epi32(a, b),
            IOp::And => _mm_and_si128(a, b),
            IOp::Or => _mm_or_si128(a, b),
            IOp::Xor => _mm_xor_si128(a, b),
            IOp::AndNot => _mm_andnot_si128(a, b),
            IOp::Min => _mm_min_epi32(a, b),
            IOp::Max => _mm_max_epi32(a, b),
        }
    }
    #[inline(always)]
    pub unsafe fn ilogic(op: Logic, a: __m128i, b: __m128i) -> __m128i {
        match op {
            Logic::And => _mm_and_si128(a, b),
            Logic::Or => _mm_or_si128(a, b),
            Logic::Xor => _mm_xor_si128(a, b),
            Logic::AndNot => _mm_andnot_si128(a, b),
        }
    }
    #[inline(always)]
    pub unsafe fn inot(a: __m128i) -> __m128i {
        _mm_xor_si128(a, _mm_set1_epi32(-1))
    }
    /// -1 where the sign bit is set, else 0.
    #[inline(always)]
    pub unsafe fn canon(a: __m128i) -> __m128i {
        _mm_srai_epi32::<31>(a)
    }
    #[inline(always)]
    pub unsafe fn shift(s: Shift, a: __m128i, n: u32) -> __m128i {
        let count = _mm_cvtsi32_si128(n as i32);
        match s {
            Shift::Shl => _mm_sll_epi32(a, count),
            Shift::Shr => _mm_srl_epi32(a, count),
            Shift::Sar => _mm_sra_epi32(a, count),
        }
    }
    #[inline(always)]
    pub unsafe fn icmp(p: Cmp, a: __m128i, b: __m128i) -> __m128i {
        match p {
            Cmp::Lt => _mm_cmplt_epi32(a, b),
            Cmp::Le => inot(_mm_cmpgt_epi32(a, b)),
            Cmp::Gt => _mm_cmpgt_epi32(a, b),
            Cmp::Ge => inot(_mm_cmplt_epi32(a, b)),
            Cmp::Eq => _mm_cmpeq_epi32(a, b),
            Cmp::Ne => inot(_mm_cmpeq_epi32(a, b)),
            Cmp::Ord => _mm_set1_epi32(-1),
            Cmp::Unord => _mm_setzero_si128(),
        }
    }
    /// Bit i = sign of lane i.
    #[inline(always)]
    pub unsafe fn movemask<const N: usize>(k: &Vk<N>) -> u32 {
        _mm_movemask_ps(kf(k, 0)) as u32
    }
}

/// AVX-512 (F + DQ) on 16-lane chunks. Compares give a `k` mask register;
/// the lane arrays hold masks as -1/0 lanes, so a compare's mask is spread
/// to lanes (`vpmovm2d`) and a blend's lanes gathered into a `k` register
/// (`vpmovd2m`, the sign bits, as `blendvps` reads them).
#[cfg(all(
    target_arch = "x86_64",
    target_feature = "avx512f",
    target_feature = "avx512dq"
))]
mod avx512 {
    use super::*;
    use std::arch::x86_64::*;

    // The lane arrays are 32-byte aligned: unaligned loads and stores.
    chunk_helpers!(
        16,
        __m512,
        __m512i,
        _mm512_loadu_ps,
        _mm512_storeu_ps,
        _mm512_loadu_si512,
        _mm512_storeu_si512
    );

    #[inline(always)]
    pub unsafe fn add(a: __m512, b: __m512) -> __m512 {
        _mm512_add_ps(a, b)
    }
    #[inline(always)]
    pub unsafe fn sub(a: __m512, b: __m512) -> __m512 {
        _mm512_sub_ps(a, b)
    }
    #[inline(always)]
    pub unsafe fn mul(a: __m512, b: __m512) -> __m512 {
        _mm512_mul_ps(a, b)
    }
    #[inline(always)]
    pub unsafe fn div(a: __m512, b: __m512) -> __m512 {
        _mm512_div_ps(a, b)
    }
    #[inline(always)]
    pub unsafe fn min(a: __m512, b: __m512) -> __m512 {
        _mm512_min_ps(a, b)
    }
    #[inline(always)]
    pub unsafe fn max(a: __m512, b: __m512) -> __m512 {
        _mm512_max_ps(a, b)
    }
    #[inline(always)]
    pub unsafe fn sqrt(a: __m512) -> __m512 {
        _mm512_sqrt_ps(a)
    }
    #[inline(always)]
    pub unsafe fn one() -> __m512 {
        _mm512_set1_ps(1.0)
    }
    #[inline(always)]
    pub unsafe fn splat_bits(x: i32) -> __m512 {
        _mm512_castsi512_ps(_mm512_set1_epi32(x))
    }
    #[inline(always)]
    pub unsafe fn and(a: __m512, b: __m512) -> __m512 {
        _mm512_and_ps(a, b)
    }
    #[inline(always)]
    pub unsafe fn abs(a: __m512) -> __m512 {
        _mm512_and_ps(a, splat_bits(i32::MAX))
    }
    #[inline(always)]
    pub unsafe fn neg(a: __m512) -> __m512 {
        _mm512_xor_ps(a, splat_bits(i32::MIN))
    }
    /// The fused form of `kind` (AVX-512F has it).
    #[inline(always)]
    pub unsafe fn fused(kind: Fma, a: __m512, b: __m512, c: __m512) -> __m512 {
        match kind {
            Fma::MAdd => _mm512_fmadd_ps(a, b, c),
            Fma::MSub => _mm512_fmsub_ps(a, b, c),
            Fma::NMAdd => _mm512_fnmadd_ps(a, b, c),
            Fma::NMSub => _mm512_fnmsub_ps(a, b, c),
        }
    }
    /// The sign bits of `m` as a mask register.
    #[inline(always)]
    unsafe fn signs(m: __m512i) -> __mmask16 {
        _mm512_movepi32_mask(m)
    }
    /// -1 lanes where `k` is set, else 0.
    #[inline(always)]
    unsafe fn lanes(k: __mmask16) -> __m512i {
        _mm512_movm_epi32(k)
    }
    /// Take `b` where the sign of `m` is set, else `a`.
    #[inline(always)]
    pub unsafe fn blend(a: __m512, b: __m512, m: __m512) -> __m512 {
        _mm512_mask_blend_ps(signs(_mm512_castps_si512(m)), a, b)
    }
    #[inline(always)]
    pub unsafe fn iblend(a: __m512i, b: __m512i, m: __m512i) -> __m512i {
        _mm512_mask_blend_epi32(signs(m), a, b)
    }
    #[inline(always)]
    pub unsafe fn logic(op: Logic, a: __m512, b: __m512) -> __m512 {
        match op {
            Logic::And => _mm512_and_ps(a, b),
            Logic::Or => _mm512_or_ps(a, b),
            Logic::Xor => _mm512_xor_ps(a, b),
            Logic::AndNot => _mm512_andnot_ps(a, b),
        }
    }
    #[inline(always)]
    pub unsafe fn cmp(p: Cmp, a: __m512, b: __m512) -> __m512 {
        let k = match p {
            Cmp::Lt => _mm512_cmp_ps_mask::<_CMP_LT_OQ>(a, b),
            Cmp::Le => _mm512_cmp_ps_mask::<_CMP_LE_OQ>(a, b),
            Cmp::Gt => _mm512_cmp_ps_mask::<_CMP_GT_OQ>(a, b),
            Cmp::Ge => _mm512_cmp_ps_mask::<_CMP_GE_OQ>(a, b),
            Cmp::Eq => _mm512_cmp_ps_mask::<_CMP_EQ_OQ>(a, b),
            Cmp::Ne => _mm512_cmp_ps_mask::<_CMP_NEQ_UQ>(a, b),
            Cmp::Ord => _mm512_cmp_ps_mask::<_CMP_ORD_Q>(a, b),
            Cmp::Unord => _mm512_cmp_ps_mask::<_CMP_UNORD_Q>(a, b),
        };
        _mm512_castsi512_ps(lanes(k))
    }
    #[inline(always)]
    pub unsafe fn cvtt(a: __m512) -> __m512i {
        _mm512_cvttps_epi32(a)
    }
    #[inline(always)]
    pub unsafe fn cvt(a: __m512) -> __m512i {
        _mm512_cvtps_epi32(a)
    }
    #[inline(always)]
    pub unsafe fn cvtdq(a: __m512i) -> __m512 {
        _mm512_cvtepi32_ps(a)
    }
    #[inline(always)]
    pub unsafe fn iop(op: IOp, a: __m512i, b: __m512i) -> __m512i {
        match op {
            IOp::Add => _mm512_add_epi32(a, b),
            IOp::Sub => _mm512_sub_epi32(a, b),
            IOp::Mul => _mm512_mullo_epi32(a, b),
            IOp::And => _mm512_and_si512(a, b),
            IOp::Or => _mm512_or_si512(a, b),
            IOp::Xor => _mm512_xor_si512(a, b),
            IOp::AndNot => _mm512_andnot_si512(a, b),
            IOp::Min => _mm512_min_epi32(a, b),
            IOp::Max => _mm512_max_epi32(a, b),
        }
    }
    #[inline(always)]
    pub unsafe fn ilogic(op: Logic, a: __m512i, b: __m512i) -> __m512i {
        match op {
            Logic::And => _mm512_and_si512(a, b),
            Logic::Or => _mm512_or_si512(a, b),
            Logic::Xor => _mm512_xor_si512(a, b),
            Logic::AndNot => _mm512_andnot_si512(a, b),
        }
    }
    #[inline(always)]
    pub unsafe fn inot(a: __m512i) -> __m512i {
        _mm512_xor_si512(a, _mm512_set1_epi32(-1))
    }
    /// -1 where the sign bit is set, else 0.
    #[inline(always)]
    pub unsafe fn canon(a: __m512i) -> __m512i {
        _mm512_srai_epi32::<31>(a)
    }
    #[inline(always)]
    pub unsafe fn shift(s: Shift, a: __m512i, n: u32) -> __m512i {
        let count = _mm_cvtsi32_si128(n as i32);
        match s {
            Shift::Shl => _mm512_sll_epi32(a, count),
            Shift::Shr => _mm512_srl_epi32(a, count),
            Shift::Sar => _mm512_sra_epi32(a, count),
        }
    }
    #[inline(always)]
    pub unsafe fn icmp(p: Cmp, a: __m512i, b: __m512i) -> __m512i {
        let k = match p {
            Cmp::Lt => _mm512_cmplt_epi32_mask(a, b),
            Cmp::Le => _mm512_cmple_epi32_mask(a, b),
            Cmp::Gt => _mm512_cmpgt_epi32_mask(a, b),
            Cmp::Ge => _mm512_cmpge_epi32_mask(a, b),
            Cmp::Eq => _mm512_cmpeq_epi32_mask(a, b),
            Cmp::Ne => _mm512_cmpneq_epi32_mask(a, b),
            Cmp::Ord => 0xffff,
            Cmp::Unord => 0,
        };
        lanes(k)
    }
    /// Bit i = sign of lane i, over every chunk.
    #[inline(always)]
    pub unsafe fn movemask<const N: usize>(k: &Vk<N>) -> u32 {
        let mut bits = 0u32;
        for c in 0..N / W {
            bits |= u32::from(signs(ki(k, c))) << (W * c);
        }
        bits
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lanes::{cvt_round, cvt_trunc};

    /// Awkward lanes: signed zeros, NaNs, infinities, denormals, limits.
    const SPECIALS: [f32; 16] = [
        0.0,
        -0.0,
        f32::NAN,
        -f32::NAN,
        f32::INFINITY,
        f32::NEG_INFINITY,
        1e-40,
        -1e-40,
        2147483520.0,
        2147483648.0,
        -2147483648.0,
        2.5,
        -3.5,
        1.0,
        -7.25,
        3e38,
    ];
    const INTS: [i32; 16] = [
        0,
        1,
        -1,
        i32::MIN,
        i32::MAX,
        7,
        -8,
        123456,
        -99,
        31,
        32,
        2,
        5,
        -5,
        1 << 20,
        3,
    ];

    fn rot<T: Copy, const N: usize>(s: &[T; 16], step: usize, k: usize) -> [T; N] {
        std::array::from_fn(|i| s[(i * step + k) % 16])
    }

    /// Equal bits, or both NaN (a NaN result's sign and payload are unspecified).
    fn same<const N: usize>(got: Option<Vf<N>>, want: Vf<N>) -> bool {
        got.is_none_or(|g| {
            g.0.iter()
                .zip(&want.0)
                .all(|(x, y)| x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan()))
        })
    }

    const CMPS: [Cmp; 8] = [
        Cmp::Lt,
        Cmp::Le,
        Cmp::Gt,
        Cmp::Ge,
        Cmp::Eq,
        Cmp::Ne,
        Cmp::Ord,
        Cmp::Unord,
    ];

    fn float_ops<const N: usize>() {
        for k in 0..16 {
            let a = Vf::<N>(rot(&SPECIALS, 7, k));
            let b = Vf::<N>(rot(&SPECIALS, 7, k + 5));
            let c = Vf::<N>(rot(&SPECIALS, 3, k + 11));
            for op in [
                BinOp::Add,
                BinOp::Sub,
                BinOp::Mul,
                BinOp::Div,
                BinOp::Min,
                BinOp::Max,
            ] {
                assert!(
                    same(bin(op, a, b), a.zip(b, |x, y| op.eval(x, y))),
                    "{op:?}"
                );
            }
            for kind in [Fma::MAdd, Fma::MSub, Fma::NMAdd, Fma::NMSub] {
                for fused in [false, true] {
                    let want = a.zip3(b, c, |x, y, z| kind.eval(fused, x, y, z));
                    assert!(same(fma(kind, fused, a, b, c), want), "{kind:?} {fused}");
                }
            }
            assert!(same(unary(Unary::Abs, a), a.map(f32::abs)));
            assert!(same(unary(Unary::Neg, a), a.map(|x| -x)));
            assert!(same(unary(Unary::Sqrt, a), a.map(f32::sqrt)));
            assert!(same(unary(Unary::Rcp, a), a.map(|x| 1.0 / x)));
            assert!(same(unary(Unary::Rsqrt, a), a.map(|x| 1.0 / x.sqrt())));
            let t = |x| crate::lanes::truncate_mantissa(x, 12);
            assert!(same(truncate_mantissa(a, 12), a.map(t)));
            for p in CMPS {
                assert!(cmp(p, a, b).is_none_or(|r| r == a.cmp(p, b)), "{p:?}");
            }
            let want = Vi(a.0.map(cvt_trunc));
            assert!(to_int(ToInt::Trunc, a).is_none_or(|r| r == want));
            let want = Vi(a.0.map(cvt_round));
            assert!(to_int(ToInt::Round, a).is_none_or(|r| r == want));
            let m = a.cmp(Cmp::Lt, b);
            assert!(same(select(m, a, c), m.select(a, c)));
            let want = Vf(std::array::from_fn(|i| {
                if c.0[i].is_sign_negative() {
                    b.0[i]
                } else {
                    a.0[i]
                }
            }));
            assert!(same(blend_sign(c, a, b), want));
            for op in [Logic::And, Logic::Or, Logic::Xor, Logic::AndNot] {
                let want = a.zip(b, |x, y| f32::from_bits(op.eval(x.to_bits(), y.to_bits())));
                assert!(same(logic(op, a, b), want));
            }
        }
    }

    fn int_and_mask_ops<const N: usize>() {
        for k in 0..16 {
            let a = Vi::<N>(rot(&INTS, 3, k));
            let b = Vi::<N>(rot(&INTS, 5, k + 1));
            for op in [
                IOp::Add,
                IOp::Sub,
                IOp::Mul,
                IOp::And,
                IOp::Or,
                IOp::Xor,
                IOp::AndNot,
                IOp::Min,
                IOp::Max,
            ] {
                let want = a.zip(b, |x, y| op.eval(x, y));
                assert!(iop(op, a, b).is_none_or(|r| r == want), "{op:?}");
            }
            for s in [Shift::Shl, Shift::Shr, Shift::Sar] {
                for n in [0, 1, 5, 31, 32, 40, u32::MAX] {
                    let want = a.map(|x| s.eval32(x, n));
                    assert!(ishift(s, a, n).is_none_or(|r| r == want), "{s:?} {n}");
                }
            }
            for p in CMPS {
                let want = Vk(std::array::from_fn(|i| {
                    -i32::from(p.eval_i(i64::from(a.0[i]), i64::from(b.0[i])))
                }));
                assert!(icmp(p, a, b).is_none_or(|r| r == want), "{p:?}");
            }
            let want = Vf(std::array::from_fn(|i| a.0[i] as f32));
            assert!(same(to_float(a), want));
            // Masks that are not canonical: any negative lane is active.
            let (ka, kb) = (Vk(a.0), Vk(b.0));
            for op in [Logic::And, Logic::Or, Logic::Xor, Logic::AndNot] {
                let want = ka.zip(kb, |x, y| op.eval_b(x, y));
                assert!(klogic(op, ka, kb).is_none_or(|r| r == want), "{op:?}");
            }
            assert!(knot(ka).is_none_or(|r| r == ka.zip(ka, |x, _| !x)));
            let want: u32 = (0..N).map(|i| u32::from(ka.0[i] < 0) << i).sum();
            assert!(mask_bits(ka).is_none_or(|r| r == want));
            assert!(select_i(ka, a, b).is_none_or(|r| r == ka.select_i(a, b)));
        }
    }

    #[test]
    fn float_ops_match_the_lane_loops() {
        float_ops::<4>();
        float_ops::<8>();
        float_ops::<16>();
        float_ops::<32>();
    }

    #[test]
    fn int_and_mask_ops_match_the_lane_loops() {
        int_and_mask_ops::<4>();
        int_and_mask_ops::<8>();
        int_and_mask_ops::<16>();
        int_and_mask_ops::<32>();
    }

    #[test]
    fn widths_the_binary_runs() {
        let avx2 = cfg!(all(target_arch = "x86_64", target_feature = "avx2"));
        let sse = cfg!(all(target_arch = "x86_64", target_feature = "sse4.1"));
        let add = |n: usize| match n {
            2 => bin(BinOp::Add, Vf([1.0f32; 2]), Vf([2.0; 2])).is_some(),
            4 => bin(BinOp::Add, Vf([1.0f32; 4]), Vf([2.0; 4])).is_some(),
            8 => bin(BinOp::Add, Vf([1.0f32; 8]), Vf([2.0; 8])).is_some(),
            _ => bin(BinOp::Add, Vf([1.0f32; 16]), Vf([2.0; 16])).is_some(),
        };
        assert_eq!(add(8), avx2);
        assert_eq!(add(16), avx2 || avx512());
        assert_eq!(add(4), sse);
        assert!(!add(2));
        for n in [2, 4, 8, 16] {
            assert_eq!(intrinsics_for(n), add(n), "{n} lanes");
        }
    }
}
