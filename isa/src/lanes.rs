//! Lane arrays and the exact semantics of every op, shared by the traced and
//! native backends (so both compute bit-identical results).
//!
//! Semantics follow x86 where flavours agree:
//! - `min(a, b) = if a < b { a } else { b }`, `max(a, b) = if a > b { a } else { b }`
//!   (minps/maxps: a NaN in either operand, or `min(-0, +0)`, gives `b`).
//! - float to int conversion out of range or NaN gives `i32::MIN` (cvttps2dq).
//! - integer shifts by 32 or more give 0 (arithmetic: the sign) (vpslld).
//! - denormals are kept (no FTZ/DAZ); Larrabee's behaviour there is not public.
//! - the sign and payload of a NaN *result* are unspecified, as in Rust and
//!   LLVM (x86 hardware makes negative default NaNs, constant folding positive
//!   ones); NaN-ness itself is exact. Kernels must not branch on NaN bits.
//!
//! A mask lane is active when its i32 is negative (sign bit), as blendv reads
//! it; masks made by compares hold -1 or 0.

/// A vector of `N` f32 lanes.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
pub struct Vf<const N: usize>(pub [f32; N]);

/// A vector of `N` i32 lanes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(C, align(32))]
pub struct Vi<const N: usize>(pub [i32; N]);

/// A lane mask of `N` lanes (lane active iff its i32 is negative).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(C, align(32))]
pub struct Vk<const N: usize>(pub [i32; N]);

/// Float compare predicates (ordered unless said).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Cmp {
    /// a < b
    Lt,
    /// a <= b
    Le,
    /// a > b
    Gt,
    /// a >= b
    Ge,
    /// a == b
    Eq,
    /// a != b, true when either is NaN (NEQ_UQ)
    Ne,
    /// neither is NaN
    Ord,
    /// either is NaN
    Unord,
}

impl Cmp {
    /// Apply to two floats.
    #[inline(always)]
    #[must_use]
    pub fn eval(self, a: f32, b: f32) -> bool {
        match self {
            Cmp::Lt => a < b,
            Cmp::Le => a <= b,
            Cmp::Gt => a > b,
            Cmp::Ge => a >= b,
            Cmp::Eq => a == b,
            Cmp::Ne => a != b,
            Cmp::Ord => !a.is_nan() && !b.is_nan(),
            Cmp::Unord => a.is_nan() || b.is_nan(),
        }
    }
    /// Apply to two integers (signed); `Ord` is always true, `Unord` always false.
    #[inline(always)]
    #[must_use]
    pub fn eval_i(self, a: i64, b: i64) -> bool {
        match self {
            Cmp::Lt => a < b,
            Cmp::Le => a <= b,
            Cmp::Gt => a > b,
            Cmp::Ge => a >= b,
            Cmp::Eq => a == b,
            Cmp::Ne => a != b,
            Cmp::Ord => true,
            Cmp::Unord => false,
        }
    }
}

/// Binary float ops that have masked forms.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BinOp {
    /// a + b
    Add,
    /// a - b
    Sub,
    /// a * b
    Mul,
    /// a / b
    Div,
    /// x86 min
    Min,
    /// x86 max
    Max,
}

impl BinOp {
    /// Apply to two floats.
    #[inline(always)]
    #[must_use]
    pub fn eval(self, a: f32, b: f32) -> f32 {
        match self {
            BinOp::Add => a + b,
            BinOp::Sub => a - b,
            BinOp::Mul => a * b,
            BinOp::Div => a / b,
            BinOp::Min => fmin(a, b),
            BinOp::Max => fmax(a, b),
        }
    }
}

/// The four fused multiply-add forms.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Fma {
    /// a * b + c
    MAdd,
    /// a * b - c
    MSub,
    /// -(a * b) + c
    NMAdd,
    /// -(a * b) - c
    NMSub,
}

impl Fma {
    /// Apply, fused (one rounding) or as mul then add (two roundings).
    #[inline(always)]
    #[must_use]
    pub fn eval(self, fused: bool, a: f32, b: f32, c: f32) -> f32 {
        if fused {
            match self {
                Fma::MAdd => a.mul_add(b, c),
                Fma::MSub => a.mul_add(b, -c),
                Fma::NMAdd => (-a).mul_add(b, c),
                Fma::NMSub => (-a).mul_add(b, -c),
            }
        } else {
            let p = a * b;
            match self {
                Fma::MAdd => p + c,
                Fma::MSub => p - c,
                Fma::NMAdd => c - p,
                Fma::NMSub => -p - c,
            }
        }
    }
}

