//! Shapes the procedural scenes are made of: quads, boxes, round legs and
//! curved chair backs, and the meeting room (the Conference stand-in) built
//! from them.

use crate::mesh::Mesh;
use isa::rng::Rng;

pub(crate) fn quad(m: &mut Mesh, p: [f32; 3], u: [f32; 3], v: [f32; 3]) {
    let b = m.positions.len() as u32;
    let add = |a: [f32; 3], b: [f32; 3]| [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
    m.positions
        .extend([p, add(p, u), add(add(p, u), v), add(p, v)]);
    m.tris.extend([[b, b + 1, b + 2], [b, b + 2, b + 3]]);
}

/// A closed box of 12 triangles with shared corners.
pub(crate) fn cuboid(m: &mut Mesh, lo: [f32; 3], hi: [f32; 3]) {
    let b = m.positions.len() as u32;
    for i in 0..8u32 {
        m.positions.push([
            if i & 1 == 0 { lo[0] } else { hi[0] },
            if i & 2 == 0 { lo[1] } else { hi[1] },
            if i & 4 == 0 { lo[2] } else { hi[2] },
        ]);
    }
    for f in [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ] {
        m.tris.push([b + f[0], b + f[1], b + f[2]]);
        m.tris.push([b + f[0], b + f[2], b + f[3]]);
    }
}

/// A closed round leg: an upright prism of `s` sides (2s side triangles,
/// two fans of s - 2) on the base centre `c`.
pub(crate) fn cylinder(m: &mut Mesh, c: [f32; 3], radius: f32, height: f32, s: u32) {
    let b = m.positions.len() as u32;
    for k in 0..s {
        let a = std::f32::consts::TAU * k as f32 / s as f32;
        let (x, z) = (c[0] + radius * a.cos(), c[2] + radius * a.sin());
        m.positions.push([x, c[1], z]);
        m.positions.push([x, c[1] + height, z]);
    }
    for k in 0..s {
        let (i, j) = (b + 2 * k, b + 2 * ((k + 1) % s));
        m.tris.push([i, j, j + 1]);
        m.tris.push([i, j + 1, i + 1]);
    }
    for k in 1..s - 1 {
        m.tris.push([b, b + 2 * (k + 1), b + 2 * k]);
        m.tris.push([b + 1, b + 1 + 2 * k, b + 1 + 2 * (k + 1)]);
    }
}

/// A chair back: a closed band `thick` deep, an arc of `s` segments of the
/// circle of radius `r` about the vertical axis through `(cx, cz)`, spanning
/// `half` radians either side of direction `dir` (+1: +z), from `y0` to
/// `y1` (8s + 4 triangles).
#[allow(clippy::too_many_arguments)]
fn arc_band(
    m: &mut Mesh,
    (cx, cz): (f32, f32),
    r: f32,
    thick: f32,
    dir: f32,
    half: f32,
    (y0, y1): (f32, f32),
    s: u32,
) {
    let b = m.positions.len() as u32;
    for k in 0..=s {
        let a = -half + 2.0 * half * k as f32 / s as f32;
        for rr in [r, r + thick] {
            let (x, z) = (cx + rr * a.sin(), cz + dir * rr * a.cos());
            m.positions.push([x, y0, z]);
            m.positions.push([x, y1, z]);
        }
    }
    // Vertex k*4 + (outer? 2: 0) + (top? 1: 0).
    let v = |k: u32, outer: u32, top: u32| b + 4 * k + 2 * outer + top;
    let mut quad_ix = |p: u32, q: u32, r: u32, t: u32| {
        m.tris.push([p, q, r]);
        m.tris.push([p, r, t]);
    };
    for k in 0..s {
        quad_ix(v(k, 0, 0), v(k + 1, 0, 0), v(k + 1, 0, 1), v(k, 0, 1)); // inner face
        quad_ix(v(k, 1, 0), v(k, 1, 1), v(k + 1, 1, 1), v(k + 1, 1, 0)); // outer face
        quad_ix(v(k, 0, 1), v(k + 1, 0, 1), v(k + 1, 1, 1), v(k, 1, 1)); // top edge
        quad_ix(v(k, 0, 0), v(k, 1, 0), v(k + 1, 1, 0), v(k + 1, 0, 0)); // bottom edge
    }
    for k in [0, s] {
        quad_ix(v(k, 0, 0), v(k, 0, 1), v(k, 1, 1), v(k, 1, 0)); // ends
    }
}

/// A closed 20 x 6 x 14 m room centred on x = z = 0, floor at y = 0:
/// floor, ceiling and four walls facing in (12 triangles).
pub(crate) fn closed_room(m: &mut Mesh) {
    quad(m, [-10.0, 0.0, -7.0], [0.0, 0.0, 14.0], [20.0, 0.0, 0.0]); // floor
    quad(m, [-10.0, 6.0, -7.0], [20.0, 0.0, 0.0], [0.0, 0.0, 14.0]); // ceiling
    quad(m, [-10.0, 0.0, -7.0], [20.0, 0.0, 0.0], [0.0, 6.0, 0.0]); // back wall
    quad(m, [-10.0, 0.0, -7.0], [0.0, 6.0, 0.0], [0.0, 0.0, 14.0]); // left
    quad(m, [10.0, 0.0, -7.0], [0.0, 0.0, 14.0], [0.0, 6.0, 0.0]); // right
    quad(m, [-10.0, 0.0, 7.0], [0.0, 6.0, 0.0], [20.0, 0.0, 0.0]); // front
}

/// Triangles of one table with its 4 chairs at `s` segments.
#[cfg(test)]
fn meeting_set_triangles(s: u32) -> u32 {
    112 * s - 4
}

/// The meeting room: a closed 20 x 6 x 14 room (floor, ceiling and four
/// walls, 12 triangles: no ray leaves it) with `tables` tables on a
/// seeded, jittered grid of up to 8 per row, each with 4 chairs (2 per long side, facing it, pulled out by a
/// seeded amount). Table tops and seats are boxes; table and chair legs are
/// round (`s` sides) and chair backs curved bands of `s` segments: the
/// detail is in the furniture's curves, as in a modelled room, and flat
/// surfaces stay large triangles.
pub(crate) fn meeting_room(m: &mut Mesh, seed: u64, tables: u32, s: u32) {
    let mut r = Rng::new(seed);
    closed_room(m);
    let cols = tables.clamp(1, 8);
    let rows = tables.div_ceil(cols).max(1);
    let (dx, dz) = (20.0 / cols as f32, 11.5 / rows as f32);
    for t in 0..tables {
        let (i, j) = (t % cols, t / cols);
        let x = -10.0 + dx * (i as f32 + 0.5) + r.range(-0.1, 0.1);
        let z = -6.0 + dz * (j as f32 + 0.5) + r.range(-0.1, 0.1);
        let (w, d, h) = (r.range(0.65, 0.8), r.range(0.35, 0.42), 0.74);
        cuboid(m, [x - w, h - 0.04, z - d], [x + w, h, z + d]);
        for (lx, lz) in [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)] {
            let c = [x + lx * (w - 0.08), 0.0, z + lz * (d - 0.08)];
            cylinder(m, c, 0.03, h - 0.04, s);
        }
        for side in [-1.0f32, 1.0] {
            for off in [-0.5f32, 0.5] {
                let cx = x + off * w + r.range(-0.08, 0.08);
                let cz = z + side * (d + 0.3 + r.range(0.0, 0.15));
                chair(m, (cx, cz), -side, s);
            }
        }
    }
}

