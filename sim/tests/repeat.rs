//! `sim::repeat`, the loop traces `rtsim sim --iterations` times: a
//! loop-carried value is the previous iteration's (a store's address too),
//! ready from the start in the first iteration, and every machine times
//! any valid loop trace without a panic (a property test over seeded
//! random loop bodies).

use isa::rng::Rng;
use isa::trace_text::parse;
use isa::Trace;
use sim::{repeat, simulate, MachineConfig, SimOptions};

/// A loop body (a source may be defined later in it: loop-carried).
fn body(isa: &str, text: &str) -> Result<Trace, String> {
    let t = parse(&format!(
        ".trace 1\n.isa {isa}\n.mem 0 other d 0x20000000 16777216\n{text}"
    ))
    .map_err(|e| e.to_string())?;
    t.validate_loop()?;
    Ok(t)
}

/// The op of iteration `k` at body position `i` (the body has `len` ops).
fn at(t: &Trace, len: usize, k: usize, i: usize) -> isa::Op {
    t.ops[k * len + i]
}

#[test]
fn a_loop_carried_store_address_is_the_previous_iterations_value() {
    // The store's address %2 is defined after it: loop-carried.
    let body = "%1 = alu\nstore %1 @d+0x40:8 addr=%2\n%2 = alu %2\n";
    let b = self::body("avx2", body).unwrap();
    let t = repeat(&b, 4);
    t.validate().unwrap();
    // First iteration: the carried address is ready, so the store has no
    // address source; its one source is its data, this iteration's %1.
    let first = at(&t, 3, 0, 1);
    assert!(!first.has_addr_src());
    assert_eq!(first.sources(), &[at(&t, 3, 0, 0).dst]);
    for k in 1..4 {
        let st = at(&t, 3, k, 1);
        assert!(st.has_addr_src(), "iteration {k}");
        // Address: the previous iteration's %2; data: this iteration's %1.
        assert_eq!(
            st.sources(),
            &[at(&t, 3, k - 1, 2).dst, at(&t, 3, k, 0).dst]
        );
        // The carried chain reads the previous iteration's %2.
        assert_eq!(at(&t, 3, k, 2).sources(), &[at(&t, 3, k - 1, 2).dst]);
    }
    let m = MachineConfig::load("haswell-i7-4750hq").unwrap();
    simulate(&m, &[&t], &SimOptions::default()).unwrap();
    // A store flagged with an address source but holding none (what the
    // first iteration once made) is no valid trace.
    let mut bad = t.clone();
    bad.ops[4].nsrc = 0;
    assert!(bad.ops[4].has_addr_src());
    assert!(bad.validate().unwrap_err().contains("address source"));
}

/// A random loop body of `n` ops: ALU ops, loads and stores over a few
/// lines, sources drawn from every value id of the body (so some are
/// defined later: loop-carried), stores with and without an address source.
fn random_body(r: &mut Rng, n: usize) -> String {
    // Op kinds first (0: store, 1: load, else ALU), so sources name only
    // values the body defines; at least one ALU op defines a value.
    let mut kinds: Vec<u64> = (0..n).map(|_| r.below(4)).collect();
    kinds[0] = 2;
    let ids = kinds.iter().filter(|&&k| k != 0).count() as u64;
    let src = |r: &mut Rng| format!("%{}", 1 + r.below(ids));
    let mut s = String::new();
    let mut next = 0;
    for k in kinds {
        let off = 8 * r.below(64);
        match k {
            0 => {
                let data = src(r);
                if r.below(2) == 0 {
                    let a = src(r);
                    s.push_str(&format!("store {data} @d+{off:#x}:8 addr={a}\n"));
                } else {
                    s.push_str(&format!("store {data} @d+{off:#x}:8\n"));
                }
            }
            1 => {
                next += 1;
                let a = src(r);
                s.push_str(&format!("%{next} = load {a} @d+{off:#x}:8\n"));
            }
            _ => {
                next += 1;
                let (a, b) = (src(r), src(r));
                s.push_str(&format!("%{next} = alu {a} {b}\n"));
            }
        }
    }
    s
}

#[test]
fn random_loop_traces_repeat_and_time_without_a_panic() {
    let machines: Vec<MachineConfig> = ["haswell-i7-4750hq", "core2-q6600", "larrabee", "zen3"]
        .iter()
        .map(|n| MachineConfig::load(n).unwrap())
        .collect();
    let mut r = Rng::new(56);
    let (mut timed, mut carried_addresses) = (0, 0);
    for case in 0..300 {
        let n = 1 + r.below(12) as usize;
        let text = random_body(&mut r, n);
        for m in &machines {
            let b = body(&m.isa, &text).unwrap_or_else(|e| panic!("{e}\n{text}"));
            let iterations = 1 + r.below(40) as usize;
            let t = repeat(&b, iterations);
            t.validate()
                .unwrap_or_else(|e| panic!("case {case}: {e}\n{text}"));
            // Every store's address source is an earlier value.
            for (i, op) in t.ops.iter().enumerate() {
                if op.has_addr_src() {
                    let a = op.sources()[0];
                    let from = t.ops[..i].iter().rposition(|o| o.dst == a);
                    let from = from.unwrap_or_else(|| {
                        panic!("case {case}: op {i}'s address {a:?} is no earlier value\n{text}")
                    });
                    // Carried: defined at or after the store's body position,
                    // so in the iteration before.
                    let len = b.ops.len();
                    if from % len >= i % len {
                        assert_eq!(from / len + 1, i / len, "case {case}\n{text}");
                        carried_addresses += 1;
                    }
                }
            }
            simulate(m, &[&t], &SimOptions::default())
                .unwrap_or_else(|e| panic!("case {case} on {}: {e}\n{text}", m.name));
            timed += 1;
        }
    }
    // Not vacuous: many bodies carry a store's address.
    assert_eq!(timed, 1200);
    assert!(
        carried_addresses > 100,
        "{carried_addresses} carried addresses"
    );
}
