//! Sampling: the seeded generator that picks samples, and confidence
//! intervals of ratio estimates.

/// splitmix64: the tile sample's generator.
pub fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// 95% half-width of the ratio estimator sum(num) / sum(den) over tiles
/// (delta method, Student's t with n - 1 degrees of freedom: a sample of a
/// few tiles gets the wide interval it has); `None` below 2 tiles. A tile's
/// own ratio is not averaged: tiles whose rays all miss are very fast and
/// would dominate a mean of per-tile rates.
pub fn ratio_ci(v: &[(f64, f64)]) -> Option<f64> {
    if v.len() < 2 {
        return None;
    }
    let n = v.len() as f64;
    let (d, dbar) = residuals(v);
    let var = d.iter().map(|x| x * x).sum::<f64>() / (n - 1.0);
    Some(t95(v.len() - 1) * (var / n).sqrt() / dbar)
}

/// Each observation's residual `num - r den` from the ratio estimate `r`,
/// and the mean denominator.
fn residuals(v: &[(f64, f64)]) -> (Vec<f64>, f64) {
    let (sn, sd) = v.iter().fold((0.0, 0.0), |(a, b), &(x, y)| (a + x, b + y));
    let r = sn / sd;
    (
        v.iter().map(|&(x, y)| x - r * y).collect(),
        sd / v.len() as f64,
    )
}

/// One unit at a seeded place in each of `groups` equal strata of `n`
/// units in render order, with the unit before it (warmed): `(before,
/// unit)` per stratum.
#[must_use]
pub fn strata_with_previous(n: usize, groups: usize, seed: u64) -> Vec<(Option<usize>, usize)> {
    let stride = (n / groups.max(1)).max(1);
    (0..groups.min(n))
        .map(|g| {
            let k = g * stride + (mix(seed ^ mix(g as u64 + 1)) % stride as u64) as usize;
            (k.checked_sub(1), k.min(n - 1))
        })
        .collect()
}

/// [`ratio_ci`] for a systematic sample (observations at evenly spaced
/// places in a fixed order, e.g. bands of an image top to bottom): the
/// variance from successive differences of the residuals (Wolter's v2
/// estimator), which does not count a smooth trend over the order as
/// noise, as the independent-draw formula does; `None` below 3 observations.
#[must_use]
pub fn systematic_ratio_ci(v: &[(f64, f64)]) -> Option<f64> {
    if v.len() < 3 {
        return None;
    }
    let n = v.len() as f64;
    let (d, dbar) = residuals(v);
    let var = d.windows(2).map(|w| (w[1] - w[0]).powi(2)).sum::<f64>() / (2.0 * (n - 1.0));
    Some(t95(v.len() - 1) * (var / n).sqrt() / dbar)
}

/// [`paired_ratio`] over a systematic sample ([`systematic_ratio_ci`]).
#[must_use]
pub fn paired_ratio_systematic(a: &[f64], b: &[f64]) -> (f64, Option<f64>) {
    paired_with(a, b, systematic_ratio_ci)
}

/// sum(a) / sum(b) and `ci` of the pairs.
fn paired_with(a: &[f64], b: &[f64], ci: fn(&[(f64, f64)]) -> Option<f64>) -> (f64, Option<f64>) {
    let pairs: Vec<(f64, f64)> = a.iter().copied().zip(b.iter().copied()).collect();
    let (sa, sb): (f64, f64) = (a.iter().sum(), b.iter().sum());
    (sa / sb.max(f64::MIN_POSITIVE), ci(&pairs))
}

/// The ratio sum(a) / sum(b) of two methods measured on the same samples
/// (tiles, batches), and its paired 95% half-width: the spread the samples
/// share cancels.
#[must_use]
pub fn paired_ratio(a: &[f64], b: &[f64]) -> (f64, Option<f64>) {
    paired_with(a, b, ratio_ci)
}

/// Whether a ratio's interval excludes 1: the sample separates the two.
#[must_use]
pub fn separates((r, ci): (f64, Option<f64>)) -> bool {
    ci.is_some_and(|h| (r - 1.0).abs() > h)
}

/// Two-sided 95% quantile of Student's t with `df` degrees of freedom
/// (tabulated; between entries the smaller df's, so never narrower).
#[must_use]
pub fn t95(df: usize) -> f64 {
    const T: [(usize, f64); 19] = [
        (1, 12.706),
        (2, 4.303),
        (3, 3.182),
        (4, 2.776),
        (5, 2.571),
        (6, 2.447),
        (7, 2.365),
        (8, 2.306),
        (9, 2.262),
        (10, 2.228),
        (12, 2.179),
        (15, 2.131),
        (20, 2.086),
        (25, 2.060),
        (30, 2.042),
        (40, 2.021),
        (60, 2.000),
        (120, 1.980),
        (usize::MAX, 1.960),
    ];
    T.iter()
        .rev()
        .find(|&&(d, _)| d <= df.max(1))
        .map_or(T[0].1, |&(_, t)| t)
}

