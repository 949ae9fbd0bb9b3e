//! Every op on every flavour and both backends against a scalar reference
//! written here, independently of `lanes.rs`, over special inputs: NaN, +-0,
//! +-inf, denormals, extremes. Approximate ops are checked against their
//! documented error bound.

// Lane checks index inputs and results in step; tables of (op, reference fn) pairs.
#![allow(clippy::needless_range_loop, clippy::type_complexity)]

use isa::{
    At, Avx2, Avx512, BinOp, Cmp, FlavourId, Float, Fma, IOp, Int, LaneMask, Logic, Lrb16, Machine,
    MemKind, Native, SOp, Shift, Sse4, Traced, Wide32,
};

const SPECIAL: [f32; 16] = [
    0.0,
    -0.0,
    1.0,
    -1.0,
    1.5,
    -2.25,
    f32::INFINITY,
    f32::NEG_INFINITY,
    f32::NAN,
    1e-40,  // denormal
    -1e-40, // denormal
    f32::MAX,
    f32::MIN_POSITIVE,
    3.0e38,
    1e-30,
    123456.7,
];

/// Same value, or both NaN.
fn same(a: f32, b: f32) -> bool {
    a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
}

fn ref_min(a: f32, b: f32) -> f32 {
    // minps: the second operand unless a < b.
    if a < b {
        a
    } else {
        b
    }
}
fn ref_max(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}
fn ref_cvt(x: f32, round: bool) -> i32 {
    let y = if round {
        // round half to even, by hand
        let f = x.floor();
        let d = x - f;
        if d > 0.5 || (d == 0.5 && (f as i64) % 2 != 0) {
            f + 1.0
        } else {
            f
        }
    } else {
        x.trunc()
    };
    if y.is_nan() || !(-2147483648.0..2147483648.0).contains(&y) {
        i32::MIN
    } else {
        y as i32
    }
}

fn rcp_bits(f: FlavourId) -> i32 {
    match f {
        FlavourId::Lrb16 => 23,
        FlavourId::Avx512 | FlavourId::Wide32 => 14,
        FlavourId::Avx2 | FlavourId::Sse4 => 12,
    }
}

fn fused(f: FlavourId) -> bool {
    f != FlavourId::Sse4
}

