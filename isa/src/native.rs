//! The native backend: the generic kernel code compiled to the host's
//! instructions. Vector ops are `std::arch` intrinsics where the binary is
//! built with AVX2 (8-lane chunks) or SSE4.1 (4 lanes) ([`crate::host`]),
//! portable lane loops elsewhere; scalar ops are plain integer and float
//! ops. No recording, no allocation, no per-op branching, and the bounds
//! check of each access hoisted to the buffer ([`Buf::hot_off`]). Results
//! are bit-identical to the traced backend's.
//!
//! A *logging* native machine ([`Native::logging`]) also keeps, for
//! functional warming (SMARTS), the memory accesses and branches the traced
//! backend would record for the same code — the same addresses, regions,
//! per-lane addresses and branch outcomes in the same order, the flavour's
//! expansions included (a gather without a gather instruction is its lane
//! loads) — and nothing else: warming at the native backend's speed instead
//! of recording every op (a test holds the two logs equal on every kernel).

use crate::class::OpClass;
use crate::flavour::{Flavour, FlavourId};
use crate::host::{self, ToInt, Unary};
use crate::lanes::{
    cvt_round, cvt_trunc, permute2, rcp_approx, reduce, rsqrt_approx, BinOp, Cmp, Fma, IOp, Shift,
    Vf, Vi, Vk,
};
use crate::machine::{Float, Int, Logic, Machine, SOp};
use crate::mem::{AddrSpace, At, Buf, OpenBuf};
use crate::trace::{Op, Trace, FLAG_TAKEN};
use crate::types::{Addr, LaneMask, MemId, Region, Site};
use std::marker::PhantomData;

/// Scalar integer of the native backend.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NS(pub i64);
impl Int for NS {
    #[inline(always)]
    fn get(self) -> i64 {
        self.0
    }
}

/// Scalar f32 of the native backend.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NX(pub f32);
impl Float for NX {
    #[inline(always)]
    fn get(self) -> f32 {
        self.0
    }
}

/// Whether a native machine keeps a warming log: [`NoLog`] (nothing, and
/// no test of it per memory op) or [`WarmLog`]. A type, not a field tested
/// at run time, so the plain machine's memory ops compile to the access
/// alone.
pub trait LogKind: std::fmt::Debug {
    /// The log to append to, if this machine keeps one.
    fn get(&mut self) -> Option<&mut Trace>;
}

/// No warming log (the plain native machine).
#[derive(Debug, Default)]
pub struct NoLog;
impl LogKind for NoLog {
    #[inline(always)]
    fn get(&mut self) -> Option<&mut Trace> {
        None
    }
}

/// A warming log of memory and branch ops ([`Native::logging`]).
#[derive(Debug)]
pub struct WarmLog(Box<Trace>);
impl LogKind for WarmLog {
    #[inline(always)]
    fn get(&mut self) -> Option<&mut Trace> {
        Some(&mut self.0)
    }
}

/// A native machine of flavour `FL` with `N` lanes (e.g. `Native<Avx2, 8>`);
/// `L` says whether it keeps a warming log.
#[derive(Debug)]
pub struct Native<FL, const N: usize, L = NoLog> {
    space: AddrSpace,
    /// The warming log of a logging machine.
    log: L,
    _f: PhantomData<FL>,
}

impl<FL: Flavour<N>, const N: usize> Default for Native<FL, N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<FL: Flavour<N>, const N: usize> Native<FL, N> {
    /// A machine with a fresh address space.
    #[must_use]
    pub fn new() -> Self {
        Native {
            space: AddrSpace::new(),
            log: NoLog,
            _f: PhantomData,
        }
    }
}

impl<FL: Flavour<N>, const N: usize> Native<FL, N, WarmLog> {
    /// A machine that logs its memory accesses and branches for functional
    /// warming ([`Native::take_log`]); the log's header says it came from `source`.
    #[must_use]
    pub fn logging(source: &str) -> Self {
        Self::logging_in(AddrSpace::new(), source)
    }

    /// [`Native::logging`] in `space` (e.g. a traced machine's, after it
    /// laid a scene out whose buffers this machine then shares).
    #[must_use]
    pub fn logging_in(space: AddrSpace, source: &str) -> Self {
        Native {
            space,
            log: WarmLog(Box::new(Trace::new(FL::ID, source))),
            _f: PhantomData,
        }
    }

