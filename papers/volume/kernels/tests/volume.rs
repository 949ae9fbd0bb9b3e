//! Listing 2's integration, traced and native, against the f64 reference
//! ray caster: every pixel within the stated tolerance, unlit, diffuse and
//! Phong, uniform and differential sampling.

use isa::FlavourId;
use scene::transfer::Transfer;
use scene::volume::Volume;
use scene::volume_ref::{cast, Filter, Lighting, Sampling};
use std::sync::Arc;
use volume_kernels::bvh::ConstantAt;
use volume_kernels::dvr::Counters;
use volume_kernels::naive::{GccRun, Translation};
use volume_kernels::{Prepared, Rays, Run};

const TF: &str = "(points: [(value: 0.0, rgba: (0.0, 0.0, 0.0, 0.0)), (value: 70.0, rgba: (0.1, 0.2, 0.8, 0.02)), (value: 160.0, rgba: (0.9, 0.6, 0.1, 0.15)), (value: 255.0, rgba: (1.0, 1.0, 1.0, 0.6))])";

/// Per channel the largest difference, the PSNR over the image, and the
/// share of pixels off by more than 0.05 in some channel.
fn compare(a: &[[f32; 4]], b: &[[f64; 4]]) -> (f64, f64, f64) {
    let (mut max, mut se, mut off) = (0f64, 0f64, 0usize);
    for (x, y) in a.iter().zip(b) {
        let mut px = 0f64;
        for c in 0..4 {
            let d = (f64::from(x[c]) - y[c]).abs();
            px = px.max(d);
            se += d * d;
        }
        max = max.max(px);
        off += usize::from(px > 0.05);
    }
    let mse = se / (4 * a.len()) as f64;
    (
        max,
        10.0 * (1.0 / mse.max(1e-30)).log10(),
        off as f64 / a.len() as f64,
    )
}

/// The f64 reference's colour for every ray.
fn reference(pr: &Prepared, rays: &Rays, s: &Sampling) -> Vec<[f64; 4]> {
    (0..rays.len())
        .map(|i| {
            let (o, d) = (rays.org[i].map(f64::from), rays.dir[i].map(f64::from));
            cast(&pr.volume, &pr.tf, o, d, s)
        })
        .collect()
}

/// The rays of the 2x2 packets at the corner of a 16x16 image of a
/// `dims` volume seen from `eye`.
fn corner_packets(dims: [u32; 3], eye: [f64; 3]) -> Arc<Rays> {
    let (mut org, mut dir) = (Vec::new(), Vec::new());
    for py in 0..2 {
        for px in 0..2 {
            let r = Rays::packet(dims, eye, 40.0, (16, 16), (px, py));
            org.extend(r.org);
            dir.extend(r.dir);
        }
    }
    Arc::new(Rays { org, dir })
}

/// The paper's heuristics: delta_c 1e-3, delta_p 1.5, delta_sv 1e-4.
const PAPER: volume_kernels::bvh::Heuristics = volume_kernels::bvh::Heuristics {
    delta_c: 1e-3,
    delta_p: 1.5,
    delta_sv: 1e-4,
    constant_at: ConstantAt::Leaves,
};

/// Which caster a check runs.
#[derive(Clone, Copy, Debug)]
enum Caster {
    /// Listing 2 per pixel.
    Sse,
    /// The naive scalar baseline, addresses computed.
    Gcc,
    /// The naive scalar baseline through the offset tables.
    GccTables,
}

fn check(vol: Volume, lighting: Lighting, rda: f64) -> (f64, f64, f64) {
    check_with(vol, Caster::Sse, Filter::Trilinear, (lighting, rda))
}

