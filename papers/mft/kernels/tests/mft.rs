//! Multi-frusta tracing returns the reference's answer for every ray it
//! generates — closest hits of primary frusta, occlusion of shadow frusta —
//! with back-face culling against the front-faces-only reference and without
//! it against the two-sided one; so does the 16-ray packet baseline on the
//! same rays; traced and native agree.

use isa::FlavourId;
use mft_kernels::{mismatches_of, Frusta, FrustaRun, MftStats, PacketPrimaryRun, Shrink};
use scene::agreement::F32Test;
use scene::bvh::{BuildConfig, Bvh2};
use scene::reference::{Ray, Reference};
use scene::scene::{Light, Scene};
use scene::workload::soft_shadow_group;

/// Rays of active frusta whose answer differs from the reference's (the
/// MFT kernel's tolerance is its Pluecker test's, the packets' Moller-Trumbore's).
fn bad(label: &str, refi: &Reference, sets: &[Frusta], out: &[scene::Hit]) -> usize {
    let test = if label.starts_with("mft") {
        F32Test::Pluecker
    } else {
        F32Test::MollerTrumbore
    };
    mismatches_of(test, label, refi, sets, out)
}

/// The kernel tests' shared fixture: a scene with the shallow BVH MFT
/// traverses and the deep BVH of the packet baseline.
struct Fixture {
    scene: Scene,
    shallow: Bvh2,
    deep: Bvh2,
}

impl Fixture {
    fn load(name: &str) -> Fixture {
        Fixture::of(Scene::load(name).unwrap())
    }
    fn of(scene: Scene) -> Fixture {
        let shallow = Bvh2::build(&scene.mesh, &mft_kernels::SHALLOW_BVH).unwrap();
        let deep = Bvh2::build(&scene.mesh, &BuildConfig::default()).unwrap();
        Fixture {
            scene,
            shallow,
            deep,
        }
    }
    /// The reference over the deep BVH (both faces).
    fn reference(&self) -> Reference<'_> {
        Reference::with_bvh(&self.scene.mesh, &self.deep)
    }
}

