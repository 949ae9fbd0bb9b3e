//! The boardroom: the Conference stand-in furnished as a modelled
//! conference room is: long tables with rounded tops in rows, and swivel
//! office chairs (five-star base on casters, a gas column, upholstered
//! seat and back, armrests) whose curved parts hold most of the triangles.

use crate::mesh::Mesh;
use crate::shapes::{closed_room, mapped};
use isa::rng::Rng;
use std::f32::consts::{FRAC_PI_2, PI, TAU};

/// `x^e` keeping the sign of `x` (a superellipsoid's profile).
fn spow(x: f32, e: f32) -> f32 {
    x.signum() * x.abs().powf(e)
}

fn sub(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn unit(a: [f32; 3]) -> [f32; 3] {
    let l = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    [a[0] / l, a[1] / l, a[2] / l]
}

/// A closed superellipsoid (an upholstered cushion): centre `c`, radii
/// `r`, squareness `e` (1: an ellipsoid; smaller: boxier), `nu` segments
/// around and `nv` from pole to pole: 2 nu (nv - 1) triangles.
pub(crate) fn cushion(m: &mut Mesh, c: [f32; 3], r: [f32; 3], e: f32, nu: u32, nv: u32) {
    let b = m.positions.len() as u32;
    m.positions.push([c[0], c[1] - r[1], c[2]]);
    for v in 1..nv {
        let phi = -FRAC_PI_2 + PI * v as f32 / nv as f32;
        let (sp, cp) = (spow(phi.sin(), e), spow(phi.cos(), e));
        for u in 0..nu {
            let th = TAU * u as f32 / nu as f32;
            m.positions.push([
                c[0] + r[0] * cp * spow(th.cos(), e),
                c[1] + r[1] * sp,
                c[2] + r[2] * cp * spow(th.sin(), e),
            ]);
        }
    }
    let top = m.positions.len() as u32;
    m.positions.push([c[0], c[1] + r[1], c[2]]);
    let ring = |v: u32, u: u32| b + 1 + (v - 1) * nu + u % nu;
    for u in 0..nu {
        m.tris.push([b, ring(1, u + 1), ring(1, u)]);
        m.tris.push([top, ring(nv - 1, u), ring(nv - 1, u + 1)]);
    }
    for v in 1..nv - 1 {
        for u in 0..nu {
            let (a, bb) = (ring(v, u), ring(v, u + 1));
            let (cc, d) = (ring(v + 1, u + 1), ring(v + 1, u));
            m.tris.push([a, bb, cc]);
            m.tris.push([a, cc, d]);
        }
    }
}

/// A closed round tube of `s` sides from `p` to `q` (a leg, a column, a
/// caster's wheel): 4s - 4 triangles.
pub(crate) fn tube(m: &mut Mesh, p: [f32; 3], q: [f32; 3], radius: f32, s: u32) {
    let axis = sub(q, p);
    let len = (axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]).sqrt();
    let w = unit(axis);
    let helper = if w[1].abs() < 0.9 {
        [0.0, 1.0, 0.0]
    } else {
        [1.0, 0.0, 0.0]
    };
    let u = unit(cross(helper, w));
    let v = cross(w, u);
    let make = |part: &mut Mesh| crate::shapes::cylinder(part, [0.0; 3], radius, len, s);
    // The upright cylinder's (x, y, z) becomes p + x u + y w + z v.
    mapped(m, make, |[x, y, z]| {
        [
            p[0] + x * u[0] + y * w[0] + z * v[0],
            p[1] + x * u[1] + y * w[1] + z * v[1],
            p[2] + x * u[2] + y * w[2] + z * v[2],
        ]
    });
}

/// Triangles of one swivel chair at `s` segments (`s` a multiple of 4, at least 8).
#[cfg(test)]
pub(crate) fn chair_triangles(s: u32) -> u32 {
    // 5 casters and 5 legs (s/2 sides), the column (s), seat and back
    // (s x s/2), 2 arm posts and the back's stem (s/2), 2 arm pads (s/2 x s/4).
    10 * (2 * s - 4) + (4 * s - 4) + 4 * s * (s / 2 - 1) + 3 * (2 * s - 4) + 2 * s * (s / 4 - 1)
}

