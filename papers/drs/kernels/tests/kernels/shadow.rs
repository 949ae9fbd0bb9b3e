//! Every traversal kernel answers shadow rays (any hit up to the light) as the
//! reference does (`Run::mismatches` -> `shadow_mismatches`), traced and
//! native, on the shadow streams of the path-tracing loop.

use crate::common::fixture;
use drs_kernels::methods::{Kernel, Run};
use isa::FlavourId;
use scene::workload::{path_trace_tile, StreamKind, Tile};

#[test]
fn every_kernel_answers_shadow_rays_as_the_reference() {
    let fx = fixture("fern");
    let (scene, b2, b4) = (&fx.scene, &fx.b2, &fx.b4);
    let refi = fx.reference();
    let (size, spp) = (16, 4);
    let cam = &scene.config.camera;
    let mixed = |st: &scene::workload::RayStream| {
        let occluded = (0..st.len()).filter(|&i| refi.any(&st.ray(i))).count();
        occluded > st.len() / 20 && occluded < st.len() * 19 / 20
    };
    // The first tile along the middle row whose two shadow streams (of the
    // primary and the first bounce hits) each mix lit and occluded rays.
    let shadows: Vec<_> = (0..cam.width / size)
        .map(|x| Tile {
            x,
            y: cam.height / size / 2,
            size,
        })
        .map(|tile| {
            path_trace_tile(scene, b2, tile, spp, 1, 9)
                .into_iter()
                .filter(|s| matches!(s.kind, StreamKind::Shadow(_)))
                .collect::<Vec<_>>()
        })
        .find(|sh| sh.len() == 2 && sh.iter().all(mixed))
        .expect("a tile whose shadow rays mix lit and occluded");
    for st in &shadows {
        let occluded = (0..st.len()).filter(|&i| refi.any(&st.ray(i))).count();
        assert!(
            occluded > st.len() / 20 && occluded < st.len() * 19 / 20,
            "{:?}: a mix of lit and occluded ({occluded}/{})",
            st.kind,
            st.len()
        );
        for kernel in Kernel::ALL {
            let mut run = Run::new(kernel, scene, b2, b4, st.clone());
            run.packet_tile = Some((size, spp));
            for fl in [
                FlavourId::Avx2,
                FlavourId::Sse4,
                FlavourId::Lrb16,
                FlavourId::Wide32,
            ] {
                if !kernel.supports(fl.lanes()) {
                    continue;
                }
                let label = format!("{} {fl} {:?}", kernel.name(), st.kind);
                let (traced, tests) = isa::record(&run, fl, kernel.name()).1;
                assert_eq!(
                    (traced.clone(), tests),
                    isa::run_native(&run, fl),
                    "{label}: traced and native agree"
                );
                let bad = run.mismatches(&label, &refi, &traced);
                assert_eq!(bad, 0, "{label}: {bad} of {} rays differ", st.len());
            }
        }
    }
}
