//! Hit agreement: when an f32 kernel's answer counts as the f64 reference's.
//! Every paper checks its kernels with these rules.

use crate::hit::Hit;
use crate::mesh::Mesh;
use crate::reference::{Ray, RefHit, Reference, TriGeom};
use crate::workload::RayStream;
use glam::DVec3;
use rayon::prelude::*;

/// Least barycentric distance to an edge within which an f32 kernel may
/// miss a triangle the f64 watertight reference hits (or hit one it misses).
pub const EDGE_EPS: f64 = 1e-5;

/// The barycentric tolerance of f32 Moller-Trumbore on triangle `prim` for a
/// ray from `org`: [`EDGE_EPS`], or more for small or thin triangles far from
/// the origin, where the f32 rounding of the edges and of the origin offset
/// (about 2^-24 of the largest coordinate each) is a larger fraction of the
/// triangle's least altitude.
#[must_use]
pub fn tri_eps(mesh: &Mesh, prim: u32, org: [f64; 3]) -> f64 {
    tri_eps_for(F32Test::MollerTrumbore, mesh, prim, org, [0.0; 3])
}

/// Which f32 ray-triangle test a kernel runs: it sets how far from an edge
/// the kernel may disagree with the f64 reference.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum F32Test {
    /// Moller-Trumbore relative to v0 (single, packet, DRS kernels).
    MollerTrumbore,
    /// Edge normals of origin-relative vertices (the MFT paper's common-origin
    /// Pluecker test): cross products of two long, nearly parallel vectors,
    /// so the error grows with the squared distance over the triangle's area.
    Pluecker,
}

/// [`tri_eps`] for a test, and (Pluecker) a ray direction `dir`.
#[must_use]
pub fn tri_eps_for(test: F32Test, mesh: &Mesh, prim: u32, org: [f64; 3], dir: [f64; 3]) -> f64 {
    let g = TriGeom::of(mesh, prim);
    let longest =
        g.e1.length()
            .max(g.e2.length())
            .max((g.v[2] - g.v[1]).length());
    let altitude = g.n.length() / longest.max(1e-300);
    let reach =
        g.v.iter()
            .map(|v| v.abs().max_element())
            .fold(DVec3::from(org).abs().max_element(), f64::max);
    let f32_err = 16.0 * f64::from(f32::EPSILON) * reach / altitude.max(1e-300);
    let eps = EDGE_EPS.max(f32_err);
    let eps = if test == F32Test::Pluecker {
        // |d . E| carries about eps * |d| * reach^2 of rounding; the signal
        // is lambda * |d . n| (n = e1 x e2).
        let d = DVec3::from(dir);
        let r = reach.max((g.v[0] - DVec3::from(org)).length());
        let dn = g.n.dot(d).abs();
        eps.max(4.0 * f64::from(f32::EPSILON) * d.length() * r * r / dn.max(1e-300))
    } else {
        eps
    };
    eps.min(0.5)
}

/// How far an f32 kernel's t on triangle `prim` may stray from the exact
/// one: the triangle's plane as f32 edges define it tilts by about
/// 4 ulp x longest / altitude (the normal is a cross product of nearly
/// parallel edges on a sliver), which moves a point up to a longest edge
/// away by that much along the normal, plus the rounding of the origin
/// offset (4 ulp of the largest coordinate); seen along the ray, over its
/// incidence |d . n| / |n|. Negligible for most triangles; on a long sliver
/// far from the origin it is not (a studio's 45 m cove strip: 1e-4 at t =
/// 0.46, where 1e-4 relative allows 5e-5).
pub(crate) fn t_tolerance(mesh: &Mesh, prim: u32, ray: &Ray) -> f64 {
    let g = TriGeom::of(mesh, prim);
    let longest =
        g.e1.length()
            .max(g.e2.length())
            .max((g.v[2] - g.v[1]).length());
    let altitude = g.n.length() / longest.max(1e-300);
    let reach =
        g.v.iter()
            .map(|v| v.abs().max_element())
            .fold(DVec3::from(ray.org).abs().max_element(), f64::max);
    let d = DVec3::from(ray.dir);
    let incidence = g.n.dot(d).abs() / g.n.length().max(1e-300);
    let across = longest * longest / altitude.max(1e-300) + reach;
    4.0 * f64::from(f32::EPSILON) * across / incidence.max(1e-3 * d.length()).max(1e-300)
}

