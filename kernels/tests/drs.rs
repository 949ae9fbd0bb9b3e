//! The dynamic ray stream BVH4 kernel returns the reference's closest hits
//! (same rule as the single-ray test) on a 4096-ray primary stream (16 x 16
//! pixels x 16 samples, the DRS stream) and on path-tracing bounce streams.

use isa::{FlavourId, Machine, MemKind, Program};
use kernels::bvh::{BuildConfig, Bvh2, Bvh4};
use kernels::drs::{trace, StreamBufs};
use kernels::layout::{hit_records, lay_out, ray_records};
use kernels::reference::{Ray, Reference};
use kernels::scene::Scene;
use kernels::workload::{path_trace_tile, primary_tile, StreamKind, Tile};

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
        let n = self.org.len();
        let (tr, is) = ray_records(&self.org, &self.dir, &vec![f32::INFINITY; n]);
        let mut trav = m.space().alloc_f32(MemKind::Rays, "rays-trav", &tr, 64);
        let isect = m.space().alloc_f32(MemKind::Rays, "rays-isect", &is, 64);
        let mut hits = m
            .space()
            .alloc_bytes(MemKind::Hits, "hits", hit_records(n), 64);
        let depth = self.b2.depth();
        let mut st = StreamBufs::new(m, n, depth);
        trace(m, &s, &mut st, &mut trav, &isect, &mut hits, n);
        (0..n)
            .map(|i| (hits.f32_at(16 * i), hits.u32_at(16 * i + 12) as i32))
            .collect()
    }
}

/// A ray stream as (origins, directions).
type Stream = (Vec<[f32; 3]>, Vec<[f32; 3]>);

fn check(scene_name: &str, streams: &[Stream], flavours: &[FlavourId]) {
    let scene = Scene::load(scene_name).unwrap();
    let b2 = Bvh2::build(
        &scene.mesh,
        &BuildConfig {
            max_leaf: 8,
            ..BuildConfig::default()
        },
    )
    .unwrap();
    let b4 = Bvh4::collapse(&b2);
    let refi = Reference::with_bvh(&scene.mesh, &b2);
    for (org, dir) in streams {
        let run = Run {
            scene: &scene,
            b2: &b2,
            b4: &b4,
            org: org.clone(),
            dir: dir.clone(),
        };
        for &fl in flavours {
            let traced = isa::record(&run, fl, "drs").1;
            assert_eq!(
                traced,
                isa::run_native(&run, fl),
                "{scene_name} {fl}: traced and native agree"
            );
            let mut bad = 0;
            for i in 0..org.len() {
                let ray = Ray::new(org[i].map(f64::from), dir[i].map(f64::from));
                let want = refi.closest(&ray);
                let (t, prim) = traced[i];
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
                        eprintln!(
                            "{scene_name} {fl} ray {i}: kernel ({t}, {prim}) reference {want:?}"
                        );
                    }
                }
            }
            assert_eq!(
                bad,
                0,
                "{scene_name} {fl}: {bad} of {} rays differ",
                org.len()
            );
        }
    }
}

#[test]
fn drs_bvh4_matches_the_reference_on_primary_and_bounce_streams() {
    let scene = Scene::load("saloon").unwrap();
    let cam = &scene.config.camera;
    let b2 = Bvh2::build(&scene.mesh, &BuildConfig::default()).unwrap();
    let p = primary_tile(cam, cam.width / 32, cam.height / 32, 16, 16, 5);
    assert_eq!(p.len(), 4096);
    let mut streams = vec![(p.org.clone(), p.dir.clone())];
    for st in path_trace_tile(
        &scene,
        &b2,
        Tile {
            x: 20,
            y: 24,
            size: 16,
        },
        4,
        2,
        9,
    ) {
        if matches!(st.kind, StreamKind::Bounce(_)) && st.len() > 64 {
            streams.push((st.org.clone(), st.dir.clone()));
        }
    }
    assert!(streams.len() >= 2);
    check("saloon", &streams, &[FlavourId::Avx2, FlavourId::Sse4]);
}

#[test]
fn drs_bvh4_matches_the_reference_on_foliage() {
    let scene = Scene::load("fern").unwrap();
    let cam = &scene.config.camera;
    let p = primary_tile(cam, cam.width / 32, cam.height / 32, 16, 4, 3);
    check("fern", &[(p.org, p.dir)], &[FlavourId::Avx2]);
}
