//! Built-in microkernels for calibrating a machine model: a dependent chain and
//! independent streams per op class, a pointer chase over a working set,
//! streaming loads and stores, predictable and random branches.
//!
//! Every loop iteration ends with the loop's own scalar work (counter add,
//! compare, branch), as a real loop has; chains unroll `unroll` dependent ops
//! per iteration so that overhead is small and known.

#![warn(missing_docs)]

use isa::rng::Rng;
use isa::{At, BinOp, Cmp, IOp, Machine, MemKind, Program, Region, Shift, Site};
use std::fmt;

/// Loop-back branch site of every microkernel.
pub const SITE_LOOP: Site = isa::sites::MICRO.at(0);
/// The data-dependent branch of the branch microkernels.
pub const SITE_DATA: Site = isa::sites::MICRO.at(1);

/// Every branch site of the module (checked for duplicates by the layout test).
pub const SITES: [Site; 2] = [SITE_LOOP, SITE_DATA];

/// The op a chain or stream microkernel repeats.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ChainOp {
    /// vfmadd
    Fma,
    /// vaddps
    Add,
    /// vmulps
    Mul,
    /// vdivps
    Div,
    /// vsqrtps
    Sqrt,
    /// vmaxps
    MinMax,
    /// vandps
    Logic,
    /// vblendvps / masked move
    Blend,
    /// in-lane shuffle
    Shuf,
    /// cross-lane permute
    Perm,
    /// approximate reciprocal
    Rcp,
    /// approximate rsqrt
    Rsqrt,
    /// broadcast from a scalar register
    Bcast,
    /// int <-> float conversion (alternating)
    Cvt,
    /// vector int add
    IAdd,
    /// vector int multiply
    IMul,
    /// vector int shift
    IShift,
    /// vector int logic
    ILogic,
    /// vector compare (streams only: a compare's result is a mask)
    Cmp,
    /// scalar ALU add
    Alu,
    /// scalar multiply
    SMul,
    /// popcnt
    BitCnt,
}

/// Every chainable op with its name prefix.
pub const CHAIN_OPS: &[(ChainOp, &str)] = &[
    (ChainOp::Fma, "fma"),
    (ChainOp::Add, "add"),
    (ChainOp::Mul, "mul"),
    (ChainOp::Div, "div"),
    (ChainOp::Sqrt, "sqrt"),
    (ChainOp::MinMax, "minmax"),
    (ChainOp::Logic, "logic"),
    (ChainOp::Blend, "blend"),
    (ChainOp::Shuf, "shuf"),
    (ChainOp::Perm, "perm"),
    (ChainOp::Rcp, "rcp"),
    (ChainOp::Rsqrt, "rsqrt"),
    (ChainOp::Bcast, "bcast"),
    (ChainOp::Cvt, "cvt"),
    (ChainOp::IAdd, "iadd"),
    (ChainOp::IMul, "imul"),
    (ChainOp::IShift, "ishift"),
    (ChainOp::ILogic, "ilogic"),
    (ChainOp::Cmp, "cmp"),
    (ChainOp::Alu, "alu"),
    (ChainOp::SMul, "smul"),
    (ChainOp::BitCnt, "bitcnt"),
];

/// What a microkernel measures.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// One dependent chain: latency.
    Chain(ChainOp),
    /// `streams` independent chains: reciprocal throughput.
    Streams(ChainOp),
    /// Dependent loads over a random cycle of lines: load-to-use latency.
    PointerChase,
    /// Sequential vector loads: load bandwidth.
    StreamLoad,
    /// Sequential vector stores: store bandwidth.
    StreamStore,
    /// A data-dependent branch with a short repeating pattern.
    BranchPredictable,
    /// A data-dependent branch taken with probability 1/2.
    BranchRandom,
}