fn check_with(
    vol: Volume,
    caster: Caster,
    filter: Filter,
    (lighting, rda): (Lighting, f64),
) -> (f64, f64, f64) {
    let dims = vol.dims;
    let pr = Arc::new(Prepared::new(vol, Transfer::parse(TF).unwrap()));
    let c = dims.map(f64::from);
    let eye = [c[0] * 1.9, -c[1] * 0.7, c[2] * 1.4];
    let rays = Arc::new(Rays::camera(dims, eye, 40.0, (24, 24)));
    let s = Sampling {
        filter,
        dt: 0.5,
        rda,
        lighting,
        light: [c[0] * 2.0, -c[1], c[2] * 3.0],
        light_threshold: 0.01,
    };
    let (traced, counts) = match caster {
        Caster::Sse => traced_equals_native(&Run {
            prepared: pr.clone(),
            rays: rays.clone(),
            sampling: s,
        }),
        Caster::Gcc | Caster::GccTables => traced_equals_native(&GccRun {
            prepared: pr.clone(),
            rays: rays.clone(),
            sampling: s,
            translation: match caster {
                Caster::Gcc => Translation::Arithmetic,
                _ => Translation::Tables,
            },
        }),
    };
    assert_eq!(counts.rays, rays.len() as u64);
    assert!(counts.classified > 0 && counts.classified <= counts.samples);
    let want = reference(&pr, &rays, &s);
    assert!(
        want.iter().filter(|p| p[3] > 0.05).count() > 100,
        "the volume is in view"
    );
    compare(&traced, &want)
}

fn traced_equals_native<P: isa::Program<Out = (Vec<[f32; 4]>, Counters)>>(
    run: &P,
) -> (Vec<[f32; 4]>, Counters) {
    let out = isa::record(run, FlavourId::Sse4, "volume").1;
    assert_eq!(
        out,
        isa::run_native(run, FlavourId::Sse4),
        "traced = native"
    );
    out
}

#[test]
fn the_naive_caster_and_nearest_sampling_match_the_reference() {
    // The naive caster normalises exactly (sqrtss and a division), yet its
    // Phong image is as far from the reference as Listing 2's (37.8 dB
    // both, measured): the error is the normals of near-vanishing
    // gradients, not rsqrtps. Sample positions and truncations are
    // Listing 2's (see below). Nearest
    // sampling takes the base voxel's own value: a position that truncates
    // to the neighbouring voxel in f32 changes the value by a whole voxel
    // step, not an interpolated sliver, so a few pixels move further.
    for (caster, filter, lighting, rda, tol) in [
        (
            Caster::Gcc,
            Filter::Trilinear,
            Lighting::Unlit,
            0.0,
            (45.0, 0.05, 0.002),
        ),
        (
            Caster::Gcc,
            Filter::Nearest,
            Lighting::Unlit,
            0.0,
            (44.0, 0.15, 0.01),
        ),
        (
            Caster::GccTables,
            Filter::Trilinear,
            Lighting::Unlit,
            0.0,
            (45.0, 0.05, 0.002),
        ),
        (
            Caster::Gcc,
            Filter::Trilinear,
            Lighting::Phong,
            0.002,
            (35.0, 0.5, 0.01),
        ),
        (
            Caster::Sse,
            Filter::Nearest,
            Lighting::Unlit,
            0.002,
            (44.0, 0.15, 0.01),
        ),
    ] {
        let (max, psnr, off) =
            check_with(Volume::mixing_layer(32, 9), caster, filter, (lighting, rda));
        eprintln!("{caster:?} {filter:?} {lighting:?} rda {rda}: max {max:.4}, PSNR {psnr:.1} dB, {off:.4} off");
        assert!(
            psnr > tol.0 && max < tol.1 && off < tol.2,
            "{caster:?} {filter:?} {lighting:?}: max {max}, PSNR {psnr}, {off} off"
        );
    }
}

#[test]
fn listing_2_matches_the_reference_unlit_and_lit() {
    // Tolerances: PSNR, largest difference, share of pixels off by > 0.05.
    // A sample within f32 rounding of a voxel boundary may land on the other
    // side (Listing 2 truncates the position to pick the base voxel it skips
    // on, and the interpolant to pick the table entry: an interpolant that is
    // an exact integer in f64 may truncate one lower in f32), moving one
    // sample's contribution. Lighting adds rsqrtps (12 bits) and normals of
    // near-vanishing gradients, whose direction f32 does not resolve; Phong's
    // (n . h)^16 multiplies a direction error 16-fold.
    for (lighting, rda, tol) in [
        (Lighting::Unlit, 0.0, (45.0, 0.05, 0.002)),
        (Lighting::Diffuse, 0.0, (40.0, 0.3, 0.01)),
        (Lighting::Phong, 0.002, (35.0, 0.5, 0.01)),
    ] {
        let (max, psnr, off) = check(Volume::mixing_layer(32, 9), lighting, rda);
        eprintln!("{lighting:?} rda {rda}: max {max:.4}, PSNR {psnr:.1} dB, {off:.4} off");
        assert!(
            psnr > tol.0 && max < tol.1 && off < tol.2,
            "{lighting:?}: max {max}, PSNR {psnr}, {off} off"
        );
    }
}