/// x86 minps semantics.
#[inline(always)]
#[must_use]
pub fn fmin(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

/// x86 maxps semantics.
#[inline(always)]
#[must_use]
pub fn fmax(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

/// Keep the top `bits` of the 23 mantissa bits (toward zero). NaN stays NaN
/// (the quiet bit is the top mantissa bit), infinities and zeros are unchanged.
#[inline(always)]
#[must_use]
pub fn truncate_mantissa(x: f32, bits: u32) -> f32 {
    if bits >= 23 {
        return x;
    }
    let drop = 23 - bits;
    f32::from_bits(x.to_bits() & !((1u32 << drop) - 1))
}

/// Approximate reciprocal with `bits` mantissa bits.
#[inline(always)]
#[must_use]
pub fn rcp_approx(x: f32, bits: u32) -> f32 {
    truncate_mantissa(1.0 / x, bits)
}

/// Approximate reciprocal square root with `bits` mantissa bits.
#[inline(always)]
#[must_use]
pub fn rsqrt_approx(x: f32, bits: u32) -> f32 {
    truncate_mantissa(1.0 / x.sqrt(), bits)
}

/// cvttps2dq: truncate; NaN or out of range gives `i32::MIN`.
#[inline(always)]
#[must_use]
pub fn cvt_trunc(x: f32) -> i32 {
    if x.is_nan() || !(-2147483648.0..2147483648.0).contains(&x) {
        i32::MIN
    } else {
        x as i32
    }
}

/// cvtps2dq in round-to-nearest-even mode; NaN or out of range gives `i32::MIN`.
#[inline(always)]
#[must_use]
pub fn cvt_round(x: f32) -> i32 {
    let r = x.round_ties_even();
    if r.is_nan() || !(-2147483648.0..2147483648.0).contains(&r) {
        i32::MIN
    } else {
        r as i32
    }
}

/// Integer vector ops.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum IOp {
    /// wrapping a + b
    Add,
    /// wrapping a - b
    Sub,
    /// wrapping a * b (low 32 bits)
    Mul,
    /// a & b
    And,
    /// a | b
    Or,
    /// a ^ b
    Xor,
    /// !a & b
    AndNot,
    /// signed min
    Min,
    /// signed max
    Max,
}

impl IOp {
    /// Apply to two i32.
    #[inline(always)]
    #[must_use]
    pub fn eval(self, a: i32, b: i32) -> i32 {
        match self {
            IOp::Add => a.wrapping_add(b),
            IOp::Sub => a.wrapping_sub(b),
            IOp::Mul => a.wrapping_mul(b),
            IOp::And => a & b,
            IOp::Or => a | b,
            IOp::Xor => a ^ b,
            IOp::AndNot => !a & b,
            IOp::Min => a.min(b),
            IOp::Max => a.max(b),
        }
    }
}

/// Shift kinds (by an immediate count).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Shift {
    /// logical left
    Shl,
    /// logical right
    Shr,
    /// arithmetic right
    Sar,
}

impl Shift {
    /// Apply to an i32 lane with x86 vector semantics (counts >= 32 saturate).
    #[inline(always)]
    #[must_use]
    pub fn eval32(self, a: i32, n: u32) -> i32 {
        match self {
            Shift::Shl => {
                if n >= 32 {
                    0
                } else {
                    ((a as u32) << n) as i32
                }
            }
            Shift::Shr => {
                if n >= 32 {
                    0
                } else {
                    ((a as u32) >> n) as i32
                }
            }
            Shift::Sar => a >> n.min(31),
        }
    }
    /// Apply to an i64 scalar with x86 semantics (count taken mod 64).
    #[inline(always)]
    #[must_use]
    pub fn eval64(self, a: i64, n: u32) -> i64 {
        let n = n & 63;
        match self {
            Shift::Shl => ((a as u64) << n) as i64,
            Shift::Shr => ((a as u64) >> n) as i64,
            Shift::Sar => a >> n,
        }
    }
}

