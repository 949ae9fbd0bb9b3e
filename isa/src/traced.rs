//! The traced backend: computes every result (with the same lane semantics as
//! the native backend) and records the machine instructions the flavour needs
//! for it. An op a flavour lacks expands into the ops it would really issue,
//! each recorded, so its cost shows up honestly:
//!
//! | op | mask-register flavours (lrb16, avx512) | avx2 | sse4 |
//! |----|-----|-----|-----|
//! | `masked(op)` | 1 masked op | op + vblend | op + vblend |
//! | `select` | vmaskmov | vblend | vblend |
//! | `fma` | vfma | vfma | vmul + vadd (+ vlogic for -(ab)-c) |
//! | `masked_fma` | vfma{k} | vfma + vblend | vmul + vadd + vblend |
//! | `bin(Div)`, `rcp` (exact) | lrb16 (no divide): vrcp + vmul, vrcp; avx512: vdiv | vdiv | vdiv |
//! | `rsqrt` (exact) | vsqrt + vdiv (lrb16: vsqrt + vrcp) | same | same |
//! | `abs`, `neg` | vlogic | vlogic | vlogic |
//! | `extract(i)`, i > 0 | vshuf (i < 4), else vperm (+ vshuf if i % 4 != 0) | same | vshuf |
//! | `permute` | vshuf in-lane, else vperm | same | vshuf |
//! | `shuffle2` | vshuf if shufps/unpck/blend-able, else vperm | vshuf, vperm if whole 128-bit blocks, else 2 permutes + blend | vshuf, else 2 shuffles + blend |
//! | `reduce` | log2(N) x (vperm or vshuf + op) | same | same |
//! | `icmp` Ne/Le/Ge | vicmp | vicmp + vilogic | vicmp + vilogic |
//! | `knot`, `klogic` | klogic | vlogic | vlogic |
//! | `popcnt(k)` | movmsk + bitcnt | same | same |
//! | `bitscan(k)` | movmsk + alu (sentinel bit) + bitcnt | same | same |
//! | `load_masked` | vloadmasked | vloadmasked + vblend (vmaskmovps zeroes) | vload + vblend |
//! | `store_masked` | vstoremasked | vstoremasked | movmsk + per active lane: extract + store |
//! | `gather` | vgather | vgather | per active lane: vshuf + load + vinsert |
//! | `scatter` | vscatter | movmsk + per active lane: extract idx, extract value, store | same |
//! | `compress_store` | vcompress + movmsk + bitcnt | movmsk + LUT vload + vperm + vstore + bitcnt | movmsk + LUT vload + vshuf + vstore + bitcnt |
//! | `s_op` Min/Max | cmp + cmov | same | same |
//! | `x_fma` | vfma (1 lane) | vfma | vmul + vadd (+ vlogic) |

use crate::class::OpClass;
use crate::flavour::{Flavour, FlavourId};
use crate::lanes::{
    cvt_round, cvt_trunc, permute2, rcp_approx, rsqrt_approx, xor_pattern, BinOp, Cmp, Fma, IOp,
    Shift, Vf, Vi, Vk,
};
use crate::machine::{Float, Int, Logic, Machine, SOp};
use crate::mem::{AddrSpace, At, Buf};
use crate::native::{arr, base_ea_off, compress_lanes, ea_off, idx_arr, load_int, reduce_op};
use crate::trace::{Op, Trace, FLAG_TAKEN, MAX_SRCS};
use crate::types::{Addr, LaneMask, MemId, Region, Site, ValId};
use std::marker::PhantomData;

/// Traced f32 vector: value and id.
#[derive(Clone, Copy, Debug)]
pub struct TF<const N: usize> {
    /// Lanes.
    pub v: Vf<N>,
    /// Producer.
    pub id: ValId,
}
/// Traced i32 vector.
#[derive(Clone, Copy, Debug)]
pub struct TI<const N: usize> {
    /// Lanes.
    pub v: Vi<N>,
    /// Producer.
    pub id: ValId,
}
/// Traced mask.
#[derive(Clone, Copy, Debug)]
pub struct TK<const N: usize> {
    /// Lanes.
    pub v: Vk<N>,
    /// Producer.
    pub id: ValId,
}
/// Traced scalar integer.
#[derive(Clone, Copy, Debug)]
pub struct TS {
    /// Value.
    pub v: i64,
    /// Producer.
    pub id: ValId,
}
/// Traced scalar f32.
#[derive(Clone, Copy, Debug)]
pub struct TX {
    /// Value.
    pub v: f32,
    /// Producer.
    pub id: ValId,
}

impl Int for TS {
    #[inline(always)]
    fn get(self) -> i64 {
        self.v
    }
}
impl Float for TX {
    #[inline(always)]
    fn get(self) -> f32 {
        self.v
    }
}

/// A traced machine of flavour `FL` with `N` lanes (e.g. `Traced<Avx2, 8>`).
#[derive(Debug)]
pub struct Traced<FL, const N: usize> {
    space: AddrSpace,
    trace: Trace,
    next: u32,
    region: Region,
    active: u32,
    /// The ISA's own lookup table region (compress-store permutations).
    lut: Option<Buf>,
    /// Where full chunks of [`STREAM_CHUNK`] ops go while a unit is
    /// streamed ([`Traced::stream_to`]); `None`: the trace keeps them.
    sink: Option<std::sync::mpsc::SyncSender<Trace>>,
    _f: PhantomData<FL>,
}

/// Ops in each chunk a streamed unit hands over but its last: a whole
/// number of the timing model's 256-op pieces (`sim::session::PIECE`).
pub const STREAM_CHUNK: usize = 1 << 15;

impl<FL, const N: usize> Clone for Traced<FL, N> {
    /// The same machine state (address space, values, buffers shared)
    /// with an empty trace and no sink: a second recorder of a frame's units.
    fn clone(&self) -> Self {
        Traced {
            space: self.space.clone(),
            trace: Trace::new(self.trace.flavour, &self.trace.source),
            next: self.next,
            region: self.region,
            active: self.active,
            lut: self.lut.clone(),
            sink: None,
            _f: PhantomData,
        }
    }
}

