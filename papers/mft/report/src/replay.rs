//! The MFT paper's kernels for `rtsim replay`: primary multi-frusta and
//! the 16-ray packet baseline over the same 16x16-pixel blocks (four at
//! the T-Rex stand-in's centre, back faces culled as the paper's renderer
//! does), on 16 lanes (AVX-512 on an x86-64 host; LRBni does not run
//! there).

use isa::{FlavourId, Trace};
use mft_kernels::{Frusta, FrustaRun, PacketPrimaryRun};
use repro::{AppError, AppResult};
use scene::bvh::{BuildConfig, Bvh2};
use scene::scene::Scene;

/// Both kernels on the blocks, on a 16-lane `fl`; none on other widths.
///
/// # Errors
/// The scene does not load or its BVHs do not build.
pub fn traces(fl: FlavourId) -> AppResult<Vec<(String, Trace)>> {
    if fl.lanes() != 16 {
        return Ok(Vec::new());
    }
    let scene = Scene::load("trex")?;
    let shallow = Bvh2::build(&scene.mesh, &mft_kernels::SHALLOW_BVH).map_err(AppError)?;
    let deep = Bvh2::build(&scene.mesh, &BuildConfig::default()).map_err(AppError)?;
    let cam = &scene.config.camera;
    let (cx, cy) = (cam.width / 32, cam.height / 32);
    let mut out = Vec::new();
    for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
        let sets = vec![Frusta::primary(cam, cx + dx, cy + dy)];
        let frusta = FrustaRun {
            scene: &scene,
            bvh: &shallow,
            sets: sets.clone(),
            cull_back: true,
            packets256: false,
            shrink: mft_kernels::Shrink::None,
            plane_noise: mft_kernels::PlaneNoise::Reject,
            slab: mft_kernels::SlabTest::Paper,
        };
        out.push(("frusta".to_string(), isa::record(&frusta, fl, "mft").0));
        let packets = PacketPrimaryRun {
            scene: &scene,
            bvh: &deep,
            sets,
            cull_back: true,
            leaves: mft_kernels::PacketLeaves::Indexed,
            plane_noise: mft_kernels::PlaneNoise::Reject,
            grouping: mft_kernels::PacketGrouping::PerFrustum,
        };
        out.push(("packets16".to_string(), isa::record(&packets, fl, "p16").0));
    }
    Ok(out)
}