/// Whether the reference hit `h` of a ray from `org` lies within the f32
/// tolerance of an edge of its triangle.
fn grazing(test: F32Test, mesh: &Mesh, ray: &Ray, h: &RefHit) -> bool {
    h.u.min(h.v).min(1.0 - h.u - h.v) <= tri_eps_for(test, mesh, h.prim, ray.org, ray.dir)
}

/// [`grazing`], or (one-sided reference) met nearly edge-on, where a
/// back-face culling kernel may drop it.
pub(crate) fn may_skip(test: F32Test, refi: &Reference, ray: &Ray, h: &RefHit) -> bool {
    grazing(test, refi.mesh(), ray, h)
        || (refi.is_one_sided() && refi.edge_on(h.prim, ray.dir))
        || (test == F32Test::Pluecker && pluecker_unreliable(refi.mesh(), h.prim, ray))
}

/// Whether the MFT kernel's common-origin test cannot resolve `ray` against
/// triangle `prim`: |d . n| within 8 ulp x |v0 - o|^2 x |d| (twice the
/// noise floor the kernel rejects below).
fn pluecker_unreliable(mesh: &Mesh, prim: u32, ray: &Ray) -> bool {
    let g = TriGeom::of(mesh, prim);
    let (o, d) = (DVec3::from(ray.org), DVec3::from(ray.dir));
    d.dot(g.n).abs() <= 8.0 * f64::from(f32::EPSILON) * (g.v[0] - o).length_squared() * d.length()
}

/// Whether triangle `prim` is hit at about `t` (`None`: anywhere in
/// (0, tmax]) by `ray` in f64 with its edges widened by the f32 tolerance (a
/// hit the reference calls a near miss).
pub(crate) fn near_hit(
    test: F32Test,
    refi: &Reference,
    ray: &Ray,
    prim: u32,
    t: Option<f64>,
) -> bool {
    // One-sided: a back face counts only when nearly edge-on, where the
    // kernel's f32 orientation test may go either way.
    if !refi.faces(prim, ray.dir) && !refi.edge_on(prim, ray.dir) {
        return false;
    }
    // f64 Moller-Trumbore barycentrics, edges widened by the tolerance.
    let g = TriGeom::of(refi.mesh(), prim);
    let (o, d) = (DVec3::from(ray.org), DVec3::from(ray.dir));
    let p = d.cross(g.e2);
    let det = g.e1.dot(p);
    if det == 0.0 || !det.is_finite() {
        return false;
    }
    let s = o - g.v[0];
    let u = s.dot(p) / det;
    let q = s.cross(g.e1);
    let v = d.dot(q) / det;
    let th = g.e2.dot(q) / det;
    let eps = tri_eps_for(test, refi.mesh(), prim, ray.org, ray.dir);
    let at_t = match t {
        Some(t) => {
            (th - t).abs() <= (1e-4 * t.abs().max(1.0)).max(t_tolerance(refi.mesh(), prim, ray))
        }
        None => th > 0.0 && th <= ray.tmax * (1.0 + 1e-4),
    };
    u >= -eps && v >= -eps && u + v <= 1.0 + eps && at_t
}

/// Rays whose kernel hit differs from the reference's closest hit. Agreement:
/// both miss; or both hit with t within 1e-4 relative and the same triangle —
/// or, at a shared edge where two triangles tie, a triangle the reference also
/// hits at that t, or one it misses by less than the f32 tolerance
/// ([`tri_eps`]); or the reference's hit lies within the tolerance of an
/// edge (a crack for f32 Moller-Trumbore) and the kernel returns the next hit
/// the reference finds behind it (or a miss when every later hit grazes too).
pub fn mismatches(
    label: &str,
    refi: &Reference,
    org: &[[f32; 3]],
    dir: &[[f32; 3]],
    out: &[Hit],
) -> usize {
    mismatches_for(F32Test::MollerTrumbore, label, refi, org, dir, out)
}

