//! The DRS paper's kernels for `rtsim replay`: the seven traversal kernels
//! recorded on the centre 8x8 tile (4 samples a pixel) of the conference
//! and ferrari stand-ins, primary, bounce and shadow streams.

use crate::run::tile_stream;
use drs_kernels::methods::{Kernel, Run};
use isa::{FlavourId, Trace};
use repro::{AppError, AppResult};
use scene::loaded::Loaded;

/// Every kernel that runs `fl`'s lanes, on each scene and stream.
///
/// # Errors
/// A scene that does not load.
pub fn traces(fl: FlavourId) -> AppResult<Vec<(String, Trace)>> {
    let mut out = Vec::new();
    for s in ["conference", "ferrari"] {
        let ld = Loaded::load(s, &drs_kernels::BVH).map_err(AppError)?;
        for stream in ["primary", "bounce", "shadow"] {
            let (tile, rays) = tile_stream(&ld, stream, 8, 4, 7)?;
            for k in Kernel::ALL.into_iter().filter(|k| k.supports(fl.lanes())) {
                let mut run = Run::new(k, &ld.scene, &ld.b2, &ld.b4, rays.clone());
                run.packet_tile = Some((tile.size, 4));
                let (t, _) = isa::record(&run, fl, k.name());
                out.push((k.name().to_string(), t));
            }
        }
    }
    Ok(out)
}
