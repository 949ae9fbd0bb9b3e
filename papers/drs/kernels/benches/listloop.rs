//! DRS BVH2's inner loop, the ray-list loop of one node (the paper's
//! Appendix A, `coreLoopBvh2`), natively by the kernel's own step
//! (`drs_kernels::bvh2::node_item`) and as the paper's listing written by
//! hand in AVX2 + FMA intrinsics: two rays per iteration, a 4-wide box test
//! of both children per ray, scalar appends to three lists advanced by the
//! left-first, right and left-second conditions. The item is the root of a
//! scene's BVH2 with 4096 rays spread over its box and the sphere of
//! directions; the three lists each gets are checked equal to the kernel's
//! outside the timing loop.
//!
//! Run: `cargo bench -p drs-kernels --bench listloop` (`RTSIM_BENCH_SCENE`
//! picks another scene than `conference`). Results, with the machine, are in
//! `rt/benches/RESULTS.md`.

use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};
use drs_kernels::stream::StreamBufs;
use isa::{Avx2, Machine, MemKind, Native};
use rt::layout::{lay_out_bvh2, ray_records, Bvh2Bufs};
use scene::loaded::Loaded;
use scene::HitPolicy;

/// The item: the rays' traversal records and their indices.
struct Item {
    trav: Vec<f32>,
    rays: Vec<u16>,
}

/// The kernel's node step over the item on a native machine, from fresh
/// counters; the three lists' entries.
struct Kernel {
    m: Native<Avx2, 8>,
    s: Bvh2Bufs,
    st: StreamBufs,
    trav: isa::Buf,
    n: usize,
    /// List 0's bytes at the start of a run: the item's indices and the
    /// padding copy of the last (one copy restores them, the appends having
    /// overwritten them in place).
    list0: Vec<u8>,
}

impl Kernel {
    fn new(ld: &Loaded, item: &Item) -> Kernel {
        let mut m = Native::<Avx2, 8>::new();
        let s = lay_out_bvh2(&mut m, &ld.scene.mesh, &ld.b2);
        let n = item.rays.len();
        let st = StreamBufs::new(&mut m, n, ld.b2.depth());
        let trav = m.space().alloc_f32(MemKind::Rays, "trav", &item.trav, 64);
        let list0 = (0..=n)
            .flat_map(|i| (i.min(n - 1) as u16).to_le_bytes())
            .collect();
        Kernel {
            m,
            s,
            st,
            trav,
            n,
            list0,
        }
    }

    /// The root node's rows `[min_l, min_r, max_l, max_r]` per axis.
    fn rows(&self) -> [f32; 12] {
        let base = self.s.root as usize * 64;
        std::array::from_fn(|j| self.s.nodes.f32_at(base + 4 * j))
    }

    /// One run: list 0 holds the item (and its padding copy), every counter
    /// at 0, then the node step.
    fn run(&mut self) {
        let n = self.n;
        self.st.lists.bytes_mut()[..2 * (n + 1)].copy_from_slice(&self.list0);
        for k in 0..9 {
            self.st.counters.set_uint(8 * k, 8, 0);
        }
        let m = &mut self.m;
        let mut sp = m.int(0);
        let node = m.int(i64::from(self.s.root));
        let item = (m.int(0), m.int(n as i64));
        drs_kernels::bvh2::node_item(
            m,
            &self.s,
            &mut self.st,
            &self.trav,
            &mut sp,
            node,
            item,
            HitPolicy::Closest,
        );
    }

    /// The three lists the last run appended (each from 0 to its end, as
    /// the counters say: each counter holds its list's end plus padding).
    fn lists(&self) -> [Vec<u16>; 3] {
        let cap = self.st.cap;
        std::array::from_fn(|k| {
            let items = &self.st.items;
            // The pushed items name each list's start and count.
            let count = (0..3)
                .map(|j| (items.uint_at(16 * j + 4, 1), items.u32_at(16 * j + 12)))
                .find(|&(list, _)| list as usize == k)
                .map_or(0, |(_, c)| c as usize);
            (0..count)
                .map(|i| self.st.lists.u16_at(2 * (k * cap + i)))
                .collect()
        })
    }
}

