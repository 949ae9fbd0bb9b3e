//! A BVH2 build cache on disk, keyed by content: the mesh's vertices and
//! triangles, the build configuration and this format's version, hashed
//! with BLAKE3. A second run over the same scene reads the tree instead of
//! building it (large stand-in scenes take seconds to build). The build is
//! deterministic, so a cached tree is the tree a build would make.
//!
//! Where: `$RTSIM_CACHE` if set (`off` disables the cache), else
//! `rtsim-cache` in the system's temporary directory. Files are written to
//! a temporary name and renamed, so concurrent runs never read half a file;
//! a file that does not decode is rebuilt and replaced. Within one
//! process a file is made once: a second caller asking for it while the
//! first builds it waits and reads it ([`file_lock`]).

use crate::bvh::{Aabb, BuildConfig, Bvh2, Node};
use crate::mesh::Mesh;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Bumped whenever the builder or the file format changes.
const FORMAT: u32 = 1;
/// Meshes smaller than this are built, not cached (they build in milliseconds).
pub const MIN_TRIANGLES: usize = 50_000;

/// Where a BVH came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Source {
    /// Read from the cache.
    Cache,
    /// Built (and stored when a cache directory is in use).
    Built,
}

/// The cache directory in use, if any.
#[must_use]
pub fn dir() -> Option<PathBuf> {
    match std::env::var_os("RTSIM_CACHE") {
        Some(v) if v == "off" => None,
        Some(v) => Some(PathBuf::from(v)),
        None => Some(std::env::temp_dir().join("rtsim-cache")),
    }
}

/// [`Bvh2::build`] through the cache in [`dir`] (meshes of at least
/// [`MIN_TRIANGLES`]); `build_seconds` is this call's time either way.
pub fn build(mesh: &Mesh, cfg: &BuildConfig) -> Result<(Bvh2, Source), String> {
    match dir() {
        Some(d) if mesh.len() >= MIN_TRIANGLES => build_in(&d, mesh, cfg),
        _ => Ok((Bvh2::build(mesh, cfg)?, Source::Built)),
    }
}

/// [`build`] with the cache in directory `d`.
pub fn build_in(d: &Path, mesh: &Mesh, cfg: &BuildConfig) -> Result<(Bvh2, Source), String> {
    let start = Instant::now();
    let path = d.join(format!("bvh2-{}.bin", key(mesh, cfg)));
    let lock = file_lock(&path);
    let _made_once = lock
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    if let Some(mut b) = std::fs::read(&path).ok().and_then(|v| decode(&v)) {
        b.build_seconds = start.elapsed().as_secs_f64();
        return Ok((b, Source::Cache));
    }
    let b = Bvh2::build(mesh, cfg)?;
    store(d, &path, &encode(&b));
    Ok((b, Source::Built))
}

/// The lock of cache file `path` in this process: held from looking the
/// file up to storing it, so threads wanting the same tree or mesh at once
/// (reports run side by side, tests in one binary) build it once, not once
/// each (a paper-size scene's tree is most of a minute of one core).
pub(crate) fn file_lock(path: &Path) -> std::sync::Arc<std::sync::Mutex<()>> {
    use std::collections::HashMap;
    use std::sync::{Arc, Mutex, OnceLock, PoisonError};
    static LOCKS: OnceLock<Mutex<HashMap<PathBuf, Arc<Mutex<()>>>>> = OnceLock::new();
    let mut locks = LOCKS
        .get_or_init(Mutex::default)
        .lock()
        .unwrap_or_else(PoisonError::into_inner);
    Arc::clone(locks.entry(path.to_path_buf()).or_default())
}

/// Write `bytes` to `path` in cache directory `d` by a temporary name and a
/// rename, so a concurrent reader never sees half a file. A cache that
/// cannot be written is no error: the caller has what it built.
pub(crate) fn store(d: &Path, path: &Path, bytes: &[u8]) {
    let _ = std::fs::create_dir_all(d).and_then(|()| {
        let tmp = d.join(format!(".{}.{}.tmp", std::process::id(), unique()));
        std::fs::write(&tmp, bytes)?;
        std::fs::rename(&tmp, path)
    });
}

/// A name no other writer in this process uses.
fn unique() -> u64 {
    use std::sync::atomic::{AtomicU64, Ordering};
    static N: AtomicU64 = AtomicU64::new(0);
    N.fetch_add(1, Ordering::Relaxed)
}

/// The content key: BLAKE3 of the format, the configuration and the mesh.
fn key(mesh: &Mesh, cfg: &BuildConfig) -> String {
    let mut h = blake3::Hasher::new();
    h.update(&FORMAT.to_le_bytes());
    h.update(&(cfg.bins as u64).to_le_bytes());
    h.update(&(cfg.max_leaf as u64).to_le_bytes());
    h.update(&cfg.c_trav.to_bits().to_le_bytes());
    h.update(&(mesh.positions.len() as u64).to_le_bytes());
    hash_words(&mut h, mesh.positions.iter().flatten().map(|c| c.to_bits()));
    hash_words(&mut h, mesh.tris.iter().flatten().copied());
    h.finalize().to_hex()[..32].to_string()
}

