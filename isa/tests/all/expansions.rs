//! One test per expansion: the exact op classes each flavour records for an op
//! it lacks (or has), as listed in the table at the top of `traced.rs`.

use isa::traced::classes_of;
use isa::OpClass::*;
use isa::{At, Avx2, Avx512, BinOp, Cmp, Fma, Lrb16, Machine, MemKind, Sse4};

#[test]
fn masked_op_is_one_op_with_masks_else_op_plus_blend() {
    assert_eq!(
        classes_of::<Lrb16, 16>(|m| {
            let (k, a) = (m.mask(0xff), m.splat(1.0));
            m.masked(BinOp::Add, k, a, a, a);
        }),
        [VAdd]
    );
    assert_eq!(
        classes_of::<Avx2, 8>(|m| {
            let (k, a) = (m.mask(0xf), m.splat(1.0));
            m.masked(BinOp::Mul, k, a, a, a);
        }),
        [VMul, VBlend]
    );
    assert_eq!(
        classes_of::<Sse4, 4>(|m| {
            let (k, a) = (m.mask(0x3), m.splat(1.0));
            m.masked(BinOp::Min, k, a, a, a);
        }),
        [VMinMax, VBlend]
    );
}

#[test]
fn masked_move_is_maskmov_or_blendv() {
    assert_eq!(
        classes_of::<Avx512, 16>(|m| {
            let (k, a) = (m.mask(1), m.splat(1.0));
            m.select(k, a, a);
        }),
        [VMaskMov]
    );
    assert_eq!(
        classes_of::<Avx2, 8>(|m| {
            let (k, a) = (m.mask(1), m.splat(1.0));
            m.select(k, a, a);
        }),
        [VBlend]
    );
}

#[test]
fn fma_on_sse4_is_mul_plus_add() {
    let run = |kind: Fma| {
        classes_of::<Sse4, 4>(|m| {
            let a = m.splat(2.0);
            m.fma(kind, a, a, a);
        })
    };
    assert_eq!(run(Fma::MAdd), [VMul, VAdd]);
    assert_eq!(run(Fma::MSub), [VMul, VAdd]);
    assert_eq!(run(Fma::NMAdd), [VMul, VAdd]);
    assert_eq!(run(Fma::NMSub), [VMul, VAdd, VLogic]);
    assert_eq!(
        classes_of::<Avx2, 8>(|m| {
            let a = m.splat(2.0);
            m.fmsub(a, a, a);
        }),
        [VFma]
    );
}

#[test]
fn masked_fma_expansions() {
    let run_lrb = classes_of::<Lrb16, 16>(|m| {
        let (k, a) = (m.mask(3), m.splat(2.0));
        m.masked_fma(Fma::MAdd, k, a, a, a);
    });
    assert_eq!(run_lrb, [VFma]);
    let run_avx2 = classes_of::<Avx2, 8>(|m| {
        let (k, a) = (m.mask(3), m.splat(2.0));
        m.masked_fma(Fma::MAdd, k, a, a, a);
    });
    assert_eq!(run_avx2, [VFma, VBlend]);
    let run_sse = classes_of::<Sse4, 4>(|m| {
        let (k, a) = (m.mask(3), m.splat(2.0));
        m.masked_fma(Fma::MAdd, k, a, a, a);
    });
    assert_eq!(run_sse, [VMul, VAdd, VBlend]);
}

#[test]
fn exact_reciprocals_are_divides() {
    let c = classes_of::<Avx2, 8>(|m| {
        let a = m.splat(2.0);
        m.rcp(a);
        m.rsqrt(a);
        m.rcp_approx(a);
        m.rsqrt_approx(a);
        m.abs(a);
        m.neg(a);
    });
    assert_eq!(c, [VDiv, VSqrt, VDiv, VRcp, VRsqrt, VLogic, VLogic]);
}

#[test]
fn extract_costs_by_lane() {
    let c = classes_of::<Avx2, 8>(|m| {
        let a = m.splat(1.0);
        m.extract(a, 0);
        m.extract(a, 2);
        m.extract(a, 4);
        m.extract(a, 6);
    });
    assert_eq!(c, [VShuf, VPerm, VPerm, VShuf]);
    let c = classes_of::<Sse4, 4>(|m| {
        let a = m.splat(1.0);
        m.extract(a, 3);
    });
    assert_eq!(c, [VShuf]);
}

