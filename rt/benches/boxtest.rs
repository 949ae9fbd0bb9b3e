//! Native backend vs hand-written AVX2 on the kernels' inner loops: the
//! ray-vs-4-boxes test of single-ray BVH4 and DRS over a 4096-ray stream
//! (the DRS paper's stream size), the packet kernels' 8-rays-vs-one-box test
//! over the children of 1024 BVH4 nodes, single-ray BVH2's node step (each of
//! the 4096 rays against 16 nodes), and the traced backend's recording
//! speed on the first.
//!
//! Run: `cargo bench -p rt --bench boxtest`. Results, with the machine
//! they ran on, are recorded in `rt/benches/RESULTS.md`.

use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};
use isa::{Avx2, Machine, Native, Traced};
use rt::boxtest::bvh2::{bvh2_nodes_stream, Bvh2Nodes};
use rt::boxtest::{box4_stream, packet_nodes_stream, words, BoxStream, PacketNodes};

const RAYS: usize = 4096;
const NODES: usize = 1024;
/// Nodes every ray of the BVH2-step stream is tested against.
const BVH2_NODES: usize = 16;

#[cfg(target_arch = "x86_64")]
mod hand {
    use std::arch::x86_64::*;

    /// The same algorithm written directly with AVX2 + FMA intrinsics.
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA; `rays.len() == 16 * out.len()`.
    #[target_feature(enable = "avx2,fma")]
    pub unsafe fn box4_avx2(node: &[f32; 24], rays: &[f32], out: &mut [u8]) {
        let b = |k: usize| _mm256_broadcast_ps(&*(node.as_ptr().add(4 * k) as *const __m128));
        let (minx, maxx, miny, maxy, minz, maxz) = (b(0), b(1), b(2), b(3), b(4), b(5));
        let n = out.len();
        let mut g = 0;
        while g < n {
            let p = rays.as_ptr().add(16 * g);
            let a = _mm256_loadu_ps(p);
            let c = _mm256_loadu_ps(p.add(8));
            let dn = _mm256_permute2f128_ps::<0x20>(a, c);
            let of = _mm256_permute2f128_ps::<0x31>(a, c);
            let dx = _mm256_permute_ps::<0x00>(dn);
            let dy = _mm256_permute_ps::<0x55>(dn);
            let dz = _mm256_permute_ps::<0xaa>(dn);
            let near = _mm256_permute_ps::<0xff>(dn);
            let ox = _mm256_permute_ps::<0x00>(of);
            let oy = _mm256_permute_ps::<0x55>(of);
            let oz = _mm256_permute_ps::<0xaa>(of);
            let far = _mm256_permute_ps::<0xff>(of);
            let x0 = _mm256_fmsub_ps(minx, dx, ox);
            let x1 = _mm256_fmsub_ps(maxx, dx, ox);
            let y0 = _mm256_fmsub_ps(miny, dy, oy);
            let y1 = _mm256_fmsub_ps(maxy, dy, oy);
            let z0 = _mm256_fmsub_ps(minz, dz, oz);
            let z1 = _mm256_fmsub_ps(maxz, dz, oz);
            let tn = _mm256_max_ps(near, _mm256_min_ps(x0, x1));
            let tf = _mm256_min_ps(far, _mm256_max_ps(x0, x1));
            let tn = _mm256_max_ps(tn, _mm256_min_ps(y0, y1));
            let tf = _mm256_min_ps(tf, _mm256_max_ps(y0, y1));
            let tn = _mm256_max_ps(tn, _mm256_min_ps(z0, z1));
            let tf = _mm256_min_ps(tf, _mm256_max_ps(z0, z1));
            let bits = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(tn, tf));
            *out.get_unchecked_mut(g) = bits as u8;
            g += 1;
        }
    }

    /// The packet kernels' box test written with AVX2 + FMA: one packet of 8
    /// rays (`rows`: idir.xyz, oid.xyz, t_near, t_far, 8 lanes each) against
    /// the 4 children of each node (24 floats apart), each plane broadcast.
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA; `nodes.len() == 6 * out.len()`.
    #[target_feature(enable = "avx2,fma")]
    pub unsafe fn packet_nodes_avx2(nodes: &[f32], rows: &[f32], out: &mut [u32]) {
        let r = |k: usize| _mm256_loadu_ps(rows.as_ptr().add(8 * k));
        let (id, oid) = ([r(0), r(1), r(2)], [r(3), r(4), r(5)]);
        let (tnear, tfar) = (r(6), r(7));
        for j in 0..out.len() / 4 {
            let nb = nodes.as_ptr().add(24 * j);
            for c in 0..4 {
                let (mut near, mut far) = (tnear, tfar);
                for a in 0..3 {
                    let lo = _mm256_broadcast_ss(&*nb.add(8 * a + c));
                    let hi = _mm256_broadcast_ss(&*nb.add(8 * a + 4 + c));
                    let t0 = _mm256_fmsub_ps(lo, id[a], oid[a]);
                    let t1 = _mm256_fmsub_ps(hi, id[a], oid[a]);
                    near = _mm256_max_ps(near, _mm256_min_ps(t0, t1));
                    far = _mm256_min_ps(far, _mm256_max_ps(t0, t1));
                }
                let bits = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far));
                *out.get_unchecked_mut(4 * j + c) = bits as u32;
            }
        }
    }

    /// Single-ray BVH2's node step written with SSE + FMA (the 4 lanes that
    /// carry data, as Embree's BVH2 path): every ray (`rays`, 8 floats
    /// each) against the nodes (`nodes`, 16 words each) in turn up to its
    /// first miss, the next node (`u32::MAX`: none) into `out` at
    /// `nodes * ray + node`, the farther child and its entry distance
    /// pushed on `stack` when both are hit; the number of pushes.
    /// `BRANCH_FREE`: after the miss test, selects instead of the kernel's
    /// branches, and the entry past the last push holds a candidate never
    /// pushed.
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA; `out.len()` is rays times nodes,
    /// `stack.len()` twice that plus 2.
    #[target_feature(enable = "avx2,fma")]
    pub unsafe fn bvh2_nodes_avx2<const BRANCH_FREE: bool>(
        nodes: &[u32],
        rays: &[f32],
        out: &mut [u32],
        stack: &mut [u32],
    ) -> usize {
        let nn = nodes.len() / 16;
        let (mut rb, mut sp) = (0, 0);
        for ray in rays.chunks_exact(8) {
            let b = |k: usize| _mm_set1_ps(*ray.get_unchecked(k));
            let (idir, oid) = ([b(0), b(1), b(2)], [b(4), b(5), b(6)]);
            let (tnear, tfar) = (b(3), b(7));
            for j in 0..nn {
                let nb = nodes.as_ptr().add(16 * j);
                let (mut tn, mut tf) = (tnear, tfar);
                for a in 0..3 {
                    let p = _mm_loadu_ps(nb.add(4 * a) as *const f32);
                    let t = _mm_fmsub_ps(p, idir[a], oid[a]);
                    let sw = _mm_permute_ps::<0b01_00_11_10>(t);
                    tn = _mm_max_ps(tn, _mm_min_ps(t, sw));
                    tf = _mm_min_ps(tf, _mm_max_ps(t, sw));
                }
                let bits = _mm_movemask_ps(_mm_cmp_ps::<_CMP_LE_OQ>(tn, tf)) & 3;
                let o = rb + j;
                if bits == 0 {
                    // A miss ends the descent.
                    *out.get_unchecked_mut(o) = u32::MAX;
                    break;
                }
                let (l, r) = (*nb.add(12), *nb.add(13));
                let dl = _mm_cvtss_f32(tn);
                let dr = _mm_cvtss_f32(_mm_permute_ps::<1>(tn));
                let next = next_child::<BRANCH_FREE>(bits, (l, r), (dl, dr), stack, &mut sp);
                *out.get_unchecked_mut(o) = next;
            }
            rb += nn;
        }
        sp
    }

    /// The next node of a BVH2 step whose children `bits` hit (1 left, 2
    /// right, 3 both), the farther pushed with its entry distance when both
    /// are. `BRANCH_FREE`: selects instead of the kernel's branches, the
    /// entry past the last push holding a candidate never pushed.
    ///
    /// # Safety
    /// `stack` has room for the push at `sp`.
    #[inline(always)]
    unsafe fn next_child<const BRANCH_FREE: bool>(
        bits: i32,
        (l, r): (u32, u32),
        (dl, dr): (f32, f32),
        stack: &mut [u32],
        sp: &mut usize,
    ) -> u32 {
        if BRANCH_FREE {
            // The farther child is stored every step and kept (sp
            // advanced) only when both are hit.
            let (near, far, d) = if dr < dl { (r, l, dl) } else { (l, r, dr) };
            *stack.get_unchecked_mut(2 * *sp) = far;
            *stack.get_unchecked_mut(2 * *sp + 1) = d.to_bits();
            *sp += usize::from(bits == 3);
            let one = if bits == 1 { l } else { r };
            if bits == 3 {
                near
            } else {
                one
            }
        } else if bits == 3 {
            // The kernel's (and Embree's) branches: one or both
            // children, then which is nearer.
            let (near, far, d) = if dr < dl { (r, l, dl) } else { (l, r, dr) };
            *stack.get_unchecked_mut(2 * *sp) = far;
            *stack.get_unchecked_mut(2 * *sp + 1) = d.to_bits();
            *sp += 1;
            near
        } else if bits == 1 {
            l
        } else {
            r
        }
    }

    /// [`bvh2_nodes_avx2`] with the kernel's branches at the kernel's width
    /// for the avx2 flavour: every vector op on 256 bits, the node's 16
    /// bytes repeated in both halves (`vbroadcastf128`, as the kernel's
    /// `load_repeat`), 4 of the 8 lanes of use. Beside the 128-bit version
    /// it measures what the width alone costs on this host (on Zen 1 a
    /// 256-bit op is two 128-bit macro-ops).
    ///
    /// # Safety
    /// As [`bvh2_nodes_avx2`].
    #[target_feature(enable = "avx2,fma")]
    pub unsafe fn bvh2_nodes_avx2_ymm(
        nodes: &[u32],
        rays: &[f32],
        out: &mut [u32],
        stack: &mut [u32],
    ) -> usize {
        let nn = nodes.len() / 16;
        let (mut rb, mut sp) = (0, 0);
        for ray in rays.chunks_exact(8) {
            let b = |k: usize| _mm256_set1_ps(*ray.get_unchecked(k));
            let (idir, oid) = ([b(0), b(1), b(2)], [b(4), b(5), b(6)]);
            let (tnear, tfar) = (b(3), b(7));
            for j in 0..nn {
                let nb = nodes.as_ptr().add(16 * j);
                let (mut tn, mut tf) = (tnear, tfar);
                for a in 0..3 {
                    let p = _mm256_broadcast_ps(&*(nb.add(4 * a) as *const __m128));
                    let t = _mm256_fmsub_ps(p, idir[a], oid[a]);
                    let sw = _mm256_permute_ps::<0b01_00_11_10>(t);
                    tn = _mm256_max_ps(tn, _mm256_min_ps(t, sw));
                    tf = _mm256_min_ps(tf, _mm256_max_ps(t, sw));
                }
                let bits = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(tn, tf)) & 3;
                let o = rb + j;
                if bits == 0 {
                    *out.get_unchecked_mut(o) = u32::MAX;
                    break;
                }
                let (l, r) = (*nb.add(12), *nb.add(13));
                let lo = _mm256_castps256_ps128(tn);
                let dl = _mm_cvtss_f32(lo);
                let dr = _mm_cvtss_f32(_mm_permute_ps::<1>(lo));
                let next = next_child::<false>(bits, (l, r), (dl, dr), stack, &mut sp);
                *out.get_unchecked_mut(o) = next;
            }
            rb += nn;
        }
        sp
    }
}

