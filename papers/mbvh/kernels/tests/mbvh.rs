//! Every MBVH kernel returns the reference's hits on every ray of a
//! distribution-traced tile (primary, glossy bounces, shadow rays), on every
//! flavour, traced and native alike; and the counters behave as the paper
//! describes them.

use isa::FlavourId;
use mbvh_kernels::layout::RayForm;
use mbvh_kernels::stats::Counters;
use mbvh_kernels::stream::{Order, StreamConfig};
use mbvh_kernels::{Kernel, Run, Trees, BVH};
use scene::agreement::{mismatches_expected, Expected, F32Test};
use scene::bvh::Bvh2;
use scene::reference::Reference;
use scene::scene::Scene;
use scene::workload::{distribution_tile, Lens, RayStream, Tile};
use std::sync::Arc;

fn tile_streams(name: &str, size: u32, paths: u32, bounces: u32) -> (Arc<Trees>, Vec<RayStream>) {
    let scene = Scene::load(name).unwrap();
    let b2 = Bvh2::build(&scene.mesh, &BVH).unwrap();
    let cam = &scene.config.camera;
    let tile = Tile {
        x: cam.width / (2 * size),
        y: cam.height / (2 * size),
        size,
    };
    let lens = Lens {
        aperture: 0.01,
        focus: 5.0,
    };
    let streams = distribution_tile(&scene, &b2, tile, paths, lens, bounces, 7);
    let trees = Trees::new(Arc::new(scene.mesh.clone()), Arc::new(b2));
    (Arc::new(trees), streams)
}

fn kernels() -> Vec<Kernel> {
    let rs = StreamConfig::default();
    vec![
        Kernel::Stream(rs),
        Kernel::Stream(StreamConfig {
            order: Order::Unordered,
            form: RayForm::Compact,
            group: 16,
        }),
        Kernel::Single,
        Kernel::Packet,
        Kernel::LargePacket(mbvh_kernels::large_packet::DEFAULT_PACKET),
        Kernel::LargePacket(16),
    ]
}

fn check(trees: &Arc<Trees>, streams: &[RayStream], flavours: &[FlavourId]) -> Vec<Counters> {
    let refi = Reference::with_bvh(&trees.mesh, &trees.b2);
    let mut out = Vec::new();
    for st in streams.iter().filter(|s| !s.is_empty()) {
        let want = Expected::of(&refi, st);
        let rays = Arc::new(st.clone());
        for kernel in kernels() {
            let run = Run {
                kernel,
                trees: trees.clone(),
                rays: rays.clone(),
            };
            for &fl in flavours {
                let label = format!("{} {fl} {:?}", kernel.name(), st.kind);
                let (hits, c) = isa::record(&run, fl, kernel.name()).1;
                assert_eq!(
                    (hits.clone(), c),
                    isa::run_native(&run, fl),
                    "{label}: traced and native agree"
                );
                let bad =
                    mismatches_expected(F32Test::MollerTrumbore, &label, &refi, st, &want, &hits);
                assert_eq!(bad, 0, "{label}: {bad} of {} rays differ", st.len());
                assert_eq!(c.rays, st.len() as u64);
                out.push(c);
            }
        }
    }
    out
}

#[test]
fn every_kernel_matches_the_reference_on_a_distribution_traced_tile() {
    let (trees, streams) = tile_streams("conference", 4, 16, 2);
    let lens: Vec<usize> = streams.iter().map(RayStream::len).collect();
    assert!(lens.len() == 5 && lens.iter().all(|&n| n > 0), "{lens:?}");
    check(&trees, &streams, &[FlavourId::Sse4, FlavourId::Lrb16]);
}

#[test]
fn avx2_and_avx512_widths_match_the_reference_too() {
    let (trees, streams) = tile_streams("sphere", 4, 4, 1);
    check(&trees, &streams, &[FlavourId::Avx2, FlavourId::Avx512]);
}
