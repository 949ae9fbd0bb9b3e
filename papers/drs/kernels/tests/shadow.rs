//! Every traversal kernel answers shadow rays (any hit up to the light) as the
//! reference does (`Run::mismatches` -> `shadow_mismatches`), traced and
//! native, on the shadow streams of the path-tracing loop.

mod common;

use common::fixture;
use drs_kernels::methods::{Kernel, Run};
use isa::FlavourId;
use scene::workload::{path_trace_tile, StreamKind, Tile};

#[test]
fn every_kernel_answers_shadow_rays_as_the_reference() {
    let fx = fixture("sanmiguel");
    let (scene, b2, b4) = (&fx.scene, &fx.b2, &fx.b4);
    let refi = fx.reference();
    let (size, spp) = (16, 4);
    let tile = Tile { x: 20, y: 24, size };
    let shadows: Vec<_> = path_trace_tile(scene, b2, tile, spp, 1, 9)
        .into_iter()
        .filter(|s| matches!(s.kind, StreamKind::Shadow(_)))
        .collect();
    assert_eq!(
        shadows.len(),
        2,
        "shadow rays of the primary and first bounce hits"
    );
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
            for fl in [FlavourId::Avx2, FlavourId::Sse4, FlavourId::Lrb16] {
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
