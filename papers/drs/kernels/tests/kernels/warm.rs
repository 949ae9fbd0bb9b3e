//! Functional warming at native speed: a unit run natively with its memory
//! accesses and branches logged warms exactly as its recorded trace does, for
//! every DRS method on every flavour that runs it (the flavours' expansions
//! included: SSE4 has no gather, scatter or masked store).

use crate::common::{fixture, Kernel, Run};
use isa::{run_units, Detail, FlavourId, Placed};
use scene::workload::{path_trace_tile, RayStream, StreamKind, Tile};

#[test]
fn a_warmed_unit_touches_what_its_recorded_trace_touches() {
    let fx = fixture("sphere");
    let cam = &fx.scene.config.camera;
    let tile = Tile {
        x: cam.width / 8 / 2,
        y: cam.height / 8 / 2,
        size: 8,
    };
    let streams: Vec<RayStream> = path_trace_tile(&fx.scene, &fx.b2, tile, 2, 1, 3)
        .into_iter()
        .filter(|s| !s.is_empty())
        .collect();
    assert!(streams
        .iter()
        .any(|s| matches!(s.kind, StreamKind::Shadow(_))));
    assert!(streams
        .iter()
        .any(|s| matches!(s.kind, StreamKind::Bounce(_))));
    for kernel in Kernel::ALL {
        for fl in [FlavourId::Sse4, FlavourId::Avx2, FlavourId::Avx512] {
            if !kernel.supports(fl.lanes()) {
                continue;
            }
            let mut run = Run::new(kernel, &fx.scene, &fx.b2, &fx.b4, streams[0].clone());
            run.packet_tile = Some((tile.size, 2));
            // Each stream on thread 1, recorded then warmed: the same unit
            // on both machines, in the same place.
            let units = streams.iter().flat_map(|s| {
                [Detail::Timed, Detail::Warmed].map(|d| {
                    let u = Placed {
                        thread: 1,
                        unit: s.clone(),
                    };
                    (u, d)
                })
            });
            let mut views = Vec::new();
            run_units(&run, fl, "warm-test", units, |_, d, t, out| {
                views.push((d, t.warming_view(), out));
                Ok::<(), ()>(())
            })
            .unwrap();
            for pair in views.chunks(2) {
                let ((_, timed, o1), (_, warmed, o2)) = (&pair[0], &pair[1]);
                let label = format!("{} {fl}", kernel.name());
                assert_eq!(o1, o2, "{label}: same hits and counts");
                assert!(timed.len() > 100, "{label}: {} events", timed.len());
                assert_eq!(timed.len(), warmed.len(), "{label}: event count");
                if let Some(i) = (0..timed.len()).find(|&i| timed[i] != warmed[i]) {
                    panic!(
                        "{label}: event {i} differs: recorded {:?}, warmed {:?}",
                        timed[i], warmed[i]
                    );
                }
            }
        }
    }
}

#[test]
fn a_shared_layout_records_what_a_machine_of_its_own_records() {
    let fx = fixture("sphere");
    let cam = &fx.scene.config.camera;
    let stream = scene::workload::primary_tile(cam, cam.width / 16, cam.height / 16, 8, 2, 5);
    assert!(!stream.is_empty());
    let shared = drs_kernels::methods::SharedLayouts::default();
    for kernel in Kernel::ALL {
        let own = Run::new(kernel, &fx.scene, &fx.b2, &fx.b4, stream.clone());
        let mut via = Run::new(kernel, &fx.scene, &fx.b2, &fx.b4, stream.clone());
        via.shared = Some(&shared);
        let (a, out_a) = isa::record(&own, FlavourId::Avx2, "own");
        let (b, out_b) = isa::record(&via, FlavourId::Avx2, "own");
        assert_eq!(out_a, out_b, "{}", kernel.name());
        assert_eq!(a.regions, b.regions, "{}: same regions", kernel.name());
        assert_eq!(a.ops, b.ops, "{}: same ops", kernel.name());
        assert!(a.ops.len() > 1000);
    }
}
