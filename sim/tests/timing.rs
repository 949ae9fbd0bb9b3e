//! Exact-timing tests: a unit between mock neighbours, asserting the exact
//! cycles the config implies. Traces are written by hand in the text form.
//!
//! Timing conventions of the out-of-order model: the first op dispatches in
//! cycle 0, issues no earlier than the next cycle, completes `lat` cycles after
//! issue and retires no earlier than it completes; a run's cycles are the last
//! retirement's cycle.

use isa::trace_text::parse;
use isa::{Addr, LineAddr, MemId, Trace};
use sim::{simulate, Fidelity, Hierarchy, MachineConfig, SimOptions};

fn hsw() -> MachineConfig {
    MachineConfig::load("haswell-i7-4750hq").unwrap()
}

fn trace(isa: &str, body: &str) -> Trace {
    let t = parse(&format!(".trace 1\n.isa {isa}\n.mem 0 lut isa-lut 0x10000000 8192\n.mem 1 other d 0x20000000 16777216\n{body}")).unwrap();
    t.validate().unwrap();
    t
}

fn cycles(m: &MachineConfig, body: &str) -> u64 {
    let t = trace(&m.isa, body);
    simulate(m, &[&t], &SimOptions::default()).unwrap().cycles
}

#[test]
fn dependent_and_independent_pairs() {
    let m = hsw();
    // issue 1, +5 latency
    assert_eq!(cycles(&m, "%1 = vfma\n"), 6);
    // the second waits for the first: 6 + 5
    assert_eq!(cycles(&m, "%1 = vfma\n%2 = vfma %1\n"), 11);
    // both issue in cycle 1 on p0 and p1
    assert_eq!(cycles(&m, "%1 = vfma\n%2 = vfma\n"), 6);
}

#[test]
fn a_port_conflict_serialises() {
    let m = hsw();
    // vaddps has only p1: the second issues a cycle later (done 4 and 5).
    assert_eq!(cycles(&m, "%1 = vadd\n%2 = vadd\n"), 5);
    // vmulps has p0 and p1: both in cycle 1.
    assert_eq!(cycles(&m, "%1 = vmul\n%2 = vmul\n"), 6);
    // A non-pipelined divide keeps p0 busy 14 cycles: the second starts at 15.
    assert_eq!(cycles(&m, "%1 = vdiv\n%2 = vdiv\n"), 15 + 21);
}

#[test]
fn every_cache_level_hit_latency() {
    let m = hsw_untranslated();
    let mut h = Hierarchy::new(&m, 1);
    let line = 1000u64;
    let at = |l: u64| Addr(l * 64).0;
    let r = MemId(1);
    // Cold: every level misses, DRAM latency.
    assert_eq!(h.access(0, at(line), false, r, 0).latency, 196);
    assert_eq!(h.access(0, at(line), false, r, 0).latency, 4, "L1 hit");
    // 8 more lines in the same L1 set (64 sets): the line falls to L2.
    for k in 1..=8 {
        h.access(0, at(line + 64 * k), false, r, 0);
    }
    assert_eq!(h.access(0, at(line), false, r, 0).latency, 12, "L2 hit");
    // 12 more lines in its L2 set (512 sets; 8 ways): it falls to L3. (Some of
    // them hit in L1 and do not refresh their L2 LRU position, hence more than 8.)
    for k in 1..=12 {
        h.access(0, at(line + 512 * k), false, r, 0);
    }
    assert_eq!(h.access(0, at(line), false, r, 0).latency, 36, "L3 hit");
    // 12 more in its L3 set (8192 sets): it falls to the eDRAM L4.
    for k in 1..=12 {
        h.access(0, at(line + 8192 * k), false, r, 0);
    }
    assert_eq!(h.access(0, at(line), false, r, 0).latency, 110, "L4 hit");
    let _ = LineAddr(0);
}

#[test]
fn an_access_wider_than_a_line_touches_every_line_it_spans() {
    let m = hsw_untranslated();
    let mut h = Hierarchy::new(&m, 1);
    let r = MemId(1);
    let base = 2000 * 64;
    // A 32-lane vector (128 bytes) spans two lines, unaligned three; a
    // 32-byte access one line, even across a boundary (no split modelled).
    assert_eq!(h.span(base, 128).collect::<Vec<_>>(), [base, base + 64]);
    assert_eq!(h.span(base + 32, 128).count(), 3);
    assert_eq!(h.span(base + 48, 32).collect::<Vec<_>>(), [base + 48]);
    // Cold: both lines miss at once (two miss slots); the second's data
    // queues behind the first's on the DRAM bus (196 alone, see above).
    let mut mshrs = sim::memory::Mshrs::new(m.mshrs as usize);
    assert_eq!(h.load_span(0, (base, 128), r, 0, &mut mshrs), (202, 4));
    // Both are in the L1 now.
    assert_eq!(h.access(0, base + 64, false, r, 0).latency, 4);
    assert_eq!(h.load_span(0, (base, 128), r, 300, &mut mshrs), (304, 0));
    // A wide store writes both lines.
    h.store_span(0, (base + 4096, 128), r, 400);
    assert_eq!(h.access(0, base + 4096 + 64, false, r, 0).latency, 4);
}

#[test]
fn a_mispredicted_branch_costs_resolution_plus_penalty() {
    let m = hsw();
    // alu: issue 1, done 2; the compare macro-fuses with the branch: one uop
    // on p06 that issues when the alu's value is ready (2), done 3.
    // Predicted not-taken (counters start weakly not-taken) but taken: fetch
    // resumes at 3 + 15 = 18; the alu after it issues 19, done 20.
    assert_eq!(
        cycles(
            &m,
            "%1 = alu\n%2 = cmp %1\nbranch %2 site=1 taken\n%3 = alu\n"
        ),
        20
    );
    // Correctly predicted: the last alu finishes at 2, the branch retires at 3.
    assert_eq!(
        cycles(
            &m,
            "%1 = alu\n%2 = cmp %1\nbranch %2 site=1 not-taken\n%3 = alu\n"
        ),
        3
    );
}

#[test]
fn a_full_rob_stalls_dispatch() {
    let mut body = String::from("%1 = vdiv\n");
    // Fillers on p5 only, so they never take the imuls' port p1.
    for i in 2..=8 {
        body.push_str(&format!("%{i} = vshuf\n"));
    }
    body.push_str("%9 = imul\n");
    for i in 10..=18 {
        body.push_str(&format!("%{i} = imul %{}\n", i - 1));
    }
    // ROB 192: the imul chain dispatches in cycle 2, issues 3, ends 3 + 10 x 3 = 33.
    assert_eq!(cycles(&hsw(), &body), 33);
    // ROB 8: the chain's first op waits for the divide to retire (22), issues 23, ends 53.
    let small = hsw()
        .with_sets(&["core.rob=8".into(), "core.scheduler=8".into()])
        .unwrap();
    assert_eq!(cycles(&small, &body), 53);
}