    /// The memory and branch ops logged since the last take, as a trace with
    /// the address space's current regions.
    #[must_use]
    pub fn take_log(&mut self) -> Trace {
        let log = &mut *self.log.0;
        let mut t = Trace::new(FL::ID, &log.source);
        t.regions = self.space.regions().to_vec();
        let (ops, lanes) = crate::trace::pooled_buffers();
        t.ops = std::mem::replace(&mut log.ops, ops);
        t.lane_addrs = std::mem::replace(&mut log.lane_addrs, lanes);
        t
    }
}

impl<FL: Flavour<N>, const N: usize, L: LogKind> Native<FL, N, L> {
    /// Log an access of `class` at byte `off` of `buf`.
    #[inline(always)]
    fn log_mem(&mut self, class: OpClass, buf: &Buf, off: usize, bytes: usize) {
        if let Some(log) = self.log.get() {
            log_at(log, class, buf.addr(off), buf.id(), bytes);
        }
    }

    /// Log a gather or scatter: one address per active lane, in lane order.
    #[inline(always)]
    fn log_lanes(
        &mut self,
        class: OpClass,
        buf: &Buf,
        k: Vk<N>,
        lane_off: impl Fn(usize) -> usize,
    ) {
        if let Some(log) = self.log.get() {
            let first = log.lane_addrs.len() as u32;
            for i in (0..N).filter(|&i| k.get(i)) {
                log.lane_addrs.push(buf.addr(lane_off(i)));
            }
            let mut op = Op::new(class, Region::Other);
            op.mask = LaneMask(k.bits());
            op.addr = log
                .lane_addrs
                .get(first as usize)
                .copied()
                .unwrap_or(Addr(0));
            op.bytes = 4;
            op.mem = buf.id();
            op.aux = first;
            log.ops.push(op);
        }
    }

    /// Log each active lane as an access of its own (the flavour has no
    /// gather or scatter instruction: lane loads or stores).
    #[inline(always)]
    fn log_each_lane(
        &mut self,
        class: OpClass,
        buf: &Buf,
        k: Vk<N>,
        lane_off: impl Fn(usize) -> usize,
    ) {
        for i in (0..N).filter(|&i| k.get(i)) {
            self.log_mem(class, buf, lane_off(i), 4);
        }
    }
}

impl<FL: Flavour<N>, const N: usize, L: LogKind> Native<FL, N, L> {
    /// Log a compress-store of `n` lanes at `off`: one compressing store, or
    /// (no compress instruction) the permutation's LUT load and a full store.
    #[inline(always)]
    fn log_compress(&mut self, k: Vk<N>, buf: &Buf, off: usize, n: usize) {
        if FL::COMPRESS {
            self.log_mem(OpClass::VCompress, buf, off, 4 * n);
        } else if let Some(log) = self.log.get() {
            let lut = &self.space.regions()[0];
            let entry = Addr(lut.base.0 + (4 * N * k.bits() as usize) as u64);
            log_at(log, OpClass::VLoad, entry, lut.id, 4 * N);
            log_at(log, OpClass::VStore, buf.addr(off), buf.id(), 4 * N);
        }
    }
}

/// Append one memory op to a warming log.
#[inline(always)]
fn log_at(log: &mut Trace, class: OpClass, addr: Addr, mem: MemId, bytes: usize) {
    let mut op = Op::new(class, Region::Other);
    op.addr = addr;
    op.bytes = bytes as u32;
    op.mem = mem;
    log.ops.push(op);
}

/// Byte offset of an effective address.
#[inline(always)]
pub(crate) fn ea_off(index: Option<i64>, scale: u8, disp: usize) -> usize {
    base_ea_off(None, index, scale, disp)
}

/// Byte offset of an effective address with an optional base register.
#[inline(always)]
pub(crate) fn base_ea_off(base: Option<i64>, index: Option<i64>, scale: u8, disp: usize) -> usize {
    let off = base.unwrap_or(0) + index.map_or(0, |i| i * i64::from(scale)) + disp as i64;
    if off < 0 {
        negative_address(off);
    }
    off as usize
}

