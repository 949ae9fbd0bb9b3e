//! Scenes: RON descriptions in `configs/scenes/` (meshes with transforms and
//! materials, a camera, lights), procedural generators for the papers' scenes
//! no one can redistribute, and a plain mesh file as a scene (camera framing
//! its bounds, a light above it).
//!
//! Mesh files named `data:PATH` are read from the data folder: the
//! `RTSIM_DATA` environment variable, else the project's `data/`.

use crate::bvh::Aabb;
use crate::mesh::{self, Mesh, MeshError};
use crate::shapes::{cuboid, quad};
use isa::rng::Rng;
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// Surface behaviour the workloads need.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Default)]
pub enum Material {
    /// Lambertian.
    #[default]
    Diffuse,
    /// Glossy reflection.
    Glossy,
    /// Perfect mirror.
    Mirror,
}

/// Where a mesh comes from.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum Source {
    /// An OBJ or PLY file (optionally .gz); `data:` for the shared data folder.
    File(String),
    /// A ground quad of half-size `size` at y = 0.
    Ground(f32),
    /// An axis-aligned box.
    Cuboid([f32; 3], [f32; 3]),
    /// A closed icosphere, subdivided `level` times.
    Sphere(u32),
    /// A room with furniture-like boxes (Conference, Saloon): seed, items.
    Room(u64, u32),
    /// A meeting room of tables and chairs whose legs and chair backs are
    /// tessellated round (Conference): seed, tables (4 chairs each), segments
    /// of a round part. Its triangles are in the furniture's curves; the
    /// shell and table tops stay a few large triangles.
    Meeting(u64, u32, u32),
    /// A boardroom of long tables and swivel office chairs (Conference):
    /// seed, tables (in rows of up to five, six chairs each and one at
    /// each row's end), segments of the curves (a multiple of 4, 8 to 256).
    Boardroom(u64, u32, u32),
    /// A cab-over cargo truck with its interior on a ground plane (the
    /// multi-hit paper's truck): seed, crates and drums in its cargo body,
    /// sides of a round part.
    Truck(u64, u32, u32),
    /// Water: a square plane at y = 0 of half-size `half`, subdivided into
    /// cells x cells squares, its vertices raised by a seeded height map of
    /// amplitude `amp` (Ferrari's sea): seed, cells, half, amp.
    Water(u64, u32, f32, f32),
    /// A forest of instanced leaves on trunks (Fern, Fairy Forest): seed, trees, leaves per tree.
    Forest(u64, u32, u32),
    /// A forest of finer leaves (dense plants, SANMIGUEL): seed, trees, leaves
    /// per tree, a leaf's half-size in metres (`Forest`'s is 0.15).
    Foliage(u64, u32, u32, f32),
    /// Parallel layers for depth complexity (multi-hit): layers, cells per side.
    Layers(u32, u32),
}

/// A mesh placed in the scene.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Placed {
    /// The mesh.
    pub source: Source,
    /// Uniform scale (applied first).
    #[serde(default = "one")]
    pub scale: f32,
    /// Rotation about +y in degrees (second).
    #[serde(default)]
    pub rotate_y: f32,
    /// Translation (last).
    #[serde(default)]
    pub translate: [f32; 3],
    /// Material of its triangles.
    #[serde(default)]
    pub material: Material,
    /// Triangles of at least this area (after scaling) take the second
    /// material: the studio (floor, backdrop) merged into a model's file.
    #[serde(default)]
    pub large: Option<(f32, Material)>,
    /// Drop the `large` triangles (a studio's floor and backdrop, where the
    /// scene puts its own ground).
    #[serde(default)]
    pub drop_large: bool,
    /// Simplify the mesh's other triangles (not the `large` ones) to this
    /// many triangles in all by quadric edge collapse ([`crate::simplify`]):
    /// a real model brought down to the size of the paper's.
    #[serde(default)]
    pub simplify: Option<u32>,
    /// Refine the mesh's other triangles (not the `large` ones) in place to
    /// this many triangles in all, largest first ([`crate::refine`]): a real
    /// scan brought to the size of the paper's scene.
    #[serde(default)]
    pub refine: Option<u32>,
}

