//! # multihit-kernels
//!
//! The kernels of Gribble, Wald and Amstutz 2016, "Implementing Node Culling
//! Multi-Hit BVH Traversal in Embree": multi-hit traversal written as
//! intersection filters ([`filters`]) over the Embree-style kernels' filter
//! hook ([`rt::filter`]): single-ray BVH4 (`rtcIntersect1`) and 8-wide
//! packets (`rtcIntersect8`, the paper's ispc modules on AVX2).
//!
//! - **Naive** (Amstutz et al. 2015): the filter records every hit and
//!   rejects it; after traversal a selection sort picks the N_query closest
//!   ([`sort`]; coherent across a packet's lanes).
//! - **Node culling** (Listing 1): insertion into a per-ray buffer of
//!   N_query + 1 entries initialised beyond any hit; reject while fewer than
//!   N_query hits are held, then accept with t_far = the N_query-th hit's t,
//!   so farther nodes are culled.
//!
//! Each hit is a triangle: two triangles met at their shared edge are two
//! hits (as Embree reports them), and no triangle is reported twice because
//! the BVH references each triangle from exactly one leaf
//! (`scene::bvh::Bvh2::validate`).

#![warn(missing_docs)]

pub mod buffers;
pub mod filters;
pub mod sort;

use buffers::HitBufs;
use isa::{At, Cmp, Machine, MemKind, Program, Region};
use rt::layout::{hit_records, ray_records, Bvh4Bufs};
use rt::stats::Tests;
use scene::bvh::{Bvh2, Bvh4};
use scene::mesh::Mesh;
use scene::workload::RayStream;
use scene::Hit;
use std::sync::Arc;

/// Branch sites of the filters and the sort.
pub mod site {
    use isa::Site;
    /// Node culling: idx > 0?
    pub const CULL_IDX: Site = isa::sites::MULTIHIT.at(0);
    /// Node culling: the candidate nearer than the entry below?
    pub const CULL_CLOSER: Site = isa::sites::MULTIHIT.at(1);
    /// Node culling: fewer than N_query hits held (reject)?
    pub const CULL_HELD: Site = isa::sites::MULTIHIT.at(2);
    /// Node culling, packets: any lane still moving entries up?
    pub const CULL_PK_SHIFT: Site = isa::sites::MULTIHIT.at(3);
    /// Naive: room left in the ray's buffer?
    pub const NAIVE_ROOM: Site = isa::sites::MULTIHIT.at(4);
    /// Set-up: more rays?
    pub const INIT_RAY: Site = isa::sites::MULTIHIT.at(5);
    /// Set-up: more entries?
    pub const INIT_ENTRY: Site = isa::sites::MULTIHIT.at(6);
    /// Set-up: more packets?
    pub const INIT_PACKET: Site = isa::sites::MULTIHIT.at(7);
    /// Sort: more rays?
    pub const SORT_RAY: Site = isa::sites::MULTIHIT.at(8);
    /// Sort: another place to fill (i < min(count, N_query))?
    pub const SORT_I: Site = isa::sites::MULTIHIT.at(9);
    /// Sort: another entry to compare (j < count)?
    pub const SORT_J: Site = isa::sites::MULTIHIT.at(10);
    /// Sort: a nearer entry?
    pub const SORT_LESS: Site = isa::sites::MULTIHIT.at(11);
    /// Sort, packets: more packets?
    pub const SORT_PACKET: Site = isa::sites::MULTIHIT.at(12);
    /// Sort, packets: any lane with another place to fill?
    pub const SORT_PK_I: Site = isa::sites::MULTIHIT.at(13);
    /// Sort, packets: any lane with another entry to compare?
    pub const SORT_PK_J: Site = isa::sites::MULTIHIT.at(14);
    /// Node culling, packets (row insertion): entry index k > 0?
    pub const CULL_PK_ROW: Site = isa::sites::MULTIHIT.at(15);

    /// Every site of the crate (checked for duplicates by the layout test).
    pub const ALL: [Site; 16] = [
        CULL_IDX,
        CULL_CLOSER,
        CULL_HELD,
        CULL_PK_SHIFT,
        NAIVE_ROOM,
        INIT_RAY,
        INIT_ENTRY,
        INIT_PACKET,
        SORT_RAY,
        SORT_I,
        SORT_J,
        SORT_LESS,
        SORT_PACKET,
        SORT_PK_I,
        SORT_PK_J,
        CULL_PK_ROW,
    ];
}

/// The tree: Embree-like binned SAH, leaves of up to 4 triangles (one
/// triangle block each), traversal cost 1; the BVH4 is collapsed from it.
pub const BVH: scene::bvh::BuildConfig = scene::bvh::BuildConfig {
    bins: 16,
    max_leaf: 4,
    c_trav: 1.0,
};

/// Hits per ray the naive kernels' buffers hold unless a run asks for more
/// (a hit beyond it is dropped and counted in [`Counters::overflowed`]).
pub const NAIVE_CAPACITY: u32 = 256;