/// All binary-float, unary-float, compare, convert and fma checks for one pair of input vectors.
fn check_float_ops<M: Machine>(m: &mut M, a: &[f32], b: &[f32], c: &[f32]) {
    let n = M::LANES;
    let va = m.consts(a);
    let vb = m.consts(b);
    let vc = m.consts(c);
    let bin: [(BinOp, fn(f32, f32) -> f32); 6] = [
        (BinOp::Add, |x, y| x + y),
        (BinOp::Sub, |x, y| x - y),
        (BinOp::Mul, |x, y| x * y),
        (BinOp::Div, |x, y| x / y),
        (BinOp::Min, ref_min),
        (BinOp::Max, ref_max),
    ];
    for (op, f) in bin {
        let r = m.bin(op, va, vb);
        // Lrb16 has no divide: a reciprocal of 23 bits times the dividend.
        let no_div = op == BinOp::Div && M::FLAVOUR == FlavourId::Lrb16;
        let f = |x: f32, y: f32| {
            if no_div {
                x * isa::lanes::rcp_approx(y, 23)
            } else {
                f(x, y)
            }
        };
        for i in 0..n {
            let want = f(a[i], b[i]);
            assert!(
                same(m.lane(r, i), want),
                "{:?} {op:?}({}, {}) = {} want {want}",
                M::FLAVOUR,
                a[i],
                b[i],
                m.lane(r, i)
            );
        }
        let k = m.mask(0b1010_0110_0101_1001 & LaneMask::full(n).0);
        let r = m.masked(op, k, vc, va, vb);
        for i in 0..n {
            let want = if m.bits(k) >> i & 1 == 1 {
                f(a[i], b[i])
            } else {
                c[i]
            };
            assert!(same(m.lane(r, i), want), "{:?} masked {op:?}", M::FLAVOUR);
        }
        let xa = m.extract(va, 1 % n);
        let xb = m.extract(vb, 1 % n);
        let x = m.x_op(op, xa, xb);
        let scalar = if no_div {
            a[1 % n] / b[1 % n]
        } else {
            f(a[1 % n], b[1 % n])
        };
        assert!(same(x.get(), scalar), "{:?} scalar {op:?}", M::FLAVOUR);
    }
    let fl = M::FLAVOUR;
    let fmas: [(Fma, fn(bool, f32, f32, f32) -> f32); 4] = [
        (Fma::MAdd, |fu, x, y, z| {
            if fu {
                ((x as f64) * (y as f64) + z as f64) as f32
            } else {
                x * y + z
            }
        }),
        (Fma::MSub, |fu, x, y, z| {
            if fu {
                ((x as f64) * (y as f64) - z as f64) as f32
            } else {
                x * y - z
            }
        }),
        (Fma::NMAdd, |fu, x, y, z| {
            if fu {
                (-(x as f64) * (y as f64) + z as f64) as f32
            } else {
                z - x * y
            }
        }),
        (Fma::NMSub, |fu, x, y, z| {
            if fu {
                (-(x as f64) * (y as f64) - z as f64) as f32
            } else {
                -(x * y) - z
            }
        }),
    ];
    for (kind, f) in fmas {
        let r = m.fma(kind, va, vb, vc);
        for i in 0..n {
            // f64 product of two f32 is exact; the f64 sum then rounds once to
            // f64 and again to f32. That double rounding can differ from a true
            // fused result only off the f32 grid's midpoints; skip such lanes
            // by checking against std's fused op when the two disagree.
            let want = f(fused(fl), a[i], b[i], c[i]);
            let got = m.lane(r, i);
            let exact = match kind {
                Fma::MAdd => a[i].mul_add(b[i], c[i]),
                Fma::MSub => a[i].mul_add(b[i], -c[i]),
                Fma::NMAdd => (-a[i]).mul_add(b[i], c[i]),
                Fma::NMSub => (-a[i]).mul_add(b[i], -c[i]),
            };
            let ok = same(got, want) || (fused(fl) && same(got, exact));
            assert!(
                ok,
                "{fl:?} {kind:?}({}, {}, {}) = {got} want {want}",
                a[i], b[i], c[i]
            );
        }
        let k = m.mask(0x5 & LaneMask::full(n).0);
        let r2 = m.masked_fma(kind, k, va, vb, vc);
        for i in 0..n {
            let want = if i == 0 || i == 2 { m.lane(r, i) } else { c[i] };
            assert!(same(m.lane(r2, i), want), "{fl:?} masked {kind:?}");
        }
    }
    let un: [(&str, fn(&mut M, M::F) -> M::F, fn(f32) -> f32); 6] = [
        (
            "abs",
            |m, x| m.abs(x),
            |x| f32::from_bits(x.to_bits() & 0x7fff_ffff),
        ),
        (
            "neg",
            |m, x| m.neg(x),
            |x| f32::from_bits(x.to_bits() ^ 0x8000_0000),
        ),
        ("sqrt", |m, x| m.sqrt(x), |x| ((x as f64).sqrt()) as f32),
        ("rcp", |m, x| m.rcp(x), |x| 1.0 / x),
        ("rsqrt", |m, x| m.rsqrt(x), |x| 1.0 / x.sqrt()),
        (
            "permute-identity",
            |m, x| {
                let id: Vec<u8> = (0..M::LANES as u8).collect();
                m.permute(x, &id)
            },
            |x| x,
        ),
    ];
    for (name, f, rf) in un {
        let r = f(m, va);
        for i in 0..n {
            assert!(
                same(m.lane(r, i), rf(a[i])),
                "{fl:?} {name}({}) = {}",
                a[i],
                m.lane(r, i)
            );
        }
    }
    // Approximations: within 2^-bits relative of the exact value, specials exact.
    let bits = rcp_bits(fl);
    let bound = 2f64.powi(-bits);
    let r = m.rcp_approx(va);
    let q = m.rsqrt_approx(va);
    for i in 0..n {
        let x = a[i] as f64;
        for (got, exact) in [(m.lane(r, i), 1.0 / x), (m.lane(q, i), 1.0 / x.sqrt())] {
            let e32 = exact as f32;
            if e32.is_nan() || e32.is_infinite() || e32 == 0.0 {
                assert!(same(got, e32), "{fl:?} approx of {x}: {got} vs {e32}");
            } else if e32.is_normal() {
                let rel = ((got as f64) - exact).abs() / exact.abs();
                assert!(
                    rel < bound,
                    "{fl:?} approx of {x}: rel error {rel} >= 2^-{bits}"
                );
            }
        }
    }
    for p in [
        Cmp::Lt,
        Cmp::Le,
        Cmp::Gt,
        Cmp::Ge,
        Cmp::Eq,
        Cmp::Ne,
        Cmp::Ord,
        Cmp::Unord,
    ] {
        let k = m.cmp(p, va, vb);
        for i in 0..n {
            let (x, y) = (a[i], b[i]);
            let want = match p {
                Cmp::Lt => x < y,
                Cmp::Le => x <= y,
                Cmp::Gt => x > y,
                Cmp::Ge => x >= y,
                Cmp::Eq => x == y,
                Cmp::Ne => !(x == y),
                Cmp::Ord => !(x.is_nan() || y.is_nan()),
                Cmp::Unord => x.is_nan() || y.is_nan(),
            };
            assert_eq!(m.bits(k) >> i & 1 == 1, want, "{fl:?} cmp {p:?}({x}, {y})");
        }
        let s = m.select(k, va, vb);
        for i in 0..n {
            let want = if m.bits(k) >> i & 1 == 1 { a[i] } else { b[i] };
            assert!(same(m.lane(s, i), want));
        }
        let xa = m.extract(va, 0);
        let xb = m.extract(vb, 0);
        let c0 = m.x_cmp(p, xa, xb);
        assert_eq!(c0.get() == 1, m.bits(k) & 1 == 1, "{fl:?} scalar cmp {p:?}");
    }
    for (op, f) in [
        (Logic::And, (|x, y| x & y) as fn(u32, u32) -> u32),
        (Logic::Or, |x, y| x | y),
        (Logic::Xor, |x, y| x ^ y),
        (Logic::AndNot, |x, y| !x & y),
    ] {
        let r = m.logic(op, va, vb);
        for i in 0..n {
            assert_eq!(
                m.lane(r, i).to_bits(),
                f(a[i].to_bits(), b[i].to_bits()),
                "{fl:?} {op:?}"
            );
        }
    }
    let t = m.to_int(va);
    let tr = m.to_int_round(va);
    for i in 0..n {
        assert_eq!(m.lane_i(t, i), ref_cvt(a[i], false), "{fl:?} cvtt {}", a[i]);
        assert_eq!(m.lane_i(tr, i), ref_cvt(a[i], true), "{fl:?} cvt {}", a[i]);
    }
    let back = m.to_float(t);
    let bi = m.bits_to_i(va);
    let bf = m.bits_to_f(bi);
    for i in 0..n {
        assert_eq!(m.lane(back, i), m.lane_i(t, i) as f32);
        assert_eq!(m.lane_i(bi, i) as u32, a[i].to_bits());
        assert_eq!(m.lane(bf, i).to_bits(), a[i].to_bits());
    }
    // Reductions: compare with the same halving tree computed here.
    for (op, f) in [
        (BinOp::Add, (|x, y| x + y) as fn(f32, f32) -> f32),
        (BinOp::Min, ref_min),
        (BinOp::Max, ref_max),
    ] {
        let mut v: Vec<f32> = a.to_vec();
        let mut d = n / 2;
        while d >= 1 {
            let p = v.clone();
            for i in 0..n {
                v[i] = f(p[i], p[i ^ d]);
            }
            d /= 2;
        }
        let r = m.reduce(op, va);
        assert!(same(r.get(), v[0]), "{fl:?} reduce {op:?}");
    }
    let x = m.extract(va, n - 1);
    assert!(same(x.get(), a[n - 1]));
    let bc = m.broadcast(x);
    for i in 0..n {
        assert!(same(m.lane(bc, i), a[n - 1]));
    }
    let xs = m.x_sqrt(x);
    assert!(same(xs.get(), a[n - 1].sqrt()));
    let ti = m.x_to_int(x);
    assert_eq!(ti.get(), i64::from(a[n - 1] as i32), "cvttss2si truncates");
    let back = m.x_from_int(ti);
    assert!(same(back.get(), ti.get() as f32));
    let xf = m.x_fma(Fma::MAdd, x, x, x);
    let want = if fused(fl) {
        a[n - 1].mul_add(a[n - 1], a[n - 1])
    } else {
        a[n - 1] * a[n - 1] + a[n - 1]
    };
    assert!(same(xf.get(), want));
}

