//! Instruction selection: each recorded op as the x86-64 instruction its
//! class names on the recorded flavour (AVX2 and SSE4 as VEX forms,
//! AVX-512 as EVEX forms with mask registers), over the registers the
//! allocator hands out.

use crate::alloc::{copy, Alloc};
use crate::files::{address_sources, infer};
use crate::layout::{first_addr, Layout};
use crate::program::{Changes, File, Inst, MemRef, Opnd, Program, Reg};
use iced_x86::Code;
use isa::{FlavourId, Op, OpClass, Trace, ValId};
use std::collections::HashMap;

/// Width-dependent codes: (SSE4 as VEX.128, AVX2 VEX.256, AVX-512 EVEX.512).
type W = (Code, Code, Code);

struct Sel<'a> {
    trace: &'a Trace,
    ops: &'a [Op],
    file: HashMap<ValId, File>,
    a: Alloc,
    layout: Layout,
    out: Vec<Inst>,
    vbytes: u32,
    avx512: bool,
    mask_regs: bool,
    /// The value whose flags are current.
    flags: Option<ValId>,
    changes: Changes,
}

/// The window `trace.ops[range]` as a loop body.
///
/// # Errors
/// A flavour the host cannot run (LRBni, the 32-lane what-if), or an op
/// whose form the replay does not build.
pub fn select(trace: &Trace, range: std::ops::Range<usize>) -> Result<Program, String> {
    let (vbytes, avx512, vregs) = match trace.flavour {
        FlavourId::Sse4 => (16, false, 16),
        FlavourId::Avx2 => (32, false, 16),
        FlavourId::Avx512 => (64, true, 32),
        f => return Err(format!("flavour {} does not run on x86-64 hosts", f.name())),
    };
    let ops = &trace.ops[range];
    let mut uses: HashMap<ValId, Vec<usize>> = HashMap::new();
    for (i, o) in ops.iter().enumerate() {
        for &s in o.sources() {
            uses.entry(s).or_default().push(i);
        }
    }
    let layout = Layout::of(trace, ops);
    let mut s = Sel {
        trace,
        ops,
        file: infer(ops, avx512),
        a: Alloc::new(uses, vregs, avx512, vbytes, layout.spill_base),
        layout,
        out: Vec::new(),
        vbytes,
        avx512,
        mask_regs: avx512,
        flags: None,
        changes: Changes::default(),
    };
    for i in 0..ops.len() {
        s.op(i)?;
        s.a.release(i);
    }
    let mut changes = s.changes;
    changes.spills = s.a.spills;
    changes.added = s.out.iter().filter(|x| !x.recorded).count();
    Ok(Program {
        buffer_bytes: s.layout.bytes(s.a.slots()),
        insts: s.out,
        vbytes,
        lanes: trace.flavour.lanes() as u32,
        recorded_ops: ops.len(),
        changes,
        init_regs: Vec::new(),
        init_mem: Vec::new(),
    })
}