/// The item at the root of `ld`'s BVH2: 4096 rays from points spread over
/// the root's box in directions spread over the sphere (fixed seed). A
/// tile's camera or bounce rays meet the root's children in one order
/// nearly always, which would leave the left-second list empty.
fn item(ld: &Loaded) -> Item {
    let b = *ld.b2.nodes[0].bounds();
    let mut rng = isa::rng::Rng::new(7);
    let n = 4096;
    let (mut org, mut dir) = (Vec::with_capacity(n), Vec::with_capacity(n));
    while org.len() < n {
        let d = [0, 1, 2].map(|_| rng.range(-1.0, 1.0));
        let len2 = d.iter().map(|c| c * c).sum::<f32>();
        if !(0.01..=1.0).contains(&len2) {
            continue;
        }
        org.push(std::array::from_fn(|a| rng.range(b.lo[a], b.hi[a])));
        dir.push(d);
    }
    let (trav, _) = ray_records(&org, &dir, &vec![f32::INFINITY; n]);
    Item {
        trav,
        rays: (0..n as u16).collect(),
    }
}

#[cfg(target_arch = "x86_64")]
mod hand {
    //! The paper's `coreLoopBvh2` in AVX2 + FMA intrinsics, its mask formed
    //! as the kernel forms it (the listing omits that step).
    use std::arch::x86_64::*;

    /// `_MM_SHUFFLE(d, c, b, a)`.
    const fn m(d: i32, c: i32, b: i32, a: i32) -> i32 {
        (d << 6) | (c << 4) | (b << 2) | a
    }

    /// Rays `rays` (plus one padding copy of the last) against the node
    /// `rows` (`[min_l, min_r, max_l, max_r]` per axis); appends to `lists`
    /// (three of `cap` entries each), returns their lengths.
    ///
    /// # Safety
    /// The host has AVX2 and FMA; `trav` holds every ray's 8-float record;
    /// `lists` holds `3 * cap` entries with `cap >= rays.len()`.
    #[target_feature(enable = "avx2,fma")]
    pub unsafe fn core_loop_bvh2(
        rows: &[f32; 12],
        trav: &[f32],
        rays: &[u16],
        lists: &mut [u16],
        cap: usize,
    ) -> [usize; 3] {
        let neg = _mm256_set1_ps(-0.0);
        let pos_neg = _mm256_setr_ps(0.0, 0.0, -0.0, -0.0, 0.0, 0.0, -0.0, -0.0);
        let row = |a: usize| _mm256_broadcast_ps(&*(rows.as_ptr().add(4 * a) as *const __m128));
        let (bx, by, bz) = (row(0), row(1), row(2));
        let swap = |b: __m256| _mm256_permute_ps::<{ m(1, 0, 3, 2) }>(b);
        let bb = [
            _mm256_xor_ps(bx, pos_neg),
            _mm256_xor_ps(by, pos_neg),
            _mm256_xor_ps(bz, pos_neg),
        ];
        let bb_neg = [
            _mm256_xor_ps(swap(bx), pos_neg),
            _mm256_xor_ps(swap(by), pos_neg),
            _mm256_xor_ps(swap(bz), pos_neg),
        ];
        let t = trav.as_ptr();
        let mut cnt = [0usize; 3];
        let out = lists.as_mut_ptr();
        let n = rays.len();
        let mut i = 0;
        while i < n {
            let (ia, ib) = (rays[i], if i + 1 < n { rays[i + 1] } else { rays[i] });
            let a = _mm256_loadu_ps(t.add(8 * usize::from(ia)));
            let b = _mm256_loadu_ps(t.add(8 * usize::from(ib)));
            let dir_near = _mm256_permute2f128_ps::<0x20>(a, b);
            let org_far = _mm256_permute2f128_ps::<0x31>(a, b);
            let org_far_neg = _mm256_xor_ps(org_far, neg);
            let d = [
                _mm256_permute_ps::<{ m(0, 0, 0, 0) }>(dir_near),
                _mm256_permute_ps::<{ m(1, 1, 1, 1) }>(dir_near),
                _mm256_permute_ps::<{ m(2, 2, 2, 2) }>(dir_near),
            ];
            let o = [
                _mm256_shuffle_ps::<{ m(0, 0, 0, 0) }>(org_far, org_far_neg),
                _mm256_shuffle_ps::<{ m(1, 1, 1, 1) }>(org_far, org_far_neg),
                _mm256_shuffle_ps::<{ m(2, 2, 2, 2) }>(org_far, org_far_neg),
            ];
            let nf = |k: usize| {
                let planes = _mm256_blendv_ps(bb[k], bb_neg[k], d[k]);
                _mm256_fmsub_ps(planes, d[k], o[k])
            };
            let ray = _mm256_shuffle_ps::<{ m(3, 3, 3, 3) }>(dir_near, org_far_neg);
            let x = _mm256_max_ps(_mm256_max_ps(ray, nf(0)), _mm256_max_ps(nf(1), nf(2)));
            let xn = _mm256_xor_ps(x, neg);
            let rhs = _mm256_shuffle_ps::<{ m(0, 0, 3, 2) }>(xn, x);
            let lhs = _mm256_permute_ps::<{ m(1, 1, 1, 0) }>(x);
            let mask = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(lhs, rhs)) as usize;
            let mut append = |idx: u16, bits: usize| {
                let (left, right) = (bits & 1, (bits >> 1) & 1);
                let order = (bits >> 2) & right;
                *out.add(cnt[0]) = idx;
                *out.add(cap + cnt[1]) = idx;
                *out.add(2 * cap + cnt[2]) = idx;
                cnt[0] += left & (1 ^ order);
                cnt[1] += right;
                cnt[2] += left & order;
            };
            append(ia, mask);
            if i + 1 < n {
                append(ib, mask >> 4);
            }
            i += 2;
        }
        cnt
    }
}