#[test]
fn permute_in_lane_vs_cross() {
    let c = classes_of::<Avx2, 8>(|m| {
        let a = m.splat(1.0);
        m.permute(a, &[1, 0, 3, 2, 5, 4, 7, 6]);
        m.permute(a, &[7, 6, 5, 4, 3, 2, 1, 0]);
    });
    assert_eq!(c, [VShuf, VPerm]);
    let c = classes_of::<Sse4, 4>(|m| {
        let a = m.splat(1.0);
        m.permute(a, &[3, 2, 1, 0]);
    });
    assert_eq!(c, [VShuf]);
}

#[test]
fn shuffle2_expansions() {
    // shufps pattern (DRS appendix: shuffle(orgFar, orgFarNeg, M(0,0,0,0))).
    let shufps = [0u8, 0, 8, 8, 4, 4, 12, 12];
    // permute2f128 pattern (DRS appendix: permute2f128(a, b, 0 | 2 << 4)).
    let p2f128 = [0u8, 1, 2, 3, 8, 9, 10, 11];
    let arbitrary = [0u8, 9, 3, 14, 5, 1, 15, 2];
    let c = classes_of::<Avx2, 8>(|m| {
        let (a, b) = (m.splat(1.0), m.splat(2.0));
        m.shuffle2(a, b, &shufps);
        m.shuffle2(a, b, &p2f128);
        m.shuffle2(a, b, &arbitrary);
    });
    assert_eq!(c, [VShuf, VPerm, VPerm, VPerm, VShuf]);
    let c = classes_of::<Avx512, 16>(|m| {
        let (a, b) = (m.splat(1.0), m.splat(2.0));
        let idx: Vec<u8> = (0..16u8).map(|i| (i * 7 + 3) % 32).collect();
        m.shuffle2(a, b, &idx);
    });
    assert_eq!(c, [VPerm]);
    let c = classes_of::<Sse4, 4>(|m| {
        let (a, b) = (m.splat(1.0), m.splat(2.0));
        m.shuffle2(a, b, &[0, 5, 2, 7]); // blendps
        m.shuffle2(a, b, &[4, 0, 7, 1]); // no single instruction
    });
    assert_eq!(c, [VShuf, VShuf, VShuf, VShuf]);
}

#[test]
fn reductions_are_log2_steps() {
    let c = classes_of::<Avx2, 8>(|m| {
        let a = m.splat(1.0);
        m.hmin(a);
    });
    assert_eq!(c, [VPerm, VMinMax, VShuf, VMinMax, VShuf, VMinMax]);
    let c = classes_of::<Lrb16, 16>(|m| {
        let a = m.splat(1.0);
        m.hsum(a);
    });
    assert_eq!(c, [VPerm, VAdd, VPerm, VAdd, VShuf, VAdd, VShuf, VAdd]);
}

#[test]
fn integer_compare_complements() {
    let c = classes_of::<Avx2, 8>(|m| {
        let a = m.splat_i(1);
        m.icmp(Cmp::Eq, a, a);
        m.icmp(Cmp::Ge, a, a);
    });
    assert_eq!(c, [VICmp, VICmp, VILogic]);
    let c = classes_of::<Avx512, 16>(|m| {
        let a = m.splat_i(1);
        m.icmp(Cmp::Ge, a, a);
    });
    assert_eq!(c, [VICmp]);
}

#[test]
fn mask_ops_by_flavour() {
    let c = classes_of::<Lrb16, 16>(|m| {
        let k = m.mask(5);
        m.kand(k, k);
        m.knot(k);
        m.movemask(k);
        m.popcnt(k);
        m.bitscan(k);
        m.any(k);
        m.all(k);
    });
    assert_eq!(
        c,
        [KLogic, KLogic, MovMsk, MovMsk, BitCnt, MovMsk, Alu, BitCnt, KTest, KTest]
    );
    let c = classes_of::<Avx2, 8>(|m| {
        let k = m.mask(5);
        m.kor(k, k);
        m.knot(k);
    });
    assert_eq!(c, [VLogic, VLogic]);
}

