//! This host's vector pipes, measured: the latency of a dependent 256-bit
//! add chain gives the clock (the configs' `vadd` latency 3 holds on every
//! AVX2 core they model), then the throughput of independent 256-bit max,
//! FMA and add ops, and of the packet slab test's mix (one FMA feeding a
//! min and a max), in cycles per op, to set beside the machine config of
//! this host (`rtsim calibrate --machine NAME` prints the model's). Thread
//! CPU time, so the other core's load does not count; best of 5.
//!
//! Then the latencies of the single-ray node step's pieces as dependent
//! chains (vmaxps, FMA into max, a compare into its mask, a vector load into
//! one, pointer chases by base + index and by a scaled index, tzcnt, movzx,
//! and round trips between the FP and integer registers), each chain's sum
//! where one piece cannot be closed on itself.
//!
//! On a host with AVX-512 F the same for 512-bit ops, with their latencies
//! (dependent chains) and the mask register's round trip through a general
//! register (`kmovw` both ways), for a config of this host running AVX-512.
//!
//! Run: `cargo bench -p isa --bench host_pipes` (x86-64 Linux with AVX2 and
//! FMA; elsewhere it says so). Results, with the machine, are in
//! `rt/benches/RESULTS.md`.

#[cfg(all(target_arch = "x86_64", target_os = "linux"))]
mod pipes {
    use std::arch::asm;
    use std::arch::x86_64::*;

    /// Ops per measurement.
    const N: usize = 20_000_000;

    #[repr(C)]
    struct Timespec {
        sec: i64,
        nsec: i64,
    }
    extern "C" {
        fn clock_gettime(clock: i32, t: *mut Timespec) -> i32;
    }
    /// `CLOCK_THREAD_CPUTIME_ID`.
    const THREAD_CPU: i32 = 3;

    fn cpu_seconds() -> f64 {
        let mut t = Timespec { sec: 0, nsec: 0 };
        // SAFETY: a valid clock id and a valid out-pointer.
        unsafe { clock_gettime(THREAD_CPU, &mut t) };
        t.sec as f64 + t.nsec as f64 * 1e-9
    }

    /// Nanoseconds per op of `f` doing `ops` ops, best of 5.
    fn ns_per_op(ops: usize, f: impl Fn()) -> f64 {
        (0..5)
            .map(|_| {
                let t = cpu_seconds();
                f();
                cpu_seconds() - t
            })
            .fold(f64::MAX, f64::min)
            * 1e9
            / ops as f64
    }

    /// Eight independent chains of `op`, kept in registers.
    #[target_feature(enable = "avx2,fma")]
    unsafe fn eight(op: fn(__m256) -> __m256) {
        let mut a = [_mm256_set1_ps(0.5); 8];
        for _ in 0..N / 8 {
            for x in &mut a {
                *x = op(*x);
            }
            asm!("/* {} {} {} {} {} {} {} {} */",
                inout(ymm_reg) a[0], inout(ymm_reg) a[1], inout(ymm_reg) a[2], inout(ymm_reg) a[3],
                inout(ymm_reg) a[4], inout(ymm_reg) a[5], inout(ymm_reg) a[6], inout(ymm_reg) a[7]);
        }
        std::hint::black_box(a);
    }

    /// One chain of `vaddps`.
    #[target_feature(enable = "avx2,fma")]
    unsafe fn add_chain() {
        let (mut a, one) = (_mm256_set1_ps(0.5), _mm256_set1_ps(1.0));
        for _ in 0..N {
            a = _mm256_add_ps(a, one);
            asm!("/* {} */", inout(ymm_reg) a);
        }
        std::hint::black_box(a);
    }

