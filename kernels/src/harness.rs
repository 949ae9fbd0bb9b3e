//! Run a traversal kernel on any machine over a ray stream, and compare its
//! closest hits with the f64 reference (used by the tests and `rtsim run`).

use crate::bvh::{Bvh2, Bvh4};
use crate::layout::{hit_records, lay_out, ray_records};
use crate::reference::{Ray, Reference};
use crate::scene::Scene;
use isa::{Machine, MemKind, Program};

/// Which traversal kernel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kernel {
    /// Single-ray BVH2.
    Single2,
    /// Single-ray BVH4.
    Single,
    /// Dynamic ray stream BVH4.
    Drs,
}

/// A kernel over a ray stream of a scene; the output is (t, prim) per ray
/// and the kernel's test counts.
pub struct Run<'a> {
    /// The kernel.
    pub kernel: Kernel,
    /// The scene.
    pub scene: &'a Scene,
    /// Its BVH2 (leaves of at most 8 triangles).
    pub b2: &'a Bvh2,
    /// The BVH4 collapsed from it.
    pub b4: &'a Bvh4,
    /// Ray origins.
    pub org: Vec<[f32; 3]>,
    /// Ray directions.
    pub dir: Vec<[f32; 3]>,
}

impl Kernel {
    /// Every kernel.
    pub const ALL: [Kernel; 3] = [Kernel::Single2, Kernel::Single, Kernel::Drs];
    /// Stable name (`single-bvh2`, `single-bvh4`, `drs-bvh4`).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Kernel::Single2 => "single-bvh2",
            Kernel::Single => "single-bvh4",
            Kernel::Drs => "drs-bvh4",
        }
    }
    /// Whether it runs on machines of `lanes` lanes.
    #[must_use]
    pub fn supports(self, lanes: usize) -> bool {
        match self {
            Kernel::Single | Kernel::Single2 => true,
            Kernel::Drs => matches!(lanes, 4 | 8),
        }
    }
}

impl Program for Run<'_> {
    type Out = (Vec<(f32, i32)>, crate::stats::Tests);
    fn run<M: Machine>(&self, m: &mut M) -> Self::Out {
        let n = self.org.len();
        let (tr, is) = ray_records(&self.org, &self.dir, &vec![f32::INFINITY; n]);
        let mut trav = m.space().alloc_f32(MemKind::Rays, "rays-trav", &tr, 64);
        let isect = m.space().alloc_f32(MemKind::Rays, "rays-isect", &is, 64);
        let mut hits = m
            .space()
            .alloc_bytes(MemKind::Hits, "hits", hit_records(n), 64);
        let mut tests = crate::stats::Tests::default();
        match self.kernel {
            Kernel::Single2 => {
                let s = crate::layout::lay_out2(m, &self.scene.mesh, self.b2);
                let mut stack = m.space().alloc(
                    MemKind::Stack,
                    "stack",
                    crate::single::STACK_ENTRIES * 8,
                    64,
                );
                crate::single::trace2(
                    m, &s, &mut trav, &isect, &mut hits, &mut stack, n, &mut tests,
                );
            }
            Kernel::Single => {
                let s = lay_out(m, &self.scene.mesh, self.b2, self.b4);
                let mut stack = m.space().alloc(
                    MemKind::Stack,
                    "stack",
                    crate::single::STACK_ENTRIES * 8,
                    64,
                );
                crate::single::trace(
                    m, &s, &mut trav, &isect, &mut hits, &mut stack, n, &mut tests,
                );
            }
            Kernel::Drs => {
                let s = lay_out(m, &self.scene.mesh, self.b2, self.b4);
                let mut st = crate::drs::StreamBufs::new(m, n, self.b2.depth());
                crate::drs::trace(m, &s, &mut st, &mut trav, &isect, &mut hits, n);
                tests = st.tests;
            }
        }
        let out = (0..n)
            .map(|i| (hits.f32_at(16 * i), hits.u32_at(16 * i + 12) as i32))
            .collect();
        (out, tests)
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