/// Parameters of a microkernel run.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MicroParams {
    /// Loop iterations.
    pub iters: usize,
    /// Ops per stream (chains, streams), loads (pointer chase, streaming) per iteration;
    /// `iters` counts iterations for chains and streams, loads for the others.
    pub unroll: usize,
    /// Independent chains (streams).
    pub streams: usize,
    /// Working set in bytes (pointer chase, streaming).
    pub ws: usize,
    /// Bytes between chased nodes (pointer chase; a multiple of 8).
    pub stride: usize,
    /// Seed of the random cycle and branch outcomes.
    pub seed: u64,
}

impl Default for MicroParams {
    fn default() -> Self {
        MicroParams {
            iters: 1000,
            unroll: 8,
            streams: 10,
            ws: 16 * 1024,
            stride: CHASE_STRIDE,
            seed: 1,
        }
    }
}

impl MicroParams {
    /// Set a parameter from `key=value` text.
    pub fn set(&mut self, key: &str, value: &str) -> Result<(), String> {
        let v: u64 = parse_size(value).ok_or_else(|| {
            format!("parameter {key}: '{value}' is not a whole number (K, M suffixes allowed)")
        })?;
        let nonzero = |v: u64| {
            if v == 0 {
                Err(format!("parameter {key} must be at least 1"))
            } else {
                Ok(v as usize)
            }
        };
        match key {
            "iters" => self.iters = nonzero(v)?,
            "unroll" => self.unroll = nonzero(v)?,
            "streams" => self.streams = nonzero(v)?,
            "ws" => {
                if v < 128 {
                    return Err(format!("parameter ws must be at least 128 bytes, got {v}"));
                }
                self.ws = v as usize;
            }
            "stride" => {
                if v < 8 || !v.is_multiple_of(8) {
                    return Err(format!(
                        "parameter stride must be a multiple of 8 bytes, at least 8, got {v}"
                    ));
                }
                self.stride = v as usize;
            }
            "seed" => self.seed = v,
            _ => {
                return Err(format!(
                    "unknown parameter '{key}' (iters, unroll, streams, ws, stride, seed)"
                ))
            }
        }
        Ok(())
    }
}

/// `123`, `16K`, `8M` (binary multiples).
#[must_use]
pub fn parse_size(s: &str) -> Option<u64> {
    let s = s.trim();
    let (num, mul) = match s.chars().last()? {
        'k' | 'K' => (&s[..s.len() - 1], 1024),
        'm' | 'M' => (&s[..s.len() - 1], 1024 * 1024),
        'g' | 'G' => (&s[..s.len() - 1], 1024 * 1024 * 1024),
        _ => (s, 1),
    };
    num.parse::<u64>().ok()?.checked_mul(mul)
}

/// A microkernel: what and how much.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Micro {
    /// What it measures.
    pub kind: Kind,
    /// Parameters.
    pub params: MicroParams,
}

/// A microkernel's name and description, for `rtsim list micro`.
#[derive(Clone, Debug)]
pub struct MicroInfo {
    /// Name (e.g. `fma-chain`).
    pub name: String,
    /// What it measures.
    pub what: String,
    /// Its kind.
    pub kind: Kind,
}

impl fmt::Display for MicroInfo {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:<20} {}", self.name, self.what)
    }
}

/// Every built-in microkernel.
#[must_use]
pub fn list() -> Vec<MicroInfo> {
    let mut v = Vec::new();
    for &(op, name) in CHAIN_OPS {
        if op != ChainOp::Cmp {
            v.push(MicroInfo {
                name: format!("{name}-chain"),
                what: format!("one dependent chain of {name} ops: latency"),
                kind: Kind::Chain(op),
            });
        }
        v.push(MicroInfo {
            name: format!("{name}-streams"),
            what: format!("independent chains (streams=K) of {name} ops: reciprocal throughput"),
            kind: Kind::Streams(op),
        });
    }
    v.push(MicroInfo {
        name: "pointer-chase".into(),
        what:
            "dependent loads over a random cycle of 64-byte lines in ws bytes: load-to-use latency"
                .into(),
        kind: Kind::PointerChase,
    });
    v.push(MicroInfo {
        name: "stream-load".into(),
        what: "sequential vector loads over ws bytes: load bandwidth".into(),
        kind: Kind::StreamLoad,
    });
    v.push(MicroInfo {
        name: "stream-store".into(),
        what: "sequential vector stores over ws bytes: store bandwidth".into(),
        kind: Kind::StreamStore,
    });
    v.push(MicroInfo {
        name: "branch-predictable".into(),
        what: "a data-dependent branch with pattern T,T,T,N: predictor should learn it".into(),
        kind: Kind::BranchPredictable,
    });
    v.push(MicroInfo {
        name: "branch-random".into(),
        what: "a data-dependent branch taken with probability 1/2: mispredict cost".into(),
        kind: Kind::BranchRandom,
    });
    v
}

