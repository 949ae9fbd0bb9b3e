//! The f64 reference ray caster for direct volume rendering: the sampling
//! of the volume paper's Listing 2, in f64 and scalar, so every kernel's
//! image can be held to it.
//!
//! In voxel coordinates (voxel centres at integers), a ray enters the
//! volume's box `[0, dims - 1]` at `t_enter` and leaves at `t_exit`
//! (direction normalised). Sample k sits at `t_k = t_enter + k dt + k (k - 1)
//! / 2 rda` (differential sampling: each step `rda` longer than the last;
//! `rda = 0`: uniform). At a sample whose base voxel (the stencil's corner,
//! the position truncated) is 0 nothing is added (Listing 2's `if (val)`);
//! otherwise the value is the trilinear interpolant truncated to an integer,
//! classified by the preintegrated table from the previous classified value
//! to this one, optionally lit (the interpolant's analytic gradient: diffuse
//! `0.15 + |n . l|` on the colour, Phong `(n . h)^16` added in proportion to
//! opacity), and blended front to back; the ray stops once opacity exceeds
//! 0.95 or the sample passes `t_exit`.

use crate::transfer::Transfer;
use crate::volume::Volume;

/// Lighting modes of Figure 5 (u, d, p).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Lighting {
    /// Unlit.
    Unlit,
    /// Diffuse.
    Diffuse,
    /// Diffuse and Phong highlight.
    Phong,
}

/// How a sample's value is reconstructed (Table 1's "NN" and "tril").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Filter {
    /// The base voxel's value (the position truncated); never lit (no
    /// gradient without the stencil).
    Nearest,
    /// The trilinear interpolant, truncated to an integer.
    Trilinear,
}

/// How a ray is sampled and shaded.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sampling {
    /// Value reconstruction.
    pub filter: Filter,
    /// First step, in voxels.
    pub dt: f64,
    /// Growth of each step (differential sampling), in voxels; 0: uniform.
    pub rda: f64,
    /// Lighting.
    pub lighting: Lighting,
    /// Light position (voxel coordinates).
    pub light: [f64; 3],
    /// Samples with opacity at most this are not lit.
    pub light_threshold: f64,
}

/// Opacity at which a ray stops (Listing 2's `_alpha_term`).
pub const EARLY_TERMINATION: f64 = 0.95;

/// The ray's entry and exit distances through the box `[0, dims - 1]`, if it
/// meets it.
#[must_use]
pub fn enter_exit(dims: [u32; 3], org: [f64; 3], dir: [f64; 3]) -> Option<(f64, f64)> {
    let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
    for a in 0..3 {
        let hi = f64::from(dims[a].max(1) - 1);
        let inv = 1.0 / dir[a];
        let (mut n, mut f) = ((0.0 - org[a]) * inv, (hi - org[a]) * inv);
        if n > f {
            std::mem::swap(&mut n, &mut f);
        }
        if n.is_nan() || f.is_nan() {
            // Parallel to this slab: inside or not.
            if org[a] < 0.0 || org[a] > hi {
                return None;
            }
            continue;
        }
        t0 = t0.max(n);
        t1 = t1.min(f);
    }
    (t0 <= t1).then_some((t0, t1))
}

/// Trilinear weights and the 8 corner values at `p` (base voxel `i`).
struct Stencil {
    i: [u32; 3],
    f: [f64; 3],
    v: [[[f64; 2]; 2]; 2],
}