/// Triangles of one table at `s` segments.
#[cfg(test)]
pub(crate) fn table_triangles(s: u32) -> u32 {
    16 * s + 4 * (2 * s - 4)
}

/// A swivel chair facing +z at the origin (seat 0.46 m high), `s`
/// segments to its curves.
fn chair_local(m: &mut Mesh, s: u32) {
    let h = s / 2;
    for k in 0..5 {
        let a = TAU * k as f32 / 5.0;
        let (ca, sa) = (a.cos(), a.sin());
        let foot = [0.3 * ca, 0.07, 0.3 * sa];
        tube(m, [0.0, 0.1, 0.0], foot, 0.018, h);
        // The caster: a wheel whose axle runs along the leg's tangent.
        let (tx, tz) = (-sa * 0.014, ca * 0.014);
        let w = [0.3 * ca, 0.03, 0.3 * sa];
        tube(
            m,
            [w[0] - tx, 0.03, w[2] - tz],
            [w[0] + tx, 0.03, w[2] + tz],
            0.03,
            h,
        );
    }
    tube(m, [0.0, 0.07, 0.0], [0.0, 0.42, 0.0], 0.028, s);
    cushion(m, [0.0, 0.46, 0.0], [0.25, 0.05, 0.24], 0.25, s, h);
    cushion(m, [0.0, 0.8, -0.25], [0.23, 0.27, 0.045], 0.3, s, h);
    tube(m, [0.0, 0.42, -0.12], [0.0, 0.62, -0.24], 0.02, h);
    for x in [-0.27f32, 0.27] {
        tube(m, [x, 0.44, -0.02], [x, 0.64, 0.02], 0.016, h);
        cushion(m, [x, 0.655, 0.02], [0.035, 0.016, 0.14], 0.5, h, s / 4);
    }
}

/// A chair at `(x, z)` turned by `yaw` (0: facing +z).
fn chair(m: &mut Mesh, (x, z): (f32, f32), yaw: f32, s: u32) {
    let (c, sn) = (yaw.cos(), yaw.sin());
    mapped(
        m,
        |p| chair_local(p, s),
        |[px, py, pz]| [x + c * px + sn * pz, py, z - sn * px + c * pz],
    );
}

/// A table 2.4 x 1.0 m centred at `(x, z)`, 0.74 m high: a rounded top
/// (a superellipse outline of 4s points, 4 cm thick, fanned from its
/// centre) on four round legs.
fn table(m: &mut Mesh, (x, z): (f32, f32), s: u32) {
    let (a, b, h, t) = (1.2f32, 0.5f32, 0.74f32, 0.04f32);
    let n = 4 * s;
    let base = m.positions.len() as u32;
    m.positions.push([x, h, z]);
    m.positions.push([x, h - t, z]);
    for k in 0..n {
        let th = TAU * k as f32 / n as f32;
        let (px, pz) = (x + a * spow(th.cos(), 0.25), z + b * spow(th.sin(), 0.25));
        m.positions.push([px, h, pz]);
        m.positions.push([px, h - t, pz]);
    }
    let top = |k: u32| base + 2 + 2 * (k % n);
    for k in 0..n {
        let (i, j) = (top(k), top(k + 1));
        m.tris.push([base, j, i]);
        m.tris.push([base + 1, i + 1, j + 1]);
        m.tris.push([i, j, j + 1]);
        m.tris.push([i, j + 1, i + 1]);
    }
    for (lx, lz) in [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)] {
        let (px, pz) = (x + lx * (a - 0.15), z + lz * (b - 0.12));
        tube(m, [px, 0.0, pz], [px, h - t, pz], 0.03, s / 2);
    }
}