fn with_buf<FL: isa::Flavour<N>, const N: usize>(
    f: impl FnOnce(&mut isa::Traced<FL, N>, &mut isa::Buf),
) -> Vec<isa::OpClass> {
    let mut m = isa::Traced::<FL, N>::new("test");
    let mut b = m.space().alloc(MemKind::Other, "b", 4096, 64);
    f(&mut m, &mut b);
    m.ops().iter().map(|o| o.class).collect()
}

#[test]
fn masked_load_expansions() {
    assert_eq!(
        with_buf::<Avx512, 16>(|m, b| {
            let (k, z) = (m.mask(3), m.splat(0.0));
            m.load_masked(k, z, b, At::off(0));
        }),
        [VLoadMasked]
    );
    assert_eq!(
        with_buf::<Avx2, 8>(|m, b| {
            let (k, z) = (m.mask(3), m.splat(0.0));
            m.load_masked(k, z, b, At::off(0));
        }),
        [VLoadMasked, VBlend]
    );
    assert_eq!(
        with_buf::<Sse4, 4>(|m, b| {
            let (k, z) = (m.mask(3), m.splat(0.0));
            m.load_masked(k, z, b, At::off(0));
        }),
        [VLoad, VBlend]
    );
}

#[test]
fn masked_store_on_sse4_is_per_lane() {
    assert_eq!(
        with_buf::<Avx2, 8>(|m, b| {
            let (k, v) = (m.mask(0b1010), m.splat(1.0));
            m.store_masked(k, b, At::off(0), v);
        }),
        [VStoreMasked]
    );
    assert_eq!(
        with_buf::<Sse4, 4>(|m, b| {
            let (k, v) = (m.mask(0b1001), m.splat(1.0));
            m.store_masked(k, b, At::off(0), v);
        }),
        // lane 0: free extract + store; lane 3: pshufd + store
        [MovMsk, Store, VShuf, Store]
    );
}

#[test]
fn gather_on_sse4_is_per_lane() {
    assert_eq!(
        with_buf::<Avx2, 8>(|m, b| {
            let (k, z, i) = (m.mask(0xff), m.splat(0.0), m.splat_i(2));
            m.gather(k, z, b, At::off(0), i, 4);
        }),
        [VGather]
    );
    assert_eq!(
        with_buf::<Sse4, 4>(|m, b| {
            let (k, z, i) = (m.mask(0b0011), m.splat(0.0), m.splat_i(2));
            m.gather(k, z, b, At::off(0), i, 4);
        }),
        [Load, VInsert, VShuf, Load, VInsert]
    );
}

#[test]
fn scatter_on_avx2_is_extracts_and_stores() {
    assert_eq!(
        with_buf::<Lrb16, 16>(|m, b| {
            let (k, v, i) = (m.mask(0xffff), m.splat(1.0), m.splat_i(2));
            m.scatter(k, b, At::off(0), i, 4, v);
        }),
        [VScatter]
    );
    assert_eq!(
        with_buf::<Avx2, 8>(|m, b| {
            let (k, v) = (m.mask(0b1_0001), m.splat(1.0));
            let i = m.consts_i(&[0, 1, 2, 3, 4, 5, 6, 7]);
            m.scatter(k, b, At::off(0), i, 4, v);
        }),
        // lane 0: index and value extracts are free; lane 4: vextractf128 each
        [MovMsk, Store, VPerm, VPerm, Store]
    );
}

#[test]
fn compress_store_expansions() {
    assert_eq!(
        with_buf::<Avx512, 16>(|m, b| {
            let (k, v) = (m.mask(0x0f0f), m.splat(1.0));
            m.compress_store(k, b, At::off(0), v);
        }),
        [VCompress, MovMsk, BitCnt]
    );
    assert_eq!(
        with_buf::<Avx2, 8>(|m, b| {
            let (k, v) = (m.mask(0x0f), m.splat(1.0));
            m.compress_store(k, b, At::off(0), v);
        }),
        [MovMsk, VLoad, VPerm, VStore, BitCnt]
    );
    assert_eq!(
        with_buf::<Sse4, 4>(|m, b| {
            let (k, v) = (m.mask(0x5), m.splat(1.0));
            m.compress_store(k, b, At::off(0), v);
        }),
        [MovMsk, VLoad, VShuf, VStore, BitCnt]
    );
}

