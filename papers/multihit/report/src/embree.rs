//! The peer, for real (cargo feature `embree`): Embree 3 (Debian's
//! `libembree-dev`) traces the same rays with its own BVH and traversal, and
//! the same two filters written against its API: `rtcIntersect1` and
//! `rtcIntersect8` with an intersection filter that rejects, or accepts with
//! a changed t_far (Listing 1 as the paper wrote it for Embree 2.10).
//!
//! The scene is built with `RTC_SCENE_FLAG_ROBUST` (watertight triangle
//! tests: a ray down a shared edge hits both neighbours, as the f64
//! reference does; the agreement rule lets an f32 kernel drop a grazing hit
//! either way). The bindings are written here (a handful of calls of
//! `rtcore.h` 3.13); no bindings crate on crates.io targets Embree 3's C API
//! as Debian ships it.

#![allow(unsafe_code)]

use multihit_kernels::Method;
use scene::mesh::Mesh;
use scene::workload::RayStream;
use scene::Hit;
use std::ffi::c_void;

#[repr(C)]
struct RTCIntersectContext {
    flags: u32,
    filter: Option<unsafe extern "C" fn(*const FilterArgs)>,
    inst_id: [u32; 1],
}

#[repr(C)]
struct FilterArgs {
    valid: *mut i32,
    geometry_user_ptr: *mut c_void,
    context: *mut RTCIntersectContext,
    ray: *mut c_void,
    hit: *mut c_void,
    n: u32,
}

#[repr(C, align(16))]
#[derive(Clone, Copy)]
struct RayHit1 {
    org: [f32; 3],
    tnear: f32,
    dir: [f32; 3],
    time: f32,
    tfar: f32,
    mask: u32,
    id: u32,
    flags: u32,
    ng: [f32; 3],
    u: f32,
    v: f32,
    prim_id: u32,
    geom_id: u32,
    inst_id: u32,
}

/// `RTCRayHit8`: the ray rows (org x/y/z, tnear, dir x/y/z, time, tfar,
/// mask, id, flags), then the hit rows (Ng x/y/z, u, v, primID, geomID,
/// instID), 8 lanes each.
#[repr(C, align(32))]
struct RayHit8 {
    f: [[f32; 8]; 20],
}

type Device = *mut c_void;
type Scene = *mut c_void;
type Geometry = *mut c_void;

#[link(name = "embree3")]
extern "C" {
    fn rtcNewDevice(config: *const i8) -> Device;
    fn rtcReleaseDevice(d: Device);
    fn rtcGetDeviceError(d: Device) -> i32;
    fn rtcNewScene(d: Device) -> Scene;
    fn rtcSetSceneFlags(s: Scene, flags: u32);
    fn rtcReleaseScene(s: Scene);
    fn rtcNewGeometry(d: Device, kind: u32) -> Geometry;
    fn rtcSetNewGeometryBuffer(
        g: Geometry,
        kind: u32,
        slot: u32,
        format: u32,
        stride: usize,
        count: usize,
    ) -> *mut c_void;
    fn rtcSetGeometryIntersectFilterFunction(
        g: Geometry,
        f: Option<unsafe extern "C" fn(*const FilterArgs)>,
    );
    fn rtcCommitGeometry(g: Geometry);
    fn rtcAttachGeometry(s: Scene, g: Geometry) -> u32;
    fn rtcReleaseGeometry(g: Geometry);
    fn rtcCommitScene(s: Scene);
    fn rtcIntersect1(s: Scene, ctx: *mut RTCIntersectContext, rh: *mut RayHit1);
    fn rtcIntersect8(valid: *const i32, s: Scene, ctx: *mut RTCIntersectContext, rh: *mut RayHit8);
}

const GEOMETRY_TYPE_TRIANGLE: u32 = 0;
const BUFFER_TYPE_INDEX: u32 = 0;
const BUFFER_TYPE_VERTEX: u32 = 1;
const FORMAT_UINT3: u32 = 0x5003;
const FORMAT_FLOAT3: u32 = 0x9003;
const SCENE_FLAG_ROBUST: u32 = 1 << 2;
const INVALID_ID: u32 = u32::MAX;

/// The filter's state, reached through the context (Embree's tutorials'
/// way of passing per-call data): the method, N_query and every ray's
/// entries, found by the ray's id.
#[repr(C)]
struct Context {
    base: RTCIntersectContext,
    state: *mut State,
}

