//! Soft-shadow shading and the 4 x 4 discontinuity filter (Benthin and Wald
//! 2009, section 4.5), 16 pixels of a row at a time: shading from one sample
//! at the light's centre (the visibility term kept apart), then each pixel's
//! visibility averaged over the 4 x 4 neighbourhood of pixels with a similar
//! depth and normal, so the 16 interleaved sample sets of a 4 x 4 pixel
//! tile combine into 256 samples.
//!
//! Frame buffers (f32, rows padded by [`PAD_X`] columns and [`PAD_Y`] rows on
//! each side so neighbours never leave the buffer; padding has depth +inf,
//! so it is never similar):
//!
//! | buffer | per pixel |
//! |---|---|
//! | `t`, `prim` | the primary hit (t along the camera ray, prim -1: none) |
//! | `vis` | fraction of the pixel's shadow rays that reach the light |
//! | `nx ny nz` | unit normal facing the camera (G-buffer) |
//! | `z` | depth (t; +inf for no hit) |
//! | `e` | direct light from the light's centre, unshadowed |
//! | `color` | the shaded pixel, in [0, 1] |
//!
//! Triangle table: 64 B per triangle, `v0.xyz v1.xyz v2.xyz` f32, gathered
//! by primitive id. Deviation: the paper gathers three vertex indices, then
//! the vertices; we store the vertices per triangle (one gather level).

use isa::{At, Buf, Cmp, Machine, MemKind, Program, Region, Shift};
use scene::mesh::Mesh;

/// Padding columns on each side (keeps the image's columns 64 B aligned).
pub const PAD_X: usize = 16;
/// Padding rows above and below (the filter reaches 2 rows).
pub const PAD_Y: usize = 2;

/// Depth similarity: neighbours within this fraction of the pixel's depth.
pub const DEPTH_TOL: f32 = 0.1;
/// Normal similarity: neighbours whose normal has at least this cosine.
pub const NORMAL_COS: f32 = 0.9;

/// What the shading pass needs besides the hits: the camera, the light and
/// the look of the scene.
#[derive(Clone, Debug, PartialEq)]
pub struct ShadeSetup {
    /// Image size (width a multiple of 16).
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Camera origin.
    pub eye: [f32; 3],
    /// Camera ray direction through pixel (0, 0)'s centre; directions are
    /// affine in the pixel: `d00 + x dx + y dy`.
    pub d00: [f32; 3],
    /// Direction step per pixel column.
    pub dx: [f32; 3],
    /// Direction step per pixel row.
    pub dy: [f32; 3],
    /// The light's centre.
    pub light_centre: [f32; 3],
    /// The light's unit normal (either side lights).
    pub light_normal: [f32; 3],
    /// Scale of the direct term (power, area, albedo and exposure together).
    pub scale: f32,
    /// Ambient term of lit-or-not geometry.
    pub ambient: f32,
}

/// Shading (and filtering) over rows `rows` of an image (a [`Program`]):
/// the colour of every pixel of those rows, row-major.
pub struct ShadeRun<'a> {
    /// The scene's triangles.
    pub mesh: &'a Mesh,
    /// Camera, light, look.
    pub setup: &'a ShadeSetup,
    /// Per pixel (row-major, unpadded): primary hit t.
    pub t: &'a [f32],
    /// Per pixel: primary hit primitive (-1: none).
    pub prim: &'a [i32],
    /// Per pixel: unshadowed fraction of its shadow rays.
    pub vis: &'a [f32],
    /// Rows to produce.
    pub rows: std::ops::Range<u32>,
    /// Apply the 4 x 4 discontinuity filter to the visibility.
    pub filter: bool,
}

/// Counters of the shading kernel.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ShadeStats {
    /// 16-pixel shading steps.
    pub shade_steps: u64,
    /// 16-pixel filter steps.
    pub filter_steps: u64,
}