fn check_int_and_mask_ops<M: Machine>(m: &mut M) {
    let n = M::LANES;
    let fl = M::FLAVOUR;
    let ia: Vec<i32> = (0..n as i32)
        .map(|i| [i32::MIN, -7, 0, 1, 5, i32::MAX, 123456, -1][i as usize % 8])
        .collect();
    let ib: Vec<i32> = (0..n as i32)
        .map(|i| [3, -7, i32::MAX, -1, 5, 1, 0, 31][(i as usize + 3) % 8])
        .collect();
    let va = m.consts_i(&ia);
    let vb = m.consts_i(&ib);
    for (op, f) in [
        (
            IOp::Add,
            (|x: i32, y: i32| x.wrapping_add(y)) as fn(i32, i32) -> i32,
        ),
        (IOp::Sub, |x, y| x.wrapping_sub(y)),
        (IOp::Mul, |x, y| x.wrapping_mul(y)),
        (IOp::And, |x, y| x & y),
        (IOp::Or, |x, y| x | y),
        (IOp::Xor, |x, y| x ^ y),
        (IOp::AndNot, |x, y| !x & y),
        (IOp::Min, |x: i32, y| x.min(y)),
        (IOp::Max, |x: i32, y| x.max(y)),
    ] {
        let r = m.iop(op, va, vb);
        for i in 0..n {
            assert_eq!(m.lane_i(r, i), f(ia[i], ib[i]), "{fl:?} {op:?}");
        }
    }
    for (s, cnt) in [
        (Shift::Shl, 3u32),
        (Shift::Shr, 5),
        (Shift::Sar, 5),
        (Shift::Shl, 40),
        (Shift::Sar, 40),
        (Shift::Shr, 32),
    ] {
        let r = m.ishift(s, va, cnt);
        for i in 0..n {
            let x = ia[i];
            let want = match s {
                Shift::Shl => {
                    if cnt >= 32 {
                        0
                    } else {
                        ((x as u32) << cnt) as i32
                    }
                }
                Shift::Shr => {
                    if cnt >= 32 {
                        0
                    } else {
                        ((x as u32) >> cnt) as i32
                    }
                }
                Shift::Sar => {
                    if cnt >= 32 {
                        if x < 0 {
                            -1
                        } else {
                            0
                        }
                    } else {
                        x >> cnt
                    }
                }
            };
            assert_eq!(m.lane_i(r, i), want, "{fl:?} {s:?} {cnt}");
        }
    }
    for p in [Cmp::Eq, Cmp::Ne, Cmp::Lt, Cmp::Le, Cmp::Gt, Cmp::Ge] {
        let k = m.icmp(p, va, vb);
        for i in 0..n {
            let (x, y) = (ia[i], ib[i]);
            let want = match p {
                Cmp::Eq => x == y,
                Cmp::Ne => x != y,
                Cmp::Lt => x < y,
                Cmp::Le => x <= y,
                Cmp::Gt => x > y,
                _ => x >= y,
            };
            assert_eq!(m.bits(k) >> i & 1 == 1, want, "{fl:?} icmp {p:?}");
        }
        let s = m.iselect(k, va, vb);
        for i in 0..n {
            assert_eq!(
                m.lane_i(s, i),
                if m.bits(k) >> i & 1 == 1 {
                    ia[i]
                } else {
                    ib[i]
                }
            );
        }
    }
    let full = LaneMask::full(n).0;
    for (x, y) in [
        (0u32, 0u32),
        (full, 0),
        (0x9 & full, 0x3 & full),
        (full, full),
        (0x8000 & full, 0x1),
    ] {
        let ka = m.mask(x);
        let kb = m.mask(y);
        for (op, f) in [
            (Logic::And, (|p, q| p & q) as fn(u32, u32) -> u32),
            (Logic::Or, |p, q| p | q),
            (Logic::Xor, |p, q| p ^ q),
            (Logic::AndNot, |p, q| !p & q),
        ] {
            let r = m.klogic(op, ka, kb);
            assert_eq!(m.bits(r), f(x, y) & full, "{fl:?} k{op:?}");
        }
        let nk = m.knot(ka);
        assert_eq!(m.bits(nk), !x & full);
        assert_eq!(m.movemask(ka).get(), i64::from(x));
        assert_eq!(m.popcnt(ka).get(), i64::from(x.count_ones()));
        assert_eq!(
            m.bitscan(ka).get(),
            if x == 0 {
                n as i64
            } else {
                i64::from(x.trailing_zeros())
            }
        );
        assert_eq!(m.any(ka).get(), i64::from(x != 0));
        assert_eq!(m.all(ka).get(), i64::from(x == full));
    }
    // Scalar integer ops.
    for (x, y) in [
        (5i64, 3i64),
        (-7, 2),
        (i64::MIN, -1),
        (0, 0),
        (1 << 40, 12345),
    ] {
        let (sx, sy) = (m.int(x), m.int(y));
        for (op, f) in [
            (
                SOp::Add,
                (|p: i64, q: i64| p.wrapping_add(q)) as fn(i64, i64) -> i64,
            ),
            (SOp::Sub, |p, q| p.wrapping_sub(q)),
            (SOp::Mul, |p, q| p.wrapping_mul(q)),
            (SOp::And, |p, q| p & q),
            (SOp::Or, |p, q| p | q),
            (SOp::Xor, |p, q| p ^ q),
            (SOp::Min, |p: i64, q| p.min(q)),
            (SOp::Max, |p: i64, q| p.max(q)),
        ] {
            assert_eq!(m.s_op(op, sx, sy).get(), f(x, y), "{op:?}");
        }
        assert_eq!(m.s_shift(Shift::Shl, sx, 3).get(), x.wrapping_shl(3));
        assert_eq!(
            m.s_shift(Shift::Shr, sx, 67).get(),
            ((x as u64) >> 3) as i64
        );
        assert_eq!(m.s_shift(Shift::Sar, sx, 2).get(), x >> 2);
        assert_eq!(m.s_cmp(Cmp::Lt, sx, sy).get(), i64::from(x < y));
        assert_eq!(m.s_cmp(Cmp::Ne, sx, sy).get(), i64::from(x != y));
        let c = m.s_cmp(Cmp::Ge, sx, sy);
        assert_eq!(m.s_select(c, sx, sy).get(), if x >= y { x } else { y });
        assert_eq!(m.s_popcnt(sx).get(), i64::from(x.count_ones()));
        assert_eq!(m.s_tzcnt(sx).get(), i64::from(x.trailing_zeros()));
    }
}

