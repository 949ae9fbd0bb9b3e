//! The volume paper's casters for `rtsim replay`: the naive scalar caster
//! as gcc builds it, Listing 2 ("sse") and the coherent implicit-BVH
//! caster ("bvh", the paper's heuristics), over a 24x24 image of a 32^3
//! mixing-layer volume (trilinear, Phong-lit, 0.5-voxel steps), on SSE4
//! (the casters' 4 lanes).

use isa::{FlavourId, Trace};
use repro::AppResult;
use scene::transfer::Transfer;
use scene::volume::Volume;
use scene::volume_bvh::MinMaxBvh;
use scene::volume_ref::{Filter, Lighting, Sampling};
use std::sync::Arc;
use volume_kernels::bvh::{ConstantAt, Heuristics};
use volume_kernels::naive::{GccRun, Translation};
use volume_kernels::{BvhRun, Prepared, Rays, Run};

const TF: &str = "(points: [(value: 0.0, rgba: (0.0, 0.0, 0.0, 0.0)), (value: 70.0, rgba: (0.1, 0.2, 0.8, 0.02)), (value: 160.0, rgba: (0.9, 0.6, 0.1, 0.15)), (value: 255.0, rgba: (1.0, 1.0, 1.0, 0.6))])";

/// The three casters, on SSE4; none on other flavours.
///
/// # Errors
/// The transfer function does not parse (it is built in).
pub fn traces(fl: FlavourId) -> AppResult<Vec<(String, Trace)>> {
    if fl != FlavourId::Sse4 {
        return Ok(Vec::new());
    }
    let vol = Volume::mixing_layer(32, 9);
    let dims = vol.dims;
    let tree = Arc::new(MinMaxBvh::build(&vol, 4));
    let tf = Transfer::parse(TF).map_err(repro::AppError)?;
    let pr = Arc::new(Prepared::new(vol, tf));
    let c = dims.map(f64::from);
    let eye = [c[0] * 1.9, -c[1] * 0.7, c[2] * 1.4];
    let rays = Arc::new(Rays::camera(dims, eye, 40.0, (24, 24)));
    let sampling = Sampling {
        filter: Filter::Trilinear,
        dt: 0.5,
        rda: 0.0,
        lighting: Lighting::Phong,
        light: [c[0] * 2.0, -c[1], c[2] * 3.0],
        light_threshold: 0.01,
    };
    let (mut org, mut dir) = (Vec::new(), Vec::new());
    for py in 0..3 {
        for px in 0..3 {
            let r = Rays::packet(dims, eye, 40.0, (24, 24), (px, py));
            org.extend(r.org);
            dir.extend(r.dir);
        }
    }
    let packed = Arc::new(Rays { org, dir });
    let gcc = GccRun {
        prepared: pr.clone(),
        rays: rays.clone(),
        sampling,
        translation: Translation::Arithmetic,
    };
    let sse = Run {
        prepared: pr.clone(),
        rays,
        sampling,
    };
    let bvh = BvhRun {
        prepared: pr,
        tree,
        rays: packed,
        sampling,
        heuristics: Heuristics {
            delta_c: 1e-3,
            delta_p: 1.5,
            delta_sv: 1e-4,
            constant_at: ConstantAt::Leaves,
        },
    };
    Ok(vec![
        ("gcc".into(), isa::record(&gcc, fl, "gcc").0),
        ("sse".into(), isa::record(&sse, fl, "sse").0),
        ("bvh".into(), isa::record(&bvh, fl, "bvh").0),
    ])
}