/// A chair at `(cx, cz)` facing `face` (+1: +z): a seat, 4 round legs and
/// a curved back behind the seat.
fn chair(m: &mut Mesh, (cx, cz): (f32, f32), face: f32, s: u32) {
    let (hw, hd, seat) = (0.22, 0.21, 0.44);
    cuboid(m, [cx - hw, seat, cz - hd], [cx + hw, seat + 0.04, cz + hd]);
    for (lx, lz) in [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)] {
        let c = [cx + lx * (hw - 0.03), 0.0, cz + lz * (hd - 0.03)];
        cylinder(m, c, 0.015, seat, s);
    }
    // The back's arc bulges away from the table: its circle's centre lies
    // toward the table from the back's middle.
    let radius = 0.6;
    let back = cz - face * hd;
    let centre = back + face * radius;
    arc_band(
        m,
        (cx, centre),
        radius,
        0.02,
        -face,
        (hw / radius).asin(),
        (seat + 0.04, seat + 0.5),
        s,
    );
}

/// A water surface: a plane at y = 0 over [-half, half]^2 of cells x cells
/// squares (two triangles each), each vertex raised by a height map: four
/// seeded travelling-wave components (wavelengths a tenth to a half of the
/// plane, random directions and phases), summed and scaled to `amp`.
pub(crate) fn water(m: &mut Mesh, seed: u64, cells: u32, half: f32, amp: f32) {
    let mut r = Rng::new(seed);
    let waves: Vec<(f32, f32, f32, f32)> = (0..4)
        .map(|_| {
            let a = r.range(0.0, std::f32::consts::TAU);
            let k = std::f32::consts::TAU / (2.0 * half * r.range(0.1, 0.5));
            (
                k * a.cos(),
                k * a.sin(),
                r.range(0.0, std::f32::consts::TAU),
                r.range(0.5, 1.0),
            )
        })
        .collect();
    let norm: f32 = waves.iter().map(|w| w.3).sum();
    let b = m.positions.len() as u32;
    for j in 0..=cells {
        for i in 0..=cells {
            let x = -half + 2.0 * half * i as f32 / cells as f32;
            let z = -half + 2.0 * half * j as f32 / cells as f32;
            let h: f32 = waves
                .iter()
                .map(|&(kx, kz, ph, w)| w * (kx * x + kz * z + ph).sin())
                .sum();
            m.positions.push([x, amp * h / norm, z]);
        }
    }
    for j in 0..cells {
        for i in 0..cells {
            let a = b + j * (cells + 1) + i;
            let c = a + cells + 1;
            m.tris.push([a, c, a + 1]);
            m.tris.push([a + 1, c, c + 1]);
        }
    }
}

