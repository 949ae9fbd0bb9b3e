//! The multi-hit paper's kernels for `rtsim replay`: naive and node
//! culling, single rays and packets, on the 16x16 centre block of primary
//! rays of the layers scene (its many stacked hits), at N_query 1, 4 and
//! 16 (node culling's Listing 1 walk grows with it).

use crate::measure::pixel_rays;
use isa::{FlavourId, Trace};
use multihit_kernels::filters::Insertion;
use multihit_kernels::{Kernel, Run, Tree, NAIVE_CAPACITY};
use repro::{AppError, AppResult};
use scene::scene::Scene;
use scene::workload::packet_slots;
use std::sync::Arc;

/// Every kernel at each N_query, on `fl`.
///
/// # Errors
/// The scene does not load or its tree does not build.
pub fn traces(fl: FlavourId) -> AppResult<Vec<(String, Trace)>> {
    let scene = Scene::load("layers")?;
    let tree = Arc::new(Tree::build(scene.mesh.clone()).map_err(AppError)?);
    let cam = &scene.config.camera;
    let rays = Arc::new(pixel_rays(cam, (cam.width / 2 - 8, cam.height / 2 - 8), 16));
    let slots = Arc::new(packet_slots(&rays, 16, 1, fl.lanes()));
    let mut out = Vec::new();
    for kernel in Kernel::ALL {
        for n_query in [1, 4, 16] {
            let run = Run {
                kernel,
                n_query,
                capacity: NAIVE_CAPACITY,
                tree: tree.clone(),
                rays: rays.clone(),
                slots: Some(slots.clone()),
                insertion: Insertion::Rows,
            };
            let name = kernel
                .name()
                .replace(" (single ray)", "-single")
                .replace(' ', "-");
            out.push((name, isa::record(&run, fl, kernel.name()).0));
        }
    }
    Ok(out)
}