impl<FL: Flavour<N>, const N: usize> Traced<FL, N> {
    /// A machine recording a trace whose header says it came from `source`.
    #[must_use]
    pub fn new(source: &str) -> Self {
        let space = AddrSpace::new();
        let lut = Some(space.lut());
        Traced {
            lut,
            space,
            trace: Trace::new(FL::ID, source),
            next: 1,
            region: Region::Other,
            active: LaneMask::full(N).0,
            sink: None,
            _f: PhantomData,
        }
    }

    /// Hand the ops recorded from now on to `sink` in chunks of
    /// [`STREAM_CHUNK`] (each a trace with lane-address indices of its own),
    /// until [`Traced::end_stream`]. A closed sink is no error: the ops are
    /// dropped (the consumer stopped early).
    pub fn stream_to(&mut self, sink: std::sync::mpsc::SyncSender<Trace>) {
        self.sink = Some(sink);
    }

    /// Send the last chunk (possibly empty) and close the stream.
    pub fn end_stream(&mut self) {
        self.flush_chunk();
        self.sink = None;
    }

    /// Send the ops recorded so far as one chunk.
    #[cold]
    fn flush_chunk(&mut self) {
        let Some(sink) = &self.sink else { return };
        let mut c = Trace::new(FL::ID, &self.trace.source);
        c.regions = self.space.regions().to_vec();
        c.ops = std::mem::replace(&mut self.trace.ops, Vec::with_capacity(STREAM_CHUNK));
        c.lane_addrs = std::mem::take(&mut self.trace.lane_addrs);
        if sink.send(c).is_err() {
            self.sink = None;
        }
    }
    /// Record a parameter in the trace header.
    pub fn param(&mut self, key: &str, value: impl ToString) {
        self.trace.params.push((key.to_string(), value.to_string()));
    }
    /// Ops recorded so far.
    #[must_use]
    pub fn ops(&self) -> &[Op] {
        &self.trace.ops
    }
    /// The ops recorded since the last take (or since the start), as a trace
    /// with the address space's current regions in its header; recording goes
    /// on with the same values and memory (a frame's next unit).
    #[must_use]
    pub fn take(&mut self) -> Trace {
        let mut t = Trace::new(FL::ID, &self.trace.source);
        t.params = self.trace.params.clone();
        t.regions = self.space.regions().to_vec();
        let (ops, lanes) = crate::trace::pooled_buffers();
        t.ops = std::mem::replace(&mut self.trace.ops, ops);
        t.lane_addrs = std::mem::replace(&mut self.trace.lane_addrs, lanes);
        t
    }

    /// Finish: the trace with the address space's regions in its header.
    #[must_use]
    pub fn finish(mut self) -> Trace {
        self.trace.regions = self.space.regions().to_vec();
        self.trace
    }

    const FULL: u32 = if N == 32 { u32::MAX } else { (1u32 << N) - 1 };

    #[inline]
    fn fresh(&mut self) -> ValId {
        let id = ValId(self.next);
        self.next = self.next.checked_add(1).expect("more than 2^32 values");
        id
    }

    /// Record one op; returns its destination id (or NONE when `dst` is false).
    #[inline]
    fn emit(&mut self, class: OpClass, srcs: &[ValId], mask: u32, dst: bool) -> ValId {
        debug_assert!(srcs.len() <= MAX_SRCS, "too many sources");
        // The op built in one go (field-by-field edits of a stack copy cost
        // store-forwarding stalls when it is then copied into the buffer).
        let mut ids = [ValId::NONE; MAX_SRCS];
        let mut nsrc = 0;
        for &s in srcs {
            if s.is_some() {
                ids[nsrc] = s;
                nsrc += 1;
            }
        }
        let mask = LaneMask(if class.is_vector() {
            mask & self.active
        } else {
            mask
        });
        let id = if dst { self.fresh() } else { ValId::NONE };
        if self.trace.ops.len() >= STREAM_CHUNK && self.sink.is_some() {
            self.flush_chunk();
        }
        self.trace.ops.push(Op {
            class,
            region: self.region,
            flags: 0,
            nsrc: nsrc as u8,
            mask,
            dst: id,
            srcs: ids,
            addr: Addr(0),
            bytes: 0,
            mem: MemId(0),
            ilen: 0,
            aux: 0,
        });
        id
    }

    /// A full-width vector op with a result.
    #[inline]
    fn v(&mut self, class: OpClass, srcs: &[ValId]) -> ValId {
        self.emit(class, srcs, Self::FULL, true)
    }

    /// A scalar op with a result.
    #[inline]
    fn s(&mut self, class: OpClass, srcs: &[ValId]) -> ValId {
        self.emit(class, srcs, 1, true)
    }