/// The goals the model is held to against a host (`rtsim validate`,
/// `rtsim replay`): Kendall tau of the order, and mean absolute error.
pub const GOAL_TAU: f64 = 0.9;
/// See [`GOAL_TAU`].
pub const GOAL_ERROR: f64 = 0.15;

/// Kendall's tau-b of paired observations (ties in either count against
/// neither order); `None` with fewer than two pairs or all tied.
#[must_use]
pub fn kendall_tau(x: &[f64], y: &[f64]) -> Option<f64> {
    use std::cmp::Ordering::Equal;
    let (mut c, mut d, mut tx, mut ty) = (0u64, 0u64, 0u64, 0u64);
    for i in 0..x.len() {
        for j in i + 1..x.len() {
            match (x[i].partial_cmp(&x[j]), y[i].partial_cmp(&y[j])) {
                (Some(Equal), Some(Equal)) | (None, _) | (_, None) => {}
                (Some(Equal), _) => tx += 1,
                (_, Some(Equal)) => ty += 1,
                (a, b) if a == b => c += 1,
                _ => d += 1,
            }
        }
    }
    let (c, d, tx, ty) = (c as f64, d as f64, tx as f64, ty as f64);
    let den = ((c + d + tx) * (c + d + ty)).sqrt();
    (den > 0.0).then(|| (c - d) / den)
}

#[cfg(test)]
mod tests {
    use super::{ratio_ci, strata_with_previous, systematic_ratio_ci, t95};

    #[test]
    fn strata_hold_one_unit_each_with_the_one_before() {
        for (n, g) in [
            (4096, 1),
            (4096, 8),
            (4096, 64),
            (3072, 1),
            (3072, 4),
            (3072, 16),
        ] {
            let p = strata_with_previous(n, g, 7);
            assert_eq!(p.len(), g);
            for (i, &(before, k)) in p.iter().enumerate() {
                let stride = n / g;
                assert!(k >= i * stride && k < (i + 1) * stride, "{n} {g} {i} {k}");
                assert_eq!(before, k.checked_sub(1));
            }
        }
        assert_ne!(
            strata_with_previous(3072, 4, 7),
            strata_with_previous(3072, 4, 8)
        );
    }

    #[test]
    fn t_quantiles_shrink_towards_the_normal() {
        assert_eq!(t95(1), 12.706);
        assert_eq!(t95(11), 2.228, "between entries: the smaller df's");
        assert_eq!(t95(1000), 1.980);
        assert!((2..200).all(|d| t95(d) <= t95(d - 1)));
    }

    #[test]
    fn ratio_ci_is_zero_for_proportional_tiles_and_grows_with_spread() {
        assert_eq!(ratio_ci(&[(1.0, 2.0)]), None);
        assert!(ratio_ci(&[(1.0, 2.0), (2.0, 4.0), (3.0, 6.0)]).unwrap() < 1e-12);
        let wide = ratio_ci(&[(1.0, 2.0), (4.0, 2.0)]).unwrap();
        let narrow = ratio_ci(&[(1.0, 2.0), (1.5, 2.0)]).unwrap();
        assert!(wide > narrow && narrow > 0.0);
    }

    #[test]
    fn a_systematic_sample_does_not_count_a_smooth_trend_as_noise() {
        assert_eq!(systematic_ratio_ci(&[(1.0, 2.0), (2.0, 2.0)]), None);
        // Costs rising steadily down the image: independent draws would
        // call the spread noise; successive differences see a small step.
        let trend: Vec<(f64, f64)> = (0..16).map(|i| (f64::from(i), 1.0)).collect();
        let sys = systematic_ratio_ci(&trend).unwrap();
        let srs = ratio_ci(&trend).unwrap();
        assert!(sys * 3.0 < srs, "{sys} vs {srs}");
        // Alternating costs have no trend: the differences are large.
        let zigzag: Vec<(f64, f64)> = (0..16).map(|i| (f64::from(i % 2) * 15.0, 1.0)).collect();
        assert!(systematic_ratio_ci(&zigzag).unwrap() > ratio_ci(&zigzag).unwrap());
        let flat: Vec<(f64, f64)> = (0..8).map(|_| (3.0, 1.5)).collect();
        assert!(systematic_ratio_ci(&flat).unwrap() < 1e-12);
    }
}
