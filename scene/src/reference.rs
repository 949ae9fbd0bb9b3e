//! The ground truth every traversal kernel is tested against: scalar, f64,
//! brute force or over a BVH2; closest hit, any hit, all hits sorted by t.
//!
//! - Triangles: the watertight test of Woop, Benthin and Wald (JCGT 2013):
//!   shear the translated vertices into ray space, edge functions decide
//!   inside; no ray through a shared edge or vertex of a closed mesh leaks.
//!   Triangles are double-sided. A ray through a shared edge may report both
//!   triangles (all-hits lists both, as Embree #188 describes).
//! - Boxes: a closed slab test. A zero direction component (either sign)
//!   never divides: the ray is inside that slab iff its origin is (no NaN from
//!   0 * inf). The far distance is padded by 2 ulp (Ize 2013), so a ray grazing
//!   a face is kept.
//! - [`moller_trumbore`]: the kernels' usual f32 test, with its known failure
//!   cases: it is not watertight (rays through shared edges and vertices can
//!   miss both triangles), and near-parallel rays lose precision in `det`.

use crate::bvh::{Aabb, Bvh2, Node};
use crate::mesh::Mesh;

/// A ray in f64.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Origin.
    pub org: [f64; 3],
    /// Direction (need not be normalised; t is in its units).
    pub dir: [f64; 3],
    /// Hits need t > tmin.
    pub tmin: f64,
    /// Hits need t <= tmax.
    pub tmax: f64,
}

impl Ray {
    /// A ray over (0, inf].
    #[must_use]
    pub fn new(org: [f64; 3], dir: [f64; 3]) -> Ray {
        Ray {
            org,
            dir,
            tmin: 0.0,
            tmax: f64::INFINITY,
        }
    }
}

/// A hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RefHit {
    /// Distance along the ray.
    pub t: f64,
    /// Barycentric u (weight of the second vertex).
    pub u: f64,
    /// Barycentric v (weight of the third vertex).
    pub v: f64,
    /// Triangle index.
    pub prim: u32,
}

/// Per-ray constants of the watertight test.
#[derive(Clone, Copy, Debug)]
pub struct Watertight {
    k: [usize; 3],
    s: [f64; 3],
    org: [f64; 3],
}

impl Watertight {
    /// Prepare a ray (its direction must not be zero).
    #[must_use]
    pub fn new(r: &Ray) -> Watertight {
        let d = r.dir;
        let kz = (0..3)
            .max_by(|&a, &b| d[a].abs().total_cmp(&d[b].abs()))
            .expect("3 axes");
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        if d[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        Watertight {
            k: [kx, ky, kz],
            s: [d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]],
            org: r.org,
        }
    }

    /// Intersect triangle (a, b, c): (t, u, v) with t in (tmin, tmax].
    #[must_use]
    pub fn hit(&self, tri: [[f32; 3]; 3], tmin: f64, tmax: f64) -> Option<(f64, f64, f64)> {
        let [kx, ky, kz] = self.k;
        let rel = |p: [f32; 3]| {
            [
                f64::from(p[0]) - self.org[0],
                f64::from(p[1]) - self.org[1],
                f64::from(p[2]) - self.org[2],
            ]
        };
        let (a, b, c) = (rel(tri[0]), rel(tri[1]), rel(tri[2]));
        let sh = |p: [f64; 3]| (p[kx] - self.s[0] * p[kz], p[ky] - self.s[1] * p[kz]);
        let ((ax, ay), (bx, by), (cx, cy)) = (sh(a), sh(b), sh(c));
        let u = cx * by - cy * bx;
        let v = ax * cy - ay * cx;
        let w = bx * ay - by * ax;
        if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
            return None;
        }
        let det = u + v + w;
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let (az, bz, cz) = (self.s[2] * a[kz], self.s[2] * b[kz], self.s[2] * c[kz]);
        let t = (u * az + v * bz + w * cz) / det;
        if !(t > tmin && t <= tmax) {
            return None;
        }
        Some((t, v / det, w / det))
    }
}

/// Per-ray constants of the slab test.
#[derive(Clone, Copy, Debug)]
pub struct Slab {
    org: [f64; 3],
    inv: [f64; 3],
    zero: [bool; 3],
}

impl Slab {
    /// Prepare a ray.
    #[must_use]
    pub fn new(r: &Ray) -> Slab {
        Slab {
            org: r.org,
            inv: r.dir.map(|d| if d == 0.0 { 0.0 } else { 1.0 / d }),
            zero: r.dir.map(|d| d == 0.0),
        }
    }