fn one() -> f32 {
    1.0
}

/// A pinhole camera.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Camera {
    /// Eye position.
    pub eye: [f32; 3],
    /// Point looked at.
    pub target: [f32; 3],
    /// Up direction.
    #[serde(default = "up")]
    pub up: [f32; 3],
    /// Vertical field of view in degrees.
    pub fov: f32,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
}

fn up() -> [f32; 3] {
    [0.0, 1.0, 0.0]
}

impl Camera {
    /// The primary ray through image point (`x`, `y`) in pixels (0,0 is the
    /// top-left corner; pixel centres are at +0.5): origin and unnormalised
    /// direction, in f64.
    #[must_use]
    pub fn ray(&self, x: f64, y: f64) -> ([f64; 3], [f64; 3]) {
        let e = self.eye.map(f64::from);
        let t = self.target.map(f64::from);
        let u = self.up.map(f64::from);
        let norm = |v: [f64; 3]| {
            let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            v.map(|c| c / l)
        };
        let cross = |a: [f64; 3], b: [f64; 3]| {
            [
                a[1] * b[2] - a[2] * b[1],
                a[2] * b[0] - a[0] * b[2],
                a[0] * b[1] - a[1] * b[0],
            ]
        };
        let f = norm([t[0] - e[0], t[1] - e[1], t[2] - e[2]]);
        let r = norm(cross(f, u));
        let v = cross(r, f);
        let h = (f64::from(self.fov).to_radians() / 2.0).tan();
        let aspect = f64::from(self.width) / f64::from(self.height);
        let px = (2.0 * x / f64::from(self.width) - 1.0) * h * aspect;
        let py = (1.0 - 2.0 * y / f64::from(self.height)) * h;
        (
            e,
            [
                f[0] + px * r[0] + py * v[0],
                f[1] + px * r[1] + py * v[1],
                f[2] + px * r[2] + py * v[2],
            ],
        )
    }
}

/// A light.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum Light {
    /// A quad area light: corner, two edge vectors, emitted radiance.
    Quad([f32; 3], [f32; 3], [f32; 3], f32),
    /// A point light: position, intensity.
    Point([f32; 3], f32),
}

/// A scene description (`configs/scenes/*.ron`).
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneConfig {
    /// Name.
    pub name: String,
    /// Which paper scene it stands for.
    pub stands_for: String,
    /// What property it matches, and how it differs.
    pub about: String,
    /// Triangles of the paper's scene it stands for, where the paper gives them.
    #[serde(default)]
    pub paper_triangles: Option<u64>,
    /// Meshes.
    pub meshes: Vec<Placed>,
    /// Camera.
    pub camera: Camera,
    /// Lights.
    pub lights: Vec<Light>,
}

/// A loaded scene.
#[derive(Clone, Debug)]
pub struct Scene {
    /// Its description.
    pub config: SceneConfig,
    /// All triangles, in world space.
    pub mesh: Mesh,
    /// Material per triangle.
    pub materials: Vec<Material>,
    /// [`Scene::bounds`], computed on first use (the path tracer asks per
    /// tile, and a paper-size mesh has millions of vertices).
    bounds: std::sync::OnceLock<Aabb>,
}

/// The scenes shipped in `configs/scenes/`.
pub const BUILTIN: &[(&str, &str)] = &[
    ("crown", include_str!("../../configs/scenes/crown.ron")),
    ("bentley", include_str!("../../configs/scenes/bentley.ron")),
    ("dragon", include_str!("../../configs/scenes/dragon.ron")),
    (
        "sanmiguel",
        include_str!("../../configs/scenes/sanmiguel.ron"),
    ),
    ("bmw", include_str!("../../configs/scenes/bmw.ron")),
    (
        "conference",
        include_str!("../../configs/scenes/conference.ron"),
    ),
    ("ferrari", include_str!("../../configs/scenes/ferrari.ron")),
    ("trex", include_str!("../../configs/scenes/trex.ron")),
    ("fern", include_str!("../../configs/scenes/fern.ron")),
    ("saloon", include_str!("../../configs/scenes/saloon.ron")),
    ("fairy", include_str!("../../configs/scenes/fairy.ron")),
    ("layers", include_str!("../../configs/scenes/layers.ron")),
    ("truck", include_str!("../../configs/scenes/truck.ron")),
    (
        "courtyard",
        include_str!("../../configs/scenes/courtyard.ron"),
    ),
    ("sphere", include_str!("../../configs/scenes/sphere.ron")),
];