#[test]
fn the_outstanding_miss_limit_queues_misses() {
    let fast = |mshrs: u32| {
        hsw_untranslated()
            .with_sets(&[
                format!("mshrs={mshrs}"),
                "dram.bandwidth_gbs=1000000".into(),
                "prefetch=\"None\"".into(),
            ])
            .unwrap()
    };
    let body = "%1 = load @d+0x0:8\n%2 = load @d+0x10000:8\n%3 = load @d+0x20000:8\n%4 = load @d+0x30000:8\n";
    // Two load ports: loads issue in cycles 1, 1, 2, 2; each misses to DRAM (196).
    assert_eq!(cycles(&fast(10), body), 2 + 196);
    // Two miss slots: the last two wait for the first two (197), then 196 more.
    assert_eq!(cycles(&fast(2), body), 197 + 196);
}

#[test]
fn store_to_load_forwarding() {
    let m = hsw();
    // Store issues 1 (data ready at dispatch + 1); the load of the same bytes
    // gets the data after the forwarding latency (5) instead of the cache.
    assert_eq!(
        cycles(&m, "%1 = alu\nstore %1 @d+0x40:8\n%2 = load @d+0x40:8\n"),
        2 + 5
    );
}

fn larrabee() -> MachineConfig {
    MachineConfig::load("larrabee").unwrap()
}

fn threads(m: &MachineConfig, bodies: &[&str]) -> u64 {
    let ts: Vec<Trace> = bodies.iter().map(|b| trace(&m.isa, b)).collect();
    let refs: Vec<&Trace> = ts.iter().collect();
    simulate(m, &refs, &SimOptions::default()).unwrap().cycles
}

#[test]
fn in_order_threads_hide_latency() {
    let m = larrabee();
    let chain = "%1 = vfma\n%2 = vfma %1\n%3 = vfma %2\n%4 = vfma %3\n";
    // One thread: issues at 0, 4, 8, 12 (stall on use), done 16.
    assert_eq!(threads(&m, &[chain]), 16);
    // Two threads: the second fills the first's stalls (1, 5, 9, 13): done 17, not 32.
    assert_eq!(threads(&m, &[chain, chain]), 17);
}

#[test]
fn in_order_thread_cannot_issue_back_to_back() {
    let m = larrabee();
    let indep = "%1 = vfma\n%2 = vfma\n%3 = vfma\n%4 = vfma\n";
    // Vector ops use the U pipe only, one per cycle, and one thread issues every
    // other cycle: 0, 2, 4, 6, done 10.
    assert_eq!(threads(&m, &[indep]), 10);
    // Two threads alternate: 0..7, done 11.
    assert_eq!(threads(&m, &[indep, indep]), 11);
    // Without the rule, one thread issues every cycle: 0..3, done 7.
    let free = m.with_sets(&["core.no_back_to_back=false".into()]).unwrap();
    assert_eq!(threads(&free, &[indep]), 7);
    // Scalar ops pair in U and V: two per issue cycle.
    assert_eq!(
        threads(&free, &["%1 = alu\n%2 = alu\n%3 = alu\n%4 = alu\n"]),
        2
    );
}

#[test]
fn wrong_flavour_and_too_many_traces_are_errors() {
    let m = hsw();
    let t = trace("lrb16", "%1 = vfma\n");
    assert!(simulate(&m, &[&t], &SimOptions::default())
        .unwrap_err()
        .contains("lrb16"));
    let t = trace("avx2", "%1 = vfma\n");
    let five = vec![&t; 5];
    assert!(simulate(&m, &five, &SimOptions::default()).is_err());
    let opt = SimOptions {
        fidelity: Fidelity::Counts,
        ..SimOptions::default()
    };
    assert_eq!(simulate(&m, &[&t], &opt).unwrap().ops, 1);
}

#[test]
fn scheduler_entries_free_when_their_uop_issues() {
    // A 2-entry scheduler: a divide, an op waiting on it, then an independent
    // dependent chain of four FMAs (5 cycles each).
    let m = hsw().with_sets(&["core.scheduler=2".into()]).unwrap();
    let body = "%1 = vdiv\n%2 = vfma %1\n%3 = vfma\n%4 = vfma %3\n%5 = vfma %4\n%6 = vfma %5\n";
    // The divide issues in cycle 1 (done 22); its user holds an entry until it
    // issues in 22 (done 27). The chain takes the other entry as each op
    // issues: its ops dispatch in cycles 1, 2, 7 and 12, complete in 7, 12,
    // 17 and 22, and retire behind the divide's user, which retires in 27
    // with three of them; 4 retire a cycle, so the last retires in 28.
    // Entries freed in program order would hold the chain's second op until
    // the divide's user issues (dispatch 22): its last FMA would complete in
    // 38 and retire in 38.
    assert_eq!(cycles(&m, body), 28);
    // With the full scheduler nothing waits for an entry: the same 28.
    assert_eq!(cycles(&hsw(), body), 28);
}

/// A body after a prefix that brings line `d+0x0` into L1 and waits for it.
fn warm(body: &str) -> String {
    format!("%100 = vload @d+0x0:64\n%101 = vfma %100\n{body}")
}

#[test]
fn larrabee_folded_operand_takes_no_issue_slot() {
    let m = larrabee()
        .with_sets(&["core.no_back_to_back=false".into()])
        .unwrap();
    let regs = warm("%1 = vfma\n%2 = vfma\n%3 = vfma\n%4 = vfma\n");
    let folded = warm(
        "%1 = vloadfold @d+0x0:64\n%2 = vfma %1\n%3 = vloadfold @d+0x0:4\n%4 = vfma %3\n\
         %5 = vloadfold @d+0x0:16\n%6 = vfma %5\n%7 = vloadfold @d+0x0:64\n%8 = vfma %7\n",
    );
    let separate = warm(
        "%1 = vload @d+0x0:64\n%2 = vfma %1\n%3 = vloadbcast @d+0x0:4\n%4 = vfma %3\n\
         %5 = vloadbcast @d+0x0:16\n%6 = vfma %5\n%7 = vload @d+0x0:64\n%8 = vfma %7\n",
    );
    let base = threads(&m, &[&regs]);
    // Folded: the four FMAs issue as if their operands were registers.
    assert_eq!(threads(&m, &[&folded]), base);
    // Separate loads take the U pipe and stall each FMA on its load (3
    // cycles, L1 hit): each pair takes 4 issue cycles instead of 1.
    assert_eq!(threads(&m, &[&separate]), base + 4 * (4 - 1));
}