    /// Four independent slab steps: `f = fma(a, 1, 0.5); a = max(f, b);
    /// b = min(f, b)` (3 ops each).
    #[target_feature(enable = "avx2,fma")]
    unsafe fn slab_mix() {
        // A multiplier of 1.0 would let the compiler make the FMA an add.
        let (one, h) = (_mm256_set1_ps(1.000_000_1), _mm256_set1_ps(0.5));
        let (mut a, mut b) = ([h; 4], [h; 4]);
        for _ in 0..N / 12 {
            for k in 0..4 {
                let f = _mm256_fmadd_ps(a[k], one, h);
                a[k] = _mm256_max_ps(f, b[k]);
                b[k] = _mm256_min_ps(f, b[k]);
            }
            asm!("/* {} {} {} {} {} {} {} {} */",
                inout(ymm_reg) a[0], inout(ymm_reg) a[1], inout(ymm_reg) a[2], inout(ymm_reg) a[3],
                inout(ymm_reg) b[0], inout(ymm_reg) b[1], inout(ymm_reg) b[2], inout(ymm_reg) b[3]);
        }
        std::hint::black_box((a, b));
    }

    /// Independent 256-bit loads from an L1-resident buffer, as `loads_zmm`.
    #[target_feature(enable = "avx2")]
    unsafe fn loads_ymm() {
        let buf = [0.5f32; 128];
        let p = buf.as_ptr();
        for _ in 0..N / 8 {
            asm!(
                "vmovups {0}, [{p}]", "vmovups {1}, [{p} + 32]",
                "vmovups {2}, [{p} + 64]", "vmovups {3}, [{p} + 96]",
                "vmovups {4}, [{p} + 128]", "vmovups {5}, [{p} + 160]",
                "vmovups {6}, [{p} + 192]", "vmovups {7}, [{p} + 224]",
                out(ymm_reg) _, out(ymm_reg) _, out(ymm_reg) _, out(ymm_reg) _,
                out(ymm_reg) _, out(ymm_reg) _, out(ymm_reg) _, out(ymm_reg) _,
                p = in(reg) p,
                options(nostack, readonly),
            );
        }
        std::hint::black_box(&buf);
    }

    fn max(x: __m256) -> __m256 {
        // SAFETY: called only from `eight`, compiled with AVX2.
        unsafe { _mm256_max_ps(x, _mm256_set1_ps(1.0)) }
    }
    fn fma(x: __m256) -> __m256 {
        // SAFETY: as `max`.
        // Not 1.0: the compiler would make the FMA an add.
        unsafe { _mm256_fmadd_ps(x, _mm256_set1_ps(0.999_999_9), _mm256_set1_ps(0.5)) }
    }
    fn add(x: __m256) -> __m256 {
        // SAFETY: as `max`.
        unsafe { _mm256_add_ps(x, _mm256_set1_ps(1.0)) }
    }

    /// Eight independent chains of a 512-bit `op`, kept in registers.
    #[target_feature(enable = "avx512f")]
    unsafe fn eight_zmm(op: fn(__m512) -> __m512) {
        let mut a = [_mm512_set1_ps(0.5); 8];
        for _ in 0..N / 8 {
            for x in &mut a {
                *x = op(*x);
            }
            asm!("/* {} {} {} {} {} {} {} {} */",
                inout(zmm_reg) a[0], inout(zmm_reg) a[1], inout(zmm_reg) a[2], inout(zmm_reg) a[3],
                inout(zmm_reg) a[4], inout(zmm_reg) a[5], inout(zmm_reg) a[6], inout(zmm_reg) a[7]);
        }
        std::hint::black_box(a);
    }

    /// One chain of a 512-bit `op`.
    #[target_feature(enable = "avx512f")]
    unsafe fn chain_zmm(op: fn(__m512) -> __m512) {
        let mut a = _mm512_set1_ps(0.5);
        for _ in 0..N {
            a = op(a);
            asm!("/* {} */", inout(zmm_reg) a);
        }
        std::hint::black_box(a);
    }

    /// One chain of a mask's round trip: `kmovw r32, k` then `kmovw k, r32`,
    /// 100 per asm block (the compiler moves nothing in between).
    #[target_feature(enable = "avx512f")]
    unsafe fn kmov_chain() {
        for _ in 0..N / 100 {
            asm!(".rept 100", "kmovw k1, eax", "kmovw eax, k1", ".endr",
                out("eax") _, out("k1") _, options(nostack, nomem));
        }
    }