fn listloop(c: &mut Criterion) {
    let name = std::env::var("RTSIM_BENCH_SCENE").unwrap_or_else(|_| "conference".into());
    let ld = Loaded::load(&name, &drs_kernels::BVH).expect("the scene");
    let it = item(&ld);
    let n = it.rays.len();
    let mut k = Kernel::new(&ld, &it);
    let rows = k.rows();
    assert_eq!(k.s.root & scene::bvh::LEAF, 0, "{name}: an inner root");
    let mut g = c.benchmark_group("drs-bvh2-list-loop");
    g.throughput(Throughput::Elements(n as u64));
    g.bench_function("native-avx2", |b| b.iter(|| k.run()));
    k.run();
    let native = k.lists();
    assert!(
        native.iter().all(|l| !l.is_empty()),
        "every list gets rays: {:?}",
        native.iter().map(Vec::len).collect::<Vec<_>>()
    );

    #[cfg(target_arch = "x86_64")]
    if is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma") {
        let cap = n + 16;
        let mut lists = vec![0u16; 3 * cap];
        let mut run = |rays: &[u16]| {
            // SAFETY: features checked above; every ray has a record and
            // each list holds `cap >= n` entries.
            unsafe { hand::core_loop_bvh2(&rows, &it.trav, rays, &mut lists, cap) }
        };
        g.bench_function("hand-avx2", |b| b.iter(|| run(black_box(&it.rays))));
        let cnt = run(&it.rays);
        let hand: [Vec<u16>; 3] =
            std::array::from_fn(|j| lists[j * cap..j * cap + cnt[j]].to_vec());
        assert_eq!(
            hand, native,
            "the hand-written listing appends what the kernel appends"
        );
    }
    g.finish();
}

criterion_group!(benches, listloop);
criterion_main!(benches);
