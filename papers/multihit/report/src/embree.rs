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

/// A method's per-ray buffers for one run of `n` rays: allocated once,
/// reset before each timed pass (outside it), read after it.
pub(crate) struct State {
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

    /// Buffers for `n` rays of `method` at `n_query` (naive: the capacity
    /// its kernels have; node culling: N_query + 1 entries).
    pub(crate) fn new((method, n_query): (Method, u32), n: usize) -> State {
        let cap = match method {
            Method::Naive => multihit_kernels::NAIVE_CAPACITY.max(n_query) as usize,
            Method::NodeCulling => n_query as usize + 1,
        };
        State {
            method,
            n_query,
            cap,
            entries: vec![(f32::INFINITY, INVALID_ID); n * cap],
            counts: vec![0; n],
        }
    }

    /// Before a pass: no hits held, every entry's t +inf (as the kernels'
    /// set-up; untimed here, in place).
    pub(crate) fn reset(&mut self) {
        self.entries.fill((f32::INFINITY, INVALID_ID));
        self.counts.fill(0);
    }

    /// After traversal, naive's selection of each ray's N_query nearest into
    /// its first places (the paper's post-traversal sort, part of the
    /// method's time); node culling's lists are in order already.
    pub(crate) fn finish(&mut self) {
        if self.method != Method::Naive {
            return;
        }
        for r in 0..self.counts.len() {
            let e = &mut self.entries[r * self.cap..(r + 1) * self.cap];
            let count = (self.counts[r] as usize).min(self.cap);
            for i in 0..count.min(self.n_query as usize) {
                let best = (i..count)
                    .min_by(|&x, &y| e[x].0.total_cmp(&e[y].0))
                    .expect("a place");
                e.swap(i, best);
            }
        }
    }

    /// Each ray's N_query nearest, nearest first (after [`State::finish`]).
    pub(crate) fn lists(&self) -> Vec<Vec<Hit>> {
        (0..self.counts.len())
            .map(|r| {
                let e = &self.entries[r * self.cap..(r + 1) * self.cap];
                let count = (self.counts[r] as usize).min(self.cap);
                let k = count.min(self.n_query as usize);
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
    /// Each ray's list, nearest first.
    pub(crate) fn trace(
        &self,
        rays: &RayStream,
        (method, n_query): (Method, u32),
        call: Call,
        slots: &[u32],
    ) -> Vec<Vec<Hit>> {
        let mut st = State::new((method, n_query), rays.len());
        self.pass(&mut st, rays, call, slots);
        st.lists()
    }

    /// The timed part of a native run: the Embree calls over `rays` with the
    /// filter on `st` (reset by the caller), then naive's sort in place. It
    /// allocates nothing (a test holds it to that).
    pub(crate) fn pass(&self, st: &mut State, rays: &RayStream, call: Call, slots: &[u32]) {
        let mut ctx = Context {
            base: IntersectContext::new(false),
            state: st,
        };
        match call {
            Call::One => (0..rays.len()).for_each(|i| self.one(&mut ctx, rays, i)),
            Call::Eight => slots.chunks(8).for_each(|c| self.eight(&mut ctx, rays, c)),
        }
        st.finish();
    }

    /// Each tile's time (the best of `repeats` passes of it, buffers
    /// allocated once and reset before each pass outside the timer, the
    /// same way for both methods; `rtcIntersect8` over its packets) and
    /// the hits it returned: `(seconds, hits)` per tile.
    pub(crate) fn time_tiles(
        &self,
        tiles: &[(&RayStream, &[u32])],
        q: (Method, u32),
        repeats: usize,
    ) -> Vec<(f64, f64)> {
        let mut bufs: Vec<State> = tiles.iter().map(|(r, _)| State::new(q, r.len())).collect();
        let mut best = vec![f64::INFINITY; tiles.len()];
        for _ in 0..repeats {
            for ((&(rays, slots), st), b) in tiles.iter().zip(&mut bufs).zip(&mut best) {
                st.reset();
                let t0 = std::time::Instant::now();
                self.pass(st, rays, Call::Eight, slots);
                *b = b.min(t0.elapsed().as_secs_f64());
            }
        }
        let hits = bufs
            .iter()
            .map(|st| st.lists().iter().map(Vec::len).sum::<usize>() as f64);
        best.into_iter().zip(hits).collect()
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

#[cfg(test)]
mod tests {
    use super::*;
    use std::alloc::{GlobalAlloc, Layout, System};
    use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

    /// Counts allocations while `ON` is set (this test binary's allocator).
    struct Counting;
    static ON: AtomicBool = AtomicBool::new(false);
    static ALLOCS: AtomicUsize = AtomicUsize::new(0);

    // SAFETY: forwards to the system allocator.
    unsafe impl GlobalAlloc for Counting {
        unsafe fn alloc(&self, l: Layout) -> *mut u8 {
            if ON.load(Ordering::Relaxed) {
                ALLOCS.fetch_add(1, Ordering::Relaxed);
            }
            // SAFETY: the caller's layout, passed on.
            unsafe { System.alloc(l) }
        }
        unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
            // SAFETY: a pointer this allocator (the system's) returned.
            unsafe { System.dealloc(p, l) }
        }
    }

    #[global_allocator]
    static A: Counting = Counting;

    #[test]
    fn the_timed_pass_allocates_nothing() {
        if let Err(why) = embree_peer::available() {
            eprintln!("skipped: {why}");
            return;
        }
        let scene = scene::scene::Scene::load("sphere").unwrap();
        let e = Embree::new(&scene.mesh).unwrap();
        let cam = &scene.config.camera;
        let rays = scene::workload::primary_tile(cam, cam.width / 32, cam.height / 32, 16, 1, 7);
        let slots: Vec<u32> = (0..rays.len() as u32).collect();
        for method in [Method::Naive, Method::NodeCulling] {
            for call in [Call::One, Call::Eight] {
                let mut st = State::new((method, 4), rays.len());
                st.reset();
                ALLOCS.store(0, Ordering::Relaxed);
                ON.store(true, Ordering::Relaxed);
                e.pass(&mut st, &rays, call, &slots);
                ON.store(false, Ordering::Relaxed);
                assert_eq!(ALLOCS.load(Ordering::Relaxed), 0, "{method:?} {call:?}");
                assert!(
                    st.lists().iter().any(|l| !l.is_empty()),
                    "the sphere is hit"
                );
            }
        }
    }
}
