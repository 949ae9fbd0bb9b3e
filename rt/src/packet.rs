//! Packet traversal (the DRS paper's "Packet BVH2/BVH4", Wald et al. 2001, as
//! Embree 2.0's `BVH4Intersector8Chunk`) and hybrid traversal ("Hybrid BVH4",
//! Benthin et al. 2012, as Embree 2.0's `BVH4Intersector8Hybrid`).
//!
//! A packet is `LANES` consecutive rays of a stream (8 on AVX2), one ray per
//! lane, in an SoA record. All rays of a packet take one traversal order:
//! children are tested in storage order against every ray, and a hit child
//! replaces the current next node when *any* ray reaches it earlier, else it
//! is pushed with its per-ray entry distances (a vector); a popped entry is
//! culled when no ray's entry distance is below its hit distance. Leaves test
//! all rays of the packet against one triangle at a time (triangle data
//! broadcast). The hybrid kernel, on popping a node with at most
//! [`SWITCH_THRESHOLD`] active rays, traces each of them alone from that node
//! with the single-ray BVH4 kernel and carries on.
//!
//! Packet record (`LANES` = W lanes, rows of 4W bytes):
//!
//! | row | field |
//! |---|---|
//! | 0-2 | origin x, y, z |
//! | 3-5 | direction x, y, z |
//! | 6-8 | reciprocal direction x, y, z |
//! | 9 | t_near (0) |
//! | 10 | t_far (in: the ray's limit; out: the hit distance) |
//! | 11, 12 | hit u, v |
//! | 13 | hit prim (i32, -1: none) |
//! | 14, 15 | pad (a record is 16 rows: 512 B at W = 8) |
//!
//! Lanes past the end of the stream are padding: t_far = -1, so no box or
//! triangle test ever succeeds for them.
//!
//! Deviations: leaves are one block of <= 8 triangles (as for the other
//! kernels) iterated triangle by triangle until an empty slot, where Embree
//! iterates triangle4 lists by their count; the hybrid kernel's single-ray
//! leaves test 1 ray vs 8 triangles (the paper: 1 vs 4).

use crate::filter::{CandidateK, Filter};
use crate::layout::{Bvh2Bufs, Bvh4Bufs, BLOCK_BYTES, NODE_BYTES};
use crate::single::{moller_sided, walk4, Block, Moller, RayState, Sides, STACK_ENTRIES};
use crate::stats::Tests;
use isa::{At, Buf, Cmp, Int, Machine, MemKind, Region, Shift};
use scene::bvh::{EMPTY_SLOT, LEAF};
use scene::Hit;
use scene::HitPolicy;

pub use crate::layout::{packet_bytes, row};

/// Embree 2.0's `SWITCH_THRESHOLD` for 8-wide hybrid BVH4 traversal: at most
/// this many active rays switch to single-ray traversal.
pub const SWITCH_THRESHOLD: u32 = 3;

/// Branch sites.
pub mod site {
    use isa::Site;
    /// More packets?
    pub const PACKETS: Site = isa::sites::PACKET.at(0);
    /// Stack sentinel reached?
    pub const DONE: Site = isa::sites::PACKET.at(1);
    /// Any ray in front of its hit (else the entry is culled)?
    pub const CULL: Site = isa::sites::PACKET.at(2);
    /// Leaf (or sentinel)?
    pub const LEAF: Site = isa::sites::PACKET.at(3);
    /// Empty child slot?
    pub const EMPTY: Site = isa::sites::PACKET.at(4);
    /// Any ray hits the child?
    pub const HIT: Site = isa::sites::PACKET.at(5);
    /// Any ray reaches the child before the current next node?
    pub const CLOSER: Site = isa::sites::PACKET.at(6);
    /// Empty triangle slot?
    pub const TRI_SLOT: Site = isa::sites::PACKET.at(7);
    /// Any ray passes the triangle's depth test?
    pub const TRI: Site = isa::sites::PACKET.at(8);
    /// Few active rays: switch to single-ray traversal?
    pub const SWITCH: Site = isa::sites::PACKET.at(9);
    /// Next active ray of a switched packet?
    pub const SWITCH_RAY: Site = isa::sites::PACKET.at(10);
    /// Shadow packet: any lane not yet occluded?
    pub const ALIVE: Site = isa::sites::PACKET.at(11);
    /// Any ray passes the triangle's edge tests?
    pub const TRI_EDGE: Site = isa::sites::PACKET.at(12);