/// The data folder: `RTSIM_DATA` when set, else the project's `data/`
/// (the meshes and volumes the reports read, shipped with the source).
#[must_use]
pub fn data_root() -> PathBuf {
    match std::env::var_os("RTSIM_DATA") {
        Some(p) => PathBuf::from(p),
        None => Path::new(env!("CARGO_MANIFEST_DIR"))
            .parent()
            .map_or_else(|| PathBuf::from("data"), |root| root.join("data")),
    }
}

/// What to do about a data file that is not there (appended to the error).
#[must_use]
pub fn missing_data_hint(path: &Path) -> String {
    let root = data_root();
    let how = if std::env::var_os("RTSIM_DATA").is_some() {
        "RTSIM_DATA names a folder without it: unset RTSIM_DATA to use the project's data/ folder, or copy the file there"
    } else {
        "the project ships its data in data/ (a fresh clone has it; a few files are not shipped for their licences); data/README.md says where each file comes from; set RTSIM_DATA to a folder of the same layout that has it"
    };
    format!(
        "{} not found in the data folder {}: {how}",
        path.display(),
        root.display()
    )
}

fn resolve(file: &str) -> PathBuf {
    match file.strip_prefix("data:") {
        Some(rest) => data_root().join(rest),
        None => PathBuf::from(file),
    }
}

/// A `data:` file that must be there, or the hint saying how to get it.
fn existing(file: &str) -> Result<PathBuf, String> {
    let p = resolve(file);
    match file.strip_prefix("data:") {
        Some(rest) if !p.exists() => Err(missing_data_hint(Path::new(rest))),
        _ => Ok(p),
    }
}

/// A scene error.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SceneError(pub String);

impl std::fmt::Display for SceneError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl From<MeshError> for SceneError {
    fn from(e: MeshError) -> Self {
        SceneError(e.to_string())
    }
}

impl Scene {
    /// A built-in scene by name, a scene RON file, or a mesh file.
    pub fn load(name_or_path: &str) -> Result<Scene, SceneError> {
        if let Some((n, text)) = BUILTIN.iter().find(|(n, _)| *n == name_or_path) {
            return Scene::from_ron(text, &format!("configs/scenes/{n}.ron"));
        }
        let p = Path::new(name_or_path);
        let lower = name_or_path.to_lowercase();
        if lower.ends_with(".ron") {
            let text = std::fs::read_to_string(p)
                .map_err(|e| SceneError(format!("{name_or_path}: {e}")))?;
            return Scene::from_ron(&text, name_or_path);
        }
        if [".obj", ".ply", ".obj.gz", ".ply.gz"]
            .iter()
            .any(|e| lower.ends_with(e))
        {
            return Scene::from_mesh_file(p);
        }
        let names: Vec<&str> = BUILTIN.iter().map(|(n, _)| *n).collect();
        Err(SceneError(format!(
            "{name_or_path}: no such scene (built in: {}; or a .ron, .obj or .ply file)",
            names.join(", ")
        )))
    }

