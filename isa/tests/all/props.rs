//! Seeded property tests: random op sequences give bit-identical results on
//! the traced and native backends of every flavour; every recorded trace
//! validates and survives binary and text round trips; corrupt and truncated
//! files are rejected with an error, never a panic.

use isa::rng::Rng;
use isa::{
    trace_file, trace_text, At, Avx2, Avx512, BinOp, Buf, Cmp, Float, Fma, IOp, Int, Logic, Lrb16,
    Machine, MemKind, Native, SOp, Shift, Sse4, Trace, Traced, Wide32,
};

const SPECIAL: [f32; 12] = [
    0.0,
    -0.0,
    1.0,
    -1.0,
    0.5,
    f32::INFINITY,
    f32::NEG_INFINITY,
    f32::NAN,
    1e-40,
    3.0e38,
    7.25,
    -1e-3,
];

fn pick<T: Copy>(r: &mut Rng, v: &[T]) -> T {
    v[r.below(v.len() as u64) as usize]
}

/// Run a random program of `steps` ops; returns every value's bits and the buffer bytes.
fn program<M: Machine>(m: &mut M, seed: u64, steps: usize) -> Vec<u64> {
    let n = M::LANES;
    let mut r = Rng::new(seed);
    let data: Vec<f32> = (0..64)
        .map(|_| pick(&mut r, &SPECIAL) * r.range(-4.0, 4.0))
        .collect();
    let mut buf: Buf = m.space().alloc_f32(MemKind::Other, "data", &data, 64);
    let mut fs: Vec<M::F> = Vec::new();
    let mut is: Vec<M::I> = Vec::new();
    let mut ks: Vec<M::K> = Vec::new();
    let mut ss: Vec<M::S> = vec![m.int(3), m.int(-5)];
    let mut xs: Vec<M::X> = vec![m.float(1.5)];
    for _ in 0..3 {
        let v: Vec<f32> = (0..n)
            .map(|_| pick(&mut r, &SPECIAL) * r.range(-2.0, 2.0))
            .collect();
        fs.push(m.consts(&v));
        let w: Vec<i32> = (0..n).map(|_| r.next_u64() as i32).collect();
        is.push(m.consts_i(&w));
        ks.push(m.mask(r.next_u64() as u32 & isa::LaneMask::full(n).0));
    }
    let vec_off = |r: &mut Rng| 4 * r.below((64 - n) as u64 + 1) as usize;
    for _ in 0..steps {
        let f = |r: &mut Rng, fs: &Vec<M::F>| fs[r.below(fs.len() as u64) as usize];
        let (a, b, c) = (f(&mut r, &fs), f(&mut r, &fs), f(&mut r, &fs));
        let i1 = is[r.below(is.len() as u64) as usize];
        let i2 = is[r.below(is.len() as u64) as usize];
        let k = ks[r.below(ks.len() as u64) as usize];
        let k2 = ks[r.below(ks.len() as u64) as usize];
        let s1 = ss[r.below(ss.len() as u64) as usize];
        let s2 = ss[r.below(ss.len() as u64) as usize];
        let x1 = xs[r.below(xs.len() as u64) as usize];
        let x2 = xs[r.below(xs.len() as u64) as usize];
        let bin = pick(
            &mut r,
            &[
                BinOp::Add,
                BinOp::Sub,
                BinOp::Mul,
                BinOp::Div,
                BinOp::Min,
                BinOp::Max,
            ],
        );
        let fma = pick(&mut r, &[Fma::MAdd, Fma::MSub, Fma::NMAdd, Fma::NMSub]);
        let cmp = pick(
            &mut r,
            &[
                Cmp::Lt,
                Cmp::Le,
                Cmp::Gt,
                Cmp::Ge,
                Cmp::Eq,
                Cmp::Ne,
                Cmp::Ord,
                Cmp::Unord,
            ],
        );
        let icmp = pick(
            &mut r,
            &[Cmp::Lt, Cmp::Le, Cmp::Gt, Cmp::Ge, Cmp::Eq, Cmp::Ne],
        );
        let iop = pick(
            &mut r,
            &[
                IOp::Add,
                IOp::Sub,
                IOp::Mul,
                IOp::And,
                IOp::Or,
                IOp::Xor,
                IOp::AndNot,
                IOp::Min,
                IOp::Max,
            ],
        );
        let logic = pick(&mut r, &[Logic::And, Logic::Or, Logic::Xor, Logic::AndNot]);
        let shift = pick(&mut r, &[Shift::Shl, Shift::Shr, Shift::Sar]);
        let sop = pick(
            &mut r,
            &[
                SOp::Add,
                SOp::Sub,
                SOp::Mul,
                SOp::And,
                SOp::Or,
                SOp::Xor,
                SOp::Min,
                SOp::Max,
            ],
        );
        let perm: Vec<u8> = (0..n).map(|_| r.below(n as u64) as u8).collect();
        let perm2: Vec<u8> = (0..n).map(|_| r.below(2 * n as u64) as u8).collect();
        match r.below(40) {
            0 => fs.push(m.bin(bin, a, b)),
            1 => fs.push(m.masked(bin, k, c, a, b)),
            2 => fs.push(m.fma(fma, a, b, c)),
            3 => fs.push(m.masked_fma(fma, k, a, b, c)),
            4 => fs.push(m.abs(a)),
            5 => fs.push(m.neg(a)),
            6 => fs.push(m.sqrt(a)),
            7 => fs.push(m.rcp(a)),
            8 => fs.push(m.rcp_approx(a)),
            9 => fs.push(m.rsqrt(a)),
            10 => fs.push(m.rsqrt_approx(a)),
            11 => ks.push(m.cmp(cmp, a, b)),
            12 => fs.push(m.select(k, a, b)),
            // Bit logic on a NaN exposes its sign and payload, which the
            // backends need not agree on (see `compare`): skipped then.
            13 => {
                let nan = |m: &M, v: M::F| (0..n).any(|i| m.lane(v, i).is_nan());
                if !nan(m, a) && !nan(m, b) {
                    fs.push(m.logic(logic, a, b));
                }
            }
            14 => fs.push(m.broadcast(x1)),
            15 => xs.push(m.extract(a, r.below(n as u64) as usize)),
            16 => fs.push(m.permute(a, &perm)),
            17 => fs.push(m.shuffle2(a, b, &perm2)),
            18 => xs.push(m.reduce(pick(&mut r, &[BinOp::Add, BinOp::Min, BinOp::Max]), a)),
            19 => is.push(if r.below(2) == 0 {
                m.to_int(a)
            } else {
                m.to_int_round(a)
            }),
            20 => fs.push(m.to_float(i1)),
            21 => is.push(m.iop(iop, i1, i2)),
            22 => is.push(m.ishift(shift, i1, r.below(40) as u32)),
            23 => ks.push(m.icmp(icmp, i1, i2)),
            24 => is.push(m.iselect(k, i1, i2)),
            25 => ks.push(m.klogic(logic, k, k2)),
            26 => ks.push(m.knot(k)),
            27 => ss.push(match r.below(5) {
                0 => m.movemask(k),
                1 => m.popcnt(k),
                2 => m.bitscan(k),
                3 => m.any(k),
                _ => m.all(k),
            }),
            28 => fs.push(match r.below(4) {
                0 => m.loadu(&buf, At::off(vec_off(&mut r))),
                1 => m.load_bcast(&buf, At::off(4 * r.below(64) as usize)),
                2 => m.load_repeat(&buf, At::off(4 * r.below(60) as usize), 4.min(n)),
                _ => m.load_masked(k, a, &buf, At::off(vec_off(&mut r))),
            }),
            29 => match r.below(3) {
                0 => m.storeu(&mut buf, At::off(vec_off(&mut r)), a),
                1 => m.store_masked(k, &mut buf, At::off(vec_off(&mut r)), a),
                _ => {
                    let cnt = m.compress_store(k, &mut buf, At::off(vec_off(&mut r)), a);
                    ss.push(cnt);
                }
            },
            30 => {
                let mask63 = m.splat_i(63);
                let idx = m.iop(IOp::And, i1, mask63);
                if r.below(2) == 0 {
                    fs.push(m.gather(k, a, &buf, At::off(0), idx, 4));
                } else {
                    m.scatter(k, &mut buf, At::off(0), idx, 4, a);
                }
            }
            31 => ss.push(m.s_op(sop, s1, s2)),
            32 => ss.push(m.s_shift(shift, s1, r.below(70) as u32)),
            33 => ss.push(m.s_cmp(icmp, s1, s2)),
            34 => ss.push(m.s_select(s1, s1, s2)),
            35 => ss.push(if r.below(2) == 0 {
                m.s_popcnt(s1)
            } else {
                m.s_tzcnt(s1)
            }),
            36 => {
                let w = pick(&mut r, &[1u8, 2, 4, 8]);
                let off = r.below(256 - 8) as usize;
                match r.below(3) {
                    0 => ss.push(m.s_load(&buf, At::off(off), w, r.below(2) == 0)),
                    1 => m.s_store(&mut buf, At::off(off), w, s1),
                    _ => {
                        // A run of stores through the buffer opened once.
                        let mut open = m.open(&mut buf);
                        m.s_store_open(&mut open, At::off(off), w, s1);
                        m.s_store_open(&mut open, At::off(off / 2), w, s2);
                    }
                }
            }
            37 => xs.push(match r.below(3) {
                0 => m.x_op(bin, x1, x2),
                1 => m.x_fma(fma, x1, x2, x1),
                _ => m.x_sqrt(x1),
            }),
            38 => ss.push(m.x_cmp(cmp, x1, x2)),
            _ => {
                let c = m.s_cmp(Cmp::Lt, s1, s2);
                m.branch(isa::Site(r.below(8) as u32), c);
            }
        }
    }
    let mut out = Vec::new();
    for v in &fs {
        out.extend((0..n).map(|i| u64::from(m.lane(*v, i).to_bits())));
    }
    for v in &is {
        out.extend((0..n).map(|i| m.lane_i(*v, i) as u32 as u64));
    }
    out.extend(ks.iter().map(|k| u64::from(m.bits(*k))));
    out.extend(ss.iter().map(|s| s.get() as u64));
    out.extend(xs.iter().map(|x| u64::from(x.get().to_bits())));
    // The buffer as 4-byte words, so a stored NaN compares as a NaN.
    let words = buf.bytes().chunks_exact(4);
    let tail: Vec<u64> = words.remainder().iter().map(|&b| u64::from(b)).collect();
    out.extend(words.map(|w| u64::from(u32::from_le_bytes([w[0], w[1], w[2], w[3]]))));
    out.extend(tail);
    out
}