/// The image buffers of a shading run in simulated memory (padded rows).
struct ShadeBufs {
    stride: usize,
    tris: Buf,
    tb: Buf,
    pb: Buf,
    vb: Buf,
    /// Unit normals (x, y, z), depth and direct light of shaded pixels.
    g: Vec<Buf>,
    zb: Buf,
    eb: Buf,
    cb: Buf,
}

impl ShadeBufs {
    /// Byte offset of pixel (x, y).
    fn at(&self, x: usize, y: usize) -> usize {
        4 * ((y + PAD_Y) * self.stride + PAD_X + x)
    }
}

/// The splatted constants of a shading run.
struct ShadeConsts<M: Machine> {
    lanes: M::F,
    eye: [M::F; 3],
    d00: [M::F; 3],
    ddx: [M::F; 3],
    ddy: [M::F; 3],
    lc: [M::F; 3],
    ln: [M::F; 3],
    scale: M::F,
    ambient: M::F,
    zero: M::F,
    one: M::F,
    pinf: M::F,
    none: M::I,
}

/// `a . b` per lane.
fn dot3<M: Machine>(m: &mut M, a: [M::F; 3], b: [M::F; 3]) -> M::F {
    let d = m.mul(a[0], b[0]);
    let d = m.fmadd(a[1], b[1], d);
    m.fmadd(a[2], b[2], d)
}

impl ShadeRun<'_> {
    /// The triangles, hits and visibility laid out padded, and the work buffers.
    fn lay_out<M: Machine>(&self, m: &mut M) -> ShadeBufs {
        let su = self.setup;
        let (w, h) = (su.width as usize, su.height as usize);
        let stride = w + 2 * PAD_X;
        let rows_p = h + 2 * PAD_Y;
        let padded = |src: &[f32], fill: f32| {
            let mut v = vec![fill; stride * rows_p];
            for y in 0..h {
                for x in 0..w {
                    v[(y + PAD_Y) * stride + PAD_X + x] = src[y * w + x];
                }
            }
            v
        };
        let mut tri = Vec::with_capacity(self.mesh.len() * 16);
        for p in 0..self.mesh.len() {
            let [a, b, c] = self.mesh.tri(p);
            tri.extend(a.iter().chain(&b).chain(&c));
            tri.extend([0.0; 7]);
        }
        let prim_f: Vec<f32> = self
            .prim
            .iter()
            .map(|&p| f32::from_bits(p as u32))
            .collect();
        let sp = m.space();
        let tris = sp.alloc_f32(MemKind::Triangles, "shade-tris", &tri, 64);
        let tb = sp.alloc_f32(MemKind::Hits, "shade-t", &padded(self.t, 0.0), 64);
        let pb = sp.alloc_f32(
            MemKind::Hits,
            "shade-prim",
            &padded(&prim_f, f32::from_bits(u32::MAX)),
            64,
        );
        let vb = sp.alloc_f32(MemKind::Hits, "shade-vis", &padded(self.vis, 0.0), 64);
        let n = stride * rows_p;
        let g: Vec<Buf> = ["nx", "ny", "nz"]
            .iter()
            .map(|s| sp.alloc_f32(MemKind::Other, s, &vec![0.0; n], 64))
            .collect();
        let zb = sp.alloc_f32(MemKind::Other, "z", &vec![f32::INFINITY; n], 64);
        let eb = sp.alloc_f32(MemKind::Other, "e", &vec![0.0; n], 64);
        let cb = sp.alloc_f32(MemKind::Other, "color", &vec![0.0; n], 64);
        ShadeBufs {
            stride,
            tris,
            tb,
            pb,
            vb,
            g,
            zb,
            eb,
            cb,
        }
    }

    /// The run's constants (setup region).
    fn consts<M: Machine>(&self, m: &mut M) -> ShadeConsts<M> {
        let su = self.setup;
        m.region(Region::Setup);
        let lanes: Vec<f32> = (0..16).map(|i| i as f32).collect();
        let lanes = m.consts(&lanes);
        let sp3 = |m: &mut M, v: [f32; 3]| [m.splat(v[0]), m.splat(v[1]), m.splat(v[2])];
        let eye = sp3(m, su.eye);
        let d00 = sp3(m, su.d00);
        let ddx = sp3(m, su.dx);
        let ddy = sp3(m, su.dy);
        let lc = sp3(m, su.light_centre);
        let ln = sp3(m, su.light_normal);
        let scale = m.splat(su.scale);
        let ambient = m.splat(su.ambient);
        let zero = m.splat(0.0);
        let one = m.splat(1.0);
        let pinf = m.splat(f32::INFINITY);
        let none = m.splat_i(-1);
        ShadeConsts {
            lanes,
            eye,
            d00,
            ddx,
            ddy,
            lc,
            ln,
            scale,
            ambient,
            zero,
            one,
            pinf,
            none,
        }
    }
}

