//! The single-ray BVH4 kernel returns the reference's hits on every flavour,
//! traced and native: same triangle, t within 1e-4 relative, or — at a shared
//! edge where two triangles tie — a triangle the reference also hits at that t.

use isa::{FlavourId, Machine, MemKind, Program};
use kernels::bvh::{BuildConfig, Bvh2, Bvh4};
use kernels::layout::{hit_records, lay_out, ray_records};
use kernels::reference::{Ray, Reference};
use kernels::scene::Scene;
use kernels::single::{trace, STACK_ENTRIES};
use kernels::workload::primary_tile;

struct Run<'a> {
    scene: &'a Scene,
    b2: &'a Bvh2,
    b4: &'a Bvh4,
    org: Vec<[f32; 3]>,
    dir: Vec<[f32; 3]>,
}

impl Program for Run<'_> {
    type Out = Vec<(f32, i32)>;
    fn run<M: Machine>(&self, m: &mut M) -> Self::Out {
        let s = lay_out(m, &self.scene.mesh, self.b2, self.b4);
        let tfar = vec![f32::INFINITY; self.org.len()];
        let (tr, is) = ray_records(&self.org, &self.dir, &tfar);
        let mut trav = m.space().alloc_f32(MemKind::Rays, "rays-trav", &tr, 64);
        let isect = m.space().alloc_f32(MemKind::Rays, "rays-isect", &is, 64);
        let mut hits =
            m.space()
                .alloc_bytes(MemKind::Hits, "hits", hit_records(self.org.len()), 64);
        let mut stack = m
            .space()
            .alloc(MemKind::Stack, "stack", STACK_ENTRIES * 8, 64);
        trace(
            m,
            &s,
            &mut trav,
            &isect,
            &mut hits,
            &mut stack,
            self.org.len(),
        );
        (0..self.org.len())
            .map(|i| (hits.f32_at(16 * i), hits.u32_at(16 * i + 12) as i32))
            .collect()
    }
}

fn check(scene_name: &str, flavours: &[FlavourId]) {
    let scene = Scene::load(scene_name).unwrap();
    let cfg = BuildConfig {
        max_leaf: 8,
        ..BuildConfig::default()
    };
    let b2 = Bvh2::build(&scene.mesh, &cfg).unwrap();
    let b4 = Bvh4::collapse(&b2);
    b4.validate(&b2, &scene.mesh).unwrap();
    let cam = &scene.config.camera;
    let mut org = Vec::new();
    let mut dir = Vec::new();
    for (fx, fy) in [(0.5, 0.5), (0.4, 0.6), (0.6, 0.75), (0.5, 0.9)] {
        let (tx, ty) = (
            (fx * f64::from(cam.width) / 8.0) as u32,
            (fy * f64::from(cam.height) / 8.0) as u32,
        );
        let s = primary_tile(cam, tx, ty, 8, 2, 11);
        org.extend(s.org);
        dir.extend(s.dir);
    }
    let refi = Reference::with_bvh(&scene.mesh, &b2);
    let run = Run {
        scene: &scene,
        b2: &b2,
        b4: &b4,
        org: org.clone(),
        dir: dir.clone(),
    };
    for &fl in flavours {
        let (trace_out, native_out) =
            (isa::record(&run, fl, "single").1, isa::run_native(&run, fl));
        assert_eq!(
            trace_out, native_out,
            "{scene_name} {fl}: traced and native agree"
        );
        let mut bad = 0;
        let mut hits = 0;
        for i in 0..org.len() {
            let ray = Ray::new(org[i].map(f64::from), dir[i].map(f64::from));
            let want = refi.closest(&ray);
            let (t, prim) = trace_out[i];
            let ok = match want {
                None => prim < 0,
                Some(h) => {
                    hits += 1;
                    let close = |a: f64, b: f64| (a - b).abs() <= 1e-4 * b.abs().max(1.0);
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
                    eprintln!("{scene_name} {fl} ray {i}: kernel ({t}, {prim}) reference {want:?}");
                }
            }
        }
        assert!(
            hits > org.len() / 4,
            "{scene_name}: a mix of hits ({hits}/{})",
            org.len()
        );
        assert_eq!(
            bad,
            0,
            "{scene_name} {fl}: {bad} of {} rays differ from the reference",
            org.len()
        );
    }
}

#[test]
fn single_ray_bvh4_matches_the_reference_on_the_sphere_scene() {
    check(
        "sphere",
        &[
            FlavourId::Avx2,
            FlavourId::Lrb16,
            FlavourId::Sse4,
            FlavourId::Avx512,
        ],
    );
}

#[test]
fn single_ray_bvh4_matches_the_reference_in_rooms_and_foliage() {
    check("saloon", &[FlavourId::Avx2]);
    check("fern", &[FlavourId::Avx2]);
}