fn compare<FL: isa::Flavour<N>, const N: usize>(seeds: std::ops::Range<u64>) -> Vec<Trace> {
    let mut traces = Vec::new();
    for seed in seeds {
        let mut t = Traced::<FL, N>::new("prop");
        let mut nm = Native::<FL, N>::new();
        let a = program(&mut t, seed, 150);
        let b = program(&mut nm, seed, 150);
        // NaN sign and payload are unspecified (as in Rust and LLVM: x86's
        // default NaN is negative, constant folding makes positive ones), so
        // a NaN equals any NaN; every other bit must match.
        let nan = |x: u64| x <= u64::from(u32::MAX) && f32::from_bits(x as u32).is_nan();
        if let Some(i) =
            (0..a.len().min(b.len())).find(|&i| a[i] != b[i] && !(nan(a[i]) && nan(b[i])))
        {
            panic!(
                "{:?} seed {seed}: traced and native differ at output {i}: {:#x} vs {:#x}",
                FL::ID,
                a[i],
                b[i]
            );
        }
        assert_eq!(a.len(), b.len(), "{:?} seed {seed}: output lengths", FL::ID);
        let tr = t.finish();
        tr.validate().unwrap_or_else(|e| panic!("seed {seed}: {e}"));
        traces.push(tr);
    }
    traces
}

