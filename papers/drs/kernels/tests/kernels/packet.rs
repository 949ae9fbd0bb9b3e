//! The packet BVH2/BVH4 and hybrid BVH4 kernels return the reference's closest
//! hits (agreement rule: `common::mismatches`) on every flavour, traced and
//! native, on a 4096-ray primary stream and on path-tracing bounce streams.

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
        for kernel in [Kernel::PacketBvh4, Kernel::PacketBvh2, Kernel::HybridBvh4] {
            let run = Run::new(kernel, scene, b2, b4, st.clone());
            for &fl in flavours {
                let label = format!("{} {scene_name} {fl} {:?}", kernel.name(), st.kind);
                let (traced, tests) = isa::record(&run, fl, kernel.name()).1;
                let (native, ntests) = isa::run_native(&run, fl);
                let first = (0..traced.len()).find(|&i| traced[i] != native[i]);
                assert_eq!(
                    first,
                    None,
                    "{label}: traced and native differ (traced {:?} native {:?})",
                    first.map(|i| traced[i]),
                    first.map(|i| native[i])
                );
                assert_eq!(tests, ntests, "{label}: counts");
                assert_eq!(tests.core_loop, 0, "{label}: no core loop");
                assert!(tests.other > 0 && tests.leaf > 0, "{label}: {tests:?}");
                let bad = mismatches(&label, &refi, &st.org, &st.dir, &traced);
                assert_eq!(bad, 0, "{label}: {bad} of {} rays differ", st.len());
            }
        }
    }
}

#[test]
fn packet_kernels_match_the_reference_on_primary_and_bounce_streams() {
    let scene = Scene::load("saloon").unwrap();
    let cam = &scene.config.camera;
    let b2 = Bvh2::build(&scene.mesh, &BuildConfig::default()).unwrap();
    let p = primary_tile(cam, cam.width / 32, cam.height / 32, 16, 16, 5);
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
        // 1001 rays or so: the last packet is partly padding.
        if matches!(st.kind, StreamKind::Bounce(_)) && st.len() > 64 {
            streams.push(st);
        }
    }
    assert!(streams.len() >= 2);
    assert!(streams.iter().any(|s| s.len() % 8 != 0), "a partial packet");
    check(
        "saloon",
        &streams,
        &[
            FlavourId::Avx2,
            FlavourId::Sse4,
            FlavourId::Lrb16,
            FlavourId::Wide32,
        ],
    );
}

#[test]
fn packet_kernels_match_the_reference_on_foliage() {
    let scene = Scene::load("fern").unwrap();
    let cam = &scene.config.camera;
    let p = primary_tile(cam, cam.width / 32, cam.height / 32, 16, 4, 3);
    check("fern", &[p], &[FlavourId::Avx2]);
}