/// Eight pairs of a `load` of `bytes` (an L1 hit, after [`warm`]) and the
/// `op` reading it.
fn load_op_pairs(load: &str, bytes: u32, op: &str) -> String {
    warm(
        &(1..=8)
            .map(|k| {
                format!(
                    "%{a} = {load} @d+0x0:{bytes}\n%{b} = {op} %{a}\n",
                    a = 2 * k,
                    b = 2 * k + 1
                )
            })
            .collect::<String>(),
    )
}

#[test]
fn haswell_folded_load_is_micro_fused() {
    let m = hsw();
    // Eight FMAs, each with its own load (two load ports, 4 cycles L1).
    let pairs = |class: &str| load_op_pairs(class, 32, "vfma");
    let folded = cycles(&m, &pairs("vloadfold"));
    let separate = cycles(&m, &pairs("vload"));
    // The same uops and ports; folded, the 16 ops dispatch in 8 slots, not 16.
    assert!(folded < separate, "{folded} {separate}");
    assert_eq!(separate - folded, 2);
}

/// `body` after ten dependent imuls on the value `%3` it produces: makes
/// the time `%3` is ready the run's end (+ 30).
fn then_chain(body: &str) -> String {
    let mut s = body.to_string();
    s.push_str("%10 = imul %3\n");
    for i in 11..20 {
        s.push_str(&format!("%{i} = imul %{}\n", i - 1));
    }
    s
}

#[test]
fn a_load_forwards_from_the_youngest_overlapping_store() {
    let m = hsw();
    // An old store of a slow value (vdiv: done 22) and a younger store of
    // a fast one (alu: done 2) to the same stack slot; the load (dispatched
    // in cycle 1, issues 2) takes the younger store's data: 2 + 5 = 7, and
    // the chain ends at 7 + 30. Forwarding from the old store would be a
    // false chain through the slot: 22 + 5 + 30 = 57.
    let body = then_chain(
        "%1 = vdiv\nstore %1 @d+0x40:8\n%2 = alu\nstore %2 @d+0x40:8\n%3 = load @d+0x40:8\n",
    );
    assert_eq!(cycles(&m, &body), 37);
}

#[test]
fn a_load_the_store_does_not_contain_cannot_forward() {
    let m = hsw();
    let run = |m: &MachineConfig, stores: &str, load: &str| {
        cycles(m, &then_chain(&format!("%1 = imul\n{stores}%3 = {load}\n")))
    };
    // Store data ready at 4 (imul), the load issues 2: forwarded at 4 + 5.
    let fwd = 9 + 30;
    assert_eq!(run(&m, "store %1 @d+0x40:8\n", "load @d+0x40:8"), fwd);
    // A smaller load inside the store forwards too.
    assert_eq!(run(&m, "store %1 @d+0x40:8\n", "load @d+0x44:4"), fwd);
    // Wider than the store: fails, 12 cycles more (Haswell).
    assert_eq!(run(&m, "store %1 @d+0x40:4\n", "load @d+0x40:8"), fwd + 12);
    // Spanning two stores: fails too.
    let two = "store %1 @d+0x40:4\nstore %1 @d+0x44:4\n";
    assert_eq!(run(&m, two, "load @d+0x40:8"), fwd + 12);
    let p = m
        .with_sets(&["core.store_forward_fail_penalty=3".into()])
        .unwrap();
    assert_eq!(run(&p, two, "load @d+0x40:8"), fwd + 3);
}

#[test]
fn core2_forwards_from_a_wide_store_only_to_a_load_at_its_start() {
    // A 16-byte store of %1 (imul: ready 4), then a 4-byte load inside it.
    let run = |m: &MachineConfig, load: &str| {
        cycles(
            m,
            &then_chain(&format!("%1 = imul\nstore %1 @d+0x40:16\n%3 = {load}\n")),
        )
    };
    let fwd = 9 + 30;
    let hsw_like = hsw();
    let core2 = hsw()
        .with_sets(&["core.store_forward_wide_same_start=true".into()])
        .unwrap();
    // Contained loads forward on Haswell wherever they start.
    assert_eq!(run(&hsw_like, "load @d+0x44:4"), fwd);
    // With the Core 2 rule: at the store's start it forwards, at +4 it
    // fails (12 cycles more at Haswell's penalty).
    assert_eq!(run(&core2, "load @d+0x40:4"), fwd);
    assert_eq!(run(&core2, "load @d+0x44:4"), fwd + 12);
    // Stores of 8 bytes or less still forward to any load they contain.
    let narrow = "%1 = imul\nstore %1 @d+0x40:8\n%3 = load @d+0x44:4\n";
    assert_eq!(cycles(&core2, &then_chain(narrow)), fwd);
}

#[test]
fn a_full_store_buffer_stalls_dispatch() {
    // A slow store first (its data: a divide, done 22; it retires in 22),
    // then two more stores and an alu chain.
    let body = "%1 = vdiv\nstore %1 @d+0x0:8\nstore @d+0x40:8\nstore @d+0x80:8\n\
                %2 = alu\n%3 = alu %2\n";
    // 42 entries: nothing waits. The first store issues when its data is
    // ready (22), done 23; the four ops after the divide retire in 23 and
    // the last alu in 24.
    assert_eq!(cycles(&hsw(), body), 24);
    // Two entries: the third store waits for the first's entry (it retires
    // in 23): dispatch 24, and the alus after it issue 25 and 26: done 27.
    let two = hsw().with_sets(&["core.store_buffer=2".into()]).unwrap();
    assert_eq!(cycles(&two, body), 27);
}

#[test]
fn a_macro_fused_compare_and_branch_is_one_uop() {
    // Eight independent compare-branch pairs: fused, each pair is one uop
    // on p06 and one dispatch slot; unfused, 16 uops (cmp on p0156, branch
    // on p06) in 16 slots.
    let mut body = String::new();
    for k in 1..=8 {
        body.push_str(&format!("%{k} = cmp\nbranch %{k} site={k} not-taken\n"));
    }
    let fused = hsw();
    let plain = hsw().with_sets(&["core.macro_fusion=Off".into()]).unwrap();
    let s = |m: &MachineConfig| {
        let t = trace(&m.isa, &body);
        simulate(m, &[&t], &SimOptions::default()).unwrap()
    };
    let (f, p) = (s(&fused), s(&plain));
    assert_eq!((f.uops, p.uops), (8, 16));
    // Fused: 8 uops on two ports (p0, p6) issue 4 cycles (1..4), done 5.
    assert_eq!(f.cycles, 5);
    // Unfused: 16 slots dispatch in cycles 0..3; each cmp issues a cycle
    // after its dispatch and its branch a cycle later, on p0/p6: the
    // eight branches end at 6 (all four ALU ports help the compares).
    assert_eq!(p.cycles, 6);
    assert_eq!(f.ops, p.ops, "both count 16 instructions");
}