#[test]
fn the_bvh_caster_matches_the_reference_and_skips_work() {
    use scene::volume_bvh::MinMaxBvh;
    use volume_kernels::bvh::Heuristics;
    use volume_kernels::BvhRun;
    let vol = Volume::mixing_layer(32, 9);
    let dims = vol.dims;
    let tree = Arc::new(MinMaxBvh::build(&vol, 4));
    let pr = Arc::new(Prepared::new(vol, Transfer::parse(TF).unwrap()));
    let c = dims.map(f64::from);
    let eye = [c[0] * 1.9, -c[1] * 0.7, c[2] * 1.4];
    let rays = Arc::new(Rays::camera(dims, eye, 40.0, (24, 24)));
    let s = Sampling {
        filter: Filter::Trilinear,
        dt: 0.5,
        rda: 0.0,
        lighting: Lighting::Unlit,
        light: [0.0; 3],
        light_threshold: 0.01,
    };
    let want = reference(&pr, &rays, &s);
    let sse = Run {
        prepared: pr.clone(),
        rays: rays.clone(),
        sampling: s,
    };
    let (sse_img, sse_trace, sse_counts) = {
        let (t, (img, c)) = isa::record(&sse, FlavourId::Sse4, "sse");
        (img, t.ops.len(), c)
    };
    // The same pixels in packet order, and back.
    let packets: Vec<(u32, u32)> = (0..3).flat_map(|y| (0..3).map(move |x| (x, y))).collect();
    let mut order = Vec::new();
    let (mut org, mut dir) = (Vec::new(), Vec::new());
    for &(px, py) in &packets {
        let r = Rays::packet(dims, eye, 40.0, (24, 24), (px, py));
        org.extend(r.org);
        dir.extend(r.dir);
        for k in 0..64u32 {
            let (p, l) = (k / 4, k % 4);
            let (x, y) = (px * 8 + (p % 4) * 2 + l % 2, py * 8 + (p / 4) * 2 + l / 2);
            order.push((y * 24 + x) as usize);
        }
    }
    let packed = Arc::new(Rays { org, dir });
    for (i, &j) in order.iter().enumerate() {
        assert_eq!((packed.org[i], packed.dir[i]), (rays.org[j], rays.dir[j]));
    }
    for (dc, dp, dsv, at) in [
        (0.0, f32::INFINITY, 0.0, ConstantAt::Leaves),
        (1e-3, 1.5, 0.0, ConstantAt::Leaves),
        (1e-3, 1.5, 1e-4, ConstantAt::Leaves),
        (1e-3, 1.5, 1e-4, ConstantAt::EveryNode),
    ] {
        let run = BvhRun {
            prepared: pr.clone(),
            tree: tree.clone(),
            rays: packed.clone(),
            sampling: s,
            heuristics: Heuristics {
                delta_c: dc,
                delta_p: dp,
                delta_sv: dsv,
                constant_at: at,
            },
        };
        let (t, (packed_img, counts)) = isa::record(&run, FlavourId::Sse4, "bvh");
        let native = isa::run_native(&run, FlavourId::Sse4);
        assert_eq!((packed_img.clone(), counts), native, "traced = native");
        // The BVH only removes samples: never more than the brute-force caster.
        assert!(
            counts.samples <= sse_counts.samples,
            "{counts:?} {sse_counts:?}"
        );
        assert!(counts.nodes > 0 && counts.leaf_rays > 0 && counts.frustum_culls > 0);
        let mut img = vec![[0f32; 4]; rays.len()];
        for (i, &j) in order.iter().enumerate() {
            img[j] = packed_img[i];
        }
        let (max, psnr, off) = compare(&img, &want);
        let (smax, spsnr, _) = compare(&sse_img, &want);
        eprintln!(
            "bvh dc {dc} dp {dp} dsv {dsv} {at:?}: max {max:.4} PSNR {psnr:.1} off {off:.4} ops {} (sse: max {smax:.4} PSNR {spsnr:.1} ops {sse_trace})",
            t.ops.len()
        );
        assert!(
            psnr > 40.0 && max < 0.3 && off < 0.02,
            "dc {dc}: max {max}, PSNR {psnr}, {off}"
        );
    }
}