#[cold]
#[inline(never)]
fn negative_address(off: i64) -> ! {
    panic!("negative effective address {off}")
}

/// A native access's byte offset: [`ea_off`] in debug builds; in release
/// builds the sum as it wraps (a negative offset becomes a huge one, which
/// the buffer's [`Buf::hot_off`] stops at).
#[inline(always)]
fn ea(at: At<NS>) -> usize {
    match at.base {
        None => hot_ea(at.index.map(|s| s.0), at.scale, at.disp),
        Some(b) if cfg!(debug_assertions) => {
            base_ea_off(Some(b.0), at.index.map(|s| s.0), at.scale, at.disp)
        }
        Some(b) => (b.0 as usize).wrapping_add(hot_ea(at.index.map(|s| s.0), at.scale, at.disp)),
    }
}

/// [`ea`] of a lane's index.
#[inline(always)]
fn hot_ea(index: Option<i64>, scale: u8, disp: usize) -> usize {
    if cfg!(debug_assertions) {
        return ea_off(index, scale, disp);
    }
    let i = index.map_or(0, |i| i.wrapping_mul(i64::from(scale)));
    (i as usize).wrapping_add(disp)
}

/// Lanes stored by a compress: active lanes in order, then the inactive ones.
#[inline(always)]
pub(crate) fn compress_lanes<const N: usize>(k: Vk<N>, v: Vf<N>) -> (Vf<N>, usize) {
    let mut r = [0f32; N];
    let mut n = 0;
    for i in 0..N {
        if k.get(i) {
            r[n] = v.0[i];
            n += 1;
        }
    }
    let mut j = n;
    for i in 0..N {
        if !k.get(i) {
            r[j] = v.0[i];
            j += 1;
        }
    }
    (Vf(r), n)
}

/// Load an integer of `width` bytes, zero- or sign-extended.
#[inline(always)]
pub(crate) fn load_int(buf: &Buf, off: usize, width: u8, signed: bool) -> i64 {
    extend(buf.uint_at(off, width as usize), width, signed)
}

/// An integer of `width` bytes, zero- or sign-extended.
#[inline(always)]
fn extend(u: u64, width: u8, signed: bool) -> i64 {
    if signed && width < 8 {
        let sh = 64 - 8 * u32::from(width);
        ((u << sh) as i64) >> sh
    } else {
        u as i64
    }
}

/// `first` repeated across `N` lanes.
#[inline(always)]
fn repeat<const K: usize, const N: usize>(first: [f32; K]) -> Vf<N> {
    Vf(std::array::from_fn(|i| first[i & (K - 1)]))
}

/// Horizontal reduction op.
#[inline(always)]
pub(crate) fn reduce_op<const N: usize>(op: BinOp, a: Vf<N>) -> f32 {
    assert!(
        matches!(op, BinOp::Add | BinOp::Min | BinOp::Max | BinOp::Mul),
        "reduce by {op:?}"
    );
    reduce(a, |x, y| op.eval(x, y))
}

/// Lanes for `consts` from a slice.
#[inline(always)]
pub(crate) fn arr<T: Copy + Default, const N: usize>(v: &[T]) -> [T; N] {
    assert_eq!(
        v.len(),
        N,
        "constant vector of {} lanes, machine has {N}",
        v.len()
    );
    let mut r = [T::default(); N];
    r.copy_from_slice(v);
    r
}

/// Bit i = lane i active, by the host's movemask where it has one.
#[inline(always)]
fn kbits<const N: usize>(k: Vk<N>) -> u32 {
    host::mask_bits(k).unwrap_or_else(|| k.bits())
}

/// A binary float op by the flavour's semantics: the host's instruction
/// where it has one (the flavour's approximate divide is the lane loop).
#[inline(always)]
fn bin<FL: Flavour<N>, const N: usize>(op: BinOp, a: Vf<N>, b: Vf<N>) -> Vf<N> {
    if FL::DIV || op != BinOp::Div {
        if let Some(r) = host::bin(op, a, b) {
            return r;
        }
    }
    a.zip(b, |x, y| FL::eval(op, x, y))
}

