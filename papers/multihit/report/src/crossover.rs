//! Where naive multi-hit catches up with node culling: the N_query at which
//! node culling's speed-up over naive first falls to 1, interpolated
//! linearly between the two measured N_query around it, with a 95%
//! interval from the speed-up's own 95% band (the crossing of its lower
//! edge, which comes first, and of its upper edge), and the crossing as a
//! fraction of a scene's most, mean and 95th-percentile hits per ray.

use crate::measure::HitStats;

/// One measured point: N_query, node culling's speed-up over naive, and
/// the speed-up's 95% half-width.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Point {
    pub(crate) n: f64,
    pub(crate) speedup: f64,
    pub(crate) ci: Option<f64>,
}

/// The N_query at which `s(point)` first falls to 1 or below, linear in
/// N_query between the point before (above 1) and that point; the first
/// N_query if the curve starts at or below 1; `None` if it never falls.
#[must_use]
pub(crate) fn first_crossing(points: &[Point], s: impl Fn(&Point) -> f64) -> Option<f64> {
    let k = points.iter().position(|p| s(p) <= 1.0)?;
    let Some(before) = k.checked_sub(1).map(|j| &points[j]) else {
        return Some(points[0].n);
    };
    let (a, b) = (before, &points[k]);
    let (sa, sb) = (s(a), s(b));
    Some(a.n + (b.n - a.n) * (sa - 1.0) / (sa - sb))
}

/// A crossover with its 95% interval, in N_query (`None`: naive never
/// catches up over the N_query measured).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Crossover {
    pub(crate) at: Option<f64>,
    pub(crate) low: Option<f64>,
    pub(crate) high: Option<f64>,
}

impl Crossover {
    /// The crossover of a speed-up curve ordered by N_query. Without a
    /// half-width (fewer than 3 tiles) the interval is the estimate.
    #[must_use]
    pub(crate) fn of(points: &[Point]) -> Crossover {
        let edge = |sign: f64| first_crossing(points, |p| p.speedup + sign * p.ci.unwrap_or(0.0));
        Crossover {
            at: first_crossing(points, |p| p.speedup),
            low: edge(-1.0),
            high: edge(1.0),
        }
    }

    /// Each bound (estimate, low, high) divided by `by`; NaN where naive
    /// never catches up.
    #[must_use]
    pub(crate) fn scaled(&self, by: f64) -> [(&'static str, f64); 3] {
        let f = |v: Option<f64>| v.map_or(f64::NAN, |v| v / by);
        [
            ("estimate", f(self.at)),
            ("low95", f(self.low)),
            ("high95", f(self.high)),
        ]
    }

    /// The crossover in N_query and as fractions of the most, mean and
    /// 95th-percentile hits per ray: (normalisation, [(bound, value)]).
    #[must_use]
    pub(crate) fn normalised(&self, h: &HitStats) -> [(&'static str, [(&'static str, f64); 3]); 4] {
        let [max, mean, p95] = h.scales().map(|(per, by)| (per, self.scaled(by)));
        [("n_query", self.scaled(1.0)), max, mean, p95]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn curve(v: &[(f64, f64, f64)]) -> Vec<Point> {
        v.iter()
            .map(|&(n, speedup, ci)| Point {
                n,
                speedup,
                ci: Some(ci),
            })
            .collect()
    }

    #[test]
    fn the_crossing_is_interpolated_between_the_points_around_it() {
        let c = curve(&[(1.0, 3.0, 0.1), (10.0, 1.5, 0.1), (20.0, 0.5, 0.1)]);
        let x = Crossover::of(&c);
        assert!((x.at.unwrap() - 15.0).abs() < 1e-12);
        // The lower edge (1.4 -> 0.4) crosses at 14, the upper (1.6 -> 0.6) at 16.
        assert!((x.low.unwrap() - 14.0).abs() < 1e-12);
        assert!((x.high.unwrap() - 16.0).abs() < 1e-12);
    }

    #[test]
    fn a_curve_that_never_falls_has_no_crossing_and_one_below_at_once_its_first_n() {
        let never = curve(&[(1.0, 3.0, 0.5), (2.0, 2.0, 0.5), (4.0, 1.2, 0.5)]);
        let x = Crossover::of(&never);
        assert_eq!((x.at, x.high), (None, None));
        // The lower edge reaches 0.7 at N = 4: between 2 (1.5) and 4.
        assert!((x.low.unwrap() - (2.0 + 2.0 * 0.5 / 0.8)).abs() < 1e-12);
        let below = curve(&[(1.0, 0.9, 0.0), (2.0, 0.8, 0.0)]);
        assert_eq!(Crossover::of(&below).at, Some(1.0));
        assert_eq!(first_crossing(&[], |p| p.speedup), None);
    }

    #[test]
    fn the_normalisations_divide_by_the_hit_statistics() {
        let x = Crossover {
            at: Some(14.0),
            low: Some(7.0),
            high: None,
        };
        let h = HitStats::of(vec![0, 2, 4, 10, 20, 28]);
        assert_eq!((h.max, h.p95), (28, 28));
        let n = x.normalised(&h);
        assert_eq!(n[1].1[0], ("estimate", 0.5));
        assert_eq!(n[2].1[1], ("low95", 7.0 / h.mean));
        assert!(n[3].1[2].1.is_nan());
    }
}