impl<const N: usize> Vf<N> {
    /// Lane-wise map.
    #[inline(always)]
    #[must_use]
    pub fn map(self, f: impl Fn(f32) -> f32) -> Self {
        let mut r = self.0;
        for x in &mut r {
            *x = f(*x);
        }
        Vf(r)
    }
    /// Lane-wise zip.
    #[inline(always)]
    #[must_use]
    pub fn zip(self, b: Self, f: impl Fn(f32, f32) -> f32) -> Self {
        let mut r = self.0;
        for i in 0..N {
            r[i] = f(self.0[i], b.0[i]);
        }
        Vf(r)
    }
    /// Lane-wise three-way zip.
    #[inline(always)]
    #[must_use]
    pub fn zip3(self, b: Self, c: Self, f: impl Fn(f32, f32, f32) -> f32) -> Self {
        let mut r = self.0;
        for i in 0..N {
            r[i] = f(self.0[i], b.0[i], c.0[i]);
        }
        Vf(r)
    }
    /// Compare lane-wise into a mask.
    #[inline(always)]
    #[must_use]
    pub fn cmp(self, p: Cmp, b: Self) -> Vk<N> {
        let mut r = [0i32; N];
        for i in 0..N {
            r[i] = -(p.eval(self.0[i], b.0[i]) as i32);
        }
        Vk(r)
    }
    /// Reinterpret the bits as i32 lanes.
    #[inline(always)]
    #[must_use]
    pub fn to_bits(self) -> Vi<N> {
        let mut r = [0i32; N];
        for i in 0..N {
            r[i] = self.0[i].to_bits() as i32;
        }
        Vi(r)
    }
    /// Bit patterns equal (NaN-aware equality for tests).
    #[must_use]
    pub fn bit_eq(&self, b: &Self) -> bool {
        self.0
            .iter()
            .zip(&b.0)
            .all(|(x, y)| x.to_bits() == y.to_bits())
    }
}

impl<const N: usize> Vi<N> {
    /// Lane-wise zip.
    #[inline(always)]
    #[must_use]
    pub fn zip(self, b: Self, f: impl Fn(i32, i32) -> i32) -> Self {
        let mut r = self.0;
        for i in 0..N {
            r[i] = f(self.0[i], b.0[i]);
        }
        Vi(r)
    }
    /// Lane-wise map.
    #[inline(always)]
    #[must_use]
    pub fn map(self, f: impl Fn(i32) -> i32) -> Self {
        let mut r = self.0;
        for x in &mut r {
            *x = f(*x);
        }
        Vi(r)
    }
    /// Reinterpret the bits as f32 lanes.
    #[inline(always)]
    #[must_use]
    pub fn to_f32_bits(self) -> Vf<N> {
        let mut r = [0f32; N];
        for i in 0..N {
            r[i] = f32::from_bits(self.0[i] as u32);
        }
        Vf(r)
    }
}

impl<const N: usize> Vk<N> {
    /// Mask from bits (bit i = lane i).
    #[inline(always)]
    #[must_use]
    pub fn from_bits(bits: u32) -> Self {
        let mut r = [0i32; N];
        for (i, x) in r.iter_mut().enumerate() {
            *x = -(((bits >> i) & 1) as i32);
        }
        Vk(r)
    }
    /// Bits (bit i = lane i), as movmskps reads them.
    #[inline(always)]
    #[must_use]
    pub fn bits(self) -> u32 {
        #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
        {
            if N == 8 {
                // SAFETY: Vk<8> is 32 bytes, 32-aligned; avx2 is enabled at compile time.
                unsafe {
                    use std::arch::x86_64::*;
                    let v = _mm256_load_ps(self.0.as_ptr() as *const f32);
                    return _mm256_movemask_ps(v) as u32;
                }
            }
            if N == 4 {
                // SAFETY: Vk<4> is 16 bytes, 32-aligned; sse is part of x86_64.
                unsafe {
                    use std::arch::x86_64::*;
                    let v = _mm_load_ps(self.0.as_ptr() as *const f32);
                    return _mm_movemask_ps(v) as u32;
                }
            }
        }
        let mut b = 0u32;
        for i in 0..N {
            b |= ((self.0[i] < 0) as u32) << i;
        }
        b
    }
    /// Lane `i` active.
    #[inline(always)]
    #[must_use]
    pub fn get(self, i: usize) -> bool {
        self.0[i] < 0
    }
    /// Lane-wise logic on the canonical form (result lanes are -1 or 0).
    #[inline(always)]
    #[must_use]
    pub fn zip(self, b: Self, f: impl Fn(bool, bool) -> bool) -> Self {
        let mut r = [0i32; N];
        for i in 0..N {
            r[i] = -(f(self.0[i] < 0, b.0[i] < 0) as i32);
        }
        Vk(r)
    }
    /// Select lanes: active -> `t`, else `f`.
    #[inline(always)]
    #[must_use]
    pub fn select(self, t: Vf<N>, f: Vf<N>) -> Vf<N> {
        // Branch-free on the lane's sign (all ones when active), the form
        // LLVM vectorises into one blend.
        let mut r = [0f32; N];
        for i in 0..N {
            let k = (self.0[i] >> 31) as u32;
            r[i] = f32::from_bits((t.0[i].to_bits() & k) | (f.0[i].to_bits() & !k));
        }
        Vf(r)
    }
    /// Select integer lanes: active -> `t`, else `f`.
    #[inline(always)]
    #[must_use]
    pub fn select_i(self, t: Vi<N>, f: Vi<N>) -> Vi<N> {
        let mut r = [0i32; N];
        for i in 0..N {
            let k = self.0[i] >> 31;
            r[i] = (t.0[i] & k) | (f.0[i] & !k);
        }
        Vi(r)
    }
}

