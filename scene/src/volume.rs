//! Structured scalar volumes for the volume-rendering paper (Knoll et al.
//! 2011): raw voxels (x fastest, then y, then z) read from a raw file
//! (optionally `.gz`) described by a RON sidecar or by its name
//! (`name_WxHxD_type.raw[.gz]`, as the data folder names them), or
//! generated from a seed.
//!
//! The paper's renderer classifies 8-bit values (its table is 256 x 256 and
//! Listing 2 reads `unsigned char` voxels), so every volume is held as
//! 8-bit values: wider types are mapped linearly from their own minimum and
//! maximum onto 0..=255 (rounded), and the range is kept. Zero is empty
//! space (Listing 2 skips a sample whose voxel is 0).

use crate::mesh::read_all;
use isa::rng::Rng;
use serde::Deserialize;
use std::fmt;
use std::path::Path;

/// A voxel type a raw file may hold (little-endian unless the sidecar says).
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
pub enum Voxel {
    /// Unsigned 8-bit.
    U8,
    /// Unsigned 16-bit.
    U16,
    /// Signed 16-bit.
    I16,
    /// 32-bit float.
    F32,
}

impl Voxel {
    /// Bytes per voxel.
    #[must_use]
    pub fn bytes(self) -> usize {
        match self {
            Voxel::U8 => 1,
            Voxel::U16 | Voxel::I16 => 2,
            Voxel::F32 => 4,
        }
    }
    /// The type a file name's suffix names (`uint8`, `uint16`, `int16le`,
    /// `float32le`, ...).
    fn from_name(s: &str) -> Option<Voxel> {
        let s = s.trim_end_matches("le");
        match s {
            "uint8" | "u8" => Some(Voxel::U8),
            "uint16" | "u16" => Some(Voxel::U16),
            "int16" | "i16" => Some(Voxel::I16),
            "float32" | "float" | "f32" => Some(Voxel::F32),
            _ => None,
        }
    }
}

/// A raw volume's sidecar (`*.ron`): the raw file beside it and its layout.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RawSpec {
    /// The raw file, relative to the sidecar.
    pub file: String,
    /// Voxels along x, y, z.
    pub dims: [u32; 3],
    /// Voxel type.
    pub voxel: Voxel,
    /// Voxel spacing along x, y, z (default 1).
    #[serde(default = "unit")]
    pub spacing: [f32; 3],
    /// Big-endian words (default: little-endian).
    #[serde(default)]
    pub big_endian: bool,
}

fn unit() -> [f32; 3] {
    [1.0; 3]
}

/// A volume error: the file, where in it (field, voxel), what.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct VolumeError {
    /// File.
    pub file: String,
    /// Field or place, if known.
    pub at: Option<String>,
    /// What is wrong.
    pub msg: String,
}

impl fmt::Display for VolumeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.at {
            Some(a) => write!(f, "{}: {a}: {}", self.file, self.msg),
            None => write!(f, "{}: {}", self.file, self.msg),
        }
    }
}

/// An 8-bit structured volume.
#[derive(Clone, Debug, PartialEq)]
pub struct Volume {
    /// Voxels along x, y, z.
    pub dims: [u32; 3],
    /// Voxel spacing along x, y, z.
    pub spacing: [f32; 3],
    /// Values, x fastest.
    pub data: Vec<u8>,
    /// The source values 0 and 255 stand for.
    pub range: (f64, f64),
}