impl Program for ShadeRun<'_> {
    type Out = (Vec<f32>, ShadeStats);

    fn run<M: Machine>(&self, m: &mut M) -> Self::Out {
        assert_eq!(M::LANES, 16, "16 pixels a step");
        let su = self.setup;
        let (w, h) = (su.width as usize, su.height as usize);
        assert!(w.is_multiple_of(16), "width a multiple of 16");
        let mut bf = self.lay_out(m);
        let mut st = ShadeStats::default();
        let c = self.consts(m);

        // Pass 1: shade the rows and the filter's neighbour rows.
        m.region(Region::Shading);
        let lo = (self.rows.start as usize).saturating_sub(2);
        let hi = (self.rows.end as usize + 2).min(h);
        let y_lo = if self.filter {
            lo
        } else {
            self.rows.start as usize
        };
        let y_hi = if self.filter {
            hi
        } else {
            self.rows.end as usize
        };
        for y in y_lo..y_hi {
            let yf = m.splat(y as f32);
            for x0 in (0..w).step_by(16) {
                st.shade_steps += 1;
                shade_step(m, &mut bf, &c, (x0, y, yf));
            }
        }

        // Pass 2: (filtered) visibility times the direct light, plus ambient.
        let tol = m.splat(DEPTH_TOL);
        let ncos = m.splat(NORMAL_COS);
        let mut out = Vec::with_capacity(self.rows.len() * w);
        for y in self.rows.clone() {
            let y = y as usize;
            for x0 in (0..w).step_by(16) {
                if self.filter {
                    st.filter_steps += 1;
                }
                colour_step(m, &mut bf, &c, (tol, ncos), (x0, y), self.filter);
                for i in 0..16 {
                    out.push(bf.cb.f32_at(bf.at(x0 + i, y)));
                }
            }
        }
        (out, st)
    }
}

