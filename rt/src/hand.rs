//! Hand-written `std::arch` twins of whole kernels, for the native-speed
//! comparison: the same algorithm over the same layout, written as a
//! person would write it for one host (AVX2 + FMA), with no [`isa::Machine`]
//! in between. A twin's answers are bit-identical to its kernel's on the
//! native backend (a test holds them equal), so what separates the two in
//! time is the cost of writing the kernel once against the ISA model.
//!
//! [`single_bvh4`] is the twin of [`crate::single::trace_bvh4`]: Embree
//! 2.0's single-ray BVH4 traversal (SSE node test, the hit children ordered
//! and sorted as the kernel does) and the 8-wide Moller-Trumbore leaf.
//! Bounds are checked once, when the view is made ([`Bvh4View::new`]: every
//! child ref inside its buffer), not per access.

use crate::layout::{is_leaf, Bvh4Bufs, BLOCK_BYTES, NODE_BYTES};
use scene::bvh::{EMPTY_SLOT, LEAF};
use scene::HitPolicy;

/// One ray's answer as the kernels' hit record holds it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HitRecord {
    /// Hit distance (t_far for a miss, -1 for an occluded shadow ray).
    pub t: f32,
    /// Barycentric u.
    pub u: f32,
    /// Barycentric v.
    pub v: f32,
    /// Triangle id word (-1 as u32: none).
    pub prim: u32,
}

/// A BVH4 layout's node and block bytes, every child ref checked to lie
/// inside its buffer (so the traversal reads without a check per access).
pub struct Bvh4View<'a> {
    nodes: &'a [u8],
    tris: &'a [u8],
}

impl<'a> Bvh4View<'a> {
    /// The view of `s`, or which child ref points outside its buffer.
    ///
    /// # Errors
    /// When the root is missing or a child ref names a node or block past
    /// the end of its buffer.
    pub fn new(s: &'a Bvh4Bufs) -> Result<Self, String> {
        let (nodes, tris) = (s.nodes.bytes(), s.tris.bytes());
        let n_nodes = s.nodes.len() / NODE_BYTES;
        let n_blocks = s.tris.len() / BLOCK_BYTES;
        if n_nodes == 0 {
            return Err("BVH4 layout without a root node".into());
        }
        for i in 0..n_nodes {
            for c in 0..4 {
                let r = s.nodes.u32_at(i * NODE_BYTES + 96 + 4 * c);
                let ok = match r {
                    EMPTY_SLOT => true,
                    r if is_leaf(r) => ((r & !LEAF) as usize) < n_blocks,
                    r => (r as usize) < n_nodes,
                };
                if !ok {
                    return Err(format!("BVH4 node {i} child {c}: ref {r:#x} out of range"));
                }
            }
        }
        Ok(Bvh4View { nodes, tris })
    }
}

/// Whether this host runs the twins (AVX2 and FMA).
#[must_use]
pub fn available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// The registers the twin's node test holds a BVH4 node's 4 child boxes in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NodeWidth {
    /// 4-lane (SSE) registers: Embree 2.0's node test, as a person writes it.
    Xmm,
    /// 8-lane (AVX) registers, the 4 boxes in both halves: the width the
    /// kernel's node test runs at on an 8-lane machine (on a CPU that splits
    /// 256-bit ops in two, such as Zen 1, twice the micro-ops).
    Ymm,
}

impl NodeWidth {
    /// The twin's method name suffix (`hand-single-bvh4` and
    /// `hand-single-bvh4-ymm`).
    #[must_use]
    pub fn suffix(self) -> &'static str {
        match self {
            NodeWidth::Xmm => "",
            NodeWidth::Ymm => "-ymm",
        }
    }
}