/// Run MFT (shallow BVH) and 16-ray packets (deep BVH) on `sets`, both
/// culling modes; the counters of the two-sided run.
fn check(fx: &Fixture, sets: &[Frusta]) -> (MftStats, MftStats) {
    let (scene, shallow, deep) = (&fx.scene, &fx.shallow, &fx.deep);
    let name = &scene.config.name;
    let mut last = None;
    for cull_back in [true, false] {
        let refi = Reference::with_bvh(&scene.mesh, shallow);
        let refi = if cull_back {
            refi.front_faces_only()
        } else {
            refi
        };
        let label = format!("{name} cull_back {cull_back}");
        let run = FrustaRun {
            scene,
            bvh: shallow,
            sets: sets.to_vec(),
            cull_back,
            packets256: false,
            shrink: mft_kernels::Shrink::None,
            plane_noise: mft_kernels::PlaneNoise::Reject,
            slab: mft_kernels::SlabTest::Paper,
        };
        let (traced, stats) = isa::record(&run, FlavourId::Lrb16, "mft").1;
        assert_eq!(
            (traced.clone(), stats),
            isa::run_native(&run, FlavourId::Lrb16),
            "{label}: traced and native agree"
        );
        let n = bad(&format!("mft {label}"), &refi, sets, &traced);
        assert_eq!(n, 0, "mft {label}: {n} rays differ");
        // Without the robustness test (the paper's kernel): no hit changes
        // on this small sample.
        let robust = FrustaRun {
            plane_noise: mft_kernels::PlaneNoise::Keep,
            sets: sets.to_vec(),
            ..run
        };
        let (rtraced, rstats) = isa::run_native(&robust, FlavourId::Lrb16);
        assert_eq!(
            rstats, stats,
            "{label}: the same counts with the robustness test"
        );
        let n = bad(&format!("mft no-robust {label}"), &refi, sets, &rtraced);
        assert_eq!(
            n, 0,
            "mft without the robustness test {label}: {n} rays differ"
        );
        // The sign-free slab test (the named variant): the same hits and
        // counts as the paper's offset-table test.
        let free = FrustaRun {
            slab: mft_kernels::SlabTest::SignFree,
            sets: sets.to_vec(),
            ..run
        };
        assert_eq!(
            isa::run_native(&free, FlavourId::Lrb16),
            (traced.clone(), stats),
            "{label}: the sign-free slab test answers and counts the same"
        );
        let hits = traced.iter().filter(|h| h.is_hit()).count();
        assert!(hits > traced.len() / 16, "{label}: some hits ({hits})");
        assert!(stats.aabb_tests > 0 && stats.isec_tests > 0, "{stats:?}");
        assert!(stats.tris_after_culling <= stats.tris_accessed);
        let pr = PacketPrimaryRun {
            scene,
            bvh: deep,
            sets: sets.to_vec(),
            cull_back,
            leaves: mft_kernels::PacketLeaves::Indexed,
            plane_noise: mft_kernels::PlaneNoise::Reject,
            grouping: mft_kernels::PacketGrouping::PerFrustum,
        };
        let (ptraced, pstats) = isa::record(&pr, FlavourId::Lrb16, "p16").1;
        assert_eq!(
            (ptraced.clone(), pstats),
            isa::run_native(&pr, FlavourId::Lrb16)
        );
        let n = bad(&format!("packet {label}"), &refi, sets, &ptraced);
        assert_eq!(n, 0, "packet {label}: {n} rays differ");
        // Packets of ray k of every frustum (the other grouping): the
        // reference's hits too, traced as native.
        let per_sample = PacketPrimaryRun {
            grouping: mft_kernels::PacketGrouping::PerSample,
            sets: sets.to_vec(),
            ..pr
        };
        let (straced, _) = isa::record(&per_sample, FlavourId::Lrb16, "p16s").1;
        assert_eq!(
            straced,
            isa::run_native(&per_sample, FlavourId::Lrb16).0,
            "{label}: per-sample packets, traced and native"
        );
        let n = bad(&format!("packet per-sample {label}"), &refi, sets, &straced);
        assert_eq!(n, 0, "packet per-sample {label}: {n} rays differ");
        // The precomputed-edge variant: the same hits and counts.
        let edges = PacketPrimaryRun {
            leaves: mft_kernels::PacketLeaves::Edges,
            sets: sets.to_vec(),
            ..pr
        };
        let (etraced, estats) = isa::run_native(&edges, FlavourId::Lrb16);
        assert_eq!(estats, pstats, "{label}: edge-form packets count the same");
        let n = bad(&format!("packet edges {label}"), &refi, sets, &etraced);
        assert_eq!(n, 0, "packet edges {label}: {n} rays differ");
        // 256-ray packets: MFT's leaves behind per-ray box tests of 16 packets.
        let big = FrustaRun {
            packets256: true,
            shrink: mft_kernels::Shrink::None,
            ..run
        };
        let (btraced, bstats) = isa::record(&big, FlavourId::Lrb16, "p256").1;
        assert_eq!(
            (btraced.clone(), bstats),
            isa::run_native(&big, FlavourId::Lrb16)
        );
        let n = bad(&format!("mft p256 {label}"), &refi, sets, &btraced);
        assert_eq!(n, 0, "256-ray packets {label}: {n} rays differ");
        assert!(
            bstats.aabb_tests > stats.aabb_tests,
            "{bstats:?} vs {stats:?}"
        );
        last = Some((stats, pstats));
    }
    last.unwrap()
}

/// A primary block where some frustum's direction interval holds zero (the
/// zero-interval fix) and its centre ray sees geometry.
fn zero_block(scene: &Scene, refi: &Reference) -> Frusta {
    let cam = &scene.config.camera;
    let holds_zero = |f: &Frusta| {
        let rec = f.record();
        (0..16).any(|n| {
            (0..3).any(|a| {
                rec[(mft_kernels::row::DIR_LO + a) * 16 + n] <= 0.0
                    && rec[(mft_kernels::row::DIR_HI + a) * 16 + n] >= 0.0
            })
        })
    };
    (0..cam.height / 16)
        .flat_map(|y| (0..cam.width / 16).map(move |x| (x, y)))
        .map(|(x, y)| Frusta::primary(cam, x, y))
        .find(|f| {
            let (o, d) = f.ray(5, 5);
            holds_zero(f)
                && refi
                    .closest(&Ray::new(o.map(f64::from), d.map(f64::from)))
                    .is_some()
        })
        .expect("a frustum straddling an axis direction")
}