/// The microkernel with this name.
pub fn find(name: &str) -> Result<MicroInfo, String> {
    list()
        .into_iter()
        .find(|m| m.name == name)
        .ok_or_else(|| format!("unknown microkernel '{name}' (rtsim list micro shows them)"))
}

impl Program for Micro {
    type Out = ();

    fn params(&self) -> Vec<(String, String)> {
        let p = &self.params;
        let mut v = vec![("iters".to_string(), p.iters.to_string())];
        match self.kind {
            Kind::Chain(_) => v.push(("unroll".into(), p.unroll.to_string())),
            Kind::Streams(_) => {
                v.push(("streams".into(), p.streams.to_string()));
                v.push(("unroll".into(), p.unroll.to_string()));
            }
            Kind::PointerChase | Kind::StreamLoad | Kind::StreamStore => {
                v.push(("ws".into(), p.ws.to_string()));
                v.push(("unroll".into(), p.unroll.to_string()));
            }
            Kind::BranchPredictable | Kind::BranchRandom => {}
        }
        if self.kind == Kind::PointerChase {
            v.push(("stride".into(), p.stride.to_string()));
        }
        if matches!(self.kind, Kind::PointerChase | Kind::BranchRandom) {
            v.push(("seed".into(), p.seed.to_string()));
        }
        v
    }

    fn run<M: Machine>(&self, m: &mut M) {
        m.region(Region::CoreLoop);
        match self.kind {
            Kind::Chain(op) => chains(m, op, 1, self.params.unroll, self.params.iters),
            Kind::Streams(op) => chains(
                m,
                op,
                self.params.streams,
                self.params.unroll,
                self.params.iters,
            ),
            Kind::PointerChase => pointer_chase(m, &self.params),
            Kind::StreamLoad => stream(m, &self.params, false),
            Kind::StreamStore => stream(m, &self.params, true),
            Kind::BranchPredictable => branches(m, &self.params, false),
            Kind::BranchRandom => branches(m, &self.params, true),
        }
    }
}

/// The loop's own work: i += 1; if i < n goto top.
fn loop_end<M: Machine>(m: &mut M, i: M::S, n: M::S) -> (M::S, bool) {
    let i = m.s_addi(i, 1);
    let again = m.branch_if(SITE_LOOP, Cmp::Lt, i, n);
    (i, again)
}

/// A chain value of whichever register file the op uses.
enum Val<M: Machine> {
    F(M::F),
    I(M::I),
    S(M::S),
}

impl<M: Machine> Clone for Val<M> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<M: Machine> Copy for Val<M> {}