    /// Record a memory op at byte `off` of `buf`.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn mem(
        &mut self,
        class: OpClass,
        srcs: &[ValId],
        mask: u32,
        buf: &Buf,
        off: usize,
        bytes: usize,
        dst: bool,
    ) -> ValId {
        assert!(
            off + bytes <= buf.len(),
            "{class} of {bytes} bytes at offset {off} outside region {} of {} bytes",
            buf.id().0,
            buf.len()
        );
        let id = self.emit(class, srcs, mask, dst);
        let op = self.trace.ops.last_mut().expect("just pushed");
        op.addr = buf.addr(off);
        op.bytes = bytes as u32;
        op.mem = buf.id();
        id
    }

    /// Record a gather or scatter with one address per active lane.
    fn per_lane(
        &mut self,
        class: OpClass,
        srcs: &[ValId],
        mask: u32,
        buf: &Buf,
        offs: &[usize],
        dst: bool,
    ) -> ValId {
        for &o in offs {
            assert!(
                o + 4 <= buf.len(),
                "{class} lane at offset {o} outside region {}",
                buf.id().0
            );
        }
        // The op first: a streamed unit may start a chunk with it, and its
        // lane addresses go with it.
        let id = self.emit(class, srcs, mask, dst);
        let first = self.trace.lane_addrs.len() as u32;
        for &o in offs {
            self.trace.lane_addrs.push(buf.addr(o));
        }
        let op = self.trace.ops.last_mut().expect("just pushed");
        op.mask = LaneMask(mask);
        op.addr = offs.first().map_or(Addr(0), |&o| buf.addr(o));
        op.bytes = 4;
        op.mem = buf.id();
        op.aux = first;
        id
    }

    #[inline]
    /// An address's byte offset, its index's and its base's values.
    fn ea(at: &At<TS>) -> (usize, ValId, ValId) {
        (
            base_ea_off(
                at.base.map(|s| s.v),
                at.index.map(|s| s.v),
                at.scale,
                at.disp,
            ),
            at.index.map_or(ValId::NONE, |s| s.id),
            at.base.map_or(ValId::NONE, |s| s.id),
        )
    }

    /// The divisor's value for a divide without a divide op (LRBni): its
    /// reciprocal, recorded; the divide itself is then a multiply.
    fn divisor(&mut self, op: BinOp, b: ValId) -> ValId {
        if op == BinOp::Div && !FL::DIV {
            self.v(OpClass::VRcp, &[b])
        } else {
            b
        }
    }

    fn bin_class(op: BinOp) -> OpClass {
        match op {
            BinOp::Add | BinOp::Sub => OpClass::VAdd,
            BinOp::Mul => OpClass::VMul,
            BinOp::Div if !FL::DIV => OpClass::VMul,
            BinOp::Div => OpClass::VDiv,
            BinOp::Min | BinOp::Max => OpClass::VMinMax,
        }
    }

    /// FMA family on `mask` lanes: fused op, or mul + add (+ sign flip).
    fn rec_fma(&mut self, kind: Fma, a: ValId, b: ValId, c: ValId, mask: u32) -> ValId {
        if FL::FMA {
            self.emit(OpClass::VFma, &[a, b, c], mask, true)
        } else {
            let p = self.emit(OpClass::VMul, &[a, b], mask, true);
            let s = self.emit(OpClass::VAdd, &[p, c], mask, true);
            if kind == Fma::NMSub {
                self.emit(OpClass::VLogic, &[s], mask, true)
            } else {
                s
            }
        }
    }

    /// Blend or masked move: `k ? t : f`.
    fn rec_select(&mut self, k: ValId, t: ValId, f: ValId) -> ValId {
        let class = if FL::MASK_REGS {
            OpClass::VMaskMov
        } else {
            OpClass::VBlend
        };
        self.v(class, &[f, t, k])
    }

    /// Lane `i` of vector `a` to a scalar register.
    fn rec_extract(&mut self, a: ValId, i: usize) -> ValId {
        if i == 0 {
            return a;
        }
        if i < 4 {
            return self.s(OpClass::VShuf, &[a]);
        }
        let blk = self.s(OpClass::VPerm, &[a]);
        if i.is_multiple_of(4) {
            blk
        } else {
            self.s(OpClass::VShuf, &[blk])
        }
    }

    /// Class of a one-source permute.
    fn perm_class(idx: &[u8; N]) -> OpClass {
        let in_lane = idx
            .iter()
            .enumerate()
            .all(|(i, &j)| j as usize / 4 == i / 4);
        if in_lane || !FL::CROSS_PERMUTE {
            OpClass::VShuf
        } else {
            OpClass::VPerm
        }
    }

    /// Whether a two-source pattern is one in-lane instruction: shufps
    /// (two lanes from x, two from y, same offsets in every 128-bit block),
    /// unpcklps/unpckhps, or blendps with an immediate.
    fn one_shuf(idx: &[u8; N]) -> bool {
        let n = N;
        let blend = idx
            .iter()
            .enumerate()
            .all(|(i, &j)| j as usize == i || j as usize == i + n);
        if blend {
            return true;
        }
        // (source, offset) per lane, requiring the lane's own block.
        let mut parts = [(0usize, 0usize); 32];
        for (i, &j) in idx.iter().enumerate() {
            let j = j as usize;
            let (src, e) = if j < n { (0, j) } else { (1, j - n) };
            if e / 4 != i / 4 {
                return false;
            }
            parts[i] = (src, e % 4);
        }
        let block0 = &parts[..4];
        let same_each_block = (0..n / 4).all(|b| parts[4 * b..4 * b + 4] == *block0);
        if !same_each_block {
            return false;
        }
        let shufps = block0[0].0 == block0[1].0 && block0[2].0 == block0[3].0;
        let unpck = [[0usize, 0, 1, 1], [2, 2, 3, 3]].iter().any(|offs| {
            (0..4).all(|i| block0[i].1 == offs[i])
                && block0[0].0 != block0[1].0
                && block0[0].0 == block0[2].0
                && block0[1].0 == block0[3].0
        });
        shufps || unpck
    }

    /// Whether each 128-bit block of the result is one whole block of a or b.
    fn block_perm(idx: &[u8; N]) -> bool {
        (0..N / 4).all(|b| {
            let s = idx[4 * b] as usize;
            s.is_multiple_of(4) && (0..4).all(|i| idx[4 * b + i] as usize == s + i)
        })
    }

    fn rec_shuffle2(&mut self, a: ValId, b: ValId, idx: &[u8; N]) -> ValId {
        if idx.iter().all(|&j| (j as usize) < N) {
            let c = Self::perm_class(idx);
            return self.v(c, &[a]);
        }
        if idx.iter().all(|&j| (j as usize) >= N) {
            let mut p = [0u8; N];
            for (o, &j) in p.iter_mut().zip(idx) {
                *o = j - N as u8;
            }
            let c = Self::perm_class(&p);
            return self.v(c, &[b]);
        }
        if Self::one_shuf(idx) {
            return self.v(OpClass::VShuf, &[a, b]);
        }
        if FL::PERMUTE2 || (N == 8 && Self::block_perm(idx)) {
            return self.v(OpClass::VPerm, &[a, b]);
        }
        // Two one-source permutes into place, then a blend by immediate.
        let mut pa = [0u8; N];
        let mut pb = [0u8; N];
        for i in 0..N {
            let j = idx[i] as usize;
            pa[i] = if j < N { j as u8 } else { i as u8 };
            pb[i] = if j >= N { (j - N) as u8 } else { i as u8 };
        }
        let ca = Self::perm_class(&pa);
        let x = self.v(ca, &[a]);
        let cb = Self::perm_class(&pb);
        let y = self.v(cb, &[b]);
        self.v(OpClass::VShuf, &[x, y])
    }

    fn tf(v: Vf<N>, id: ValId) -> TF<N> {
        TF { v, id }
    }
}

impl<FL: Flavour<N>, const N: usize> Machine for Traced<FL, N> {
    const LANES: usize = N;
    const FLAVOUR: FlavourId = FL::ID;
    type F = TF<N>;
    type I = TI<N>;
    type K = TK<N>;
    type S = TS;
    type X = TX;
    type Open<'b> = &'b mut Buf;

