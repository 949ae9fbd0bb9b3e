//! One loop natively on this host and on the model of it, side by side: a
//! synthetic single-ray traversal of the shape of single-ray BVH4's node
//! step (6 plane loads folded into FMAs, min/max, a compare, its mask to a
//! register, a bit scan, the child's load), 6 nodes a ray, every ray the
//! same path (all L1 hits, every branch predictable). Each ray runs free,
//! or serialised: its root made to depend on the previous ray's answer
//! (`and reg, 0`, not a zero idiom), so the serialised time is the ray's
//! dependent chain and serialised / free is how much the core overlaps
//! successive rays. The model runs the same ops as a hand-written trace
//! (`isa::trace_text`), warmed, on the machine given (default `zen4`).
//! Each shape runs again with 16 to 48 integer ops (`lea`) added a node,
//! reading the node's index or a register off the chain: how overlap falls
//! as a ray's instructions grow towards a compiled kernel's, on the host
//! and on the model.
//!
//! Run: `cargo bench -p sim --bench host_chain [-- MACHINE [GHZ]]` (the
//! host half on x86-64 Linux with AVX2 and FMA; GHZ the host's clock for
//! its cycles, by default measured with a dependent vaddps chain as
//! `cargo bench -p isa --bench host_pipes` does). Results, with the
//! machine, are in `rt/benches/RESULTS.md`.

use sim::{MachineConfig, Session};

/// Node tests per ray.
const DEPTH: usize = 6;
/// Rays in the model's trace.
const MODEL_RAYS: usize = 2000;

/// Appends `%n = op` and gives `n`.
struct Ops {
    lines: Vec<String>,
    n: usize,
}

impl Ops {
    fn v(&mut self, op: String) -> usize {
        self.n += 1;
        self.lines.push(format!("%{} = {op}", self.n));
        self.n
    }
    fn branch(&mut self, on: usize, site: u32, taken: bool) {
        let t = if taken { "taken" } else { "not-taken" };
        self.lines.push(format!("branch %{on} site={site} {t}"));
    }
}

/// One node test of the host loop at node `k` (address from `node`), with
/// the ray's broadcasts `rv`: the node's address and its hit mask.
fn node_ops(o: &mut Ops, k: usize, node: usize, rv: &[usize], fill: Fill) -> (usize, usize) {
    let a = o.v(format!("alu %{node}"));
    for _ in 0..fill.per_node {
        match fill.on_chain {
            true => o.v(format!("alu %{node}")),
            false => o.v("alu".into()),
        };
    }
    let c = o.v(format!("cmp %{a}"));
    o.branch(c, 1, false);
    let t: Vec<usize> = (0..6)
        .map(|i| {
            let ld = o.v(format!("vloadfold %{a} @n+0x{:x}:16", 128 * k + 16 * i));
            o.v(format!("vfma %{ld} %{} %{}", rv[i / 2], rv[4 + i / 2]))
        })
        .collect();
    let m1 = o.v(format!("vminmax %{} %{}", t[0], t[2]));
    let m2 = o.v(format!("vminmax %{} %{}", t[4], rv[3]));
    let tn = o.v(format!("vminmax %{m1} %{m2}"));
    let f1 = o.v(format!("vminmax %{} %{}", t[1], t[3]));
    let f2 = o.v(format!("vminmax %{} %{}", t[5], rv[7]));
    let tf = o.v(format!("vminmax %{f1} %{f2}"));
    let hit = o.v(format!("vcmp %{tn} %{tf}"));
    let bits = o.v(format!("movmsk %{hit}"));
    let c = o.v(format!("cmp %{bits}"));
    o.branch(c, 2, false);
    (a, bits)
}

/// The child in the lowest set bit of `bits` at node `k` (address `a`),
/// slot `slot` as the host finds it.
fn child_ops(o: &mut Ops, k: usize, a: usize, bits: usize, slot: usize) -> usize {
    let tz = o.v(format!("bitcnt %{bits}"));
    o.v(format!(
        "load %{tz} %{a} @n+0x{:x}:4",
        128 * k + 96 + 4 * slot
    ))
}

/// Integer ops added to every node test (one `lea` each on the host), as
/// the instructions a compiled kernel runs beyond the node step's own
/// (address arithmetic, bounds checks, bookkeeping): each reads the node's
/// index (`on_chain`, so it waits for the node test before it) or a
/// register off the chain.
#[derive(Clone, Copy)]
struct Fill {
    per_node: usize,
    on_chain: bool,
}

/// The fillers a run sweeps: none, then 8 to 48 a node on and off the
/// chain (48 a node brings the loop to about the twin's 462 instructions a
/// ray).
const FILLS: [usize; 4] = [0, 16, 32, 48];

