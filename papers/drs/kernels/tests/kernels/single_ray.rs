//! The single-ray BVH2 and BVH4 kernels return the reference's hits on every flavour,
//! traced and native (agreement rule: `common::mismatches`).

use crate::common::{fixture, mismatches, Kernel, Run};
use isa::FlavourId;
use scene::reference::Ray;
use scene::workload::{primary_tile, RayStream};

fn check(kernel: Kernel, scene_name: &str, flavours: &[FlavourId]) {
    let fx = fixture(scene_name);
    let (scene, b2, b4) = (&fx.scene, &fx.b2, &fx.b4);
    b4.validate(b2, &scene.mesh).unwrap();
    let cam = &scene.config.camera;
    let (mut org, mut dir) = (Vec::new(), Vec::new());
    for (fx, fy) in [(0.5, 0.5), (0.4, 0.6), (0.6, 0.75), (0.5, 0.9)] {
        let (tx, ty) = (
            (fx * f64::from(cam.width) / 8.0) as u32,
            (fy * f64::from(cam.height) / 8.0) as u32,
        );
        let s = primary_tile(cam, tx, ty, 8, 2, 11);
        org.extend(s.org);
        dir.extend(s.dir);
    }
    let refi = fx.reference();
    let hits = org
        .iter()
        .zip(&dir)
        .filter(|(o, d)| {
            refi.closest(&Ray::new(o.map(f64::from), d.map(f64::from)))
                .is_some()
        })
        .count();
    assert!(
        hits > org.len() / 4,
        "{scene_name}: a mix of hits ({hits}/{})",
        org.len()
    );
    let run = Run::new(
        kernel,
        scene,
        b2,
        b4,
        RayStream::closest(org.clone(), dir.clone()),
    );
    for &fl in flavours {
        let (traced, tests) = isa::record(&run, fl, "single").1;
        assert_eq!(
            (traced.clone(), tests),
            isa::run_native(&run, fl),
            "{} {scene_name} {fl}: traced and native agree",
            kernel.name()
        );
        // Single-ray kernels have no core loop; every ray tests the root
        // (all these scenes have an inner root) and some leaf.
        assert_eq!(tests.core_loop, 0);
        assert!(tests.other >= org.len() as u64, "{tests:?}");
        assert!(tests.leaf > 0, "{tests:?}");
        let bad = mismatches(&format!("{scene_name} {fl}"), &refi, &org, &dir, &traced);
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
        Kernel::SingleBvh4,
        "sphere",
        &[
            FlavourId::Avx2,
            FlavourId::Lrb16,
            FlavourId::Sse4,
            FlavourId::Avx512,
            FlavourId::Wide32,
        ],
    );
}

#[test]
fn single_ray_bvh4_matches_the_reference_in_rooms_and_foliage() {
    check(Kernel::SingleBvh4, "saloon", &[FlavourId::Avx2]);
    check(Kernel::SingleBvh4, "fern", &[FlavourId::Avx2]);
}

#[test]
fn single_ray_bvh2_matches_the_reference_on_every_flavour() {
    check(
        Kernel::SingleBvh2,
        "sphere",
        &[
            FlavourId::Avx2,
            FlavourId::Lrb16,
            FlavourId::Sse4,
            FlavourId::Avx512,
            FlavourId::Wide32,
        ],
    );
    check(Kernel::SingleBvh2, "saloon", &[FlavourId::Avx2]);
    check(Kernel::SingleBvh2, "fern", &[FlavourId::Avx2]);
}