fn check_memory_ops<M: Machine>(m: &mut M) {
    let n = M::LANES;
    let fl = M::FLAVOUR;
    let data: Vec<f32> = (0..8 * n).map(|i| i as f32 * 0.5 - 3.0).collect();
    let src = m.space().alloc_f32(MemKind::Other, "src", &data, 64);
    let mut dst = m.space().alloc(MemKind::Other, "dst", 16 * n, 64);
    let off = |i: usize| 4 * i;
    let v = m.load(&src, At::off(off(n)));
    let u = m.loadu(&src, At::off(off(1)));
    for i in 0..n {
        assert_eq!(m.lane(v, i), data[n + i]);
        assert_eq!(m.lane(u, i), data[1 + i]);
    }
    let ix = m.int(3);
    let b = m.load_bcast(&src, At::idx(ix, 4, 8)); // element 5
    let base = m.int(8);
    let b6 = m.load_bcast(&src, At::base_idx(base, ix, 4, 4)); // 8 + 12 + 4 bytes: element 6
    let x6 = m.x_load(&src, At::base_idx(base, ix, 4, 4));
    assert_eq!(m.lane(b6, n - 1), data[6]);
    assert_eq!(x6.get(), data[6]);
    let r4 = m.load_repeat(&src, At::off(off(2)), 4.min(n));
    for i in 0..n {
        assert_eq!(m.lane(b, i), data[5]);
        assert_eq!(m.lane(r4, i), data[2 + i % 4.min(n)]);
    }
    let full = LaneMask::full(n).0;
    let k = m.mask(0x5a5a & full);
    let z = m.splat(-9.0);
    let lm = m.load_masked(k, z, &src, At::off(0));
    for i in 0..n {
        let want = if (0x5a5a & full) >> i & 1 == 1 {
            data[i]
        } else {
            -9.0
        };
        assert_eq!(m.lane(lm, i), want, "{fl:?} load_masked");
    }
    m.store(&mut dst, At::off(0), v);
    m.storeu(&mut dst, At::off(off(n) + 4), u);
    m.store_masked(k, &mut dst, At::off(off(3 * n)), v);
    for i in 0..n {
        assert_eq!(dst.f32_at(off(i)), data[n + i]);
        assert_eq!(dst.f32_at(off(n + 1 + i)), data[1 + i]);
        let want = if (0x5a5a & full) >> i & 1 == 1 {
            data[n + i]
        } else {
            0.0
        };
        assert_eq!(dst.f32_at(off(3 * n + i)), want, "{fl:?} store_masked");
    }
    let idx: Vec<i32> = (0..n as i32)
        .map(|i| (i * 5 + 1) % (8 * n as i32))
        .collect();
    let vi = m.consts_i(&idx);
    let g = m.gather(k, z, &src, At::off(0), vi, 4);
    for i in 0..n {
        let want = if (0x5a5a & full) >> i & 1 == 1 {
            data[idx[i] as usize]
        } else {
            -9.0
        };
        assert_eq!(m.lane(g, i), want, "{fl:?} gather");
    }
    let mut sc = m.space().alloc(MemKind::Other, "scatter", 4 * 8 * n, 64);
    m.scatter(k, &mut sc, At::off(0), vi, 4, v);
    for i in 0..n {
        if (0x5a5a & full) >> i & 1 == 1 {
            assert_eq!(
                sc.f32_at(4 * idx[i] as usize),
                data[n + i],
                "{fl:?} scatter"
            );
        }
    }
    let mut cs = m.space().alloc(MemKind::Other, "compress", 4 * n, 64);
    let cnt = m.compress_store(k, &mut cs, At::off(0), v);
    let active: Vec<f32> = (0..n)
        .filter(|i| (0x5a5a & full) >> i & 1 == 1)
        .map(|i| data[n + i])
        .collect();
    assert_eq!(cnt.get(), active.len() as i64);
    for (j, w) in active.iter().enumerate() {
        assert_eq!(cs.f32_at(4 * j), *w, "{fl:?} compress");
    }
    let mut ib = m.space().alloc(MemKind::Other, "ints", 64, 64);
    let neg = m.int(-2);
    m.s_store(&mut ib, At::off(8), 2, neg);
    assert_eq!(m.s_load(&ib, At::off(8), 2, false).get(), 0xfffe);
    assert_eq!(m.s_load(&ib, At::off(8), 2, true).get(), -2);
    let xv = m.float(2.5);
    m.x_store(&mut ib, At::off(16), xv);
    assert_eq!(m.x_load(&ib, At::off(16)).get(), 2.5);
    let c = m.int(1);
    assert!(m.branch(isa::Site(1), c));
    let c0 = m.int(0);
    assert!(!m.branch_if(isa::Site(2), Cmp::Lt, c, c0));
}

