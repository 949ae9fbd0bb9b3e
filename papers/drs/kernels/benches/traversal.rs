//! The DRS paper's seven traversal kernels run natively (native AVX2
//! backend) on one scene's primary, bounce and shadow streams of one 16 x 16
//! pixel x 16 spp tile, so their real speed on this machine can be set beside
//! the simulated ranking of `rtsim reproduce drs-table1`. The scene is laid
//! out once per kernel; each iteration allocates the ray records, traces, and
//! releases the records.
//!
//! Run: `cargo bench -p drs-kernels --bench traversal` (reads the project's `data/`;
//! `RTSIM_BENCH_SCENE` picks another stand-in than `crown`). Results, with the
//! machine they ran on, are in `rt/benches/RESULTS.md`.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use drs_kernels::methods::{Kernel, Run};
use isa::{Avx2, Machine, Native};
use scene::bvh::{Bvh2, Bvh4};
use scene::scene::Scene;
use scene::workload::{path_trace_tile, StreamKind, Tile};

fn traversal(c: &mut Criterion) {
    let name = std::env::var("RTSIM_BENCH_SCENE").unwrap_or_else(|_| "crown".into());
    let scene = Scene::load(&name).expect("the scene");
    let b2 = Bvh2::build(&scene.mesh, &drs_kernels::BVH).expect("a BVH");
    let b4 = Bvh4::collapse(&b2);
    let cam = &scene.config.camera;
    let tile = Tile {
        x: cam.width / 32,
        y: cam.height / 32,
        size: 16,
    };
    let streams = path_trace_tile(&scene, &b2, tile, 16, 1, 7);
    let pick = |want: StreamKind| streams.iter().find(|s| s.kind == want).cloned();
    let chosen = [
        ("primary", pick(StreamKind::Primary)),
        ("bounce", pick(StreamKind::Bounce(1))),
        ("shadow", pick(StreamKind::Shadow(0))),
    ];
    let mut g = c.benchmark_group(format!("traversal-native-avx2-{name}"));
    g.sample_size(10);
    for (label, st) in chosen {
        let Some(st) = st else { continue };
        g.throughput(Throughput::Elements(st.len() as u64));
        for kernel in Kernel::ALL {
            let mut run = Run::new(kernel, &scene, &b2, &b4, st.clone());
            run.packet_tile = Some((tile.size, 16));
            let mut m = Native::<Avx2, 8>::new();
            let laid = run.lay_out(&mut m);
            let mark = m.space().mark();
            g.bench_function(format!("{}/{label}", kernel.name()), |b| {
                b.iter(|| {
                    let out = run.trace(&mut m, &laid);
                    m.space().release(mark);
                    out
                });
            });
        }
    }
    g.finish();
}

criterion_group!(benches, traversal);
criterion_main!(benches);
