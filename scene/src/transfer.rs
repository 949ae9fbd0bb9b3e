//! Transfer functions for direct volume rendering (the volume paper's
//! classification, section 3): a 1D piecewise-linear RGBA map over the 8-bit
//! values (read from RON), its preintegrated 256 x 256 table (Engel et al.
//! 2001) and the paper's BVH heuristics read off that table: empty space
//! (eq. 5), pruning (eq. 6) and constant subvolumes (eq. 7).
//!
//! Opacity is a density per unit sample step: a segment from value `a` to
//! value `b` (linear in between, one step long) has opacity
//! `1 - exp(-mean(alpha))` and associated colour `mean(rgb * alpha)` scaled
//! to that opacity, the means taken over the values from `a` to `b`
//! (the preintegration of eq. 4 without self-attenuation inside a step).

use serde::Deserialize;

/// One control point: a value (0 to 255) and its colour and opacity.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Point {
    /// The value, 0 to 255.
    pub value: f32,
    /// Red, green, blue, opacity, each 0 to 1.
    pub rgba: [f32; 4],
}

/// A transfer function file: control points in increasing value.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct TransferFile {
    /// Control points; values before the first and after the last take
    /// the nearest point's colour.
    pub points: Vec<Point>,
}

impl TransferFile {
    /// Parse a transfer function file (RON) without checking its points.
    ///
    /// # Errors
    /// A parse error, with its line.
    pub fn parse(text: &str) -> Result<TransferFile, String> {
        ron::from_str(text).map_err(|e| format!("line {}: {}", e.position.line, e.code))
    }
}

/// A transfer function: 256 entries and its preintegrated table.
#[derive(Clone, Debug, PartialEq)]
pub struct Transfer {
    /// RGBA per 8-bit value.
    pub lut: Vec<[f32; 4]>,
    /// Preintegrated RGBA (associated colour) per (front value, back value):
    /// entry `a * 256 + b`.
    pub pre: Vec<[f32; 4]>,
}

impl Transfer {
    /// Parse a transfer function (RON); errors name the field or point.
    ///
    /// # Errors
    /// A parse error (with its line), no points, values out of 0..=255 or
    /// not increasing, colours outside 0..=1 or not finite.
    pub fn parse(text: &str) -> Result<Transfer, String> {
        Transfer::new(&TransferFile::parse(text)?.points)
    }

    /// From control points.
    ///
    /// # Errors
    /// As [`Transfer::parse`].
    pub fn new(points: &[Point]) -> Result<Transfer, String> {
        if points.is_empty() {
            return Err("points: an empty transfer function".into());
        }
        for (i, p) in points.iter().enumerate() {
            if !(0.0..=255.0).contains(&p.value) {
                return Err(format!("points[{i}]: value {} outside 0 to 255", p.value));
            }
            if p.rgba.iter().any(|c| !(0.0..=1.0).contains(c)) {
                return Err(format!("points[{i}]: rgba {:?} outside 0 to 1", p.rgba));
            }
            if i > 0 && p.value <= points[i - 1].value {
                return Err(format!("points[{i}]: values must increase"));
            }
        }
        let lut: Vec<[f32; 4]> = (0..256).map(|v| eval(points, v as f32)).collect();
        Ok(Transfer {
            pre: preintegrate(&lut),
            lut,
        })
    }

    /// Preintegrated RGBA for a step from value `a` to value `b`.
    #[must_use]
    pub fn pre(&self, a: u8, b: u8) -> [f32; 4] {
        self.pre[a as usize * 256 + b as usize]
    }

    /// Preintegrated opacity over a node's range (eq. 5-7's rho_alpha).
    #[must_use]
    pub fn alpha(&self, min: u8, max: u8) -> f32 {
        self.pre(min, max)[3]
    }

    /// Eq. 5: whether a node with this range holds anything visible.
    #[must_use]
    pub fn visible(&self, (min, max): (u8, u8), delta_c: f32) -> bool {
        self.alpha(min, max) > delta_c
    }

    /// Eq. 6: whether to stop descending at a node of diagonal `box_diag`
    /// in a volume of diagonal `vol_diag` (treat it as a leaf).
    #[must_use]
    pub fn prune(&self, (min, max): (u8, u8), box_diag: f32, vol_diag: f32, delta_p: f32) -> bool {
        self.alpha(min, max) * vol_diag / box_diag > delta_p
    }

    /// Eq. 7: whether a node's range is constant enough for the
    /// constant-subvolume routine.
    #[must_use]
    pub fn constant(&self, (min, max): (u8, u8), delta_sv: f32) -> bool {
        let a = self.alpha(min, max);
        (a - self.alpha(min, min))
            .abs()
            .max((a - self.alpha(max, max)).abs())
            < delta_sv
    }
}