fn check_all<M: Machine>(mut m: M) -> M {
    let n = M::LANES;
    let l = SPECIAL.len();
    for r1 in 0..l {
        for r2 in 0..l {
            let a: Vec<f32> = (0..n).map(|i| SPECIAL[(r1 + i) % l]).collect();
            let b: Vec<f32> = (0..n).map(|i| SPECIAL[(r2 + 3 * i) % l]).collect();
            let c: Vec<f32> = (0..n).map(|i| SPECIAL[(r1 + r2 + 5 * i) % l]).collect();
            check_float_ops(&mut m, &a, &b, &c);
        }
    }
    // Two-source shuffles over every pattern family.
    let a: Vec<f32> = (0..n).map(|i| i as f32).collect();
    let b: Vec<f32> = (0..n).map(|i| 100.0 + i as f32).collect();
    let va = m.consts(&a);
    let vb = m.consts(&b);
    for pat in shuffle_patterns(n) {
        let r = m.shuffle2(va, vb, &pat);
        for i in 0..n {
            let j = pat[i] as usize;
            let want = if j < n { a[j] } else { b[j - n] };
            assert_eq!(m.lane(r, i), want, "{:?} shuffle2 {pat:?}", M::FLAVOUR);
        }
    }
    check_int_and_mask_ops(&mut m);
    check_memory_ops(&mut m);
    m
}