/// Rays (`trav`, `isect`: the records of [`crate::layout::ray_records`])
/// through `bvh` as [`crate::single::trace_bvh4`] traces them on an 8-lane
/// native machine, the node test at `width`; `None` when the host lacks
/// AVX2 or FMA.
#[must_use]
pub fn single_bvh4(
    bvh: &Bvh4View,
    (trav, isect): (&[f32], &[f32]),
    policy: HitPolicy,
    width: NodeWidth,
) -> Option<Vec<HitRecord>> {
    assert_eq!(trav.len(), isect.len(), "ray records");
    assert_eq!(trav.len() % 8, 0, "8 words per ray record");
    if !available() {
        return None;
    }
    #[cfg(target_arch = "x86_64")]
    {
        // SAFETY: the host has AVX2 and FMA (checked above).
        Some(unsafe {
            match width {
                NodeWidth::Xmm => avx2::trace::<false>(bvh, trav, isect, policy),
                NodeWidth::Ymm => avx2::trace::<true>(bvh, trav, isect, policy),
            }
        })
    }
    #[cfg(not(target_arch = "x86_64"))]
    None
}

#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)]
mod avx2 {
    //! The AVX2 + FMA single-ray BVH4 twin, step by step.
    use super::{Bvh4View, HitRecord};
    use crate::layout::{is_leaf, BLOCK_BYTES, NODE_BYTES};
    use crate::single::{sort_network, STACK_ENTRIES};
    use scene::bvh::{EMPTY_SLOT, LEAF};
    use scene::HitPolicy;
    use std::arch::x86_64::*;

    /// One ray's registers: broadcasts for the 4-wide node test (and the
    /// 8-wide one) and the 8-wide leaf test, its best hit so far.
    struct Ray {
        idir: [__m128; 3],
        oid: [__m128; 3],
        tnear: __m128,
        tfar4: __m128,
        idir8: [__m256; 3],
        oid8: [__m256; 3],
        tnear8: __m256,
        org: [__m256; 3],
        dir: [__m256; 3],
        tfar8: __m256,
        /// Per axis the byte offset of the near plane's row (16 if the
        /// direction is negative).
        near: [usize; 3],
        hit: HitRecord,
    }

    /// The rays in turn; `YMM`: the node test in 8-lane registers.
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn trace<const YMM: bool>(
        bvh: &Bvh4View,
        trav: &[f32],
        isect: &[f32],
        policy: HitPolicy,
    ) -> Vec<HitRecord> {
        let mut stack = [(0u32, 0f32); STACK_ENTRIES];
        trav.chunks_exact(8)
            .zip(isect.chunks_exact(8))
            .map(|(t, i)| {
                let mut ray = load(t, i);
                walk::<YMM>(bvh, &mut ray, &mut stack, policy);
                ray.hit
            })
            .collect()
    }

    #[target_feature(enable = "avx2,fma")]
    unsafe fn load(t: &[f32], i: &[f32]) -> Ray {
        let b4 = |x: f32| _mm_set1_ps(x);
        let b8 = |x: f32| _mm256_set1_ps(x);
        let near = |d: f32| if d < 0.0 { 16 } else { 0 };
        Ray {
            idir: [b4(t[0]), b4(t[1]), b4(t[2])],
            oid: [b4(t[4]), b4(t[5]), b4(t[6])],
            tnear: b4(t[3]),
            tfar4: b4(t[7]),
            idir8: [b8(t[0]), b8(t[1]), b8(t[2])],
            oid8: [b8(t[4]), b8(t[5]), b8(t[6])],
            tnear8: b8(t[3]),
            org: [b8(i[0]), b8(i[1]), b8(i[2])],
            dir: [b8(i[4]), b8(i[5]), b8(i[6])],
            tfar8: b8(t[7]),
            near: [near(t[0]), near(t[1]), near(t[2])],
            hit: HitRecord {
                t: t[7],
                u: 0.0,
                v: 0.0,
                prim: u32::MAX,
            },
        }
    }