    #[inline]
    fn space(&mut self) -> &mut AddrSpace {
        &mut self.space
    }
    #[inline]
    fn region(&mut self, r: Region) {
        self.region = r;
    }
    #[inline]
    fn active(&mut self, k: Option<TK<N>>) {
        self.active = k.map_or(Self::FULL, |k| k.v.bits());
    }

    #[inline]
    fn splat(&mut self, x: f32) -> TF<N> {
        Self::tf(Vf([x; N]), ValId::NONE)
    }
    #[inline]
    fn consts(&mut self, v: &[f32]) -> TF<N> {
        Self::tf(Vf(arr(v)), ValId::NONE)
    }
    #[inline]
    fn splat_i(&mut self, x: i32) -> TI<N> {
        TI {
            v: Vi([x; N]),
            id: ValId::NONE,
        }
    }
    #[inline]
    fn consts_i(&mut self, v: &[i32]) -> TI<N> {
        TI {
            v: Vi(arr(v)),
            id: ValId::NONE,
        }
    }
    #[inline]
    fn mask(&mut self, bits: u32) -> TK<N> {
        TK {
            v: Vk::from_bits(bits),
            id: ValId::NONE,
        }
    }
    #[inline]
    fn int(&mut self, v: i64) -> TS {
        TS { v, id: ValId::NONE }
    }
    #[inline]
    fn float(&mut self, v: f32) -> TX {
        TX { v, id: ValId::NONE }
    }

    #[inline]
    fn bin(&mut self, op: BinOp, a: TF<N>, b: TF<N>) -> TF<N> {
        let b_id = self.divisor(op, b.id);
        let id = self.v(Self::bin_class(op), &[a.id, b_id]);
        Self::tf(a.v.zip(b.v, |x, y| FL::eval(op, x, y)), id)
    }
    #[inline]
    fn masked(&mut self, op: BinOp, k: TK<N>, src: TF<N>, a: TF<N>, b: TF<N>) -> TF<N> {
        let v = k.v.select(a.v.zip(b.v, |x, y| FL::eval(op, x, y)), src.v);
        let b = TF {
            v: b.v,
            id: self.divisor(op, b.id),
        };
        let id = if FL::MASK_REGS {
            self.emit(
                Self::bin_class(op),
                &[a.id, b.id, k.id, src.id],
                k.v.bits(),
                true,
            )
        } else {
            let t = self.v(Self::bin_class(op), &[a.id, b.id]);
            self.rec_select(k.id, t, src.id)
        };
        Self::tf(v, id)
    }
    #[inline]
    fn fma(&mut self, kind: Fma, a: TF<N>, b: TF<N>, c: TF<N>) -> TF<N> {
        let id = self.rec_fma(kind, a.id, b.id, c.id, Self::FULL);
        Self::tf(
            a.v.zip3(b.v, c.v, |x, y, z| kind.eval(FL::FMA, x, y, z)),
            id,
        )
    }
    #[inline]
    fn masked_fma(&mut self, kind: Fma, k: TK<N>, a: TF<N>, b: TF<N>, c: TF<N>) -> TF<N> {
        let v = k.v.select(
            a.v.zip3(b.v, c.v, |x, y, z| kind.eval(FL::FMA, x, y, z)),
            c.v,
        );
        let id = if FL::MASK_REGS {
            self.emit(OpClass::VFma, &[a.id, b.id, c.id, k.id], k.v.bits(), true)
        } else {
            let t = self.rec_fma(kind, a.id, b.id, c.id, Self::FULL);
            self.rec_select(k.id, t, c.id)
        };
        Self::tf(v, id)
    }
    #[inline]
    fn abs(&mut self, a: TF<N>) -> TF<N> {
        let id = self.v(OpClass::VLogic, &[a.id]);
        Self::tf(a.v.map(f32::abs), id)
    }
    #[inline]
    fn neg(&mut self, a: TF<N>) -> TF<N> {
        let id = self.v(OpClass::VLogic, &[a.id]);
        Self::tf(a.v.map(|x| -x), id)
    }
    #[inline]
    fn sqrt(&mut self, a: TF<N>) -> TF<N> {
        let id = self.v(OpClass::VSqrt, &[a.id]);
        Self::tf(a.v.map(f32::sqrt), id)
    }
    #[inline]
    fn rcp(&mut self, a: TF<N>) -> TF<N> {
        if !FL::DIV {
            return self.rcp_approx(a);
        }
        let id = self.v(OpClass::VDiv, &[a.id]);
        Self::tf(a.v.map(|x| 1.0 / x), id)
    }
    #[inline]
    fn rcp_approx(&mut self, a: TF<N>) -> TF<N> {
        let id = self.v(OpClass::VRcp, &[a.id]);
        Self::tf(a.v.map(|x| rcp_approx(x, FL::RCP_BITS)), id)
    }
    #[inline]
    fn rsqrt(&mut self, a: TF<N>) -> TF<N> {
        let s = self.v(OpClass::VSqrt, &[a.id]);
        let inv = if FL::DIV {
            OpClass::VDiv
        } else {
            OpClass::VRcp
        };
        let id = self.v(inv, &[s]);
        Self::tf(a.v.map(|x| 1.0 / x.sqrt()), id)
    }
    #[inline]
    fn rsqrt_approx(&mut self, a: TF<N>) -> TF<N> {
        let id = self.v(OpClass::VRsqrt, &[a.id]);
        Self::tf(a.v.map(|x| rsqrt_approx(x, FL::RCP_BITS)), id)
    }
    #[inline]
    fn cmp(&mut self, p: Cmp, a: TF<N>, b: TF<N>) -> TK<N> {
        let id = self.v(OpClass::VCmp, &[a.id, b.id]);
        TK {
            v: a.v.cmp(p, b.v),
            id,
        }
    }
    #[inline]
    fn select(&mut self, k: TK<N>, t: TF<N>, f: TF<N>) -> TF<N> {
        let id = self.rec_select(k.id, t.id, f.id);
        Self::tf(k.v.select(t.v, f.v), id)
    }
    #[inline]
    fn blend_sign(&mut self, s: TF<N>, a: TF<N>, b: TF<N>) -> TF<N> {
        let v = Vf(std::array::from_fn(|i| {
            if s.v.0[i].is_sign_negative() {
                b.v.0[i]
            } else {
                a.v.0[i]
            }
        }));
        let id = if FL::MASK_REGS {
            // vpmovd2m / a signed integer compare with zero, then a masked move.
            let k = self.v(OpClass::VICmp, &[s.id]);
            self.v(OpClass::VMaskMov, &[a.id, b.id, k])
        } else {
            self.v(OpClass::VBlend, &[a.id, b.id, s.id])
        };
        Self::tf(v, id)
    }
    #[inline]
    fn logic(&mut self, op: Logic, a: TF<N>, b: TF<N>) -> TF<N> {
        let id = self.v(OpClass::VLogic, &[a.id, b.id]);
        Self::tf(
            a.v.zip(b.v, |x, y| {
                f32::from_bits(op.eval(x.to_bits(), y.to_bits()))
            }),
            id,
        )
    }
    #[inline]
    fn broadcast(&mut self, x: TX) -> TF<N> {
        let id = self.v(OpClass::VBcast, &[x.id]);
        Self::tf(Vf([x.v; N]), id)
    }
    #[inline]
    fn extract(&mut self, a: TF<N>, i: usize) -> TX {
        assert!(i < N, "lane {i} of {N}");
        let id = self.rec_extract(a.id, i);
        TX { v: a.v.0[i], id }
    }
    #[inline]
    fn permute(&mut self, a: TF<N>, idx: &[u8]) -> TF<N> {
        let idx = idx_arr::<N>(idx, N);
        let id = self.v(Self::perm_class(&idx), &[a.id]);
        Self::tf(permute2(a.v, a.v, &idx), id)
    }
    #[inline]
    fn shuffle2(&mut self, a: TF<N>, b: TF<N>, idx: &[u8]) -> TF<N> {
        let idx = idx_arr::<N>(idx, 2 * N);
        let id = self.rec_shuffle2(a.id, b.id, &idx);
        Self::tf(permute2(a.v, b.v, &idx), id)
    }
    #[inline]
    fn reduce(&mut self, op: BinOp, a: TF<N>) -> TX {
        let v = reduce_op(op, a.v);
        let class = Self::bin_class(op);
        let mut id = a.id;
        let mut d = N / 2;
        while d >= 1 {
            let pat = xor_pattern::<N>(d);
            let sh = self.v(Self::perm_class(&pat), &[id]);
            id = self.v(class, &[id, sh]);
            d /= 2;
        }
        TX { v, id }
    }
    #[inline]
    fn to_int(&mut self, a: TF<N>) -> TI<N> {
        let id = self.v(OpClass::VCvt, &[a.id]);
        let mut r = [0i32; N];
        for i in 0..N {
            r[i] = cvt_trunc(a.v.0[i]);
        }
        TI { v: Vi(r), id }
    }
    #[inline]
    fn to_int_round(&mut self, a: TF<N>) -> TI<N> {
        let id = self.v(OpClass::VCvt, &[a.id]);
        let mut r = [0i32; N];
        for i in 0..N {
            r[i] = cvt_round(a.v.0[i]);
        }
        TI { v: Vi(r), id }
    }
    #[inline]
    fn to_float(&mut self, a: TI<N>) -> TF<N> {
        let id = self.v(OpClass::VCvt, &[a.id]);
        let mut r = [0f32; N];
        for i in 0..N {
            r[i] = a.v.0[i] as f32;
        }
        Self::tf(Vf(r), id)
    }
    #[inline]
    fn bits_to_i(&mut self, a: TF<N>) -> TI<N> {
        TI {
            v: a.v.to_bits(),
            id: a.id,
        }
    }
    #[inline]
    fn bits_to_f(&mut self, a: TI<N>) -> TF<N> {
        Self::tf(a.v.to_f32_bits(), a.id)
    }

