//! What every register holds when the replay runs. The loop starts with
//! every register at 0 and a zero-filled buffer, and its values are a pure
//! function of those, so each instruction's inputs can be computed (as
//! constants, each vector's lanes alike) wherever they are the same in
//! every iteration: a run of the loop over such values to a fixed point
//! (a value that differs between iterations becomes unknown). With them:
//! an address register keeps its place and the displacement takes its
//! value off, so the recorded dependency stays and the recorded address is
//! reached; a branch jumps on the flag state that makes its direction the
//! recorded one; a gather's lanes stay in the buffer.

use crate::program::{Inst, Opnd, Program, Reg};
use iced_x86::Mnemonic as N;
use std::collections::HashMap;

/// A known value (a general register's 64 bits, a vector's lane, a mask's
/// bits, the flags' ZF as 0 or 1), or unknown.
type V = Option<u64>;

#[derive(Clone, Default, PartialEq)]
struct State {
    regs: HashMap<Reg, V>,
    /// Bytes written so far (absent: 0 as mapped).
    mem: HashMap<u64, Option<u8>>,
}

fn f(x: u64) -> f32 {
    f32::from_bits(x as u32)
}

fn b(x: f32) -> V {
    Some(u64::from(x.to_bits()))
}

impl State {
    fn get(&self, r: Reg) -> V {
        self.regs.get(&r).copied().unwrap_or(Some(0))
    }

    fn read(&self, addr: u64, n: u32) -> V {
        let mut v = 0u64;
        for k in (0..u64::from(n.min(8))).rev() {
            v = (v << 8) | u64::from(self.mem.get(&(addr + k)).copied().unwrap_or(Some(0))?);
        }
        Some(v)
    }

    /// A vector read of `n` bytes: known when every lane holds the same.
    fn read_lanes(&self, addr: u64, n: u32) -> V {
        let first = self.read(addr, 4)?;
        (0..n / 4)
            .all(|l| self.read(addr + 4 * u64::from(l), 4) == Some(first))
            .then_some(first)
    }

    fn write(&mut self, addr: u64, n: u32, v: V, lane_bytes: u32) {
        for k in 0..u64::from(n) {
            let byte = v.map(|v| (v >> (8 * (k % u64::from(lane_bytes)))) as u8);
            self.mem.insert(addr + k, byte);
        }
    }
}

struct Ctx {
    lanes: u32,
    vbytes: u32,
}

impl Ctx {
    fn full(&self) -> u64 {
        (1u64 << self.lanes) - 1
    }
    fn sign_mask(&self, c: u64) -> u64 {
        if c >> 31 & 1 == 1 {
            self.full()
        } else {
            0
        }
    }
}

fn imm(x: &Inst) -> u64 {
    x.ops
        .iter()
        .find_map(|o| match o {
            Opnd::Imm(v) => Some(*v as u32 as u64),
            _ => None,
        })
        .unwrap_or(0)
}

/// All inputs known and alike: that value.
fn same(u: &[V]) -> V {
    let first = (*u.first()?)?;
    u.iter().all(|&v| v == Some(first)).then_some(first)
}

