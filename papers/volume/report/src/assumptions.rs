//! What the choices the paper leaves open move: the view (the volume
//! filling 88% of the frame, or its bounding sphere just inside it) and the transfer
//! function's opacity (ours, scaled by 0.5 and 2), each measured on the
//! engine by the sse and bvh casters against the reports' settings.

use crate::measure::{density, measure, sample, Dataset, Framing, Method};
use crate::rows::{density_rows, whole_machine};
use repro::{AppError, AppResult, ReproduceArgs, Row};
use scene::transfer::{Transfer, TransferFile};
use std::sync::Arc;

/// The dataset the assumptions are measured on.
const DATASET: &str = "engine";

/// The engine's transfer function.
const ENGINE_TF: &str = include_str!("../../../../configs/transfer/engine.ron");

/// Transfer function `text` with every control point's opacity scaled by
/// `k` (at most 1).
pub(crate) fn scaled(text: &str, k: f32) -> AppResult<Transfer> {
    let mut f = TransferFile::parse(text).map_err(AppError)?;
    for p in &mut f.points {
        p.rgba[3] = (p.rgba[3] * k).min(1.0);
    }
    Transfer::new(&f.points).map_err(AppError)
}

/// One variant of the engine: its name, setting, and the dataset.
fn variants(base: &Dataset) -> AppResult<Vec<(&'static str, &'static str, Dataset)>> {
    let mut out = vec![
        ("reports", "reports", base.clone()),
        (
            "view",
            "bounding sphere framed",
            base.reframed(Framing::Sphere),
        ),
    ];
    for (k, name) in [(0.5, "opacity x0.5"), (2.0, "opacity x2")] {
        // The reports' first step kept: the opacity alone changes.
        out.push(("opacity", name, base.with_transfer(scaled(ENGINE_TF, k)?)));
    }
    Ok(out)
}

/// Rows for each variant: fps of sse and bvh on the whole machine, the
/// sampling density, and each fps over the reports' setting's.
pub(crate) fn assumption_rows(
    a: &ReproduceArgs,
    m: &sim::MachineConfig,
    (chip, groups): (u32, usize),
    ops: &mut u64,
    bad: &mut usize,
) -> AppResult<Vec<Row>> {
    let base = Dataset::load(DATASET, ('u', 4), a.quick)?;
    let mut rows = Vec::new();
    let mut reference = [0f64; 2];
    for (i, (assumption, setting, ds)) in variants(&base)?.into_iter().enumerate() {
        let ds = Arc::new(ds);
        let smp = sample(&ds, groups, a.seed);
        let k = |r: Row| {
            r.key("dataset", DATASET)
                .key("assumption", assumption)
                .key("setting", setting)
        };
        rows.extend(density_rows(k, &ds, &density(&smp)));
        for (j, method) in [Method::Sse, Method::Bvh].into_iter().enumerate() {
            let c = measure(m, &ds, &smp, method, &a.progress)?;
            *ops += c.ops;
            *bad += c.mismatches();
            let fps = whole_machine(c.fps, chip);
            if i == 0 {
                reference[j] = fps;
            }
            let k = |r: Row| k(r).key("method", method.name());
            rows.push(k(Row::new("fps", fps).key("cores", chip).unit("frame/s")));
            rows.push(k(Row::new("fps_over_reports_setting", fps / reference[j])));
        }
    }
    Ok(rows)
}
