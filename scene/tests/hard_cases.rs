//! Numerical hard cases for the reference intersector, each with its
//! expected answer. Where f32 Moller-Trumbore disagrees with the watertight
//! test, the test says so and counts it.

use isa::rng::Rng;
use scene::bvh::{Aabb, BuildConfig, Bvh2};
use scene::mesh::Mesh;
use scene::reference::{moller_trumbore, Ray, Reference, Slab, Watertight};

fn icosphere(level: u32) -> Mesh {
    scene::scene::icosphere(level)
}

fn f64v(p: [f32; 3]) -> [f64; 3] {
    p.map(f64::from)
}

#[test]
fn closed_mesh_has_no_leaks_at_vertices_and_edges() {
    // 1M seeded rays aimed exactly at vertices and at points on edges, half
    // from inside, half from outside. Expected: every ray hits (0 leaks).
    let m = icosphere(3);
    assert_eq!(m.len(), 1280);
    let b = Bvh2::build(&m, &BuildConfig::default()).unwrap();
    b.validate(&m).unwrap();
    const RAYS: usize = 1_000_000;
    let leaks: usize = std::thread::scope(|s| {
        let hs: Vec<_> = (0..2u64)
            .map(|part| {
                let (m, b) = (&m, &b);
                s.spawn(move || {
                    let refi = Reference::with_bvh(m, b);
                    let mut r = Rng::new(100 + part);
                    let mut leaks = 0;
                    for i in 0..RAYS / 2 {
                        let tri = m.tri(r.below(m.len() as u64) as usize);
                        let target = if i % 2 == 0 {
                            f64v(tri[r.below(3) as usize])
                        } else {
                            let (p, q) = (f64v(tri[0]), f64v(tri[1]));
                            let t = f64::from(r.f32());
                            [
                                p[0] + t * (q[0] - p[0]),
                                p[1] + t * (q[1] - p[1]),
                                p[2] + t * (q[2] - p[2]),
                            ]
                        };
                        let org = if i % 4 < 2 {
                            [
                                f64::from(r.range(-0.3, 0.3)),
                                f64::from(r.range(-0.3, 0.3)),
                                f64::from(r.range(-0.3, 0.3)),
                            ]
                        } else {
                            // Outside, roughly along the target's outward direction, so the
                            // ray crosses the surface there. (A ray through a silhouette
                            // vertex only touches a convex mesh: no crossing, no leak.)
                            let mut j = || f64::from(r.range(-0.3, 0.3));
                            [
                                3.0 * target[0] + j(),
                                3.0 * target[1] + j(),
                                3.0 * target[2] + j(),
                            ]
                        };
                        let dir = [target[0] - org[0], target[1] - org[1], target[2] - org[2]];
                        if refi.closest(&Ray::new(org, dir)).is_none() {
                            leaks += 1;
                        }
                    }
                    leaks
                })
            })
            .collect();
        hs.into_iter().map(|h| h.join().unwrap()).sum()
    });
    assert_eq!(leaks, 0, "watertight test leaked {leaks} of {RAYS} rays");
}

#[test]
fn moller_trumbore_leaks_where_watertight_does_not() {
    // The same kind of rays, 20K from inside aimed at vertices, brute force.
    // Documented: f32 Moller-Trumbore misses some; the watertight test none.
    let m = icosphere(2);
    let refi = Reference::brute(&m);
    let mut r = Rng::new(7);
    let (mut mt_leaks, mut wt_leaks) = (0, 0);
    for _ in 0..20_000 {
        let target = f64v(m.tri(r.below(m.len() as u64) as usize)[r.below(3) as usize]);
        let org = [
            f64::from(r.range(-0.3, 0.3)),
            f64::from(r.range(-0.3, 0.3)),
            f64::from(r.range(-0.3, 0.3)),
        ];
        let dir = [target[0] - org[0], target[1] - org[1], target[2] - org[2]];
        wt_leaks += usize::from(refi.closest(&Ray::new(org, dir)).is_none());
        let (o32, d32) = (org.map(|x| x as f32), dir.map(|x| x as f32));
        let any =
            (0..m.len()).any(|i| moller_trumbore(o32, d32, m.tri(i), 0.0, f32::INFINITY).is_some());
        mt_leaks += usize::from(!any);
    }
    assert_eq!(wt_leaks, 0);
    println!("f32 Moller-Trumbore leaked {mt_leaks} of 20000 vertex-aimed rays");
    assert!(
        mt_leaks > 0,
        "expected Moller-Trumbore to leak at shared vertices on this seed"
    );
}