impl Volume {
    /// Load a sidecar `.ron` or a raw file named `name_WxHxD_type.raw[.gz]`.
    ///
    /// # Errors
    /// A file that cannot be read, a sidecar that does not parse (field
    /// named), dimensions that do not match the file's size, an unknown
    /// voxel type, a NaN or infinite voxel (its index named).
    pub fn load(path: &Path) -> Result<Volume, VolumeError> {
        let file = path.display().to_string();
        let err = |at: Option<String>, msg: String| VolumeError {
            file: file.clone(),
            at,
            msg,
        };
        if path.extension().is_some_and(|e| e == "ron") {
            let text = std::fs::read_to_string(path).map_err(|e| err(None, e.to_string()))?;
            let spec: RawSpec = ron::from_str(&text).map_err(|e| {
                err(
                    Some(format!("line {}", e.position.line)),
                    e.code.to_string(),
                )
            })?;
            let raw = path.parent().unwrap_or(Path::new(".")).join(&spec.file);
            return Volume::from_raw(&raw, &spec);
        }
        let spec = spec_from_name(path).map_err(|m| err(Some("name".into()), m))?;
        Volume::from_raw(path, &spec)
    }

    /// Read `raw` as `spec` describes it.
    ///
    /// # Errors
    /// As [`Volume::load`].
    pub fn from_raw(raw: &Path, spec: &RawSpec) -> Result<Volume, VolumeError> {
        let file = raw.display().to_string();
        let err = |at: Option<String>, msg: String| VolumeError {
            file: file.clone(),
            at,
            msg,
        };
        let [x, y, z] = spec.dims;
        if x == 0 || y == 0 || z == 0 || spec.spacing.iter().any(|s| !(*s > 0.0 && s.is_finite())) {
            return Err(err(
                Some("dims".into()),
                format!(
                    "dims {:?} and spacing {:?} must be positive",
                    spec.dims, spec.spacing
                ),
            ));
        }
        let bytes = read_all(raw).map_err(|e| err(None, e.msg))?;
        let n = x as usize * y as usize * z as usize;
        if bytes.len() != n * spec.voxel.bytes() {
            return Err(err(
                Some("dims".into()),
                format!(
                    "{x}x{y}x{z} {:?} voxels are {} bytes; the file has {}",
                    spec.voxel,
                    n * spec.voxel.bytes(),
                    bytes.len()
                ),
            ));
        }
        let values = decode(&bytes, spec)
            .map_err(|i| err(Some(format!("voxel {i}")), "not a finite number".into()))?;
        Ok(quantise(
            spec.dims,
            spec.spacing,
            &values,
            spec.voxel == Voxel::U8,
        ))
    }

    /// Voxels in all.
    #[must_use]
    pub fn len(&self) -> usize {
        self.data.len()
    }