impl Stencil {
    fn at(vol: &Volume, p: [f64; 3]) -> Stencil {
        let i = p.map(|c| c.max(0.0) as u32);
        let f: [f64; 3] = std::array::from_fn(|a| p[a] - f64::from(i[a]));
        let v = std::array::from_fn(|z| {
            std::array::from_fn(|y| {
                std::array::from_fn(|x| {
                    f64::from(vol.at(i[0] + x as u32, i[1] + y as u32, i[2] + z as u32))
                })
            })
        });
        Stencil { i, f, v }
    }
    fn value(&self) -> f64 {
        let w = |k: usize, a: usize| if k == 1 { self.f[a] } else { 1.0 - self.f[a] };
        let mut s = 0.0;
        for z in 0..2 {
            for y in 0..2 {
                for x in 0..2 {
                    s += w(x, 0) * w(y, 1) * w(z, 2) * self.v[z][y][x];
                }
            }
        }
        s
    }
    /// The analytic gradient of the trilinear interpolant (eq. 9).
    fn gradient(&self) -> [f64; 3] {
        let w = |k: usize, a: usize| if k == 1 { self.f[a] } else { 1.0 - self.f[a] };
        let mut g = [0.0; 3];
        for z in 0..2 {
            for y in 0..2 {
                g[0] += w(y, 1) * w(z, 2) * (self.v[z][y][1] - self.v[z][y][0]);
            }
        }
        for z in 0..2 {
            for x in 0..2 {
                g[1] += w(x, 0) * w(z, 2) * (self.v[z][1][x] - self.v[z][0][x]);
            }
        }
        for y in 0..2 {
            for x in 0..2 {
                g[2] += w(x, 0) * w(y, 1) * (self.v[1][y][x] - self.v[0][y][x]);
            }
        }
        g
    }
}

fn norm(v: [f64; 3]) -> [f64; 3] {
    let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    if l > 0.0 {
        v.map(|c| c / l)
    } else {
        v
    }
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The colour (associated RGB and opacity) a ray from `org` along `dir`
/// gathers through `vol` classified by `tf`.
#[must_use]
pub fn cast(vol: &Volume, tf: &Transfer, org: [f64; 3], dir: [f64; 3], s: &Sampling) -> [f64; 4] {
    cast_walk(vol, tf, org, dir, s).0
}

/// How a ray's samples went: for the sampling density of a frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Walk {
    /// Sample positions visited.
    pub samples: u64,
    /// Voxels the visited samples' steps cover (from the entry to where
    /// the next sample would have been).
    pub length: f64,
    /// Whether the ray met the volume's box.
    pub entered: bool,
    /// Whether it stopped by opacity (early termination) before its exit.
    pub terminated: bool,
}

/// [`cast`], with how its samples went.
#[must_use]
pub fn cast_walk(
    vol: &Volume,
    tf: &Transfer,
    org: [f64; 3],
    dir: [f64; 3],
    s: &Sampling,
) -> ([f64; 4], Walk) {
    let dir = norm(dir);
    let Some((t_enter, t_exit)) = enter_exit(vol.dims, org, dir) else {
        return ([0.0; 4], Walk::default());
    };
    let mut walk = Walk {
        entered: true,
        ..Walk::default()
    };
    let mut rgba = [0.0f64; 4];
    let (mut t, mut step) = (t_enter, s.dt);
    let mut last: Option<u8> = None;
    while t <= t_exit {
        walk.samples += 1;
        let p: [f64; 3] = std::array::from_fn(|a| org[a] + t * dir[a]);
        let st = Stencil::at(vol, p);
        let base = vol.at(st.i[0], st.i[1], st.i[2]);
        if base != 0 {
            let f = match s.filter {
                Filter::Nearest => base,
                Filter::Trilinear => st.value().clamp(0.0, 255.0) as u8,
            };
            let c = tf.pre(last.unwrap_or(f), f).map(f64::from);
            let c = shade(c, &st, p, dir, s);
            let keep = 1.0 - rgba[3];
            for k in 0..4 {
                rgba[k] += keep * c[k];
            }
            last = Some(f);
            if rgba[3] > EARLY_TERMINATION {
                walk.terminated = true;
                t += step;
                break;
            }
        }
        t += step;
        step += s.rda;
    }
    walk.length = t - t_enter;
    (rgba, walk)
}