#[test]
fn a_scalar_divide_is_priced_apart_from_the_vector_divide() {
    let m = hsw();
    // divsd: 13 cycles, the divider busy 8; vdivps ymm: 21, busy 14.
    assert_eq!(cycles(&m, "%1 = div\n%2 = div %1\n"), 1 + 13 + 13);
    assert_eq!(cycles(&m, "%1 = div\n%2 = div\n"), 9 + 13);
    assert_eq!(cycles(&m, "%1 = vdiv\n%2 = vdiv\n"), 15 + 21);
}

#[test]
fn a_three_component_lea_is_slow_and_on_one_port() {
    let m = hsw();
    // lea3: 3 cycles on p1 only; a two-component lea (alu): 1 cycle, p0156.
    assert_eq!(cycles(&m, "%1 = lea3\n%2 = lea3 %1\n"), 1 + 3 + 3);
    assert_eq!(cycles(&m, "%1 = lea3\n%2 = lea3\n%3 = lea3\n"), 3 + 3);
    assert_eq!(cycles(&m, "%1 = alu\n%2 = alu\n%3 = alu\n"), 2);
}

#[test]
fn haswell_scalar_load_op_is_micro_fused() {
    let m = hsw();
    // Eight alus, each reading its own memory operand (an L1 hit).
    let pairs = |class: &str| load_op_pairs(class, 8, "alu");
    let (folded, separate) = (cycles(&m, &pairs("loadfold")), cycles(&m, &pairs("load")));
    // The same uops on the same ports; folded, the 16 ops take 8 dispatch
    // slots (2 cycles), not 16 (4 cycles): the loads issue, two a cycle,
    // as soon as they dispatch, and the last pair ends 2 cycles earlier.
    assert_eq!(separate - folded, 2);
    let t = trace(&m.isa, &pairs("loadfold"));
    let s = simulate(&m, &[&t], &SimOptions::default()).unwrap();
    assert_eq!(s.ops, 2 + 8, "a folded operand is part of its op");
}

#[test]
fn a_narrow_operand_takes_its_own_timing() {
    let m = hsw();
    // divps xmm (w=16): 13 cycles, the divider busy 7; ymm: 21 and 14.
    assert_eq!(
        cycles(&m, "%1 = vdiv w=16\n%2 = vdiv w=16 %1\n"),
        1 + 13 + 13
    );
    assert_eq!(cycles(&m, "%1 = vdiv w=16\n%2 = vdiv w=16\n"), 8 + 13);
    assert_eq!(cycles(&m, "%1 = vdiv w=32\n%2 = vdiv\n"), 15 + 21);
    // A class without a narrow timing keeps its own: vfma 5.
    assert_eq!(cycles(&m, "%1 = vfma w=16\n"), 6);
}

#[test]
fn a_load_that_passed_an_aliasing_store_clears_and_its_site_then_waits() {
    let m = hsw();
    // The store's address comes from a divide (known at 22); the load of
    // its bytes issues at once (cycle 1 or 2), before the address is known.
    let first = "%1 = vdiv\n%2 = alu\nstore %2 @d+0x40:8 addr=%1\n%3 = load @d+0x40:8 site=1\n";
    // Without a site the load is disambiguated perfectly: it gets the
    // store's bytes once its address is known, 22 + 5 = 27, and the alu
    // after it runs at once.
    let perfect = cycles(&m, &format!("{}%4 = alu\n", first.replace(" site=1", "")));
    assert_eq!(perfect, 27);
    // With a site, a machine clear: fetch resumes at 22 + 15 = 37; the alu
    // dispatches 37, issues 38, done 39.
    assert_eq!(cycles(&m, &format!("{first}%4 = alu\n")), 39);
    // The site is now predicted dependent: a later load from it waits for
    // every older store's address even where it reads other bytes. The
    // second divide issues when %4 is ready (39), done 60; the load then
    // issues at 60 (an L1 hit, 4): done 64, its alu 65. A load from
    // another site issues at once; the store, issued when its address is
    // known (60), ends the run at 61.
    let second = |site: u32| {
        format!(
            "{first}%4 = alu\n%5 = vdiv %4\nstore %2 @d+0x50:8 addr=%5\n\
             %6 = load @d+0x48:8 site={site}\n%7 = alu %6\n"
        )
    };
    assert_eq!(cycles(&m, &second(1)), 65);
    assert_eq!(cycles(&m, &second(2)), 61);
    let t = trace(&m.isa, &second(1));
    let s = simulate(&m, &[&t], &SimOptions::default()).unwrap();
    assert_eq!(s.ordering_clears, 1);
}

#[test]
fn a_stores_address_uop_issues_before_its_data() {
    // A 2-entry scheduler; a store whose data is a divide (done 22) and whose
    // address is ready at 2, then a chain of 30 alus.
    let mut body = String::from("%1 = vdiv\n%2 = alu\nstore %1 @d+0x40:8 addr=%2\n%3 = alu\n");
    for i in 4..33 {
        body.push_str(&format!("%{i} = alu %{}\n", i - 1));
    }
    let m = hsw().with_sets(&["core.scheduler=2".into()]).unwrap();
    // Split: the address uop issues at 2 and frees its entry, so the chain
    // takes the other entry from cycle 2: its 30 alus end at 33 (the store
    // retires at 23 behind the divide).
    assert_eq!(cycles(&m, &body), 33);
    // Without an address source both uops wait for the data (22) and hold
    // both entries until then: the chain starts at 22 and ends at 53.
    let unnamed = body.replace("store %1 @d+0x40:8 addr=%2", "store %1 %2 @d+0x40:8");
    assert_eq!(cycles(&m, &unnamed), 53);
}

#[test]
fn moves_and_zero_idioms_are_done_at_rename_on_haswell() {
    let (hsw, nhm) = (hsw(), MachineConfig::load("nehalem-x5550").unwrap());
    // imul (3), an eliminated move (0), imul (3): 1 + 3 + 3.
    let chain = "%1 = imul\n%2 = mov %1\n%3 = imul %2\n";
    assert_eq!(cycles(&hsw, chain), 7);
    // Nehalem executes the move on an ALU: one cycle more.
    let t = isa::trace_text::parse(&format!(".trace 1\n.isa sse4\n{chain}")).unwrap();
    let s = simulate(&nhm, &[&t], &SimOptions::default()).unwrap();
    assert_eq!(s.cycles, 8);
    // A zero idiom is ready at once: the imul reading it issues in cycle 1.
    assert_eq!(cycles(&hsw, "%1 = zero\n%2 = imul %1\n"), 4);
    assert_eq!(cycles(&hsw, "%1 = alu\n%2 = imul %1\n"), 5);
    // No port: eight moves and zeroings take only dispatch slots (2 cycles
    // of 4) and retire at once.
    let t = trace(&hsw.isa, "%1 = zero\n%2 = zero\n%3 = mov %1\n%4 = mov %2\n%5 = zero\n%6 = mov %5\n%7 = zero\n%8 = mov %7\n");
    let s = simulate(&hsw, &[&t], &SimOptions::default()).unwrap();
    assert_eq!((s.uops, s.cycles), (0, 2));
}