    #[inline]
    fn iop(&mut self, op: IOp, a: TI<N>, b: TI<N>) -> TI<N> {
        let class = match op {
            IOp::Add | IOp::Sub | IOp::Min | IOp::Max => OpClass::VIAdd,
            IOp::Mul => OpClass::VIMul,
            IOp::And | IOp::Or | IOp::Xor | IOp::AndNot => OpClass::VILogic,
        };
        let id = self.v(class, &[a.id, b.id]);
        TI {
            v: a.v.zip(b.v, |x, y| op.eval(x, y)),
            id,
        }
    }
    #[inline]
    fn ishift(&mut self, s: Shift, a: TI<N>, n: u32) -> TI<N> {
        let id = self.v(OpClass::VIShift, &[a.id]);
        TI {
            v: a.v.map(|x| s.eval32(x, n)),
            id,
        }
    }
    #[inline]
    fn icmp(&mut self, p: Cmp, a: TI<N>, b: TI<N>) -> TK<N> {
        assert!(!matches!(p, Cmp::Ord | Cmp::Unord), "integer compare {p:?}");
        let mut id = self.v(OpClass::VICmp, &[a.id, b.id]);
        if !FL::MASK_REGS && matches!(p, Cmp::Ne | Cmp::Le | Cmp::Ge) {
            // pcmpeqd/pcmpgtd only: the complement needs an xor with all ones.
            id = self.v(OpClass::VILogic, &[id]);
        }
        let mut r = [0i32; N];
        for i in 0..N {
            r[i] = -(p.eval_i(i64::from(a.v.0[i]), i64::from(b.v.0[i])) as i32);
        }
        TK { v: Vk(r), id }
    }
    #[inline]
    fn keep(&mut self, k: TK<N>, a: TF<N>) -> TF<N> {
        let class = if FL::MASK_REGS {
            OpClass::VMaskMov
        } else {
            OpClass::VLogic
        };
        let id = self.v(class, &[a.id, k.id]);
        Self::tf(k.v.select(a.v, Vf([0.0; N])), id)
    }

    #[inline]
    fn keep_i(&mut self, k: TK<N>, a: TI<N>) -> TI<N> {
        let class = if FL::MASK_REGS {
            OpClass::VMaskMov
        } else {
            OpClass::VILogic
        };
        let id = self.v(class, &[a.id, k.id]);
        TI {
            v: k.v.select_i(a.v, Vi([0; N])),
            id,
        }
    }

    #[inline]
    fn iselect(&mut self, k: TK<N>, t: TI<N>, f: TI<N>) -> TI<N> {
        let id = self.rec_select(k.id, t.id, f.id);
        TI {
            v: k.v.select_i(t.v, f.v),
            id,
        }
    }