    /// The ordered stack loop: pop, cull, descend to a leaf, test it.
    #[target_feature(enable = "avx2,fma")]
    unsafe fn walk<const YMM: bool>(
        bvh: &Bvh4View,
        ray: &mut Ray,
        stack: &mut [(u32, f32); STACK_ENTRIES],
        policy: HitPolicy,
    ) {
        stack[0] = (0, 0.0);
        let mut sp = 1;
        while sp > 0 {
            sp -= 1;
            let (mut node, tn) = stack[sp];
            if tn > ray.hit.t {
                continue;
            }
            // An empty slot carries the leaf bit too: it ends the descent
            // (a NaN slab can pass one), then is skipped.
            while node & LEAF == 0 {
                let base = node as usize * NODE_BYTES;
                let (bits, tn) = if YMM {
                    node_test_ymm(bvh.nodes, base, ray)
                } else {
                    node_test(bvh.nodes, base, ray)
                };
                if bits == 0 {
                    node = EMPTY_SLOT;
                    break;
                }
                let children = bvh.nodes.as_ptr().add(base + 96) as *const u32;
                node = descend(children, bits, tn, stack, &mut sp, policy);
            }
            if !is_leaf(node) {
                continue;
            }
            if leaf(bvh.tris, node, ray, policy) && policy.is_any() {
                break;
            }
        }
    }

    /// The 4 child boxes of the node at `base` against the ray: the hit
    /// mask and the entry distances.
    #[inline(always)]
    unsafe fn node_test(nodes: &[u8], base: usize, r: &Ray) -> (u32, [f32; 4]) {
        let p = nodes.as_ptr().add(base);
        let row = |off: usize| _mm_loadu_ps(p.add(off) as *const f32);
        let slab = |a: usize| {
            let lo = row(32 * a + r.near[a]);
            let hi = row(32 * a + (16 ^ r.near[a]));
            (
                _mm_fmsub_ps(lo, r.idir[a], r.oid[a]),
                _mm_fmsub_ps(hi, r.idir[a], r.oid[a]),
            )
        };
        let (n0, f0) = slab(0);
        let (n1, f1) = slab(1);
        let (n2, f2) = slab(2);
        let tn = _mm_max_ps(_mm_max_ps(n0, n1), _mm_max_ps(n2, r.tnear));
        let tf = _mm_min_ps(_mm_min_ps(f0, f1), _mm_min_ps(f2, r.tfar4));
        let bits = _mm_movemask_ps(_mm_cmple_ps(tn, tf)) as u32;
        let mut d = [0f32; 4];
        _mm_storeu_ps(d.as_mut_ptr(), tn);
        (bits, d)
    }