#[test]
fn mft_primary_frusta_match_the_reference() {
    let fx = Fixture::load("trex");
    let (scene, refi) = (&fx.scene, fx.reference());
    let cam = &scene.config.camera;
    let mut sets: Vec<Frusta> = [(30, 30), (32, 28), (25, 35)]
        .iter()
        .map(|&(x, y)| Frusta::primary(cam, x, y))
        .collect();
    sets.push(zero_block(scene, &refi));
    let (s, p) = check(&fx, &sets);
    assert!(s.isec_tests >= s.tris_after_culling, "{s:?}");
    // The paper's headline: frusta need far fewer box tests than packets.
    assert!(
        p.aabb_tests >= 10 * s.aabb_tests,
        "packets {p:?} vs frusta {s:?}"
    );
    let fern = Fixture::load("fern");
    let cam = &fern.scene.config.camera;
    let sets: Vec<Frusta> = [(30, 30), (20, 40)]
        .iter()
        .map(|&(x, y)| Frusta::primary(cam, x, y))
        .collect();
    check(&fern, &sets);
}

#[test]
fn mft_shadow_frusta_match_the_reference() {
    let fx = Fixture::load("trex");
    let (scene, refi) = (&fx.scene, fx.reference());
    let Some(Light::Quad(c, e1, e2, _)) = scene.config.lights.first().cloned() else {
        panic!("trex has a quad light");
    };
    // 4 x 4 pixel groups around the T-Rex's feet: lit, penumbra and umbra.
    let sets: Vec<Frusta> = [(500, 760), (540, 780), (460, 800), (600, 740)]
        .iter()
        .map(|&(x, y)| Frusta::shadow(&soft_shadow_group(scene, &refi, x, y), [c, e1, e2]))
        .collect();
    assert!(
        sets.iter().all(|f| f.active != 0),
        "the groups see geometry"
    );
    let (s, p) = check(&fx, &sets);
    assert!(p.aabb_tests > s.aabb_tests, "packets {p:?} vs frusta {s:?}");
    // Frustum shrinking (Table 2) keeps every answer and only ever culls
    // more; on penumbra groups (some frustum partly occluded) as well.
    let shallow = &fx.shallow;
    let refi = Reference::with_bvh(&scene.mesh, shallow).front_faces_only();
    let partly = |f: &Frusta| {
        (0..16).filter(|&n| f.active & (1 << n) != 0).any(|n| {
            let occ = (0..16)
                .filter(|&k| {
                    let (o, d) = f.ray(n, k);
                    let r = Ray::new(o.map(f64::from), d.map(f64::from));
                    refi.all(&r).iter().any(|h| h.t < f64::from(f.tmax))
                })
                .count();
            occ > 0 && occ < 16
        })
    };
    let mut sets = sets;
    sets.extend(
        (0..64u32)
            .map(|i| (384 + 8 * i, 700 + 4 * (i % 8)))
            .map(|(x, y)| Frusta::shadow(&soft_shadow_group(scene, &refi, x, y), [c, e1, e2]))
            .filter(partly)
            .take(3),
    );
    assert!(sets.len() >= 6, "penumbra groups found");
    let mut by = Vec::new();
    for shrink in Shrink::ALL {
        let run = FrustaRun {
            scene,
            bvh: shallow,
            sets: sets.clone(),
            cull_back: true,
            packets256: false,
            shrink,
            plane_noise: mft_kernels::PlaneNoise::Reject,
            slab: mft_kernels::SlabTest::Paper,
        };
        let (out, st) = isa::record(&run, FlavourId::Lrb16, "shrink").1;
        assert_eq!((out.clone(), st), isa::run_native(&run, FlavourId::Lrb16));
        let n = bad(&format!("mft {shrink:?}"), &refi, &sets, &out);
        assert_eq!(n, 0, "{shrink:?}: {n} rays differ");
        by.push(st);
    }
    let [none, ray_aabb, cr, fs] = [by[0], by[1], by[2], by[3]];
    assert_eq!(none.shrinks + none.leaf_box_tests, 0, "{none:?}");
    assert!(ray_aabb.leaf_box_tests > 0 && ray_aabb.aabb_tests > none.aabb_tests);
    assert!(ray_aabb.tris_accessed <= none.tris_accessed, "{ray_aabb:?}");
    assert!(ray_aabb.isec_tests <= none.isec_tests, "{ray_aabb:?}");
    // CR: same traversal, tighter corners.
    assert!(cr.shrinks > 0, "{cr:?}");
    assert_eq!(
        (cr.aabb_tests, cr.tris_accessed),
        (none.aabb_tests, none.tris_accessed)
    );
    assert!(cr.isec_tests < none.isec_tests, "{cr:?} vs {none:?}");
    // FS: CR plus tighter traversal.
    assert!(fs.aabb_tests <= none.aabb_tests && fs.isec_tests <= none.isec_tests);
    assert!(fs.shrinks > 0, "{fs:?}");
}

