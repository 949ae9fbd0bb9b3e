//! The program as a loop-body trace for the model: one op per instruction
//! (the loop's `dec`/`jnz` included), each reading the value its registers
//! last received: earlier in the body, or (loop-carried) at the body's end.

use crate::program::{Program, Reg, BUFFER_BASE};
use isa::trace::FLAG_ADDR;
use isa::{
    Addr, FlavourId, LaneMask, MemId, MemKind, MemRegion, Op, OpClass, Region, Trace, ValId,
};
use std::collections::HashMap;

/// The registers instruction `x` reads, address registers first.
fn reads(x: &crate::program::Inst) -> Vec<Reg> {
    let mut r: Vec<Reg> = x
        .mem
        .iter()
        .filter(|_| x.class.is_mem())
        .flat_map(|m| m.regs.clone())
        .collect();
    for &u in &x.uses {
        if !r.contains(&u) {
            r.push(u);
        }
    }
    r
}

/// The loop body the model times, for flavour `fl`.
#[must_use]
pub fn body_trace(p: &Program, fl: FlavourId) -> Trace {
    let mut t = Trace::new(fl, "replay");
    t.regions.push(MemRegion {
        id: MemId(0),
        kind: MemKind::Other,
        name: "replay-buffer".into(),
        base: Addr(BUFFER_BASE),
        size: p.buffer_bytes,
    });
    let mut last: HashMap<Reg, ValId> = HashMap::new();
    let mut id = 0u32;
    for x in &p.insts {
        if !x.defs.is_empty() {
            id += 1;
            for &d in &x.defs {
                last.insert(d, ValId(id));
            }
        }
    }
    // The loop's own counter (r14) and flags: `dec` then `jnz`.
    let counter = ValId(id + 1);
    let mut cur: HashMap<Reg, ValId> = HashMap::new();
    let full = LaneMask::full(fl.lanes());
    let mut next = 0u32;
    for (n, x) in p.insts.iter().enumerate() {
        let mut op = Op::new(x.class, x.region);
        for r in reads(x) {
            let v = cur
                .get(&r)
                .or_else(|| last.get(&r))
                .copied()
                .unwrap_or(ValId::NONE);
            // Flags read before the body writes them are the loop's `dec`'s.
            let v = if r == Reg::Flags && !cur.contains_key(&r) {
                counter
            } else {
                v
            };
            op.push_src(v);
        }
        if !x.defs.is_empty() {
            next += 1;
            op.dst = ValId(next);
            for &d in &x.defs {
                cur.insert(d, op.dst);
            }
        }
        op.mask = if x.class.is_per_lane_mem()
            || matches!(
                x.class,
                OpClass::VLoadMasked | OpClass::VStoreMasked | OpClass::VCompress
            ) {
            LaneMask(x.lanes & full.0)
        } else if x.class.is_vector() && !x.class.is_mem() {
            full
        } else {
            LaneMask(1)
        };
        if let Some(m) = x.mem.as_ref().filter(|_| x.class.is_mem()) {
            op.addr = Addr(m.addr);
            op.bytes = m.bytes;
            op.mem = MemId(0);
            op.aux = n as u32 + 1;
            if x.class.is_store() && !m.regs.is_empty() {
                op.flags |= FLAG_ADDR;
            }
            if x.class.is_per_lane_mem() {
                op.aux = t.lane_addrs.len() as u32;
                for _ in 0..op.mask.count() {
                    t.lane_addrs.push(Addr(m.addr));
                }
            }
        }
        if x.class == OpClass::Branch {
            op.aux = n as u32 + 1;
            // Its flags are known (the zero analysis), so it goes the
            // recorded way (or, unknown, is counted as such).
            if x.taken {
                op.flags |= isa::trace::FLAG_TAKEN;
            }
        }
        t.ops.push(op);
    }
    let mut dec = Op::new(OpClass::Alu, Region::Other);
    dec.flags |= isa::trace::FLAG_FUSIBLE;
    dec.push_src(counter);
    dec.dst = counter;
    let mut jnz = Op::new(OpClass::Branch, Region::Other);
    jnz.push_src(counter);
    jnz.flags |= isa::trace::FLAG_TAKEN;
    jnz.aux = p.insts.len() as u32 + 1;
    t.ops.push(dec);
    t.ops.push(jnz);
    t
}