/// Which nodes a ray visits: a chain of [`DEPTH`] nodes, or a tree whose
/// root hits two children, the first descended (nodes 1, 2, 3), the second
/// pushed and popped after that subtree ends (nodes 4, 5): [`DEPTH`] node
/// tests either way, the longest dependent path 4 nodes in the tree.
#[derive(Clone, Copy, PartialEq)]
enum Shape {
    Chain,
    Tree,
}

/// Per node of `shape`: its hit slots' children (the first descended, a
/// second pushed); a child of [`DEPTH`] or more ends the descent.
fn children(shape: Shape, k: usize) -> &'static [u32] {
    match (shape, k) {
        (Shape::Chain, 0) => &[1],
        (Shape::Chain, 1) => &[2],
        (Shape::Chain, 2) => &[3],
        (Shape::Chain, 3) => &[4],
        (Shape::Chain, 4) => &[5],
        (Shape::Tree, 0) => &[1, 4],
        (Shape::Tree, 1) => &[2],
        (Shape::Tree, 2) => &[3],
        (Shape::Tree, 4) => &[5],
        _ => &[DEPTH as u32],
    }
}

/// The sum of the first children a ray of `shape` visits (what the host
/// loop returns), walked as the loop walks.
fn first_children_sum(shape: Shape) -> u32 {
    let (mut stack, mut sum) = (vec![0usize], 0);
    while let Some(mut k) = stack.pop() {
        loop {
            let kids = children(shape, k);
            if let Some(&second) = kids.get(1) {
                stack.push(second as usize);
            }
            sum += kids[0];
            if kids[0] as usize >= DEPTH {
                break;
            }
            k = kids[0] as usize;
        }
    }
    sum
}

/// The model's trace of `rays` rays of `shape`, free or serialised: the
/// host loop's ops in its order (pop, descend, push the second child).
fn trace_text(shape: Shape, rays: usize, serial: bool, fill: Fill) -> String {
    let mut o = Ops {
        lines: vec![
            ".trace 1".into(),
            ".isa avx2".into(),
            ".mem 0 nodes n 0x10000000 65536".into(),
            ".mem 1 rays r 0x20000000 4096".into(),
            ".mem 2 stack s 0x30000000 4096".into(),
        ],
        n: 0,
    };
    let mut prev: Option<usize> = None;
    for _ in 0..rays {
        let root = match prev {
            Some(p) if serial => o.v(format!("alu %{p}")),
            _ => o.v("alu".into()),
        };
        let rv: Vec<usize> = (0..8)
            .map(|i| o.v(format!("vloadbcast @r+0x{:x}:4", 4 * i)))
            .collect();
        o.lines.push(format!("store %{root} @s+0x0:4"));
        // (node index, the value naming it) of the stack's entries.
        let mut stack = vec![0usize];
        let mut acc: Option<usize> = None;
        while let Some(k0) = stack.pop() {
            let c = o.v("cmp".into());
            o.branch(c, 6, true);
            let mut node = o.v(format!("load @s+0x{:x}:4", 4 * stack.len()));
            let mut k = k0;
            loop {
                let (a, bits) = node_ops(&mut o, k, node, &rv, fill);
                let kids = children(shape, k);
                let first = child_ops(&mut o, k, a, bits, 0);
                let rest = o.v(format!("alu %{bits}"));
                let c = o.v(format!("cmp %{rest}"));
                o.branch(c, 5, kids.len() > 1);
                if kids.len() > 1 {
                    let second = child_ops(&mut o, k, a, rest, 1);
                    o.lines
                        .push(format!("store %{second} @s+0x{:x}:4", 4 * stack.len()));
                    stack.push(kids[1] as usize);
                }
                let sum = acc.map_or(format!("alu %{first}"), |x| format!("alu %{first} %{x}"));
                acc = Some(o.v(sum));
                let c = o.v(format!("cmp %{first}"));
                let end = kids[0] as usize >= DEPTH;
                o.branch(c, 3, end);
                if end {
                    break;
                }
                (node, k) = (first, kids[0] as usize);
            }
        }
        prev = acc;
        let c = o.v("cmp".into());
        o.branch(c, 4, true);
    }
    o.lines.join("\n")
}

/// The model's ops and cycles a ray of `shape` with `fill`: ops, cycles
/// free, cycles serialised.
fn model(m: &MachineConfig, shape: Shape, fill: Fill) -> (f64, f64, f64) {
    let run = |serial| {
        let text = trace_text(shape, MODEL_RAYS, serial, fill);
        let t = isa::trace_text::parse(&text).expect("trace");
        let mut s = Session::new(m);
        s.warm(&[(0, &t)]).expect("warm");
        let st = s.timed(&[(0, &t)]).expect("timed");
        let per_ray = |x: u64| x as f64 / MODEL_RAYS as f64;
        (per_ray(st.ops), per_ray(st.cycles))
    };
    let ((ops, free), (_, serial)) = (run(false), run(true));
    (ops, free, serial)
}

