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
/// (delta method, normal approximation); `None` below 2 tiles. A tile's own
/// ratio is not averaged: tiles whose rays all miss are very fast and would
/// dominate a mean of per-tile rates.
pub fn ratio_ci(v: &[(f64, f64)]) -> Option<f64> {
    if v.len() < 2 {
        return None;
    }
    let n = v.len() as f64;
    let (sn, sd) = v.iter().fold((0.0, 0.0), |(a, b), &(x, y)| (a + x, b + y));
    let r = sn / sd;
    let dbar = sd / n;
    let var = v.iter().map(|&(x, y)| (x - r * y).powi(2)).sum::<f64>() / (n - 1.0);
    Some(1.96 * (var / n).sqrt() / dbar)
}

#[cfg(test)]
mod tests {
    use super::ratio_ci;

    #[test]
    fn ratio_ci_is_zero_for_proportional_tiles_and_grows_with_spread() {
        assert_eq!(ratio_ci(&[(1.0, 2.0)]), None);
        assert!(ratio_ci(&[(1.0, 2.0), (2.0, 4.0), (3.0, 6.0)]).unwrap() < 1e-12);
        let wide = ratio_ci(&[(1.0, 2.0), (4.0, 2.0)]).unwrap();
        let narrow = ratio_ci(&[(1.0, 2.0), (1.5, 2.0)]).unwrap();
        assert!(wide > narrow && narrow > 0.0);
    }
}