struct State {
    method: Method,
    n_query: u32,
    cap: usize,
    /// Per ray `cap` entries (t, triangle).
    entries: Vec<(f32, u32)>,
    counts: Vec<u32>,
}

/// The filter (`RTCFilterFunctionN`): for each valid lane, Listing 1 or the
/// naive append, on that ray's buffer.
unsafe extern "C" fn filter(args: *const FilterArgs) {
    // SAFETY: Embree passes valid arguments for N rays; the context is ours
    // (`Context` starts with the RTCIntersectContext Embree was given).
    let a = unsafe { &*args };
    let st = unsafe { &mut *(*(a.context as *const Context)).state };
    let n = a.n as usize;
    for i in 0..n {
        // SAFETY: N-wide SoA rows as `rtcore_ray.h` lays out RTCRayN/RTCHitN.
        unsafe {
            if *a.valid.add(i) == 0 {
                continue;
            }
            let tfar = (a.ray as *mut f32).add(8 * n + i);
            let id = *(a.ray as *const u32).add(10 * n + i) as usize;
            let prim = *(a.hit as *const u32).add(5 * n + i);
            match st.judge(id, *tfar, prim) {
                None => *a.valid.add(i) = 0,
                Some(t) => *tfar = t,
            }
        }
    }
}

impl State {
    /// One candidate of ray `id`: `None` rejects; `Some(t_far)` accepts.
    fn judge(&mut self, id: usize, t: f32, prim: u32) -> Option<f32> {
        let e = &mut self.entries[id * self.cap..(id + 1) * self.cap];
        let held = &mut self.counts[id];
        match self.method {
            Method::Naive => {
                if (*held as usize) < self.cap {
                    e[*held as usize] = (t, prim);
                    *held += 1;
                }
                None
            }
            Method::NodeCulling => {
                let nq = self.n_query as usize;
                let mut idx = nq;
                while idx > 0 && t < e[idx - 1].0 {
                    e[idx] = e[idx - 1];
                    idx -= 1;
                }
                e[idx] = (t, prim);
                *held += u32::from((*held as usize) < nq);
                ((*held as usize) >= nq).then(|| e[nq - 1].0)
            }
        }
    }

    /// Each ray's N_query nearest, nearest first (naive: a selection of the
    /// N_query nearest after traversal, as the paper's naive module).
    fn lists(&mut self, n_rays: usize) -> Vec<Vec<Hit>> {
        (0..n_rays)
            .map(|r| {
                let e = &mut self.entries[r * self.cap..(r + 1) * self.cap];
                let count = (self.counts[r] as usize).min(self.cap);
                let k = count.min(self.n_query as usize);
                if self.method == Method::Naive {
                    for i in 0..k {
                        let best = (i..count)
                            .min_by(|&x, &y| e[x].0.total_cmp(&e[y].0))
                            .expect("a place");
                        e.swap(i, best);
                    }
                }
                e[..k]
                    .iter()
                    .map(|&(t, p)| Hit { t, prim: Some(p) })
                    .collect()
            })
            .collect()
    }
}

/// Which Embree call traces the rays.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Call {
    /// `rtcIntersect1`, ray by ray.
    One,
    /// `rtcIntersect8` over packet slots.
    Eight,
}

/// An Embree device and the scene of one mesh.
pub(crate) struct Embree {
    device: Device,
    scene: Scene,
}

// SAFETY: Embree scenes are safe to trace from several threads once
// committed; the device and scene are released once, on drop.
unsafe impl Send for Embree {}
unsafe impl Sync for Embree {}

