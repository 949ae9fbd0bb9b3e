//! Multi-frusta tracing returns the reference's closest hit for every ray it
//! generates: with back-face culling against the front-faces-only reference,
//! without it against the two-sided one; traced and native agree.

use isa::FlavourId;
use kernels::bvh::{BuildConfig, Bvh2};
use kernels::harness::mismatches;
use kernels::mft::{Frusta, PacketPrimaryRun, PrimaryRun};
use kernels::reference::Reference;
use kernels::scene::Scene;

fn check(
    scene_name: &str,
    blocks: &[(u32, u32)],
) -> (kernels::mft::MftStats, kernels::mft::MftStats) {
    let scene = Scene::load(scene_name).unwrap();
    // A shallow BVH for the frusta (large leaves), a deep one for packets.
    let bvh = Bvh2::build(
        &scene.mesh,
        &BuildConfig {
            max_leaf: 8,
            c_trav: 8.0,
            ..BuildConfig::default()
        },
    )
    .unwrap();
    let cam = &scene.config.camera;
    let mut sets: Vec<Frusta> = blocks
        .iter()
        .map(|&(x, y)| Frusta::primary(cam, x, y))
        .collect();
    // And a block where some frustum's direction interval holds zero (the
    // zero-interval fix), among those whose centre pixel sees geometry.
    let holds_zero = |f: &Frusta| {
        let rec = f.record();
        (0..16).any(|n| {
            (0..3).any(|a| {
                rec[(kernels::mft::row::DIR_LO + a) * 16 + n] <= 0.0
                    && rec[(kernels::mft::row::DIR_HI + a) * 16 + n] >= 0.0
            })
        })
    };
    let zero_block = (0..cam.height / 16)
        .flat_map(|y| (0..cam.width / 16).map(move |x| (x, y)))
        .map(|(x, y)| Frusta::primary(cam, x, y))
        .find(|f| {
            let refi = Reference::with_bvh(&scene.mesh, &bvh);
            let (o, d) = f.ray(5, 5);
            holds_zero(f)
                && refi
                    .closest(&kernels::reference::Ray::new(
                        o.map(f64::from),
                        d.map(f64::from),
                    ))
                    .is_some()
        })
        .expect("a frustum straddling an axis direction");
    sets.push(zero_block);
    let deep = Bvh2::build(&scene.mesh, &BuildConfig::default()).unwrap();
    let mut last = None;
    for cull_back in [true, false] {
        let run = PrimaryRun {
            scene: &scene,
            bvh: &bvh,
            sets: sets.clone(),
            cull_back,
        };
        let (org, dir) = run.rays();
        let (traced, stats) = isa::record(&run, FlavourId::Lrb16, "mft").1;
        assert_eq!(
            (traced.clone(), stats),
            isa::run_native(&run, FlavourId::Lrb16),
            "{scene_name}: traced and native agree"
        );
        let refi = Reference::with_bvh(&scene.mesh, &bvh);
        let refi = if cull_back {
            refi.front_faces_only()
        } else {
            refi
        };
        let label = format!("mft {scene_name} cull_back {cull_back}");
        let bad = mismatches(&label, &refi, &org, &dir, &traced);
        assert_eq!(bad, 0, "{label}: {bad} of {} rays differ", org.len());
        let hits = traced.iter().filter(|h| h.1 >= 0).count();
        assert!(hits > org.len() / 8, "{label}: some hits ({hits})");
        assert!(stats.aabb_tests > 0 && stats.isec_tests > 0, "{stats:?}");
        assert!(stats.tris_after_culling <= stats.tris_accessed);
        // The 16-ray packet baseline on the same rays, deep BVH.
        let pr = PacketPrimaryRun {
            scene: &scene,
            bvh: &deep,
            sets: sets.clone(),
            cull_back,
        };
        let (ptraced, pstats) = isa::record(&pr, FlavourId::Lrb16, "p16").1;
        assert_eq!(
            (ptraced.clone(), pstats),
            isa::run_native(&pr, FlavourId::Lrb16)
        );
        let bad = mismatches(&format!("packet {label}"), &refi, &org, &dir, &ptraced);
        assert_eq!(bad, 0, "packet {label}: {bad} rays differ");
        last = Some((stats, pstats));
    }
    last.unwrap()
}

#[test]
fn mft_primary_frusta_match_the_reference() {
    let (s, p) = check("trex", &[(30, 30), (32, 28), (25, 35)]);
    eprintln!("trex: frusta {s:?} packets {p:?}");
    assert!(s.isec_tests >= s.tris_after_culling, "{s:?}");
    // The paper's headline: frusta need far fewer box tests than packets.
    assert!(
        p.aabb_tests >= 10 * s.aabb_tests,
        "packets {p:?} vs frusta {s:?}"
    );
    check("fern", &[(30, 30), (20, 40)]);
}