    /// Whether the volume has no voxels (never, once loaded).
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }

    /// The value at voxel (x, y, z), clamped to the volume.
    #[must_use]
    pub fn at(&self, x: u32, y: u32, z: u32) -> u8 {
        let [dx, dy, dz] = self.dims;
        let (x, y, z) = (x.min(dx - 1), y.min(dy - 1), z.min(dz - 1));
        self.data[((z * dy + y) * dx + x) as usize]
    }

    /// A Richtmyer-Meshkov-like mixing layer of `n`^3 voxels: a heavy fluid
    /// (255) over a light one (64) along z, their interface perturbed by a
    /// seeded multi-mode wave and, within the mixing zone, by seeded
    /// multi-octave noise; outside the mixing zone the fluids are uniform
    /// (the homogeneous regions the paper's constant-subvolume heuristic
    /// finds), and a quarter of the volume above the heavy fluid is empty.
    #[must_use]
    pub fn mixing_layer(n: u32, seed: u64) -> Volume {
        let noise = Noise::new(seed);
        let modes = noise.modes(6);
        let f = |x: f64, y: f64, z: f64| {
            let wave: f64 = modes
                .iter()
                .map(|m| m.0 * (m.1 * x + m.2 * y + m.3).sin())
                .sum();
            let interface = 0.45 + 0.06 * wave;
            let d = (z - interface) / 0.12;
            if z > 0.75 {
                return 0.0;
            }
            if d.abs() >= 1.0 {
                return if d < 0.0 { 64.0 } else { 255.0 };
            }
            let mix =
                0.5 + 0.5 * d + 0.45 * (1.0 - d.abs()) * noise.fbm(8.0 * x, 8.0 * y, 8.0 * z, 5);
            64.0 + 191.0 * mix.clamp(0.0, 1.0)
        };
        Volume::sample(n, f)
    }

    /// A dense noisy field of `n`^3 voxels (the paper's backpack and
    /// zebrafish case: little empty or homogeneous space): seeded
    /// multi-octave noise over the whole volume, 1..=255.
    #[must_use]
    pub fn noisy(n: u32, seed: u64) -> Volume {
        Volume::noisy_box([n; 3], seed)
    }

    /// [`Volume::noisy`] over a `dims` box (the noise's scale set by the
    /// largest side, so a cube gives the same bytes as `noisy`).
    #[must_use]
    pub fn noisy_box(dims: [u32; 3], seed: u64) -> Volume {
        let noise = Noise::new(seed);
        Volume::sample_box(dims, |x, y, z| {
            128.0 + 127.0 * noise.fbm(6.0 * x, 6.0 * y, 6.0 * z, 6).clamp(-1.0, 1.0)
        })
    }

    /// `n`^3 voxels of `f` over the unit cube at voxel centres, rounded.
    fn sample(n: u32, f: impl Fn(f64, f64, f64) -> f64 + Sync) -> Volume {
        Volume::sample_box([n; 3], f)
    }

    /// `dims` voxels of `f` at voxel centres, the largest side spanning
    /// 0..1, rounded. Slices are filled in parallel (each voxel depends
    /// only on its position: the same bytes for any number of threads).
    fn sample_box(dims: [u32; 3], f: impl Fn(f64, f64, f64) -> f64 + Sync) -> Volume {
        use rayon::prelude::*;
        let n = dims.iter().copied().max().unwrap_or(1).max(1);
        let c = |i: u32| (f64::from(i) + 0.5) / f64::from(n);
        let (w, h) = (dims[0] as usize, dims[1] as usize);
        let mut data = vec![0u8; w * h * dims[2] as usize];
        data.par_chunks_mut((w * h).max(1))
            .enumerate()
            .for_each(|(z, slice)| {
                for (k, v) in slice.iter_mut().enumerate() {
                    let (x, y) = ((k % w) as u32, (k / w) as u32);
                    *v = f(c(x), c(y), c(z as u32)).round().clamp(0.0, 255.0) as u8;
                }
            });
        Volume {
            dims,
            spacing: [1.0; 3],
            data,
            range: (0.0, 255.0),
        }
    }
}

/// The layout a data-folder name gives: `..._WxHxD_type.raw[.gz]`.
fn spec_from_name(path: &Path) -> Result<RawSpec, String> {
    let name = path
        .file_name()
        .and_then(|n| n.to_str())
        .unwrap_or_default();
    let stem = name.trim_end_matches(".gz").trim_end_matches(".raw");
    let parts: Vec<&str> = stem.rsplitn(3, '_').collect();
    let bad = || {
        format!("'{name}': name the layout (name_WxHxD_type.raw[.gz], type uint8, uint16, int16le or float32le) or give a .ron sidecar")
    };
    let [ty, dims, _] = parts[..] else {
        return Err(bad());
    };
    let voxel =
        Voxel::from_name(ty).ok_or_else(|| format!("unknown voxel type '{ty}' in {}", bad()))?;
    let d: Vec<u32> = dims.split('x').filter_map(|s| s.parse().ok()).collect();
    let [x, y, z] = d[..] else {
        return Err(bad());
    };
    Ok(RawSpec {
        file: name.into(),
        dims: [x, y, z],
        voxel,
        spacing: unit(),
        big_endian: false,
    })
}

