//! Run a traversal kernel on any machine over a ray stream, and compare its
//! closest hits with the f64 reference (used by the tests and `rtsim run`).

use rt::hand::NodeWidth;
use rt::layout::{hit_records, lay_out_bvh4, ray_records};
use scene::agreement::{mismatches, shadow_mismatches};
use scene::bvh::{Bvh2, Bvh4};
use scene::reference::Reference;
use scene::scene::Scene;
use scene::workload::RayStream;
use scene::Hit;

use isa::{AddrSpace, Machine, MemKind, Program};
use std::sync::OnceLock;

/// Which traversal kernel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kernel {
    /// Single-ray BVH2.
    SingleBvh2,
    /// Single-ray BVH4.
    SingleBvh4,
    /// Dynamic ray stream BVH4.
    DrsBvh4,
    /// Dynamic ray stream BVH2.
    DrsBvh2,
    /// 8-ray (LANES-ray) packets, BVH2.
    PacketBvh2,
    /// 8-ray (LANES-ray) packets, BVH4.
    PacketBvh4,
    /// Packets switching to single rays, BVH4.
    HybridBvh4,
}

/// A kernel over a ray stream of a scene; the output is (t, prim) per ray
/// (shadow streams: prim >= 0 when occluded) and the kernel's test counts.
pub struct Run<'a> {
    /// The kernel.
    pub kernel: Kernel,
    /// The scene.
    pub scene: &'a Scene,
    /// Its BVH2 (leaves of at most 8 triangles).
    pub b2: &'a Bvh2,
    /// The BVH4 collapsed from it.
    pub b4: &'a Bvh4,
    /// The rays (closest hit, or any hit for a shadow stream).
    pub rays: RayStream,
    /// For the packet kernels: the stream's tile (size in pixels, samples per
    /// pixel), to form packets as a packet renderer does
    /// ([`scene::workload::packet_slots`]); `None`: consecutive rays.
    pub packet_tile: Option<(u32, u32)>,
    /// Layouts shared with other runs of the same scene ([`SharedLayouts`]);
    /// `None`: each machine lays the scene out itself.
    pub shared: Option<&'a SharedLayouts>,
}

/// Buffers kept from one trace to the next ([`Run::scratch`]).
pub struct Scratch {
    stream: Option<crate::bvh4::StreamBufs>,
}

/// A scene's BVH2 and BVH4 layouts shared by every method's machines: each
/// laid out once, on first use, and given to a fresh machine as its address
/// space and buffers (the bytes shared), exactly as if that machine had laid
/// it out — seven methods of a 7.8 M-triangle scene hold two layouts, not seven.
#[derive(Default)]
pub struct SharedLayouts {
    bvh2: OnceLock<(AddrSpace, Laid)>,
    bvh4: OnceLock<(AddrSpace, Laid)>,
}

impl<'a> Run<'a> {
    /// `kernel` over `rays`, packets of consecutive rays.
    #[must_use]
    pub fn new(
        kernel: Kernel,
        scene: &'a Scene,
        b2: &'a Bvh2,
        b4: &'a Bvh4,
        rays: RayStream,
    ) -> Self {
        Run {
            kernel,
            scene,
            b2,
            b4,
            rays,
            packet_tile: None,
            shared: None,
        }
    }

    /// Rays whose result differs from the reference's ([`mismatches`] for
    /// closest hits, [`shadow_mismatches`] for shadow rays).
    #[must_use]
    pub fn mismatches(&self, label: &str, refi: &Reference, out: &[Hit]) -> usize {
        stream_mismatches(label, refi, &self.rays, out)
    }
}

/// Rays of `rays` whose result in `out` differs from the reference's
/// ([`mismatches`] for closest hits, [`shadow_mismatches`] for shadow rays).
#[must_use]
pub fn stream_mismatches(label: &str, refi: &Reference, rays: &RayStream, out: &[Hit]) -> usize {
    if rays.is_shadow() {
        shadow_mismatches(label, refi, rays, out)
    } else {
        mismatches(label, refi, &rays.org, &rays.dir, out)
    }
}