/// Permutation index array from a slice.
#[inline(always)]
pub(crate) fn idx_arr<const N: usize>(idx: &[u8], limit: usize) -> [u8; N] {
    assert_eq!(
        idx.len(),
        N,
        "permute of {} lanes, machine has {N}",
        idx.len()
    );
    let mut r = [0u8; N];
    for (o, &i) in r.iter_mut().zip(idx) {
        assert!((i as usize) < limit, "permute index {i} out of range");
        *o = i;
    }
    r
}

impl<FL: Flavour<N>, const N: usize, L: LogKind> Machine for Native<FL, N, L> {
    const LANES: usize = N;
    const FLAVOUR: FlavourId = FL::ID;
    type F = Vf<N>;
    type I = Vi<N>;
    type K = Vk<N>;
    type S = NS;
    type X = NX;
    type Open<'b> = OpenBuf<'b>;

    fn space(&mut self) -> &mut AddrSpace {
        &mut self.space
    }
    #[inline(always)]
    fn region(&mut self, _r: Region) {}
    #[inline(always)]
    fn active(&mut self, _k: Option<Vk<N>>) {}

    #[inline(always)]
    fn splat(&mut self, x: f32) -> Vf<N> {
        Vf([x; N])
    }
    #[inline(always)]
    fn consts(&mut self, v: &[f32]) -> Vf<N> {
        Vf(arr(v))
    }
    #[inline(always)]
    fn splat_i(&mut self, x: i32) -> Vi<N> {
        Vi([x; N])
    }
    #[inline(always)]
    fn consts_i(&mut self, v: &[i32]) -> Vi<N> {
        Vi(arr(v))
    }
    #[inline(always)]
    fn mask(&mut self, bits: u32) -> Vk<N> {
        Vk::from_bits(bits)
    }
    #[inline(always)]
    fn int(&mut self, v: i64) -> NS {
        NS(v)
    }
    #[inline(always)]
    fn float(&mut self, v: f32) -> NX {
        NX(v)
    }