    /// Parse a scene description.
    pub fn from_ron(text: &str, file: &str) -> Result<Scene, SceneError> {
        let config: SceneConfig = ron::from_str(text)
            .map_err(|e| SceneError(format!("{file}: line {}: {}", e.position.line, e.code)))?;
        let c = &config.camera;
        if c.width == 0 || c.height == 0 || c.width > 16384 || c.height > 16384 {
            return Err(SceneError(format!(
                "{file}: camera.width/height must be 1 to 16384"
            )));
        }
        if !(c.fov > 0.0 && c.fov < 180.0) {
            return Err(SceneError(format!(
                "{file}: camera.fov must be between 0 and 180 degrees"
            )));
        }
        let mut mesh = Mesh::default();
        let mut materials = Vec::new();
        for (i, p) in config.meshes.iter().enumerate() {
            let (m, mats) =
                placed_mesh(p).map_err(|e| SceneError(format!("{file}: meshes[{i}]: {e}")))?;
            let (s, ang) = (p.scale, p.rotate_y.to_radians());
            let (sn, cs) = ang.sin_cos();
            let t = p.translate;
            mesh.append(&m, |v| {
                let (x, y, z) = (v[0] * s, v[1] * s, v[2] * s);
                [cs * x + sn * z + t[0], y + t[1], -sn * x + cs * z + t[2]]
            });
            materials.extend(mats);
        }
        mesh.check(file)?;
        if mesh.is_empty() {
            return Err(SceneError(format!("{file}: empty scene: no triangles")));
        }
        Ok(Scene {
            config,
            mesh,
            materials,
            bounds: std::sync::OnceLock::new(),
        })
    }

    /// A mesh file as a scene: the camera frames its bounds from the front-right,
    /// a quad light above it.
    pub fn from_mesh_file(path: &Path) -> Result<Scene, SceneError> {
        let mesh = mesh::load(path)?;
        if mesh.is_empty() {
            return Err(SceneError(format!(
                "{}: empty scene: no triangles",
                path.display()
            )));
        }
        let (lo, hi) = mesh.bounds();
        let c = [
            (lo[0] + hi[0]) / 2.0,
            (lo[1] + hi[1]) / 2.0,
            (lo[2] + hi[2]) / 2.0,
        ];
        let r = ((hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2) + (hi[2] - lo[2]).powi(2))
            .sqrt()
            / 2.0;
        let eye = [c[0] + 1.2 * r, c[1] + 0.8 * r, c[2] + 2.2 * r];
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().to_string())
            .unwrap_or_default();
        let config = SceneConfig {
            name: name.clone(),
            stands_for: "-".into(),
            about: format!("mesh file {}", path.display()),
            paper_triangles: None,
            meshes: vec![Placed {
                source: Source::File(path.display().to_string()),
                scale: 1.0,
                rotate_y: 0.0,
                translate: [0.0; 3],
                material: Material::Diffuse,
                large: None,
                drop_large: false,
                simplify: None,
                refine: None,
            }],
            camera: Camera {
                eye,
                target: c,
                up: [0.0, 1.0, 0.0],
                fov: 40.0,
                width: 512,
                height: 512,
            },
            lights: vec![Light::Quad(
                [c[0] - r / 2.0, hi[1] + r, c[2] - r / 2.0],
                [r, 0.0, 0.0],
                [0.0, 0.0, r],
                10.0,
            )],
        };
        let materials = vec![Material::Diffuse; mesh.len()];
        Ok(Scene {
            config,
            mesh,
            materials,
            bounds: std::sync::OnceLock::new(),
        })
    }

    /// Bounds of all triangles (computed once: a scene's mesh does not
    /// change after it is loaded).
    #[must_use]
    pub fn bounds(&self) -> Aabb {
        *self.bounds.get_or_init(|| {
            let (lo, hi) = self.mesh.bounds();
            Aabb { lo, hi }
        })
    }
}

/// A closed icosphere of radius 1.
#[must_use]
pub fn icosphere(level: u32) -> Mesh {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut v: Vec<[f64; 3]> = vec![
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ];
    let mut f: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..level {
        let mut mid = std::collections::HashMap::new();
        let mut nf = Vec::with_capacity(f.len() * 4);
        for tri in &f {
            let mut m = [0u32; 3];
            for k in 0..3 {
                let (a, b) = (tri[k].min(tri[(k + 1) % 3]), tri[k].max(tri[(k + 1) % 3]));
                m[k] = *mid.entry((a, b)).or_insert_with(|| {
                    let (p, q) = (v[a as usize], v[b as usize]);
                    v.push([
                        (p[0] + q[0]) / 2.0,
                        (p[1] + q[1]) / 2.0,
                        (p[2] + q[2]) / 2.0,
                    ]);
                    v.len() as u32 - 1
                });
            }
            nf.extend([
                [tri[0], m[0], m[2]],
                [tri[1], m[1], m[0]],
                [tri[2], m[2], m[1]],
                [m[0], m[1], m[2]],
            ]);
        }
        f = nf;
    }
    let positions = v
        .iter()
        .map(|p| {
            let l = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
            [(p[0] / l) as f32, (p[1] / l) as f32, (p[2] / l) as f32]
        })
        .collect();
    Mesh { positions, tris: f }
}