fn first_diff(a: &Trace, b: &Trace, what: &str) {
    assert_eq!(a.regions, b.regions, "{what}: regions");
    assert_eq!(a.lane_addrs, b.lane_addrs, "{what}: lane addresses");
    for (i, (x, y)) in a.ops.iter().zip(&b.ops).enumerate() {
        assert_eq!(x, y, "{what}: op {i}");
    }
    assert_eq!(a.ops.len(), b.ops.len(), "{what}: op count");
    assert!(a == b, "{what}: header");
}

fn round_trips(traces: &[Trace]) {
    for t in traces {
        let bin = trace_file::encode(t);
        let back = trace_file::decode(&bin).expect("decodes");
        first_diff(&back, t, "binary round trip");
        let text = trace_text::write(t);
        let parsed = trace_text::parse(&text).expect("parses");
        first_diff(&parsed, t, "text round trip");
        assert_eq!(
            trace_file::encode(&parsed),
            bin,
            "binary -> text -> binary is byte-identical"
        );
    }
}

#[test]
fn traced_equals_native_lrb16() {
    round_trips(&compare::<Lrb16, 16>(0..60));
}
#[test]
fn traced_equals_native_avx512() {
    round_trips(&compare::<Avx512, 16>(100..160));
}
#[test]
fn traced_equals_native_avx2() {
    round_trips(&compare::<Avx2, 8>(200..260));
}
#[test]
fn traced_equals_native_sse4() {
    round_trips(&compare::<Sse4, 4>(300..360));
}

#[test]
fn traced_equals_native_wide32() {
    round_trips(&compare::<Wide32, 32>(400..460));
}

#[test]
fn recording_is_deterministic() {
    let rec = || {
        let mut t = Traced::<Avx2, 8>::new("prop");
        program(&mut t, 42, 300);
        trace_file::encode(&t.finish())
    };
    assert_eq!(rec(), rec());
}

#[test]
fn every_flipped_byte_and_truncation_is_an_error() {
    let mut t = Traced::<Avx2, 8>::new("prop");
    program(&mut t, 7, 120);
    let bin = trace_file::encode(&t.finish());
    for i in 0..bin.len() {
        for x in [0x01u8, 0x80, 0xff] {
            let mut b = bin.clone();
            b[i] ^= x;
            let e = trace_file::decode(&b).expect_err("a flipped byte is detected");
            assert!(e.offset <= bin.len(), "offset {} in range", e.offset);
        }
    }
    for len in 0..bin.len() {
        assert!(
            trace_file::decode(&bin[..len]).is_err(),
            "truncated to {len}"
        );
    }
}

#[test]
fn garbage_after_a_valid_header_never_panics() {
    let mut r = Rng::new(99);
    for _ in 0..2000 {
        let mut b = trace_file::MAGIC.to_vec();
        b.extend_from_slice(&trace_file::VERSION.to_le_bytes());
        let n = r.below(200) as usize;
        b.extend((0..n).map(|_| r.next_u64() as u8));
        // Make the checksum right so the structural checks are what fails.
        let sum = trace_file::fnv1a64(&b);
        b.extend_from_slice(&sum.to_le_bytes());
        let _ = trace_file::decode(&b);
    }
}