/// Which multi-hit algorithm.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Method {
    /// Record every hit, reject; sort after traversal.
    Naive,
    /// Listing 1: insertion sort, accept with the N_query-th t.
    NodeCulling,
}

/// Which traversal kernel the filter runs in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Traversal {
    /// One ray at a time (`rtcIntersect1`).
    Single,
    /// `LANES`-wide packets (`rtcIntersect8` on AVX2).
    Packet,
}

/// A multi-hit kernel: a traversal and a method.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Kernel {
    /// Traversal kernel.
    pub traversal: Traversal,
    /// Multi-hit method.
    pub method: Method,
}

impl Kernel {
    /// Every kernel.
    pub const ALL: [Kernel; 4] = [
        Kernel::new(Traversal::Single, Method::Naive),
        Kernel::new(Traversal::Single, Method::NodeCulling),
        Kernel::new(Traversal::Packet, Method::Naive),
        Kernel::new(Traversal::Packet, Method::NodeCulling),
    ];
    /// A kernel.
    #[must_use]
    pub const fn new(traversal: Traversal, method: Method) -> Kernel {
        Kernel { traversal, method }
    }
    /// Name as reports print it.
    #[must_use]
    pub fn name(self) -> &'static str {
        match (self.traversal, self.method) {
            (Traversal::Single, Method::Naive) => "naive (single ray)",
            (Traversal::Single, Method::NodeCulling) => "node culling (single ray)",
            (Traversal::Packet, Method::Naive) => "naive",
            (Traversal::Packet, Method::NodeCulling) => "node culling",
        }
    }
}

/// What a multi-hit run counts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counters {
    /// Rays traced.
    pub rays: u64,
    /// Hits returned (at most N_query per ray).
    pub hits: u64,
    /// Candidates the filter judged (lanes, for packets).
    pub candidates: u64,
    /// Candidates accepted (node culling once N_query are held).
    pub accepted: u64,
    /// Entries moved by node culling's insertion or the naive sort's swaps.
    pub moves: u64,
    /// Steps of node culling's insertion walk or the naive sort's inner
    /// walk: entries (single rays) or entry rows (packets) compared.
    pub steps: u64,
    /// Hits a naive buffer had no room for.
    pub overflowed: u64,
    /// Ray-node and ray-leaf tests of the traversal.
    pub tests: Tests,
}

/// A scene's mesh and the trees the kernels walk.
pub struct Tree {
    /// The mesh.
    pub mesh: Mesh,
    /// Its BVH2 ([`BVH`]).
    pub b2: Bvh2,
    /// The BVH4 collapsed from it.
    pub b4: Bvh4,
}

impl Tree {
    /// Build the trees of `mesh`.
    ///
    /// # Errors
    /// The builder's (an empty or non-finite mesh).
    pub fn build(mesh: Mesh) -> Result<Tree, String> {
        let b2 = Bvh2::build(&mesh, &BVH)?;
        let b4 = Bvh4::collapse(&b2);
        Ok(Tree { mesh, b2, b4 })
    }
    /// Lay the BVH4 out in `m`'s memory.
    pub fn lay_out<M: Machine>(&self, m: &mut M) -> Bvh4Bufs {
        rt::layout::lay_out_bvh4(m, &self.mesh, &self.b2, &self.b4)
    }
}

/// One multi-hit run over a stream: a kernel, N_query and (packets) the
/// lanes each ray takes.
#[derive(Clone)]
pub struct Run {
    /// The kernel.
    pub kernel: Kernel,
    /// Hits asked for per ray (at least 1).
    pub n_query: u32,
    /// Naive buffers' entries per ray.
    pub capacity: u32,
    /// The scene's trees.
    pub tree: Arc<Tree>,
    /// The rays.
    pub rays: Arc<RayStream>,
    /// Packets: per lane slot the ray in it (`scene::workload::packet_slots`);
    /// `None`: consecutive rays fill each packet.
    pub slots: Option<Arc<Vec<u32>>>,
    /// How node culling's packet filter moves entries (rows by default).
    pub insertion: filters::Insertion,
}

impl Program for Run {
    type Out = (Vec<Vec<Hit>>, Counters);
    fn run<M: Machine>(&self, m: &mut M) -> Self::Out {
        let s = self.tree.lay_out(m);
        self.trace_on(m, &s)
    }
}

impl Run {
    /// Trace the rays over a laid-out BVH4 on `m`: each ray's hits, nearest
    /// first (at most N_query), and the counters.
    ///
    /// # Panics
    /// If N_query is 0.
    pub fn trace_on<M: Machine>(&self, m: &mut M, s: &Bvh4Bufs) -> (Vec<Vec<Hit>>, Counters) {
        assert!(self.n_query >= 1, "N_query is at least 1");
        let entries = match self.kernel.method {
            Method::Naive => self.capacity.max(self.n_query),
            Method::NodeCulling => self.n_query + 1,
        };
        let (lists, mut c) = match self.kernel.traversal {
            Traversal::Single => self.single(m, s, entries),
            Traversal::Packet => self.packet(m, s, entries),
        };
        c.rays = self.rays.len() as u64;
        c.hits = lists.iter().map(|l| l.len() as u64).sum();
        (lists, c)
    }

