//! A disk cache of built meshes, beside the BVH cache ([`crate::bvh_cache`]):
//! a scene's placed mesh read and refined to the paper's size (millions of
//! triangles: decompressing the scan and refining it took longer than the
//! BVH build the cache already skips). Keyed by BLAKE3 of this format's
//! version and the caller's description of the build (the placement as
//! written and the source file's bytes), so a changed file, option or
//! refiner is built anew. The builds are deterministic, so a cached mesh is
//! the mesh a build would make (tested).

use crate::bvh_cache::{dir, hash_words, store};
use crate::mesh::Mesh;
use std::path::Path;

/// Bumped whenever the file format or anything a key does not cover
/// (the refiner, the loaders, the generators) changes.
const FORMAT: u32 = 2; // 2: the meeting room closed (issue 54)

/// A mesh and one tag byte per triangle (the caller's material index).
pub type Tagged = (Mesh, Vec<u8>);

/// `build()` through the cache in [`dir`], keyed by `key_parts`, its tags
/// below `ntags` (a file holding another is rebuilt); results of fewer than
/// [`crate::bvh_cache::MIN_TRIANGLES`] triangles are not stored.
pub fn cached(
    key_parts: &[&[u8]],
    ntags: u8,
    build: impl FnOnce() -> Result<Tagged, String>,
) -> Result<Tagged, String> {
    let Some(d) = dir() else {
        return build();
    };
    cached_in(&d, key_parts, ntags, build)
}

/// [`cached`] with the cache in directory `d`.
pub fn cached_in(
    d: &Path,
    key_parts: &[&[u8]],
    ntags: u8,
    build: impl FnOnce() -> Result<Tagged, String>,
) -> Result<Tagged, String> {
    let path = d.join(format!("mesh-{}.bin", key(key_parts)));
    let lock = crate::bvh_cache::file_lock(&path);
    let _made_once = lock
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    let read = std::fs::read(&path).ok().and_then(|v| decode(&v));
    if let Some(t) = read.filter(|t| t.1.iter().all(|&x| x < ntags)) {
        return Ok(t);
    }
    let t = build()?;
    if t.0.len() >= crate::bvh_cache::MIN_TRIANGLES {
        store(d, &path, &encode(&t));
    }
    Ok(t)
}

/// BLAKE3 of the format and each part with its length.
fn key(parts: &[&[u8]]) -> String {
    let mut h = blake3::Hasher::new();
    h.update(&FORMAT.to_le_bytes());
    for p in parts {
        h.update(&(p.len() as u64).to_le_bytes());
        h.update(p);
    }
    h.finalize().to_hex()[..32].to_string()
}

/// Words: format, vertex count, triangle count, the positions (3 f32 bits
/// each), the triangles (3 indices each); then one tag byte per triangle.
fn encode((m, tags): &Tagged) -> Vec<u8> {
    let mut b = Vec::with_capacity(12 + 12 * (m.positions.len() + m.tris.len()) + tags.len());
    let head = [FORMAT, m.positions.len() as u32, m.tris.len() as u32];
    let words = head
        .into_iter()
        .chain(m.positions.iter().flatten().map(|c| c.to_bits()))
        .chain(m.tris.iter().flatten().copied());
    for w in words {
        b.extend_from_slice(&w.to_le_bytes());
    }
    b.extend_from_slice(tags);
    b
}

/// The inverse of [`encode`]; `None` for a file of another format, a
/// wrong length or a triangle naming a vertex that is not there.
fn decode(v: &[u8]) -> Option<Tagged> {
    let word = |i: usize| -> u32 {
        let c = &v[4 * i..4 * i + 4];
        u32::from_le_bytes([c[0], c[1], c[2], c[3]])
    };
    if v.len() < 12 || word(0) != FORMAT {
        return None;
    }
    let (np, nt) = (word(1) as usize, word(2) as usize);
    if v.len() != 12 + 12 * (np + nt) + nt {
        return None;
    }
    let f = |i: usize| f32::from_bits(word(i));
    let positions = (0..np)
        .map(|k| [f(3 + 3 * k), f(4 + 3 * k), f(5 + 3 * k)])
        .collect();
    let t0 = 3 + 3 * np;
    let tris: Vec<[u32; 3]> = (0..nt)
        .map(|k| [word(t0 + 3 * k), word(t0 + 3 * k + 1), word(t0 + 3 * k + 2)])
        .collect();
    if tris.iter().flatten().any(|&i| i as usize >= np) {
        return None;
    }
    let tags = v[12 + 12 * (np + nt)..].to_vec();
    Some((Mesh { positions, tris }, tags))
}

/// A source file's bytes hashed into a key part (a 32-byte digest, so a
/// key does not hold the file).
pub fn file_digest(path: &Path) -> Result<[u8; 32], String> {
    let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(*blake3::hash(&bytes).as_bytes())
}

/// Words hashed into a key part, for callers that describe a build by data.
#[must_use]
pub fn words_digest(words: impl Iterator<Item = u32>) -> [u8; 32] {
    let mut h = blake3::Hasher::new();
    hash_words(&mut h, words);
    *h.finalize().as_bytes()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tagged(n: u32) -> Tagged {
        let positions = (0..3 * n).map(|i| [i as f32, -(i as f32), 0.5]).collect();
        let tris = (0..n).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect();
        (
            Mesh { positions, tris },
            (0..n).map(|t| (t % 3) as u8).collect(),
        )
    }

    #[test]
    fn a_mesh_round_trips_and_bad_files_do_not_decode() {
        let t = tagged(5);
        let e = encode(&t);
        assert_eq!(decode(&e), Some(t.clone()));
        assert_eq!(decode(&e[..e.len() - 1]), None, "short");
        let mut bad = e.clone();
        bad[0] ^= 1;
        assert_eq!(decode(&bad), None, "other format");
        let mut oob = e.clone();
        let tri0 = 12 + 12 * 15;
        oob[tri0..tri0 + 4].copy_from_slice(&99u32.to_le_bytes());
        assert_eq!(decode(&oob), None, "vertex out of range");
    }

    #[test]
    fn the_second_call_reads_the_cache_and_another_key_builds() {
        let d = std::env::temp_dir().join(format!("rtsim-mesh-cache-test-{}", std::process::id()));
        let big = crate::bvh_cache::MIN_TRIANGLES as u32;
        let mut builds = 0;
        let mut get = |k: &[u8]| {
            cached_in(&d, &[k], 3, || {
                builds += 1;
                Ok(tagged(big))
            })
            .unwrap()
        };
        let a = get(b"a");
        let b = get(b"a");
        assert_eq!(a, b);
        get(b"b");
        assert_eq!(builds, 2, "one build per key");
        let _ = std::fs::remove_dir_all(&d);
    }
}