/// Patterns covering every shuffle2 expansion path.
pub fn shuffle_patterns(n: usize) -> Vec<Vec<u8>> {
    let n8 = n as u8;
    let mut v = Vec::new();
    // one source, in-lane
    v.push((0..n8).map(|i| (i & !3) | (3 - (i & 3))).collect());
    // one source, cross-lane (reverse)
    v.push((0..n8).map(|i| n8 - 1 - i).collect());
    // shufps-like: two from a, two from b, same in each block
    v.push(
        (0..n8)
            .map(|i| {
                if i % 4 < 2 {
                    (i & !3) + 1
                } else {
                    n8 + (i & !3) + 2
                }
            })
            .collect(),
    );
    // unpcklps
    v.push(
        (0..n8)
            .map(|i| (i & !3) + (i % 4) / 2 + if i % 2 == 1 { n8 } else { 0 })
            .collect(),
    );
    // blend by immediate
    v.push(
        (0..n8)
            .map(|i| if i % 3 == 0 { i + n8 } else { i })
            .collect(),
    );
    // whole 128-bit blocks (permute2f128-like): low block of b, then low block of a
    v.push(
        (0..n8)
            .map(|i| if i < 4 { n8 + i % 4 } else { i % 4 })
            .collect(),
    );
    // arbitrary
    v.push((0..n8).map(|i| (i * 7 + 3) % (2 * n8)).collect());
    // all from b
    v.push((0..n8).map(|i| n8 + (n8 - 1 - i)).collect());
    v
}