fn bench(c: &mut Criterion) {
    let w = BoxStream::generate(RAYS, 7);
    let mut group = c.benchmark_group("ray-vs-4-boxes");
    group.throughput(Throughput::Elements(RAYS as u64));

    let mut m = Native::<Avx2, 8>::new();
    let (node, rays, mut out) = w.buffers(&mut m);
    group.bench_function("native-avx2", |b| {
        b.iter(|| {
            box4_stream::<_, 8>(&mut m, black_box(&node), black_box(&rays), RAYS, &mut out);
        })
    });
    // Once more outside the timing loop: a filter may have skipped it.
    box4_stream::<_, 8>(&mut m, &node, &rays, RAYS, &mut out);
    let native_out = out.bytes()[..RAYS / 2].to_vec();

    #[cfg(target_arch = "x86_64")]
    if is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma") {
        let flat: Vec<f32> = w.rays.iter().flat_map(|r| r.f).collect();
        let mut hand_out = vec![0u8; RAYS / 2];
        group.bench_function("hand-avx2", |b| {
            // SAFETY: features checked above; sizes match.
            b.iter(|| unsafe {
                hand::box4_avx2(black_box(&w.node.f), black_box(&flat), &mut hand_out)
            })
        });
        // SAFETY: as above.
        unsafe { hand::box4_avx2(&w.node.f, &flat, &mut hand_out) };
        assert_eq!(
            hand_out, native_out,
            "hand-written and native results agree"
        );
    }

    group.bench_function("traced-avx2", |b| {
        b.iter(|| {
            let mut t = Traced::<Avx2, 8>::new("bench");
            let (node, rays, mut out) = w.buffers(&mut t);
            box4_stream::<_, 8>(&mut t, &node, &rays, RAYS, &mut out);
            black_box(t.finish().ops.len())
        })
    });
    group.finish();

    let mut t = Traced::<Avx2, 8>::new("bench");
    let (node, rays, mut out) = w.buffers(&mut t);
    box4_stream::<_, 8>(&mut t, &node, &rays, RAYS, &mut out);
    let ops = t.finish().ops.len();
    println!(
        "traced-avx2 records {ops} ops per {RAYS}-ray stream ({:.1} ops/ray)",
        ops as f64 / RAYS as f64
    );
    let _ = m.space();
    packet_nodes(c);
    bvh2_nodes(c);
}