/// [`mismatches`] with the tolerance of triangle test `test`.
pub fn mismatches_for(
    test: F32Test,
    label: &str,
    refi: &Reference,
    org: &[[f32; 3]],
    dir: &[[f32; 3]],
    out: &[Hit],
) -> usize {
    // Rays are checked in parallel; the first few mismatches are printed in order.
    let ok: Vec<bool> = (0..org.len())
        .into_par_iter()
        .map(|i| closest_agrees(test, refi, org[i], dir[i], out[i]))
        .collect();
    report_bad(&ok, |i| {
        let ray = Ray::new(org[i].map(f64::from), dir[i].map(f64::from));
        let Hit { t, prim } = out[i];
        eprintln!(
            "{label} ray {i}: kernel ({t}, {prim:?}) reference {:?}",
            refi.closest(&ray)
        );
    })
}

/// Whether a shadow ray's answer `h` agrees with the reference, given the
/// reference's any-hit `want` over the ray's interval.
fn shadow_agrees_with(test: F32Test, refi: &Reference, ray: &Ray, want: bool, h: Hit) -> bool {
    let got = h.is_hit();
    want == got
        || (want && refi.all(ray).iter().all(|a| may_skip(test, refi, ray, a)))
        || (got && {
            let mut longer = *ray;
            longer.tmax *= 1.0 + 1e-4;
            refi.any(&longer) || h.prim.is_some_and(|p| near_hit(test, refi, ray, p, None))
        })
}

/// The reference's answer for each ray of a stream, computed once and
/// shared by every method checked on the stream (a report's methods trace
/// the same rays: asking the reference again per method cost more than the
/// checks themselves).
#[derive(Clone, Debug)]
pub enum Expected {
    /// Closest hits of a closest-hit stream.
    Closest(Vec<Option<RefHit>>),
    /// Any-hit answers of a shadow stream.
    Occluded(Vec<bool>),
}

impl Expected {
    /// The reference's answers for `rays`, in parallel (call it outside
    /// tasks that run methods: a waiting thread may steal one).
    #[must_use]
    pub fn of(refi: &Reference, rays: &RayStream) -> Expected {
        let n = rays.len();
        if rays.is_shadow() {
            Expected::Occluded(
                (0..n)
                    .into_par_iter()
                    .map(|i| refi.any(&rays.ray(i)))
                    .collect(),
            )
        } else {
            let closest = (0..n)
                .into_par_iter()
                .map(|i| refi.closest(&closest_ray(rays, i)))
                .collect();
            Expected::Closest(closest)
        }
    }
}

/// Ray `i` of a closest-hit stream as the checks see it: over (0, inf].
fn closest_ray(rays: &RayStream, i: usize) -> Ray {
    Ray::new(rays.org[i].map(f64::from), rays.dir[i].map(f64::from))
}

/// [`stream_mismatches`](crate::agreement) against answers computed once
/// ([`Expected::of`] on the same stream), one ray after another: for the
/// host thread that runs one method's units.
#[must_use]
pub fn mismatches_expected(
    test: F32Test,
    label: &str,
    refi: &Reference,
    rays: &RayStream,
    want: &Expected,
    out: &[Hit],
) -> usize {
    let ok: Vec<bool> = match want {
        Expected::Closest(w) => (0..rays.len())
            .map(|i| closest_agrees_with(test, refi, &closest_ray(rays, i), w[i], out[i]))
            .collect(),
        Expected::Occluded(w) => (0..rays.len())
            .map(|i| shadow_agrees_with(test, refi, &rays.ray(i), w[i], out[i]))
            .collect(),
    };
    report_bad(&ok, |i| {
        let (k, r) = (out[i], rays.ray(i));
        eprintln!(
            "{label} ray {i}: kernel ({}, {:?}) reference {:?}",
            k.t,
            k.prim,
            match want {
                Expected::Closest(w) => format!("{:?}", w[i]),
                Expected::Occluded(_) => format!("occluded {}", refi.any(&r)),
            }
        );
    })
}