    #[inline(always)]
    fn bin(&mut self, op: BinOp, a: Vf<N>, b: Vf<N>) -> Vf<N> {
        bin::<FL, N>(op, a, b)
    }
    #[inline(always)]
    fn masked(&mut self, op: BinOp, k: Vk<N>, src: Vf<N>, a: Vf<N>, b: Vf<N>) -> Vf<N> {
        self.select(k, bin::<FL, N>(op, a, b), src)
    }
    #[inline(always)]
    fn fma(&mut self, kind: Fma, a: Vf<N>, b: Vf<N>, c: Vf<N>) -> Vf<N> {
        host::fma(kind, FL::FMA, a, b, c)
            .unwrap_or_else(|| a.zip3(b, c, |x, y, z| kind.eval(FL::FMA, x, y, z)))
    }
    #[inline(always)]
    fn masked_fma(&mut self, kind: Fma, k: Vk<N>, a: Vf<N>, b: Vf<N>, c: Vf<N>) -> Vf<N> {
        let r = self.fma(kind, a, b, c);
        self.select(k, r, c)
    }
    #[inline(always)]
    fn abs(&mut self, a: Vf<N>) -> Vf<N> {
        host::unary(Unary::Abs, a).unwrap_or_else(|| a.map(f32::abs))
    }
    #[inline(always)]
    fn neg(&mut self, a: Vf<N>) -> Vf<N> {
        host::unary(Unary::Neg, a).unwrap_or_else(|| a.map(|x| -x))
    }
    #[inline(always)]
    fn sqrt(&mut self, a: Vf<N>) -> Vf<N> {
        host::unary(Unary::Sqrt, a).unwrap_or_else(|| a.map(f32::sqrt))
    }
    #[inline(always)]
    fn rcp(&mut self, a: Vf<N>) -> Vf<N> {
        if !FL::DIV {
            return self.rcp_approx(a);
        }
        host::unary(Unary::Rcp, a).unwrap_or_else(|| a.map(|x| 1.0 / x))
    }
    #[inline(always)]
    fn rcp_approx(&mut self, a: Vf<N>) -> Vf<N> {
        host::unary(Unary::Rcp, a)
            .and_then(|r| host::truncate_mantissa(r, FL::RCP_BITS))
            .unwrap_or_else(|| a.map(|x| rcp_approx(x, FL::RCP_BITS)))
    }
    #[inline(always)]
    fn rsqrt(&mut self, a: Vf<N>) -> Vf<N> {
        host::unary(Unary::Rsqrt, a).unwrap_or_else(|| a.map(|x| 1.0 / x.sqrt()))
    }
    #[inline(always)]
    fn rsqrt_approx(&mut self, a: Vf<N>) -> Vf<N> {
        host::unary(Unary::Rsqrt, a)
            .and_then(|r| host::truncate_mantissa(r, FL::RCP_BITS))
            .unwrap_or_else(|| a.map(|x| rsqrt_approx(x, FL::RCP_BITS)))
    }
    #[inline(always)]
    fn cmp(&mut self, p: Cmp, a: Vf<N>, b: Vf<N>) -> Vk<N> {
        host::cmp(p, a, b).unwrap_or_else(|| a.cmp(p, b))
    }
    #[inline(always)]
    fn select(&mut self, k: Vk<N>, t: Vf<N>, f: Vf<N>) -> Vf<N> {
        host::select(k, t, f).unwrap_or_else(|| k.select(t, f))
    }
    #[inline(always)]
    fn blend_sign(&mut self, s: Vf<N>, a: Vf<N>, b: Vf<N>) -> Vf<N> {
        if let Some(r) = host::blend_sign(s, a, b) {
            return r;
        }
        Vf(std::array::from_fn(|i| {
            if s.0[i].is_sign_negative() {
                b.0[i]
            } else {
                a.0[i]
            }
        }))
    }
    #[inline(always)]
    fn logic(&mut self, op: Logic, a: Vf<N>, b: Vf<N>) -> Vf<N> {
        host::logic(op, a, b)
            .unwrap_or_else(|| a.zip(b, |x, y| f32::from_bits(op.eval(x.to_bits(), y.to_bits()))))
    }
    #[inline(always)]
    fn broadcast(&mut self, x: NX) -> Vf<N> {
        Vf([x.0; N])
    }
    #[inline(always)]
    fn extract(&mut self, a: Vf<N>, i: usize) -> NX {
        NX(a.0[i])
    }
    #[inline(always)]
    fn permute(&mut self, a: Vf<N>, idx: &[u8]) -> Vf<N> {
        permute2(a, a, &idx_arr(idx, N))
    }
    #[inline(always)]
    fn shuffle2(&mut self, a: Vf<N>, b: Vf<N>, idx: &[u8]) -> Vf<N> {
        permute2(a, b, &idx_arr(idx, 2 * N))
    }
    #[inline(always)]
    fn reduce(&mut self, op: BinOp, a: Vf<N>) -> NX {
        NX(reduce_op(op, a))
    }
    #[inline(always)]
    fn to_int(&mut self, a: Vf<N>) -> Vi<N> {
        if let Some(r) = host::to_int(ToInt::Trunc, a) {
            return r;
        }
        let mut r = [0i32; N];
        for i in 0..N {
            r[i] = cvt_trunc(a.0[i]);
        }
        Vi(r)
    }
    #[inline(always)]
    fn to_int_round(&mut self, a: Vf<N>) -> Vi<N> {
        if let Some(r) = host::to_int(ToInt::Round, a) {
            return r;
        }
        let mut r = [0i32; N];
        for i in 0..N {
            r[i] = cvt_round(a.0[i]);
        }
        Vi(r)
    }
    #[inline(always)]
    fn to_float(&mut self, a: Vi<N>) -> Vf<N> {
        if let Some(r) = host::to_float(a) {
            return r;
        }
        let mut r = [0f32; N];
        for i in 0..N {
            r[i] = a.0[i] as f32;
        }
        Vf(r)
    }
    #[inline(always)]
    fn bits_to_i(&mut self, a: Vf<N>) -> Vi<N> {
        a.to_bits()
    }
    #[inline(always)]
    fn bits_to_f(&mut self, a: Vi<N>) -> Vf<N> {
        a.to_f32_bits()
    }