    #[inline]
    fn klogic(&mut self, op: Logic, a: TK<N>, b: TK<N>) -> TK<N> {
        let class = if FL::MASK_REGS {
            OpClass::KLogic
        } else {
            OpClass::VLogic
        };
        let id = self.v(class, &[a.id, b.id]);
        TK {
            v: a.v.zip(b.v, |x, y| op.eval_b(x, y)),
            id,
        }
    }
    #[inline]
    fn knot(&mut self, a: TK<N>) -> TK<N> {
        let class = if FL::MASK_REGS {
            OpClass::KLogic
        } else {
            OpClass::VLogic
        };
        let id = self.v(class, &[a.id]);
        TK {
            v: a.v.zip(a.v, |x, _| !x),
            id,
        }
    }
    #[inline]
    fn kmov(&mut self, bits: TS) -> TK<N> {
        let v = Vk::from_bits((bits.v as u64 & ((1u64 << N) - 1)) as u32);
        let id = if FL::MASK_REGS {
            self.v(OpClass::KLogic, &[bits.id])
        } else {
            let b = self.v(OpClass::VBcast, &[bits.id]);
            let a = self.v(OpClass::VILogic, &[b]);
            self.v(OpClass::VICmp, &[a])
        };
        TK { v, id }
    }
    #[inline]
    fn movemask(&mut self, k: TK<N>) -> TS {
        let id = self.s(OpClass::MovMsk, &[k.id]);
        TS {
            v: i64::from(k.v.bits()),
            id,
        }
    }
    #[inline]
    fn popcnt(&mut self, k: TK<N>) -> TS {
        let m = self.s(OpClass::MovMsk, &[k.id]);
        let id = self.s(OpClass::BitCnt, &[m]);
        TS {
            v: i64::from(k.v.bits().count_ones()),
            id,
        }
    }
    #[inline]
    fn bitscan(&mut self, k: TK<N>) -> TS {
        let m = self.s(OpClass::MovMsk, &[k.id]);
        let g = self.s(OpClass::Alu, &[m]);
        let id = self.s(OpClass::BitCnt, &[g]);
        TS {
            v: i64::from(k.v.bits().trailing_zeros().min(N as u32)),
            id,
        }
    }
    #[inline]
    fn any(&mut self, k: TK<N>) -> TS {
        let id = self.s(OpClass::KTest, &[k.id]);
        TS {
            v: i64::from(k.v.bits() != 0),
            id,
        }
    }
    #[inline]
    fn all(&mut self, k: TK<N>) -> TS {
        let id = self.s(OpClass::KTest, &[k.id]);
        TS {
            v: i64::from(k.v.bits() == Self::FULL),
            id,
        }
    }

