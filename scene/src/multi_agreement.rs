//! Hit agreement for multi-hit rays: when an f32 kernel's list of the
//! N_query nearest hits counts as the f64 reference's.
//!
//! A hit is a triangle. Two triangles met at their shared edge are two hits
//! at one t (the reference and Embree report both); a triangle is never
//! reported twice (each is referenced from one leaf). A kernel's list
//! agrees when:
//!
//! 1. it holds at most N_query hits, nearest first, no triangle twice;
//! 2. each is real: the reference hits that triangle at that t (within
//!    1e-4 relative or the triangle's f32 plane tolerance), or misses it by
//!    less than the f32 edge tolerance (`agreement::tri_eps`);
//! 3. nothing is skipped: every reference hit the list does not hold lies
//!    at or beyond the list's last t (within the tolerance) when the list is
//!    full, or grazes an edge within the f32 tolerance (a crack f32
//!    Moller-Trumbore may fall through).
//!
//! So ties (equal t: shared edges, coplanar overlaps) may come in any order
//! and, at the N_query-th place, either tied triangle may be the one kept.

use crate::agreement::{may_skip, near_hit, t_tolerance, F32Test};
use crate::hit::Hit;
use crate::reference::{Ray, RefHit, Reference};

/// Whether `got` (a kernel's hits for `ray`, asked for `n_query`) agrees
/// with `all`, the reference's every hit of the ray (nearest first).
#[must_use]
pub fn list_agrees(
    test: F32Test,
    refi: &Reference,
    ray: &Ray,
    all: &[RefHit],
    n_query: u32,
    got: &[Hit],
) -> bool {
    let close = |a: f64, b: f64, p: u32| {
        (a - b).abs() <= (1e-4 * b.abs().max(1.0)).max(t_tolerance(refi.mesh(), p, ray))
    };
    let mut prims: Vec<u32> = Vec::with_capacity(got.len());
    let mut last = f64::NEG_INFINITY;
    for h in got {
        let (Some(p), t) = (h.prim, f64::from(h.t)) else {
            return false;
        };
        if prims.contains(&p) || t < last {
            return false;
        }
        let real = all.iter().any(|a| a.prim == p && close(t, a.t, p))
            || near_hit(test, refi, ray, p, Some(t));
        if !real {
            return false;
        }
        prims.push(p);
        last = t;
    }
    if got.len() > n_query as usize {
        return false;
    }
    let full = got.len() == n_query as usize;
    all.iter().filter(|a| !prims.contains(&a.prim)).all(|a| {
        (full && (a.t >= last || close(a.t, last, a.prim))) || may_skip(test, refi, ray, a)
    })
}

/// How many rays' lists disagree ([`list_agrees`]); `all[i]` is ray `i`'s
/// every reference hit. The first three are printed with `label`.
#[must_use]
pub fn list_mismatches(
    label: &str,
    refi: &Reference,
    rays: &[Ray],
    all: &[Vec<RefHit>],
    n_query: u32,
    got: &[Vec<Hit>],
) -> usize {
    let test = F32Test::MollerTrumbore;
    let bad: Vec<usize> = (0..rays.len())
        .filter(|&i| !list_agrees(test, refi, &rays[i], &all[i], n_query, &got[i]))
        .collect();
    for &i in bad.iter().take(3) {
        let want: Vec<(f64, u32)> = all[i].iter().map(|a| (a.t, a.prim)).collect();
        let have: Vec<(f32, Option<u32>)> = got[i].iter().map(|h| (h.t, h.prim)).collect();
        eprintln!("{label} N={n_query} ray {i}: kernel {have:?} reference {want:?}");
    }
    bad.len()
}

/// Whether two kernels' lists for one ray (each checked against the
/// reference with [`list_agrees`]) are the same hits: as long, t within 1e-4
/// relative place by place, and the same triangles apart from those tied
/// with the last t (either tied triangle may take the N_query-th place).
#[must_use]
pub fn same_hits(a: &[Hit], b: &[Hit]) -> bool {
    let close = |x: f32, y: f32| (x - y).abs() <= 1e-4 * y.abs().max(1.0);
    if a.len() != b.len() || a.iter().zip(b).any(|(x, y)| !close(x.t, y.t)) {
        return false;
    }
    let Some(last) = a.last().map(|h| h.t) else {
        return true;
    };
    let before = |l: &[Hit]| {
        let mut p: Vec<Option<u32>> = l
            .iter()
            .filter(|h| !close(h.t, last))
            .map(|h| h.prim)
            .collect();
        p.sort_unstable();
        p
    };
    before(a) == before(b)
}