/// The piecewise-linear function at `v`.
fn eval(points: &[Point], v: f32) -> [f32; 4] {
    let i = points.partition_point(|p| p.value <= v);
    if i == 0 {
        return points[0].rgba;
    }
    if i == points.len() {
        return points[i - 1].rgba;
    }
    let (p, q) = (points[i - 1], points[i]);
    let t = (v - p.value) / (q.value - p.value);
    std::array::from_fn(|c| p.rgba[c] + t * (q.rgba[c] - p.rgba[c]))
}

/// The 256 x 256 table from prefix sums of opacity and associated colour
/// (each value's entry weighted by the trapezoid rule between values).
fn preintegrate(lut: &[[f32; 4]]) -> Vec<[f32; 4]> {
    // Prefix integrals over value, in f64: I[k] = integral from 0 to k.
    let assoc = |v: usize| -> [f64; 4] {
        let [r, g, b, a] = lut[v].map(f64::from);
        [r * a, g * a, b * a, a]
    };
    let mut prefix = vec![[0f64; 4]; 256];
    for v in 1..256 {
        let (p, q) = (assoc(v - 1), assoc(v));
        prefix[v] = std::array::from_fn(|c| prefix[v - 1][c] + 0.5 * (p[c] + q[c]));
    }
    let mut pre = Vec::with_capacity(256 * 256);
    for a in 0..256 {
        for b in 0..256 {
            let mean: [f64; 4] = if a == b {
                assoc(a)
            } else {
                let w = (b as f64 - a as f64).abs();
                std::array::from_fn(|c| (prefix[a.max(b)][c] - prefix[a.min(b)][c]) / w)
            };
            let alpha = 1.0 - (-mean[3]).exp();
            // Associated colour: the mean colour-weighted opacity, scaled to
            // the step's opacity.
            let scale = if mean[3] > 0.0 { alpha / mean[3] } else { 0.0 };
            pre.push([
                (mean[0] * scale) as f32,
                (mean[1] * scale) as f32,
                (mean[2] * scale) as f32,
                alpha as f32,
            ]);
        }
    }
    pre
}

#[cfg(test)]
mod tests {
    use super::*;

    const RAMP: &str = "(points: [(value: 0.0, rgba: (0.0, 0.0, 0.0, 0.0)), (value: 100.0, rgba: (0.0, 0.0, 0.0, 0.0)), (value: 200.0, rgba: (1.0, 0.5, 0.0, 0.8)), (value: 255.0, rgba: (1.0, 1.0, 1.0, 0.8))])";

    #[test]
    fn a_ramp_classifies_and_preintegrates() {
        let t = Transfer::parse(RAMP).unwrap();
        assert_eq!(t.lut[50][3], 0.0);
        assert!((t.lut[150][3] - 0.4).abs() < 1e-6);
        // A constant segment: 1 - exp(-a).
        let a = t.pre(230, 230)[3];
        assert!((a - (1.0 - (-0.8f32).exp())).abs() < 1e-5, "{a}");
        // Symmetric, and between the ends' opacities.
        assert_eq!(t.pre(120, 180), t.pre(180, 120));
        let mid = t.alpha(120, 180);
        assert!(t.alpha(120, 120) < mid && mid < t.alpha(180, 180));
    }

    #[test]
    fn the_heuristics_read_the_table() {
        let t = Transfer::parse(RAMP).unwrap();
        assert!(!t.visible((0, 100), 1e-3), "empty below 100");
        assert!(t.visible((90, 120), 1e-3));
        assert!(t.constant((210, 215), 0.05) && !t.constant((100, 250), 0.05));
        assert!(t.prune((220, 255), 10.0, 100.0, 1.5) && !t.prune((100, 110), 10.0, 100.0, 1.5));
    }

    #[test]
    fn bad_transfer_functions_name_the_point() {
        let e = Transfer::parse("(points: [])").unwrap_err();
        assert!(e.contains("empty"), "{e}");
        let e = Transfer::parse("(points: [(value: 10.0, rgba: (0.0, 0.0, 0.0, 0.5)), (value: 5.0, rgba: (0.0, 0.0, 0.0, 0.5))])").unwrap_err();
        assert!(e.contains("points[1]: values must increase"), "{e}");
        let e =
            Transfer::parse("(points: [(value: 300.0, rgba: (0.0, 0.0, 0.0, 0.5))])").unwrap_err();
        assert!(e.contains("points[0]: value 300"), "{e}");
        let e =
            Transfer::parse("(points: [(value: 3.0, rgba: (0.0, 2.0, 0.0, 0.5))])").unwrap_err();
        assert!(e.contains("outside 0 to 1"), "{e}");
        let e = Transfer::parse("(points: [(value: 3.0, rgba: (0.0, 0.0, 0.0, 0.5), glow: 1)])")
            .unwrap_err();
        assert!(e.contains("line 1") && e.contains("glow"), "{e}");
    }
}