/// Feed words to `h` as little-endian bytes, a block at a time (one
/// `update` per word cost more than the hashing).
pub(crate) fn hash_words(h: &mut blake3::Hasher, words: impl Iterator<Item = u32>) {
    let mut block = Vec::with_capacity(1 << 16);
    for w in words {
        block.extend_from_slice(&w.to_le_bytes());
        if block.len() == block.capacity() {
            h.update(&block);
            block.clear();
        }
    }
    h.update(&block);
}

/// Words: format, node count, prim count, then 9 words per node (tag,
/// bounds lo and hi, two u32), then the prims.
fn encode(b: &Bvh2) -> Vec<u8> {
    let mut w: Vec<u32> = vec![FORMAT, b.nodes.len() as u32, b.prims.len() as u32];
    for n in &b.nodes {
        let (tag, bounds, x, y) = match *n {
            Node::Inner {
                bounds,
                left,
                right,
            } => (0, bounds, left, right),
            Node::Leaf {
                bounds,
                first,
                count,
            } => (1, bounds, first, count),
        };
        w.push(tag);
        w.extend(bounds.lo.iter().chain(&bounds.hi).map(|f| f.to_bits()));
        w.extend([x, y]);
    }
    w.extend(&b.prims);
    w.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// The tree of [`encode`]'s bytes, `None` if they are not one.
fn decode(v: &[u8]) -> Option<Bvh2> {
    if !v.len().is_multiple_of(4) {
        return None;
    }
    let w: Vec<u32> = v
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    let (&[format, nodes, prims], rest) = w.split_first_chunk::<3>()?;
    let (nodes, prims) = (nodes as usize, prims as usize);
    if format != FORMAT || rest.len() != 9 * nodes + prims {
        return None;
    }
    let f = |x: u32| f32::from_bits(x);
    let node = |c: &[u32]| {
        let bounds = Aabb {
            lo: [f(c[1]), f(c[2]), f(c[3])],
            hi: [f(c[4]), f(c[5]), f(c[6])],
        };
        match c[0] {
            0 => Some(Node::Inner {
                bounds,
                left: c[7],
                right: c[8],
            }),
            1 => Some(Node::Leaf {
                bounds,
                first: c[7],
                count: c[8],
            }),
            _ => None,
        }
    };
    let (head, tail) = rest.split_at(9 * nodes);
    let nodes: Option<Vec<Node>> = head.chunks_exact(9).map(node).collect();
    Some(Bvh2 {
        nodes: nodes?,
        prims: tail.to_vec(),
        build_seconds: 0.0,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(n: usize) -> Mesh {
        let mut m = Mesh::default();
        for i in 0..n {
            let x = i as f32;
            let b = m.positions.len() as u32;
            m.positions
                .extend([[x, 0.0, 0.0], [x + 1.0, 0.0, 0.5], [x, 1.0, 0.25]]);
            m.tris.push([b, b + 1, b + 2]);
        }
        m
    }

    #[test]
    fn a_second_build_reads_the_same_tree_from_the_cache() {
        let d = std::env::temp_dir().join(format!("rtsim-cache-test-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        let (mesh, cfg) = (grid(300), BuildConfig::default());
        let (a, sa) = build_in(&d, &mesh, &cfg).unwrap();
        let (b, sb) = build_in(&d, &mesh, &cfg).unwrap();
        assert_eq!((sa, sb), (Source::Built, Source::Cache));
        assert_eq!((a.nodes, a.prims), (b.nodes, b.prims));
        // Another mesh or configuration is another key.
        let other = BuildConfig { max_leaf: 2, ..cfg };
        assert_eq!(build_in(&d, &mesh, &other).unwrap().1, Source::Built);
        assert_eq!(build_in(&d, &grid(301), &cfg).unwrap().1, Source::Built);
        // A damaged file is rebuilt, not trusted.
        for e in std::fs::read_dir(&d).unwrap() {
            std::fs::write(e.unwrap().path(), b"not a tree").unwrap();
        }
        assert_eq!(build_in(&d, &mesh, &cfg).unwrap().1, Source::Built);
        assert_eq!(build_in(&d, &mesh, &cfg).unwrap().1, Source::Cache);
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn threads_wanting_the_same_tree_at_once_build_it_once() {
        let d = std::env::temp_dir().join(format!("rtsim-cache-once-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        let (mesh, cfg) = (grid(20_000), BuildConfig::default());
        let mut got: Vec<(Source, Bvh2)> = std::thread::scope(|s| {
            let hs: Vec<_> = (0..3)
                .map(|_| s.spawn(|| build_in(&d, &mesh, &cfg).unwrap()))
                .collect();
            hs.into_iter()
                .map(|h| h.join().unwrap())
                .map(|(b, s)| (s, b))
                .collect()
        });
        got.sort_by_key(|(s, _)| *s != Source::Built);
        let sources: Vec<Source> = got.iter().map(|g| g.0).collect();
        assert_eq!(sources, [Source::Built, Source::Cache, Source::Cache]);
        assert!(got.iter().all(|g| g.1.nodes == got[0].1.nodes));
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn truncated_or_foreign_bytes_do_not_decode() {
        let mesh = grid(40);
        let b = Bvh2::build(&mesh, &BuildConfig::default()).unwrap();
        let bytes = encode(&b);
        assert!(decode(&bytes).is_some());
        assert!(decode(&bytes[..bytes.len() - 4]).is_none());
        assert!(decode(&bytes[..7]).is_none());
        let mut wrong = bytes.clone();
        wrong[0] ^= 1;
        assert!(decode(&wrong).is_none(), "another format version");
    }
}