    /// Every site of the module (checked for duplicates by the layout test).
    pub const ALL: [Site; 13] = [
        PACKETS, DONE, CULL, LEAF, EMPTY, HIT, CLOSER, TRI_SLOT, TRI, SWITCH, SWITCH_RAY, ALIVE,
        TRI_EDGE,
    ];
}

/// SoA packet records of rays (org, dir, t_far) for packets of `w` lanes;
/// `slots[j]` is the ray in lane slot j (`u32::MAX`: an empty lane).
#[must_use]
pub fn packet_records(
    org: &[[f32; 3]],
    dir: &[[f32; 3]],
    tfar: &[f32],
    slots: &[u32],
    w: usize,
) -> Vec<f32> {
    let np = slots.len().div_ceil(w).max(1);
    let mut v = vec![0f32; np * row::ROWS * w];
    for p in 0..np {
        let base = p * row::ROWS * w;
        for l in 0..w {
            let i = slots.get(p * w + l).copied().unwrap_or(u32::MAX) as usize;
            let at = |r: usize| base + r * w + l;
            let (o, d, tf) = if i < org.len() {
                (org[i], dir[i], tfar[i])
            } else {
                ([0.0; 3], [1.0; 3], -1.0)
            };
            for a in 0..3 {
                v[at(row::ORG + a)] = o[a];
                v[at(row::DIR + a)] = d[a];
                v[at(row::IDIR + a)] = 1.0 / d[a];
            }
            v[at(row::TNEAR)] = 0.0;
            v[at(row::TFAR)] = tf;
            v[at(row::PRIM)] = f32::from_bits((-1i32) as u32);
        }
    }
    v
}

/// Where a packet leaf reads each triangle from.
#[derive(Clone)]
pub enum TriForm {
    /// The leaf's triangle block: v0 and two edges, precomputed.
    Edges,
    /// The block's triangle ids, then three vertex indices and three
    /// vertices each, edges computed at the leaf (the MFT paper's baseline);
    /// shared by the work units of one layout.
    Indexed(std::sync::Arc<crate::layout::IndexedTris>),
}

/// The packet kernels' buffers.
pub struct PacketBufs {
    /// Packet records.
    pub rays: Buf,
    /// Packets.
    pub packets: usize,
    /// Stack node refs (u32).
    pub stack_node: Buf,
    /// Stack entry distances (one vector per entry).
    pub stack_near: Buf,
    /// The hybrid kernel's single-ray stack.
    pub single_stack: Buf,
    /// Ray-node and ray-leaf tests (active rays per packet test).
    pub tests: Tests,
    /// Each ray's lane slot.
    slot_of: Vec<usize>,
    /// Faces the leaves report ([`Sides::Front`]: back-face culling, for the
    /// MFT comparison's packet baseline).
    pub sides: Sides,
    /// Where leaves read a triangle's vertices from.
    pub tri_form: TriForm,
    /// The MFT paper's counters for the packet baseline: box tests (one per
    /// child box per packet), triangles tested per packet (all of them are
    /// 16-wide intersection tests; no culling).
    pub frusta_stats: crate::stats::MftStats,
}

