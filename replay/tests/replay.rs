//! The replay end to end on recorded microkernels: every recorded op
//! emitted, the code decodes back to the program, the model's body is a
//! valid loop, the host runs it (where it has AVX, which the VEX forms
//! need), and a loop that would fault is reported, not crashed on.

use isa::{FlavourId, OpClass};
use replay::program::{Inst, Opnd, Program, Reg};

fn trace(name: &str, fl: FlavourId) -> isa::Trace {
    let k = micro::build(name, &[("iters".into(), "64".into())]).expect("built-in microkernel");
    isa::record(&k, fl, name).0
}

fn host_runs(fl: FlavourId) -> bool {
    match fl {
        FlavourId::Avx512 => {
            std::arch::is_x86_feature_detected!("avx512f")
                && std::arch::is_x86_feature_detected!("avx512dq")
        }
        FlavourId::Avx2 => {
            std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma")
        }
        _ => std::arch::is_x86_feature_detected!("avx"),
    }
}

#[test]
fn every_recorded_op_is_emitted_and_the_code_decodes_back() {
    for name in [
        "pointer-chase",
        "stream-load",
        "stream-store",
        "branch-random",
    ] {
        for fl in [FlavourId::Sse4, FlavourId::Avx2, FlavourId::Avx512] {
            let t = trace(name, fl);
            let n = t.ops.len().min(300);
            let b =
                replay::build(&t, 0..n).unwrap_or_else(|e| panic!("{name} on {}: {e}", fl.name()));
            let recorded = b.program.insts.iter().filter(|x| x.recorded).count();
            assert!(
                recorded
                    >= n - t.ops[..n]
                        .iter()
                        .filter(|o| o.class == OpClass::Branch)
                        .count(),
                "{name}: {recorded} of {n}"
            );
            let lines = replay::listing(&b).lines().count();
            assert_eq!(
                lines,
                b.program.insts.len() + 2,
                "{name} on {}: every instruction decodes",
                fl.name()
            );
            assert_eq!(b.body.ops.len(), b.program.insts.len() + 2);
            b.body
                .validate_loop()
                .unwrap_or_else(|e| panic!("{name}: {e}"));
        }
    }
}

#[test]
fn a_loaded_pointer_stays_the_next_loads_address() {
    let t = trace("pointer-chase", FlavourId::Avx2);
    let b = replay::build(&t, 0..t.ops.len().min(200)).expect("builds");
    let chained = b
        .program
        .insts
        .iter()
        .filter(|x| x.class.is_load() && x.mem.as_ref().is_some_and(|m| !m.regs.is_empty()))
        .count();
    assert!(chained > 10, "loads addressed by a loaded value: {chained}");
    assert_eq!(b.program.changes.dropped_address_deps, 0);
}

#[test]
fn windows_run_on_the_host() {
    for fl in [FlavourId::Sse4, FlavourId::Avx2, FlavourId::Avx512] {
        if !host_runs(fl) {
            eprintln!("skipped {}: this host does not run it", fl.name());
            continue;
        }
        for name in ["pointer-chase", "stream-store"] {
            let t = trace(name, fl);
            let b = replay::build(&t, 0..t.ops.len().min(300)).expect("builds");
            let h = replay::host::time(
                &b.code,
                &b.program.init_mem,
                b.program.buffer_bytes,
                3,
                100_000,
            )
            .unwrap_or_else(|e| panic!("{name} on {}: {e}", fl.name()));
            assert!(h.ticks_per_iteration > 0.0 && h.iterations >= 16);
        }
    }
}

#[test]
fn a_fault_is_a_failed_window() {
    if !host_runs(FlavourId::Sse4) {
        return;
    }
    let mut x = Inst::new(
        OpClass::Load,
        isa::Region::Other,
        iced_x86::Code::Mov_r64_rm64,
    );
    x.ops = vec![Opnd::R(Reg::G(0)), Opnd::M];
    x.defs = vec![Reg::G(0)];
    // Far past the buffer's one page.
    x.mem = Some(replay::program::MemRef::at(
        replay::program::BUFFER_BASE + (1 << 24),
        8,
        false,
    ));
    let p = Program {
        insts: vec![x],
        vbytes: 16,
        lanes: 4,
        buffer_bytes: 4096,
        recorded_ops: 1,
        changes: replay::Changes::default(),
        init_regs: Vec::new(),
        init_mem: Vec::new(),
    };
    let code = replay::encode::encode(&p, 0).expect("encodes");
    let e = replay::host::time(&code, &[], 4096, 1, 1000).expect_err("faults");
    assert!(e.contains("faulted at body offset 0x0"), "{e}");
}