/// Lighting of one classified sample (associated colour `c`).
fn shade(c: [f64; 4], st: &Stencil, p: [f64; 3], dir: [f64; 3], s: &Sampling) -> [f64; 4] {
    if s.lighting == Lighting::Unlit || s.filter == Filter::Nearest || c[3] <= s.light_threshold {
        return c;
    }
    let n = norm(st.gradient());
    let l = norm(std::array::from_fn(|a| s.light[a] - p[a]));
    let diffuse = 0.15 + dot(n, l).abs();
    let mut out = [c[0] * diffuse, c[1] * diffuse, c[2] * diffuse, c[3]];
    if s.lighting == Lighting::Phong {
        let h = norm(std::array::from_fn(|a| l[a] - dir[a]));
        let spec = dot(n, h).powi(16) * c[3];
        for k in 0..3 {
            out[k] += spec;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::transfer::Point;

    fn flat(value: u8, n: u32) -> Volume {
        Volume {
            dims: [n; 3],
            spacing: [1.0; 3],
            data: vec![value; (n as usize).pow(3)],
            range: (0.0, 255.0),
        }
    }

    fn grey(alpha: f32) -> Transfer {
        Transfer::new(&[Point {
            value: 0.0,
            rgba: [1.0, 1.0, 1.0, alpha],
        }])
        .unwrap()
    }

    fn unlit(dt: f64, rda: f64) -> Sampling {
        Sampling {
            filter: Filter::Trilinear,
            dt,
            rda,
            lighting: Lighting::Unlit,
            light: [0.0; 3],
            light_threshold: 0.0,
        }
    }

    #[test]
    fn a_uniform_slab_composites_in_closed_form() {
        // 9 voxels deep, unit steps: samples at t = 0..=8, each opacity a.
        let (v, tf) = (flat(100, 9), grey(0.05));
        let a = 1.0 - (-0.05f64).exp();
        let c = cast(&v, &tf, [4.0, 4.0, -3.0], [0.0, 0.0, 1.0], &unlit(1.0, 0.0));
        let want = 1.0 - (1.0 - a).powi(9);
        assert!((c[3] - want).abs() < 1e-6, "{} vs {want}", c[3]);
        assert!((c[0] - c[3]).abs() < 1e-6, "white, associated");
    }

    #[test]
    fn rays_stop_early_miss_the_box_and_skip_empty_voxels() {
        let (v, tf) = (flat(200, 64), grey(1.0));
        let c = cast(
            &v,
            &tf,
            [10.0, 10.0, -5.0],
            [0.0, 0.0, 1.0],
            &unlit(1.0, 0.0),
        );
        assert!(c[3] > EARLY_TERMINATION && c[3] < 1.0);
        let miss = cast(
            &v,
            &tf,
            [100.0, 10.0, -5.0],
            [0.0, 0.0, 1.0],
            &unlit(1.0, 0.0),
        );
        assert_eq!(miss, [0.0; 4]);
        let c = cast(
            &flat(0, 8),
            &tf,
            [3.0, 3.0, -1.0],
            [0.0, 0.0, 1.0],
            &unlit(1.0, 0.0),
        );
        assert_eq!(c, [0.0; 4]);
    }

    #[test]
    fn differential_sampling_takes_fewer_samples_farther_out() {
        // Fewer samples through the same slab: less opacity gathered.
        let (v, tf) = (flat(100, 64), grey(0.01));
        let uni = cast(
            &v,
            &tf,
            [30.0, 30.0, -1.0],
            [0.0, 0.0, 1.0],
            &unlit(0.5, 0.0),
        );
        let diff = cast(
            &v,
            &tf,
            [30.0, 30.0, -1.0],
            [0.0, 0.0, 1.0],
            &unlit(0.5, 0.01),
        );
        assert!(diff[3] < uni[3], "{diff:?} {uni:?}");
    }

    #[test]
    fn lighting_scales_colour_by_the_gradient_and_keeps_opacity() {
        // A ramp along x: gradient along x; light along x: |n . l| = 1.
        let n = 16u32;
        let data = (0..n.pow(3)).map(|i| (1 + 10 * (i % n)) as u8).collect();
        let v = Volume {
            dims: [n; 3],
            spacing: [1.0; 3],
            data,
            range: (0.0, 255.0),
        };
        let tf = grey(0.02);
        let mut s = unlit(1.0, 0.0);
        let flat_c = cast(&v, &tf, [-2.0, 7.5, 7.5], [1.0, 0.0, 0.0], &s);
        s.lighting = Lighting::Diffuse;
        s.light = [-100.0, 7.5, 7.5];
        let lit = cast(&v, &tf, [-2.0, 7.5, 7.5], [1.0, 0.0, 0.0], &s);
        assert!((lit[3] - flat_c[3]).abs() < 1e-12);
        // Every sample but the last (whose stencil is clamped flat at the
        // far face: no gradient, 0.15) is lit by 1.15.
        let r = lit[0] / flat_c[0];
        assert!(r > 1.05 && r < 1.15, "{r}: {lit:?} {flat_c:?}");
    }
}
