//! Bringing a real mesh down to a paper's triangle count: quadric-error
//! edge collapse (meshoptimizer's `simplify`, through the `meshopt` crate:
//! a well-kept, deterministic implementation, where writing our own would
//! be a project of its own) over the eligible triangles, the others kept.

use crate::mesh::Mesh;

/// Simplify the `eligible` triangles of `m` so that the mesh has about
/// `target` triangles in all; the kept (ineligible) triangles come first.
/// Returns, per triangle of the new mesh, whether it was eligible. Errors
/// if the simplifier stops more than 5% above the target after repeated
/// passes (its topology rules can refuse collapses).
pub fn simplify(m: &mut Mesh, target: usize, eligible: &[bool]) -> Result<Vec<bool>, String> {
    let kept: Vec<[u32; 3]> = m
        .tris
        .iter()
        .zip(eligible)
        .filter(|(_, &e)| !e)
        .map(|(t, _)| *t)
        .collect();
    let idx: Vec<u32> = m
        .tris
        .iter()
        .zip(eligible)
        .filter(|(_, &e)| e)
        .flat_map(|(t, _)| *t)
        .collect();
    let want = target.saturating_sub(kept.len());
    let bytes: Vec<u8> = m
        .positions
        .iter()
        .flatten()
        .flat_map(|c| c.to_le_bytes())
        .collect();
    let adapter =
        meshopt::VertexDataAdapter::new(&bytes, 12, 0).map_err(|e| format!("simplify: {e:?}"))?;
    // Any error is allowed: the count is what must be met. The simplifier's
    // topology rules can stop a pass short; passes repeat while they gain.
    let mut out = idx;
    for _ in 0..4 {
        let next = meshopt::simplify(
            &out,
            &adapter,
            3 * want,
            1.0,
            meshopt::SimplifyOptions::empty(),
            None,
        );
        let done = next.len() <= 3 * want || next.len() == out.len();
        out = next;
        if done {
            break;
        }
    }
    let got = out.len() / 3;
    if got as f64 > want as f64 * 1.05 {
        return Err(format!(
            "simplify: stopped at {got} triangles, {want} asked"
        ));
    }
    let mut from = vec![false; kept.len()];
    m.tris = kept;
    m.tris
        .extend(out.chunks_exact(3).map(|c| [c[0], c[1], c[2]]));
    from.resize(m.tris.len(), true);
    Ok(from)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(n: u32) -> Mesh {
        let mut m = Mesh::default();
        for y in 0..=n {
            for x in 0..=n {
                let h = ((x * 7 + y * 3) % 5) as f32 * 0.1;
                m.positions.push([x as f32, y as f32, h]);
            }
        }
        for y in 0..n {
            for x in 0..n {
                let a = y * (n + 1) + x;
                m.tris.push([a, a + 1, a + n + 2]);
                m.tris.push([a, a + n + 2, a + n + 1]);
            }
        }
        m
    }

    #[test]
    fn simplify_meets_the_count_keeps_the_others_and_repeats() {
        let mut m = grid(40);
        let n = m.len();
        let mut eligible = vec![true; n];
        eligible[0] = false;
        let first = m.tris[0];
        let mut a = m.clone();
        let from = simplify(&mut a, n / 2, &eligible).unwrap();
        assert!(
            a.len() <= n / 2 + 1 && a.len() as f64 >= 0.9 * (n / 2) as f64,
            "{}",
            a.len()
        );
        assert_eq!(a.tris[0], first);
        assert_eq!(from.iter().filter(|&&e| !e).count(), 1);
        let mut b = m.clone();
        simplify(&mut b, n / 2, &eligible).unwrap();
        assert_eq!(a.tris, b.tris, "deterministic");
        assert!(simplify(&mut m, 0, &vec![false; n]).is_ok());
    }
}
