//! Each dataset as rendered: the "bvh" caster's whole frame (run natively:
//! the same code, its ops not timed) beside the f64 reference's, their
//! agreement over every pixel, and a PNG.

use crate::measure::Dataset;
use rayon::prelude::*;
use repro::AppResult;
use scene::volume_ref::cast;
use std::sync::Arc;
use volume_kernels::bvh::Heuristics;
use volume_kernels::{BvhRun, Rays};

/// A frame's agreement with the reference: the largest difference in a
/// channel, the PSNR, and the share of pixels off by more than 0.05.
pub(crate) struct Agreement {
    pub(crate) max: f64,
    pub(crate) psnr: f64,
    pub(crate) off: f64,
    /// Pixels differing by more than `tol` in a channel.
    pub(crate) bad: usize,
    /// The caster's frame, RGB rows.
    pub(crate) rgb: Vec<u8>,
    /// Whether eq. 7 was on: its constant nodes take their range's colour,
    /// lit by the ambient term only (the paper: "one can forgo lighting"),
    /// so colours may leave the reference by design.
    pub(crate) approximate: bool,
}

impl Agreement {
    /// The pixels off that count as mismatches: all of them when the
    /// colours are the reference's by construction, none when eq. 7
    /// approximates them (they are reported as `frame_pixels_off_reference`;
    /// the same frame without eq. 7 is held to the reference).
    pub(crate) fn mismatches(&self) -> usize {
        if self.approximate {
            0
        } else {
            self.bad
        }
    }
}

/// Render `ds` at `res` x `res` with the bvh caster (natively) and the
/// reference; write the caster's frame to `png` if given.
pub(crate) fn frame(
    png: Option<std::path::PathBuf>,
    ds: &Dataset,
    res: u32,
    tol: f64,
) -> AppResult<Agreement> {
    let fr = frames(ds, res, tol, &[ds.heuristics]).remove(0);
    if let Some(path) = png {
        write_png(&path, res, &fr.rgb)?;
    }
    Ok(fr)
}

/// The frame of `ds` at `res` x `res` rendered by the bvh caster once per
/// heuristics in `variants`, each held to the one reference frame.
pub(crate) fn frames(ds: &Dataset, res: u32, tol: f64, variants: &[Heuristics]) -> Vec<Agreement> {
    let (rays, pixel) = frame_rays(ds, res);
    let want: Vec<[f64; 4]> = (0..rays.len())
        .into_par_iter()
        .map(|i| {
            let (o, d) = (rays.org[i].map(f64::from), rays.dir[i].map(f64::from));
            cast(&ds.prepared.volume, &ds.prepared.tf, o, d, &ds.sampling)
        })
        .collect();
    variants
        .iter()
        .map(|&h| Agreement {
            approximate: h.delta_sv > 0.0,
            ..agreement(&render(ds, &rays, h), &want, (&pixel, res), tol)
        })
        .collect()
}

/// The frame's rays in packet order and each one's pixel.
fn frame_rays(ds: &Dataset, res: u32) -> (Rays, Vec<usize>) {
    let dims = ds.prepared.volume.dims;
    let per = res / 8;
    let (mut org, mut dir, mut pixel) = (Vec::new(), Vec::new(), Vec::new());
    for (px, py) in (0..per).flat_map(|y| (0..per).map(move |x| (x, y))) {
        let r = Rays::packet(dims, ds.eye, ds.fov, (res, res), (px, py));
        org.extend(r.org);
        dir.extend(r.dir);
        for k in 0..64u32 {
            let (p, l) = (k / 4, k % 4);
            let (x, y) = (px * 8 + (p % 4) * 2 + l % 2, py * 8 + (p / 4) * 2 + l / 2);
            pixel.push((y * res + x) as usize);
        }
    }
    (Rays { org, dir }, pixel)
}

/// The bvh caster's colours of `rays` (whole packets) with heuristics `h`:
/// runs of 64 packets in parallel, results in order.
fn render(ds: &Dataset, rays: &Rays, h: Heuristics) -> Vec<[f32; 4]> {
    let per_run = 64 * 64;
    (0..rays.len().div_ceil(per_run))
        .into_par_iter()
        .map(|c| {
            let (lo, hi) = (c * per_run, ((c + 1) * per_run).min(rays.len()));
            let part = Rays {
                org: rays.org[lo..hi].to_vec(),
                dir: rays.dir[lo..hi].to_vec(),
            };
            let run = BvhRun {
                prepared: ds.prepared.clone(),
                tree: ds.tree.clone(),
                rays: Arc::new(part),
                sampling: ds.sampling,
                heuristics: h,
            };
            isa::run_native(&run, isa::FlavourId::Sse4).0
        })
        .collect::<Vec<_>>()
        .into_iter()
        .flatten()
        .collect()
}

/// `got` against `want` pixel by pixel, and `got` as RGB rows.
fn agreement(
    got: &[[f32; 4]],
    want: &[[f64; 4]],
    (pixel, res): (&[usize], u32),
    tol: f64,
) -> Agreement {
    let mut rgb = vec![0u8; (res * res * 3) as usize];
    let (mut max, mut se, mut off, mut bad) = (0f64, 0f64, 0usize, 0usize);
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        let mut px = 0f64;
        for c in 0..4 {
            let d = (f64::from(g[c]) - w[c]).abs();
            px = px.max(d);
            se += d * d;
        }
        max = max.max(px);
        off += usize::from(px > 0.05);
        bad += usize::from(px > tol);
        for c in 0..3 {
            rgb[3 * pixel[i] + c] = (g[c].clamp(0.0, 1.0) * 255.0).round() as u8;
        }
    }
    let n = got.len().max(1) as f64;
    Agreement {
        max,
        psnr: 10.0 * (1.0 / (se / (4.0 * n)).max(1e-30)).log10(),
        off: off as f64 / n,
        bad,
        rgb,
        approximate: false,
    }
}

/// Write a square frame's RGB rows as a PNG (atomically).
pub(crate) fn write_png(path: &std::path::Path, res: u32, rgb: &[u8]) -> AppResult<()> {
    repro::io::write_atomic(path, &repro::png::encode(res, res, rgb))
}