    #[inline(always)]
    fn iop(&mut self, op: IOp, a: Vi<N>, b: Vi<N>) -> Vi<N> {
        host::iop(op, a, b).unwrap_or_else(|| a.zip(b, |x, y| op.eval(x, y)))
    }
    #[inline(always)]
    fn ishift(&mut self, s: Shift, a: Vi<N>, n: u32) -> Vi<N> {
        host::ishift(s, a, n).unwrap_or_else(|| a.map(|x| s.eval32(x, n)))
    }
    #[inline(always)]
    fn icmp(&mut self, p: Cmp, a: Vi<N>, b: Vi<N>) -> Vk<N> {
        if let Some(r) = host::icmp(p, a, b) {
            return r;
        }
        let mut r = [0i32; N];
        for i in 0..N {
            r[i] = -(p.eval_i(i64::from(a.0[i]), i64::from(b.0[i])) as i32);
        }
        Vk(r)
    }
    #[inline(always)]
    fn iselect(&mut self, k: Vk<N>, t: Vi<N>, f: Vi<N>) -> Vi<N> {
        host::select_i(k, t, f).unwrap_or_else(|| k.select_i(t, f))
    }

    #[inline(always)]
    fn keep(&mut self, k: Vk<N>, a: Vf<N>) -> Vf<N> {
        self.select(k, a, Vf([0.0; N]))
    }

    #[inline(always)]
    fn keep_i(&mut self, k: Vk<N>, a: Vi<N>) -> Vi<N> {
        self.iselect(k, a, Vi([0; N]))
    }

    #[inline(always)]
    fn klogic(&mut self, op: Logic, a: Vk<N>, b: Vk<N>) -> Vk<N> {
        host::klogic(op, a, b).unwrap_or_else(|| a.zip(b, |x, y| op.eval_b(x, y)))
    }
    #[inline(always)]
    fn knot(&mut self, a: Vk<N>) -> Vk<N> {
        host::knot(a).unwrap_or_else(|| a.zip(a, |x, _| !x))
    }
    #[inline(always)]
    fn kmov(&mut self, bits: NS) -> Vk<N> {
        Vk::from_bits((bits.0 as u64 & ((1u64 << N) - 1)) as u32)
    }
    #[inline(always)]
    fn movemask(&mut self, k: Vk<N>) -> NS {
        NS(i64::from(kbits(k)))
    }
    #[inline(always)]
    fn popcnt(&mut self, k: Vk<N>) -> NS {
        NS(i64::from(kbits(k).count_ones()))
    }
    #[inline(always)]
    fn bitscan(&mut self, k: Vk<N>) -> NS {
        NS(i64::from(kbits(k).trailing_zeros().min(N as u32)))
    }
    #[inline(always)]
    fn any(&mut self, k: Vk<N>) -> NS {
        NS(i64::from(kbits(k) != 0))
    }
    #[inline(always)]
    fn all(&mut self, k: Vk<N>) -> NS {
        NS(i64::from(kbits(k).count_ones() == N as u32))
    }