/// `n` copies of `body` (op texts without `%D =`): every op but a branch
/// produces the next value id, none reads another.
fn repeat(n: u32, body: &[&str]) -> String {
    let mut id = 0;
    let mut s = String::new();
    for _ in 0..n {
        for op in body {
            if op.starts_with("branch") {
                s.push_str(&format!("{op}\n"));
            } else {
                id += 1;
                s.push_str(&format!("%{id} = {op}\n"));
            }
        }
    }
    s
}

/// `n` iterations of a loop body: four independent ALU ops and a branch
/// (`taken` or `not-taken`) closing it.
fn alu_loop(n: u32, branch: &str) -> String {
    let close = format!("branch site=1 {branch}");
    repeat(n, &["alu", "alu", "alu", "alu", &close])
}

/// Cycles per `n` more iterations of a loop (its steady state).
fn per_iterations(m: &MachineConfig, body: impl Fn(u32) -> String, n: u32) -> u64 {
    cycles(m, &body(2 * n)) - cycles(m, &body(n))
}

#[test]
fn a_taken_branch_ends_its_issue_group_on_haswell() {
    let m = hsw();
    let off = m
        .with_sets(&["core.taken_branch_ends_issue=false".into()])
        .unwrap();
    let taken = |n| alu_loop(n, "taken");
    let not_taken = |n| alu_loop(n, "not-taken");
    // Five uops an iteration on the four ALU ports, four issue slots a
    // cycle: 64 iterations take 128 cycles when the loop's taken branch ends
    // each group (4 | 1 slots), 80 when groups run across it (5 uops on
    // four ports and four slots: 1.25 cycles each).
    assert_eq!(per_iterations(&m, taken, 64), 128);
    assert_eq!(per_iterations(&off, taken, 64), 80);
    // A branch not taken does not end the group.
    assert_eq!(per_iterations(&m, not_taken, 64), 80);
}

#[test]
fn a_taken_branch_issues_on_port_6_only_on_haswell() {
    let m = hsw()
        .with_sets(&["core.taken_branch_ends_issue=false".into()])
        .unwrap();
    let any_port = m.with_sets(&["core.taken_branch_ports=[]".into()]).unwrap();
    let branches = |taken: &'static str| {
        move |n: u32| {
            (0..n)
                .map(|_| format!("branch site=1 {taken}\n"))
                .collect::<String>()
        }
    };
    // Taken: one branch unit (p6), one a cycle; not taken: p0 and p6, two.
    assert_eq!(per_iterations(&m, branches("taken"), 64), 64);
    assert_eq!(per_iterations(&m, branches("not-taken"), 64), 32);
    // With the class's ports for taken branches too: two a cycle.
    assert_eq!(per_iterations(&any_port, branches("taken"), 64), 32);
}

/// `n` independent `class` ops (no sources), each with `extra` tokens.
fn straight(n: u32, class: &str, extra: &str) -> String {
    repeat(n, &[&format!("{class} {extra}")])
}

#[test]
fn legacy_decode_fetches_sixteen_bytes_a_cycle_on_haswell() {
    let m = hsw();
    // Seven-byte ALU ops: 32 of them are 224 bytes, 14 fetch blocks, 14
    // cycles; from the uop cache (no length) four a cycle, 8 cycles.
    let long = |n| straight(n, "alu", "len=7");
    let cached = |n| straight(n, "alu", "");
    assert_eq!(per_iterations(&m, long, 32), 14);
    assert_eq!(per_iterations(&m, cached, 32), 8);
    // Three-byte ops: five a block, but four decoders: 8 cycles again.
    assert_eq!(per_iterations(&m, |n| straight(n, "alu", "len=3"), 32), 8);
    // Without the legacy decoders in the config, lengths are ignored.
    let none = m.with_sets(&["core.legacy_decode=null".into()]).unwrap();
    assert_eq!(per_iterations(&none, long, 32), 8);
}

#[test]
fn only_the_first_decoder_takes_a_multi_uop_instruction_on_haswell() {
    let m = hsw();
    // cmov: 2 fused uops. From the legacy decoders one a cycle (the complex
    // decoder); from the uop cache two a cycle (4 slots; p0156 and p06
    // keep up).
    assert_eq!(per_iterations(&m, |n| straight(n, "cmov", "len=4"), 32), 32);
    assert_eq!(per_iterations(&m, |n| straight(n, "cmov", ""), 32), 16);
    // A cmov and the two single-uop moves after it (eliminated at rename:
    // no port) decode in one cycle, the next cmov in the next: 8 groups of
    // 4 fused uops, 8 cycles, as from the uop cache (16 if the moves had to
    // wait for a cycle of their own).
    let groups = |extra: &'static str| {
        let ops = ["cmov", "mov", "mov"].map(|c| format!("{c} {extra}"));
        move |n: u32| repeat(n, &ops.each_ref().map(String::as_str))
    };
    assert_eq!(per_iterations(&m, groups("len=4"), 8), 8);
    assert_eq!(per_iterations(&m, groups(""), 8), 8);
}

#[test]
fn a_length_changing_prefix_stalls_the_predecoder_on_haswell() {
    let m = hsw();
    // Four-byte ops, four a block and a cycle; each with a length-changing
    // prefix (add r16, imm16) costs 3 more cycles: 8 ops, 2 + 8 * 3 cycles.
    let lcp = |n| straight(n, "alu", "len=4 lcp");
    let plain = |n| straight(n, "alu", "len=4");
    assert_eq!(per_iterations(&m, plain, 8), 2);
    assert_eq!(per_iterations(&m, lcp, 8), 2 + 8 * 3);
}