    /// One chain of `kandw`, 100 per asm block.
    #[target_feature(enable = "avx512f")]
    unsafe fn kand_chain() {
        for _ in 0..N / 100 {
            asm!(".rept 100", "kandw k1, k1, k1", ".endr",
                out("k1") _, options(nostack, nomem));
        }
    }

    /// 512-bit stores to an L1-resident buffer, 8 per step.
    #[target_feature(enable = "avx512f")]
    unsafe fn stores_zmm() {
        let mut buf = [0.5f32; 256];
        let p = buf.as_mut_ptr();
        for _ in 0..N / 8 {
            asm!(
                "vmovups [{p}], zmm0", "vmovups [{p} + 64], zmm0",
                "vmovups [{p} + 128], zmm0", "vmovups [{p} + 192], zmm0",
                "vmovups [{p} + 256], zmm0", "vmovups [{p} + 320], zmm0",
                "vmovups [{p} + 384], zmm0", "vmovups [{p} + 448], zmm0",
                p = in(reg) p, out("zmm0") _, options(nostack),
            );
        }
        std::hint::black_box(&buf);
    }

    /// Compressing stores (`vcompressps [mem]{k}, zmm`, half the lanes
    /// active), 8 per step, and the same into a register (`vcompressps
    /// zmm{k}{z}, zmm`) alone and then with a full store (form 0, 1, 2): DRS's
    /// stream compaction.
    #[target_feature(enable = "avx512f")]
    unsafe fn compress_zmm(form: u8) {
        let mut buf = [0.5f32; 256];
        let p = buf.as_mut_ptr();
        let k: __mmask16 = 0x5a5a;
        for _ in 0..N / 8 {
            if form == 0 {
                asm!(".rept 8", "vcompressps [{p}]{{{k}}}, zmm0", ".endr",
                    p = in(reg) p, k = in(kreg) k, out("zmm0") _, options(nostack));
            } else if form == 1 {
                asm!("vcompressps zmm1{{{k}}}{{z}}, zmm0", "vcompressps zmm2{{{k}}}{{z}}, zmm0",
                    "vcompressps zmm3{{{k}}}{{z}}, zmm0", "vcompressps zmm4{{{k}}}{{z}}, zmm0",
                    "vcompressps zmm5{{{k}}}{{z}}, zmm0", "vcompressps zmm6{{{k}}}{{z}}, zmm0",
                    "vcompressps zmm7{{{k}}}{{z}}, zmm0", "vcompressps zmm8{{{k}}}{{z}}, zmm0",
                    k = in(kreg) k, out("zmm0") _, out("zmm1") _, out("zmm2") _, out("zmm3") _,
                    out("zmm4") _, out("zmm5") _, out("zmm6") _, out("zmm7") _, out("zmm8") _,
                    options(nostack, nomem));
            } else {
                asm!("vcompressps zmm1{{{k}}}{{z}}, zmm0", "vmovups [{p}], zmm1",
                    "vcompressps zmm2{{{k}}}{{z}}, zmm0", "vmovups [{p} + 64], zmm2",
                    "vcompressps zmm3{{{k}}}{{z}}, zmm0", "vmovups [{p} + 128], zmm3",
                    "vcompressps zmm4{{{k}}}{{z}}, zmm0", "vmovups [{p} + 192], zmm4",
                    "vcompressps zmm5{{{k}}}{{z}}, zmm0", "vmovups [{p} + 256], zmm5",
                    "vcompressps zmm6{{{k}}}{{z}}, zmm0", "vmovups [{p} + 320], zmm6",
                    "vcompressps zmm7{{{k}}}{{z}}, zmm0", "vmovups [{p} + 384], zmm7",
                    "vcompressps zmm8{{{k}}}{{z}}, zmm0", "vmovups [{p} + 448], zmm8",
                    p = in(reg) p, k = in(kreg) k, out("zmm0") _, out("zmm1") _, out("zmm2") _,
                    out("zmm3") _, out("zmm4") _, out("zmm5") _, out("zmm6") _, out("zmm7") _,
                    out("zmm8") _, options(nostack));
            }
        }
        std::hint::black_box(&buf);
    }

