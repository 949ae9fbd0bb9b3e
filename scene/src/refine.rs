//! Planar refinement of a mesh to a triangle count: the largest triangle is
//! split at the midpoint of its longest edge until the mesh has the count.
//! The surface does not change (every new vertex lies on an old edge); the
//! triangles get smaller and more numerous, so a stand-in reaches the size of
//! the paper's scene (BVH depth, memory footprint) from a real scan.
//!
//! Midpoints are shared between the two triangles of an edge once both are
//! split; until then the unsplit neighbour keeps the whole edge (a T-vertex on
//! a plane: no gap). Ties in area go to the lower triangle index, so the
//! result is deterministic.

use crate::mesh::Mesh;
use std::cmp::Ordering;
use std::collections::{BinaryHeap, HashMap};

/// A triangle in the queue: its area and index; the largest first.
#[derive(PartialEq)]
struct Item(f32, u32);

impl Eq for Item {}

impl PartialOrd for Item {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}

impl Ord for Item {
    fn cmp(&self, o: &Self) -> Ordering {
        self.0.total_cmp(&o.0).then(o.1.cmp(&self.1))
    }
}

/// The area of triangle `t` of `m`.
#[must_use]
pub fn area(m: &Mesh, t: [u32; 3]) -> f32 {
    let p = t.map(|v| m.positions[v as usize]);
    let u = [p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]];
    let v = [p[2][0] - p[0][0], p[2][1] - p[0][1], p[2][2] - p[0][2]];
    let c = [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ];
    0.5 * (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt()
}

fn len2(m: &Mesh, a: u32, b: u32) -> f32 {
    let (p, q) = (m.positions[a as usize], m.positions[b as usize]);
    (0..3).map(|k| (p[k] - q[k]) * (p[k] - q[k])).sum()
}

/// Refine the triangles of `m` for which `eligible` holds until the mesh has
/// `target` triangles (nothing happens if it already has as many). Returns,
/// for every triangle of the result, the index of the input triangle it came
/// from (so per-triangle data such as materials can follow).
pub fn refine(m: &mut Mesh, target: usize, eligible: &[bool]) -> Vec<u32> {
    let mut origin: Vec<u32> = (0..m.len() as u32).collect();
    let mut heap: BinaryHeap<Item> = (0..m.len())
        .filter(|&i| eligible[i])
        .map(|i| Item(area(m, m.tris[i]), i as u32))
        .collect();
    let mut midpoints: HashMap<(u32, u32), u32> = HashMap::new();
    while m.len() < target {
        let Some(Item(_, i)) = heap.pop() else { break };
        let t = m.tris[i as usize];
        // The longest edge (k, k+1); ties to the first.
        let k = (0..3)
            .max_by(|&a, &b| {
                len2(m, t[a], t[(a + 1) % 3])
                    .total_cmp(&len2(m, t[b], t[(b + 1) % 3]))
                    .then(b.cmp(&a))
            })
            .expect("three edges");
        let (a, b, c) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
        let key = (a.min(b), a.max(b));
        let mid = *midpoints.entry(key).or_insert_with(|| {
            let (p, q) = (m.positions[a as usize], m.positions[b as usize]);
            m.positions.push([
                0.5 * (p[0] + q[0]),
                0.5 * (p[1] + q[1]),
                0.5 * (p[2] + q[2]),
            ]);
            (m.positions.len() - 1) as u32
        });
        // Same winding as the parent: (a, mid, c) and (mid, b, c).
        m.tris[i as usize] = [a, mid, c];
        m.tris.push([mid, b, c]);
        origin.push(origin[i as usize]);
        let j = (m.len() - 1) as u32;
        heap.push(Item(area(m, m.tris[i as usize]), i));
        heap.push(Item(area(m, m.tris[j as usize]), j));
    }
    origin
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> Mesh {
        Mesh {
            positions: vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [1.0, 1.0, 0.0],
                [0.0, 1.0, 0.0],
            ],
            tris: vec![[0, 1, 2], [0, 2, 3]],
        }
    }

    #[test]
    fn refinement_reaches_the_count_and_keeps_the_surface() {
        let mut m = square();
        let origin = refine(&mut m, 37, &[true, true]);
        assert_eq!(m.len(), 37);
        assert_eq!(origin.len(), 37);
        m.check("refined").unwrap();
        let total: f32 = m.tris.iter().map(|&t| area(&m, t)).sum();
        assert!((total - 1.0).abs() < 1e-5, "area {total}");
        assert!(m.positions.iter().all(|p| p[2] == 0.0), "planar");
        // Largest first: no triangle more than twice the smallest's area.
        let areas: Vec<f32> = m.tris.iter().map(|&t| area(&m, t)).collect();
        let (lo, hi) = areas
            .iter()
            .fold((f32::MAX, 0f32), |(l, h), &a| (l.min(a), h.max(a)));
        assert!(hi <= 2.0 * lo + 1e-6, "{lo} {hi}");
        // The shared diagonal's midpoint is one vertex, not two.
        let mut p = m.positions.clone();
        p.sort_by(|a, b| a.partial_cmp(b).unwrap());
        p.dedup();
        assert_eq!(p.len(), m.positions.len());
    }

    #[test]
    fn ineligible_triangles_and_degenerate_counts_are_kept() {
        let mut m = square();
        let origin = refine(&mut m, 10, &[false, true]);
        assert_eq!(m.tris[0], [0, 1, 2], "ineligible triangle untouched");
        assert!(origin[1..].iter().all(|&o| o == 1));
        let mut m = square();
        refine(&mut m, 1, &[true, true]);
        assert_eq!(m, square(), "already at the count");
        let mut m = square();
        refine(&mut m, 100, &[false, false]);
        assert_eq!(m, square(), "nothing eligible");
    }

    #[test]
    fn refinement_is_deterministic() {
        let (mut a, mut b) = (square(), square());
        refine(&mut a, 1000, &[true, true]);
        refine(&mut b, 1000, &[true, true]);
        assert_eq!(a, b);
    }
}