impl PacketBufs {
    /// Packet records of the rays in `m`'s memory, and the stacks. `slots`
    /// places rays in lanes (see [`scene::workload::packet_slots`]); `None`:
    /// consecutive rays fill each packet.
    pub fn new<M: Machine>(
        m: &mut M,
        org: &[[f32; 3]],
        dir: &[[f32; 3]],
        tfar: &[f32],
        slots: Option<&[u32]>,
    ) -> PacketBufs {
        let w = M::LANES;
        let seq: Vec<u32>;
        let slots = match slots {
            Some(s) => s,
            None => {
                seq = (0..org.len() as u32).collect();
                &seq
            }
        };
        let mut slot_of = vec![usize::MAX; org.len()];
        for (j, &i) in slots.iter().enumerate() {
            if (i as usize) < org.len() {
                slot_of[i as usize] = j;
            }
        }
        assert!(
            slot_of.iter().all(|&j| j != usize::MAX),
            "every ray has a lane"
        );
        let recs = packet_records(org, dir, tfar, slots, w);
        let packets = recs.len() / (row::ROWS * w);
        let sp = m.space();
        PacketBufs {
            rays: sp.alloc_f32(MemKind::Rays, "packets", &recs, 64),
            packets,
            stack_node: sp.alloc(MemKind::Stack, "stack-node", STACK_ENTRIES * 4, 64),
            stack_near: sp.alloc(MemKind::Stack, "stack-near", STACK_ENTRIES * 4 * w, 64),
            single_stack: sp.alloc(MemKind::Stack, "stack-single", STACK_ENTRIES * 8, 64),
            tests: Tests::default(),
            slot_of,
            sides: Sides::Both,
            tri_form: TriForm::Edges,
            frusta_stats: crate::stats::MftStats::default(),
        }
    }

    /// Reuse the buffers for other rays (at most as many packets as they
    /// were made for): the records are rewritten in place (host side, like
    /// the initial contents) and the counters kept.
    ///
    /// # Panics
    /// If the rays need more packets than the buffer holds.
    pub fn reload(
        &mut self,
        w: usize,
        org: &[[f32; 3]],
        dir: &[[f32; 3]],
        tfar: &[f32],
        slots: Option<&[u32]>,
    ) {
        let seq: Vec<u32>;
        let slots = match slots {
            Some(s) => s,
            None => {
                seq = (0..org.len() as u32).collect();
                &seq
            }
        };
        let recs = packet_records(org, dir, tfar, slots, w);
        let bytes: Vec<u8> = recs.iter().flat_map(|x| x.to_le_bytes()).collect();
        assert!(bytes.len() <= self.rays.len(), "rays fit the packet buffer");
        self.rays.write(0, &bytes);
        self.packets = recs.len() / (row::ROWS * w);
        self.slot_of = vec![usize::MAX; org.len()];
        for (j, &i) in slots.iter().enumerate() {
            if (i as usize) < org.len() {
                self.slot_of[i as usize] = j;
            }
        }
    }

    /// Ray `i`'s lane slot (packet `slot / LANES`, lane `slot % LANES`).
    #[must_use]
    pub fn slot(&self, i: usize) -> usize {
        self.slot_of[i]
    }

    /// Ray `i`'s hit after a kernel ran.
    #[must_use]
    pub fn hit(&self, w: usize, i: usize) -> Hit {
        let j = self.slot_of[i];
        let (p, l) = (j / w, j % w);
        let base = p * packet_bytes(w) + 4 * l;
        Hit::from_record(
            self.rays.f32_at(base + row(w, row::TFAR)),
            self.rays.u32_at(base + row(w, row::PRIM)),
        )
    }
}