    /// Masked 512-bit loads (`vmovups zmm{k}{z}, m`), stores (`vmovups
    /// m{k}, zmm`) and gathers (`vgatherdps zmm{k}`, 16 indices in one
    /// 1 KB buffer), half the lanes active, 8 per step (form 0, 1, 2).
    #[target_feature(enable = "avx512f")]
    unsafe fn masked_zmm(form: u8) {
        let mut buf = [0.5f32; 256];
        let p = buf.as_mut_ptr();
        let k: __mmask16 = 0x5a5a;
        let idx = _mm512_setr_epi32(
            0, 17, 34, 51, 68, 85, 102, 119, 136, 153, 170, 187, 204, 221, 238, 255,
        );
        for _ in 0..N / 8 {
            match form {
                0 => asm!(".rept 8", "vmovups zmm1{{{k}}}{{z}}, [{p}]", ".endr",
                    p = in(reg) p, k = in(kreg) k, out("zmm1") _, options(nostack, readonly)),
                1 => asm!(".rept 8", "vmovups [{p}]{{{k}}}, zmm0", ".endr",
                    p = in(reg) p, k = in(kreg) k, out("zmm0") _, options(nostack)),
                _ => asm!(
                    "kmovw k1, {k:e}", "vgatherdps zmm1{{k1}}, [{p} + 4 * {i}]",
                    "kmovw k1, {k:e}", "vgatherdps zmm2{{k1}}, [{p} + 4 * {i}]",
                    "kmovw k1, {k:e}", "vgatherdps zmm3{{k1}}, [{p} + 4 * {i}]",
                    "kmovw k1, {k:e}", "vgatherdps zmm4{{k1}}, [{p} + 4 * {i}]",
                    "kmovw k1, {k:e}", "vgatherdps zmm5{{k1}}, [{p} + 4 * {i}]",
                    "kmovw k1, {k:e}", "vgatherdps zmm6{{k1}}, [{p} + 4 * {i}]",
                    "kmovw k1, {k:e}", "vgatherdps zmm7{{k1}}, [{p} + 4 * {i}]",
                    "kmovw k1, {k:e}", "vgatherdps zmm8{{k1}}, [{p} + 4 * {i}]",
                    p = in(reg) p, k = in(reg) u32::from(k), i = in(zmm_reg) idx, out("k1") _,
                    out("zmm1") _, out("zmm2") _, out("zmm3") _, out("zmm4") _, out("zmm5") _,
                    out("zmm6") _, out("zmm7") _, out("zmm8") _, options(nostack, readonly)),
            }
        }
        std::hint::black_box(&buf);
    }

    /// Independent `kandw` (six masks), 96 per asm block.
    #[target_feature(enable = "avx512f")]
    unsafe fn kand_free() {
        for _ in 0..N / 96 {
            asm!(".rept 16", "kandw k1, k1, k1", "kandw k2, k2, k2", "kandw k3, k3, k3",
                "kandw k4, k4, k4", "kandw k5, k5, k5", "kandw k6, k6, k6", ".endr",
                out("k1") _, out("k2") _, out("k3") _, out("k4") _, out("k5") _, out("k6") _,
                options(nostack, nomem));
        }
    }

    /// Independent `vcmpps k, zmm, zmm` (six masks), 96 per asm block.
    #[target_feature(enable = "avx512f")]
    unsafe fn cmp_free() {
        for _ in 0..N / 96 {
            asm!(".rept 16", "vcmpltps k1, zmm0, zmm1", "vcmpltps k2, zmm0, zmm1",
                "vcmpltps k3, zmm0, zmm1", "vcmpltps k4, zmm0, zmm1",
                "vcmpltps k5, zmm0, zmm1", "vcmpltps k6, zmm0, zmm1", ".endr",
                out("k1") _, out("k2") _, out("k3") _, out("k4") _, out("k5") _, out("k6") _,
                out("zmm0") _, out("zmm1") _, options(nostack, nomem));
        }
    }