impl Kernel {
    /// Every kernel.
    pub const ALL: [Kernel; 7] = [
        Kernel::DrsBvh2,
        Kernel::DrsBvh4,
        Kernel::SingleBvh2,
        Kernel::SingleBvh4,
        Kernel::PacketBvh2,
        Kernel::PacketBvh4,
        Kernel::HybridBvh4,
    ];
    /// Stable name (`single-bvh2`, `single-bvh4`, `drs-bvh2`, `drs-bvh4`,
    /// `packet-bvh2`, `packet-bvh4`, `hybrid-bvh4`).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Kernel::SingleBvh2 => "single-bvh2",
            Kernel::SingleBvh4 => "single-bvh4",
            Kernel::DrsBvh4 => "drs-bvh4",
            Kernel::DrsBvh2 => "drs-bvh2",
            Kernel::PacketBvh2 => "packet-bvh2",
            Kernel::PacketBvh4 => "packet-bvh4",
            Kernel::HybridBvh4 => "hybrid-bvh4",
        }
    }
    /// Whether it reads the BVH2 (else the BVH4).
    #[must_use]
    pub fn reads_bvh2(self) -> bool {
        matches!(
            self,
            Kernel::SingleBvh2 | Kernel::DrsBvh2 | Kernel::PacketBvh2
        )
    }
    /// Whether it traces packets of rays (the packet and hybrid kernels).
    #[must_use]
    pub fn is_packet(self) -> bool {
        matches!(
            self,
            Kernel::PacketBvh4 | Kernel::PacketBvh2 | Kernel::HybridBvh4
        )
    }
    /// Whether it runs on machines of `lanes` lanes.
    #[must_use]
    pub fn supports(self, lanes: usize) -> bool {
        match self {
            Kernel::SingleBvh4
            | Kernel::SingleBvh2
            | Kernel::PacketBvh4
            | Kernel::PacketBvh2
            | Kernel::HybridBvh4 => true,
            Kernel::DrsBvh4 | Kernel::DrsBvh2 => matches!(lanes, 4 | 8 | 16 | 32),
        }
    }
}

impl Program for Run<'_> {
    type Out = (Vec<Hit>, rt::stats::Tests);
    fn run<M: Machine>(&self, m: &mut M) -> Self::Out {
        let laid = self.lay_out(m);
        self.trace(m, &laid)
    }
}

/// A kernel over a frame's streams, as a renderer runs it: the scene laid
/// out once, each unit one ray stream (the `rays` of `self` are not used).
impl isa::UnitProgram for Run<'_> {
    type Laid = Laid;
    type Unit = RayStream;
    type Out = (Vec<Hit>, rt::stats::Tests);
    fn lay_out<M: Machine>(&self, m: &mut M) -> Laid {
        Run::lay_out(self, m)
    }
    fn unit<M: Machine>(&self, m: &mut M, laid: &Laid, rays: &RayStream) -> Self::Out {
        self.trace_rays(m, laid, rays, None)
    }
}

/// A scene laid out in a machine's memory for one kernel: the BVH4 or BVH2
/// records it reads.
#[derive(Clone)]
pub struct Laid {
    /// BVH4 layout (BVH4 kernels).
    pub bvh4: Option<rt::layout::Bvh4Bufs>,
    /// BVH2 layout (BVH2 kernels).
    pub bvh2: Option<rt::layout::Bvh2Bufs>,
    /// The BVH2's depth (sizes the stream kernels' stacks; a walk of the
    /// whole tree, so taken once here).
    pub depth: usize,
}