/// Which node format a packet kernel walks.
#[derive(Clone, Copy)]
enum Tree<'a> {
    Bvh4(&'a Bvh4Bufs),
    Bvh2(&'a Bvh2Bufs),
}

/// Packet BVH4 (`hybrid`: switch to single rays at few active rays;
/// `shadow`: any hit, a lane stops at its first hit, the packet when all have).
pub fn trace_bvh4<M: Machine>(
    m: &mut M,
    s: &Bvh4Bufs,
    pb: &mut PacketBufs,
    hybrid: bool,
    policy: HitPolicy,
) {
    trace(m, Tree::Bvh4(s), pb, hybrid, policy, None);
}

/// Packet BVH4 (closest hit), every candidate hit judged by `filter`
/// ([`crate::filter`]): a triangle's hits over the packet go to the filter
/// together; the lanes it accepts take the hit and the t_far it set.
pub fn trace_bvh4_filtered<M: Machine>(
    m: &mut M,
    s: &Bvh4Bufs,
    pb: &mut PacketBufs,
    filter: &mut dyn Filter<M>,
) {
    trace(
        m,
        Tree::Bvh4(s),
        pb,
        false,
        HitPolicy::Closest,
        Some(filter),
    );
}

/// Packet BVH2.
pub fn trace_bvh2<M: Machine>(m: &mut M, s: &Bvh2Bufs, pb: &mut PacketBufs, policy: HitPolicy) {
    trace(m, Tree::Bvh2(s), pb, false, policy, None);
}

/// One packet's vector registers.
struct Packet<M: Machine> {
    org: [M::F; 3],
    dir: [M::F; 3],
    idir: [M::F; 3],
    oid: [M::F; 3],
    tnear: M::F,
    tfar: M::F,
}

fn trace<M: Machine>(
    m: &mut M,
    tree: Tree,
    pb: &mut PacketBufs,
    hybrid: bool,
    policy: HitPolicy,
    mut filter: Option<&mut dyn Filter<M>>,
) {
    let w = M::LANES;
    let mut p = m.int(0);
    let np = m.int(pb.packets as i64);
    loop {
        m.region(Region::Traversal);
        let base = m.s_shift(Shift::Shl, p, packet_bytes(w).trailing_zeros());
        let f: Option<(&mut dyn Filter<M>, M::S)> = match filter {
            Some(ref mut f) => Some((&mut **f, p)),
            None => None,
        };
        trace_packet(m, tree, pb, base, hybrid, policy, f);
        p = m.s_addi(p, 1);
        if !m.branch_if(site::PACKETS, Cmp::Lt, p, np) {
            break;
        }
    }
}

fn trace_packet<M: Machine>(
    m: &mut M,
    tree: Tree,
    pb: &mut PacketBufs,
    base: M::S,
    hybrid: bool,
    policy: HitPolicy,
    mut filter: Option<(&mut dyn Filter<M>, M::S)>,
) {
    let w = M::LANES;
    let mut pk = load_packet(m, &pb.rays, base);
    let inf = m.splat(f32::INFINITY);
    // Stack: the sentinel, then the root with the rays' t_near.
    let sentinel = m.int(i64::from(EMPTY_SLOT));
    let root = m.int(match tree {
        Tree::Bvh4(_) => 0,
        Tree::Bvh2(s) => i64::from(s.root),
    });
    let (sn, snear) = (&mut pb.stack_node, &mut pb.stack_near);
    m.s_store(sn, At::off(0), 4, sentinel);
    m.store(snear, At::off(0), inf);
    m.s_store(sn, At::off(4), 4, root);
    m.store(snear, At::off(4 * w), pk.tnear);
    let mut sp = m.int(2);
    let (mut aabb, mut tri_tests) = (0u64, 0u64);
    let sides = pb.sides;
    let leaf_flag = m.int(i64::from(LEAF));
    loop {
        m.region(Region::Traversal);
        sp = m.s_addi(sp, -1);
        let near_off = m.s_shift(Shift::Shl, sp, (4 * w).trailing_zeros());
        let mut cur = m.s_load(&pb.stack_node, At::idx(sp, 4, 0), 4, false);
        let mut cur_d = m.load(&pb.stack_near, At::idx(near_off, 1, 0));
        let done = m.s_cmp(Cmp::Eq, cur, sentinel);
        if m.branch(site::DONE, done) {
            break;
        }
        let active = m.cmp(Cmp::Lt, cur_d, pk.tfar);
        let any = m.any(active);
        if !m.branch(site::CULL, any) {
            pb.tests.culled += 1;
            continue;
        }
        if hybrid {
            let bits = m.movemask(active);
            let cnt = m.s_popcnt(bits);
            let few = m.int(i64::from(SWITCH_THRESHOLD));
            if m.branch_if(site::SWITCH, Cmp::Le, cnt, few) {
                let Tree::Bvh4(s) = tree else {
                    unreachable!("hybrid traversal is BVH4 only")
                };
                single_rays(m, s, pb, (base, bits, cur), policy);
                m.region(Region::Traversal);
                pk.tfar = m.load(&pb.rays, At::idx(base, 1, row(w, row::TFAR)));
                continue;
            }
        }
        down(
            m,
            tree,
            &pk,
            (&mut pb.stack_node, &mut pb.stack_near),
            (&mut pb.tests, &mut aabb),
            (&mut cur, &mut cur_d, &mut sp),
            (sentinel, leaf_flag, inf),
        );
        let done = m.s_cmp(Cmp::Eq, cur, sentinel);
        if m.branch(site::DONE, done) {
            break;
        }
        // Leaf: every ray still in front of its hit against each triangle.
        let valid_leaf = m.cmp(Cmp::Gt, pk.tfar, cur_d);
        pb.tests.leaf += u64::from(m.bits(valid_leaf).count_ones());
        let blocks = match tree {
            Tree::Bvh4(s) => &s.tris,
            Tree::Bvh2(s) => &s.tris,
        };
        leaf(
            m,
            (blocks, &pb.tri_form),
            cur,
            valid_leaf,
            &mut pk,
            &mut pb.rays,
            base,
            (policy, sides),
            &mut tri_tests,
            match filter {
                Some((ref mut f, p)) => Some((&mut **f, p)),
                None => None,
            },
        );
        if policy.is_any() {
            // Done when every lane is occluded (t_far = -1) or padding.
            let zero_v = m.splat(0.0);
            let alive = m.cmp(Cmp::Ge, pk.tfar, zero_v);
            let any = m.any(alive);
            if !m.branch(site::ALIVE, any) {
                break;
            }
        }
    }
    pb.frusta_stats.aabb_tests += aabb;
    pb.frusta_stats.tris_accessed += tri_tests;
    pb.frusta_stats.tris_after_culling += tri_tests;
    pb.frusta_stats.isec_tests += tri_tests;
}

/// The packet of rays at byte `base` of the records, with `org * idir`.
fn load_packet<M: Machine>(m: &mut M, rays: &Buf, base: M::S) -> Packet<M> {
    let w = M::LANES;
    let ld = |m: &mut M, rays: &Buf, r: usize| m.load(rays, At::idx(base, 1, row(w, r)));
    let org = [0, 1, 2].map(|a| ld(m, rays, row::ORG + a));
    let dir = [0, 1, 2].map(|a| ld(m, rays, row::DIR + a));
    let idir = [0, 1, 2].map(|a| ld(m, rays, row::IDIR + a));
    let oid = [0, 1, 2].map(|a| m.mul(org[a], idir[a]));
    let tnear = ld(m, rays, row::TNEAR);
    let tfar = ld(m, rays, row::TFAR);
    Packet::<M> {
        org,
        dir,
        idir,
        oid,
        tnear,
        tfar,
    }
}

/// Hybrid traversal's switch: each active ray (`bits`) of the packet traced
/// alone from node `cur` by the single-ray BVH4 kernel, its record updated.
fn single_rays<M: Machine>(
    m: &mut M,
    s: &Bvh4Bufs,
    pb: &mut PacketBufs,
    (base, bits, cur): (M::S, M::S, M::S),
    policy: HitPolicy,
) {
    let tests = &mut pb.tests;
    let mut bits = bits;
    loop {
        let lane = m.s_tzcnt(bits);
        let k = lane.get() as usize;
        let mut st = RayState::load_packet(m, &pb.rays, base, k);
        walk4(m, s, &mut st, &mut pb.single_stack, cur, tests, policy);
        m.region(Region::SingleRay);
        st.write_packet(m, &mut pb.rays);
        let lm1 = m.s_addi(bits, -1);
        bits = m.s_and(bits, lm1);
        let zero = m.int(0);
        if !m.branch_if(site::SWITCH_RAY, Cmp::Ne, bits, zero) {
            break;
        }
    }
}

/// Down traversal: test the node's children, keep the one any ray reaches
/// first as the next node (`cur`, `cur_d`), push the others, until a leaf
/// or the sentinel.
fn down<M: Machine>(
    m: &mut M,
    tree: Tree,
    pk: &Packet<M>,
    (sn, snear): (&mut Buf, &mut Buf),
    (tests, aabb): (&mut Tests, &mut u64),
    (cur, cur_d, sp): (&mut M::S, &mut M::F, &mut M::S),
    (sentinel, leaf_flag, inf): (M::S, M::S, M::F),
) {
    let w = M::LANES;
    loop {
        let lf = m.s_and(*cur, leaf_flag);
        if m.branch(site::LEAF, lf) {
            break;
        }
        // Ray-node tests: lanes still in front of their hit (counted on the
        // host, as Embree's STAT3 counter, which release builds compile out).
        tests.other += (0..w)
            .filter(|&i| m.lane(pk.tfar, i) > m.lane(*cur_d, i))
            .count() as u64;
        let node = *cur;
        // The node's address, once per node.
        let nb = match tree {
            Tree::Bvh4(_) => m.s_shift(Shift::Shl, node, NODE_BYTES.trailing_zeros()),
            Tree::Bvh2(_) => m.s_shift(Shift::Shl, node, 6),
        };
        // Pop the next node now; a hit child may take its place.
        *sp = m.s_addi(*sp, -1);
        let near_off = m.s_shift(Shift::Shl, *sp, (4 * w).trailing_zeros());
        *cur = m.s_load(sn, At::idx(*sp, 4, 0), 4, false);
        *cur_d = m.load(snear, At::idx(near_off, 1, 0));
        let children: &[usize] = match tree {
            Tree::Bvh4(_) => &[0, 1, 2, 3],
            Tree::Bvh2(_) => &[0, 1],
        };
        for &i in children {
            let (child, lnear, lhit) = match tree {
                Tree::Bvh4(s) => {
                    let child = m.s_load(&s.nodes, At::idx(nb, 1, 96 + 4 * i), 4, false);
                    let empty = m.s_cmp(Cmp::Eq, child, sentinel);
                    if m.branch(site::EMPTY, empty) {
                        break;
                    }
                    // Rows min_x max_x min_y max_y min_z max_z, child i at 4i.
                    let plane = |m: &mut M, r: usize| {
                        m.load_operand(&s.nodes, At::idx(nb, 1, 16 * r + 4 * i), 1)
                    };
                    let (lnear, lhit) = box_test(m, pk, plane);
                    (child, lnear, lhit)
                }
                Tree::Bvh2(s) => {
                    let child = m.s_load(&s.nodes, At::idx(nb, 1, 48 + 4 * i), 4, false);
                    // Per axis [min_l, min_r, max_l, max_r]: min at 4i, max at 8 + 4i.
                    let plane = |m: &mut M, r: usize| {
                        let off = 16 * (r / 2) + 8 * (r % 2) + 4 * i;
                        m.load_operand(&s.nodes, At::idx(nb, 1, off), 1)
                    };
                    let (lnear, lhit) = box_test(m, pk, plane);
                    (child, lnear, lhit)
                }
            };
            *aabb += 1;
            let any = m.any(lhit);
            if !m.branch(site::HIT, any) {
                continue;
            }
            let child_d = m.select(lhit, lnear, inf);
            let closer = m.cmp(Cmp::Lt, child_d, *cur_d);
            let anyc = m.any(closer);
            let (push, push_d) = if m.branch(site::CLOSER, anyc) {
                let old = (*cur, *cur_d);
                *cur = child;
                *cur_d = child_d;
                old
            } else {
                (child, child_d)
            };
            let near_off = m.s_shift(Shift::Shl, *sp, (4 * w).trailing_zeros());
            m.s_store(sn, At::idx(*sp, 4, 0), 4, push);
            m.store(snear, At::idx(near_off, 1, 0), push_d);
            *sp = m.s_addi(*sp, 1);
        }
    }
}

/// One child box against every ray of the packet: (entry distances, hit
/// mask). `plane(m, r)` broadcasts the box's row r (min_x, max_x, min_y,
/// max_y, min_z, max_z) as the fmsub's memory operand (folded on LRBni; a
/// vbroadcastss load on AVX2, as Embree's `msub(node->lower_x[i], ...)`).
fn box_test<M: Machine>(
    m: &mut M,
    pk: &Packet<M>,
    plane: impl FnMut(&mut M, usize) -> M::F,
) -> (M::F, M::K) {
    let slabs = PacketSlabs {
        idir: pk.idir,
        oid: pk.oid,
        tnear: pk.tnear,
        tfar: pk.tfar,
    };
    slab_test(m, &slabs, plane)
}

/// What a packet's box test reads: per axis the inverse directions and
/// origins times them, and each ray's [t_near, t_far].
#[derive(Clone, Copy, Debug)]
pub struct PacketSlabs<F> {
    /// 1 / dir per axis.
    pub idir: [F; 3],
    /// org * idir per axis.
    pub oid: [F; 3],
    /// Entry bound per ray.
    pub tnear: F,
    /// Exit bound per ray (the closest hit so far).
    pub tfar: F,
}

/// The packet kernels' box test (the inner step of their down traversal),
/// also timed alone against hand-written AVX2 (`rt::boxtest::packet_nodes_stream`).
/// Inlined where it is used: as a call, natively, its packet's 8 vectors
/// went through memory on every child box.
#[inline(always)]
pub fn slab_test<M: Machine>(
    m: &mut M,
    pk: &PacketSlabs<M::F>,
    mut plane: impl FnMut(&mut M, usize) -> M::F,
) -> (M::F, M::K) {
    let mut near = pk.tnear;
    let mut far = pk.tfar;
    for a in 0..3 {
        let lo = plane(m, 2 * a);
        let hi = plane(m, 2 * a + 1);
        let t0 = m.fmsub(lo, pk.idir[a], pk.oid[a]);
        let t1 = m.fmsub(hi, pk.idir[a], pk.oid[a]);
        let mn = m.min(t0, t1);
        let mx = m.max(t0, t1);
        near = m.max(near, mn);
        far = m.min(far, mx);
    }
    let hit = m.cmp(Cmp::Le, near, far);
    (near, hit)
}

/// The packet against each triangle of leaf `node`'s block (8 rays vs one
/// broadcast triangle per step), lanes `valid` only; hits are written to the
/// packet record at byte `base` of `rays` with masked stores (memory holds
/// the hits, as in Embree, so the hybrid kernel's single rays see them). A
/// shadow lane that hits gets t_far = -1: it is done.
#[allow(clippy::too_many_arguments)]
fn leaf<M: Machine>(
    m: &mut M,
    (tris, form): (&Buf, &TriForm),
    node: M::S,
    valid: M::K,
    pk: &mut Packet<M>,
    rays: &mut Buf,
    base: M::S,
    (policy, sides): (HitPolicy, Sides),
    tri_tests: &mut u64,
    mut filter: Option<(&mut dyn Filter<M>, M::S)>,
) {
    let w = M::LANES;
    let mut valid = valid;
    m.region(Region::Leaf);
    let mask_idx = m.int(i64::from(!LEAF));
    let blk = m.s_and(node, mask_idx);
    let bytes = m.int(BLOCK_BYTES as i64);
    let bb = m.s_op(isa::SOp::Mul, blk, bytes);
    for j in 0..crate::layout::BLOCK {
        let id = m.s_load(tris, At::idx(bb, 1, 32 * 9 + 4 * j), 4, true);
        let zero = m.int(0);
        if m.branch_if(site::TRI_SLOT, Cmp::Lt, id, zero) {
            break;
        }
        let r = |m: &mut M, k: usize| m.load_bcast(tris, At::idx(bb, 1, 32 * k + 4 * j));
        let (v0, e1, e2) = match form {
            TriForm::Edges => (
                [r(m, 0), r(m, 1), r(m, 2)],
                [r(m, 3), r(m, 4), r(m, 5)],
                [r(m, 6), r(m, 7), r(m, 8)],
            ),
            TriForm::Indexed(t) => {
                let [v0, e1, e2] = indexed_triangle(m, t, id);
                (v0, e1, e2)
            }
        };
        let pf = r(m, 9);
        let prim = m.bits_to_i(pf);
        let blk = Block::<M> { v0, e1, e2, prim };
        *tri_tests += 1;
        let ray = (&pk.org, &pk.dir, pk.tfar);
        let sites = [site::TRI_EDGE, site::TRI];
        let Some(Moller {
            t,
            u: tu,
            v: tv,
            valid: hit,
        }) = moller_sided(m, &blk, ray, sides, Some(valid), sites)
        else {
            continue;
        };
        let at = |r: usize| At::idx(base, 1, row(w, r));
        if let Some((f, packet)) = filter.as_mut() {
            // Embree 3's `IntersectKEpilogM`: the lanes the filter accepts
            // take the hit and its t_far; the others keep theirs.
            let c = CandidateK {
                packet: *packet,
                valid: hit,
                t,
                prim: pf,
            };
            let (acc, t_far) = f.packet(m, c);
            m.region(Region::Leaf);
            pk.tfar = m.select(acc, t_far, pk.tfar);
            m.store_masked(acc, rays, at(row::TFAR), pk.tfar);
            m.store_masked(acc, rays, at(row::U), tu);
            m.store_masked(acc, rays, at(row::V), tv);
            m.store_masked(acc, rays, at(row::PRIM), pf);
            continue;
        }
        if policy.is_any() {
            let done = m.splat(-1.0);
            pk.tfar = m.select(hit, done, pk.tfar);
            m.store_masked(hit, rays, at(row::TFAR), done);
            m.store_masked(hit, rays, at(row::PRIM), pf);
            let miss = m.knot(hit);
            valid = m.kand(valid, miss);
            continue;
        }
        pk.tfar = m.select(hit, t, pk.tfar);
        m.store_masked(hit, rays, at(row::TFAR), t);
        m.store_masked(hit, rays, at(row::U), tu);
        m.store_masked(hit, rays, at(row::V), tv);
        m.store_masked(hit, rays, at(row::PRIM), pf);
    }
}

/// Triangle `id`'s v0 and edges from its vertex indices: three index loads,
/// each vertex's coordinates broadcast (v1 and v2 as the subtractions'
/// memory operands), two edges computed.
fn indexed_triangle<M: Machine>(
    m: &mut M,
    t: &crate::layout::IndexedTris,
    id: M::S,
) -> [[M::F; 3]; 3] {
    // id * 12: id + 2 id, scaled by 4 in the address.
    let twice = m.s_shift(Shift::Shl, id, 1);
    let i3 = m.s_add(id, twice);
    let vert = |m: &mut M, c: usize| {
        let v = m.s_load(&t.idx, At::idx(i3, 4, 4 * c), 4, false);
        m.s_shift(Shift::Shl, v, crate::layout::VERTEX_BYTES.trailing_zeros())
    };
    let (a, b, c) = (vert(m, 0), vert(m, 1), vert(m, 2));
    let v0 = [0, 1, 2].map(|k| m.load_bcast(&t.verts, At::idx(a, 1, 4 * k)));
    let edge = |m: &mut M, at: M::S, k: usize| {
        let p = m.load_operand(&t.verts, At::idx(at, 1, 4 * k), 1);
        m.sub(p, v0[k])
    };
    let e1 = [0, 1, 2].map(|k| edge(m, b, k));
    let e2 = [0, 1, 2].map(|k| edge(m, c, k));
    [v0, e1, e2]
}
