//! The peer, for real (cargo feature `embree`): Embree 3 (Debian's
//! `libembree-dev`) traces the same rays with its own BVH and traversal, and
//! the same two filters written against its API: `rtcIntersect1` and
//! `rtcIntersect8` with an intersection filter that rejects, or accepts with
//! a changed t_far (Listing 1 as the paper wrote it for Embree 2.10).
//!
//! The scene is built with `RTC_SCENE_FLAG_ROBUST` (watertight triangle
//! tests: a ray down a shared edge hits both neighbours, as the f64
//! reference does; the agreement rule lets an f32 kernel drop a grazing hit
//! either way). The bindings and the scene are `embree-peer`'s; the filter
//! and its per-ray state are here.

#![allow(unsafe_code)]

use embree_peer::{FilterArgs, IntersectContext, RayHit1, RayHit8, INVALID_ID};
use multihit_kernels::Method;
use scene::mesh::Mesh;
use scene::workload::RayStream;
use scene::Hit;

/// The filter's state, reached through the context (Embree's tutorials'
/// way of passing per-call data): the method, N_query and every ray's
/// entries, found by the ray's id.
#[repr(C)]
struct Context {
    base: IntersectContext,
    state: *mut State,
}

// SAFETY: `#[repr(C)]`, the IntersectContext first.
unsafe impl embree_peer::Context for Context {}

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

/// An Embree scene of one mesh with the filter set on its geometry.
pub(crate) struct Embree(embree_peer::Embree);

impl Embree {
    /// Embree's BVH over `mesh` (robust mode), the filter set on its geometry.
    pub(crate) fn new(mesh: &Mesh) -> Result<Embree, String> {
        embree_peer::Embree::new(mesh, Some(filter)).map(Embree)
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
            base: IntersectContext::new(false),
            state: &raw mut st,
        };
        match call {
            Call::One => (0..n).for_each(|i| self.one(&mut ctx, rays, i)),
            Call::Eight => slots.chunks(8).for_each(|c| self.eight(&mut ctx, rays, c)),
        }
        st.lists(n)
    }

    fn one(&self, ctx: &mut Context, rays: &RayStream, i: usize) {
        let mut rh = RayHit1::new(rays.org[i], rays.dir[i], rays.tmax[i], i as u32);
        self.0.intersect1(ctx, &mut rh);
    }

    fn eight(&self, ctx: &mut Context, rays: &RayStream, lanes: &[u32]) {
        let mut rh = RayHit8::new();
        let mut valid = [0i32; 8];
        for (l, &r) in lanes.iter().enumerate().filter(|(_, &r)| r != u32::MAX) {
            valid[l] = -1;
            let i = r as usize;
            rh.set(l, rays.org[i], rays.dir[i], rays.tmax[i], r);
        }
        self.0.intersect8(&valid, ctx, &mut rh);
    }
}