fn step<M: Machine>(m: &mut M, op: ChainOp, v: Val<M>, flip: bool) -> Val<M> {
    let n = M::LANES;
    match v {
        Val::F(x) => {
            let one = m.splat(1.0);
            let half = m.splat(0.5);
            Val::F(match op {
                ChainOp::Fma => m.fmadd(x, one, half),
                ChainOp::Add => m.add(x, half),
                ChainOp::Mul => m.mul(x, one),
                ChainOp::Div => m.div(x, one),
                ChainOp::Sqrt => m.sqrt(x),
                ChainOp::MinMax => m.bin(BinOp::Max, x, half),
                ChainOp::Logic => m.and(x, x),
                ChainOp::Blend => {
                    let k = m.mask(0x5555 & isa::LaneMask::full(n).0);
                    m.select(k, x, one)
                }
                ChainOp::Shuf => {
                    let p: Vec<u8> = (0..n as u8).map(|i| i ^ 1).collect();
                    m.permute(x, &p)
                }
                ChainOp::Perm => {
                    let p: Vec<u8> = (0..n as u8).map(|i| n as u8 - 1 - i).collect();
                    m.permute(x, &p)
                }
                ChainOp::Rcp => m.rcp_approx(x),
                ChainOp::Rsqrt => m.rsqrt_approx(x),
                ChainOp::Bcast => {
                    let s = m.extract(x, 0);
                    m.broadcast(s)
                }
                ChainOp::Cvt => {
                    // Two conversions per step (to int and back), both vcvt.
                    let i = if flip { m.to_int(x) } else { m.to_int_round(x) };
                    m.to_float(i)
                }
                ChainOp::Cmp => {
                    m.cmp(Cmp::Lt, x, one);
                    x
                }
                _ => unreachable!("float chain op {op:?}"),
            })
        }
        Val::I(x) => {
            let c = m.splat_i(3);
            Val::I(match op {
                ChainOp::IAdd => m.iop(IOp::Add, x, c),
                ChainOp::IMul => m.iop(IOp::Mul, x, c),
                ChainOp::IShift => m.ishift(Shift::Shl, x, 1),
                ChainOp::ILogic => m.iop(IOp::Xor, x, c),
                _ => unreachable!("int chain op {op:?}"),
            })
        }
        Val::S(x) => {
            let c = m.int(3);
            Val::S(match op {
                ChainOp::Alu => m.s_add(x, c),
                ChainOp::SMul => m.s_op(isa::SOp::Mul, x, c),
                ChainOp::BitCnt => m.s_popcnt(x),
                _ => unreachable!("scalar chain op {op:?}"),
            })
        }
    }
}

fn initial<M: Machine>(m: &mut M, op: ChainOp) -> Val<M> {
    match op {
        ChainOp::IAdd | ChainOp::IMul | ChainOp::IShift | ChainOp::ILogic => Val::I(m.splat_i(1)),
        ChainOp::Alu | ChainOp::SMul | ChainOp::BitCnt => Val::S(m.int(1)),
        _ => Val::F(m.splat(1.0)),
    }
}

fn chains<M: Machine>(m: &mut M, op: ChainOp, streams: usize, unroll: usize, iters: usize) {
    let mut vals: Vec<Val<M>> = (0..streams).map(|_| initial(m, op)).collect();
    let mut i = m.int(0);
    let n = m.int(iters as i64);
    let mut flip = false;
    loop {
        for _ in 0..unroll {
            for v in &mut vals {
                *v = step(m, op, *v, flip);
            }
            flip = !flip;
        }
        let (ni, again) = loop_end(m, i, n);
        i = ni;
        if !again {
            break;
        }
    }
}

/// Bytes between chased lines by default: one line in two, so a next-line
/// prefetch never helps, and consecutive chased lines fill a cache's even
/// sets evenly. (A stride of a page and a line puts every node in a page
/// of its own: the TLB rows of `rtsim calibrate`.)
pub const CHASE_STRIDE: usize = 128;

fn pointer_chase<M: Machine>(m: &mut M, p: &MicroParams) {
    let stride = p.stride;
    let nodes = (p.ws / stride).max(2);
    // Sattolo's algorithm: a single random cycle through every node.
    let mut order: Vec<usize> = (0..nodes).collect();
    let mut r = Rng::new(p.seed);
    for i in (1..nodes).rev() {
        let j = r.below(i as u64) as usize;
        order.swap(i, j);
    }
    let mut buf = m.space().alloc(MemKind::Other, "chase", nodes * stride, 64);
    for (i, &next) in order.iter().enumerate() {
        buf.set_uint(i * stride, 8, (next * stride) as u64);
    }
    let mut cur = m.int(0);
    let mut i = m.int(0);
    let n = m.int(p.iters.div_ceil(p.unroll) as i64);
    loop {
        for _ in 0..p.unroll {
            cur = m.s_load(&buf, At::idx(cur, 1, 0), 8, false);
        }
        let (ni, again) = loop_end(m, i, n);
        i = ni;
        if !again {
            break;
        }
    }
}