/// The boardroom: a closed 20 x 6 x 14 room (floor, ceiling and four
/// walls, 12 triangles: no ray leaves it) with `tables` tables joined end
/// to end in rows of up to five, each row a long conference table; three
/// swivel chairs along each long side of every table and one at each end
/// of a row, pulled out and turned by seeded amounts. Curves have `s`
/// segments (a multiple of 4).
pub(crate) fn boardroom(m: &mut Mesh, seed: u64, tables: u32, s: u32) {
    let mut r = Rng::new(seed);
    closed_room(m);
    let rows = tables.div_ceil(5).max(1);
    let dz = 11.0 / rows as f32;
    let pull = |r: &mut Rng| (r.range(0.0, 0.25), r.range(-0.35, 0.35));
    for row in 0..rows {
        let n = (tables - 5 * row).min(5);
        let z = -5.5 + dz * (row as f32 + 0.5);
        let x0 = -1.2 * n as f32;
        for t in 0..n {
            let x = x0 + 2.4 * (t as f32 + 0.5);
            table(m, (x, z), s);
            for side in [-1.0f32, 1.0] {
                for k in [-0.75f32, 0.0, 0.75] {
                    let (out, turn) = pull(&mut r);
                    let yaw = if side < 0.0 { 0.0 } else { PI };
                    chair(m, (x + k, z + side * (0.85 + out)), yaw + turn, s);
                }
            }
        }
        for end in [-1.0f32, 1.0] {
            let (out, turn) = pull(&mut r);
            let yaw = end * FRAC_PI_2;
            chair(m, (end * (1.2 * n as f32 + 0.55 + out), z), yaw + turn, s);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every edge of a closed mesh is shared by exactly two triangles.
    fn closed(m: &Mesh) -> bool {
        let mut edges = std::collections::BTreeMap::new();
        for t in &m.tris {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                *edges.entry((a.min(b), a.max(b))).or_insert(0) += 1;
            }
        }
        edges.values().all(|&n| n == 2)
    }

    #[test]
    fn cushions_tubes_and_tables_are_closed_and_counted() {
        let mut c = Mesh::default();
        cushion(&mut c, [0.0; 3], [1.0, 0.5, 0.8], 0.3, 12, 6);
        assert_eq!(c.len(), 2 * 12 * 5);
        assert!(closed(&c));
        let mut t = Mesh::default();
        tube(&mut t, [0.0, 0.0, 0.0], [1.0, 0.5, -0.2], 0.1, 8);
        assert_eq!(t.len(), 4 * 8 - 4);
        assert!(closed(&t));
        let mut tb = Mesh::default();
        table(&mut tb, (0.0, 0.0), 8);
        assert_eq!(tb.len() as u32, table_triangles(8));
        let mut ch = Mesh::default();
        chair_local(&mut ch, 8);
        assert_eq!(ch.len() as u32, chair_triangles(8));
    }

    #[test]
    fn the_boardroom_has_its_formula_s_triangles_and_is_seeded() {
        for (tables, s) in [(1, 8), (7, 8), (10, 36)] {
            let mut m = Mesh::default();
            boardroom(&mut m, 7, tables, s);
            let rows = tables.div_ceil(5);
            let chairs = 6 * tables + 2 * rows;
            let want = 12 + tables * table_triangles(s) + chairs * chair_triangles(s);
            assert_eq!(m.len() as u32, want);
            assert!(m.positions.iter().flatten().all(|v| v.is_finite()));
        }
        let (mut a, mut b) = (Mesh::default(), Mesh::default());
        boardroom(&mut a, 7, 4, 8);
        boardroom(&mut b, 7, 4, 8);
        assert_eq!(a.positions, b.positions);
    }

    #[test]
    fn no_ray_leaves_the_boardroom() {
        let mut m = Mesh::default();
        boardroom(&mut m, 7, 3, 8);
        assert_eq!(crate::shapes::escaping_rays(&m), 0);
    }
}
