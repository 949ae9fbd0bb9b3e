//! This host's vector pipes, measured: the latency of a dependent 256-bit
//! add chain gives the clock (the configs' `vadd` latency 3 holds on every
//! AVX2 core they model), then the throughput of independent 256-bit max,
//! FMA and add ops, and of the packet slab test's mix (one FMA feeding a
//! min and a max), in cycles per op, to set beside the machine config of
//! this host (`rtsim calibrate --machine NAME` prints the model's). Thread
//! CPU time, so the other core's load does not count; best of 5.
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
        let rows: [(&str, f64); 4] = [
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
    }
}

fn main() {
    #[cfg(all(target_arch = "x86_64", target_os = "linux"))]
    pipes::main();
    #[cfg(not(all(target_arch = "x86_64", target_os = "linux")))]
    println!("host_pipes: x86-64 Linux only");
}