#[cfg(all(target_arch = "x86_64", target_os = "linux"))]
mod host {
    use super::{Fill, Shape, DEPTH};
    use std::arch::x86_64::*;
    use std::time::Instant;

    /// Rays per timing.
    const RAYS: usize = 1 << 20;

    /// A node: 6 rows of 4 planes (x lo, x hi, y lo, y hi, z lo, z hi)
    /// and 4 child indices.
    #[repr(C, align(64))]
    #[derive(Clone, Copy)]
    struct Node {
        rows: [[f32; 4]; 6],
        child: [u32; 4],
        pad: [u32; 4],
    }

    /// Nodes 0..=DEPTH of `shape`: per node, its hit slots a box [-1, 1]^3
    /// holding the children [`super::children`] gives, the other slots a
    /// box the ray misses (y in [100, 101]).
    fn nodes(shape: Shape) -> Vec<Node> {
        (0..=DEPTH)
            .map(|k| {
                let kids = super::children(shape, k);
                let (mut rows, mut child) = (
                    [
                        [-1.0f32; 4],
                        [1.0; 4],
                        [-1.0; 4],
                        [1.0; 4],
                        [-1.0; 4],
                        [1.0; 4],
                    ],
                    [0u32; 4],
                );
                for s in 0..4 {
                    match kids.get(s) {
                        Some(&c) => child[s] = c,
                        None => (rows[2][s], rows[3][s]) = (100.0, 101.0),
                    }
                }
                Node {
                    rows,
                    child,
                    pad: [0; 4],
                }
            })
            .collect()
    }

    /// One ray from node `start` as the single-ray kernel walks: pop, then
    /// descend into the first hit child, pushing a second: the sum of the
    /// first children it visits.
    /// `K` fillers (`lea`) reading the node's index `node` (`ON`) or a
    /// register off the chain.
    #[inline(always)]
    fn fill<const K: usize, const ON: bool>(node: usize) {
        if K == 0 {
            return;
        }
        let src = if ON { node } else { 0 };
        // SAFETY: register operations only.
        unsafe {
            std::arch::asm!(
                ".rept {k}", "lea {t}, [{n} + 1]", ".endr",
                k = const K, t = out(reg) _, n = in(reg) src,
                options(nomem, nostack, preserves_flags)
            )
        };
    }

    #[target_feature(enable = "avx2,fma")]
    unsafe fn walk<const K: usize, const ON: bool>(
        nodes: &[Node],
        ray: &[f32; 8],
        start: usize,
    ) -> u32 {
        let b = |x: f32| _mm_set1_ps(x);
        let idir = [b(ray[0]), b(ray[1]), b(ray[2])];
        let oid = [b(ray[4]), b(ray[5]), b(ray[6])];
        let (tnear, tfar) = (b(ray[3]), b(ray[7]));
        let (mut stack, mut sp, mut acc) = ([0usize; 8], 1usize, 0u32);
        stack[0] = start;
        while sp > 0 {
            sp -= 1;
            let mut node = stack[sp];
            loop {
                let n = &nodes[node];
                fill::<K, ON>(node);
                let p = n.rows.as_ptr() as *const f32;
                let t =
                    |i: usize| _mm_fmsub_ps(_mm_loadu_ps(p.add(4 * i)), idir[i / 2], oid[i / 2]);
                let tn = _mm_max_ps(_mm_max_ps(t(0), t(2)), _mm_max_ps(t(4), tnear));
                let tf = _mm_min_ps(_mm_min_ps(t(1), t(3)), _mm_min_ps(t(5), tfar));
                let bits = _mm_movemask_ps(_mm_cmple_ps(tn, tf)) as u32;
                if bits == 0 {
                    break;
                }
                let first = n.child[bits.trailing_zeros() as usize] as usize;
                let rest = bits & (bits - 1);
                if rest != 0 {
                    stack[sp] = n.child[rest.trailing_zeros() as usize] as usize;
                    sp += 1;
                }
                acc = acc.wrapping_add(first as u32);
                if first >= DEPTH {
                    break;
                }
                node = first;
            }
        }
        acc
    }

