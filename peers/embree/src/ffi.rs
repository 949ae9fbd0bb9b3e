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

/// The library's names, tried in order: Debian's runtime package
/// (`libembree3-3`) installs the first, `libembree-dev` adds the second.
const LIBRARY: [&str; 2] = ["libembree3.so.3", "libembree3.so"];

/// The entry points, each declared once: the [`Api`] struct's fields and
/// the symbols they are loaded from.
macro_rules! api {
    ($($field:ident = $sym:literal: fn($($arg:ty),*) $(-> $ret:ty)?;)*) => {
        /// Embree's entry points, resolved from the library at run time.
        pub(crate) struct Api {
            $(pub(crate) $field: unsafe extern "C" fn($($arg),*) $(-> $ret)?,)*
            /// Kept open while the entry points are in use (for the process).
            _lib: libloading::Library,
        }

        impl Api {
            /// Open the library and resolve every entry point.
            fn load() -> Result<Api, String> {
                let lib = LIBRARY
                    .iter()
                    // SAFETY: loading Embree runs its initialisers only.
                    .find_map(|name| unsafe { libloading::Library::new(name) }.ok())
                    .ok_or_else(|| {
                        format!(
                            "Embree 3 not found ({}; on Debian: apt install libembree3-3)",
                            LIBRARY.join(", ")
                        )
                    })?;
                // SAFETY: each symbol has the signature rtcore.h 3.13 gives it.
                unsafe {
                    Ok(Api {
                        $($field: *lib
                            .get::<unsafe extern "C" fn($($arg),*) $(-> $ret)?>($sym)
                            .map_err(|e| format!("Embree 3: {e}"))?,)*
                        _lib: lib,
                    })
                }
            }
        }
    };
}

api! {
    new_device = b"rtcNewDevice": fn(*const std::ffi::c_char) -> Device;
    release_device = b"rtcReleaseDevice": fn(Device);
    get_device_error = b"rtcGetDeviceError": fn(Device) -> i32;
    new_scene = b"rtcNewScene": fn(Device) -> Scene;
    set_scene_flags = b"rtcSetSceneFlags": fn(Scene, u32);
    release_scene = b"rtcReleaseScene": fn(Scene);
    new_geometry = b"rtcNewGeometry": fn(Device, u32) -> Geometry;
    set_new_geometry_buffer = b"rtcSetNewGeometryBuffer":
        fn(Geometry, u32, u32, u32, usize, usize) -> *mut c_void;
    set_geometry_intersect_filter_function = b"rtcSetGeometryIntersectFilterFunction":
        fn(Geometry, Option<unsafe extern "C" fn(*const FilterArgs)>);
    commit_geometry = b"rtcCommitGeometry": fn(Geometry);
    attach_geometry = b"rtcAttachGeometry": fn(Scene, Geometry) -> u32;
    release_geometry = b"rtcReleaseGeometry": fn(Geometry);
    commit_scene = b"rtcCommitScene": fn(Scene);
    intersect1 = b"rtcIntersect1": fn(Scene, *mut IntersectContext, *mut RayHit1);
    intersect8 = b"rtcIntersect8":
        fn(*const i32, Scene, *mut IntersectContext, *mut RayHit8);
    intersect1m = b"rtcIntersect1M":
        fn(Scene, *mut IntersectContext, *mut RayHit1, u32, usize);
    occluded1 = b"rtcOccluded1": fn(Scene, *mut IntersectContext, *mut RayHit1);
    occluded8 = b"rtcOccluded8":
        fn(*const i32, Scene, *mut IntersectContext, *mut RayHit8);
    occluded1m = b"rtcOccluded1M":
        fn(Scene, *mut IntersectContext, *mut RayHit1, u32, usize);
}

/// Embree's entry points, loaded on first use; why not, when the library
/// is missing or lacks one.
pub(crate) fn api() -> Result<&'static Api, String> {
    static API: std::sync::OnceLock<Result<Api, String>> = std::sync::OnceLock::new();
    API.get_or_init(Api::load).as_ref().map_err(Clone::clone)
}

pub(crate) const GEOMETRY_TYPE_TRIANGLE: u32 = 0;
pub(crate) const BUFFER_TYPE_INDEX: u32 = 0;
pub(crate) const BUFFER_TYPE_VERTEX: u32 = 1;
pub(crate) const FORMAT_UINT3: u32 = 0x5003;
pub(crate) const FORMAT_FLOAT3: u32 = 0x9003;
pub(crate) const SCENE_FLAG_ROBUST: u32 = 1 << 2;
/// Embree's "no id" (`RTC_INVALID_GEOMETRY_ID`).
pub const INVALID_ID: u32 = u32::MAX;