/// Append the shape `make` builds, its positions mapped by `map` (a
/// rotation: the upright `cylinder` laid along x).
pub(crate) fn mapped(
    m: &mut Mesh,
    make: impl FnOnce(&mut Mesh),
    map: impl Fn([f32; 3]) -> [f32; 3],
) {
    let mut part = Mesh::default();
    make(&mut part);
    let b = m.positions.len() as u32;
    m.positions.extend(part.positions.into_iter().map(map));
    m.tris
        .extend(part.tris.into_iter().map(|t| t.map(|i| i + b)));
}

/// A closed round part along x: centre `c`, `len` long, `s` sides.
fn cylinder_x(m: &mut Mesh, c: [f32; 3], radius: f32, len: f32, s: u32) {
    let make = |p: &mut Mesh| cylinder(p, [0.0, 0.0, 0.0], radius, len, s);
    mapped(m, make, |[x, y, z]| {
        [c[0] - len / 2.0 + y, c[1] + x, c[2] + z]
    });
}

/// A hollow box: six walls `t` thick (each a closed box) around the
/// inside `lo`..`hi`, as a modelled cab or cargo body is sheet on both
/// sides.
fn shell(m: &mut Mesh, lo: [f32; 3], hi: [f32; 3], t: f32) {
    for a in 0..3 {
        for (at, d) in [(lo[a], -t), (hi[a], t)] {
            let (mut l, mut h) = (lo, hi);
            l[a] = at.min(at + d);
            h[a] = at.max(at + d);
            cuboid(m, l, h);
        }
    }
}