/// Build a source's mesh (in its own space).
/// Trees of `leaves` single-triangle leaves (corners within `half` of a
/// random spot of the crown) on box trunks, on a 40 x 40 ground quad.
fn forest(m: &mut Mesh, seed: u64, trees: u32, leaves: u32, half: f32) {
    let mut r = Rng::new(seed);
    quad(m, [-20.0, 0.0, -20.0], [0.0, 0.0, 40.0], [40.0, 0.0, 0.0]);
    for _ in 0..trees {
        let (x, z) = (r.range(-15.0, 15.0), r.range(-15.0, 15.0));
        let h = r.range(2.0, 5.0);
        cuboid(m, [x - 0.1, 0.0, z - 0.1], [x + 0.1, h, z + 0.1]);
        for _ in 0..leaves {
            // A leaf: one small triangle at a random spot of the crown, random orientation.
            let c = [
                x + r.range(-1.5, 1.5),
                h + r.range(-1.0, 1.5),
                z + r.range(-1.5, 1.5),
            ];
            let b = m.positions.len() as u32;
            for _ in 0..3 {
                m.positions.push([
                    c[0] + r.range(-half, half),
                    c[1] + r.range(-half, half),
                    c[2] + r.range(-half, half),
                ]);
            }
            m.tris.push([b, b + 1, b + 2]);
        }
    }
}

/// Materials by tag byte in the mesh cache.
const MATERIALS: [Material; 3] = [Material::Diffuse, Material::Glossy, Material::Mirror];

/// [`placed_mesh_built`] through the mesh cache ([`crate::mesh_cache`]),
/// keyed by what the build reads: the source, scale, materials, `large` and
/// `refine` as written, and a source file's bytes.
fn placed_mesh(p: &Placed) -> Result<(Mesh, Vec<Material>), String> {
    let what = format!(
        "{:?} {:?} {:?} {:?} {:?}",
        p.source, p.scale, p.material, p.large, p.refine
    );
    // Appended only when used, so the keys of existing scenes stay as they were.
    let what = if p.drop_large || p.simplify.is_some() {
        format!("{what} drop {} simplify {:?}", p.drop_large, p.simplify)
    } else {
        what
    };
    let file = match p.source {
        Source::File(ref f) => crate::mesh_cache::file_digest(&existing(f)?)?,
        _ => [0; 32],
    };
    let tag = |m: &Material| MATERIALS.iter().position(|x| x == m).unwrap_or(0) as u8;
    let (mesh, tags) =
        crate::mesh_cache::cached(&[what.as_bytes(), &file], MATERIALS.len() as u8, || {
            let (m, mats) = placed_mesh_built(p)?;
            Ok((m, mats.iter().map(tag).collect()))
        })?;
    let mats = tags.iter().map(|&t| MATERIALS[t as usize]).collect();
    Ok((mesh, mats))
}