impl Embree {
    /// Embree's BVH over `mesh` (robust mode), the filter set on its geometry.
    pub(crate) fn new(mesh: &Mesh) -> Result<Embree, String> {
        // SAFETY: plain Embree API calls with buffers Embree allocates and
        // we fill within their sizes.
        unsafe {
            let device = rtcNewDevice(c"threads=1".as_ptr());
            if device.is_null() {
                return Err("embree: rtcNewDevice failed".into());
            }
            let scene = rtcNewScene(device);
            rtcSetSceneFlags(scene, SCENE_FLAG_ROBUST);
            let g = rtcNewGeometry(device, GEOMETRY_TYPE_TRIANGLE);
            let nv = mesh.positions.len();
            let v = rtcSetNewGeometryBuffer(g, BUFFER_TYPE_VERTEX, 0, FORMAT_FLOAT3, 12, nv)
                as *mut [f32; 3];
            std::ptr::copy_nonoverlapping(mesh.positions.as_ptr(), v, nv);
            let nt = mesh.tris.len();
            let ix = rtcSetNewGeometryBuffer(g, BUFFER_TYPE_INDEX, 0, FORMAT_UINT3, 12, nt)
                as *mut [u32; 3];
            std::ptr::copy_nonoverlapping(mesh.tris.as_ptr(), ix, nt);
            rtcSetGeometryIntersectFilterFunction(g, Some(filter));
            rtcCommitGeometry(g);
            rtcAttachGeometry(scene, g);
            rtcReleaseGeometry(g);
            rtcCommitScene(scene);
            let err = rtcGetDeviceError(device);
            if err != 0 {
                return Err(format!("embree: error {err} building the scene"));
            }
            Ok(Embree { device, scene })
        }
    }

    /// Trace `rays` with `call` and the filter of `method` at `n_query`;
    /// `slots` place rays in the lanes of `rtcIntersect8` (u32::MAX: empty).
    pub(crate) fn trace(
        &self,
        rays: &RayStream,
        (method, n_query): (Method, u32),
        call: Call,
        slots: &[u32],
    ) -> Vec<Vec<Hit>> {
        let n = rays.len();
        let cap = match method {
            Method::Naive => multihit_kernels::NAIVE_CAPACITY.max(n_query) as usize,
            Method::NodeCulling => n_query as usize + 1,
        };
        let mut st = State {
            method,
            n_query,
            cap,
            entries: vec![(f32::INFINITY, INVALID_ID); n * cap],
            counts: vec![0; n],
        };
        let mut ctx = Context {
            base: RTCIntersectContext {
                flags: 0,
                filter: None,
                inst_id: [INVALID_ID],
            },
            state: &raw mut st,
        };
        match call {
            Call::One => (0..n).for_each(|i| self.one(&mut ctx, rays, i)),
            Call::Eight => slots.chunks(8).for_each(|c| self.eight(&mut ctx, rays, c)),
        }
        st.lists(n)
    }

    fn one(&self, ctx: &mut Context, rays: &RayStream, i: usize) {
        let mut rh = RayHit1 {
            org: rays.org[i],
            tnear: 0.0,
            dir: rays.dir[i],
            time: 0.0,
            tfar: rays.tmax[i],
            mask: u32::MAX,
            id: i as u32,
            flags: 0,
            ng: [0.0; 3],
            u: 0.0,
            v: 0.0,
            prim_id: INVALID_ID,
            geom_id: INVALID_ID,
            inst_id: INVALID_ID,
        };
        // SAFETY: a committed scene, our context and a valid RTCRayHit.
        unsafe { rtcIntersect1(self.scene, &raw mut ctx.base, &raw mut rh) };
    }

    fn eight(&self, ctx: &mut Context, rays: &RayStream, lanes: &[u32]) {
        let mut rh = RayHit8 { f: [[0.0; 8]; 20] };
        let mut valid = [0i32; 8];
        for (l, &r) in lanes.iter().enumerate() {
            let Some(i) = (r != u32::MAX).then_some(r as usize) else {
                continue;
            };
            valid[l] = -1;
            let f = &mut rh.f;
            (f[0][l], f[1][l], f[2][l]) = (rays.org[i][0], rays.org[i][1], rays.org[i][2]);
            (f[4][l], f[5][l], f[6][l]) = (rays.dir[i][0], rays.dir[i][1], rays.dir[i][2]);
            f[8][l] = rays.tmax[i];
            f[9][l] = f32::from_bits(u32::MAX);
            f[10][l] = f32::from_bits(i as u32);
            f[17][l] = f32::from_bits(INVALID_ID);
        }
        // SAFETY: as `one`, with an RTCRayHit8 and its valid mask.
        unsafe { rtcIntersect8(valid.as_ptr(), self.scene, &raw mut ctx.base, &raw mut rh) };
    }
}

impl Drop for Embree {
    fn drop(&mut self) {
        // SAFETY: released once, after every trace.
        unsafe {
            rtcReleaseScene(self.scene);
            rtcReleaseDevice(self.device);
        }
    }
}