impl Run<'_> {
    /// Lay out the tree the kernel reads (once per machine; see [`Run::trace`]):
    /// from [`Run::shared`] when the machine's space is fresh.
    pub fn lay_out<M: Machine>(&self, m: &mut M) -> Laid {
        let Some(shared) = self.shared.filter(|_| m.space().is_fresh()) else {
            return self.lay_out_here(m);
        };
        let cell = if self.reads_bvh2() {
            &shared.bvh2
        } else {
            &shared.bvh4
        };
        let (space, laid) = cell.get_or_init(|| {
            let mut t = isa::Native::<isa::Sse4, 4>::new();
            let laid = self.lay_out_here(&mut t);
            (t.space().clone(), laid)
        });
        *m.space() = space.clone();
        laid.clone()
    }

    /// Whether the kernel reads the BVH2 (else the BVH4).
    fn reads_bvh2(&self) -> bool {
        self.kernel.reads_bvh2()
    }

    /// [`Run::lay_out`] on `m` itself.
    fn lay_out_here<M: Machine>(&self, m: &mut M) -> Laid {
        if self.reads_bvh2() {
            Laid {
                bvh4: None,
                bvh2: Some(rt::layout::lay_out_bvh2(m, &self.scene.mesh, self.b2)),
                depth: self.b2.depth(),
            }
        } else {
            Laid {
                bvh4: Some(lay_out_bvh4(m, &self.scene.mesh, self.b2, self.b4)),
                bvh2: None,
                depth: self.b2.depth(),
            }
        }
    }

    /// Trace the rays over a layout from [`Run::lay_out`] on the same machine.
    pub fn trace<M: Machine>(&self, m: &mut M, laid: &Laid) -> (Vec<Hit>, rt::stats::Tests) {
        self.trace_rays(m, laid, &self.rays, None)
    }

    /// The buffers [`Run::trace_in`] keeps from one trace to the next: the
    /// DRS kernels' ray pointer lists, allocated once as the paper's
    /// renderer does (allocated and zeroed per trace, 6.5 MB for a
    /// 16384-ray stream, they took 7% of DRS BVH4's native time and pushed
    /// the tree out of L2). Made on the machine that traces, before the
    /// mark its traces release to.
    pub fn scratch<M: Machine>(&self, m: &mut M, laid: &Laid) -> Scratch {
        let drs = matches!(self.kernel, Kernel::DrsBvh4 | Kernel::DrsBvh2);
        Scratch {
            stream: drs.then(|| crate::bvh4::StreamBufs::new(m, self.rays.org.len(), laid.depth)),
        }
    }

    /// [`Run::trace`] with buffers from [`Run::scratch`], reused (for
    /// repeated native timings).
    pub fn trace_in<M: Machine>(
        &self,
        m: &mut M,
        laid: &Laid,
        scratch: &mut Scratch,
    ) -> (Vec<Hit>, rt::stats::Tests) {
        let mut staged = self.stage(m);
        let tests = self.trace_staged(m, laid, &mut staged, scratch);
        (staged.answers(), tests)
    }

    /// The kernel alone over rays [`Run::stage`] laid out, with buffers
    /// from [`Run::scratch`]: what the timing model records, and what the
    /// native timings time (the staging before it and the answers read
    /// back after it are host work the model does not see).
    pub fn trace_staged<M: Machine>(
        &self,
        m: &mut M,
        laid: &Laid,
        staged: &mut Staged,
        scratch: &mut Scratch,
    ) -> rt::stats::Tests {
        if let Some(st) = &mut scratch.stream {
            st.reset();
        }
        self.kernel_over(m, laid, staged, &self.rays, scratch.stream.as_mut())
    }

    /// The ray records the hand-written twin reads ([`Run::trace_hand`]),
    /// made before it is timed as [`Run::stage`] is before a kernel.
    #[must_use]
    pub fn hand_records(&self) -> (Vec<f32>, Vec<f32>) {
        let r = &self.rays;
        ray_records(&r.org, &r.dir, &r.tmax)
    }

    /// The hand-written twin of the run's kernel ([`rt::hand`]), its node
    /// test at `width`, over the run's rays and `view` (the layout's BVH4):
    /// its answers as [`Run::trace_in`] gives them (ray records built, hits
    /// read back), or `None` when the kernel has no twin or the host lacks
    /// AVX2 and FMA.
    #[must_use]
    pub fn trace_hand(&self, view: &rt::hand::Bvh4View, width: NodeWidth) -> Option<Vec<Hit>> {
        let (trav, isect) = self.hand_records();
        let recs = self.trace_hand_records(view, (&trav, &isect), width)?;
        Some(hand_answers(&recs))
    }

    /// The twin alone over records from [`Run::hand_records`]: its hit
    /// records ([`hand_answers`] reads them as hits).
    #[must_use]
    pub fn trace_hand_records(
        &self,
        view: &rt::hand::Bvh4View,
        records: (&[f32], &[f32]),
        width: NodeWidth,
    ) -> Option<Vec<rt::hand::HitRecord>> {
        if self.kernel != Kernel::SingleBvh4 {
            return None;
        }
        rt::hand::single_bvh4(view, records, self.rays.policy(), width)
    }

    /// The run's rays laid out on `m` for its kernel: the ray and hit
    /// records (single-ray and DRS kernels, and the single-ray stack), or
    /// the packet buffers.
    pub fn stage<M: Machine>(&self, m: &mut M) -> Staged {
        self.stage_rays(m, &self.rays)
    }

    /// [`Run::stage`] of `rays` instead of the run's own.
    fn stage_rays<M: Machine>(&self, m: &mut M, rays: &RayStream) -> Staged {
        let (org, dir, tmax) = (&rays.org, &rays.dir, &rays.tmax);
        let n = org.len();
        if self.kernel.is_packet() {
            let slots = self
                .packet_tile
                .map(|(size, spp)| scene::workload::packet_slots(rays, size, spp, M::LANES));
            let pb = rt::packet::PacketBufs::new(m, org, dir, tmax, slots.as_deref());
            return Staged::Packets(pb, M::LANES, n);
        }
        let (tr, is) = ray_records(org, dir, tmax);
        let sp = m.space();
        let trav = sp.alloc_f32(MemKind::Rays, "rays-trav", &tr, 64);
        let isect = sp.alloc_f32(MemKind::Rays, "rays-isect", &is, 64);
        let hits = sp.alloc_bytes(MemKind::Hits, "hits", hit_records(n), 64);
        let single = matches!(self.kernel, Kernel::SingleBvh2 | Kernel::SingleBvh4);
        let stack =
            single.then(|| sp.alloc(MemKind::Stack, "stack", rt::single::STACK_ENTRIES * 8, 64));
        Staged::Rays(RayBufs {
            trav,
            isect,
            hits,
            stack,
            n,
        })
    }

    /// [`Run::trace`] over `rays` instead of the run's own; the DRS
    /// kernels' stream buffers from `stream` when given.
    fn trace_rays<M: Machine>(
        &self,
        m: &mut M,
        laid: &Laid,
        rays: &RayStream,
        stream: Option<&mut crate::bvh4::StreamBufs>,
    ) -> (Vec<Hit>, rt::stats::Tests) {
        let mut staged = self.stage_rays(m, rays);
        let tests = self.kernel_over(m, laid, &mut staged, rays, stream);
        (staged.answers(), tests)
    }

    /// The run's kernel over `staged` (made by [`Run::stage`] from
    /// `rays`); the DRS kernels' stream buffers from `stream` when given.
    fn kernel_over<M: Machine>(
        &self,
        m: &mut M,
        laid: &Laid,
        staged: &mut Staged,
        rays: &RayStream,
        stream: Option<&mut crate::bvh4::StreamBufs>,
    ) -> rt::stats::Tests {
        let s4 = || laid.bvh4.as_ref().expect("a BVH4 layout");
        let s2 = || laid.bvh2.as_ref().expect("a BVH2 layout");
        let policy = rays.policy();
        let b = match staged {
            Staged::Packets(pb, _, _) => {
                if self.kernel == Kernel::PacketBvh2 {
                    rt::packet::trace_bvh2(m, s2(), pb, policy);
                } else {
                    let hybrid = self.kernel == Kernel::HybridBvh4;
                    rt::packet::trace_bvh4(m, s4(), pb, hybrid, policy);
                }
                return pb.tests;
            }
            Staged::Rays(b) => b,
        };
        let n = b.n;
        let mut tests = rt::stats::Tests::default();
        let (trav, isect, hits) = (&mut b.trav, &b.isect, &mut b.hits);
        match (self.kernel, b.stack.as_mut()) {
            (Kernel::SingleBvh2, Some(stack)) => {
                rt::single::trace_bvh2(m, s2(), trav, isect, hits, stack, n, &mut tests, policy);
            }
            (Kernel::SingleBvh4, Some(stack)) => {
                rt::single::trace_bvh4(m, s4(), trav, isect, hits, stack, n, &mut tests, policy);
            }
            (Kernel::DrsBvh4 | Kernel::DrsBvh2, _) => {
                let mut own;
                let st = match stream {
                    Some(st) => st,
                    None => {
                        own = crate::bvh4::StreamBufs::new(m, n, laid.depth);
                        &mut own
                    }
                };
                if self.kernel == Kernel::DrsBvh4 {
                    crate::bvh4::trace(m, s4(), st, trav, isect, hits, n, policy);
                } else {
                    crate::bvh2::trace(m, s2(), st, trav, isect, hits, n, policy);
                }
                tests = st.tests;
            }
            (k, _) => unreachable!("{k:?} staged as rays without its stack"),
        }
        tests
    }
}

