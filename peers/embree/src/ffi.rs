//! The part of Embree 3's C API (`rtcore.h` 3.13) the peer calls.

use std::ffi::c_void;

/// `RTCIntersectContext`: flags, the context filter (unused: filters are
/// set on the geometry) and the instance id stack.
#[repr(C)]
pub struct IntersectContext {
    /// `RTC_INTERSECT_CONTEXT_FLAG_*` (0: incoherent, 1: coherent).
    pub flags: u32,
    /// Per-call filter; `None`.
    pub filter: Option<unsafe extern "C" fn(*const FilterArgs)>,
    /// Instance ids; [`INVALID_ID`].
    pub inst_id: [u32; 1],
}

impl IntersectContext {
    /// `rtcInitIntersectContext` with the coherence hint.
    #[must_use]
    pub fn new(coherent: bool) -> IntersectContext {
        IntersectContext {
            flags: u32::from(coherent),
            filter: None,
            inst_id: [INVALID_ID],
        }
    }
}

/// `RTCFilterFunctionNArguments`.
#[repr(C)]
pub struct FilterArgs {
    /// Per lane: -1 valid, 0 not; a filter writes 0 to reject.
    pub valid: *mut i32,
    /// The geometry's user pointer.
    pub geometry_user_ptr: *mut c_void,
    /// The context the call was given.
    pub context: *mut IntersectContext,
    /// `RTCRayN` rows.
    pub ray: *mut c_void,
    /// `RTCHitN` rows.
    pub hit: *mut c_void,
    /// Lanes.
    pub n: u32,
}

/// `RTCRayHit`: the ray, then the hit.
#[repr(C, align(16))]
#[derive(Clone, Copy, Debug)]
pub struct RayHit1 {
    /// Origin.
    pub org: [f32; 3],
    /// Near limit.
    pub tnear: f32,
    /// Direction.
    pub dir: [f32; 3],
    /// Motion-blur time.
    pub time: f32,
    /// Far limit; the hit's distance after an intersect, -inf after an
    /// occluded call that found a blocker.
    pub tfar: f32,
    /// Ray mask.
    pub mask: u32,
    /// Ray id (filters find their per-ray state by it).
    pub id: u32,
    /// Ray flags.
    pub flags: u32,
    /// Geometric normal.
    pub ng: [f32; 3],
    /// Barycentric u.
    pub u: f32,
    /// Barycentric v.
    pub v: f32,
    /// Triangle hit.
    pub prim_id: u32,
    /// Geometry hit; [`INVALID_ID`] for a miss.
    pub geom_id: u32,
    /// Instance hit.
    pub inst_id: u32,
}

impl RayHit1 {
    /// A ray over [0, tfar] with no hit.
    #[must_use]
    pub fn new(org: [f32; 3], dir: [f32; 3], tfar: f32, id: u32) -> RayHit1 {
        RayHit1 {
            org,
            tnear: 0.0,
            dir,
            time: 0.0,
            tfar,
            mask: u32::MAX,
            id,
            flags: 0,
            ng: [0.0; 3],
            u: 0.0,
            v: 0.0,
            prim_id: INVALID_ID,
            geom_id: INVALID_ID,
            inst_id: INVALID_ID,
        }
    }
}

/// `RTCRayHit8`: the ray rows (org x/y/z, tnear, dir x/y/z, time, tfar,
/// mask, id, flags), then the hit rows (Ng x/y/z, u, v, primID, geomID,
/// instID), 8 lanes each, as `f32` bit patterns.
#[repr(C, align(32))]
pub struct RayHit8 {
    /// The rows.
    pub f: [[f32; 8]; 20],
}

impl RayHit8 {
    /// Row of t_far.
    pub const TFAR: usize = 8;
    /// Row of the ray ids.
    pub const ID: usize = 10;
    /// Row of the triangle ids.
    pub const PRIM: usize = 17;
    /// Row of the geometry ids.
    pub const GEOM: usize = 18;

    /// Empty lanes (no ray).
    #[must_use]
    pub fn new() -> RayHit8 {
        RayHit8 { f: [[0.0; 8]; 20] }
    }

