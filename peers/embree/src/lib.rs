//! Embree 3, the peer: its own BVH and traversal over the same meshes and
//! the same rays the kernels trace, through three of its calls —
//! `rtcIntersect1` (one ray), `rtcIntersect8` (8-ray packets) and
//! `rtcIntersect1M` (its ray-stream API, removed in Embree 4) and their
//! `rtcOccluded*` forms for shadow rays — plus the intersection-filter hook
//! the multi-hit reports use.
//!
//! The bindings are written here (a few calls of `rtcore.h` 3.13): the
//! `embree` crate on crates.io binds 8-wide packets only in its sys module,
//! and its safe API cannot pass an extended intersect context to a filter.
//! The library is opened at run time (Debian's `libembree3-3`, which
//! `libembree-dev` pulls in): the workspace builds and runs without it, and
//! [`available`] says whether this host has it.

#![warn(missing_docs)]
#![allow(unsafe_code)]

mod ffi;
mod trace;

pub use ffi::{FilterArgs, IntersectContext, RayHit1, RayHit8, INVALID_ID};
pub use trace::{Call, OCCLUDED};

/// What a trace call may be given as its context: an [`IntersectContext`],
/// or a larger struct that starts with one and carries a filter's per-call
/// state (Embree's tutorials' way), which the filter reaches through
/// [`FilterArgs::context`].
///
/// # Safety
/// Implementors are `#[repr(C)]` with an [`IntersectContext`] as their
/// first field.
pub unsafe trait Context {}

// SAFETY: it is one.
unsafe impl Context for IntersectContext {}

use scene::mesh::Mesh;

/// Whether Embree 3 can be used on this host; why not, naming the library
/// looked for.
///
/// # Errors
/// When the library is missing or lacks an entry point the peer calls.
pub fn available() -> Result<(), String> {
    ffi::api().map(|_| ())
}

/// An Embree device (one build thread) and the scene of one mesh.
pub struct Embree {
    api: &'static ffi::Api,
    device: ffi::Device,
    scene: ffi::Scene,
}

// SAFETY: Embree scenes may be traced from several threads once committed;
// the device and scene are released once, on drop.
unsafe impl Send for Embree {}
unsafe impl Sync for Embree {}

/// An intersection filter (`RTCFilterFunctionN`).
pub type FilterFn = unsafe extern "C" fn(*const FilterArgs);

impl Embree {
    /// Embree's BVH over `mesh`, built robust (watertight triangle tests: a
    /// ray down a shared edge hits a neighbour, as the f64 reference says)
    /// at the default build quality; `filter` set on its geometry.
    ///
    /// # Errors
    /// When Embree is not installed ([`available`]), cannot make the device
    /// or reports an error building.
    pub fn new(mesh: &Mesh, filter: Option<FilterFn>) -> Result<Embree, String> {
        Self::with_config(mesh, filter, "")
    }

    /// [`Embree::new`] on a device configured by `config` too (Embree's
    /// `key=value,...` device string after `threads=1`: e.g.
    /// `tri_accel=bvh4.triangle4` for its BVH4 with the Moller test).
    ///
    /// # Errors
    /// As [`Embree::new`], and when Embree refuses the configuration.
    pub fn with_config(
        mesh: &Mesh,
        filter: Option<FilterFn>,
        config: &str,
    ) -> Result<Embree, String> {
        let full = if config.is_empty() {
            "threads=1".to_string()
        } else {
            format!("threads=1,{config}")
        };
        let cfg = std::ffi::CString::new(full)
            .map_err(|_| format!("embree config {config:?}: contains a NUL byte"))?;
        let api = ffi::api()?;
        // SAFETY: plain Embree API calls with buffers Embree allocates and
        // we fill within their sizes.
        unsafe {
            let device = (api.new_device)(cfg.as_ptr());
            if device.is_null() {
                return Err(format!("embree: rtcNewDevice refused config {config:?}"));
            }
            let scene = (api.new_scene)(device);
            (api.set_scene_flags)(scene, ffi::SCENE_FLAG_ROBUST);
            let g = (api.new_geometry)(device, ffi::GEOMETRY_TYPE_TRIANGLE);
            let nv = mesh.positions.len();
            let v = (api.set_new_geometry_buffer)(
                g,
                ffi::BUFFER_TYPE_VERTEX,
                0,
                ffi::FORMAT_FLOAT3,
                12,
                nv,
            ) as *mut [f32; 3];
            std::ptr::copy_nonoverlapping(mesh.positions.as_ptr(), v, nv);
            let nt = mesh.tris.len();
            let ix = (api.set_new_geometry_buffer)(
                g,
                ffi::BUFFER_TYPE_INDEX,
                0,
                ffi::FORMAT_UINT3,
                12,
                nt,
            ) as *mut [u32; 3];
            std::ptr::copy_nonoverlapping(mesh.tris.as_ptr(), ix, nt);
            if filter.is_some() {
                (api.set_geometry_intersect_filter_function)(g, filter);
            }
            (api.commit_geometry)(g);
            (api.attach_geometry)(scene, g);
            (api.release_geometry)(g);
            (api.commit_scene)(scene);
            let err = (api.get_device_error)(device);
            if err != 0 {
                (api.release_scene)(scene);
                (api.release_device)(device);
                return Err(format!(
                    "embree: error {err} building the scene (device config {config:?})"
                ));
            }
            Ok(Embree { api, device, scene })
        }
    }