/// [`same_hits`], or lists of two kernels that test triangles differently
/// (an f32 kernel and a watertight one) differing only where one fell
/// through a crack: every triangle only one list holds is a reference hit
/// grazing an edge within the f32 tolerance, a triangle the reference
/// misses by less than that tolerance, or that list's last hit (the place a
/// grazing hit took in the other).
#[must_use]
pub fn same_up_to_cracks(
    test: F32Test,
    refi: &Reference,
    ray: &Ray,
    all: &[RefHit],
    a: &[Hit],
    b: &[Hit],
) -> bool {
    if same_hits(a, b) {
        return true;
    }
    let only = |x: &[Hit], y: &[Hit]| {
        let last = x.last().map_or(f32::INFINITY, |h| h.t);
        x.iter()
            .filter(|h| !y.iter().any(|g| g.prim == h.prim))
            .all(|h| {
                (h.t - last).abs() <= 1e-4 * last.abs().max(1.0)
                    || all
                        .iter()
                        .any(|r| Some(r.prim) == h.prim && may_skip(test, refi, ray, r))
                    || h.prim.is_some_and(|p| {
                        !all.iter().any(|r| r.prim == p)
                            && near_hit(test, refi, ray, p, Some(f64::from(h.t)))
                    })
            })
    };
    only(a, b) && only(b, a)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::Mesh;

    /// Two triangles sharing the diagonal of the unit square at z = 0, and a
    /// third square's triangle at z = -1.
    fn quads() -> Mesh {
        let positions = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, -1.0],
            [1.0, 0.0, -1.0],
            [1.0, 1.0, -1.0],
        ];
        Mesh {
            positions,
            tris: vec![[0, 1, 2], [0, 2, 3], [4, 5, 6]],
        }
    }

    fn hit(t: f32, p: u32) -> Hit {
        Hit { t, prim: Some(p) }
    }

    #[test]
    fn a_shared_edge_is_two_hits_in_either_order_and_either_one_at_the_cut() {
        let mesh = quads();
        let refi = Reference::brute(&mesh);
        // Through the diagonal (0.5, 0.5): both triangles at t = 1, then the
        // lower square's triangle 2 at t = 2 (x >= y on it).
        let ray = Ray::new([0.6, 0.6, 1.0], [0.0, 0.0, -1.0]);
        let all = refi.all(&ray);
        assert_eq!(all.iter().map(|a| a.prim).collect::<Vec<_>>(), [0, 1, 2]);
        let t = F32Test::MollerTrumbore;
        let ok = |n, got: &[Hit]| list_agrees(t, &refi, &ray, &all, n, got);
        assert!(ok(3, &[hit(1.0, 0), hit(1.0, 1), hit(2.0, 2)]));
        assert!(ok(3, &[hit(1.0, 1), hit(1.0, 0), hit(2.0, 2)]));
        assert!(ok(1, &[hit(1.0, 1)]) && ok(1, &[hit(1.0, 0)]));
        assert!(ok(2, &[hit(1.0, 1), hit(1.0, 0)]));
        // Not: the same triangle twice, too many, out of order.
        assert!(!ok(2, &[hit(1.0, 0), hit(1.0, 0)]));
        assert!(!ok(1, &[hit(1.0, 0), hit(1.0, 1)]));
        assert!(!ok(3, &[hit(2.0, 2), hit(1.0, 0), hit(1.0, 1)]));
        // On the edge either triangle may fall through the f32 crack.
        assert!(ok(2, &[hit(1.0, 0), hit(2.0, 2)]));
    }

    #[test]
    fn same_hits_allows_ties_in_any_order_and_at_the_cut() {
        let (a, b) = (
            [hit(1.0, 0), hit(1.0, 1), hit(2.0, 2)],
            [hit(1.0, 1), hit(1.0, 0), hit(2.0, 2)],
        );
        assert!(same_hits(&a, &b));
        assert!(same_hits(&[hit(1.0, 0)], &[hit(1.0, 1)]), "tied at the cut");
        assert!(!same_hits(&a, &a[..2]));
        assert!(!same_hits(
            &[hit(1.0, 0), hit(2.0, 2)],
            &[hit(1.0, 1), hit(2.0, 2)]
        ));
        assert!(!same_hits(&[hit(1.0, 0)], &[hit(1.5, 0)]));
        assert!(same_hits(&[], &[]));
    }

    #[test]
    fn a_crack_may_separate_an_f32_kernel_from_a_watertight_one() {
        let mesh = quads();
        let refi = Reference::brute(&mesh);
        let t = F32Test::MollerTrumbore;
        // Down the shared edge: one kernel may drop triangle 1 (grazing).
        let ray = Ray::new([0.6, 0.6, 1.0], [0.0, 0.0, -1.0]);
        let all = refi.all(&ray);
        let full = [hit(1.0, 0), hit(1.0, 1), hit(2.0, 2)];
        let same = |a: &[Hit], b: &[Hit]| same_up_to_cracks(t, &refi, &ray, &all, a, b);
        assert!(same(&full, &[hit(1.0, 0), hit(2.0, 2)]));
        // Away from edges nothing may differ.
        let ray = Ray::new([0.7, 0.2, 1.0], [0.0, 0.0, -1.0]);
        let all = refi.all(&ray);
        let same = |a: &[Hit], b: &[Hit]| same_up_to_cracks(t, &refi, &ray, &all, a, b);
        assert!(!same(&[hit(1.0, 0), hit(2.0, 2)], &[hit(2.0, 2)]));
        assert!(same(
            &[hit(1.0, 0), hit(2.0, 2)],
            &[hit(1.0, 0), hit(2.0, 2)]
        ));
    }

    #[test]
    fn a_hit_away_from_edges_may_not_be_skipped_or_moved() {
        let mesh = quads();
        let refi = Reference::brute(&mesh);
        let ray = Ray::new([0.7, 0.2, 1.0], [0.0, 0.0, -1.0]);
        let all = refi.all(&ray);
        assert_eq!(all.iter().map(|a| a.prim).collect::<Vec<_>>(), [0, 2]);
        let t = F32Test::MollerTrumbore;
        let ok = |n, got: &[Hit]| list_agrees(t, &refi, &ray, &all, n, got);
        assert!(ok(2, &[hit(1.0, 0), hit(2.0, 2)]) && ok(8, &[hit(1.0, 0), hit(2.0, 2)]));
        assert!(ok(1, &[hit(1.0, 0)]));
        assert!(!ok(1, &[hit(2.0, 2)]), "skipped the nearer");
        assert!(!ok(2, &[hit(1.0, 0)]), "short of N_query with a hit left");
        assert!(!ok(1, &[hit(1.5, 0)]), "a wrong t");
        assert!(
            !ok(2, &[hit(1.0, 0), hit(2.0, 1)]),
            "a triangle the ray misses"
        );
        assert!(!ok(1, &[Hit::miss(1.0)]));
    }
}