    /// One chain through a compare into a mask and a blend by it
    /// (`vcmpps k, zmm, zmm` then `vblendmps zmm{k}`): the node test's step
    /// from a compare to a masked select.
    #[target_feature(enable = "avx512f")]
    unsafe fn cmp_blend_chain() {
        let (mut a, b) = (_mm512_set1_ps(0.5), _mm512_set1_ps(1.0));
        for _ in 0..N {
            let k = _mm512_cmp_ps_mask::<_CMP_LT_OQ>(a, b);
            a = _mm512_mask_blend_ps(k, b, a);
            asm!("/* {} */", inout(zmm_reg) a);
        }
        std::hint::black_box(a);
    }

    /// Independent 512-bit loads from an L1-resident buffer, 8 per step into
    /// registers nothing reads (no FP op beside them).
    #[target_feature(enable = "avx512f")]
    unsafe fn loads_zmm() {
        let buf = [0.5f32; 256];
        let p = buf.as_ptr();
        for _ in 0..N / 8 {
            asm!(
                "vmovups {0}, [{p}]", "vmovups {1}, [{p} + 64]",
                "vmovups {2}, [{p} + 128]", "vmovups {3}, [{p} + 192]",
                "vmovups {4}, [{p} + 256]", "vmovups {5}, [{p} + 320]",
                "vmovups {6}, [{p} + 384]", "vmovups {7}, [{p} + 448]",
                out(zmm_reg) _, out(zmm_reg) _, out(zmm_reg) _, out(zmm_reg) _,
                out(zmm_reg) _, out(zmm_reg) _, out(zmm_reg) _, out(zmm_reg) _,
                p = in(reg) p,
                options(nostack, readonly),
            );
        }
        std::hint::black_box(&buf);
    }

    fn max_zmm(x: __m512) -> __m512 {
        // SAFETY: called only from the zmm loops, compiled with AVX-512 F.
        unsafe { _mm512_max_ps(x, _mm512_set1_ps(1.0)) }
    }
    fn fma_zmm(x: __m512) -> __m512 {
        // SAFETY: as `max_zmm`.
        unsafe { _mm512_fmadd_ps(x, _mm512_set1_ps(0.999_999_9), _mm512_set1_ps(0.5)) }
    }
    fn div_zmm(x: __m512) -> __m512 {
        // SAFETY: as `max_zmm`.
        unsafe { _mm512_div_ps(x, _mm512_set1_ps(1.000_000_1)) }
    }
    fn sqrt_zmm(x: __m512) -> __m512 {
        // SAFETY: as `max_zmm`.
        unsafe { _mm512_sqrt_ps(x) }
    }
    fn add_zmm(x: __m512) -> __m512 {
        // SAFETY: as `max_zmm`.
        unsafe { _mm512_add_ps(x, _mm512_set1_ps(1.0)) }
    }