/// A wheel on the axis along x through `c`: a tyre of `s` sides (0.55 m
/// radius), the rim inside it and the hub inside that (each closed, so a
/// ray through the wheel crosses all three).
fn wheel(m: &mut Mesh, c: [f32; 3], s: u32) {
    cylinder_x(m, c, 0.55, 0.36, s);
    cylinder_x(m, c, 0.36, 0.30, s);
    cylinder_x(m, c, 0.12, 0.40, s / 2);
}

/// The truck of the multi-hit paper's Figure 2, as a vulnerability model
/// has it (surfaces inside surfaces): a 7.4 m cab-over cargo truck on a
/// ground plane. Chassis rails and three axles of two wheels each (tyre,
/// rim, hub); a cab of sheet walls with two seats, a dashboard, a steering
/// wheel and a column; under it an engine block with six cylinders and
/// their pistons, a crankshaft and a radiator of thin fins; a fuel tank; a
/// cargo body of sheet walls holding `cargo` seeded crates and drums. Round
/// parts have `s` sides.
pub(crate) fn truck(m: &mut Mesh, seed: u64, cargo: u32, s: u32) {
    let mut r = Rng::new(seed);
    quad(m, [-12.0, 0.0, -12.0], [0.0, 0.0, 24.0], [24.0, 0.0, 0.0]); // ground
                                                                      // Chassis: two rails, three axles and their wheels.
    for x in [-0.45f32, 0.45] {
        cuboid(m, [x - 0.08, 0.75, -3.6], [x + 0.08, 0.95, 3.6]);
    }
    for z in [-2.7f32, 1.2, 2.6] {
        cylinder_x(m, [0.0, 0.55, z], 0.07, 2.1, s / 2);
        for x in [-1.05f32, 1.05] {
            wheel(m, [x, 0.55, z], s);
        }
    }
    cab(m, s);
    engine(m, s);
    cylinder_x(m, [1.0, 1.0, -0.6], 0.28, 1.2, s); // fuel tank
    cylinder(m, [-1.1, 1.0, -1.4], 0.06, 2.6, s / 2); // exhaust stack
    cargo_body(m, &mut r, cargo, s);
}

/// The cab: sheet walls, seats, dashboard, steering wheel and column.
fn cab(m: &mut Mesh, s: u32) {
    shell(m, [-1.2, 1.0, -3.7], [1.2, 3.0, -2.0], 0.03);
    for x in [-0.6f32, 0.6] {
        cuboid(m, [x - 0.28, 1.4, -2.65], [x + 0.28, 1.55, -2.15]); // cushion
        cuboid(m, [x - 0.28, 1.55, -2.2], [x + 0.28, 2.3, -2.1]); // back
    }
    cuboid(m, [-1.15, 1.8, -3.65], [1.15, 2.1, -3.3]); // dashboard
    let wheel_at = |p: [f32; 3]| [p[0] - 0.6, p[2] + 2.3, p[1] - 3.05];
    mapped(m, |p| cylinder(p, [0.0, 0.0, 0.0], 0.22, 0.04, s), wheel_at);
    mapped(
        m,
        |p| cylinder(p, [0.0, -0.5, 0.0], 0.03, 0.5, s / 2),
        wheel_at,
    );
}

/// The engine under the cab: block, six cylinders each with its piston,
/// crankshaft and a radiator of 80 thin fins ahead of it.
fn engine(m: &mut Mesh, s: u32) {
    shell(m, [-0.5, 1.0, -3.4], [0.5, 1.9, -1.9], 0.02);
    for k in 0..6 {
        let z = -3.25 + 0.23 * k as f32;
        cylinder(m, [0.0, 1.1, z + 0.1], 0.09, 0.7, s);
        cylinder(m, [0.0, 1.2, z + 0.1], 0.075, 0.25, s);
    }
    let along_z = |[x, y, z]: [f32; 3]| [y, z + 1.05, x - 3.45];
    mapped(
        m,
        |p| cylinder(p, [0.0, 0.0, 0.0], 0.05, 1.6, s / 2),
        along_z,
    );
    for k in 0..80 {
        let x = -0.5 + k as f32 / 79.0;
        quad(m, [x, 1.1, -3.62], [0.0, 0.7, 0.0], [0.0, 0.0, 0.12]);
    }
}