fn unit_box() -> Aabb {
    Aabb {
        lo: [0.0; 3],
        hi: [1.0; 3],
    }
}

#[test]
fn axis_aligned_rays_with_signed_zeros() {
    // Direction (+0, -0, 1) and (-0, +0, 1) through the box: hit, t in [1, 2].
    for d in [[0.0, -0.0, 1.0], [-0.0, 0.0, 1.0], [0.0, 0.0, 1.0]] {
        let r = Ray::new([0.5, 0.5, -1.0], d);
        let (near, far) = Slab::new(&r).hit(&unit_box(), r.tmin, r.tmax).expect("hit");
        // The far distance is padded by a few ulp (Ize 2013).
        assert!(
            near == 1.0 && (2.0..2.0 + 1e-12).contains(&far),
            "{d:?}: {near} {far}"
        );
    }
    // Outside the slab in x with a zero x direction: miss, no NaN.
    let r = Ray::new([1.5, 0.5, -1.0], [-0.0, 0.0, 1.0]);
    assert_eq!(Slab::new(&r).hit(&unit_box(), r.tmin, r.tmax), None);
    // A triangle hit by an axis-aligned ray with -0 components.
    let tri = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let w = Watertight::new(&Ray::new([0.25, 0.25, 1.0], [-0.0, -0.0, -1.0]));
    assert_eq!(w.hit(tri, 0.0, f64::INFINITY).map(|h| h.0), Some(1.0));
}

#[test]
fn origin_on_a_box_face_and_flat_boxes() {
    // Origin exactly on the x = 0 face with x direction +0 and -0: inside (closed box).
    for dx in [0.0, -0.0] {
        let r = Ray::new([0.0, 0.5, 0.5], [dx, 0.0, 1.0]);
        assert!(
            Slab::new(&r).hit(&unit_box(), r.tmin, r.tmax).is_some(),
            "dx = {dx}"
        );
    }
    // Origin on a face, pointing out: the overlap starts at t = 0.
    let r = Ray::new([1.0, 0.5, 0.5], [1.0, 0.0, 0.0]);
    assert_eq!(
        Slab::new(&r).hit(&unit_box(), 0.0, f64::INFINITY),
        Some((0.0, 0.0))
    );
    // A flat box (zero thickness in z) crossed by a ray: hit at t = 1.
    let flat = Aabb {
        lo: [0.0, 0.0, 0.5],
        hi: [1.0, 1.0, 0.5],
    };
    let r = Ray::new([0.5, 0.5, -0.5], [0.0, 0.0, 1.0]);
    let h = Slab::new(&r)
        .hit(&flat, r.tmin, r.tmax)
        .expect("flat box is hit");
    assert!((h.0 - 1.0).abs() < 1e-12 && h.1 >= h.0);
}

#[test]
fn grazing_and_near_parallel_rays() {
    let tri = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    // In the triangle's plane: no hit (det = 0), no NaN.
    let w = Watertight::new(&Ray::new([-1.0, 0.25, 0.0], [1.0, 0.0, 0.0]));
    assert_eq!(w.hit(tri, 0.0, f64::INFINITY), None);
    // Nearly parallel (1e-7 rad) but crossing the interior: the watertight
    // test hits at the right t.
    let eps = 1e-7;
    let org = [-1.0, 0.25, -eps * 1.3];
    let w = Watertight::new(&Ray::new(org, [1.0, 0.0, eps]));
    let (t, _, _) = w.hit(tri, 0.0, f64::INFINITY).expect("near-parallel hit");
    assert!((t - 1.3).abs() < 1e-6, "t = {t}");
    // A box grazed along its face: kept (the far distance is padded).
    let r = Ray::new([-1.0, 1.0, 0.5], [1.0, 0.0, 0.0]);
    assert!(Slab::new(&r).hit(&unit_box(), 0.0, f64::INFINITY).is_some());
}