/// A placed mesh before its transform, and its triangles' materials: the
/// `large` triangles split off, the rest refined to `refine` triangles.
fn placed_mesh_built(p: &Placed) -> Result<(Mesh, Vec<Material>), String> {
    let mut m = build_source(&p.source)?;
    let mut mats = vec![p.material; m.len()];
    if let Some((min_area, mat)) = p.large {
        if !(min_area.is_finite() && min_area > 0.0) {
            return Err(format!("large: area {min_area} is not a positive number"));
        }
        let s2 = p.scale * p.scale;
        for (k, &t) in m.tris.iter().enumerate() {
            if crate::refine::area(&m, t) * s2 >= min_area {
                mats[k] = mat;
            }
        }
    }
    if p.drop_large {
        let keep: Vec<bool> = mats.iter().map(|&x| x == p.material).collect();
        let mut k = keep.iter();
        m.tris.retain(|_| *k.next().unwrap_or(&true));
        mats.retain(|&x| x == p.material);
    }
    if let Some(target) = p.simplify {
        if target as usize > m.len() || target == 0 {
            return Err(format!(
                "simplify: {target} is not between 1 and the mesh's {} triangles",
                m.len()
            ));
        }
        let eligible: Vec<bool> = mats.iter().map(|&x| x == p.material).collect();
        let others: Vec<Material> = mats.iter().copied().filter(|&x| x != p.material).collect();
        let from = crate::simplify::simplify(&mut m, target as usize, &eligible)?;
        let mut o = others.into_iter();
        mats = from
            .iter()
            .map(|&e| {
                if e {
                    p.material
                } else {
                    o.next().unwrap_or(p.material)
                }
            })
            .collect();
    }
    if let Some(target) = p.refine {
        if (target as usize) < m.len() || target > 50_000_000 {
            return Err(format!(
                "refine: {target} is not between the mesh's {} triangles and 50000000",
                m.len()
            ));
        }
        let eligible: Vec<bool> = mats.iter().map(|&x| x == p.material).collect();
        let origin = crate::refine::refine(&mut m, target as usize, &eligible);
        mats = origin.iter().map(|&o| mats[o as usize]).collect();
    }
    Ok((m, mats))
}

