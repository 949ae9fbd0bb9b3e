//! # mbvh-kernels
//!
//! The kernels of Tsakok 2009, "Faster Incoherent Rays: Multi-BVH Ray Stream
//! Tracing": MBVH RS ([`stream`], Algorithm 1 and Listing 1) and the two
//! baselines the paper measures it against, single-ray MBVH ([`single`]) and
//! packets ([`packet`]), over one `W`-wide MBVH ([`layout`]) where `W` is
//! the machine's lanes (4 on SSE4 for the paper's Core 2, 16 on LRBni and
//! AVX-512 for its 16-wide figures). Each is written once against
//! `isa::Machine`, runs traced or natively, and counts what the paper's
//! Figures 4-8 plot ([`stats`]).

#![warn(missing_docs)]
#![allow(clippy::needless_range_loop)]

pub mod large_packet;
pub mod layout;
pub mod packet;
mod shared;
pub mod single;
pub mod stats;
pub mod stream;

use isa::{Machine, Program};
use scene::bvh::{BuildConfig, Bvh2};
use scene::mbvh::Mbvh;
use scene::mesh::Mesh;
use scene::workload::RayStream;
use scene::Hit;
use stats::Counters;
use std::sync::{Arc, OnceLock};
use stream::StreamConfig;

/// The paper's tree: "a traditional SAH with 4-way branching" (section 3),
/// leaves as the SAH makes them. The paper gives no leaf size or cost ratio;
/// rtsim's generic defaults (16 bins, leaves of up to 4, traversal cost 1)
/// stand in, with no incentive to fill leaves to the SIMD width.
pub const BVH: BuildConfig = BuildConfig {
    bins: 16,
    max_leaf: 4,
    c_trav: 1.0,
};

/// The paper's three traversal methods.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kernel {
    /// MBVH ray streams with its configuration.
    Stream(StreamConfig),
    /// Single-ray MBVH.
    Single,
    /// `W`-wide packets over the MBVH.
    Packet,
    /// Packets of this many rays (groups of `W`) with first-hit and
    /// interval culling (Boulos et al. 2007), over the MBVH.
    LargePacket(usize),
}

impl Kernel {
    /// Short name as reports print it.
    #[must_use]
    pub fn name(&self) -> &'static str {
        match self {
            Kernel::Stream(_) => "MBVH RS",
            Kernel::Single => "MBVH",
            Kernel::Packet => "packets",
            Kernel::LargePacket(_) => "large packets",
        }
    }
}

/// A scene's MBVHs of every width asked for, collapsed once from its BVH2.
pub struct Trees {
    /// The triangles.
    pub mesh: Arc<Mesh>,
    /// The SAH BVH2 the MBVHs are collapsed from.
    pub b2: Arc<Bvh2>,
    w4: OnceLock<Mbvh>,
    w8: OnceLock<Mbvh>,
    w16: OnceLock<Mbvh>,
}

impl Trees {
    /// Trees over `mesh` from its BVH2 `b2` (built with [`BVH`]).
    #[must_use]
    pub fn new(mesh: Arc<Mesh>, b2: Arc<Bvh2>) -> Trees {
        Trees {
            mesh,
            b2,
            w4: OnceLock::new(),
            w8: OnceLock::new(),
            w16: OnceLock::new(),
        }
    }

    /// The MBVH of width `w` (4, 8 or 16).
    ///
    /// # Panics
    /// For another width.
    pub fn of_width(&self, w: usize) -> &Mbvh {
        let cell = match w {
            4 => &self.w4,
            8 => &self.w8,
            16 => &self.w16,
            _ => panic!("no MBVH of width {w}"),
        };
        cell.get_or_init(|| Mbvh::collapse(&self.b2, w))
    }
}

/// One kernel over one ray stream: a program for any machine.
pub struct Run {
    /// The method.
    pub kernel: Kernel,
    /// The scene's trees.
    pub trees: Arc<Trees>,
    /// The rays (closest hit, or any hit for shadow streams).
    pub rays: Arc<RayStream>,
}

impl Run {
    /// Trace the rays on `m` over `tree`, laid out there already (a
    /// report's frame lays the scene out once for all its streams).
    pub fn trace_on<M: Machine>(&self, m: &mut M, tree: &layout::MbvhBufs) -> (Vec<Hit>, Counters) {
        let r = &self.rays;
        let rays = (&r.org[..], &r.dir[..], &r.tmax[..]);
        let policy = r.policy();
        let mut c = Counters::default();
        let n = r.len();
        let hits = match self.kernel {
            Kernel::Stream(cfg) => {
                let mut b = stream::StreamBufs::new(m, tree, &cfg, rays);
                stream::trace(m, tree, &mut b, &cfg, policy, &mut c);
                (0..n).map(|i| b.hit(i)).collect()
            }
            Kernel::Single => {
                let mut b = single::SingleBufs::new(m, tree, rays);
                single::trace(m, tree, &mut b, policy, &mut c);
                (0..n).map(|i| b.hit(i)).collect()
            }
            Kernel::Packet => {
                let mut b = packet::PacketBufs::new(m, tree, rays);
                packet::trace(m, tree, &mut b, policy, &mut c);
                (0..n).map(|i| b.hit(i)).collect()
            }
            Kernel::LargePacket(size) => {
                let mut b = large_packet::LargeBufs::new(m, tree, rays, size);
                large_packet::trace(m, tree, &mut b, policy, &mut c);
                (0..n).map(|i| b.hit(i)).collect()
            }
        };
        (hits, c)
    }
}

impl Program for Run {
    type Out = (Vec<Hit>, Counters);

    fn run<M: Machine>(&self, m: &mut M) -> Self::Out {
        let t = self.trees.of_width(M::LANES);
        let tree = layout::lay_out(m, &self.trees.mesh, &self.trees.b2, t);
        self.trace_on(m, &tree)
    }

    fn params(&self) -> Vec<(String, String)> {
        vec![("kernel".into(), self.kernel.name().into())]
    }
}
