//! Every multi-hit kernel returns exactly the reference's first N_query
//! hits on every ray, traced and native alike, for N_query from 1 to all;
//! node culling culls; the naive kernels judge every hit.

use isa::FlavourId;
use multihit_kernels::filters::Insertion;
use multihit_kernels::{Counters, Kernel, Method, Run, Traversal, Tree, NAIVE_CAPACITY};
use scene::multi_agreement::list_mismatches;
use scene::reference::{Ray, Reference};
use scene::scene::Scene;
use scene::workload::{packet_slots, RayStream, StreamKind};
use std::sync::Arc;

/// A `size` x `size` block of pixel-centre primary rays at the middle of
/// the scene's image, path index = pixel in the block.
fn block(scene: &Scene, size: u32) -> RayStream {
    let cam = &scene.config.camera;
    let (x0, y0) = (cam.width / 2 - size / 2, cam.height / 2 - size / 2);
    let (mut org, mut dir) = (Vec::new(), Vec::new());
    for y in 0..size {
        for x in 0..size {
            let (o, d) = cam.ray(f64::from(x0 + x) + 0.5, f64::from(y0 + y) + 0.5);
            org.push(o.map(|c| c as f32));
            dir.push(d.map(|c| c as f32));
        }
    }
    let n = org.len();
    RayStream::from_rays(StreamKind::Primary, org, dir, vec![f32::INFINITY; n])
}

fn check(
    name: &str,
    size: u32,
    flavours: &[FlavourId],
    queries: &[u32],
) -> Vec<(Kernel, u32, Counters)> {
    let scene = Scene::load(name).unwrap();
    let tree = Arc::new(Tree::build(scene.mesh.clone()).unwrap());
    let rays = Arc::new(block(&scene, size));
    let refi = Reference::with_bvh(&tree.mesh, &tree.b2);
    let ref_rays: Vec<Ray> = (0..rays.len()).map(|i| rays.ray(i)).collect();
    let all: Vec<_> = ref_rays.iter().map(|r| refi.all(r)).collect();
    let max = all.iter().map(Vec::len).max().unwrap() as u32;
    assert!(max > 1, "{name}: a multi-hit scene");
    let mut out = Vec::new();
    for &fl in flavours {
        let slots = Arc::new(packet_slots(&rays, size, 1, fl.lanes()));
        // Node culling's packet filter in both insertion forms.
        let variants = Kernel::ALL.into_iter().flat_map(|k| {
            let both = k == Kernel::new(Traversal::Packet, Method::NodeCulling);
            let forms = if both {
                vec![Insertion::Rows, Insertion::GatherScatter]
            } else {
                vec![Insertion::Rows]
            };
            forms.into_iter().map(move |f| (k, f))
        });
        for (kernel, insertion) in variants {
            let mut counts = Vec::new();
            for &n_query in queries.iter().chain([&max]) {
                let run = Run {
                    kernel,
                    n_query,
                    capacity: NAIVE_CAPACITY,
                    tree: tree.clone(),
                    rays: rays.clone(),
                    slots: Some(slots.clone()),
                    insertion,
                };
                let label = format!("{name} {} {insertion:?} {fl}", kernel.name());
                let (lists, c) = isa::record(&run, fl, kernel.name()).1;
                assert_eq!(
                    (lists.clone(), c),
                    isa::run_native(&run, fl),
                    "{label}: traced = native"
                );
                let bad = list_mismatches(&label, &refi, &ref_rays, &all, n_query, &lists);
                assert_eq!(
                    bad,
                    0,
                    "{label} N={n_query}: {bad} of {} rays differ",
                    rays.len()
                );
                assert_eq!(c.overflowed, 0);
                if n_query == max {
                    // Each ray's hits as this kernel finds them (naive
                    // buffers every one, whatever N_query is).
                    counts = lists.iter().map(|l| l.len() as u32).collect();
                }
                out.push((kernel, n_query, c));
            }
            for (_, n_query, c) in &out[out.len() - queries.len() - 1..] {
                check_steps(kernel, *n_query, c, &counts, (&slots, fl.lanes()));
            }
        }
    }
    out
}

/// The walks' step counts: the naive sort's exactly as its loops run over
/// the rays' hit counts (single rays: the entries after each place; a
/// packet: per place, the most entries after it over the lanes still
/// placing); node culling's insertion at least a step per candidate and
/// one per entry moved (a packet's row step: per lanes' worth).
fn check_steps(
    kernel: Kernel,
    n_query: u32,
    c: &Counters,
    counts: &[u32],
    (slots, lanes): (&[u32], usize),
) {
    let after = |count: u32, i: u32| u64::from(count.saturating_sub(i + 1));
    let places = |count: u32| count.min(n_query);
    let want = match (kernel.method, kernel.traversal) {
        (Method::NodeCulling, Traversal::Single) => {
            assert!(c.steps >= c.candidates.max(c.moves), "{kernel:?}: {c:?}");
            return;
        }
        (Method::NodeCulling, Traversal::Packet) => {
            // A row step serves the packet's lanes.
            let least = c.candidates.max(c.moves).div_ceil(lanes as u64);
            assert!(c.steps >= least && c.steps > 0, "{kernel:?}: {c:?}");
            return;
        }
        (Method::Naive, Traversal::Single) => counts
            .iter()
            .map(|&k| (0..places(k)).map(|i| after(k, i)).sum::<u64>())
            .sum::<u64>(),
        (Method::Naive, Traversal::Packet) => slots
            .chunks(lanes)
            .map(|p| {
                let held: Vec<u32> = p
                    .iter()
                    .filter(|&&r| r != u32::MAX)
                    .map(|&r| counts[r as usize])
                    .collect();
                let top = held.iter().map(|&k| places(k)).max().unwrap_or(0);
                (0..top)
                    .map(|i| {
                        let placing = held.iter().filter(|&&k| i < places(k));
                        placing.map(|&k| after(k, i)).max().unwrap_or(0)
                    })
                    .sum::<u64>()
            })
            .sum(),
    };
    assert_eq!(c.steps, want, "{kernel:?} N={n_query}: sort steps");
}

#[test]
fn every_kernel_returns_the_references_first_hits_on_the_layers() {
    let runs = check("layers", 8, &[FlavourId::Avx2], &[1, 2, 4, 16]);
    // Node culling at N = 1 judges fewer candidates than naive (it culls);
    // naive judges every hit whatever N is.
    let get = |t, m, n| {
        runs.iter()
            .find(|(k, q, _)| *k == Kernel::new(t, m) && *q == n)
            .map(|r| r.2)
            .unwrap()
    };
    for t in [Traversal::Single, Traversal::Packet] {
        let (naive, cull) = (get(t, Method::Naive, 1), get(t, Method::NodeCulling, 1));
        assert!(
            cull.candidates * 4 < naive.candidates,
            "{t:?}: {cull:?} {naive:?}"
        );
        assert!(cull.tests.other < naive.tests.other, "{t:?}: nodes culled");
        assert_eq!(naive.candidates, get(t, Method::Naive, 16).candidates);
    }
}

#[test]
fn sse4_and_16_lane_flavours_match_the_reference_on_a_sphere() {
    check("sphere", 4, &[FlavourId::Sse4, FlavourId::Avx512], &[1, 3]);
}