/// The value an instruction defines (its first register) and the flags'.
fn eval(x: &Inst, st: &State, c: &Ctx) -> (V, V) {
    let u: Vec<V> = x.uses.iter().map(|&r| st.get(r)).collect();
    let a = u.first().copied().flatten();
    // A one-register compare or test (`test r, r`) reads it twice.
    let bb = u.get(1).or(u.first()).copied().flatten();
    let m = x.mem.as_ref();
    let width = m.map_or(0, |m| m.bytes);
    let load = |n| m.and_then(|m| st.read(m.addr, n));
    let two = |g: fn(u64, u64) -> u64| Some(g(a?, bb?));
    let fl = |r: V| r.map(|r| u64::from(r == 0));
    let mn = x.code.mnemonic();
    let store_like = x.class.is_store();
    if store_like {
        return (None, None);
    }
    match mn {
        N::Mov if matches!(x.ops.get(1), Some(Opnd::Imm(_))) => (Some(imm(x)), None),
        N::Mov if x.class.is_load() => (load(width), None),
        N::Mov | N::Vmovaps | N::Kmovw if x.class.is_load() => (load(width), None),
        N::Mov | N::Vmovaps => (a, None),
        N::Movzx => (load(width), None),
        N::Shl => {
            let r = a.map(|a| a << imm(x));
            (r, fl(r))
        }
        N::Add => {
            let r = two(u64::wrapping_add);
            (r, fl(r))
        }
        N::And => {
            let r = two(|a, b| a & b);
            (r, fl(r))
        }
        N::Imul => (two(u64::wrapping_mul), None),
        N::Popcnt => (a.map(|a| u64::from(a.count_ones())), fl(a)),
        N::Lea => {
            let m = m.expect("lea has an address");
            let s: V = m
                .regs
                .iter()
                .try_fold(m.addr, |s, &r| Some(s.wrapping_add(st.get(r)?)));
            (s, None)
        }
        // `cmp r, r` (a compare with its constant operand dropped) is equal
        // whatever r holds.
        N::Cmp if x.uses.len() == 1 => (None, Some(1)),
        N::Cmp => (None, two(|a, b| u64::from(a == b))),
        N::Test => (None, two(|a, b| u64::from(a & b == 0))),
        N::Setne => {
            let r = bb.zip(a).map(|(d, zf)| (d & !0xff) | (zf ^ 1));
            (r, None)
        }
        N::Cmovne => {
            let zf = a;
            let r = match zf {
                Some(0) => u.get(2).copied().flatten(),
                Some(_) => bb,
                None => None,
            };
            (r, None)
        }
        N::Xor | N::Vxorps | N::Kxorw | N::Vpxord => (Some(0), Some(1)),
        N::Vmovmskps | N::Vpmovd2m => (a.map(|a| c.sign_mask(a)), None),
        N::Vpmovm2d => (
            a.and_then(|k| {
                if k == c.full() {
                    Some(0xffff_ffff)
                } else if k == 0 {
                    Some(0)
                } else {
                    None
                }
            }),
            None,
        ),
        N::Kmovw if x.class.is_load() => (load(2), None),
        N::Kmovw => (a.map(|a| a & c.full()), None),
        N::Vmovd if matches!(x.uses.first(), Some(Reg::G(_))) => {
            (a.filter(|&a| a as u32 == 0), None)
        }
        N::Vmovd => (a.map(|a| a & 0xffff_ffff), None),
        N::Vcvttss2si => {
            let r = a.map(|a| {
                let v = f(a);
                if v.is_nan() || v.abs() >= 2_147_483_648.0 {
                    0x8000_0000
                } else {
                    u64::from(v as i32 as u32)
                }
            });
            (r, None)
        }
        N::Vaddps => (two(|a, b| u64::from((f(a) + f(b)).to_bits())), None),
        N::Vmulps => (two(|a, b| u64::from((f(a) * f(b)).to_bits())), None),
        N::Vdivps | N::Vdivss => (two(|a, b| u64::from((f(a) / f(b)).to_bits())), None),
        N::Vminps => (two(|a, b| if f(a) < f(b) { a } else { b }), None),
        N::Vsqrtps => (a.and_then(|a| b(f(a).sqrt())), None),
        N::Vrcpps | N::Vrcp14ps | N::Vrsqrtps | N::Vrsqrt14ps => (
            a.filter(|&a| a == 0)
                .map(|_| u64::from(f32::INFINITY.to_bits())),
            None,
        ),
        N::Vfmadd231ps => {
            let c3 = u.get(2).copied().flatten();
            let r = (|| Some(u64::from(f(bb?).mul_add(f(c3?), f(a?)).to_bits())))();
            (r, None)
        }
        N::Vandps | N::Vpand | N::Vpandd | N::Kandw => (two(|a, b| a & b), None),
        N::Knotw => (a.map(|a| !a & c.full()), None),
        N::Vcmpps => {
            let eq = two(|a, b| u64::from(f(a) == f(b)));
            let mask = if matches!(x.defs.first(), Some(Reg::K(_))) {
                c.full()
            } else {
                0xffff_ffff
            };
            (eq.map(|e| if e == 1 { mask } else { 0 }), None)
        }
        N::Vpcmpeqd => {
            let mask = if matches!(x.defs.first(), Some(Reg::K(_))) {
                c.full()
            } else {
                0xffff_ffff
            };
            (
                two(|a, b| u64::from(a == b)).map(|e| if e == 1 { mask } else { 0 }),
                None,
            )
        }
        N::Vblendvps => {
            let k = u.get(2).copied().flatten();
            (k.and_then(|k| if k >> 31 & 1 == 1 { bb } else { a }), None)
        }
        N::Vblendmps => {
            let k = u.get(2).copied().flatten();
            (
                k.and_then(|k| {
                    if k == c.full() {
                        bb
                    } else if k == 0 {
                        a
                    } else {
                        None
                    }
                }),
                None,
            )
        }
        N::Vshufps | N::Vpermps | N::Vpermilps | N::Vbroadcastss if x.mem.is_none() => {
            (same(&u), None)
        }
        N::Vpbroadcastd => (a.map(|a| a & 0xffff_ffff), None),
        N::Vcvtdq2ps => (a.and_then(|a| b(a as u32 as i32 as f32)), None),
        N::Vpaddd => (
            two(|a, b| u64::from((a as u32).wrapping_add(b as u32))),
            None,
        ),
        N::Vpmulld => (
            two(|a, b| u64::from((a as u32).wrapping_mul(b as u32))),
            None,
        ),
        N::Vpslld => (a.map(|a| u64::from((a as u32) << imm(x))), None),
        N::Vpinsrd | N::Vinsertps => (
            two(|a, b| a ^ (b & 0xffff_ffff)).filter(|&d| d == 0).and(a),
            None,
        ),
        N::Vcvtsi2ss => (
            bb.and_then(|r| b(r as u32 as i32 as f32))
                .filter(|&v| Some(v) == a),
            None,
        ),
        N::Vmovups | N::Vbroadcastf128 | N::Vbroadcastf32x4 | N::Vbroadcastf32x8
            if x.opmask.is_none() =>
        {
            (m.and_then(|m| st.read_lanes(m.addr, m.bytes)), None)
        }
        N::Vbroadcastss => (load(4), None),
        N::Vmovss => (load(4).filter(|&v| v == 0), None),
        N::Vmaskmovps => match a {
            Some(k) if k >> 31 & 1 == 1 => (m.and_then(|m| st.read_lanes(m.addr, m.bytes)), None),
            Some(_) => (Some(0), None),
            None => (None, None),
        },
        N::Vmovups => match a {
            Some(k) if k == c.full() => (m.and_then(|m| st.read_lanes(m.addr, m.bytes)), None),
            Some(0) => (bb, None),
            _ => (None, None),
        },
        N::Vgatherdps => {
            let k = u.get(2).copied().flatten();
            let full = if c.vbytes == 64 {
                c.full()
            } else {
                0xffff_ffff
            };
            match k {
                Some(k) if k & full == full || k >> 31 & 1 == 1 => (load(4), None),
                Some(0) => (a, None),
                _ => (None, None),
            }
        }
        N::Vucomiss => (
            None,
            two(|a, b| u64::from(f(a) == f(b) || f(a).is_nan() || f(b).is_nan())),
        ),
        N::Vtestps => (None, two(|a, b| u64::from((a & b) >> 31 & 1 == 0))),
        N::Kortestw => (None, two(|a, b| u64::from(a | b == 0))),
        _ => (None, None),
    }
}