/// General permute of the concatenation `a ++ b` (index < 2N selects).
#[inline(always)]
#[must_use]
pub fn permute2<const N: usize>(a: Vf<N>, b: Vf<N>, idx: &[u8; N]) -> Vf<N> {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
    if N == 8 {
        // vpermps per source and a blend; with a constant pattern LLVM folds
        // this into the single best shuffle (vpermilps, vperm2f128, ...).
        // SAFETY: Vf<8> is 32 bytes and 32-aligned; avx2 is enabled at compile time.
        unsafe {
            use std::arch::x86_64::*;
            let mut ia = [0i32; 8];
            let mut sel = [0i32; 8];
            for i in 0..8 {
                ia[i] = i32::from(idx[i] & 7);
                sel[i] = -i32::from(idx[i] >= 8);
            }
            let iv = _mm256_loadu_si256(ia.as_ptr() as *const __m256i);
            let va = _mm256_permutevar8x32_ps(_mm256_load_ps(a.0.as_ptr()), iv);
            let vb = _mm256_permutevar8x32_ps(_mm256_load_ps(b.0.as_ptr()), iv);
            let m = _mm256_loadu_ps(sel.as_ptr() as *const f32);
            let r = _mm256_blendv_ps(va, vb, m);
            return std::mem::transmute_copy::<__m256, Vf<N>>(&r);
        }
    }
    #[cfg(all(target_arch = "x86_64", target_feature = "avx512f"))]
    if N == 16 {
        // One vpermt2ps for any two-source pattern: as a lane loop, a
        // permute in a kernel step the compiler did not inline stayed a loop
        // over 16 lanes (a quarter of DRS BVH2's host time on Zen 4).
        // SAFETY: Vf<16> is 64 bytes (unaligned loads); avx512f is enabled
        // at compile time.
        unsafe {
            use std::arch::x86_64::*;
            let mut ia = [0i32; 16];
            for i in 0..16 {
                ia[i] = i32::from(idx[i] & 31);
            }
            let iv = _mm512_loadu_si512(ia.as_ptr().cast());
            let (va, vb) = (_mm512_loadu_ps(a.0.as_ptr()), _mm512_loadu_ps(b.0.as_ptr()));
            let r = _mm512_permutex2var_ps(va, iv, vb);
            return std::mem::transmute_copy::<__m512, Vf<N>>(&r);
        }
    }
    permute2_lanes(a, b, idx)
}

/// [`permute2`] as a lane loop (what the instruction paths must equal).
#[inline(always)]
#[must_use]
fn permute2_lanes<const N: usize>(a: Vf<N>, b: Vf<N>, idx: &[u8; N]) -> Vf<N> {
    let mut r = [0f32; N];
    for i in 0..N {
        let j = idx[i] as usize;
        r[i] = if j < N { a.0[j] } else { b.0[j - N] };
    }
    Vf(r)
}