#[test]
fn scalar_min_max_is_cmp_cmov_and_scalar_fma_on_sse4() {
    let c = classes_of::<Avx2, 8>(|m| {
        let (a, b) = (m.int(1), m.int(2));
        m.s_op(isa::SOp::Min, a, b);
        m.s_add(a, b);
    });
    assert_eq!(c, [Cmp, Cmov, Alu]);
    let c = classes_of::<Sse4, 4>(|m| {
        let x = m.float(1.0);
        m.x_fma(Fma::NMSub, x, x, x);
    });
    assert_eq!(c, [VMul, VAdd, VLogic]);
}

#[test]
fn broadcast_loads() {
    assert_eq!(
        with_buf::<Avx2, 8>(|m, b| {
            m.load_bcast(b, At::off(4));
            m.load_repeat(b, At::off(16), 4);
            m.load_repeat(b, At::off(0), 2);
        }),
        [VLoadBcast, VLoadBcast, VLoad, VPerm]
    );
}

#[test]
fn dependencies_are_recorded() {
    let mut m = isa::Traced::<Avx2, 8>::new("deps");
    let b = m.space().alloc(MemKind::Nodes, "n", 256, 64);
    let i = m.s_load(&b, At::off(0), 4, false);
    let v = m.load(&b, At::idx(i, 1, 32));
    let c = m.splat(1.0);
    let w = m.fmadd(v, v, c);
    let t = m.finish();
    let ops = &t.ops;
    assert_eq!(
        ops[1].sources(),
        &[ops[0].dst],
        "load depends on the index load"
    );
    assert_eq!(
        ops[2].sources(),
        &[ops[1].dst, ops[1].dst],
        "constants are not sources"
    );
    assert_eq!(w.id, ops[2].dst);
    assert_eq!(ops[1].addr.0, t.regions[1].base.0 + 32);
    assert_eq!(ops[1].bytes, 32);
}

#[test]
fn two_address_registers_are_both_sources() {
    let mut m = isa::Traced::<Avx2, 8>::new("deps2");
    let b = m.space().alloc_u32(MemKind::Nodes, "n", &[8; 64], 64);
    let node = m.s_load(&b, At::off(0), 4, false);
    let lane = m.s_tzcnt(node); // 3
    let child = m.s_load(&b, At::base_idx(node, lane, 4, 96), 4, false);
    let t = m.finish();
    let ops = &t.ops;
    assert_eq!(
        ops[2].sources(),
        &[ops[1].dst, ops[0].dst],
        "index, then base"
    );
    assert_eq!(child.id, ops[2].dst);
    assert_eq!(ops[2].addr.0, t.regions[1].base.0 + 8 + 4 * 3 + 96);
}

#[test]
fn divide_without_a_divide_is_reciprocal_and_multiply() {
    assert_eq!(
        classes_of::<Lrb16, 16>(|m| {
            let a = m.splat(3.0);
            m.bin(BinOp::Div, a, a);
        }),
        [VRcp, VMul]
    );
    assert_eq!(
        classes_of::<Lrb16, 16>(|m| {
            let (k, a) = (m.mask(0xff), m.splat(3.0));
            m.masked(BinOp::Div, k, a, a, a);
        }),
        [VRcp, VMul]
    );
    assert_eq!(
        classes_of::<Lrb16, 16>(|m| {
            let a = m.splat(3.0);
            m.rcp(a);
        }),
        [VRcp]
    );
    for run in [
        classes_of::<Avx2, 8>(|m| {
            let a = m.splat(3.0);
            m.bin(BinOp::Div, a, a);
        }),
        classes_of::<Avx512, 16>(|m| {
            let a = m.splat(3.0);
            m.rcp(a);
        }),
        classes_of::<Sse4, 4>(|m| {
            let a = m.splat(3.0);
            m.bin(BinOp::Div, a, a);
        }),
    ] {
        assert_eq!(run, [VDiv]);
    }
}

#[test]
fn divide_without_a_divide_rounds_as_reciprocal_times_dividend() {
    use isa::Machine as _;
    let mut t = isa::traced::Traced::<Lrb16, 16>::new("test");
    let (a, b) = (t.splat(1.0), t.splat(3.0));
    let q = t.bin(BinOp::Div, a, b);
    let want = 1.0f32 * isa::lanes::rcp_approx(3.0, 23);
    assert_eq!(t.lane(q, 0), want);
    assert_eq!(
        want,
        1.0 / 3.0,
        "23 bits: the reciprocal is exact to rounding"
    );
}

