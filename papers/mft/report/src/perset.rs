//! Per-set counts of soft shadows: what Table 1 gives that no machine
//! changes. The paper's soft-shadow rows include the primary rays, so its
//! shadow work per set of 16 frusta (one 4 x 4 pixel group) is (S - P) over
//! the 1024 x 1024 image's 65,536 groups: a lower bound, as groups without a
//! hit trace no shadows and the paper does not say how many it had. Ours is
//! over the sets with a hit. The stand-ins' lights are matched on these
//! counts (never on cycles): see each scene file and `papers/mft/README.md`.

use crate::frame::{bands, count_native, zero_interval_share, Counted, Prepared};
use crate::paper::PAPER;
use mft_kernels::{
    checked_rays, mismatches_expected, MftStats, PacketGrouping, PacketPrimaryRun, Shrink,
};
use repro::{AppError, AppResult};
use scene::agreement::{Expected, F32Test};
use scene::workload::SampleSplit;

/// 4 x 4 pixel groups in the paper's 1024 x 1024 image.
pub const PAPER_SETS: f64 = 65_536.0;

/// One method's soft-shadow counts per set of 16 frusta.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PerSet {
    /// 16-wide AABB tests.
    pub aabb_tests: f64,
    /// Triangles accessed.
    pub tris_accessed: f64,
    /// Triangles after culling.
    pub tris_after_culling: f64,
    /// 16-wide intersection tests.
    pub isec_tests: f64,
}

impl PerSet {
    /// `st` over `sets` sets.
    #[must_use]
    pub fn of(st: &MftStats, sets: f64) -> PerSet {
        let d = sets.max(1.0);
        PerSet {
            aabb_tests: st.aabb_tests as f64 / d,
            tris_accessed: st.tris_accessed as f64 / d,
            tris_after_culling: st.tris_after_culling as f64 / d,
            isec_tests: st.isec_tests as f64 / d,
        }
    }

    /// The four counts with their row names.
    #[must_use]
    pub fn named(&self) -> [(&'static str, f64); 4] {
        [
            ("aabb_tests", self.aabb_tests),
            ("tris_accessed", self.tris_accessed),
            ("tris_after_culling", self.tris_after_culling),
            ("isec_tests", self.isec_tests),
        ]
    }
}

/// The paper's per-set soft-shadow counts of `scene` (a Table 1 key):
/// (packets, frusta), each (S - P) / 65,536. Packets' "after culling" is
/// the paper's figure where it gives one.
#[must_use]
pub fn paper_per_set(scene: &str) -> Option<(PerSet, PerSet)> {
    let (_, _, rows) = PAPER.iter().find(|(k, _, _)| *k == scene)?;
    let of = |s: usize, p: usize| PerSet {
        aabb_tests: (rows[s].2 - rows[p].2) * 1e3 / PAPER_SETS,
        tris_accessed: (rows[s].0 - rows[p].0) * 1e3 / PAPER_SETS,
        tris_after_culling: (rows[s].1.unwrap_or(rows[s].0) - rows[p].1.unwrap_or(rows[p].0)) * 1e3
            / PAPER_SETS,
        isec_tests: (rows[s].3 - rows[p].3) * 1e3 / PAPER_SETS,
    };
    Some((of(2, 0), of(3, 1)))
}

/// What [`shadow_per_set`] measured.
#[derive(Clone, Debug)]
pub struct ShadowCounts {
    /// The scene's name (its Table 1 key for a stand-in).
    pub name: String,
    /// Soft-shadow sets with a hit over the image.
    pub sets: usize,
    /// 4 x 4 pixel groups of the image.
    pub groups: usize,
    /// 16-ray packets per set.
    pub packets: PerSet,
    /// Multi-frusta per set.
    pub frusta: PerSet,
    /// Share of active shadow frusta whose direction interval holds zero.
    pub zero_share: f64,
}

/// Soft-shadow counts per set of `scene` (a built-in name or a `.ron`
/// file) at `res` x `res`, counted natively over every `every`-th set in
/// render order (1: all), each pixel's samples from `split`, the packets
/// grouped by `grouping`. For matching a
/// stand-in's light on Table 1's counts: no simulation, seconds per scene.
pub fn shadow_per_set(
    scene: &str,
    res: u32,
    every: u32,
    (split, grouping): (SampleSplit, PacketGrouping),
) -> AppResult<ShadowCounts> {
    if res < 16 || !res.is_multiple_of(16) {
        return Err(AppError(format!(
            "resolution {res}: the frusta need a multiple of 16 pixels"
        )));
    }
    let pr = Prepared::new(scene, res, "shadow counts", false)?.with_split(split);
    let fl = sim::MachineConfig::load(crate::MACHINE)
        .map_err(|e| AppError(e.to_string()))?
        .flavour();
    let (packets, frusta) = count_shadow(fl, &pr, every, grouping).per_set();
    Ok(ShadowCounts {
        name: pr.scene.config.name.clone(),
        sets: pr.shadow.len(),
        groups: (res as usize / 4).pow(2),
        packets,
        frusta,
        zero_share: zero_interval_share(&pr.shadow),
    })
}

/// A scene's soft shadows counted natively by both methods over the same
/// sets ([`count_shadow`]).
pub(crate) struct ShadowCounted {
    /// The 16-ray packets' counts and answers.
    pub(crate) packets: Counted,
    /// The frusta's.
    pub(crate) frusta: Counted,
    /// Soft-shadow sets with a hit over the image.
    sets: usize,
}

impl ShadowCounted {
    /// (packets, frusta) per set with a hit (the counts are scaled to all
    /// sets when only some were counted).
    pub(crate) fn per_set(&self) -> (PerSet, PerSet) {
        let n = self.sets as f64;
        (
            PerSet::of(&self.packets.stats, n),
            PerSet::of(&self.frusta.stats, n),
        )
    }

    /// Rays of both methods whose answer differs from the f64 reference's
    /// (each counted ray, the reference answering once for both); `tag`
    /// names the run in a mismatch's report.
    pub(crate) fn mismatches(&self, pr: &Prepared, scene_name: &str, tag: &str) -> usize {
        let refi = pr.reference();
        let (sub, keep) = checked_rays(&self.frusta.sets);
        let want = Expected::of(&refi, &sub);
        [
            (F32Test::MollerTrumbore, "s-packet", &self.packets),
            (F32Test::Pluecker, "s-frusta", &self.frusta),
        ]
        .into_iter()
        .map(|(test, method, c)| {
            let label = format!("{scene_name} {method} {tag}");
            mismatches_expected(test, &label, &refi, (&sub, &keep, &want), &c.out)
        })
        .sum()
    }
}

/// `pr`'s soft shadows by packets (grouped by `grouping`) and by frusta,
/// counted natively over every `every`-th set in render order (1: all).
pub(crate) fn count_shadow(
    fl: isa::FlavourId,
    pr: &Prepared,
    every: u32,
    grouping: PacketGrouping,
) -> ShadowCounted {
    let b = bands(&pr.shadow, every);
    ShadowCounted {
        packets: count_native(fl, &pr.shadow, &b, |s| PacketPrimaryRun {
            grouping,
            ..pr.packets(s)
        }),
        frusta: count_native(fl, &pr.shadow, &b, |s| pr.frusta(s, false, Shrink::None)),
        sets: pr.shadow.len(),
    }
}