fn stream<M: Machine>(m: &mut M, p: &MicroParams, store: bool) {
    let vb = 4 * M::LANES;
    let step = vb * p.unroll;
    let slots = (p.ws / step).max(1);
    let mut buf = m.space().alloc(MemKind::Other, "stream", slots * step, 64);
    let v = m.splat(1.0);
    let mut off = m.int(0);
    let wrap = m.int((slots * step) as i64);
    let mut i = m.int(0);
    let n = m.int(p.iters.div_ceil(p.unroll) as i64);
    loop {
        for k in 0..p.unroll {
            if store {
                m.store(&mut buf, At::idx(off, 1, k * vb), v);
            } else {
                m.load(&buf, At::idx(off, 1, k * vb));
            }
        }
        // off = (off + step) mod size, as add + compare + cmov.
        let next = m.s_addi(off, step as i64);
        let c = m.s_cmp(Cmp::Lt, next, wrap);
        let zero = m.int(0);
        off = m.s_select(c, next, zero);
        let (ni, again) = loop_end(m, i, n);
        i = ni;
        if !again {
            break;
        }
    }
}

fn branches<M: Machine>(m: &mut M, p: &MicroParams, random: bool) {
    let mut r = Rng::new(p.seed);
    let bytes: Vec<u8> = (0..p.iters)
        .map(|i| {
            if random {
                (r.next_u64() & 1) as u8
            } else {
                u8::from(i % 4 != 3)
            }
        })
        .collect();
    let buf = m.space().alloc_bytes(MemKind::Other, "outcomes", bytes, 64);
    // Warm the outcomes into the cache first (one load per line), so the loop
    // measures branches, not cold misses.
    m.region(Region::Setup);
    for line in (0..p.iters).step_by(64) {
        m.s_load(&buf, At::off(line), 1, false);
    }
    m.region(Region::CoreLoop);
    // Each outcome's address depends on the previous outcome (cur + 1 +
    // (b & 0)), computed after the branch: a predicted iteration starts its
    // load when the previous byte arrives; a mispredicted one only after the
    // redirect, so a mispredict costs exactly its resolution and penalty,
    // whatever else the loop overlaps.
    let mut cur = m.int(0);
    let zero = m.int(0);
    let mut i = m.int(0);
    let n = m.int(p.iters as i64);
    loop {
        let b = m.s_load(&buf, At::idx(cur, 1, 0), 1, false);
        m.branch(SITE_DATA, b);
        let dep = m.s_and(b, zero);
        let next = m.s_addi(cur, 1);
        cur = m.s_add(next, dep);
        let (ni, again) = loop_end(m, i, n);
        i = ni;
        if !again {
            break;
        }
    }
}