impl Sel<'_> {
    fn w(&self, (s, a, z): W) -> Code {
        match (self.avx512, self.vbytes) {
            (true, _) => z,
            (_, 32) => a,
            _ => s,
        }
    }

    fn file_of(&self, v: ValId) -> File {
        self.file.get(&v).copied().unwrap_or(File::V)
    }

    /// A register holding source `v` in `want` (a value in another file is
    /// moved across first: `vmovd`, `kmovw`).
    fn src(&mut self, v: ValId, want: File, i: usize, keep: &[Reg]) -> Reg {
        let have = match self.file_of(v) {
            File::Flags => File::G,
            f => f,
        };
        let r = self.a.read(v, have, i, keep, &mut self.out);
        let want = if want == File::Flags { File::G } else { want };
        if have == want {
            return r;
        }
        let mut k = keep.to_vec();
        k.push(r);
        let t = self.a.temp(want, i, &k, &mut self.out);
        let code = match (want, have, self.avx512) {
            (File::V, File::G, false) => Code::VEX_Vmovd_xmm_rm32,
            (File::V, File::G, true) => Code::EVEX_Vmovd_xmm_rm32,
            (File::G, File::V, false) => Code::VEX_Vmovd_rm32_xmm,
            (File::G, File::V, true) => Code::EVEX_Vmovd_rm32_xmm,
            (File::K, File::G, _) => Code::VEX_Kmovw_kr_r32,
            (File::G, File::K, _) => Code::VEX_Kmovw_r32_kr,
            (File::V, File::K, _) => Code::EVEX_Vpmovm2d_zmm_kr,
            (File::K, File::V, _) => Code::EVEX_Vpmovd2m_kr_zmm,
            _ => Code::Mov_r64_rm64,
        };
        let mut m = Inst::new(OpClass::Mov, self.ops[i].region, code);
        m.ops = vec![Opnd::R(t), Opnd::R(r)];
        m.defs = vec![t];
        m.uses = vec![r];
        m.recorded = false;
        self.out.push(m);
        t
    }

    /// The destination register of op `i`: a fresh one, or (`tied`) the
    /// register of the source it overwrites, copied first when that
    /// source is still read later.
    fn dst(&mut self, i: usize, file: File, tied: Option<Reg>, keep: &[Reg]) -> Reg {
        let o = self.ops[i];
        match tied {
            Some(r) => {
                let tied_v = self.a.holder(r);
                if tied_v.is_some_and(|v| self.a.live_after(v, i)) {
                    let d = self.a.take(file, i, keep, &mut self.out);
                    self.out.push(copy(d, r, self.vbytes, self.avx512));
                    self.bind_dst(o.dst, d);
                    d
                } else {
                    self.bind_dst(o.dst, r);
                    r
                }
            }
            None => {
                let d = self.a.take(file, i, keep, &mut self.out);
                self.bind_dst(o.dst, d);
                d
            }
        }
    }

    fn bind_dst(&mut self, v: ValId, r: Reg) {
        if v.is_some() {
            self.a.bind(v, r);
        }
    }

    fn push(&mut self, mut m: Inst, i: usize) {
        m.region = self.ops[i].region;
        if m.defs.contains(&Reg::Flags) {
            self.flags = if m.recorded {
                Some(self.ops[i].dst)
            } else {
                None
            };
        }
        self.out.push(m);
    }

    /// The memory operand of memory op `i`: its recorded address in the
    /// buffer, its address registers where they are general registers.
    fn mem(&mut self, i: usize, keep: &mut Vec<Reg>) -> MemRef {
        let o = self.ops[i];
        let mut m = MemRef::at(
            self.layout.host(first_addr(self.trace, &o)),
            o.bytes,
            o.class.is_store(),
        );
        for &v in address_sources(&o, self.mask_regs).iter().take(2) {
            if self.file_of(v) == File::G {
                let r = self.src(v, File::G, i, keep);
                keep.push(r);
                m.regs.push(r);
            } else {
                self.changes.dropped_address_deps += 1;
            }
        }
        m
    }

    fn op(&mut self, i: usize) -> Result<(), String> {
        let o = self.ops[i];
        if o.class.is_mem() {
            return self.mem_op(i);
        }
        match o.class {
            OpClass::Branch => self.branch(i),
            OpClass::Cmp | OpClass::KTest => self.flags_op(i),
            OpClass::VCmp | OpClass::VICmp if self.file_of(o.dst) == File::Flags => {
                self.flags_op(i)
            }
            OpClass::Alu | OpClass::IMul | OpClass::BitCnt | OpClass::Lea3 => self.int_op(i),
            OpClass::Cmov => self.cmov(i),
            OpClass::Mov | OpClass::Zero => self.mov_zero(i),
            _ => self.vec_op(i),
        }
    }
}

mod emit;