    #[inline]
    fn load(&mut self, buf: &Buf, at: At<TS>) -> TF<N> {
        let (off, ix, bx) = Self::ea(&at);
        assert!(
            buf.addr(off).0.is_multiple_of(4 * N as u64),
            "misaligned {}-byte load at {}",
            4 * N,
            buf.addr(off)
        );
        let id = self.mem(OpClass::VLoad, &[ix, bx], Self::FULL, buf, off, 4 * N, true);
        Self::tf(Vf(buf.f32s::<N>(off)), id)
    }
    #[inline]
    fn loadu(&mut self, buf: &Buf, at: At<TS>) -> TF<N> {
        let (off, ix, bx) = Self::ea(&at);
        let id = self.mem(OpClass::VLoad, &[ix, bx], Self::FULL, buf, off, 4 * N, true);
        Self::tf(Vf(buf.f32s::<N>(off)), id)
    }
    #[inline]
    fn load_bcast(&mut self, buf: &Buf, at: At<TS>) -> TF<N> {
        let (off, ix, bx) = Self::ea(&at);
        let id = self.mem(
            OpClass::VLoadBcast,
            &[ix, bx],
            Self::FULL,
            buf,
            off,
            4,
            true,
        );
        Self::tf(Vf([buf.f32_at(off); N]), id)
    }
    #[inline]
    fn load_operand(&mut self, buf: &Buf, at: At<TS>, n: usize) -> TF<N> {
        if !FL::folds(n) {
            return self.load_repeat(buf, at, n);
        }
        assert!(N.is_multiple_of(n), "repeat of {n} lanes in {N}");
        let (off, ix, bx) = Self::ea(&at);
        let id = self.mem(
            OpClass::VLoadFold,
            &[ix, bx],
            Self::FULL,
            buf,
            off,
            4 * n,
            true,
        );
        let v: [f32; N] = std::array::from_fn(|i| buf.f32_at(off + 4 * (i % n)));
        Self::tf(Vf(v), id)
    }
    #[inline]
    fn load_repeat(&mut self, buf: &Buf, at: At<TS>, n: usize) -> TF<N> {
        assert!(n > 0 && N.is_multiple_of(n), "repeat of {n} lanes in {N}");
        let (off, ix, bx) = Self::ea(&at);
        let id = if n == N {
            self.mem(OpClass::VLoad, &[ix, bx], Self::FULL, buf, off, 4 * n, true)
        } else if matches!(n, 1 | 4 | 8) {
            self.mem(
                OpClass::VLoadBcast,
                &[ix, bx],
                Self::FULL,
                buf,
                off,
                4 * n,
                true,
            )
        } else {
            let l = self.mem(OpClass::VLoad, &[ix, bx], Self::FULL, buf, off, 4 * n, true);
            self.v(OpClass::VPerm, &[l])
        };
        let mut r = [0f32; N];
        for (i, x) in r.iter_mut().enumerate() {
            *x = buf.f32_at(off + 4 * (i % n));
        }
        Self::tf(Vf(r), id)
    }
    #[inline]
    fn load_masked(&mut self, k: TK<N>, src: TF<N>, buf: &Buf, at: At<TS>) -> TF<N> {
        let (off, ix, bx) = Self::ea(&at);
        let bits = k.v.bits();
        let id = if FL::MASK_REGS {
            self.mem(
                OpClass::VLoadMasked,
                &[ix, bx, k.id, src.id],
                bits,
                buf,
                off,
                4 * N,
                true,
            )
        } else {
            let class = if FL::MASKED_MEM {
                OpClass::VLoadMasked
            } else {
                OpClass::VLoad
            };
            let l = self.mem(class, &[ix, k.id], Self::FULL, buf, off, 4 * N, true);
            self.rec_select(k.id, l, src.id)
        };
        let mut r = src.v.0;
        for (i, x) in r.iter_mut().enumerate() {
            if k.v.get(i) {
                *x = buf.f32_at(off + 4 * i);
            }
        }
        Self::tf(Vf(r), id)
    }
    #[inline]
    fn store(&mut self, buf: &mut Buf, at: At<TS>, v: TF<N>) {
        let (off, ix, bx) = Self::ea(&at);
        assert!(
            buf.addr(off).0.is_multiple_of(4 * N as u64),
            "misaligned {}-byte store at {}",
            4 * N,
            buf.addr(off)
        );
        self.mem(
            OpClass::VStore,
            &[ix, bx, v.id],
            Self::FULL,
            buf,
            off,
            4 * N,
            false,
        );
        buf.set_f32s(off, &v.v.0);
    }
    #[inline]
    fn storeu(&mut self, buf: &mut Buf, at: At<TS>, v: TF<N>) {
        let (off, ix, bx) = Self::ea(&at);
        self.mem(
            OpClass::VStore,
            &[ix, bx, v.id],
            Self::FULL,
            buf,
            off,
            4 * N,
            false,
        );
        buf.set_f32s(off, &v.v.0);
    }
    #[inline]
    fn store_masked(&mut self, k: TK<N>, buf: &mut Buf, at: At<TS>, v: TF<N>) {
        let (off, ix, bx) = Self::ea(&at);
        let bits = k.v.bits();
        if FL::MASKED_MEM {
            self.mem(
                OpClass::VStoreMasked,
                &[ix, bx, k.id, v.id],
                bits,
                buf,
                off,
                4 * N,
                false,
            );
        } else {
            self.s(OpClass::MovMsk, &[k.id]);
            for i in 0..N {
                if k.v.get(i) {
                    let e = self.rec_extract(v.id, i);
                    self.mem(OpClass::Store, &[ix, e], 1, buf, off + 4 * i, 4, false);
                }
            }
        }
        for i in 0..N {
            if k.v.get(i) {
                buf.set_f32(off + 4 * i, v.v.0[i]);
            }
        }
    }
    #[inline]
    fn gather(
        &mut self,
        k: TK<N>,
        src: TF<N>,
        buf: &Buf,
        at: At<TS>,
        idx: TI<N>,
        scale: u8,
    ) -> TF<N> {
        let (off, ix, bx) = Self::ea(&at);
        assert!(!bx.is_some(), "a gather or scatter takes no base register");
        let bits = k.v.bits();
        let mut offs = [0usize; N];
        let mut n = 0;
        let mut r = src.v.0;
        for i in 0..N {
            if k.v.get(i) {
                let o = ea_off(Some(i64::from(idx.v.0[i])), scale, off);
                r[i] = buf.f32_at(o);
                offs[n] = o;
                n += 1;
            }
        }
        let id = if FL::GATHER {
            self.per_lane(
                OpClass::VGather,
                &[ix, idx.id, k.id, src.id],
                bits,
                buf,
                &offs[..n],
                true,
            )
        } else {
            let mut acc = src.id;
            let mut j = 0;
            for i in 0..N {
                if k.v.get(i) {
                    let e = self.rec_extract(idx.id, i);
                    let l = self.mem(OpClass::Load, &[ix, e], 1, buf, offs[j], 4, true);
                    acc = self.v(OpClass::VInsert, &[acc, l]);
                    j += 1;
                }
            }
            acc
        };
        Self::tf(Vf(r), id)
    }
    #[inline]
    fn scatter(&mut self, k: TK<N>, buf: &mut Buf, at: At<TS>, idx: TI<N>, scale: u8, v: TF<N>) {
        let (off, ix, bx) = Self::ea(&at);
        assert!(!bx.is_some(), "a gather or scatter takes no base register");
        let bits = k.v.bits();
        let mut offs = [0usize; N];
        let mut n = 0;
        for i in 0..N {
            if k.v.get(i) {
                offs[n] = ea_off(Some(i64::from(idx.v.0[i])), scale, off);
                n += 1;
            }
        }
        if FL::SCATTER {
            self.per_lane(
                OpClass::VScatter,
                &[ix, idx.id, k.id, v.id],
                bits,
                buf,
                &offs[..n],
                false,
            );
        } else {
            self.s(OpClass::MovMsk, &[k.id]);
            let mut j = 0;
            for i in 0..N {
                if k.v.get(i) {
                    let ei = self.rec_extract(idx.id, i);
                    let ev = self.rec_extract(v.id, i);
                    self.mem(OpClass::Store, &[ix, ei, ev], 1, buf, offs[j], 4, false);
                    j += 1;
                }
            }
        }
        let mut j = 0;
        for i in 0..N {
            if k.v.get(i) {
                buf.set_f32(offs[j], v.v.0[i]);
                j += 1;
            }
        }
    }
    #[inline]
    fn compress_store(&mut self, k: TK<N>, buf: &mut Buf, at: At<TS>, v: TF<N>) -> TS {
        let (off, ix, bx) = Self::ea(&at);
        let bits = k.v.bits();
        let (packed, n) = compress_lanes(k.v, v.v);
        let id = if FL::COMPRESS {
            self.mem(
                OpClass::VCompress,
                &[ix, bx, k.id, v.id],
                bits,
                buf,
                off,
                4 * n,
                false,
            );
            let m = self.s(OpClass::MovMsk, &[k.id]);
            self.s(OpClass::BitCnt, &[m])
        } else {
            let m = self.s(OpClass::MovMsk, &[k.id]);
            let lut = self.lut.take().expect("lut present");
            let entry = 4 * N * bits as usize;
            let p = self.mem(OpClass::VLoad, &[m], Self::FULL, &lut, entry, 4 * N, true);
            self.lut = Some(lut);
            let class = if N > 4 {
                OpClass::VPerm
            } else {
                OpClass::VShuf
            };
            let s = self.v(class, &[v.id, p]);
            self.mem(
                OpClass::VStore,
                &[ix, s],
                Self::FULL,
                buf,
                off,
                4 * N,
                false,
            );
            self.s(OpClass::BitCnt, &[m])
        };
        if FL::COMPRESS {
            for i in 0..n {
                buf.set_f32(off + 4 * i, packed.0[i]);
            }
        } else {
            buf.set_f32s(off, &packed.0);
        }
        TS { v: n as i64, id }
    }