    /// The 512-bit rows, in cycles at the clock `ghz`.
    fn zmm_rows(ghz: f64) {
        // SAFETY (every call below): AVX-512 F checked by the caller.
        let lat: [(&str, f64); 7] = [
            ("vdivps zmm", ns_per_op(N, || unsafe { chain_zmm(div_zmm) })),
            (
                "vsqrtps zmm",
                ns_per_op(N, || unsafe { chain_zmm(sqrt_zmm) }),
            ),
            ("vaddps zmm", ns_per_op(N, || unsafe { chain_zmm(add_zmm) })),
            ("vfmadd zmm", ns_per_op(N, || unsafe { chain_zmm(fma_zmm) })),
            (
                "vcmpps k + vblendmps",
                ns_per_op(N, || unsafe { cmp_blend_chain() }),
            ),
            (
                "kmovw r,k + kmovw k,r",
                ns_per_op(N, || unsafe { kmov_chain() }),
            ),
            ("kandw", ns_per_op(N, || unsafe { kand_chain() })),
        ];
        for (name, ns) in lat {
            println!(
                "{name:20} {:.3} cycles (latency, dependent chain)",
                ns * ghz
            );
        }
        let thr: [(&str, f64); 15] = [
            ("vdivps zmm", ns_per_op(N, || unsafe { eight_zmm(div_zmm) })),
            (
                "vsqrtps zmm",
                ns_per_op(N, || unsafe { eight_zmm(sqrt_zmm) }),
            ),
            (
                "vmovups zmm{k} load",
                ns_per_op(N, || unsafe { masked_zmm(0) }),
            ),
            (
                "vmovups m{k} store",
                ns_per_op(N, || unsafe { masked_zmm(1) }),
            ),
            ("vgatherdps zmm", ns_per_op(N, || unsafe { masked_zmm(2) })),
            (
                "vcompressps m{k}",
                ns_per_op(N, || unsafe { compress_zmm(0) }),
            ),
            ("vcompressps r", ns_per_op(N, || unsafe { compress_zmm(1) })),
            (
                "vcompressps r + st",
                ns_per_op(N, || unsafe { compress_zmm(2) }),
            ),
            (
                "vmovups zmm store",
                ns_per_op(N, || unsafe { stores_zmm() }),
            ),
            ("kandw", ns_per_op(N, || unsafe { kand_free() })),
            ("vcmpps k, zmm", ns_per_op(N, || unsafe { cmp_free() })),
            ("vmovups zmm load", ns_per_op(N, || unsafe { loads_zmm() })),
            ("vmaxps zmm", ns_per_op(N, || unsafe { eight_zmm(max_zmm) })),
            ("vfmadd zmm", ns_per_op(N, || unsafe { eight_zmm(fma_zmm) })),
            ("vaddps zmm", ns_per_op(N, || unsafe { eight_zmm(add_zmm) })),
        ];
        for (name, ns) in thr {
            println!("{name:20} {:.3} cycles/op (independent)", ns * ghz);
        }
    }

    /// One chain of 100 `step`s per asm block over a zeroed 256-byte buffer
    /// (`{b}` its address, `{r}` the chained register starting at 0, `{x}`
    /// a scratch xmm), `N` steps in all.
    macro_rules! chain {
        ($name:ident, $($step:literal),+) => {
            #[target_feature(enable = "avx2,fma")]
            unsafe fn $name() {
                let buf = [0u64; 32];
                let mut r: u64 = 0;
                for _ in 0..N / 100 {
                    asm!("/* {r} {b} {x} */", ".rept 100", $($step),+, ".endr",
                        r = inout(reg) r, b = in(reg) buf.as_ptr(), x = out(xmm_reg) _,
                        options(nostack, readonly));
                }
                std::hint::black_box((r, &buf));
            }
        };
    }
    // A pointer chase through a zero offset: base + index.
    chain!(load_base_index, "mov {r}, [{b} + {r}]");
    // The child load's form: base + index * 4 + displacement, 32 bits.
    chain!(load_scaled, "mov {r:e}, [{b} + {r} * 4 + 0x60]");
    chain!(tzcnt_chain, "tzcnt {r}, {r}", "and {r}, 0");
    chain!(movzx_chain, "movzx {r:e}, {r:l}");
    // FP to integer and back: the mask move, and a plain move for the pair.
    chain!(movmsk_trip, "vmovmskps {r:e}, {x}", "vmovd {x}, {r:e}");
    chain!(movd_trip, "vmovd {r:e}, {x}", "vmovd {x}, {r:e}");
    // A vector load at an integer-indexed address, back to the integer side.
    chain!(vload_trip, "vmovups {x}, [{b} + {r}]", "vmovd {r:e}, {x}");
    chain!(max_chain, "vmaxps {x}, {x}, {x}");
    // The whole node step as `host_chain`'s loop compiles it, on zeros:
    // address, plane load, FMA, two maxes, compare, mask, movzx, tzcnt
    // (of a zero mask: 32, so `and` keeps the index 0), the child load.
    chain!(
        node_step,
        "shl {r}, 7",
        "vmovups {x}, [{b} + {r}]",
        "vfmadd132ps {x}, {x}, {x}",
        "vmaxps {x}, {x}, {x}",
        "vmaxps {x}, {x}, {x}",
        "vcmpleps {x}, {x}, {x}",
        "vmovmskps {r:e}, {x}",
        "movzx {r:e}, {r:l}",
        "tzcnt {r:e}, {r:e}",
        "and {r:e}, 0",
        "mov {r:e}, [{b} + {r} * 4 + 0x60]"
    );
    chain!(
        fma_max_chain,
        "vfmadd132ps {x}, {x}, {x}",
        "vmaxps {x}, {x}, {x}"
    );
    // The node step's compare into its mask, and its load straight to one.
    chain!(
        cmp_trip,
        "vcmpleps {x}, {x}, {x}",
        "vmovmskps {r:e}, {x}",
        "vmovd {x}, {r:e}"
    );
    chain!(
        vload_msk,
        "vmovups {x}, [{b} + {r}]",
        "vmovmskps {r:e}, {x}",
        "and {r}, 0"
    );