/// Horizontal reduction by the halving tree the expansion records: partner
/// lanes at distance N/2, N/4, ..., 1; the result is lane 0.
#[inline(always)]
#[must_use]
pub fn reduce<const N: usize>(a: Vf<N>, f: impl Fn(f32, f32) -> f32) -> f32 {
    let mut v = a.0;
    let mut d = N / 2;
    while d >= 1 {
        let prev = v;
        for i in 0..N {
            v[i] = f(prev[i], prev[i ^ d]);
        }
        d /= 2;
    }
    v[0]
}

/// The lane pattern `reduce` uses at distance `d` (lane i takes lane i ^ d).
#[must_use]
pub fn xor_pattern<const N: usize>(d: usize) -> [u8; N] {
    let mut p = [0u8; N];
    for (i, x) in p.iter_mut().enumerate() {
        *x = (i ^ d) as u8;
    }
    p
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every path of `permute2` (the intrinsics this binary has for 8 and
    /// 16 lanes, the lane loop elsewhere) equals the lane loop, on seeded
    /// patterns over both sources, NaN payloads and signed zeros included.
    fn permute2_matches_lanes<const N: usize>() {
        let mut x = 0x9e37_79b9_u32;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            x
        };
        for _ in 0..200 {
            let a = Vf::<N>(std::array::from_fn(|_| f32::from_bits(next())));
            let b = Vf::<N>(std::array::from_fn(|i| {
                if i % 3 == 0 {
                    -0.0
                } else {
                    i as f32
                }
            }));
            let idx: [u8; N] = std::array::from_fn(|_| (next() % (2 * N as u32)) as u8);
            let (got, want) = (permute2(a, b, &idx), permute2_lanes(a, b, &idx));
            assert_eq!(got.0.map(f32::to_bits), want.0.map(f32::to_bits), "{idx:?}");
        }
    }

    #[test]
    fn permute2_equals_its_lane_loop_at_every_width() {
        permute2_matches_lanes::<4>();
        permute2_matches_lanes::<8>();
        permute2_matches_lanes::<16>();
        permute2_matches_lanes::<32>();
    }

    #[test]
    fn min_max_follow_x86() {
        assert_eq!(fmin(1.0, f32::NAN).to_bits(), f32::NAN.to_bits());
        assert_eq!(fmin(f32::NAN, 1.0), 1.0);
        assert_eq!(fmin(-0.0, 0.0).to_bits(), 0.0f32.to_bits());
        assert_eq!(fmin(0.0, -0.0).to_bits(), (-0.0f32).to_bits());
        assert_eq!(fmax(f32::NAN, 2.0), 2.0);
    }

    #[test]
    fn conversions_follow_x86() {
        assert_eq!(cvt_trunc(f32::NAN), i32::MIN);
        assert_eq!(cvt_trunc(3e9), i32::MIN);
        assert_eq!(cvt_trunc(-2.7), -2);
        assert_eq!(cvt_round(2.5), 2);
        assert_eq!(cvt_round(3.5), 4);
        assert_eq!(cvt_round(-2147483648.0), i32::MIN);
    }

    #[test]
    fn truncation_keeps_specials() {
        for bits in [12, 14, 23] {
            assert!(rcp_approx(f32::NAN, bits).is_nan());
            assert_eq!(rcp_approx(0.0, bits), f32::INFINITY);
            assert_eq!(rcp_approx(-0.0, bits), f32::NEG_INFINITY);
            assert_eq!(rcp_approx(f32::INFINITY, bits), 0.0);
            assert!(rsqrt_approx(-1.0, bits).is_nan());
        }
    }

    #[test]
    fn mask_bits_round_trip() {
        for bits in [0u32, 1, 0x5a, 0xff] {
            assert_eq!(Vk::<8>::from_bits(bits).bits(), bits);
        }
        assert_eq!(Vk::<16>::from_bits(0xa5a5).bits(), 0xa5a5);
        assert_eq!(Vk::<4>::from_bits(0x9).bits(), 0x9);
    }

    #[test]
    fn reduce_tree() {
        let v = Vf([1.0f32, 5.0, -3.0, 2.0, 8.0, 0.5, 7.0, -1.0]);
        assert_eq!(reduce(v, fmin), -3.0);
        assert_eq!(reduce(v, fmax), 8.0);
        assert_eq!(reduce(v, |a, b| a + b), 19.5);
    }
}