#[test]
fn the_predecoder_takes_five_instructions_a_cycle_on_haswell() {
    let m = hsw();
    // Blocks of six instructions (five of 2 bytes, one of 6): five are
    // predecoded in a block's first cycle, the sixth in a second; the
    // decoders take four, then two: two cycles a block, 16 for 8 blocks.
    let six = |n| {
        repeat(
            n,
            &[
                "alu len=2",
                "alu len=2",
                "alu len=2",
                "alu len=2",
                "alu len=2",
                "alu len=6",
            ],
        )
    };
    assert_eq!(per_iterations(&m, six, 8), 16);
    // A predecoder of 16 a cycle: the decoders' four a cycle, 12.
    let wide = m
        .with_sets(&["core.legacy_decode.predecode_width=16".into()])
        .unwrap();
    assert_eq!(per_iterations(&wide, six, 8), 12);
}

#[test]
fn a_fusible_instruction_skips_the_last_decoder_on_haswell() {
    let m = hsw();
    // Three-byte compares (cmp r, r), never followed by a branch: three a
    // cycle, as a test, add, sub, and, inc or dec marked fusible; other
    // ALU ops four.
    assert_eq!(per_iterations(&m, |n| straight(n, "cmp", "len=3"), 12), 4);
    assert_eq!(
        per_iterations(&m, |n| straight(n, "alu", "len=3 fusible"), 12),
        4
    );
    assert_eq!(per_iterations(&m, |n| straight(n, "alu", "len=3"), 12), 3);
    let later = m
        .with_sets(&["core.legacy_decode.fusible_not_last=false".into()])
        .unwrap();
    assert_eq!(
        per_iterations(&later, |n| straight(n, "cmp", "len=3"), 12),
        3
    );
}

#[test]
fn a_complex_only_instruction_decodes_alone_on_haswell() {
    let m = hsw();
    // pop r12 (2 bytes, one uop, the complex decoder): one a cycle.
    assert_eq!(
        per_iterations(&m, |n| straight(n, "alu", "len=2 complex"), 8),
        8
    );
    // It ends its group: a complex one and three simple ones take two
    // cycles (one without the flag).
    let group = |flag: &'static str| {
        let first = format!("alu len=2 {flag}");
        move |n: u32| repeat(n, &[first.as_str(), "alu len=2", "alu len=2", "alu len=2"])
    };
    assert_eq!(per_iterations(&m, group("complex"), 4), 8);
    assert_eq!(per_iterations(&m, group(""), 4), 4);
}

#[test]
fn a_branch_ends_its_decode_group_on_haswell() {
    let m = hsw();
    // Two ALU ops and a not-taken branch, 2 bytes each: one group a cycle
    // (the branch ends it), 8 cycles for 8; from the uop cache 6 (4 a cycle).
    let close = |len: &'static str| {
        let ops = [
            format!("alu {len}"),
            format!("alu {len}"),
            format!("branch site=1 not-taken {len}"),
        ];
        move |n: u32| repeat(n, &ops.each_ref().map(String::as_str))
    };
    assert_eq!(per_iterations(&m, close("len=2"), 8), 8);
    assert_eq!(per_iterations(&m, close(""), 8), 6);
}

/// A cold load and `n` 8-byte ALU ops that wait for it: two decoded a
/// cycle, dispatched until the scheduler is full of them.
fn behind_a_miss(n: u32) -> String {
    let mut s = String::from("%1 = load @d+0x0:8\n");
    for i in 0..n {
        s.push_str(&format!("%{} = alu %1 len=8\n", i + 2));
    }
    s
}

#[test]
fn the_decoders_run_ahead_by_the_decoded_queue_on_haswell() {
    let m = hsw();
    let unbounded = m
        .with_sets(&["core.legacy_decode.decoded_queue=4096".into()])
        .unwrap();
    // The load completes at 217 (walk 20, DRAM 196). Its 60 dependants fill
    // the scheduler by cycle 30; unbounded, the decoders go on (two a
    // cycle) and have all 300 decoded when the load completes: the rest
    // dispatch four a cycle as the ALUs free the scheduler: the last four
    // issue at 291 and retire at 292. Bounded, they hold 56 more and stop,
    // with 20 predecoded in the instruction queue: from 217 the decoders
    // take four a cycle as the predecoder adds two, the queue empties in 10
    // cycles (40 decoded), and the last 144 decode two a cycle (72 cycles):
    // the last decoded at 298, dispatched at 299, done and retired at 301.
    let (fast, slow) = (
        cycles(&unbounded, &behind_a_miss(300)),
        cycles(&m, &behind_a_miss(300)),
    );
    assert_eq!(fast, 217 + 300 / 4);
    assert_eq!(slow, 217 + 10 + (300 - 60 - 56 - 40) / 2 + 2);
    // Not behind a stall the queue changes nothing: decode-bound both ways.
    let free = |n| straight(n, "alu", "len=8");
    assert_eq!(
        per_iterations(&m, free, 32),
        per_iterations(&unbounded, free, 32)
    );
}

fn stall_cycles(m: &MachineConfig, body: &str) -> [u64; sim::Stall::COUNT] {
    let t = trace(&m.isa, body);
    simulate(m, &[&t], &SimOptions::default()).unwrap().stalls
}

#[test]
fn late_ops_are_charged_to_operands_or_ports() {
    use sim::Stall::{Dependency, Issue, Ports};
    let m = hsw();
    // A chain: each FMA waits 5 cycles for its operand (issue at 1, 6, 11;
    // retire at 6, 11, 16): the first retirement is its own latency after
    // dispatch (issue bandwidth), the next two 5 cycles each of dependency.
    let s = stall_cycles(&m, "%1 = vfma\n%2 = vfma %1\n%3 = vfma %2\n");
    assert_eq!(
        (s[Issue as usize], s[Dependency as usize], s[Ports as usize]),
        (6, 10, 0)
    );
    // Independent divides share p0, busy 14 cycles each: issue at 1, 15,
    // 29, done 22, 36, 50; the second and third wait for the port.
    let s = stall_cycles(&m, "%1 = vdiv\n%2 = vdiv\n%3 = vdiv\n");
    assert_eq!(
        (s[Issue as usize], s[Dependency as usize], s[Ports as usize]),
        (22, 0, 28)
    );
}

#[test]
fn a_missing_load_is_charged_to_the_level_that_served_it() {
    use sim::Stall::{MemoryDram, MemoryL2, MemoryL3};
    let m = hsw_untranslated();
    // Cold: DRAM (196 cycles; issue at 1, done 197).
    let s = stall_cycles(&m, "%1 = load @d+0x0:8\n");
    assert_eq!(s[MemoryDram as usize], 197);
    assert_eq!(s[MemoryL2 as usize] + s[MemoryL3 as usize], 0);
    // The trace's memory levels by hierarchy depth: one level (an L1 only)
    // means a miss is DRAM; L2 and L3 by their index.
    assert_eq!(sim::Stall::memory(0, 4), None);
    assert_eq!(sim::Stall::memory(1, 4), Some(MemoryL2));
    assert_eq!(sim::Stall::memory(2, 4), Some(MemoryL3));
    assert_eq!(sim::Stall::memory(3, 4), Some(MemoryL3), "an L4");
    assert_eq!(sim::Stall::memory(4, 4), Some(MemoryDram));
    assert_eq!(sim::Stall::memory(1, 1), Some(MemoryDram));
    assert_eq!(sim::Stall::memory(2, 2), Some(MemoryDram));
}