/// How many of `ok` are false; `say` prints the first three, in order.
fn report_bad(ok: &[bool], say: impl Fn(usize)) -> usize {
    let bad: Vec<usize> = (0..ok.len()).filter(|&i| !ok[i]).collect();
    for &i in bad.iter().take(3) {
        say(i);
    }
    bad.len()
}

/// Whether a kernel's closest hit `out` of a ray agrees with the reference's.
fn closest_agrees(test: F32Test, refi: &Reference, org: [f32; 3], dir: [f32; 3], out: Hit) -> bool {
    let ray = Ray::new(org.map(f64::from), dir.map(f64::from));
    closest_agrees_with(test, refi, &ray, refi.closest(&ray), out)
}

/// [`closest_agrees`] given the reference's closest hit `want` of `ray`.
fn closest_agrees_with(
    test: F32Test,
    refi: &Reference,
    ray: &Ray,
    want: Option<RefHit>,
    out: Hit,
) -> bool {
    let ray = *ray;
    let Hit { t, prim } = out;
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-4 * b.abs().max(1.0);
    let kt = prim.map_or(f64::INFINITY, |_| f64::from(t));
    // The common case: the reference's own hit (what `exact` accepts), at
    // its t within the f32 tolerance of that triangle's plane.
    let same_plane = |h: &RefHit| (kt - h.t).abs() <= t_tolerance(refi.mesh(), h.prim, &ray);
    if want.is_some_and(|h| prim == Some(h.prim) && (close(kt, h.t) || same_plane(&h))) {
        return true;
    }
    let near = |p: u32| near_hit(test, refi, &ray, p, Some(kt));
    // The kernel's hit is real: the reference hits that triangle there,
    // or misses it by less than the f32 tolerance.
    let real = |all: &[RefHit]| {
        prim.is_none_or(|p| all.iter().any(|a| a.prim == p && close(a.t, kt)) || near(p))
    };
    match want {
        None => prim.is_none_or(near),
        Some(h) => {
            let all = refi.all(&ray);
            let exact = prim.is_some() && close(kt, h.t) && real(&all);
            // f32 Moller-Trumbore is not watertight: a hit near an edge
            // may fall into the crack between two triangles; then the
            // kernel sees the next surface behind it.
            let skipped_graze = all
                .iter()
                .filter(|a| prim.is_none() || (a.t < kt && !close(a.t, kt)))
                .all(|a| may_skip(test, refi, &ray, a));
            // The mirror case: the kernel hits, in front of the reference's
            // hit, a triangle the reference misses by less than the tolerance.
            let near_front = prim.is_some_and(|p| kt < h.t && near(p));
            exact || near_front || (may_skip(test, refi, &ray, &h) && skipped_graze && real(&all))
        }
    }
}

/// Shadow rays whose occlusion (kernel: prim >= 0) differs from the
/// reference's any-hit over (0, tmax]. Allowed: a miss where every blocker
/// the reference finds grazes an edge within [`tri_eps`] (an f32 crack),
/// and a hit within 1e-4 relative of `tmax` (the light sample's end).
#[must_use]
pub fn shadow_mismatches(label: &str, refi: &Reference, rays: &RayStream, out: &[Hit]) -> usize {
    shadow_mismatches_for(F32Test::MollerTrumbore, label, refi, rays, out)
}