    #[inline(always)]
    fn load(&mut self, buf: &Buf, at: At<NS>) -> Vf<N> {
        let off = ea(at);
        debug_assert!(
            buf.addr(off).0.is_multiple_of(4 * N as u64),
            "misaligned load at {}",
            buf.addr(off)
        );
        self.log_mem(OpClass::VLoad, buf, off, 4 * N);
        Vf(buf.hot_f32s::<N>(off))
    }
    #[inline(always)]
    fn loadu(&mut self, buf: &Buf, at: At<NS>) -> Vf<N> {
        let off = ea(at);
        self.log_mem(OpClass::VLoad, buf, off, 4 * N);
        Vf(buf.hot_f32s::<N>(off))
    }
    #[inline(always)]
    fn load_bcast(&mut self, buf: &Buf, at: At<NS>) -> Vf<N> {
        let off = ea(at);
        self.log_mem(OpClass::VLoadBcast, buf, off, 4);
        Vf([buf.hot_f32(off); N])
    }
    #[inline(always)]
    fn load_repeat(&mut self, buf: &Buf, at: At<NS>, n: usize) -> Vf<N> {
        assert!(n > 0 && N.is_multiple_of(n), "repeat of {n} lanes in {N}");
        let off = ea(at);
        self.log_mem(OpClass::VLoad, buf, off, 4 * n);
        if n == N {
            return Vf(buf.hot_f32s::<N>(off));
        }
        // Each lane from the first n, read at once (n divides N, a power
        // of two: lane i is lane i mod n = i & (n - 1) of the read).
        match n {
            1 => Vf([buf.hot_f32(off); N]),
            2 => repeat::<2, N>(buf.hot_f32s::<2>(off)),
            4 => repeat::<4, N>(buf.hot_f32s::<4>(off)),
            8 => repeat::<8, N>(buf.hot_f32s::<8>(off)),
            _ => repeat::<16, N>(buf.hot_f32s::<16>(off)),
        }
    }
    #[inline(always)]
    fn load_masked(&mut self, k: Vk<N>, src: Vf<N>, buf: &Buf, at: At<NS>) -> Vf<N> {
        let off = ea(at);
        self.log_mem(OpClass::VLoadMasked, buf, off, 4 * N);
        let mut r = src.0;
        for (i, x) in r.iter_mut().enumerate() {
            if k.get(i) {
                *x = buf.hot_f32(off + 4 * i);
            }
        }
        Vf(r)
    }
    #[inline(always)]
    fn store(&mut self, buf: &mut Buf, at: At<NS>, v: Vf<N>) {
        let off = ea(at);
        debug_assert!(
            buf.addr(off).0.is_multiple_of(4 * N as u64),
            "misaligned store at {}",
            buf.addr(off)
        );
        self.log_mem(OpClass::VStore, buf, off, 4 * N);
        buf.hot_set_f32s(off, &v.0);
    }
    #[inline(always)]
    fn storeu(&mut self, buf: &mut Buf, at: At<NS>, v: Vf<N>) {
        let off = ea(at);
        self.log_mem(OpClass::VStore, buf, off, 4 * N);
        buf.hot_set_f32s(off, &v.0);
    }
    #[inline(always)]
    fn store_masked(&mut self, k: Vk<N>, buf: &mut Buf, at: At<NS>, v: Vf<N>) {
        let off = ea(at);
        if FL::MASKED_MEM {
            self.log_mem(OpClass::VStoreMasked, buf, off, 4 * N);
        } else {
            self.log_each_lane(OpClass::Store, buf, k, |i| off + 4 * i);
        }
        for i in 0..N {
            if k.get(i) {
                buf.hot_set_f32(off + 4 * i, v.0[i]);
            }
        }
    }
    #[inline(always)]
    fn gather(
        &mut self,
        k: Vk<N>,
        src: Vf<N>,
        buf: &Buf,
        at: At<NS>,
        idx: Vi<N>,
        scale: u8,
    ) -> Vf<N> {
        let off = ea(at);
        let lane = |i: usize| hot_ea(Some(i64::from(idx.0[i])), scale, off);
        if FL::GATHER {
            self.log_lanes(OpClass::VGather, buf, k, lane);
        } else {
            self.log_each_lane(OpClass::Load, buf, k, lane);
        }
        let mut r = src.0;
        for (i, x) in r.iter_mut().enumerate() {
            if k.get(i) {
                *x = buf.hot_f32(hot_ea(Some(i64::from(idx.0[i])), scale, off));
            }
        }
        Vf(r)
    }
    #[inline(always)]
    fn scatter(&mut self, k: Vk<N>, buf: &mut Buf, at: At<NS>, idx: Vi<N>, scale: u8, v: Vf<N>) {
        let off = ea(at);
        let lane = |i: usize| hot_ea(Some(i64::from(idx.0[i])), scale, off);
        if FL::SCATTER {
            self.log_lanes(OpClass::VScatter, buf, k, lane);
        } else {
            self.log_each_lane(OpClass::Store, buf, k, lane);
        }
        for i in 0..N {
            if k.get(i) {
                let o = hot_ea(Some(i64::from(idx.0[i])), scale, off);
                buf.hot_set_f32(o, v.0[i]);
            }
        }
    }
    #[inline(always)]
    fn compress_store(&mut self, k: Vk<N>, buf: &mut Buf, at: At<NS>, v: Vf<N>) -> NS {
        let off = ea(at);
        let (packed, n) = compress_lanes(k, v);
        self.log_compress(k, buf, off, n);
        if FL::COMPRESS {
            for i in 0..n {
                buf.hot_set_f32(off + 4 * i, packed.0[i]);
            }
        } else {
            buf.hot_set_f32s(off, &packed.0);
        }
        NS(n as i64)
    }

