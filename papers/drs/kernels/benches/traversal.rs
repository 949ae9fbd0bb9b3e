//! The DRS paper's seven traversal kernels run natively (native AVX2
//! backend) on one scene's primary, bounce and shadow streams of one 16 x 16
//! pixel x 16 spp tile, so their real speed on this machine can be set beside
//! the simulated ranking of `rtsim reproduce drs-table1`. The scene is laid
//! out once per kernel; each iteration lays out the rays (untimed), times
//! the kernel alone, as `rtsim native` does, reads the answers back and
//! releases the buffers (untimed).
//!
//! Run: `cargo bench -p drs-kernels --bench traversal` (reads the project's `data/`;
//! `RTSIM_BENCH_SCENE` picks another stand-in than `crown`). Results, with the
//! machine they ran on, are in `rt/benches/RESULTS.md`.

use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};
use drs_kernels::methods::{Kernel, Run};
use isa::{Avx2, Machine, Native};
use scene::bvh::{Bvh2, Bvh4};
use scene::scene::Scene;
use scene::workload::{path_trace_tile, StreamKind, Tile};
use std::time::{Duration, Instant};

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
            let mut scratch = run.scratch(&mut m, &laid);
            let mark = m.space().mark();
            g.bench_function(format!("{}/{label}", kernel.name()), |b| {
                b.iter_custom(|iters| {
                    let mut total = Duration::ZERO;
                    for _ in 0..iters {
                        let mut staged = run.stage(&mut m);
                        let t = Instant::now();
                        let tests = run.trace_staged(&mut m, &laid, &mut staged, &mut scratch);
                        total += t.elapsed();
                        black_box((staged.answers(), tests));
                        m.space().release(mark);
                    }
                    total
                });
            });
        }
    }
    g.finish();
}

criterion_group!(benches, traversal);
criterion_main!(benches);