/// Decode voxels to f64; `Err(i)`: voxel `i` is not finite.
fn decode(bytes: &[u8], spec: &RawSpec) -> Result<Vec<f64>, usize> {
    let w = spec.voxel.bytes();
    let word = |c: &[u8]| -> [u8; 4] {
        let mut b = [0u8; 4];
        b[..w].copy_from_slice(c);
        if spec.big_endian {
            b[..w].reverse();
        }
        b
    };
    bytes
        .chunks_exact(w)
        .enumerate()
        .map(|(i, c)| {
            let b = word(c);
            let v = match spec.voxel {
                Voxel::U8 => f64::from(b[0]),
                Voxel::U16 => f64::from(u16::from_le_bytes([b[0], b[1]])),
                Voxel::I16 => f64::from(i16::from_le_bytes([b[0], b[1]])),
                Voxel::F32 => f64::from(f32::from_le_bytes(b)),
            };
            if v.is_finite() {
                Ok(v)
            } else {
                Err(i)
            }
        })
        .collect()
}

/// 8-bit values: as they are for 8-bit data, else mapped linearly from the
/// data's own range onto 0..=255.
fn quantise(dims: [u32; 3], spacing: [f32; 3], v: &[f64], is_u8: bool) -> Volume {
    let (lo, hi) = if is_u8 {
        (0.0, 255.0)
    } else {
        v.iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                (a.min(x), b.max(x))
            })
    };
    let scale = if hi > lo { 255.0 / (hi - lo) } else { 0.0 };
    Volume {
        dims,
        spacing,
        data: v
            .iter()
            .map(|&x| ((x - lo) * scale).round().clamp(0.0, 255.0) as u8)
            .collect(),
        range: (lo, hi),
    }
}

/// Seeded value noise on the integer lattice, trilinearly blended with a
/// smooth fade.
struct Noise {
    seed: u64,
}

