//! The hand-written AVX2 twin of single-ray BVH4 (`rt::hand::single_bvh4`),
//! its node test in 4-lane or in 8-lane registers, answers every ray
//! exactly as the kernel does natively: t, u, v and the
//! triangle, bit for bit, on primary, bounce and shadow streams, degenerate
//! rays included.

use crate::common::{fixture, Kernel, Run};
use isa::{FlavourId, Machine, MemKind, Program};
use rt::hand::{Bvh4View, HitRecord, NodeWidth};
use rt::layout::{hit_records, ray_records};
use scene::workload::{path_trace_tile, RayStream, StreamKind, Tile};

/// The kernel's hit records and the twin's at each node width (`None` on a
/// host without AVX2), on one machine's layout of the run's tree.
struct Both<'a>(Run<'a>);

impl Program for Both<'_> {
    type Out = (Vec<HitRecord>, [Option<Vec<HitRecord>>; 2]);
    fn run<M: Machine>(&self, m: &mut M) -> Self::Out {
        let laid = self.0.lay_out(m);
        let s = laid.bvh4.as_ref().expect("a BVH4 layout");
        let rays = &self.0.rays;
        let n = rays.len();
        let (tr, is) = ray_records(&rays.org, &rays.dir, &rays.tmax);
        let mut trav = m.space().alloc_f32(MemKind::Rays, "trav", &tr, 64);
        let isect = m.space().alloc_f32(MemKind::Rays, "isect", &is, 64);
        let mut hits = m
            .space()
            .alloc_bytes(MemKind::Hits, "hits", hit_records(n), 64);
        let bytes = rt::single::STACK_ENTRIES * 8;
        let mut stack = m.space().alloc(MemKind::Stack, "stack", bytes, 64);
        let mut tests = rt::stats::Tests::default();
        let policy = rays.policy();
        let args = (&mut trav, &isect, &mut hits, &mut stack);
        rt::single::trace_bvh4(m, s, args.0, args.1, args.2, args.3, n, &mut tests, policy);
        let kernel = (0..n)
            .map(|i| HitRecord {
                t: hits.f32_at(16 * i),
                u: hits.f32_at(16 * i + 4),
                v: hits.f32_at(16 * i + 8),
                prim: hits.u32_at(16 * i + 12),
            })
            .collect();
        let view = Bvh4View::new(s).expect("a valid layout");
        let twin = |w| rt::hand::single_bvh4(&view, (&tr, &is), policy, w);
        (kernel, [twin(NodeWidth::Xmm), twin(NodeWidth::Ymm)])
    }
}

/// Rays that stress the slab and edge tests: axis-parallel directions
/// (an infinite reciprocal), a zero direction, and rays from a mesh vertex.
fn degenerate(scene: &scene::scene::Scene) -> RayStream {
    let c = scene.config.camera.eye;
    let v = scene.mesh.positions[scene.mesh.tris[0][0] as usize];
    let mut org = Vec::new();
    let mut dir = Vec::new();
    for d in [
        [1.0, 0.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.0, 0.0, 1.0],
        [-0.0, 0.0, -1.0],
        [0.0, 0.0, 0.0],
        [0.3, -0.2, 0.9],
    ] {
        org.extend([c, v]);
        dir.extend([d, d]);
    }
    RayStream::closest(org, dir)
}

#[test]
fn the_hand_written_single_bvh4_answers_every_ray_as_the_kernel() {
    let mut compared = 0;
    for name in ["sphere", "fern", "saloon"] {
        let fx = fixture(name);
        let (scene, b2, b4) = (&fx.scene, &fx.b2, &fx.b4);
        let cam = &scene.config.camera;
        let size = 8;
        let (x, y) = (cam.width / size / 2, cam.height / size / 2);
        let tile = Tile { x, y, size };
        let mut streams = path_trace_tile(scene, b2, tile, 2, 1, 5);
        streams.push(degenerate(scene));
        assert!(streams.iter().any(|s| s.kind == StreamKind::Primary));
        assert!(streams
            .iter()
            .any(|s| matches!(s.kind, StreamKind::Shadow(_))));
        for st in streams {
            let run = Run::new(Kernel::SingleBvh4, scene, b2, b4, st.clone());
            let (kernel, twins) = isa::run_native(&Both(run), FlavourId::Avx2);
            assert_eq!(kernel.len(), st.len());
            for (w, hand) in ["xmm", "ymm"].into_iter().zip(twins) {
                let Some(hand) = hand else {
                    assert!(!rt::hand::available());
                    continue;
                };
                for (i, (k, h)) in kernel.iter().zip(&hand).enumerate() {
                    let bits =
                        |r: &HitRecord| (r.t.to_bits(), r.u.to_bits(), r.v.to_bits(), r.prim);
                    assert_eq!(
                        bits(k),
                        bits(h),
                        "{name} {:?} {w} ray {i}: {k:?} vs {h:?}",
                        st.kind
                    );
                }
                compared += st.len();
            }
        }
    }
    assert!(compared > 0 || !rt::hand::available());
}

#[test]
fn a_view_refuses_a_child_ref_outside_its_buffer() {
    let fx = fixture("sphere");
    struct Corrupt<'a>(Run<'a>);
    impl Program for Corrupt<'_> {
        type Out = Result<(), String>;
        fn run<M: Machine>(&self, m: &mut M) -> Self::Out {
            let mut s = self.0.lay_out(m).bvh4.expect("a BVH4 layout");
            Bvh4View::new(&s)?;
            let n = (s.nodes.len() / rt::layout::NODE_BYTES) as u32;
            s.nodes.set_u32(96, n);
            Bvh4View::new(&s).map(|_| ())
        }
    }
    let st = RayStream::closest(vec![[0.0; 3]], vec![[1.0, 0.0, 0.0]]);
    let run = Run::new(Kernel::SingleBvh4, &fx.scene, &fx.b2, &fx.b4, st);
    let err = isa::run_native(&Corrupt(run), FlavourId::Avx2).unwrap_err();
    assert!(err.contains("node 0 child 0"), "{err}");
}
