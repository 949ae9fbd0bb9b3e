//! The intersection-filter hook of the Embree-style kernels (single-ray
//! BVH4, `single::trace_bvh4_filtered`, and the packet kernel,
//! `packet::trace_bvh4_filtered`), with the semantics Embree has
//! from 2.10 on (Embree 3's `Intersect1EpilogM` / `IntersectKEpilogM`):
//!
//! - the filter sees every candidate hit that passes the ray's current
//!   interval, nearest first within a leaf's block pass (single ray) or one
//!   triangle at a time for the lanes that hit it (packet);
//! - it rejects a candidate (traversal continues with the incoming t_far)
//!   or accepts it with a t_far that may be smaller than the candidate's
//!   (traversal continues with that interval, so farther nodes and
//!   triangles are culled); the accepted candidate becomes the ray's hit
//!   record;
//! - after a verdict, the pass's remaining candidates farther than the
//!   ray's t_far are dropped (Embree: `valid &= hit.vt <= ray.tfar`).
//!
//! A filter is ordinary kernel code over the same [`Machine`], so its ops
//! are recorded and timed with the traversal's.

use isa::Machine;

/// One candidate hit of a single ray: scalars.
#[derive(Clone, Copy)]
pub struct Candidate1<M: Machine> {
    /// Index of the ray in its stream (where the filter keeps its state).
    pub ray: M::S,
    /// Hit distance.
    pub t: M::X,
    /// Triangle id.
    pub prim: M::S,
}

/// One triangle's candidate hits over a packet: the lanes in `valid`.
#[derive(Clone, Copy)]
pub struct CandidateK<M: Machine> {
    /// Index of the packet in its stream (lane `l` is the ray in slot
    /// `packet * LANES + l`).
    pub packet: M::S,
    /// Lanes that hit the triangle within their interval.
    pub valid: M::K,
    /// Hit distances (meaningful in `valid` lanes).
    pub t: M::F,
    /// The triangle id, in every lane (the bits of an i32).
    pub prim: M::F,
}

/// An intersection filter (Embree's `RTCFilterFunctionN`).
pub trait Filter<M: Machine> {
    /// Judge a single ray's candidate: `None` rejects it, `Some(t_far)`
    /// accepts it and continues the ray with `t_far` (at most `c.t`).
    fn one(&mut self, m: &mut M, c: Candidate1<M>) -> Option<M::X>;
    /// Judge a packet's candidates: the lanes accepted (within `c.valid`)
    /// and, in those lanes, the t_far each ray continues with.
    fn packet(&mut self, m: &mut M, c: CandidateK<M>) -> (M::K, M::F);
}
