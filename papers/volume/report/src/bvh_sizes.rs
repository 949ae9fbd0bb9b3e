//! `volume-bvh`: the implicit BVH by leaf size L = 1, 2, 4, 8: its size
//! against the volume's, its build time, and the bvh caster's frame rate
//! (one core of the workstation, the same sampled packets for every L).

use crate::measure::{measure, sample, Dataset, Method};
use crate::paper::BVH_FOOTPRINT;
use crate::rows::fps_rows;
use repro::{AppResult, Produced, Report, ReproduceArgs, Row};
use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::Instant;

/// Datasets and the leaf sizes measured on each (L = 1 on the engine would
/// take 11 M nodes: left to the neghip, as the paper's 48x example).
const CASES: [(&str, char, &[u32]); 2] =
    [("neghip", 'u', &[1, 2, 4, 8]), ("engine", 'u', &[2, 4, 8])];

/// `volume-bvh`.
pub(crate) fn volume_bvh(a: &ReproduceArgs) -> AppResult<Produced> {
    let start = Instant::now();
    let m = crate::reports::one_core(a)?;
    let g = a.tiles.map_or(if a.quick { 8 } else { 32 }, |t| t as usize);
    let (mut rows, mut ops, mut bad) = (Vec::new(), 0u64, 0usize);
    for (name, lit, leaves) in CASES.into_iter().filter(|c| a.runs(c.0)) {
        for &leaf in leaves {
            let ds = Arc::new(Dataset::load(name, (lit, leaf), a.quick)?);
            let smp = sample(&ds, g, a.seed);
            let c = measure(&m, &ds, &smp, Method::Bvh, &a.progress)?;
            ops += c.ops;
            bad += c.mismatches();
            let k = |r: Row| r.key("dataset", name).key("leaf", leaf);
            let ratio = ds.tree.bytes() as f64 / ds.prepared.volume.len() as f64;
            let mut r = k(Row::new("bvh_bytes_over_volume_bytes", ratio));
            r.paper = BVH_FOOTPRINT
                .iter()
                .find(|p| p.1 == leaf && (p.0 == name || p.0 == "any"))
                .map(|p| p.2);
            rows.push(r);
            rows.push(k(Row::new("bvh_nodes", ds.tree.nodes.len() as f64)));
            rows.push(k(Row::new("bvh_build_seconds", ds.build_seconds)).unit("host-measured"));
            rows.extend(fps_rows(k, &c, None));
            rows.push(k(Row::new("traversal_cycle_share", c.traversal_share)));
            let d = crate::measure::density(&smp);
            let mut r = k(Row::new("samples_per_voxel", d.samples_per_voxel));
            r.paper = Some(crate::measure::SAMPLES_PER_VOXEL);
            rows.push(r);
        }
    }
    let mut s = BTreeMap::new();
    s.insert("design".into(), serde_json::json!(format!("the bvh caster as in volume-fig5, {g} sampled packets (the same for every L), one core of {}", m.name)));
    s.insert("seed".into(), serde_json::json!(a.seed));
    Ok(Produced {
        mismatches: bad as f64,
        report: Report {
            report: "volume-bvh".into(),
            machine: Some(m.name.clone()),
            isa: Some(m.flavour().name().into()),
            fidelity: "full".into(),
            sample: Some(s),
            input: Some("neghip, engine".into()),
            ops_simulated: ops,
            host_seconds: start.elapsed().as_secs_f64(),
            rows,
            notes: vec![
                "A node is 32 bytes (box, range and split axis, child); the paper does not give its node size.".into(),
                "Build times are host-measured on this machine (the paper's: one core of the i7).".into(),
            ],
        },
    })
}