/// Every scene of the MFT paper's stand-ins at 64 x 64: primary frusta,
/// shadow frusta under all four shrinking modes and 256-ray packets give
/// the reference's answer on every ray they generate.
#[test]
fn every_mft_scene_at_small_resolution_matches_the_reference() {
    for name in ["trex", "fern", "saloon", "fairy"] {
        let mut scene = Scene::load(name).unwrap();
        scene.config.camera.width = 64;
        scene.config.camera.height = 64;
        let cam = scene.config.camera.clone();
        let Some(Light::Quad(c, e1, e2, _)) = scene.config.lights.first().cloned() else {
            panic!("{name} has a quad light");
        };
        let fx = Fixture::of(scene);
        let (scene, shallow) = (&fx.scene, &fx.shallow);
        let refi = Reference::with_bvh(&scene.mesh, shallow).front_faces_only();
        let primary: Vec<Frusta> = (0..4)
            .flat_map(|y| (0..4).map(move |x| (x, y)))
            .map(|(x, y)| Frusta::primary(&cam, x, y))
            .collect();
        let shadow: Vec<Frusta> = (0..16)
            .flat_map(|y| (0..16).map(move |x| (4 * x, 4 * y)))
            .map(|(x, y)| Frusta::shadow(&soft_shadow_group(scene, &refi, x, y), [c, e1, e2]))
            .filter(|f| f.active != 0)
            .collect();
        assert!(!shadow.is_empty(), "{name}: shadow groups");
        let run = |sets: &[Frusta], packets256: bool, shrink: Shrink| {
            isa::run_native(
                &FrustaRun {
                    scene,
                    bvh: shallow,
                    sets: sets.to_vec(),
                    cull_back: true,
                    packets256,
                    shrink,
                    plane_noise: mft_kernels::PlaneNoise::Reject,
                    slab: mft_kernels::SlabTest::Paper,
                },
                FlavourId::Lrb16,
            )
            .0
        };
        for p256 in [false, true] {
            let out = run(&primary, p256, Shrink::None);
            let n = bad(
                &format!("mft {name} primary p256 {p256}"),
                &refi,
                &primary,
                &out,
            );
            assert_eq!(n, 0, "{name} primary p256 {p256}");
        }
        for shrink in Shrink::ALL {
            let out = run(&shadow, false, shrink);
            let n = bad(
                &format!("mft {name} shadow {shrink:?}"),
                &refi,
                &shadow,
                &out,
            );
            assert_eq!(n, 0, "{name} shadow {shrink:?}");
        }
        let out = run(&shadow, true, Shrink::None);
        assert_eq!(bad(&format!("mft {name} p256"), &refi, &shadow, &out), 0);
    }
}