    /// `rtcIntersect1` of one ray under `ctx` (which may be the first field
    /// of a larger `#[repr(C)]` struct a filter reads).
    pub fn intersect1<C: Context>(&self, ctx: &mut C, rh: &mut RayHit1) {
        // SAFETY: a committed scene, a live context and a valid RTCRayHit.
        unsafe { (self.api.intersect1)(self.scene, (ctx as *mut C).cast(), rh) };
    }

    /// `rtcIntersect8` of the lanes `valid` marks (-1 valid, 0 not).
    pub fn intersect8<C: Context>(&self, valid: &[i32; 8], ctx: &mut C, rh: &mut RayHit8) {
        // SAFETY: as `intersect1`, with an RTCRayHit8 and its valid mask.
        unsafe { (self.api.intersect8)(valid.as_ptr(), self.scene, (ctx as *mut C).cast(), rh) };
    }

    /// `rtcIntersect1M` over `rhs` (one ray stream).
    pub fn intersect1m<C: Context>(&self, ctx: &mut C, rhs: &mut [RayHit1]) {
        let m = u32::try_from(rhs.len()).expect("at most 2^32 rays in a stream");
        let stride = std::mem::size_of::<RayHit1>();
        // SAFETY: `rhs` holds `m` RTCRayHits `stride` bytes apart.
        unsafe {
            (self.api.intersect1m)(
                self.scene,
                (ctx as *mut C).cast(),
                rhs.as_mut_ptr(),
                m,
                stride,
            )
        };
    }

    /// `rtcOccluded1`: the ray part of `rh` (its t_far becomes -inf when occluded).
    pub fn occluded1<C: Context>(&self, ctx: &mut C, rh: &mut RayHit1) {
        // SAFETY: an RTCRayHit starts with its RTCRay.
        unsafe { (self.api.occluded1)(self.scene, (ctx as *mut C).cast(), rh) };
    }

    /// `rtcOccluded8` over the ray rows of `rh`.
    pub fn occluded8<C: Context>(&self, valid: &[i32; 8], ctx: &mut C, rh: &mut RayHit8) {
        // SAFETY: an RTCRayHit8 starts with its RTCRay8 rows.
        unsafe { (self.api.occluded8)(valid.as_ptr(), self.scene, (ctx as *mut C).cast(), rh) };
    }

    /// `rtcOccluded1M` over the rays of `rhs` (stride: a whole RTCRayHit).
    pub fn occluded1m<C: Context>(&self, ctx: &mut C, rhs: &mut [RayHit1]) {
        let m = u32::try_from(rhs.len()).expect("at most 2^32 rays in a stream");
        let stride = std::mem::size_of::<RayHit1>();
        // SAFETY: `rhs` holds `m` rays `stride` bytes apart.
        unsafe {
            (self.api.occluded1m)(
                self.scene,
                (ctx as *mut C).cast(),
                rhs.as_mut_ptr(),
                m,
                stride,
            )
        };
    }
}

impl Drop for Embree {
    fn drop(&mut self) {
        // SAFETY: released once, after every trace.
        unsafe {
            (self.api.release_scene)(self.scene);
            (self.api.release_device)(self.device);
        }
    }
}
