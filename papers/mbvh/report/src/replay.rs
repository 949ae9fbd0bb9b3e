//! The MBVH paper's kernels for `rtsim replay`: MBVH ray streams (the
//! default configuration), single-ray MBVH, W-wide packets and 64-ray
//! packets, each over the streams of one distribution-traced 4x4 tile
//! (16 paths a pixel, primary to the second bounce, shadow rays included)
//! of the conference stand-in at 512x512.

use crate::frame::Prepared;
use isa::{FlavourId, Trace};
use mbvh_kernels::stream::StreamConfig;
use mbvh_kernels::{Kernel, Run};
use repro::AppResult;
use std::sync::Arc;

/// Every kernel on every stream of the tile, on `fl`.
///
/// # Errors
/// The scene does not load.
pub fn traces(fl: FlavourId) -> AppResult<Vec<(String, Trace)>> {
    let pr = Prepared::new("conference", 512)?;
    let tile = pr.tiles(4, 1, 7)[0];
    let kernels = [
        Kernel::Stream(StreamConfig::default()),
        Kernel::Single,
        Kernel::Packet,
        Kernel::LargePacket(mbvh_kernels::large_packet::DEFAULT_PACKET),
    ];
    let mut out = Vec::new();
    for st in pr.streams(tile, 2, 7).into_iter().filter(|s| !s.is_empty()) {
        let rays = Arc::new(st);
        for kernel in kernels {
            let run = Run {
                kernel,
                trees: pr.trees.clone(),
                rays: rays.clone(),
            };
            let name = kernel.name().to_lowercase().replace(' ', "-");
            out.push((name, isa::record(&run, fl, kernel.name()).0));
        }
    }
    Ok(out)
}