    #[inline(always)]
    fn s_op(&mut self, op: SOp, a: NS, b: NS) -> NS {
        NS(op.eval(a.0, b.0))
    }
    #[inline(always)]
    fn s_shift(&mut self, s: Shift, a: NS, n: u32) -> NS {
        NS(s.eval64(a.0, n))
    }
    #[inline(always)]
    fn s_cmp(&mut self, p: Cmp, a: NS, b: NS) -> NS {
        NS(i64::from(p.eval_i(a.0, b.0)))
    }
    #[inline(always)]
    fn s_select(&mut self, c: NS, a: NS, b: NS) -> NS {
        if c.0 != 0 {
            a
        } else {
            b
        }
    }
    #[inline(always)]
    fn s_popcnt(&mut self, a: NS) -> NS {
        NS(i64::from(a.0.count_ones()))
    }
    #[inline(always)]
    fn s_tzcnt(&mut self, a: NS) -> NS {
        NS(i64::from(a.0.trailing_zeros()))
    }
    #[inline(always)]
    fn s_load(&mut self, buf: &Buf, at: At<NS>, width: u8, signed: bool) -> NS {
        let off = ea(at);
        self.log_mem(OpClass::Load, buf, off, width as usize);
        NS(extend(buf.hot_uint(off, width as usize), width, signed))
    }
    #[inline(always)]
    fn s_store(&mut self, buf: &mut Buf, at: At<NS>, width: u8, v: NS) {
        let off = ea(at);
        self.log_mem(OpClass::Store, buf, off, width as usize);
        buf.hot_set_uint(off, width as usize, v.0 as u64);
    }
    #[inline(always)]
    fn open<'b>(&mut self, buf: &'b mut Buf) -> OpenBuf<'b> {
        buf.open()
    }
    #[inline(always)]
    fn s_store_open(&mut self, buf: &mut OpenBuf<'_>, at: At<NS>, width: u8, v: NS) {
        let off = ea(at);
        if let Some(log) = self.log.get() {
            log_at(log, OpClass::Store, buf.addr(off), buf.id(), width as usize);
        }
        buf.hot_set_uint(off, width as usize, v.0 as u64);
    }

    #[inline(always)]
    fn x_op(&mut self, op: BinOp, a: NX, b: NX) -> NX {
        NX(op.eval(a.0, b.0))
    }
    #[inline(always)]
    fn x_fma(&mut self, kind: Fma, a: NX, b: NX, c: NX) -> NX {
        NX(kind.eval(FL::FMA, a.0, b.0, c.0))
    }
    #[inline(always)]
    fn x_sqrt(&mut self, a: NX) -> NX {
        NX(a.0.sqrt())
    }
    #[inline(always)]
    fn x_cmp(&mut self, p: Cmp, a: NX, b: NX) -> NS {
        NS(i64::from(p.eval(a.0, b.0)))
    }
    #[inline(always)]
    fn x_load(&mut self, buf: &Buf, at: At<NS>) -> NX {
        let off = ea(at);
        self.log_mem(OpClass::Load, buf, off, 4);
        NX(buf.hot_f32(off))
    }
    #[inline(always)]
    fn x_store(&mut self, buf: &mut Buf, at: At<NS>, v: NX) {
        let off = ea(at);
        self.log_mem(OpClass::Store, buf, off, 4);
        buf.hot_set_f32(off, v.0);
    }
    #[inline(always)]
    fn x_from_int(&mut self, a: NS) -> NX {
        NX(a.0 as f32)
    }
    #[inline(always)]
    fn x_to_int(&mut self, a: NX) -> NS {
        NS(i64::from(a.0 as i32))
    }

    #[inline(always)]
    fn branch(&mut self, site: Site, c: NS) -> bool {
        let taken = c.0 != 0;
        if let Some(log) = self.log.get() {
            let mut op = Op::new(OpClass::Branch, Region::Other);
            op.aux = site.0;
            if taken {
                op.flags |= FLAG_TAKEN;
            }
            log.ops.push(op);
        }
        taken
    }

    fn lane(&self, a: Vf<N>, i: usize) -> f32 {
        a.0[i]
    }
    fn lane_i(&self, a: Vi<N>, i: usize) -> i32 {
        a.0[i]
    }
    fn bits(&self, k: Vk<N>) -> u32 {
        k.bits()
    }
}