#[test]
fn degenerate_triangles_never_hit() {
    let w = Watertight::new(&Ray::new([0.5, 0.0, -1.0], [0.0, 0.0, 1.0]));
    for tri in [
        [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]], // collinear
        [[0.5, 0.0, 0.0]; 3],                                // a point
    ] {
        assert_eq!(w.hit(tri, 0.0, f64::INFINITY), None, "{tri:?}");
        assert_eq!(
            moller_trumbore([0.5, 0.0, -1.0], [0.0, 0.0, 1.0], tri, 0.0, f32::INFINITY),
            None
        );
    }
}

#[test]
fn huge_and_tiny_coordinates() {
    for s in [1e30f32, 1e-30] {
        let tri = [[0.0, 0.0, s], [s, 0.0, s], [0.0, s, s]];
        let q = f64::from(s) * 0.25;
        let w = Watertight::new(&Ray::new([q, q, 0.0], [0.0, 0.0, 1.0]));
        let (t, u, v) = w
            .hit(tri, 0.0, f64::INFINITY)
            .unwrap_or_else(|| panic!("scale {s}"));
        assert!((t / f64::from(s) - 1.0).abs() < 1e-6, "scale {s}: t = {t}");
        assert!(
            (u - 0.25).abs() < 1e-6 && (v - 0.25).abs() < 1e-6,
            "scale {s}: {u} {v}"
        );
    }
}

#[test]
fn empty_scene_single_triangle_and_bad_rays() {
    let empty = Mesh::default();
    assert!(Bvh2::build(&empty, &BuildConfig::default())
        .unwrap_err()
        .contains("empty"));
    assert_eq!(
        Reference::brute(&empty).closest(&Ray::new([0.0; 3], [0.0, 0.0, 1.0])),
        None
    );
    let one = Mesh {
        positions: vec![[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]],
        tris: vec![[0, 1, 2]],
    };
    let b = Bvh2::build(&one, &BuildConfig::default()).unwrap();
    let refi = Reference::with_bvh(&one, &b);
    let h = refi
        .closest(&Ray::new([0.2, 0.2, 0.0], [0.0, 0.0, 1.0]))
        .expect("hit");
    assert_eq!((h.t, h.prim), (1.0, 0));
    assert!(
        refi.closest(&Ray::new([0.8, 0.8, 0.0], [0.0, 0.0, 1.0]))
            .is_none(),
        "outside the triangle"
    );
    assert!(
        refi.closest(&Ray::new([0.2, 0.2, 0.0], [0.0, 0.0, -1.0]))
            .is_none(),
        "behind the origin"
    );
    // NaN or zero directions: no hit, no panic.
    assert!(refi
        .closest(&Ray::new([f64::NAN, 0.0, 0.0], [0.0, 0.0, 1.0]))
        .is_none());
    assert!(refi
        .closest(&Ray::new([0.2, 0.2, 0.0], [0.0, 0.0, 0.0]))
        .is_none());
}

#[test]
fn bvh_and_brute_force_agree_closest_and_all() {
    let m = icosphere(2);
    let b = Bvh2::build(&m, &BuildConfig::LARGE_LEAVES).unwrap();
    let (fast, slow) = (Reference::with_bvh(&m, &b), Reference::brute(&m));
    let mut r = Rng::new(9);
    for _ in 0..2000 {
        let org = [
            f64::from(r.range(-2.0, 2.0)),
            f64::from(r.range(-2.0, 2.0)),
            3.0,
        ];
        let dir = [
            f64::from(r.range(-0.5, 0.5)),
            f64::from(r.range(-0.5, 0.5)),
            -1.0,
        ];
        let ray = Ray::new(org, dir);
        assert_eq!(fast.closest(&ray), slow.closest(&ray));
        assert_eq!(fast.all(&ray), slow.all(&ray));
        // Any-hit stops at its first hit and agrees with the closest hit,
        // two-sided and front faces only, over the whole ray and a segment.
        for refi in [&fast, &slow] {
            let front = Reference::with_bvh(&m, &b).front_faces_only();
            let mut seg = ray;
            seg.tmax = f64::from(r.range(0.5, 4.0));
            for q in [&ray, &seg] {
                assert_eq!(refi.any(q), refi.closest(q).is_some());
                assert_eq!(front.any(q), front.closest(q).is_some());
            }
        }
        let all = slow.all(&ray);
        assert!(
            all.len() % 2 == 0 || all.windows(2).any(|w| w[0].t == w[1].t),
            "a closed sphere is entered and left"
        );
    }
}