    /// Nanoseconds a ray of `shape` with `fill`, free or serialised.
    pub fn ns_per_ray(shape: Shape, serial: bool, fill: Fill) -> f64 {
        match (fill.per_node, fill.on_chain) {
            (0, _) => timed::<0, true>(shape, serial),
            (16, true) => timed::<16, true>(shape, serial),
            (32, true) => timed::<32, true>(shape, serial),
            (48, true) => timed::<48, true>(shape, serial),
            (16, false) => timed::<16, false>(shape, serial),
            (32, false) => timed::<32, false>(shape, serial),
            (48, false) => timed::<48, false>(shape, serial),
            _ => unreachable!("a fill not in FILLS"),
        }
    }

    /// Nanoseconds a ray of `shape` with `K` fillers a node, best of 5:
    /// free or serialised.
    fn timed<const K: usize, const ON: bool>(shape: Shape, serial: bool) -> f64 {
        let nodes = nodes(shape);
        // From x = -5 along +x through every box.
        let ray = [1.0f32, 1e30, 1e30, 0.0, -5.0, 0.1e30, 0.2e30, 1e30];
        (0..5)
            .map(|_| {
                let t = Instant::now();
                let mut prev = 0u32;
                for _ in 0..RAYS {
                    let start = if serial {
                        let z: u32;
                        // SAFETY: a register operation.
                        unsafe { std::arch::asm!("and {0:e}, 0", inout(reg) prev => z) };
                        z as usize
                    } else {
                        0
                    };
                    // SAFETY: AVX2 and FMA checked by the caller.
                    prev = unsafe { walk::<K, ON>(&nodes, std::hint::black_box(&ray), start) };
                }
                let secs = t.elapsed().as_secs_f64();
                assert_eq!(
                    prev,
                    super::first_children_sum(shape),
                    "the host loop's path"
                );
                secs
            })
            .fold(f64::MAX, f64::min)
            * 1e9
            / RAYS as f64
    }

    /// A dependent vaddps chain's `n` adds.
    #[target_feature(enable = "avx2")]
    unsafe fn chain(n: usize) -> __m256 {
        let (mut a, one) = (_mm256_set1_ps(0.5), _mm256_set1_ps(1.0));
        for _ in 0..n {
            a = _mm256_add_ps(a, one);
            std::arch::asm!("/* {} */", inout(ymm_reg) a);
        }
        a
    }

    /// The clock from the chain (vaddps latency 3 on every AVX2 core the
    /// configs model), in GHz.
    pub fn clock_ghz() -> f64 {
        let n = 50_000_000;
        let best = (0..5)
            .map(|_| {
                let t = Instant::now();
                // SAFETY: AVX2 checked by the caller.
                std::hint::black_box(unsafe { chain(n) });
                t.elapsed().as_secs_f64()
            })
            .fold(f64::MAX, f64::min);
        3.0 * n as f64 / best / 1e9
    }
}

fn main() {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| a != "--bench")
        .collect();
    let name = args.first().map_or("zen4", String::as_str);
    let m = match MachineConfig::load(name) {
        Ok(m) => m,
        Err(e) => {
            eprintln!("host_chain: {e}");
            std::process::exit(2);
        }
    };
    let shapes = [(Shape::Chain, "chain"), (Shape::Tree, "tree")];
    let fills: Vec<(Fill, String)> = FILLS
        .iter()
        .flat_map(|&per_node| {
            let on = Fill {
                per_node,
                on_chain: true,
            };
            let off = Fill {
                on_chain: false,
                ..on
            };
            let name = |f: &str| format!("{per_node} fillers a node {f}");
            match per_node {
                0 => vec![(on, "no fillers".to_string())],
                _ => vec![(on, name("on the chain")), (off, name("off it"))],
            }
        })
        .collect();
    for (shape, what) in shapes {
        for (fill, how) in &fills {
            let (ops, free, serial) = model(&m, shape, *fill);
            println!(
                "{what}, {how}: model {name}: {ops:.0} ops a ray, {free:.1} cycles a ray free, \
                 {serial:.1} serialised (overlap {:.2}x)",
                serial / free
            );
        }
    }
    #[cfg(all(target_arch = "x86_64", target_os = "linux"))]
    if is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma") {
        let ghz = (args.get(1).and_then(|g| g.parse().ok())).unwrap_or_else(host::clock_ghz);
        for (shape, what) in shapes {
            for (fill, how) in &fills {
                let f = host::ns_per_ray(shape, false, *fill) * ghz;
                let s = host::ns_per_ray(shape, true, *fill) * ghz;
                println!(
                    "{what}, {how}: host at {ghz:.2} GHz: {f:.1} cycles a ray free, \
                     {s:.1} serialised (overlap {:.2}x)",
                    s / f
                );
            }
        }
        return;
    }
    println!("host: x86-64 Linux with AVX2 and FMA only");
}