#[test]
fn port_pressure_is_charged_to_the_port_the_op_waited_for() {
    let m = hsw();
    let by_port = |body: &str| {
        let t = trace(&m.isa, body);
        let s = simulate(&m, &[&t], &SimOptions::default()).unwrap();
        let sum = |a: &[[u64; sim::stats::MAX_PORTS]]| -> Vec<u64> {
            (0..8).map(|p| a.iter().map(|r| r[p]).sum()).collect()
        };
        (sum(&s.region_port_stalls), sum(&s.region_port_uops))
    };
    // Three divides on p0 (see above): their 28 port cycles are all p0's,
    // and p0 executed their three uops.
    let (stalls, uops) = by_port("%1 = vdiv\n%2 = vdiv\n%3 = vdiv\n");
    assert_eq!(stalls, [28, 0, 0, 0, 0, 0, 0, 0]);
    assert_eq!(uops, [3, 0, 0, 0, 0, 0, 0, 0]);
    // Two independent FMAs take p0 and p1 (least used first) and wait for
    // no port: no port cycles.
    let (stalls, uops) = by_port("%1 = vfma\n%2 = vfma\n");
    assert_eq!(stalls, [0; 8]);
    assert_eq!(uops, [1, 1, 0, 0, 0, 0, 0, 0]);
}

#[test]
fn a_vector_load_takes_its_class_latency_over_the_l1s() {
    // Zen 4: integer load-to-use 4 (the L1's), FP 7 (the vload class): a
    // vadd on a vector load of a line in L1 (its address from the load that
    // brought the line in) finishes 3 cycles later than one on an integer
    // load of it. Haswell's are both 4.
    let run = |m: &MachineConfig, load: &str| {
        cycles(
            m,
            &format!("%1 = load @d+0x0:8\n%2 = {load} %1 @d+0x8:8\n%3 = vadd %2\n"),
        )
    };
    let z = MachineConfig::load("zen4").unwrap();
    assert_eq!(run(&z, "vload") - run(&z, "load"), 3);
    let m = hsw();
    assert_eq!(run(&m, "vload"), run(&m, "load"));
}

#[test]
fn a_second_scheduler_holds_only_its_ports_uops() {
    // Zen 4 with one FP scheduler entry: a vadd waiting on a divide holds it
    // until it issues, so an independent chain of vadds waits too; a chain
    // of integer ops, held in the other scheduler, does not.
    let full = MachineConfig::load("zen4").unwrap();
    let mut one = full.clone();
    one.core.fp_scheduler.as_mut().unwrap().entries = 1;
    let div = "%1 = vdiv\n%2 = vadd %1\n";
    let vadds = format!("{div}%3 = vadd\n%4 = vadd %3\n%5 = vadd %4\n%6 = vadd %5\n");
    let alus = format!("{div}%3 = alu\n%4 = alu %3\n%5 = alu %4\n%6 = alu %5\n");
    // The divide issues in 1 (lat 11: done 12), its vadd in 12 (done 15).
    assert_eq!(cycles(&full, &vadds), 15);
    // One entry: the vadd holds it from 1 until it issues in 12; the chain
    // dispatches then, issues in 13 and takes 4 x 3 cycles: done 25.
    assert_eq!(cycles(&one, &vadds), 12 + 1 + 4 * 3);
    assert_eq!(cycles(&full, &alus), 15);
    assert_eq!(cycles(&one, &alus), 15);
}

#[test]
fn zen4_runs_a_512_bit_op_on_its_pipe_for_two_cycles() {
    let m = MachineConfig::load("zen4-avx512").unwrap();
    // Six independent loads of one line, their address known once `warm`'s
    // load has brought it (L1 hits), on the two vector load ports: 64 bytes
    // each take a port 2 cycles, so they issue in pairs at cycles t, t+2,
    // t+4; of 16 bytes (the narrow timing), t, t+1, t+2.
    let loads = |bytes: u32| {
        warm(
            &(1..=6)
                .map(|k| format!("%{k} = vload %101 @d+0x0:{bytes}\n"))
                .collect::<String>(),
        )
    };
    assert_eq!(cycles(&m, &loads(64)) - cycles(&m, &loads(16)), 2);
    // Four independent adds on the two add pipes (FP2, FP3): each zmm add
    // two uops (its halves), so they issue over 4 cycles where zen4's ymm
    // adds take 2; the latency (3) is the same.
    let adds = (1..=4)
        .map(|k| format!("%{k} = vadd\n"))
        .collect::<String>();
    let ymm = MachineConfig::load("zen4").unwrap();
    assert_eq!(cycles(&m, &adds), cycles(&ymm, &adds) + 2);
    assert_eq!(cycles(&m, "%1 = vadd\n%2 = vadd %1\n"), 1 + 3 + 3);
}

/// Haswell without its TLBs: the cache-level latencies alone.
fn hsw_untranslated() -> MachineConfig {
    hsw().with_sets(&["tlb=null".into()]).unwrap()
}

#[test]
fn a_translation_costs_its_tlb_level_or_the_walk() {
    // Haswell: DTLB 64 entries 4-way (16 sets), STLB 1024 8-way (128
    // sets), an STLB hit 8 cycles, a walk 20 (configs/machines).
    let m = hsw();
    let mut h = Hierarchy::new(&m, 1);
    let page = |p: u64| p * 4096;
    let r = MemId(1);
    // Cold page and line: the walk, then DRAM.
    assert_eq!(h.access(0, page(1000), false, r, 0).latency, 20 + 196);
    // The same line: a DTLB hit adds nothing.
    assert_eq!(h.access(0, page(1000), false, r, 0).latency, 4);
    // Another line of the same page, once the DRAM queue has drained: no
    // translation cost, the line's own.
    assert_eq!(h.access(0, page(1000) + 64, false, r, 10_000).latency, 196);
    // Four more pages in the page's DTLB set (16 sets) push it out of the
    // DTLB; the STLB (128 sets) still holds it. (Each touches another L1
    // set, so the page's line stays in the L1.)
    for k in 1..=4 {
        h.access(0, page(1000 + 16 * k) + 64 * k, false, r, 0);
    }
    assert_eq!(
        h.access(0, page(1000), false, r, 0).latency,
        8 + 4,
        "STLB hit, L1 hit"
    );
    assert_eq!(
        h.access(0, page(1000), false, r, 0).latency,
        4,
        "back in the DTLB"
    );
    // Eight more pages in its STLB set (and DTLB set) push it out of both.
    for k in 1..=8 {
        h.access(0, page(1000 + 128 * k) + 64 * (4 + k), false, r, 0);
    }
    assert_eq!(
        h.access(0, page(1000), false, r, 0).latency,
        20 + 4,
        "walk, L1 hit"
    );
    let t = h.tlb_stats().unwrap();
    assert_eq!((t.hits[1], t.walks), (1, 1 + 4 + 8 + 1));
    // Without TLBs the same cold access is DRAM alone.
    let mut plain = Hierarchy::new(&hsw_untranslated(), 1);
    assert_eq!(plain.access(0, page(1000), false, r, 0).latency, 196);
}