/// Build a microkernel by name with `key=value` parameters.
pub fn build(name: &str, params: &[(String, String)]) -> Result<Micro, String> {
    let info = find(name)?;
    let mut p = MicroParams::default();
    for (k, v) in params {
        p.set(k, v)?;
    }
    Ok(Micro {
        kind: info.kind,
        params: p,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use isa::{FlavourId, OpClass};

    fn classes(name: &str, fl: FlavourId, params: &[(&str, &str)]) -> Vec<OpClass> {
        let p: Vec<(String, String)> = params
            .iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect();
        let k = build(name, &p).unwrap();
        let (t, ()) = isa::record(&k, fl, name);
        t.validate().unwrap();
        t.ops.iter().map(|o| o.class).collect()
    }

    #[test]
    fn fma_chain_is_dependent_fmas_plus_loop() {
        let c = classes(
            "fma-chain",
            FlavourId::Avx2,
            &[("iters", "3"), ("unroll", "4")],
        );
        let body = [OpClass::VFma; 4];
        let lp = [OpClass::Alu, OpClass::Cmp, OpClass::Branch];
        let want: Vec<OpClass> = (0..3)
            .flat_map(|_| body.iter().chain(&lp).copied())
            .collect();
        assert_eq!(c, want);
        let k = build("fma-chain", &[("iters".into(), "2".into())]).unwrap();
        let (t, ()) = isa::record(&k, FlavourId::Avx2, "x");
        // Each FMA reads the previous one's result.
        let fmas: Vec<_> = t.ops.iter().filter(|o| o.class == OpClass::VFma).collect();
        for w in fmas.windows(2) {
            assert_eq!(w[1].sources(), &[w[0].dst]);
        }
    }

    #[test]
    fn streams_are_independent() {
        let k = build(
            "fma-streams",
            &[
                ("iters".into(), "2".into()),
                ("streams".into(), "10".into()),
            ],
        )
        .unwrap();
        let (t, ()) = isa::record(&k, FlavourId::Avx2, "x");
        let fmas: Vec<_> = t.ops.iter().filter(|o| o.class == OpClass::VFma).collect();
        assert_eq!(fmas.len(), 2 * 8 * 10);
        assert!(
            fmas[..10].iter().all(|o| o.nsrc == 0),
            "first round reads constants"
        );
        for j in 0..10 {
            assert_eq!(fmas[10 + j].sources(), &[fmas[j].dst]);
        }
    }

    #[test]
    fn pointer_chase_visits_every_line() {
        let k = build(
            "pointer-chase",
            &[
                ("iters".into(), "64".into()),
                ("ws".into(), "8K".into()),
                ("unroll".into(), "4".into()),
            ],
        )
        .unwrap();
        let (t, ()) = isa::record(&k, FlavourId::Avx2, "x");
        let loads: Vec<_> = t.ops.iter().filter(|o| o.class == OpClass::Load).collect();
        assert_eq!(loads.len(), 64);
        let lines: std::collections::HashSet<u64> = loads.iter().map(|o| o.addr.0 / 64).collect();
        assert_eq!(lines.len(), 64, "a single cycle through all 64 nodes");
        let parity = lines.iter().next().unwrap() % 2;
        assert!(lines.iter().all(|l| l % 2 == parity), "one line in two");
        for w in loads.windows(2) {
            assert_eq!(
                w[1].sources(),
                &[w[0].dst],
                "each load's address is the previous load"
            );
        }
    }

    #[test]
    fn every_micro_records_on_every_flavour() {
        for info in list() {
            for fl in FlavourId::ALL {
                let k = build(
                    &info.name,
                    &[("iters".into(), "5".into()), ("ws".into(), "1K".into())],
                )
                .unwrap();
                let (t, ()) = isa::record(&k, fl, &info.name);
                t.validate()
                    .unwrap_or_else(|e| panic!("{} on {fl}: {e}", info.name));
                assert!(t.ops.len() >= 5, "{} on {fl}", info.name);
                isa::run_native(&k, fl);
            }
        }
    }

    #[test]
    fn branch_patterns() {
        let k = build("branch-random", &[("iters".into(), "1000".into())]).unwrap();
        let (t, ()) = isa::record(&k, FlavourId::Avx2, "x");
        let data: Vec<_> = t
            .ops
            .iter()
            .filter(|o| o.class == OpClass::Branch && o.site() == SITE_DATA)
            .collect();
        let taken = data.iter().filter(|o| o.taken()).count();
        assert_eq!(data.len(), 1000);
        assert!((400..600).contains(&taken), "{taken}");
        assert!(build("nope", &[]).is_err());
        assert!(build("fma-chain", &[("iters".into(), "0".into())]).is_err());
        assert!(build("fma-chain", &[("bogus".into(), "1".into())]).is_err());
    }
}