    /// [`node_test`] in 8-lane registers, each row broadcast to both
    /// halves and the mask cut to 4 bits, as the kernel runs it on an
    /// 8-lane machine.
    #[inline(always)]
    unsafe fn node_test_ymm(nodes: &[u8], base: usize, r: &Ray) -> (u32, [f32; 4]) {
        let p = nodes.as_ptr().add(base);
        let row = |off: usize| _mm256_broadcast_ps(&_mm_loadu_ps(p.add(off) as *const f32));
        let slab = |a: usize| {
            let lo = row(32 * a + r.near[a]);
            let hi = row(32 * a + (16 ^ r.near[a]));
            (
                _mm256_fmsub_ps(lo, r.idir8[a], r.oid8[a]),
                _mm256_fmsub_ps(hi, r.idir8[a], r.oid8[a]),
            )
        };
        let (n0, f0) = slab(0);
        let (n1, f1) = slab(1);
        let (n2, f2) = slab(2);
        let tn = _mm256_max_ps(_mm256_max_ps(n0, n1), _mm256_max_ps(n2, r.tnear8));
        let tf = _mm256_min_ps(_mm256_min_ps(f0, f1), _mm256_min_ps(f2, r.tfar8));
        let bits = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(tn, tf)) as u32 & 0xF;
        let mut d = [0f32; 4];
        _mm_storeu_ps(d.as_mut_ptr(), _mm256_castps256_ps128(tn));
        (bits, d)
    }

    /// The next node after a node test, as the kernel's `descend4`: one hit
    /// child: it; two: push the farther; three or four: push all (sorted
    /// nearest last for closest-hit rays), pop the top.
    #[inline(always)]
    unsafe fn descend(
        children: *const u32,
        mut bits: u32,
        tn: [f32; 4],
        stack: &mut [(u32, f32); STACK_ENTRIES],
        sp: &mut usize,
        policy: HitPolicy,
    ) -> u32 {
        let mut hit = [(0u32, 0f32); 4];
        let mut n = 0;
        while bits != 0 {
            let l = bits.trailing_zeros() as usize;
            hit[n] = (*children.add(l), tn[l]);
            n += 1;
            bits &= bits - 1;
        }
        match n {
            1 => hit[0].0,
            2 => {
                let (near, far) = if hit[0].1 < hit[1].1 {
                    (hit[0], hit[1])
                } else {
                    (hit[1], hit[0])
                };
                stack[*sp] = far;
                *sp += 1;
                near.0
            }
            _ => {
                if !policy.is_any() {
                    for &(i, j) in sort_network(n) {
                        if hit[i].1 < hit[j].1 {
                            hit.swap(i, j);
                        }
                    }
                }
                stack[*sp..*sp + n].copy_from_slice(&hit[..n]);
                *sp += n - 1;
                stack[*sp].0
            }
        }
    }

    /// Leaf `node`: its block of 8 triangles, the closest hit taken; whether
    /// one was hit (a shadow ray's t becomes -1).
    #[inline(always)]
    unsafe fn leaf(tris: &[u8], node: u32, r: &mut Ray, policy: HitPolicy) -> bool {
        let bb = (node & !LEAF) as usize * BLOCK_BYTES;
        let p = tris.as_ptr().add(bb) as *const f32;
        let Some((t, u, v, lane)) = moller(p, r) else {
            return false;
        };
        r.hit = HitRecord {
            t,
            u,
            v,
            prim: *(p.add(72 + lane) as *const u32),
        };
        r.tfar4 = _mm_set1_ps(t);
        r.tfar8 = _mm256_set1_ps(t);
        if policy.is_any() {
            r.hit.t = -1.0;
            r.tfar4 = _mm_set1_ps(-1.0);
            r.tfar8 = _mm256_set1_ps(-1.0);
        }
        true
    }

    /// Moller-Trumbore of the ray against the block at `p` (the kernel's
    /// `moller` and `intersect`, op for op): the closest hit's t, u, v and
    /// lane.
    #[inline(always)]
    unsafe fn moller(p: *const f32, r: &Ray) -> Option<(f32, f32, f32, usize)> {
        let row = |k: usize| _mm256_loadu_ps(p.add(8 * k));
        let v0 = [row(0), row(1), row(2)];
        let e1 = [row(3), row(4), row(5)];
        let e2 = [row(6), row(7), row(8)];
        let prim = _mm256_castps_si256(row(9));
        let zero = _mm256_setzero_ps();
        let pv = cross(r.dir, e2);
        let det = dot(e1, pv);
        let sv = [
            _mm256_sub_ps(r.org[0], v0[0]),
            _mm256_sub_ps(r.org[1], v0[1]),
            _mm256_sub_ps(r.org[2], v0[2]),
        ];
        let u0 = dot(sv, pv);
        let qv = cross(sv, e1);
        let v0_ = dot(r.dir, qv);
        let sign = _mm256_set1_ps(-0.0);
        let sgn = _mm256_and_ps(det, sign);
        let adet = _mm256_andnot_ps(sign, det);
        let su = _mm256_xor_ps(u0, sgn);
        let sv_ = _mm256_xor_ps(v0_, sgn);
        let suv = _mm256_add_ps(su, sv_);
        let ok_det = _mm256_cmp_ps::<_CMP_NEQ_UQ>(det, zero);
        let ok_u = _mm256_cmp_ps::<_CMP_GE_OQ>(su, zero);
        let ok_v = _mm256_cmp_ps::<_CMP_GE_OQ>(sv_, zero);
        let ok_uv = _mm256_cmp_ps::<_CMP_LE_OQ>(suv, adet);
        let ok_p = _mm256_castsi256_ps(_mm256_cmpgt_epi32(prim, _mm256_set1_epi32(-1)));
        let valid = _mm256_and_ps(_mm256_and_ps(ok_det, ok_u), _mm256_and_ps(ok_v, ok_uv));
        let valid = _mm256_and_ps(valid, ok_p);
        if _mm256_movemask_ps(valid) == 0 {
            return None;
        }
        let st = _mm256_xor_ps(dot(e2, qv), sgn);
        let far = _mm256_mul_ps(adet, r.tfar8);
        let ok_t0 = _mm256_cmp_ps::<_CMP_GT_OQ>(st, zero);
        let ok_t1 = _mm256_cmp_ps::<_CMP_LT_OQ>(st, far);
        let valid = _mm256_and_ps(valid, _mm256_and_ps(ok_t0, ok_t1));
        if _mm256_movemask_ps(valid) == 0 {
            return None;
        }
        // The reciprocal as the AVX2 flavour's: 1/x to 12 mantissa bits,
        // one Newton step.
        let keep = _mm256_castsi256_ps(_mm256_set1_epi32(!((1 << (23 - 12)) - 1)));
        let est = _mm256_and_ps(_mm256_div_ps(_mm256_set1_ps(1.0), adet), keep);
        let corr = _mm256_fnmadd_ps(est, adet, _mm256_set1_ps(2.0));
        let rcp = _mm256_mul_ps(est, corr);
        let t = _mm256_mul_ps(st, rcp);
        let tv = _mm256_blendv_ps(_mm256_set1_ps(f32::INFINITY), t, valid);
        let tb = hmin(tv);
        let at_min = _mm256_and_ps(_mm256_cmp_ps::<_CMP_EQ_OQ>(tv, tb), valid);
        let lane = _mm256_movemask_ps(at_min).trailing_zeros() as usize;
        let mut uv = [[0f32; 8]; 2];
        _mm256_storeu_ps(uv[0].as_mut_ptr(), _mm256_mul_ps(su, rcp));
        _mm256_storeu_ps(uv[1].as_mut_ptr(), _mm256_mul_ps(sv_, rcp));
        Some((_mm256_cvtss_f32(tb), uv[0][lane], uv[1][lane], lane))
    }

    /// The minimum of the 8 lanes, in every lane (the kernel's butterfly:
    /// lane i against lane i ^ 4, ^ 2, ^ 1).
    #[inline(always)]
    unsafe fn hmin(a: __m256) -> __m256 {
        let a = _mm256_min_ps(a, _mm256_permute2f128_ps::<1>(a, a));
        let a = _mm256_min_ps(a, _mm256_permute_ps::<0b0100_1110>(a));
        _mm256_min_ps(a, _mm256_permute_ps::<0b1011_0001>(a))
    }

    #[inline(always)]
    unsafe fn cross(a: [__m256; 3], c: [__m256; 3]) -> [__m256; 3] {
        [
            _mm256_fmsub_ps(a[1], c[2], _mm256_mul_ps(a[2], c[1])),
            _mm256_fmsub_ps(a[2], c[0], _mm256_mul_ps(a[0], c[2])),
            _mm256_fmsub_ps(a[0], c[1], _mm256_mul_ps(a[1], c[0])),
        ]
    }

    #[inline(always)]
    unsafe fn dot(a: [__m256; 3], c: [__m256; 3]) -> __m256 {
        let d = _mm256_mul_ps(a[0], c[0]);
        _mm256_fmadd_ps(a[2], c[2], _mm256_fmadd_ps(a[1], c[1], d))
    }
}