#[test]
fn core2_stores_skip_the_loads_only_dtlb0() {
    // Core 2: DTLB0 16 entries 4-way (4 sets) for loads, DTLB1 256 4-way
    // (64 sets) +2 cycles, walk 25.
    let m = MachineConfig::load("core2-q6600").unwrap();
    let mut h = Hierarchy::new(&m, 1);
    let r = MemId(1);
    let l1 = u64::from(m.caches[0].latency);
    // A store walks and fills DTLB1 only; a load of the page then misses
    // DTLB0 and finds it in DTLB1.
    h.access(0, 7 * 4096, true, r, 0);
    assert_eq!(h.access(0, 7 * 4096, false, r, 0).latency, 2 + l1);
    assert_eq!(h.access(0, 7 * 4096, false, r, 0).latency, l1);
    let t = h.tlb_stats().unwrap();
    // The store looked up DTLB1 alone (a miss there); the load missed DTLB0.
    assert_eq!((t.hits, t.misses, t.walks), (vec![1, 1], vec![1, 1], 1));
}

#[test]
fn a_dependent_load_chain_pays_each_walk_once() {
    // Two dependent loads in two cold pages, then the same two again: each
    // page's first load walks (20) and misses to DRAM (196); the repeats
    // hit the DTLB and the L1 (4 each). Issue at 1: 1 + 216 + 216 + 4 + 4.
    let m = hsw();
    let body = "%1 = load @d+0x0:8\n%2 = load @d+0x2000:8 %1\n%3 = load @d+0x0:8 %2\n%4 = load @d+0x2000:8 %3\n";
    assert_eq!(cycles(&m, body), 1 + 2 * (20 + 196) + 2 * 4);
    assert_eq!(cycles(&hsw_untranslated(), body), 1 + 2 * 196 + 2 * 4);
}

#[test]
fn core2_fuses_compare_and_branch_in_32_bit_code_only() {
    let mut body = String::new();
    for k in 1..=8 {
        body.push_str(&format!("%{k} = cmp\nbranch %{k} site={k} not-taken\n"));
    }
    let uops = |sets: &[&str]| {
        let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
        let m = MachineConfig::load("core2-q6600")
            .unwrap()
            .with_sets(&sets)
            .unwrap();
        let t = trace(&m.isa, &body);
        simulate(&m, &[&t], &SimOptions::default()).unwrap().uops
    };
    assert_eq!(uops(&[]), 16, "64-bit code (the default): no fusion");
    assert_eq!(uops(&["core.code=Bits32"]), 8, "32-bit code fuses");
    assert_eq!(uops(&["core.macro_fusion=On"]), 8);
}

#[test]
fn every_built_in_machine_translates_and_states_its_fusion_mode() {
    for (name, _) in sim::config::BUILTIN {
        let m = MachineConfig::load(name).unwrap();
        let t = m
            .tlb
            .as_ref()
            .unwrap_or_else(|| panic!("{name} has no TLB"));
        assert_eq!(t.levels[0].latency, 0, "{name}");
        assert!(t.walk > t.levels.last().unwrap().latency, "{name}");
        // Core 2 (Merom, Penryn) fuses in 32-bit code only; the kernels run as 64-bit.
        let core2 = name.starts_with("core2") || name.starts_with("dunnington");
        if core2 {
            assert_eq!(m.core.macro_fusion, sim::config::MacroFusion::In32BitCode);
            assert!(!m.core.fuses(), "{name}");
        }
    }
    let bad = MachineConfig::load("core2-q6600")
        .unwrap()
        .with_sets(&["tlb.levels.0.latency=3".into()]);
    assert!(bad
        .unwrap_err()
        .to_string()
        .contains("tlb.levels[0].latency"));
}

#[test]
fn a_cmov_is_one_cycle_through_its_registers_and_two_through_its_flags_on_haswell() {
    let m = hsw();
    // Flags from an ALU op (done at 2); eight cmovs chained through a
    // register, the flags their first source: the first waits for the
    // flags (2 + 2 = 4), each next one cycle after the one before: 11.
    let mut data = String::from("%1 = alu\n%2 = alu\n");
    for k in 3..11 {
        data.push_str(&format!("%{k} = cmov %1 %{} %2\n", k - 1));
    }
    assert_eq!(cycles(&m, &data), 4 + 7);
    // Chained through the flags (each cmov's result the next one's
    // condition): two cycles a link, 2 + 8 * 2 = 18.
    let mut flags = String::from("%1 = alu\n%2 = alu\n");
    for k in 3..11 {
        flags.push_str(&format!("%{k} = cmov %{} %2 %2\n", k - 1));
    }
    assert_eq!(cycles(&m, &flags), 2 + 8 * 2);
    // One latency from every operand (the older model): 2 a link both ways.
    let flat = m
        .with_sets(&[
            "classes.cmov.cond_lat=null".into(),
            "classes.cmov.lat=2".into(),
        ])
        .unwrap();
    assert_eq!(cycles(&flat, &data), 2 + 8 * 2);
}

#[test]
fn a_load_that_cannot_forward_waits_for_the_store_to_reach_the_cache_on_haswell() {
    let m = hsw_untranslated();
    // The store's data is ready at 2 but it retires behind the divide (22);
    // the load, wider than the store, cannot forward: it reads the L1 once
    // the store has written it, the cycle after it retires: 23 + 4 = 27.
    let body = "%1 = vdiv\n%2 = alu\nstore %2 @d+0x40:4\n%3 = load @d+0x40:8\n";
    let l1 = u64::from(m.caches[0].latency);
    assert_eq!(cycles(&m, body), 22 + 1 + l1);
    // With the fixed penalty alone it is done at 2 + 5 + 12 = 19, and the
    // run ends with the divide's retirement.
    let fixed = m
        .with_sets(&["core.store_forward_fail_waits_commit=false".into()])
        .unwrap();
    assert_eq!(cycles(&fixed, body), 22);
}