impl Noise {
    fn new(seed: u64) -> Noise {
        Noise { seed }
    }
    /// Seeded wave modes (amplitude, kx, ky, phase) for the interface.
    fn modes(&self, n: usize) -> Vec<(f64, f64, f64, f64)> {
        let mut r = Rng::new(self.seed ^ 0x6d6f_6465);
        (0..n)
            .map(|k| {
                let f = std::f64::consts::TAU * (1.0 + k as f64);
                let amp = 1.0 / (1.0 + k as f64);
                let a = f64::from(r.range(0.0, std::f32::consts::TAU));
                let ph = f64::from(r.range(0.0, std::f32::consts::TAU));
                (amp, f * a.cos(), f * a.sin(), ph)
            })
            .collect()
    }
    /// Lattice value in [-1, 1].
    fn lattice(&self, x: i64, y: i64, z: i64) -> f64 {
        let h = crate_mix(
            self.seed ^ crate_mix((x as u64) ^ crate_mix((y as u64) ^ crate_mix(z as u64))),
        );
        (h >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    }
    /// Value noise at a point.
    fn value(&self, x: f64, y: f64, z: f64) -> f64 {
        let (ix, iy, iz) = (x.floor() as i64, y.floor() as i64, z.floor() as i64);
        let fade = |t: f64| t * t * (3.0 - 2.0 * t);
        let (fx, fy, fz) = (
            fade(x - x.floor()),
            fade(y - y.floor()),
            fade(z - z.floor()),
        );
        let lerp = |a: f64, b: f64, t: f64| a + (b - a) * t;
        let l = |dx, dy, dz| self.lattice(ix + dx, iy + dy, iz + dz);
        let x00 = lerp(l(0, 0, 0), l(1, 0, 0), fx);
        let x10 = lerp(l(0, 1, 0), l(1, 1, 0), fx);
        let x01 = lerp(l(0, 0, 1), l(1, 0, 1), fx);
        let x11 = lerp(l(0, 1, 1), l(1, 1, 1), fx);
        lerp(lerp(x00, x10, fy), lerp(x01, x11, fy), fz)
    }
    /// `octaves` of noise, each twice the frequency and half the amplitude.
    fn fbm(&self, x: f64, y: f64, z: f64, octaves: u32) -> f64 {
        (0..octaves)
            .map(|o| {
                let f = f64::from(1u32 << o);
                self.value(x * f, y * f, z * f) / f
            })
            .sum()
    }
}

/// SplitMix64's finaliser: a well-mixed hash of a word.
fn crate_mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmp(name: &str, bytes: &[u8]) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("rtsim-volume-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    }

    #[test]
    fn a_named_raw_file_loads_and_wider_types_map_onto_8_bits() {
        let p = tmp("cube_2x2x2_uint8.raw", &[0, 1, 2, 3, 4, 5, 6, 255]);
        let v = Volume::load(&p).unwrap();
        assert_eq!(
            (v.dims, v.at(1, 1, 1), v.at(9, 9, 9)),
            ([2, 2, 2], 255, 255)
        );
        let words: Vec<u8> = [-100i16, 0, 100, 155]
            .iter()
            .flat_map(|w| w.to_le_bytes())
            .collect();
        let p = tmp("w_2x2x1_int16le.raw", &words);
        let v = Volume::load(&p).unwrap();
        assert_eq!(
            (v.data.clone(), v.range),
            (vec![0, 100, 200, 255], (-100.0, 155.0))
        );
    }

    #[test]
    fn bad_volumes_are_named_errors() {
        let p = tmp("short_4x4x4_uint8.raw", &[1; 10]);
        let e = Volume::load(&p).unwrap_err().to_string();
        assert!(
            e.contains(
                "short_4x4x4_uint8.raw: dims: 4x4x4 U8 voxels are 64 bytes; the file has 10"
            ),
            "{e}"
        );
        let p = tmp("t_1x1x1_complex64.raw", &[0; 8]);
        let e = Volume::load(&p).unwrap_err().to_string();
        assert!(e.contains("unknown voxel type 'complex64'"), "{e}");
        let nan: Vec<u8> = [1.0f32, f32::NAN]
            .iter()
            .flat_map(|w| w.to_le_bytes())
            .collect();
        let p = tmp("n_2x1x1_float32le.raw", &nan);
        let e = Volume::load(&p).unwrap_err().to_string();
        assert!(e.contains("voxel 1: not a finite number"), "{e}");
        let side = tmp(
            "s.ron",
            b"(file: \"x.raw\", dims: (1, 1, 1), voxel: U8, colour: 3)",
        );
        let e = Volume::load(&side).unwrap_err().to_string();
        assert!(e.contains("s.ron: line 1") && e.contains("colour"), "{e}");
        let side = tmp(
            "z.ron",
            b"(file: \"n_2x1x1_float32le.raw\", dims: (0, 1, 1), voxel: F32)",
        );
        let e = Volume::load(&side).unwrap_err().to_string();
        assert!(e.contains("dims: dims [0, 1, 1]"), "{e}");
    }

    #[test]
    fn a_sidecar_names_its_raw_file_and_byte_order() {
        tmp("be.raw", &[0x01, 0x00, 0x00, 0x02]);
        let side = tmp("be.ron", b"(file: \"be.raw\", dims: (2, 1, 1), voxel: U16, big_endian: true, spacing: (1.0, 2.0, 3.0))");
        let v = Volume::load(&side).unwrap();
        assert_eq!((v.range, v.spacing), ((2.0, 256.0), [1.0, 2.0, 3.0]));
    }

    #[test]
    fn generated_fields_are_seeded_and_have_their_structure() {
        let a = Volume::mixing_layer(32, 3);
        assert_eq!(a, Volume::mixing_layer(32, 3));
        assert_ne!(a, Volume::mixing_layer(32, 4));
        // Uniform light fluid at the bottom, empty space at the top.
        assert_eq!((a.at(5, 5, 0), a.at(5, 5, 31)), (64, 0));
        let zeros = a.data.iter().filter(|&&v| v == 0).count();
        assert!(zeros * 5 >= a.len(), "a quarter empty: {zeros}");
        let b = Volume::noisy(32, 3);
        assert!(b.data.iter().all(|&v| v > 0), "dense");
        let distinct = b
            .data
            .iter()
            .collect::<std::collections::BTreeSet<_>>()
            .len();
        assert!(distinct > 64, "noisy: {distinct} values");
    }
}