/// Pass 1 for 16 pixels: the hit triangle's unit normal facing the camera,
/// the depth, and the unshadowed direct light from the light's centre.
fn shade_step<M: Machine>(
    m: &mut M,
    bf: &mut ShadeBufs,
    c: &ShadeConsts<M>,
    (x0, y, yf): (usize, usize, M::F),
) {
    let (zero, pinf, none, lanes) = (c.zero, c.pinf, c.none, c.lanes);
    let (eye, d00, ddx, ddy, lc, ln, scale) = (c.eye, c.d00, c.ddx, c.ddy, c.lc, c.ln, c.scale);
    let o = At::off(bf.at(x0, y));
    let t = m.load(&bf.tb, o);
    let p = m.load(&bf.pb, o);
    let p = m.bits_to_i(p);
    let hit = m.icmp(Cmp::Gt, p, none);
    let idx = m.ishift(Shift::Shl, p, 4);
    let v: Vec<M::F> = (0..9)
        .map(|k| m.gather(hit, zero, &bf.tris, At::off(4 * k), idx, 4))
        .collect();
    let e1 = [0, 1, 2].map(|a| m.sub(v[3 + a], v[a]));
    let e2 = [0, 1, 2].map(|a| m.sub(v[6 + a], v[a]));
    let cr = |m: &mut M, i: usize, j: usize| {
        let q = m.mul(e1[j], e2[i]);
        m.fmsub(e1[i], e2[j], q)
    };
    let nrm = [cr(m, 1, 2), cr(m, 2, 0), cr(m, 0, 1)];
    // The camera ray of each lane's pixel.
    let xf = m.splat(x0 as f32);
    let xs = m.add(xf, lanes);
    let d = [0, 1, 2].map(|a| {
        let q = m.fmadd(xs, ddx[a], d00[a]);
        m.fmadd(yf, ddy[a], q)
    });
    let pt = [0, 1, 2].map(|a| m.fmadd(t, d[a], eye[a]));
    // Normal facing the camera, unit length.
    let s = dot3(m, nrm, d);
    let back = m.cmp(Cmp::Gt, s, zero);
    let nn = dot3(m, nrm, nrm);
    let inv = m.rsqrt(nn);
    let ninv = m.neg(inv);
    let inv = m.select(back, ninv, inv);
    let nu = nrm.map(|c| m.mul(c, inv));
    // Direct light from the light's centre, unshadowed.
    let l = [0, 1, 2].map(|a| m.sub(lc[a], pt[a]));
    let d2 = dot3(m, l, l);
    let il = m.rsqrt(d2);
    let ndl = dot3(m, nu, l);
    let ndl = m.mul(ndl, il);
    let ndl = m.max(ndl, zero);
    let cl = dot3(m, ln, l);
    let cl = m.abs(cl);
    let cl = m.mul(cl, il);
    let e = m.mul(ndl, cl);
    let e = m.div(e, d2);
    let e = m.mul(e, scale);
    let e = m.select(hit, e, zero);
    let z = m.select(hit, t, pinf);
    for (a, buf) in bf.g.iter_mut().enumerate() {
        m.store(buf, o, nu[a]);
    }
    m.store(&mut bf.zb, o, z);
    m.store(&mut bf.eb, o, e);
}

/// Pass 2 for 16 pixels: visibility (with `filter`, averaged over the 4 x 4
/// window's pixels of similar depth and normal) times the direct light, plus
/// ambient, into the colour buffer.
fn colour_step<M: Machine>(
    m: &mut M,
    bf: &mut ShadeBufs,
    c: &ShadeConsts<M>,
    (tol, ncos): (M::F, M::F),
    (x0, y): (usize, usize),
    filter: bool,
) {
    let (zero, one, pinf, ambient, stride) = (c.zero, c.one, c.pinf, c.ambient, bf.stride);
    let o = At::off(bf.at(x0, y));
    let z0 = m.load(&bf.zb, o);
    let hit = m.cmp(Cmp::Lt, z0, pinf);
    let vis = if filter {
        let n0 = [0, 1, 2].map(|a| m.load(&bf.g[a], o));
        let lim = m.mul(z0, tol);
        let (mut sum, mut cnt) = (zero, zero);
        for dy in 0..4 {
            for dx in 0..4 {
                // The 4 x 4 window: columns and rows -1 .. +2.
                let q = At::off(bf.at(x0, y + dy) + 4 * dx - 4 * stride - 4);
                let zn = m.loadu(&bf.zb, q);
                let dz = m.sub(zn, z0);
                let dz = m.abs(dz);
                let near = m.cmp(Cmp::Le, dz, lim);
                let nn = [0, 1, 2].map(|a| m.loadu(&bf.g[a], q));
                let cs = dot3(m, n0, nn);
                let same = m.cmp(Cmp::Ge, cs, ncos);
                let ok = m.kand(near, same);
                let v = m.loadu(&bf.vb, q);
                sum = m.masked(isa::BinOp::Add, ok, sum, sum, v);
                cnt = m.masked(isa::BinOp::Add, ok, cnt, cnt, one);
            }
        }
        let some = m.cmp(Cmp::Gt, cnt, zero);
        let avg = m.div(sum, cnt);
        let own = m.load(&bf.vb, o);
        m.select(some, avg, own)
    } else {
        m.load(&bf.vb, o)
    };
    let e = m.load(&bf.eb, o);
    let col = m.fmadd(e, vis, ambient);
    let col = m.min(col, one);
    let col = m.select(hit, col, zero);
    m.store(&mut bf.cb, o, col);
}

