//! Shared by the traversal kernel tests: run a kernel on any machine over a
//! ray stream, and compare its closest hits with the f64 reference.

// Each test binary uses what it needs.
#![allow(dead_code)]

use isa::{Machine, MemKind, Program};
use kernels::bvh::{Bvh2, Bvh4};
use kernels::layout::{hit_records, lay_out, ray_records};
use kernels::reference::{Ray, Reference};
use kernels::scene::Scene;

/// Which traversal kernel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kernel {
    /// Single-ray BVH4.
    Single,
    /// Dynamic ray stream BVH4.
    Drs,
}

/// A kernel over a ray stream of a scene; the output is (t, prim) per ray.
pub struct Run<'a> {
    pub kernel: Kernel,
    pub scene: &'a Scene,
    pub b2: &'a Bvh2,
    pub b4: &'a Bvh4,
    pub org: Vec<[f32; 3]>,
    pub dir: Vec<[f32; 3]>,
}

impl Program for Run<'_> {
    type Out = Vec<(f32, i32)>;
    fn run<M: Machine>(&self, m: &mut M) -> Self::Out {
        let s = lay_out(m, &self.scene.mesh, self.b2, self.b4);
        let n = self.org.len();
        let (tr, is) = ray_records(&self.org, &self.dir, &vec![f32::INFINITY; n]);
        let mut trav = m.space().alloc_f32(MemKind::Rays, "rays-trav", &tr, 64);
        let isect = m.space().alloc_f32(MemKind::Rays, "rays-isect", &is, 64);
        let mut hits = m
            .space()
            .alloc_bytes(MemKind::Hits, "hits", hit_records(n), 64);
        match self.kernel {
            Kernel::Single => {
                let mut stack = m.space().alloc(
                    MemKind::Stack,
                    "stack",
                    kernels::single::STACK_ENTRIES * 8,
                    64,
                );
                kernels::single::trace(m, &s, &mut trav, &isect, &mut hits, &mut stack, n);
            }
            Kernel::Drs => {
                let mut st = kernels::drs::StreamBufs::new(m, n, self.b2.depth());
                kernels::drs::trace(m, &s, &mut st, &mut trav, &isect, &mut hits, n);
            }
        }
        (0..n)
            .map(|i| (hits.f32_at(16 * i), hits.u32_at(16 * i + 12) as i32))
            .collect()
    }
}

/// Rays whose kernel hit differs from the reference's closest hit. Agreement:
/// both miss; or both hit with t within 1e-4 relative and the same triangle —
/// or, at a shared edge where two triangles tie, a triangle the reference also
/// hits at that t.
pub fn mismatches(
    label: &str,
    refi: &Reference,
    org: &[[f32; 3]],
    dir: &[[f32; 3]],
    out: &[(f32, i32)],
) -> usize {
    let mut bad = 0;
    for i in 0..org.len() {
        let ray = Ray::new(org[i].map(f64::from), dir[i].map(f64::from));
        let want = refi.closest(&ray);
        let (t, prim) = out[i];
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-4 * b.abs().max(1.0);
        let ok = match want {
            None => prim < 0,
            Some(h) => {
                prim >= 0
                    && close(f64::from(t), h.t)
                    && (prim as u32 == h.prim
                        || refi
                            .all(&ray)
                            .iter()
                            .any(|a| a.prim == prim as u32 && close(a.t, h.t)))
            }
        };
        if !ok {
            bad += 1;
            if bad <= 3 {
                eprintln!("{label} ray {i}: kernel ({t}, {prim}) reference {want:?}");
            }
        }
    }
    bad
}
