//! Shading the image: per-pixel hits of primary frusta, the shadow sets
//! from them, visibility counts, the shading setup and its simulated cycles.

use crate::frame::*;
use mft_kernels::shade::{ShadeRun, ShadeSetup};
use mft_kernels::Frusta;
use repro::{AppError, AppResult};
use scene::workload::shadow_group_with;
use scene::Hit;

/// Per-pixel primary hits: (t, prim) row-major, prim -1 for none.
pub(crate) struct Hits {
    pub(crate) t: Vec<f32>,
    pub(crate) prim: Vec<i32>,
}

/// The per-pixel hits of primary frusta sets' output.
pub(crate) fn pixel_hits(sets: &[Frusta], out: &[Hit], w: usize) -> Hits {
    let mut h = Hits {
        t: vec![0.0; w * w],
        prim: vec![-1; w * w],
    };
    for (si, f) in sets.iter().enumerate() {
        for n in 0..16 {
            for k in 0..16 {
                let (x, y) = f.ray_pixel(n, k);
                let hit = out[si * 256 + n * 16 + k];
                let i = y as usize * w + x as usize;
                if let Some(p) = hit.prim {
                    h.t[i] = hit.t;
                    h.prim[i] = p as i32;
                }
            }
        }
    }
    h
}

/// The shadow frusta sets of the image with set rotation `rot`, origins from `hits`.
pub(crate) fn shadow_sets(pr: &Prepared, hits: &Hits, w: u32, rot: u32) -> Vec<Frusta> {
    let size = scene::workload::scene_size(&pr.scene);
    let hit = |x: u32, y: u32| {
        let i = (y * w + x) as usize;
        (hits.prim[i] >= 0).then(|| (f64::from(hits.t[i]), hits.prim[i] as u32))
    };
    (0..w / 4)
        .flat_map(|gy| (0..w / 4).map(move |gx| (4 * gx, 4 * gy)))
        .map(|(x, y)| {
            Frusta::shadow(
                &shadow_group_with(&pr.scene, size, &hit, (x, y), rot, pr.split),
                pr.light,
            )
        })
        .filter(|f| f.active != 0)
        .collect()
}

/// Add each ray's "reaches the light" (prim < 0) to its pixel's count.
pub(crate) fn count_visible(sets: &[Frusta], out: &[Hit], w: u32, vis: &mut [u32]) {
    for (si, f) in sets.iter().enumerate() {
        for n in (0..16).filter(|&n| f.active & (1 << n) != 0) {
            let (x, y) = (f.pixel.0 + n as u32 % 4, f.pixel.1 + n as u32 / 4);
            let free = (0..16)
                .filter(|&k| !out[si * 256 + n * 16 + k].is_hit())
                .count();
            vis[(y * w + x) as usize] += free as u32;
        }
    }
}

/// The shading setup of the prepared scene's camera and light: exposure so
/// a surface facing the light at the scene's centre gets 0.8 direct light.
pub(crate) fn shade_setup(pr: &Prepared, w: u32) -> ShadeSetup {
    let cam = &pr.scene.config.camera;
    let f = |v: [f64; 3]| v.map(|c| c as f32);
    let (eye, d00) = cam.ray(0.5, 0.5);
    let d10 = cam.ray(1.5, 0.5).1;
    let d01 = cam.ray(0.5, 1.5).1;
    let [c, e1, e2] = pr.light;
    let centre = [0, 1, 2].map(|a| c[a] + 0.5 * e1[a] + 0.5 * e2[a]);
    let n = [
        e1[1] * e2[2] - e1[2] * e2[1],
        e1[2] * e2[0] - e1[0] * e2[2],
        e1[0] * e2[1] - e1[1] * e2[0],
    ];
    let len = n
        .iter()
        .map(|x| x * x)
        .sum::<f32>()
        .sqrt()
        .max(f32::MIN_POSITIVE);
    let b = pr.scene.bounds();
    let mid = [0, 1, 2].map(|a| 0.5 * (b.lo[a] + b.hi[a]));
    let d2: f32 = (0..3).map(|a| (centre[a] - mid[a]).powi(2)).sum();
    ShadeSetup {
        width: w,
        height: w,
        eye: f(eye),
        d00: f(d00),
        dx: [0, 1, 2].map(|a| (d10[a] - d00[a]) as f32),
        dy: [0, 1, 2].map(|a| (d01[a] - d00[a]) as f32),
        light_centre: centre,
        light_normal: n.map(|x| x / len),
        scale: 0.8 * d2,
        ambient: 0.1,
    }
}

/// Simulated cycles of shading (and filtering) the whole image on one
/// core: `bands` systematic bands of 16 rows, each split over the core's
/// hardware threads, scaled to the image; (cycles, ops simulated, DRAM
/// bytes per pixel).
pub(crate) fn shade_cycles(
    m: &sim::MachineConfig,
    pr: &Prepared,
    su: &ShadeSetup,
    hits: &Hits,
    vis: &[f32],
    filter: bool,
    bands: u32,
) -> AppResult<(f64, u64, f64)> {
    let h = su.height;
    let band = 16.min(h);
    let threads = m.core.threads.max(1);
    let per = band.div_ceil(threads);
    let (mut cycles, mut ops, mut rows, mut dram) = (0.0, 0u64, 0u32, 0u64);
    for b in 0..bands {
        let y0 = (b * (h / bands.max(1))).min(h - band);
        let traces: Vec<isa::Trace> = (0..threads)
            .map(|t| (y0 + t * per).min(y0 + band)..(y0 + (t + 1) * per).min(y0 + band))
            .filter(|r| !r.is_empty())
            .map(|r| {
                let run = ShadeRun {
                    mesh: &pr.scene.mesh,
                    setup: su,
                    t: &hits.t,
                    prim: &hits.prim,
                    vis,
                    rows: r,
                    filter,
                };
                isa::record(&run, m.flavour(), "shade").0
            })
            .collect();
        let refs: Vec<&isa::Trace> = traces.iter().collect();
        let s = sim::simulate(m, &refs, &sim::SimOptions::default()).map_err(AppError)?;
        ops += traces.iter().map(|t| t.ops.len() as u64).sum::<u64>();
        cycles += s.cycles as f64;
        dram += s.dram_read + s.dram_written;
        rows += band;
    }
    let px = f64::from(rows.max(1)) * f64::from(su.width);
    Ok((
        cycles * f64::from(h) / f64::from(rows.max(1)),
        ops,
        dram as f64 / px,
    ))
}