#[test]
fn memory_operands_fold_where_the_flavour_can() {
    fn ops<FL: isa::Flavour<N>, const N: usize>(n: usize) -> Vec<isa::OpClass> {
        classes_of::<FL, N>(|m| {
            let b = m.space().alloc(MemKind::Other, "d", 256, 64);
            let v = m.load_operand(&b, At::off(0), n);
            m.fma(Fma::MAdd, v, v, v);
        })
    }
    // LRBni: full, {1to16} and {4to16} operands are read by the op.
    assert_eq!(ops::<Lrb16, 16>(1), [VLoadFold, VFma]);
    assert_eq!(ops::<Lrb16, 16>(4), [VLoadFold, VFma]);
    assert_eq!(ops::<Lrb16, 16>(16), [VLoadFold, VFma]);
    // AVX-512: m32bcst and full; 4-float repeats need their own load.
    assert_eq!(ops::<Avx512, 16>(1), [VLoadFold, VFma]);
    assert_eq!(ops::<Avx512, 16>(4), [VLoadBcast, VFma]);
    // AVX2: full (and a 128-bit op's m128); broadcasts are separate loads.
    assert_eq!(ops::<Avx2, 8>(8), [VLoadFold, VFma]);
    assert_eq!(ops::<Avx2, 8>(4), [VLoadFold, VFma]);
    assert_eq!(ops::<Avx2, 8>(1), [VLoadBcast, VFma]);
    // SSE4: full operands only.
    assert_eq!(ops::<Sse4, 4>(4), [VLoadFold, VMul, VAdd]);
    assert_eq!(ops::<Sse4, 4>(1), [VLoadBcast, VMul, VAdd]);
}

#[test]
fn general_register_to_mask_is_one_move_with_mask_registers() {
    assert_eq!(
        classes_of::<Lrb16, 16>(|m| {
            let b = m.int(0b1011);
            let k = m.kmov(b);
            assert_eq!(m.bits(k), 0b1011);
        }),
        [KLogic]
    );
    assert_eq!(
        classes_of::<Avx512, 16>(|m| {
            let b = m.int(0x1_0001);
            let k = m.kmov(b);
            assert_eq!(m.bits(k), 1, "bits beyond the lanes are dropped");
        }),
        [KLogic]
    );
    for run in [
        classes_of::<Avx2, 8>(|m| {
            let b = m.int(0b101);
            let k = m.kmov(b);
            assert_eq!(m.bits(k), 0b101);
        }),
        classes_of::<Sse4, 4>(|m| {
            let b = m.int(0b11);
            let k = m.kmov(b);
            assert_eq!(m.bits(k), 0b11);
        }),
    ] {
        assert_eq!(run, [VBcast, VILogic, VICmp]);
    }
}

#[test]
fn blend_by_sign_is_blendv_or_a_mask_and_a_masked_move() {
    assert_eq!(
        classes_of::<Avx2, 8>(|m| {
            let s = m.consts(&[-1.0, 1.0, -0.0, 0.0, 2.0, -2.0, 3.0, -3.0]);
            let (a, b) = (m.splat(10.0), m.splat(20.0));
            let r = m.blend_sign(s, a, b);
            let got: Vec<f32> = (0..8).map(|i| m.lane(r, i)).collect();
            assert_eq!(got, [20.0, 10.0, 20.0, 10.0, 10.0, 20.0, 10.0, 20.0]);
        }),
        [VBlend]
    );
    assert_eq!(
        classes_of::<Sse4, 4>(|m| {
            let (s, a) = (m.splat(-1.0), m.splat(1.0));
            m.blend_sign(s, a, a);
        }),
        [VBlend]
    );
    for run in [
        classes_of::<Lrb16, 16>(|m| {
            let (s, a) = (m.splat(-1.0), m.splat(1.0));
            m.blend_sign(s, a, a);
        }),
        classes_of::<Avx512, 16>(|m| {
            let (s, a) = (m.splat(-1.0), m.splat(1.0));
            m.blend_sign(s, a, a);
        }),
    ] {
        assert_eq!(run, [VICmp, VMaskMov]);
    }
}