    /// The single-ray node step's integer and crossing pieces as latency
    /// chains, in cycles at `ghz`.
    fn step_rows(ghz: f64) {
        // SAFETY (every call): AVX2 checked by the caller.
        let rows: [(&str, f64); 12] = [
            (
                "node step (host_chain's)",
                ns_per_op(N, || unsafe { node_step() }),
            ),
            ("vmaxps xmm", ns_per_op(N, || unsafe { max_chain() })),
            (
                "vfmadd + vmaxps xmm",
                ns_per_op(N, || unsafe { fma_max_chain() }),
            ),
            (
                "vcmpps + vmovmskps + vmovd",
                ns_per_op(N, || unsafe { cmp_trip() }),
            ),
            (
                "vmovups + vmovmskps + and",
                ns_per_op(N, || unsafe { vload_msk() }),
            ),
            (
                "mov r, [b + r]",
                ns_per_op(N, || unsafe { load_base_index() }),
            ),
            (
                "mov r32, [b + r*4 + d]",
                ns_per_op(N, || unsafe { load_scaled() }),
            ),
            (
                "tzcnt (+ and r, 0)",
                ns_per_op(N, || unsafe { tzcnt_chain() }),
            ),
            ("movzx r32, r8", ns_per_op(N, || unsafe { movzx_chain() })),
            (
                "vmovmskps + vmovd x,r",
                ns_per_op(N, || unsafe { movmsk_trip() }),
            ),
            (
                "vmovd r,x + vmovd x,r",
                ns_per_op(N, || unsafe { movd_trip() }),
            ),
            (
                "vmovups [b+r] + vmovd",
                ns_per_op(N, || unsafe { vload_trip() }),
            ),
        ];
        for (name, ns) in rows {
            println!(
                "{name:24} {:.3} cycles (latency, dependent chain)",
                ns * ghz
            );
        }
    }

    /// Prints the table.
    pub fn main() {
        if !(is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma")) {
            println!("host_pipes: this host lacks AVX2 or FMA");
            return;
        }
        // SAFETY (every call below): AVX2 and FMA checked above.
        let chain = ns_per_op(N, || unsafe { add_chain() });
        let ghz = 3.0 / chain;
        println!("vaddps ymm chain: {chain:.4} ns/op => clock {ghz:.3} GHz (latency 3)");
        let rows: [(&str, f64); 5] = [
            ("vmovups ymm load", ns_per_op(N, || unsafe { loads_ymm() })),
            ("vmaxps ymm", ns_per_op(N, || unsafe { eight(max) })),
            ("vfmadd ymm", ns_per_op(N, || unsafe { eight(fma) })),
            ("vaddps ymm", ns_per_op(N, || unsafe { eight(add) })),
            (
                "fma + min + max ymm",
                ns_per_op(N, || unsafe { slab_mix() }),
            ),
        ];
        for (name, ns) in rows {
            println!("{name:20} {:.3} cycles/op (independent)", ns * ghz);
        }
        step_rows(ghz);
        if is_x86_feature_detected!("avx512f") {
            zmm_rows(ghz);
        } else {
            println!("(no AVX-512 F on this host: no 512-bit rows)");
        }
    }
}

fn main() {
    #[cfg(all(target_arch = "x86_64", target_os = "linux"))]
    pipes::main();
    #[cfg(not(all(target_arch = "x86_64", target_os = "linux")))]
    println!("host_pipes: x86-64 Linux only");
}