    /// Put a ray over [0, tfar] in lane `l`, no hit.
    pub fn set(&mut self, l: usize, org: [f32; 3], dir: [f32; 3], tfar: f32, id: u32) {
        let f = &mut self.f;
        (f[0][l], f[1][l], f[2][l], f[3][l]) = (org[0], org[1], org[2], 0.0);
        (f[4][l], f[5][l], f[6][l], f[7][l]) = (dir[0], dir[1], dir[2], 0.0);
        f[Self::TFAR][l] = tfar;
        f[9][l] = f32::from_bits(u32::MAX);
        f[Self::ID][l] = f32::from_bits(id);
        f[Self::GEOM][l] = f32::from_bits(INVALID_ID);
        f[Self::PRIM][l] = f32::from_bits(INVALID_ID);
    }
}

impl Default for RayHit8 {
    fn default() -> Self {
        Self::new()
    }
}

pub(crate) type Device = *mut c_void;
pub(crate) type Scene = *mut c_void;
pub(crate) type Geometry = *mut c_void;

#[link(name = "embree3")]
extern "C" {
    pub(crate) fn rtcNewDevice(config: *const std::ffi::c_char) -> Device;
    pub(crate) fn rtcReleaseDevice(d: Device);
    pub(crate) fn rtcGetDeviceError(d: Device) -> i32;
    pub(crate) fn rtcNewScene(d: Device) -> Scene;
    pub(crate) fn rtcSetSceneFlags(s: Scene, flags: u32);
    pub(crate) fn rtcReleaseScene(s: Scene);
    pub(crate) fn rtcNewGeometry(d: Device, kind: u32) -> Geometry;
    pub(crate) fn rtcSetNewGeometryBuffer(
        g: Geometry,
        kind: u32,
        slot: u32,
        format: u32,
        stride: usize,
        count: usize,
    ) -> *mut c_void;
    pub(crate) fn rtcSetGeometryIntersectFilterFunction(
        g: Geometry,
        f: Option<unsafe extern "C" fn(*const FilterArgs)>,
    );
    pub(crate) fn rtcCommitGeometry(g: Geometry);
    pub(crate) fn rtcAttachGeometry(s: Scene, g: Geometry) -> u32;
    pub(crate) fn rtcReleaseGeometry(g: Geometry);
    pub(crate) fn rtcCommitScene(s: Scene);
    pub(crate) fn rtcIntersect1(s: Scene, ctx: *mut IntersectContext, rh: *mut RayHit1);
    pub(crate) fn rtcIntersect8(
        valid: *const i32,
        s: Scene,
        ctx: *mut IntersectContext,
        rh: *mut RayHit8,
    );
    pub(crate) fn rtcIntersect1M(
        s: Scene,
        ctx: *mut IntersectContext,
        rh: *mut RayHit1,
        m: u32,
        stride: usize,
    );
    pub(crate) fn rtcOccluded1(s: Scene, ctx: *mut IntersectContext, r: *mut RayHit1);
    pub(crate) fn rtcOccluded8(
        valid: *const i32,
        s: Scene,
        ctx: *mut IntersectContext,
        r: *mut RayHit8,
    );
    pub(crate) fn rtcOccluded1M(
        s: Scene,
        ctx: *mut IntersectContext,
        r: *mut RayHit1,
        m: u32,
        stride: usize,
    );
}

pub(crate) const GEOMETRY_TYPE_TRIANGLE: u32 = 0;
pub(crate) const BUFFER_TYPE_INDEX: u32 = 0;
pub(crate) const BUFFER_TYPE_VERTEX: u32 = 1;
pub(crate) const FORMAT_UINT3: u32 = 0x5003;
pub(crate) const FORMAT_FLOAT3: u32 = 0x9003;
pub(crate) const SCENE_FLAG_ROBUST: u32 = 1 << 2;
/// Embree's "no id" (`RTC_INVALID_GEOMETRY_ID`).
pub const INVALID_ID: u32 = u32::MAX;
