//! `rtsim list scenes` and `rtsim render`.

use crate::io::write_atomic;
use crate::report::{Format, Report, Row};
use crate::{AppError, AppResult};
use scene::bvh::{BuildConfig, Bvh4};
use scene::reference::{Ray, Reference};
use scene::scene::{Scene, BUILTIN};
use std::path::PathBuf;
use std::time::Instant;

/// How `render` colours a pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shade {
    /// The hit triangle's normal, facing the camera, as a colour.
    Normals,
    /// Distance, near = bright.
    Depth,
    /// Number of surfaces the ray crosses (depth complexity).
    Hits,
}

impl Shade {
    /// Every shading with its name.
    pub const ALL: [(Shade, &'static str); 3] = [
        (Shade::Normals, "normals"),
        (Shade::Depth, "depth"),
        (Shade::Hits, "hits"),
    ];
    /// The shading called `s`, or an error listing them.
    pub fn from_name(s: &str) -> Result<Shade, String> {
        Shade::ALL
            .iter()
            .find(|x| x.1 == s)
            .map(|x| x.0)
            .ok_or_else(|| format!("unknown shading '{s}' (normals, depth, hits)"))
    }
}

/// `rtsim render` options.
#[derive(Clone, Debug)]
pub struct RenderArgs {
    /// A built-in scene (`rtsim list scenes`), a scene .ron, or a mesh file.
    pub scene: String,
    /// PNG to write.
    pub out: PathBuf,
    /// Shading.
    pub shade: Shade,
    /// Image width (default: the scene camera's).
    pub width: Option<u32>,
    /// Image height (default: the scene camera's, scaled with --width).
    pub height: Option<u32>,
}

/// `rtsim render`: primary hits of the reference intersector as a PNG.
pub fn render(a: &RenderArgs) -> AppResult<()> {
    let start = Instant::now();
    let mut scene = Scene::load(&a.scene).map_err(|e| AppError(e.0))?;
    let cam = &mut scene.config.camera;
    if let Some(w) = a.width {
        let h = a.height.unwrap_or(
            ((u64::from(cam.height) * u64::from(w)) / u64::from(cam.width)).max(1) as u32,
        );
        (cam.width, cam.height) = (w, h);
    } else if let Some(h) = a.height {
        cam.height = h;
    }
    if cam.width == 0 || cam.height == 0 || cam.width > 16384 || cam.height > 16384 {
        return Err(AppError("--width/--height: must be 1 to 16384".into()));
    }
    let cam = scene.config.camera.clone();
    let (bvh, _) =
        scene::bvh_cache::build(&scene.mesh, &BuildConfig::default()).map_err(AppError)?;
    let refi = Reference::with_bvh(&scene.mesh, &bvh);
    let (w, h) = (cam.width as usize, cam.height as usize);
    let mut t = vec![f64::NAN; w * h];
    let mut shade = vec![[0u8; 3]; w * h];
    let mut count = vec![0u32; w * h];
    std::thread::scope(|s| {
        let rows_per = h.div_ceil(2);
        let chunks: Vec<_> = t
            .chunks_mut(rows_per * w)
            .zip(shade.chunks_mut(rows_per * w))
            .zip(count.chunks_mut(rows_per * w))
            .enumerate()
            .collect();
        for (k, ((tc, sc), cc)) in chunks {
            let (cam, refi, mesh) = (&cam, &refi, &scene.mesh);
            s.spawn(move || {
                for i in 0..tc.len() {
                    let (x, y) = (i % w, k * rows_per + i / w);
                    let (org, dir) = cam.ray(x as f64 + 0.5, y as f64 + 0.5);
                    let ray = Ray::new(org, dir);
                    if a.shade == Shade::Hits {
                        cc[i] = refi.all(&ray).len() as u32;
                        continue;
                    }
                    if let Some(hit) = refi.closest(&ray) {
                        tc[i] = hit.t;
                        let [p, q, r] = mesh.tri(hit.prim as usize).map(|v| v.map(f64::from));
                        let (e1, e2) = (
                            [q[0] - p[0], q[1] - p[1], q[2] - p[2]],
                            [r[0] - p[0], r[1] - p[1], r[2] - p[2]],
                        );
                        let mut n = [
                            e1[1] * e2[2] - e1[2] * e2[1],
                            e1[2] * e2[0] - e1[0] * e2[2],
                            e1[0] * e2[1] - e1[1] * e2[0],
                        ];
                        let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt().max(1e-300);
                        if n[0] * dir[0] + n[1] * dir[1] + n[2] * dir[2] > 0.0 {
                            n = n.map(|c| -c);
                        }
                        sc[i] = n.map(|c| ((c / l * 0.5 + 0.5) * 255.0).round() as u8);
                    }
                }
            });
        }
    });
    let rgb: Vec<u8> = match a.shade {
        Shade::Normals => shade.iter().flatten().copied().collect(),
        Shade::Depth => {
            let (lo, hi) = t
                .iter()
                .filter(|v| v.is_finite())
                .fold((f64::MAX, f64::MIN), |(a, b), &v| (a.min(v), b.max(v)));
            t.iter()
                .flat_map(|&v| {
                    let g = if v.is_finite() {
                        (255.0 * (1.0 - 0.85 * (v - lo) / (hi - lo).max(1e-300))) as u8
                    } else {
                        0
                    };
                    [g, g, g]
                })
                .collect()
        }
        Shade::Hits => {
            let m = count.iter().copied().max().unwrap_or(0).max(1);
            count
                .iter()
                .flat_map(|&c| {
                    let g = (255 * c / m) as u8;
                    [g, g / 2, 255 - g]
                })
                .collect()
        }
    };
    write_atomic(&a.out, &crate::png::encode(cam.width, cam.height, &rgb))?;
    let hits = if a.shade == Shade::Hits {
        count.iter().filter(|&&c| c > 0).count()
    } else {
        t.iter().filter(|v| v.is_finite()).count()
    };
    println!(
        "wrote {}: {} ({} triangles), {}x{}, {:.1}% of pixels hit, {:.2} s",
        a.out.display(),
        scene.config.name,
        scene.mesh.len(),
        cam.width,
        cam.height,
        100.0 * hits as f64 / (w * h) as f64,
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

/// `rtsim list scenes`: load each, build and validate its BVHs, report them.
pub fn list_scenes(names: &[String], format: Format) -> AppResult<()> {
    let start = Instant::now();
    let mut rows = Vec::new();
    if let Some(n) = names.iter().find(|n| !BUILTIN.iter().any(|(b, _)| b == n)) {
        let all: Vec<&str> = BUILTIN.iter().map(|(b, _)| *b).collect();
        return Err(AppError(format!(
            "list scenes: no built-in scene '{n}' (one of: {})",
            all.join(", ")
        )));
    }
    let chosen = BUILTIN
        .iter()
        .filter(|(b, _)| names.is_empty() || names.iter().any(|n| n == b));
    for (name, _) in chosen {
        let scene = match Scene::load(name) {
            Ok(s) => s,
            Err(e) => {
                rows.push(
                    Row::new("available", 0.0)
                        .key("name", name)
                        .key("note", &e.0),
                );
                continue;
            }
        };
        let cfg = BuildConfig::default();
        let (b, source) = scene::bvh_cache::build(&scene.mesh, &cfg).map_err(AppError)?;
        b.validate(&scene.mesh)
            .map_err(|e| AppError(format!("{name}: BVH2: {e}")))?;
        let b4 = Bvh4::collapse(&b);
        b4.validate(&b, &scene.mesh)
            .map_err(|e| AppError(format!("{name}: BVH4: {e}")))?;
        let k = |r: Row| {
            r.key("name", name)
                .key("stands_for", &scene.config.stands_for)
        };
        rows.push(k(Row::new("triangles", scene.mesh.len() as f64)));
        if let Some(p) = scene.config.paper_triangles {
            rows.push(k(Row::new("paper_triangles", p as f64)));
            let ratio = scene.mesh.len() as f64 / p as f64;
            rows.push(k(Row::new("triangles_vs_paper", ratio)));
        }
        rows.push(k(Row::new("bvh2_build_seconds", b.build_seconds).unit("s")));
        let cached = f64::from(u8::from(source == scene::bvh_cache::Source::Cache));
        rows.push(k(Row::new("bvh2_from_cache", cached)));
        rows.push(k(Row::new("bvh2_sah_cost", b.sah_cost(cfg.c_trav))));
        rows.push(k(Row::new("bvh2_depth", b.depth() as f64)));
        rows.push(k(Row::new("bvh4_nodes", b4.nodes.len() as f64)));
    }
    let rep = Report {
        report: "list-scenes".into(),
        machine: None,
        isa: None,
        fidelity: "none".into(),
        sample: None,
        input: Some(format!(
            "configs/scenes, data from {}",
            scene::scene::data_root().display()
        )),
        ops_simulated: 0,
        host_seconds: start.elapsed().as_secs_f64(),
        rows,
        notes: Vec::new(),
    };
    print!("{}", rep.render(format));
    Ok(())
}