#[test]
fn the_constant_subvolume_routine_is_exact_on_a_constant_field() {
    // A field of one value: every node is constant (eq. 7 at any delta_sv),
    // its gradient is zero, so the routine's colour and ambient-only
    // lighting are exactly what the reference computes per sample; only
    // f32 stepping differs (the routine's closed-form positions).
    use scene::volume_bvh::MinMaxBvh;
    use volume_kernels::BvhRun;
    let n = 24u32;
    let vol = Volume {
        dims: [n; 3],
        spacing: [1.0; 3],
        data: vec![180; (n as usize).pow(3)],
        range: (0.0, 255.0),
    };
    let tree = Arc::new(MinMaxBvh::build(&vol, 4));
    let pr = Arc::new(Prepared::new(vol, Transfer::parse(TF).unwrap()));
    let c = [f64::from(n); 3];
    let eye = [c[0] * 1.9, -c[1] * 0.7, c[2] * 1.4];
    let rays = corner_packets([n; 3], eye);
    for (lighting, rda, at) in [
        (Lighting::Unlit, 0.0, ConstantAt::Leaves),
        (Lighting::Diffuse, 0.01, ConstantAt::Leaves),
        (Lighting::Unlit, 0.0, ConstantAt::EveryNode),
        (Lighting::Diffuse, 0.01, ConstantAt::EveryNode),
    ] {
        let s = Sampling {
            filter: Filter::Trilinear,
            dt: 0.5,
            rda,
            lighting,
            light: [c[0] * 2.0, -c[1], c[2] * 3.0],
            light_threshold: 0.01,
        };
        let run = BvhRun {
            prepared: pr.clone(),
            tree: tree.clone(),
            rays: rays.clone(),
            sampling: s,
            heuristics: volume_kernels::bvh::Heuristics {
                constant_at: at,
                ..PAPER
            },
        };
        let (img, counts) = traced_equals_native(&run);
        assert!(counts.classified > 0);
        let want = reference(&pr, &rays, &s);
        assert!(want.iter().filter(|p| p[3] > 0.05).count() > 50);
        let (max, psnr, _) = compare(&img, &want);
        eprintln!("constant field {lighting:?} {at:?}: max {max:.5}, PSNR {psnr:.1} dB");
        // Measured, every node (the root is constant: one box): unlit 60.8
        // dB (largest 0.006: a sample at a box exit within f32 of the
        // boundary), diffuse 71.5 dB. At leaves the routine runs box by
        // box (216 leaves), and a differential step's closed form through
        // each box can move a sample across a boundary in f32: diffuse
        // 57.4 dB, largest 0.039 (one sample's share of the colour).
        let largest = if at == ConstantAt::Leaves { 0.05 } else { 0.02 };
        assert!(psnr > 55.0 && max < largest, "{lighting:?}: {max} {psnr}");
    }
}

#[test]
fn long_steps_through_small_leaves_never_sample_outside_the_volume() {
    // Differential steps growing to several voxels across leaves of one
    // voxel: a ray crosses whole leaves between two samples, the last one
    // at the volume's far face (its next sample lies outside the volume).
    use scene::volume_bvh::MinMaxBvh;
    use volume_kernels::BvhRun;
    let vol = Volume::mixing_layer(16, 3);
    let dims = vol.dims;
    let tree = Arc::new(MinMaxBvh::build(&vol, 1));
    let pr = Arc::new(Prepared::new(vol, Transfer::parse(TF).unwrap()));
    let c = dims.map(f64::from);
    let eye = [c[0] * 1.9, -c[1] * 0.7, c[2] * 1.4];
    let rays = corner_packets(dims, eye);
    let s = Sampling {
        filter: Filter::Trilinear,
        dt: 0.9,
        rda: 0.3,
        lighting: Lighting::Unlit,
        light: [0.0; 3],
        light_threshold: 0.01,
    };
    let run = BvhRun {
        prepared: pr.clone(),
        tree,
        rays: rays.clone(),
        sampling: s,
        heuristics: PAPER,
    };
    let (img, counts) = traced_equals_native(&run);
    assert!(counts.leaf_rays > 0);
    let want = reference(&pr, &rays, &s);
    let (max, psnr, _) = compare(&img, &want);
    eprintln!("long steps: max {max:.4}, PSNR {psnr:.1} dB");
    // Measured: 53.4 dB, largest 0.021; sampling past a leaf's exit (the
    // bug this guards) gave 33.7 dB and could read outside the volume.
    assert!(psnr > 45.0 && max < 0.1, "max {max}, PSNR {psnr}");
}
