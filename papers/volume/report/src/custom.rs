//! `rtsim volume`: a researcher's own volume through the paper's casters.
//! The volume (a raw file named `name_WxHxD_type.raw[.gz]`, or a RON
//! sidecar) and a transfer function (RON) are loaded and checked, the bvh
//! caster's frame is rendered natively and held to the f64 reference (and
//! written as a PNG), and gcc, sse and bvh are timed on sampled packets on
//! one core of a machine. Every input error names its file, field or line;
//! nothing is written unless everything succeeded.

use crate::images::{frame, write_png};
use crate::measure::{measure, sample, Dataset, Method, PIXEL_TOL};
use crate::rows::fps_rows;
use repro::progress::Progress;
use repro::{AppError, AppResult, MachineSpec, Report, Row};
use scene::transfer::Transfer;
use scene::volume::Volume;
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

/// What `rtsim volume` is given.
#[derive(Clone, Debug)]
pub struct VolumeArgs {
    /// The raw volume or its RON sidecar.
    pub volume: PathBuf,
    /// The transfer function (RON).
    pub transfer: PathBuf,
    /// `unlit`, `diffuse` or `phong`.
    pub lighting: String,
    /// Leaf size L of the implicit BVH.
    pub leaf: u32,
    /// Image side in pixels.
    pub res: u32,
    /// Packets timed per caster.
    pub packets: u32,
    /// The machine one core of which times the casters.
    pub machine: MachineSpec,
    /// The sample's seed.
    pub seed: u64,
    /// PNG of the bvh caster's frame.
    pub out: Option<PathBuf>,
}

fn lighting_code(s: &str) -> AppResult<char> {
    match s {
        "unlit" => Ok('u'),
        "diffuse" => Ok('d'),
        "phong" => Ok('p'),
        _ => Err(AppError(format!(
            "--lighting: '{s}' is not unlit, diffuse or phong"
        ))),
    }
}

/// Check the options that need no file.
fn check(a: &VolumeArgs) -> AppResult<char> {
    if ![1, 2, 4, 8].contains(&a.leaf) {
        return Err(AppError(format!("--leaf: {} is not 1, 2, 4 or 8", a.leaf)));
    }
    if a.res < 8 || a.res > 4096 || !a.res.is_multiple_of(8) {
        return Err(AppError(format!(
            "--res: {} is not a multiple of 8 from 8 to 4096",
            a.res
        )));
    }
    if a.packets == 0 || a.packets > 1024 {
        return Err(AppError(format!(
            "--packets: {} is not 1 to 1024",
            a.packets
        )));
    }
    if let Some(out) = &a.out {
        if out.extension().is_none_or(|e| e != "png") {
            return Err(AppError(format!(
                "--out {}: not a .png path",
                out.display()
            )));
        }
    }
    lighting_code(&a.lighting)
}

/// Run `rtsim volume`: the report, and the pixels that differ from the
/// reference by more than the tolerance (the PNG is written only if none).
///
/// # Errors
/// A bad option, volume or transfer function (named), or a failed write.
pub fn volume(a: &VolumeArgs) -> AppResult<(Report, usize)> {
    let start = Instant::now();
    let lit = check(a)?;
    let m0 = a.machine.load()?;
    if m0.flavour().lanes() != 4 {
        return Err(AppError(format!(
            "--machine {}: Listing 2 is 4-wide SSE; {} has {} lanes",
            m0.name,
            m0.flavour(),
            m0.flavour().lanes()
        )));
    }
    let mut m = m0.clone();
    m.cores = 1;
    let vol = Volume::load(&a.volume).map_err(|e| AppError(e.to_string()))?;
    let text = std::fs::read_to_string(&a.transfer)
        .map_err(|e| AppError(format!("{}: {e}", a.transfer.display())))?;
    let tf =
        Transfer::parse(&text).map_err(|e| AppError(format!("{}: {e}", a.transfer.display())))?;
    let ds = Arc::new(Dataset::new(vol, tf, (lit, a.leaf)).with_view(a.res, 1.0));
    let smp = sample(&ds, a.packets as usize, a.seed);
    let progress = Progress::hidden();
    let mut rows = crate::rows::density_rows(|r| r, &ds, &crate::measure::density(&smp));
    let mut bad = 0usize;
    let mut ops = 0u64;
    for me in [Method::Gcc, Method::Sse, Method::Bvh] {
        let c = measure(&m, &ds, &smp, me, &progress)?;
        ops += c.ops;
        bad += c.mismatches();
        let k = |r: Row| r.key("method", me.name());
        rows.extend(fps_rows(k, &c, None));
        rows.push(k(Row::new("samples_per_ray", c.samples_per_ray)));
        rows.push(k(Row::new("instructions_per_ray", c.instr_per_ray)));
        rows.push(k(Row::new("cpi", c.cpi)));
        rows.push(k(Row::new("pixels_off_reference", c.bad as f64)));
        if me == Method::Bvh {
            rows.push(k(Row::new("traversal_cycle_share", c.traversal_share)));
        }
    }
    let fr = frame(None, &ds, a.res, PIXEL_TOL)?;
    bad += fr.mismatches();
    rows.push(Row::new("frame_psnr_vs_reference", fr.psnr).unit("dB"));
    rows.push(Row::new("frame_max_difference", fr.max));
    rows.push(Row::new("frame_pixels_off_reference", fr.bad as f64));
    rows.push(Row::new("bvh_nodes", ds.tree.nodes.len() as f64).key("leaf", a.leaf));
    if let Some(out) = a.out.as_ref().filter(|_| bad == 0) {
        write_png(out, a.res, &fr.rgb)?;
    }
    let mut s = BTreeMap::new();
    s.insert(
        "design".into(),
        serde_json::json!(format!(
            "{} packets of 8x8 pixels at {}^2 from a view filling {:.0}% of the frame with the volume, the first step chosen for {} samples per voxel (each step {} of it longer than the last), timed on one core after warming; the bvh frame rendered natively and compared with the f64 reference",
            a.packets, a.res, crate::measure::FRAME_COVERAGE * 100.0, crate::measure::SAMPLES_PER_VOXEL, crate::measure::RDA_PER_DT
        )),
    );
    s.insert("seed".into(), serde_json::json!(a.seed));
    let report = Report {
        report: "volume".into(),
        machine: Some(m.name.clone()),
        isa: Some(m.flavour().name().into()),
        fidelity: "full".into(),
        sample: Some(s),
        input: Some(a.volume.display().to_string()),
        ops_simulated: ops,
        host_seconds: start.elapsed().as_secs_f64(),
        rows,
        notes: vec![format!(
            "A pixel is off if a channel differs from the f64 reference by more than {PIXEL_TOL}; any off pixel is an error (exit 2) and no PNG is written."
        )],
    };
    Ok((report, bad))
}