    #[inline]
    fn s_op(&mut self, op: SOp, a: TS, b: TS) -> TS {
        let id = match op {
            SOp::Add | SOp::Sub | SOp::And | SOp::Or | SOp::Xor => {
                self.s(OpClass::Alu, &[a.id, b.id])
            }
            SOp::Mul => self.s(OpClass::IMul, &[a.id, b.id]),
            SOp::Min | SOp::Max => {
                let c = self.s(OpClass::Cmp, &[a.id, b.id]);
                self.s(OpClass::Cmov, &[c, a.id, b.id])
            }
        };
        TS {
            v: op.eval(a.v, b.v),
            id,
        }
    }
    #[inline]
    fn s_shift(&mut self, s: Shift, a: TS, n: u32) -> TS {
        let id = self.s(OpClass::Alu, &[a.id]);
        TS {
            v: s.eval64(a.v, n),
            id,
        }
    }
    #[inline]
    fn s_cmp(&mut self, p: Cmp, a: TS, b: TS) -> TS {
        let id = self.s(OpClass::Cmp, &[a.id, b.id]);
        TS {
            v: i64::from(p.eval_i(a.v, b.v)),
            id,
        }
    }
    #[inline]
    fn s_select(&mut self, c: TS, a: TS, b: TS) -> TS {
        let id = self.s(OpClass::Cmov, &[c.id, a.id, b.id]);
        TS {
            v: if c.v != 0 { a.v } else { b.v },
            id,
        }
    }
    #[inline]
    fn s_popcnt(&mut self, a: TS) -> TS {
        let id = self.s(OpClass::BitCnt, &[a.id]);
        TS {
            v: i64::from(a.v.count_ones()),
            id,
        }
    }
    #[inline]
    fn s_tzcnt(&mut self, a: TS) -> TS {
        let id = self.s(OpClass::BitCnt, &[a.id]);
        TS {
            v: i64::from(a.v.trailing_zeros()),
            id,
        }
    }
    #[inline]
    fn s_load(&mut self, buf: &Buf, at: At<TS>, width: u8, signed: bool) -> TS {
        let (off, ix, bx) = Self::ea(&at);
        let id = self.mem(OpClass::Load, &[ix, bx], 1, buf, off, width as usize, true);
        TS {
            v: load_int(buf, off, width, signed),
            id,
        }
    }
    #[inline]
    fn s_store(&mut self, buf: &mut Buf, at: At<TS>, width: u8, v: TS) {
        let (off, ix, bx) = Self::ea(&at);
        self.mem(
            OpClass::Store,
            &[ix, bx, v.id],
            1,
            buf,
            off,
            width as usize,
            false,
        );
        buf.set_uint(off, width as usize, v.v as u64);
    }

    #[inline]
    fn open<'b>(&mut self, buf: &'b mut Buf) -> &'b mut Buf {
        buf
    }
    #[inline]
    fn s_store_open(&mut self, buf: &mut &mut Buf, at: At<TS>, width: u8, v: TS) {
        self.s_store(buf, at, width, v);
    }

    #[inline]
    fn x_op(&mut self, op: BinOp, a: TX, b: TX) -> TX {
        let id = self.s(Self::bin_class(op), &[a.id, b.id]);
        TX {
            v: op.eval(a.v, b.v),
            id,
        }
    }
    #[inline]
    fn x_fma(&mut self, kind: Fma, a: TX, b: TX, c: TX) -> TX {
        let id = self.rec_fma(kind, a.id, b.id, c.id, 1);
        TX {
            v: kind.eval(FL::FMA, a.v, b.v, c.v),
            id,
        }
    }
    #[inline]
    fn x_sqrt(&mut self, a: TX) -> TX {
        let id = self.s(OpClass::VSqrt, &[a.id]);
        TX { v: a.v.sqrt(), id }
    }
    #[inline]
    fn x_cmp(&mut self, p: Cmp, a: TX, b: TX) -> TS {
        let id = self.s(OpClass::VCmp, &[a.id, b.id]);
        TS {
            v: i64::from(p.eval(a.v, b.v)),
            id,
        }
    }
    #[inline]
    fn x_load(&mut self, buf: &Buf, at: At<TS>) -> TX {
        let (off, ix, bx) = Self::ea(&at);
        let id = self.mem(OpClass::Load, &[ix, bx], 1, buf, off, 4, true);
        TX {
            v: buf.f32_at(off),
            id,
        }
    }
    #[inline]
    fn x_store(&mut self, buf: &mut Buf, at: At<TS>, v: TX) {
        let (off, ix, bx) = Self::ea(&at);
        self.mem(OpClass::Store, &[ix, bx, v.id], 1, buf, off, 4, false);
        buf.set_f32(off, v.v);
    }

    #[inline]
    fn x_from_int(&mut self, a: TS) -> TX {
        let id = self.s(OpClass::VCvt, &[a.id]);
        TX { v: a.v as f32, id }
    }
    #[inline]
    fn x_to_int(&mut self, a: TX) -> TS {
        let id = self.s(OpClass::VCvt, &[a.id]);
        TS {
            v: a.v as i32 as i64,
            id,
        }
    }

    #[inline]
    fn branch(&mut self, site: Site, c: TS) -> bool {
        let taken = c.v != 0;
        self.emit(OpClass::Branch, &[c.id], 1, false);
        let op = self.trace.ops.last_mut().expect("just pushed");
        op.aux = site.0;
        if taken {
            op.flags |= FLAG_TAKEN;
        }
        taken
    }

    #[inline]
    fn lane(&self, a: TF<N>, i: usize) -> f32 {
        a.v.0[i]
    }
    #[inline]
    fn lane_i(&self, a: TI<N>, i: usize) -> i32 {
        a.v.0[i]
    }
    #[inline]
    fn bits(&self, k: TK<N>) -> u32 {
        k.v.bits()
    }
}

/// The ops of a trace that a closure produced, for expansion tests: returns
/// the classes recorded by `f` on a fresh machine.
pub fn classes_of<FL: Flavour<N>, const N: usize>(
    f: impl FnOnce(&mut Traced<FL, N>),
) -> Vec<OpClass> {
    let mut m = Traced::<FL, N>::new("test");
    f(&mut m);
    m.ops().iter().map(|o| o.class).collect()
}