    fn single<M: Machine>(
        &self,
        m: &mut M,
        s: &Bvh4Bufs,
        entries: u32,
    ) -> (Vec<Vec<Hit>>, Counters) {
        let r = &self.rays;
        let n = r.len();
        let (tr, is) = ray_records(&r.org, &r.dir, &r.tmax);
        let sp = m.space();
        let mut trav = sp.alloc_f32(MemKind::Rays, "rays-trav", &tr, 64);
        let isect = sp.alloc_f32(MemKind::Rays, "rays-isect", &is, 64);
        let mut hits = sp.alloc_bytes(MemKind::Hits, "hits", hit_records(n), 64);
        let mut stack = sp.alloc(MemKind::Stack, "stack", rt::single::STACK_ENTRIES * 8, 64);
        let bufs = HitBufs::single(m, n, entries);
        let mut tests = Tests::default();
        let mut c = Counters::default();
        let lists = match self.kernel.method {
            Method::NodeCulling => {
                let mut f = filters::NodeCulling::new(bufs, self.n_query);
                f.init_single(m, n);
                rt::single::trace_bvh4_filtered(
                    m, s, &mut trav, &isect, &mut hits, &mut stack, n, &mut tests, &mut f,
                );
                c.candidates = f.candidates;
                c.accepted = f.accepted;
                (c.moves, c.steps) = (f.moves, f.steps);
                f.bufs.lists_single(n, self.n_query)
            }
            Method::Naive => {
                let mut f = filters::Naive::new(bufs);
                f.init_single(m, n);
                rt::single::trace_bvh4_filtered(
                    m, s, &mut trav, &isect, &mut hits, &mut stack, n, &mut tests, &mut f,
                );
                c.candidates = f.candidates;
                c.overflowed = f.overflowed;
                let sorted = sort::single(m, &mut f.bufs, n, self.n_query);
                (c.moves, c.steps) = (sorted.moves, sorted.steps);
                f.bufs.lists_single(n, self.n_query)
            }
        };
        c.tests = tests;
        (lists, c)
    }

    fn packet<M: Machine>(
        &self,
        m: &mut M,
        s: &Bvh4Bufs,
        entries: u32,
    ) -> (Vec<Vec<Hit>>, Counters) {
        let r = &self.rays;
        let w = M::LANES;
        let slots = self.slots.as_ref().map(|s| s.as_slice());
        let mut pb = rt::packet::PacketBufs::new(m, &r.org, &r.dir, &r.tmax, slots);
        let np = pb.packets;
        let bufs = HitBufs::packet(m, np, w, entries);
        let mut c = Counters::default();
        let slots: Vec<usize> = (0..r.len()).map(|i| pb.slot(i)).collect();
        let lists = match self.kernel.method {
            Method::NodeCulling => {
                let mut f = filters::NodeCulling::new(bufs, self.n_query);
                f.insertion = self.insertion;
                f.init_packets(m, np);
                rt::packet::trace_bvh4_filtered(m, s, &mut pb, &mut f);
                c.candidates = f.candidates;
                c.accepted = f.accepted;
                (c.moves, c.steps) = (f.moves, f.steps);
                f.bufs.lists_packet(&slots, self.n_query)
            }
            Method::Naive => {
                let mut f = filters::Naive::new(bufs);
                f.init_packets(m, np);
                rt::packet::trace_bvh4_filtered(m, s, &mut pb, &mut f);
                c.candidates = f.candidates;
                c.overflowed = f.overflowed;
                let sorted = sort::packets(m, &mut f.bufs, np, self.n_query);
                (c.moves, c.steps) = (sorted.moves, sorted.steps);
                f.bufs.lists_packet(&slots, self.n_query)
            }
        };
        c.tests = pb.tests;
        (lists, c)
    }
}

/// A counted loop `0..n` in kernel code (at least once), its branch at `site`.
pub(crate) fn each<M: Machine>(
    m: &mut M,
    n: usize,
    site: isa::Site,
    mut f: impl FnMut(&mut M, M::S),
) {
    let mut i = m.int(0);
    let end = m.int(n as i64);
    loop {
        f(m, i);
        i = m.s_addi(i, 1);
        if !m.branch_if(site, Cmp::Lt, i, end) {
            break;
        }
    }
}

/// Set the region and return `At` for byte `off` of a register address.
pub(crate) fn at<S>(base: S, off: usize) -> At<S> {
    At::idx(base, 1, off)
}

/// The region filters and the sort record their ops in (per-hit work).
pub(crate) const FILTER_REGION: Region = Region::Shading;
