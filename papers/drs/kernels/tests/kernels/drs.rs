//! The dynamic ray stream BVH4 and BVH2 kernels return the reference's closest hits
//! (agreement rule: `common::mismatches`) on a 4096-ray primary stream
//! (16 x 16 pixels x 16 samples, the DRS stream) and on path-tracing bounce streams.

use crate::common::{fixture, mismatches, Kernel, Run};
use isa::FlavourId;
use scene::bvh::{BuildConfig, Bvh2};
use scene::scene::Scene;
use scene::workload::{path_trace_tile, primary_tile, RayStream, StreamKind, Tile};

fn check(scene_name: &str, streams: &[RayStream], flavours: &[FlavourId]) {
    let fx = fixture(scene_name);
    let (scene, b2, b4) = (&fx.scene, &fx.b2, &fx.b4);
    let refi = fx.reference();
    for st in streams {
        for kernel in [Kernel::DrsBvh4, Kernel::DrsBvh2] {
            let run = Run::new(kernel, scene, b2, b4, st.clone());
            for &fl in flavours {
                let (traced, tests) = isa::record(&run, fl, kernel.name()).1;
                assert_eq!(
                    (traced.clone(), tests),
                    isa::run_native(&run, fl),
                    "{} {scene_name} {fl}: traced and native agree",
                    kernel.name()
                );
                // Streams of >= 16 rays start in the core loop: each of its rays
                // is tested against the root there.
                assert!(tests.core_loop >= st.len() as u64, "{tests:?}");
                // The share depends on the scene: on the saloon tessellated to
                // its 60K triangles, bounce streams thin out to 31% in the loop.
                assert!(tests.core_loop_share() > 0.25, "{tests:?}");
                let bad = mismatches(
                    &format!("{} {scene_name} {fl}", kernel.name()),
                    &refi,
                    &st.org,
                    &st.dir,
                    &traced,
                );
                assert_eq!(
                    bad,
                    0,
                    "{} {scene_name} {fl}: {bad} of {} rays differ",
                    kernel.name(),
                    st.len()
                );
            }
        }
    }
}

#[test]
fn drs_kernels_match_the_reference_on_primary_and_bounce_streams() {
    let scene = Scene::load("saloon").unwrap();
    let cam = &scene.config.camera;
    let b2 = Bvh2::build(&scene.mesh, &BuildConfig::default()).unwrap();
    let p = primary_tile(cam, cam.width / 32, cam.height / 32, 16, 16, 5);
    assert_eq!(p.len(), 4096);
    let mut streams = vec![p];
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
            streams.push(st);
        }
    }
    assert!(streams.len() >= 2);
    check("saloon", &streams, &[FlavourId::Avx2, FlavourId::Sse4]);
    // Wider than the paper's kernel: 4 and 8 rays an iteration.
    check(
        "saloon",
        &streams[..2],
        &[FlavourId::Lrb16, FlavourId::Wide32],
    );
}

#[test]
fn drs_kernels_match_the_reference_on_foliage() {
    let scene = Scene::load("fern").unwrap();
    let cam = &scene.config.camera;
    let p = primary_tile(cam, cam.width / 32, cam.height / 32, 16, 4, 3);
    check("fern", &[p], &[FlavourId::Avx2, FlavourId::Wide32]);
}