/// The scalar reference of [`ShadeRun`] over the whole image (f64): the
/// same shading and filter, pixel by pixel.
#[must_use]
pub fn reference(
    mesh: &Mesh,
    su: &ShadeSetup,
    t: &[f32],
    prim: &[i32],
    vis: &[f32],
    filter: bool,
) -> Vec<f32> {
    let (w, h) = (su.width as usize, su.height as usize);
    let f = |v: [f32; 3]| v.map(f64::from);
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    // G-buffer: unit facing normal, depth, direct light.
    let mut g = vec![([0.0f64; 3], f64::INFINITY, 0.0f64); w * h];
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            if prim[i] < 0 {
                continue;
            }
            let d = [0, 1, 2].map(|a| {
                f64::from(su.d00[a])
                    + x as f64 * f64::from(su.dx[a])
                    + y as f64 * f64::from(su.dy[a])
            });
            let p = [0, 1, 2].map(|a| f64::from(su.eye[a]) + f64::from(t[i]) * d[a]);
            let [v0, v1, v2] = mesh.tri(prim[i] as usize).map(f);
            let (e1, e2) = (sub(v1, v0), sub(v2, v0));
            let mut n = [
                e1[1] * e2[2] - e1[2] * e2[1],
                e1[2] * e2[0] - e1[0] * e2[2],
                e1[0] * e2[1] - e1[1] * e2[0],
            ];
            let len = dot(n, n).sqrt() * if dot(n, d) > 0.0 { -1.0 } else { 1.0 };
            n = n.map(|c| c / len);
            let l = sub(f(su.light_centre), p);
            let d2 = dot(l, l);
            let il = 1.0 / d2.sqrt();
            let ndl = (dot(n, l) * il).max(0.0);
            let cl = dot(f(su.light_normal), l).abs() * il;
            g[i] = (n, f64::from(t[i]), ndl * cl / d2 * f64::from(su.scale));
        }
    }
    let mut out = vec![0.0f32; w * h];
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let (n0, z0, e) = g[i];
            if z0.is_infinite() {
                continue;
            }
            let v = if filter {
                let (mut sum, mut cnt) = (0.0, 0.0);
                for yy in y.saturating_sub(1)..(y + 3).min(h) {
                    for xx in x.saturating_sub(1)..(x + 3).min(w) {
                        let j = yy * w + xx;
                        let (nn, zn, _) = g[j];
                        let near = (zn - z0).abs() <= z0 * f64::from(DEPTH_TOL);
                        if near && dot(n0, nn) >= f64::from(NORMAL_COS) {
                            sum += f64::from(vis[j]);
                            cnt += 1.0;
                        }
                    }
                }
                if cnt > 0.0 {
                    sum / cnt
                } else {
                    f64::from(vis[i])
                }
            } else {
                f64::from(vis[i])
            };
            out[i] = (f64::from(su.ambient) + e * v).min(1.0) as f32;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use scene::reference::{Ray, Reference};

    /// A ground quad under a box, seen from above at an angle, with
    /// visibility varying over the image (a ramp and a step).
    fn setup() -> (Mesh, ShadeSetup, Vec<f32>, Vec<i32>, Vec<f32>) {
        let mut mesh = scene::scene::build_source(&scene::scene::Source::Ground(2.0)).unwrap();
        let cube = scene::scene::build_source(&scene::scene::Source::Cuboid(
            [-0.4, 0.0, -0.4],
            [0.4, 0.6, 0.4],
        ))
        .unwrap();
        mesh.append(&cube, |p| p);
        let (w, h) = (32u32, 20u32);
        let eye = [0.3f32, 2.0, 3.0];
        let fwd = [-0.3f32, -2.0, -3.0];
        let len = fwd.iter().map(|c| c * c).sum::<f32>().sqrt();
        let fwd = fwd.map(|c| c / len);
        let right = [1.0f32, 0.0, -0.1];
        let up = [
            right[1] * fwd[2] - right[2] * fwd[1],
            right[2] * fwd[0] - right[0] * fwd[2],
            right[0] * fwd[1] - right[1] * fwd[0],
        ];
        let s = 0.03f32;
        let d00 = [0, 1, 2].map(|a| fwd[a] - 16.0 * s * right[a] + 10.0 * s * up[a]);
        let su = ShadeSetup {
            width: w,
            height: h,
            eye,
            d00,
            dx: right.map(|c| c * s),
            dy: up.map(|c| -c * s),
            light_centre: [0.5, 3.0, 0.2],
            light_normal: [0.0, -1.0, 0.0],
            scale: 6.0,
            ambient: 0.1,
        };
        let refi = Reference::brute(&mesh);
        let (mut t, mut prim, mut vis) = (Vec::new(), Vec::new(), Vec::new());
        for y in 0..h {
            for x in 0..w {
                let d = [0, 1, 2].map(|a| {
                    f64::from(su.d00[a])
                        + f64::from(x) * f64::from(su.dx[a])
                        + f64::from(y) * f64::from(su.dy[a])
                });
                match refi.closest(&Ray::new(eye.map(f64::from), d)) {
                    Some(hh) => {
                        t.push(hh.t as f32);
                        prim.push(hh.prim as i32);
                    }
                    None => {
                        t.push(0.0);
                        prim.push(-1);
                    }
                }
                vis.push(if x < 12 {
                    x as f32 / 12.0
                } else {
                    f32::from(y % 3 == 0)
                });
            }
        }
        (mesh, su, t, prim, vis)
    }

    #[test]
    fn kernel_matches_the_scalar_reference_with_and_without_the_filter() {
        let (mesh, su, t, prim, vis) = setup();
        assert!(prim.iter().any(|&p| p < 0) && prim.iter().filter(|&&p| p >= 0).count() > 300);
        for filter in [false, true] {
            let want = reference(&mesh, &su, &t, &prim, &vis, filter);
            let run = ShadeRun {
                mesh: &mesh,
                setup: &su,
                t: &t,
                prim: &prim,
                vis: &vis,
                rows: 0..su.height,
                filter,
            };
            let (got, st) = isa::record(&run, isa::FlavourId::Lrb16, "shade").1;
            assert_eq!(
                (got.clone(), st),
                isa::run_native(&run, isa::FlavourId::Lrb16)
            );
            let worst = got
                .iter()
                .zip(&want)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0f32, f32::max);
            assert!(worst < 1e-4, "filter {filter}: worst {worst}");
            assert!(want.iter().any(|&c| c > 0.3), "lit pixels");
            // Rows in parts give the same pixels.
            let top = ShadeRun { rows: 0..7, ..run };
            let bottom = ShadeRun {
                rows: 7..su.height,
                ..top
            };
            let mut parts = isa::run_native(&top, isa::FlavourId::Lrb16).0;
            parts.extend(isa::run_native(&bottom, isa::FlavourId::Lrb16).0);
            assert_eq!(parts, got, "filter {filter}");
        }
        // The filter smooths the step pattern: fewer distinct values.
        let raw = reference(&mesh, &su, &t, &prim, &vis, false);
        let smooth = reference(&mesh, &su, &t, &prim, &vis, true);
        assert_ne!(raw, smooth);
    }
}