/// What a store writes.
fn store(x: &Inst, st: &mut State, c: &Ctx) {
    let Some(m) = x.mem.as_ref() else { return };
    let data = x.uses.last().map_or(Some(0), |&r| st.get(r));
    let k = if x.class.is_per_lane_mem() {
        x.uses.get(1)
    } else {
        x.uses.first()
    }
    .map(|&r| st.get(r));
    let masked =
        x.opmask.is_some() || x.code.mnemonic() == N::Vmaskmovps || x.class.is_per_lane_mem();
    let lane = if x.class.is_vector() {
        4
    } else {
        m.bytes.max(1)
    };
    let n = if x.code.mnemonic() == N::Vcompressps {
        match k.flatten() {
            Some(k) => 4 * (k & c.full()).count_ones(),
            None => m.bytes * c.lanes,
        }
    } else if x.class.is_per_lane_mem() {
        4
    } else {
        m.bytes
    };
    let on = match (masked, k.flatten()) {
        (false, _) => Some(true),
        (true, Some(k)) if x.code.mnemonic() == N::Vmaskmovps => Some(k >> 31 & 1 == 1),
        (true, Some(k)) if k & c.full() == c.full() => Some(true),
        (true, Some(0)) => Some(false),
        _ => None,
    };
    match on {
        Some(true) => st.write(m.addr, n, data, lane),
        Some(false) => {}
        None => st.write(m.addr, n, None, lane),
    }
}

/// One iteration from `st`: each instruction's inputs, and the state at
/// the bottom.
fn iterate(p: &Program, st: &mut State, c: &Ctx) -> Vec<Vec<V>> {
    // At the top the flags are the loop's `dec`'s that did not exit: ZF clear.
    st.regs.insert(Reg::Flags, Some(0));
    let mut seen = Vec::with_capacity(p.insts.len());
    for x in &p.insts {
        let regs = x
            .mem
            .iter()
            .flat_map(|m| m.regs.iter().chain(m.vindex.iter()));
        seen.push(regs.chain(x.uses.iter()).map(|&r| st.get(r)).collect());
        if x.class.is_store() {
            store(x, st, c);
        }
        let (v, zf) = eval(x, st, c);
        for &d in &x.defs {
            st.regs.insert(d, if d == Reg::Flags { zf } else { v });
        }
    }
    seen
}

