//! A ray stream through one of Embree's calls: closest hits, or for a shadow
//! stream whether each ray is occluded.

use crate::ffi::{IntersectContext, RayHit1, RayHit8, INVALID_ID};
use crate::Embree;
use scene::workload::{RayStream, StreamKind};
use scene::Hit;

/// Which Embree call traces the rays.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Call {
    /// `rtcIntersect1` / `rtcOccluded1`, ray by ray.
    One,
    /// `rtcIntersect8` / `rtcOccluded8` over packet slots.
    Eight,
    /// `rtcIntersect1M` / `rtcOccluded1M`: the whole stream in one call.
    Stream,
}

impl Call {
    /// Every call.
    pub const ALL: [Call; 3] = [Call::One, Call::Eight, Call::Stream];

    /// Stable name (`embree-1`, `embree-8`, `embree-1m`).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Call::One => "embree-1",
            Call::Eight => "embree-8",
            Call::Stream => "embree-1m",
        }
    }
}

/// The hit a shadow ray reports when Embree found it occluded (which
/// triangle blocks it is not returned: [`Embree::witnesses`] finds one).
pub const OCCLUDED: Hit = Hit {
    t: 0.0,
    prim: Some(INVALID_ID),
};

impl Embree {
    /// Trace `rays` with `call`: closest hits (a miss keeps the ray's t_far),
    /// or for a shadow stream [`OCCLUDED`] or a miss per ray. `slots` place
    /// rays in the lanes of `rtcIntersect8` (`u32::MAX`: an empty lane; as
    /// [`scene::workload::packet_slots`] forms a packet renderer's packets).
    /// Primary rays are traced with the coherent hint, others incoherent.
    #[must_use]
    pub fn trace(&self, rays: &RayStream, call: Call, slots: &[u32]) -> Vec<Hit> {
        let mut ctx = IntersectContext::new(rays.kind == StreamKind::Primary);
        let shadow = rays.is_shadow();
        match call {
            Call::One => (0..rays.len())
                .map(|i| {
                    let mut rh = ray1(rays, i);
                    if shadow {
                        self.occluded1(&mut ctx, &mut rh);
                    } else {
                        self.intersect1(&mut ctx, &mut rh);
                    }
                    answer1(&rh, shadow)
                })
                .collect(),
            Call::Stream => {
                let mut rhs: Vec<RayHit1> = (0..rays.len()).map(|i| ray1(rays, i)).collect();
                if shadow {
                    self.occluded1m(&mut ctx, &mut rhs);
                } else {
                    self.intersect1m(&mut ctx, &mut rhs);
                }
                rhs.iter().map(|rh| answer1(rh, shadow)).collect()
            }
            Call::Eight => {
                let mut out = vec![Hit::miss(0.0); rays.len()];
                for lanes in slots.chunks(8) {
                    self.packet(&mut ctx, rays, lanes, shadow, &mut out);
                }
                out
            }
        }
    }

    /// One `rtcIntersect8` / `rtcOccluded8` call over the rays in `lanes`.
    fn packet(
        &self,
        ctx: &mut IntersectContext,
        rays: &RayStream,
        lanes: &[u32],
        shadow: bool,
        out: &mut [Hit],
    ) {
        let mut rh = RayHit8::new();
        let mut valid = [0i32; 8];
        for (l, &r) in lanes.iter().enumerate().filter(|(_, &r)| r != u32::MAX) {
            let i = r as usize;
            valid[l] = -1;
            rh.set(l, rays.org[i], rays.dir[i], rays.tmax[i], r);
        }
        if shadow {
            self.occluded8(&valid, ctx, &mut rh);
        } else {
            self.intersect8(&valid, ctx, &mut rh);
        }
        for (l, &r) in lanes.iter().enumerate().filter(|(_, &r)| r != u32::MAX) {
            let tfar = rh.f[RayHit8::TFAR][l];
            let geom = rh.f[RayHit8::GEOM][l].to_bits();
            let prim = rh.f[RayHit8::PRIM][l].to_bits();
            out[r as usize] = answer(tfar, geom, prim, shadow);
        }
    }

    /// For the check only (untimed): the shadow rays `trace` found occluded
    /// get the closest triangle on [0, t_far] as their witness (`None` if
    /// Embree's closest-hit call finds none there).
    pub fn witnesses(&self, rays: &RayStream, hits: &mut [Hit]) {
        let mut ctx = IntersectContext::new(false);
        for (i, h) in hits.iter_mut().enumerate().filter(|(_, h)| **h == OCCLUDED) {
            let mut rh = ray1(rays, i);
            self.intersect1(&mut ctx, &mut rh);
            *h = Hit {
                t: rh.tfar,
                prim: (rh.geom_id != INVALID_ID).then_some(rh.prim_id),
            };
        }
    }
}

/// Ray `i` of the stream as an `RTCRayHit`.
fn ray1(rays: &RayStream, i: usize) -> RayHit1 {
    RayHit1::new(rays.org[i], rays.dir[i], rays.tmax[i], i as u32)
}

/// The answer of one traced `RTCRayHit`.
fn answer1(rh: &RayHit1, shadow: bool) -> Hit {
    answer(rh.tfar, rh.geom_id, rh.prim_id, shadow)
}

/// A hit from Embree's t_far and ids: closest hit or miss, or (shadow)
/// occluded when t_far became -inf.
fn answer(tfar: f32, geom: u32, prim: u32, shadow: bool) -> Hit {
    if shadow {
        return if tfar == f32::NEG_INFINITY {
            OCCLUDED
        } else {
            Hit::miss(tfar)
        };
    }
    Hit {
        t: tfar,
        prim: (geom != INVALID_ID).then_some(prim),
    }
}