/// The hand-written twin's hit records as hits.
#[must_use]
pub fn hand_answers(recs: &[rt::hand::HitRecord]) -> Vec<Hit> {
    recs.iter().map(|h| Hit::from_record(h.t, h.prim)).collect()
}

/// A trace's inputs laid out on the machine before its kernel runs
/// ([`Run::stage`]), and its answers read back after ([`Staged::answers`]).
pub enum Staged {
    /// Ray and hit records (single-ray and DRS kernels).
    Rays(RayBufs),
    /// The packet kernels' buffers, their lane count and the number of rays.
    Packets(rt::packet::PacketBufs, usize, usize),
}

/// The single-ray and DRS kernels' buffers.
pub struct RayBufs {
    trav: isa::Buf,
    isect: isa::Buf,
    hits: isa::Buf,
    /// The single-ray kernels' stack.
    stack: Option<isa::Buf>,
    n: usize,
}

impl Staged {
    /// Each ray's answer, in ray order.
    #[must_use]
    pub fn answers(&self) -> Vec<Hit> {
        match self {
            Staged::Packets(pb, lanes, n) => (0..*n).map(|i| pb.hit(*lanes, i)).collect(),
            Staged::Rays(b) => (0..b.n)
                .map(|i| Hit::from_record(b.hits.f32_at(16 * i), b.hits.u32_at(16 * i + 12)))
                .collect(),
        }
    }
}