/// Unknown wherever `a` and `b` differ.
fn join(a: &State, b: &State) -> State {
    let mut out = a.clone();
    for (r, v) in &b.regs {
        let before = a.regs.get(r).copied().unwrap_or(Some(0));
        out.regs.insert(*r, if before == *v { *v } else { None });
    }
    for (k, v) in &b.mem {
        let before = a.mem.get(k).copied().unwrap_or(Some(0));
        out.mem.insert(*k, if before == *v { *v } else { None });
    }
    out
}

/// The loop's steady state: a state at the top that one iteration maps to
/// itself (values still changing after 16 iterations, such as counters,
/// made unknown), and each instruction's inputs from it. The replay
/// starts from that state (registers and buffer set before the loop), so
/// every iteration sees the same values.
fn steady(p: &Program) -> Result<(State, Vec<Vec<V>>), String> {
    let c = Ctx {
        lanes: p.lanes,
        vbytes: p.vbytes,
    };
    let mut head = State::default();
    for round in 0..80 {
        let mut st = head.clone();
        let seen = iterate(p, &mut st, &c);
        st.regs.insert(Reg::Flags, Some(0));
        let next = if round < 16 { st } else { join(&head, &st) };
        if next == head {
            return Ok((head, seen));
        }
        head = next;
    }
    Err("the value analysis found no steady state in 80 iterations".into())
}

/// Fix the program by what the analysis knows: each address register of
/// known value stays and the displacement takes its value off; one of
/// unknown value leaves the address (counted); each branch jumps on the
/// flag state that makes its direction the recorded one.
///
/// # Errors
/// A gather or scatter whose index is unknown (its lanes could leave the
/// buffer), or an address that does not fit a displacement.
pub fn fix(p: &mut Program) -> Result<(), String> {
    let (head, seen) = steady(p)?;
    p.init_regs = head
        .regs
        .iter()
        .filter(|(r, _)| **r != Reg::Flags)
        .filter_map(|(r, v)| Some((*r, (*v)?)))
        .filter(|(_, v)| *v != 0)
        .collect();
    p.init_regs.sort();
    p.init_mem = head
        .mem
        .iter()
        .filter_map(|(a, v)| Some((*a, (*v)?)))
        .filter(|(_, v)| *v != 0)
        .collect();
    p.init_mem.sort();
    for (x, ins) in p.insts.iter_mut().zip(&seen) {
        x.inputs.clone_from(ins);
        if let Some(m) = x.mem.as_mut().filter(|_| x.class.is_mem()) {
            let nregs = m.regs.len();
            let mut off = 0u64;
            if m.vindex.is_some() {
                let i = ins
                    .get(nregs)
                    .copied()
                    .flatten()
                    .ok_or("a gather's or scatter's index is unknown")?;
                off = off.wrapping_add((i as u32 as i32 as i64 as u64).wrapping_mul(4));
            }
            let mut keep = Vec::new();
            for (r, v) in m.regs.iter().zip(ins) {
                match v {
                    Some(v) => {
                        keep.push(*r);
                        off = off.wrapping_add(*v);
                    }
                    None => p.changes.dropped_address_deps += 1,
                }
            }
            // A register holding more than a displacement can take off
            // leaves the address too.
            let fits = |o: u64| {
                (i64::from(i32::MIN)..=i64::from(i32::MAX))
                    .contains(&(m.addr.wrapping_sub(o) as i64))
            };
            let mut k = 0;
            while !fits(off) && k < keep.len() {
                let v = ins[nregs_index(&m.regs, &keep[k])].unwrap_or(0);
                off = off.wrapping_sub(v);
                keep.remove(k);
                p.changes.dropped_address_deps += 1;
                k = 0;
            }
            if !fits(off) {
                return Err(format!(
                    "a gather's index reaches {off:#x}, beyond a displacement's reach"
                ));
            }
            m.regs = keep;
            m.disp = m.addr.wrapping_sub(off);
        }
        if x.class == isa::OpClass::Branch {
            x.jump_if_zero = Some(match ins.last().copied().flatten() {
                Some(1) => x.taken,
                Some(_) => !x.taken,
                None => {
                    p.changes.unknown_branches += 1;
                    x.taken
                }
            });
        }
    }
    Ok(())
}

fn nregs_index(regs: &[Reg], r: &Reg) -> usize {
    regs.iter().position(|x| x == r).unwrap_or(0)
}