#[test]
fn traced_lrb16() {
    let m = check_all(Traced::<Lrb16, 16>::new("test"));
    m.finish().validate().unwrap();
}
#[test]
fn traced_avx512() {
    let m = check_all(Traced::<Avx512, 16>::new("test"));
    m.finish().validate().unwrap();
}
#[test]
fn traced_avx2() {
    let m = check_all(Traced::<Avx2, 8>::new("test"));
    m.finish().validate().unwrap();
}
#[test]
fn traced_sse4() {
    let m = check_all(Traced::<Sse4, 4>::new("test"));
    m.finish().validate().unwrap();
}
#[test]
fn traced_wide32() {
    let m = check_all(Traced::<Wide32, 32>::new("test"));
    m.finish().validate().unwrap();
}
#[test]
fn native_wide32() {
    check_all(Native::<Wide32, 32>::new());
}
#[test]
fn native_lrb16() {
    check_all(Native::<Lrb16, 16>::new());
}
#[test]
fn native_avx512() {
    check_all(Native::<Avx512, 16>::new());
}
#[test]
fn native_avx2() {
    check_all(Native::<Avx2, 8>::new());
}
#[test]
fn native_sse4() {
    check_all(Native::<Sse4, 4>::new());
}

#[test]
fn a_recycled_trace_gives_its_buffers_to_the_next_unit_and_nothing_else() {
    let first = check_all(Traced::<Avx2, 8>::new("test")).take();
    let cap = first.ops.capacity();
    assert!(!first.ops.is_empty());
    isa::trace::recycle(first);
    let unit = |m: &mut Traced<Avx2, 8>| {
        let x = m.splat(1.0);
        let y = m.add(x, x);
        m.mul(y, x)
    };
    let mut m = Traced::<Avx2, 8>::new("test");
    let _ = m.take(); // the layout's ops, as record_units drops them
    unit(&mut m);
    let t = m.take();
    let mut fresh = Traced::<Avx2, 8>::new("test");
    unit(&mut fresh);
    assert_eq!(t.ops, fresh.take().ops, "only the new unit's ops");
    assert!(t.ops.capacity() >= cap, "{} < {cap}", t.ops.capacity());
}

#[test]
fn validation_reads_dense_and_far_apart_ids_alike() {
    use isa::trace_text::parse;
    let t = |body: &str| parse(&format!(".trace 1\n.isa avx2\n{body}")).unwrap();
    // Ids far beyond the trace's length (a hand-written trace may name any).
    let far = t("%4000000000 = alu\n%7 = alu %4000000000\n");
    assert!(far.validate().is_ok());
    let twice = t("%4000000000 = alu\n%4000000000 = alu\n");
    assert!(twice.validate().unwrap_err().contains("defined twice"));
    // A source defined later: not a straight trace, but a loop body.
    for body in [
        "%7 = alu %9\n%9 = alu\n",
        "%7 = alu %4000000000\n%4000000000 = alu\n",
    ] {
        let later = t(body);
        assert!(later
            .validate()
            .unwrap_err()
            .contains("not defined before use"));
        assert!(later.validate_loop().is_ok());
    }
    let missing = t("%7 = alu %8\n");
    assert!(missing.validate_loop().is_err());
}