/// The packet kernels' inner loop, native and hand-written.
fn packet_nodes(c: &mut Criterion) {
    let w = PacketNodes::generate(NODES, 7);
    let mut group = c.benchmark_group("packet-vs-node-boxes");
    group.throughput(Throughput::Elements(4 * NODES as u64));
    let mut m = Native::<Avx2, 8>::new();
    let (nodes, packet, mut out) = w.buffers(&mut m);
    group.bench_function("native-avx2", |b| {
        b.iter(|| {
            packet_nodes_stream(
                &mut m,
                black_box(&nodes),
                NODES,
                black_box(&packet),
                &mut out,
            );
        })
    });
    packet_nodes_stream(&mut m, &nodes, NODES, &packet, &mut out);
    let native_out = w.masks(&out);
    assert_eq!(
        native_out,
        w.reference(8, true),
        "native agrees with the reference"
    );

    #[cfg(target_arch = "x86_64")]
    if is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma") {
        let flat: Vec<f32> = w.nodes.iter().flat_map(|n| n.f).collect();
        let rows = w.packet_rows(8);
        let mut hand_out = vec![0u32; 4 * NODES];
        group.bench_function("hand-avx2", |b| {
            // SAFETY: features checked above; sizes match.
            b.iter(|| unsafe {
                hand::packet_nodes_avx2(black_box(&flat), black_box(&rows), &mut hand_out)
            })
        });
        // SAFETY: as above.
        unsafe { hand::packet_nodes_avx2(&flat, &rows, &mut hand_out) };
        assert_eq!(
            hand_out, native_out,
            "hand-written and native results agree"
        );
    }
    group.finish();
}