/// The cargo body: sheet walls and `n` seeded crates and drums inside.
fn cargo_body(m: &mut Mesh, r: &mut Rng, n: u32, s: u32) {
    let (lo, hi) = ([-1.2f32, 1.05, -1.8], [1.2f32, 3.2, 3.7]);
    shell(m, lo, hi, 0.03);
    for _ in 0..n {
        let (x, z) = (
            r.range(lo[0] + 0.3, hi[0] - 0.3),
            r.range(lo[2] + 0.3, hi[2] - 0.3),
        );
        let y = lo[1] + r.range(0.0, 1.2);
        if r.range(0.0, 1.0) < 0.5 {
            let h = r.range(0.1, 0.25);
            cuboid(m, [x - h, y, z - h], [x + h, y + 2.0 * h, z + h]);
        } else {
            cylinder(m, [x, y, z], r.range(0.12, 0.25), r.range(0.4, 0.8), s);
        }
    }
}

/// Of 4000 seeded rays from points spread through the 20 x 6 x 14 room in
/// every direction, how many hit nothing (a closed room: none).
#[cfg(test)]
pub(crate) fn escaping_rays(m: &Mesh) -> usize {
    use crate::reference::{Ray, Reference};
    let refi = Reference::brute(m);
    let mut r = Rng::new(3);
    let mut missed = 0;
    for _ in 0..4000 {
        let o = [
            f64::from(r.range(-9.9, 9.9)),
            f64::from(r.range(0.01, 5.99)),
            f64::from(r.range(-6.99, 6.99)),
        ];
        let d = [
            f64::from(r.range(-1.0, 1.0)),
            f64::from(r.range(-1.0, 1.0)),
            f64::from(r.range(-1.0, 1.0)),
        ];
        missed += usize::from(refi.closest(&Ray::new(o, d)).is_none());
    }
    missed
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_ray_leaves_the_meeting_room() {
        let mut m = Mesh::default();
        meeting_room(&mut m, 7, 4, 6);
        assert_eq!(escaping_rays(&m), 0);
    }

    #[test]
    fn the_meeting_room_has_the_triangles_its_formula_says_and_closed_legs() {
        for (tables, s) in [(1, 3), (3, 8), (40, 62)] {
            let mut m = Mesh::default();
            meeting_room(&mut m, 7, tables, s);
            assert_eq!(m.len() as u32, 12 + tables * meeting_set_triangles(s));
            assert!(m
                .tris
                .iter()
                .flatten()
                .all(|&v| (v as usize) < m.positions.len()));
        }
        let mut a = Mesh::default();
        let mut b = Mesh::default();
        meeting_room(&mut a, 7, 5, 6);
        meeting_room(&mut b, 7, 5, 6);
        assert_eq!(a.positions, b.positions, "seeded: the same room every time");
        // A leg is closed: every edge is shared by exactly two triangles.
        let mut leg = Mesh::default();
        cylinder(&mut leg, [0.0; 3], 1.0, 2.0, 9);
        let mut edges = std::collections::BTreeMap::new();
        for t in &leg.tris {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                *edges.entry((a.min(b), a.max(b))).or_insert(0) += 1;
            }
        }
        assert!(edges.values().all(|&n| n == 2));
    }

    #[test]
    fn water_is_a_seeded_grid_within_its_amplitude() {
        let mut m = Mesh::default();
        water(&mut m, 3, 16, 10.0, 0.2);
        assert_eq!((m.len(), m.positions.len()), (2 * 16 * 16, 17 * 17));
        assert!(m
            .positions
            .iter()
            .all(|p| p[1].abs() <= 0.2 + 1e-6 && p[0].abs() <= 10.0));
        assert!(m.positions.iter().any(|p| p[1].abs() > 0.02), "perturbed");
        let mut n = Mesh::default();
        water(&mut n, 3, 16, 10.0, 0.2);
        assert_eq!(m.positions, n.positions);
    }
}
