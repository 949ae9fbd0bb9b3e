//! Simulator speed: simulated ops per host second in full-timing mode on a
//! realistic stream (the ray-vs-4-boxes kernel, 16384 rays, ~311K ops), on
//! the out-of-order Haswell model and the in-order Larrabee model, and how it
//! scales with 2 host threads over independent work units.
//!
//! Run: `cargo bench --bench sim_speed`. Results: `benches/RESULTS.md`.

use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};
use rt::boxtest::BoxStream;
use sim::{simulate, Fidelity, MachineConfig, SimOptions};

fn bench(c: &mut Criterion) {
    let w = BoxStream::generate(16384, 7);
    let mut g = c.benchmark_group("sim-full");
    for (name, fid) in [
        ("haswell-i7-4750hq", Fidelity::Full),
        ("larrabee", Fidelity::Full),
        ("haswell-i7-4750hq", Fidelity::Counts),
    ] {
        let m = MachineConfig::load(name).unwrap();
        let (t, _) = isa::record(&w, m.flavour(), "bench");
        g.throughput(Throughput::Elements(t.ops.len() as u64));
        let opt = SimOptions {
            fidelity: fid,
            ..SimOptions::default()
        };
        g.bench_function(format!("{name}-{}", fid.name()), |b| {
            b.iter(|| black_box(simulate(&m, &[&t], &opt).unwrap().cycles))
        });
    }
    // Two independent work units: one after the other vs on two host threads.
    let m = MachineConfig::load("haswell-i7-4750hq").unwrap();
    let (t, _) = isa::record(&w, m.flavour(), "bench");
    let opt = SimOptions::default();
    g.throughput(Throughput::Elements(2 * t.ops.len() as u64));
    g.bench_function("two-units-1-thread", |b| {
        b.iter(|| {
            black_box(simulate(&m, &[&t], &opt).unwrap().cycles);
            black_box(simulate(&m, &[&t], &opt).unwrap().cycles)
        })
    });
    g.bench_function("two-units-2-threads", |b| {
        b.iter(|| {
            std::thread::scope(|s| {
                let h = s.spawn(|| simulate(&m, &[&t], &opt).unwrap().cycles);
                let a = simulate(&m, &[&t], &opt).unwrap().cycles;
                black_box(a + h.join().unwrap())
            })
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