/// Single-ray BVH2's inner step, native and hand-written.
fn bvh2_nodes(c: &mut Criterion) {
    let w = Bvh2Nodes::generate(BVH2_NODES, RAYS, 7);
    let steps = BVH2_NODES * RAYS;
    let mut group = c.benchmark_group("ray-vs-bvh2-node");
    group.throughput(Throughput::Elements(RAYS as u64));
    let mut m = Native::<Avx2, 8>::new();
    let [nodes, rays, mut stack, mut out] = w.buffers(&mut m);
    group.bench_function("native-avx2", |b| {
        b.iter(|| {
            let nodes = (black_box(&nodes), BVH2_NODES);
            bvh2_nodes_stream(
                &mut m,
                nodes,
                (black_box(&rays), RAYS),
                &mut stack,
                &mut out,
            );
        })
    });
    bvh2_nodes_stream(
        &mut m,
        (&nodes, BVH2_NODES),
        (&rays, RAYS),
        &mut stack,
        &mut out,
    );
    let native_out = (words(&out, steps), words(&stack, w.stack_words()));
    assert_eq!(
        native_out,
        w.reference(true),
        "native agrees with the reference"
    );

    #[cfg(target_arch = "x86_64")]
    if is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma") {
        let (node_words, flat) = (w.node_words(), w.ray_floats());
        for name in ["hand-avx2", "hand-avx2-branch-free", "hand-avx2-ymm"] {
            let mut hand_out = vec![0u32; steps];
            let mut hand_stack = vec![0u32; w.stack_words() + 2];
            let mut run = |n: &[u32], r: &[f32]| {
                let (o, st) = (&mut hand_out, &mut hand_stack);
                // SAFETY: features checked above; sizes match.
                unsafe {
                    match name {
                        "hand-avx2" => hand::bvh2_nodes_avx2::<false>(n, r, o, st),
                        "hand-avx2-branch-free" => hand::bvh2_nodes_avx2::<true>(n, r, o, st),
                        _ => hand::bvh2_nodes_avx2_ymm(n, r, o, st),
                    }
                }
            };
            group.bench_function(name, |b| {
                b.iter(|| run(black_box(&node_words), black_box(&flat)))
            });
            let pushes = run(&node_words, &flat);
            let (next, stack) = &native_out;
            assert!(
                stack[2 * pushes..].iter().all(|&w| w == 0),
                "as many pushes"
            );
            assert_eq!(
                (&hand_out, &hand_stack[..2 * pushes]),
                (next, &stack[..2 * pushes]),
                "{name} and native results agree"
            );
        }
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