/// A source's mesh (untransformed).
pub fn build_source(s: &Source) -> Result<Mesh, String> {
    let mut m = Mesh::default();
    match *s {
        Source::File(ref f) => return mesh::load(&existing(f)?).map_err(|e| e.to_string()),
        Source::Ground(size) => quad(
            &mut m,
            [-size, 0.0, -size],
            [0.0, 0.0, 2.0 * size],
            [2.0 * size, 0.0, 0.0],
        ),
        Source::Cuboid(lo, hi) => cuboid(&mut m, lo, hi),
        Source::Sphere(level) => {
            if level > 8 {
                return Err(format!("Sphere({level}): at most 8 subdivisions"));
            }
            m = icosphere(level);
        }
        Source::Room(seed, items) => {
            // A 20 x 6 x 14 room, open toward +z, with tables (top + 4 legs) and chairs.
            let mut r = Rng::new(seed);
            quad(
                &mut m,
                [-10.0, 0.0, -7.0],
                [0.0, 0.0, 14.0],
                [20.0, 0.0, 0.0],
            ); // floor
            quad(
                &mut m,
                [-10.0, 6.0, -7.0],
                [20.0, 0.0, 0.0],
                [0.0, 0.0, 14.0],
            ); // ceiling
            quad(
                &mut m,
                [-10.0, 0.0, -7.0],
                [20.0, 0.0, 0.0],
                [0.0, 6.0, 0.0],
            ); // back wall
            quad(
                &mut m,
                [-10.0, 0.0, -7.0],
                [0.0, 6.0, 0.0],
                [0.0, 0.0, 14.0],
            ); // left
            quad(&mut m, [10.0, 0.0, -7.0], [0.0, 0.0, 14.0], [0.0, 6.0, 0.0]); // right
            for _ in 0..items {
                let (x, z) = (r.range(-8.5, 8.5), r.range(-6.0, 5.0));
                let (w, d, h) = (r.range(0.6, 1.6), r.range(0.5, 1.0), r.range(0.7, 1.1));
                cuboid(&mut m, [x - w, h - 0.06, z - d], [x + w, h, z + d]);
                for (lx, lz) in [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)] {
                    let (cx, cz) = (x + lx * (w - 0.08), z + lz * (d - 0.08));
                    cuboid(
                        &mut m,
                        [cx - 0.04, 0.0, cz - 0.04],
                        [cx + 0.04, h - 0.06, cz + 0.04],
                    );
                }
            }
        }
        Source::Meeting(seed, tables, segments) => {
            if !(3..=256).contains(&segments) || tables > 10_000 {
                return Err(format!(
                    "Meeting({seed}, {tables}, {segments}): segments 3 to 256, at most 10000 tables"
                ));
            }
            crate::shapes::meeting_room(&mut m, seed, tables, segments);
        }
        Source::Boardroom(seed, tables, segments) => {
            if !(8..=256).contains(&segments) || !segments.is_multiple_of(4) || tables > 10_000 {
                return Err(format!(
                    "Boardroom({seed}, {tables}, {segments}): segments a multiple of 4 from 8 to 256, at most 10000 tables"
                ));
            }
            crate::boardroom::boardroom(&mut m, seed, tables, segments);
        }
        Source::Truck(seed, cargo, segments) => {
            if !(8..=4096).contains(&segments) || cargo > 100_000 {
                return Err(format!(
                    "Truck({seed}, {cargo}, {segments}): segments 8 to 4096, at most 100000 cargo items"
                ));
            }
            crate::shapes::truck(&mut m, seed, cargo, segments);
        }
        Source::Water(seed, cells, half, amp) => {
            if !((1..=4096).contains(&cells) && half > 0.0 && half.is_finite() && amp.is_finite()) {
                return Err(format!(
                    "Water({seed}, {cells}, {half}, {amp}): cells 1 to 4096, a positive size, a finite amplitude"
                ));
            }
            crate::shapes::water(&mut m, seed, cells, half, amp);
        }
        Source::Forest(seed, trees, leaves) => forest(&mut m, seed, trees, leaves, 0.15),
        Source::Foliage(seed, trees, leaves, half) => {
            if !(half.is_finite() && half > 0.0 && half <= 1.0) {
                return Err(format!("Foliage: leaf half-size {half} is not in (0, 1]"));
            }
            forest(&mut m, seed, trees, leaves, half);
        }
        Source::Layers(layers, cells) => {
            if cells == 0 {
                return Err("Layers: cells must be at least 1".into());
            }
            let s = 2.0 / cells as f32;
            for l in 0..layers {
                let z = l as f32 * 0.1;
                for i in 0..cells {
                    for j in 0..cells {
                        quad(
                            &mut m,
                            [-1.0 + i as f32 * s, -1.0 + j as f32 * s, z],
                            [s, 0.0, 0.0],
                            [0.0, s, 0.0],
                        );
                    }
                }
            }
        }
    }
    Ok(m)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn procedural_sources_are_valid() {
        for s in [
            Source::Ground(1.0),
            Source::Cuboid([0.0; 3], [1.0; 3]),
            Source::Sphere(2),
            Source::Room(1, 20),
            Source::Forest(2, 10, 50),
            Source::Foliage(2, 10, 50, 0.05),
            Source::Layers(8, 4),
        ] {
            let m = build_source(&s).unwrap();
            m.check("test").unwrap();
            assert!(!m.is_empty(), "{s:?}");
        }
        assert_eq!(build_source(&Source::Sphere(3)).unwrap().len(), 1280);
        assert_eq!(
            build_source(&Source::Layers(10, 4)).unwrap().len(),
            10 * 16 * 2
        );
        assert_eq!(
            build_source(&Source::Room(5, 3)).unwrap(),
            build_source(&Source::Room(5, 3)).unwrap(),
            "seeded"
        );
    }

    #[test]
    fn bad_scene_files_name_the_problem() {
        let e = Scene::from_ron("(name: \"x\", stands_for: \"-\", about: \"-\", meshes: [], camera: (eye: (0,0,0), target: (0,0,1), fov: 40, width: 8, height: 8), lights: [], bogus: 1)", "x.ron").unwrap_err();
        assert!(
            e.0.contains("x.ron: line 1") && e.0.contains("bogus"),
            "{e}"
        );
        let e = Scene::from_ron("(name: \"x\", stands_for: \"-\", about: \"-\", meshes: [], camera: (eye: (0,0,0), target: (0,0,1), fov: 40, width: 8, height: 8), lights: [])", "x.ron").unwrap_err();
        assert!(e.0.contains("empty scene"), "{e}");
        let e = Scene::load("no-such-scene").unwrap_err();
        assert!(e.0.contains("built in"), "{e}");
    }
}