/// [`shadow_mismatches`] with the tolerance of triangle test `test`.
#[must_use]
pub fn shadow_mismatches_for(
    test: F32Test,
    label: &str,
    refi: &Reference,
    rays: &RayStream,
    out: &[Hit],
) -> usize {
    let ok: Vec<bool> = out
        .par_iter()
        .enumerate()
        .map(|(i, h)| {
            let ray = rays.ray(i);
            shadow_agrees_with(test, refi, &ray, refi.any(&ray), *h)
        })
        .collect();
    report_bad(&ok, |i| {
        let ray = rays.ray(i);
        eprintln!(
            "{label} shadow ray {i}: kernel occluded {}, reference {}",
            out[i].is_hit(),
            refi.any(&ray)
        );
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::{BuildConfig, Bvh2};

    /// Two triangles sharing the edge x = 0 at z = 0, a wall behind at z = -1.
    fn crack_scene() -> Mesh {
        let obj = b"v 0 -1 0\nv 0 1 0\nv -1 0 0\nv 1 0 0\n\
v -5 -5 -1\nv 5 -5 -1\nv 0 5 -1\n\
f 1 2 3\nf 1 4 2\nf 5 6 7\n";
        crate::mesh::parse_obj(obj, "crack.obj").unwrap()
    }

    #[test]
    fn a_crack_at_a_shared_edge_may_show_the_surface_behind_it_and_nothing_else() {
        let mesh = crack_scene();
        let b2 = Bvh2::build(&mesh, &BuildConfig::default()).unwrap();
        let refi = Reference::with_bvh(&mesh, &b2);
        let down = [[0.0, 0.0, -1.0]];
        let on_edge = [[0.0, 0.2, 1.0]];
        let inside = [[-0.3, 0.0, 1.0]];
        let check = |org: &[[f32; 3]; 1], (t, p): (f32, i32)| {
            mismatches("t", &refi, org, &down, &[Hit::from_record(t, p as u32)])
        };
        // On the edge: either triangle at t = 1, or the wall behind the crack.
        assert_eq!(check(&on_edge, (1.0, 0)), 0);
        assert_eq!(check(&on_edge, (1.0, 1)), 0);
        assert_eq!(check(&on_edge, (2.0, 2)), 0);
        // Not a miss: the wall is a real hit behind the crack.
        assert_eq!(check(&on_edge, (f32::INFINITY, -1)), 1);
        // Away from an edge nothing is skipped.
        assert_eq!(check(&inside, (1.0, 0)), 0);
        assert_eq!(check(&inside, (2.0, 2)), 1);
        assert_eq!(check(&inside, (1.0, 1)), 1);
        // A t off by more than 1e-4 on an ordinary triangle is wrong.
        assert_eq!(check(&inside, (1.0003, 0)), 1);
    }

    #[test]
    fn a_long_sliver_far_from_the_origin_allows_its_f32_plane_error_in_t() {
        // The BMW studio's cove strip (45 m long, 0.49 m altitude) and a
        // glossy ray from the car that grazes it (|d . n| = 0.0115) at
        // t = 0.4584 (f64); the MBVH RS kernel's f32 test said 0.45833334.
        // The f32 plane's tilt allows about 0.17 in t here.
        let tri = [
            [25.51033, -0.325713, 11.58034],
            [4.597421, -0.701062, -27.95673],
            [4.870702, -0.325713, -28.09888],
        ];
        let mesh = Mesh {
            positions: tri.to_vec(),
            tris: vec![[0, 1, 2]],
        };
        let b2 = Bvh2::build(&mesh, &BuildConfig::default()).unwrap();
        let refi = Reference::with_bvh(&mesh, &b2);
        let org = [[11.14121f32, -0.7160538, -15.334984]];
        let dir = [[0.38363776f32, 0.7210204, -0.57701963]];
        let want = refi
            .closest(&Ray::new(org[0].map(f64::from), dir[0].map(f64::from)))
            .unwrap();
        assert!((want.t - 0.458436).abs() < 1e-5, "{want:?}");
        let check = |t: f32| mismatches("t", &refi, &org, &dir, &[Hit::from_record(t, 0)]);
        assert_eq!(check(0.45833334), 0, "within the sliver's f32 plane error");
        assert_eq!(check(0.7), 1, "but not anywhere");
    }
}