    /// The (near, far) overlap of the ray's [tmin, tmax] with a closed box.
    #[must_use]
    pub fn hit(&self, b: &Aabb, tmin: f64, tmax: f64) -> Option<(f64, f64)> {
        let mut near = tmin;
        let mut far = tmax;
        for a in 0..3 {
            let (lo, hi) = (f64::from(b.lo[a]), f64::from(b.hi[a]));
            if self.zero[a] {
                if self.org[a] < lo || self.org[a] > hi {
                    return None;
                }
                continue;
            }
            let t0 = (lo - self.org[a]) * self.inv[a];
            let t1 = (hi - self.org[a]) * self.inv[a];
            let (tn, tf) = if t0 <= t1 { (t0, t1) } else { (t1, t0) };
            near = near.max(tn);
            far = far.min(tf * (1.0 + 4.0 * f64::EPSILON));
            if near > far {
                return None;
            }
        }
        Some((near, far))
    }
}

/// Möller-Trumbore in f32 (double-sided): t in (tmin, tmax], or None.
#[must_use]
pub fn moller_trumbore(
    org: [f32; 3],
    dir: [f32; 3],
    tri: [[f32; 3]; 3],
    tmin: f32,
    tmax: f32,
) -> Option<f32> {
    let sub = |a: [f32; 3], b: [f32; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let cross = |a: [f32; 3], b: [f32; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let dot = |a: [f32; 3], b: [f32; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let e1 = sub(tri[1], tri[0]);
    let e2 = sub(tri[2], tri[0]);
    let p = cross(dir, e2);
    let det = dot(e1, p);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let inv = 1.0 / det;
    let s = sub(org, tri[0]);
    let u = dot(s, p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = cross(s, e1);
    let v = dot(dir, q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = dot(e2, q) * inv;
    (t > tmin && t <= tmax).then_some(t)
}

/// A triangle's vertices, edges and (unnormalised) normal in f64, for the
/// agreement rules' geometric tolerances.
#[derive(Clone, Copy, Debug)]
pub struct TriGeom {
    /// Vertices.
    pub v: [glam::DVec3; 3],
    /// `v1 - v0`.
    pub e1: glam::DVec3,
    /// `v2 - v0`.
    pub e2: glam::DVec3,
    /// `e1 x e2` (twice the area, along the winding's normal).
    pub n: glam::DVec3,
}

impl TriGeom {
    /// Triangle `p` of `mesh`.
    #[must_use]
    pub fn of(mesh: &Mesh, p: u32) -> TriGeom {
        let v = mesh
            .tri(p as usize)
            .map(|x| glam::DVec3::from(x.map(f64::from)));
        let (e1, e2) = (v[1] - v[0], v[2] - v[0]);
        TriGeom {
            v,
            e1,
            e2,
            n: e1.cross(e2),
        }
    }
}

/// The reference intersector over a mesh (and, for speed, a BVH2 of it).
pub struct Reference<'a> {
    mesh: &'a Mesh,
    bvh: Option<&'a Bvh2>,
    /// Front faces only: a triangle counts only when the ray meets the side
    /// its winding's normal `(v1 - v0) x (v2 - v0)` points to (`n . dir < 0`),
    /// as kernels with back-face culling see it (the MFT paper's kernels).
    one_sided: bool,
}

impl<'a> Reference<'a> {
    /// The mesh.
    #[must_use]
    pub fn mesh(&self) -> &'a Mesh {
        self.mesh
    }

    /// Brute force over every triangle (small scenes, and the check of the BVH path).
    #[must_use]
    pub fn brute(mesh: &'a Mesh) -> Reference<'a> {
        Reference {
            mesh,
            bvh: None,
            one_sided: false,
        }
    }
    /// Over a BVH2 of `mesh`.
    #[must_use]
    pub fn with_bvh(mesh: &'a Mesh, bvh: &'a Bvh2) -> Reference<'a> {
        Reference {
            mesh,
            bvh: Some(bvh),
            one_sided: false,
        }
    }

    /// The same reference seeing front faces only (back-face culling).
    #[must_use]
    pub fn front_faces_only(mut self) -> Reference<'a> {
        self.one_sided = true;
        self
    }

    /// Whether this reference sees front faces only.
    #[must_use]
    pub fn is_one_sided(&self) -> bool {
        self.one_sided
    }

    /// Whether `dir` meets triangle `p` nearly edge-on (|cos| < 1e-3), where
    /// f32 kernels may decide its orientation either way.
    #[must_use]
    pub fn edge_on(&self, p: u32, dir: [f64; 3]) -> bool {
        let g = TriGeom::of(self.mesh, p);
        let d = glam::DVec3::from(dir);
        g.n.dot(d).abs() <= 1e-3 * g.n.length() * d.length()
    }

    /// Whether triangle `p` counts for a ray along `dir` (always, unless
    /// [`Reference::front_faces_only`]).
    #[must_use]
    pub fn faces(&self, p: u32, dir: [f64; 3]) -> bool {
        !self.one_sided || TriGeom::of(self.mesh, p).n.dot(glam::DVec3::from(dir)) < 0.0
    }

    /// Visit candidate triangles whose boxes the ray overlaps within (tmin, tmax()).
    fn visit(&self, r: &Ray, mut f: impl FnMut(u32) -> Option<f64>) {
        let Some(bvh) = self.bvh else {
            for p in 0..self.mesh.len() as u32 {
                f(p);
            }
            return;
        };
        let slab = Slab::new(r);
        let mut tmax = r.tmax;
        // (node, the near end of its box's overlap with the ray when pushed)
        let mut stack: Vec<(u32, f64)> = Vec::with_capacity(64);
        if let Some((near, _)) = slab.hit(bvh.nodes[0].bounds(), r.tmin, tmax) {
            stack.push((0, near));
        }
        while let Some((n, near)) = stack.pop() {
            // The box again against the tmax a hit may have shrunk since.
            if near > tmax {
                continue;
            }
            match bvh.nodes[n as usize] {
                Node::Inner { left, right, .. } => {
                    // Nearer child first: a closest hit found early culls
                    // the rest. The answer does not depend on the order
                    // (every triangle a box does not cull is tested), only
                    // the work does.
                    let at = |c: u32| {
                        slab.hit(bvh.nodes[c as usize].bounds(), r.tmin, tmax)
                            .map(|h| (c, h.0))
                    };
                    match (at(left), at(right)) {
                        (Some(l), Some(rt)) if rt.1 < l.1 => stack.extend([l, rt]),
                        (Some(l), Some(rt)) => stack.extend([rt, l]),
                        (Some(l), None) => stack.push(l),
                        (None, Some(rt)) => stack.push(rt),
                        (None, None) => {}
                    }
                }
                Node::Leaf { first, count, .. } => {
                    for &p in &bvh.prims[first as usize..(first + count) as usize] {
                        if let Some(t) = f(p) {
                            tmax = tmax.min(t);
                        }
                    }
                }
            }
        }
    }

    /// The closest hit (ties: the lowest triangle index).
    #[must_use]
    pub fn closest(&self, r: &Ray) -> Option<RefHit> {
        if r.dir == [0.0; 3] || r.org.iter().chain(&r.dir).any(|x| !x.is_finite()) {
            return None;
        }
        let w = Watertight::new(r);
        let mut best: Option<RefHit> = None;
        self.visit(r, |p| {
            let tmax = best.map_or(r.tmax, |b| b.t);
            // The facing test after the hit test: most candidates miss.
            let (t, u, v) = w.hit(self.mesh.tri(p as usize), r.tmin, tmax)?;
            if !self.faces(p, r.dir) {
                return None;
            }
            let better = best.is_none_or(|b| t < b.t || (t == b.t && p < b.prim));
            if better {
                best = Some(RefHit { t, u, v, prim: p });
            }
            Some(t)
        });
        best
    }

    /// Whether anything is hit in (tmin, tmax].
    #[must_use]
    pub fn any(&self, r: &Ray) -> bool {
        if r.dir == [0.0; 3] || r.org.iter().chain(&r.dir).any(|x| !x.is_finite()) {
            return false;
        }
        let w = Watertight::new(r);
        let mut found = false;
        self.visit(r, |p| {
            if found || w.hit(self.mesh.tri(p as usize), r.tmin, r.tmax).is_none() {
                return None;
            }
            found = self.faces(p, r.dir);
            // The first hit ends the search: no box overlaps (tmin, -inf).
            found.then_some(f64::NEG_INFINITY)
        });
        found
    }

    /// Every hit, sorted by t then triangle.
    #[must_use]
    pub fn all(&self, r: &Ray) -> Vec<RefHit> {
        if r.dir == [0.0; 3] || r.org.iter().chain(&r.dir).any(|x| !x.is_finite()) {
            return Vec::new();
        }
        let w = Watertight::new(r);
        let mut hits = Vec::new();
        self.visit(r, |p| {
            if let Some((t, u, v)) = w.hit(self.mesh.tri(p as usize), r.tmin, r.tmax) {
                if self.faces(p, r.dir) {
                    hits.push(RefHit { t, u, v, prim: p });
                }
            }
            None
        });
        hits.sort_by(|a, b| a.t.total_cmp(&b.t).then(a.prim.cmp(&b.prim)));
        hits
    }
}
