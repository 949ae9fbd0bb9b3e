//! Each op class as its instruction.

use super::Sel;
use crate::program::{File, Inst, Opnd, Reg};
use iced_x86::Code;
use isa::{OpClass, ValId};

/// Classes whose instruction, as selected here, writes the flags.
fn writes_flags(c: OpClass) -> bool {
    matches!(
        c,
        OpClass::Alu | OpClass::IMul | OpClass::BitCnt | OpClass::Cmp | OpClass::KTest
    )
}

impl Sel<'_> {
    fn inst(&self, class: OpClass, code: Code) -> Inst {
        Inst::new(class, isa::Region::Other, code)
    }

    fn srcs(&mut self, i: usize, want: File) -> Vec<Reg> {
        let o = self.ops[i];
        let mut keep = Vec::new();
        for &v in o.sources() {
            let r = self.src(v, want, i, &keep);
            keep.push(r);
        }
        keep
    }

    /// Whether flags value `v` (op `i`'s) must also be a 0/1 register:
    /// read other than as flags, or after another instruction wrote them.
    fn needs_gpr(&self, i: usize) -> bool {
        let v = self.ops[i].dst;
        let mut clobbered = false;
        for o in &self.ops[i + 1..] {
            if let Some(j) = o.sources().iter().position(|&s| s == v) {
                let as_flags =
                    matches!(o.class, OpClass::Branch) || (o.class == OpClass::Cmov && j == 0);
                if !as_flags || clobbered {
                    return true;
                }
            }
            clobbered |= writes_flags(o.class);
        }
        false
    }

    pub(super) fn flags_op(&mut self, i: usize) -> Result<(), String> {
        let o = self.ops[i];
        let (code, want) = match o.class {
            OpClass::Cmp => (Code::Cmp_rm64_r64, File::G),
            OpClass::KTest if self.mask_regs => (Code::VEX_Kortestw_kr_kr, File::K),
            OpClass::KTest if self.vbytes == 32 => (Code::VEX_Vtestps_ymm_ymmm256, File::V),
            OpClass::KTest => (Code::VEX_Vtestps_xmm_xmmm128, File::V),
            _ if self.avx512 => (Code::EVEX_Vucomiss_xmm_xmmm32_sae, File::V),
            _ => (Code::VEX_Vucomiss_xmm_xmmm32, File::V),
        };
        let mut s = self.srcs(i, want);
        if s.is_empty() {
            let r = self.a.temp(want, i, &[], &mut self.out);
            s.push(r);
        }
        let b = *s.get(1).unwrap_or(&s[0]);
        let mut m = self.inst(o.class, code);
        m.ops = vec![Opnd::R(s[0]), Opnd::R(b)];
        m.uses = s.clone();
        m.defs = vec![Reg::Flags];
        self.push(m, i);
        if self.needs_gpr(i) {
            let d = self.a.take(File::G, i, &s, &mut self.out);
            let mut set = self.inst(OpClass::Alu, Code::Setne_rm8);
            set.ops = vec![Opnd::R(d)];
            set.uses = vec![Reg::Flags, d];
            set.defs = vec![d];
            set.recorded = false;
            self.push(set, i);
            self.a.bind(o.dst, d);
        }
        Ok(())
    }

    /// The flags of value `v` current for op `i`: tested from its
    /// register when another instruction wrote them since.
    fn flags_of(&mut self, v: ValId, i: usize, keep: &[Reg]) {
        if v.is_some() && self.flags == Some(v) {
            return;
        }
        let r = if v.is_some() {
            self.src(v, File::G, i, keep)
        } else {
            self.a.temp(File::G, i, keep, &mut self.out)
        };
        let mut t = self.inst(OpClass::Cmp, Code::Test_rm64_r64);
        t.ops = vec![Opnd::R(r), Opnd::R(r)];
        t.uses = vec![r];
        t.defs = vec![Reg::Flags];
        t.recorded = false;
        self.push(t, i);
        self.flags = Some(v);
    }

    pub(super) fn branch(&mut self, i: usize) -> Result<(), String> {
        let o = self.ops[i];
        let c = o.sources().first().copied().unwrap_or(ValId::NONE);
        self.flags_of(c, i, &[]);
        let mut b = self.inst(OpClass::Branch, Code::Je_rel32_64);
        b.uses = vec![Reg::Flags];
        b.taken = o.taken();
        self.push(b, i);
        Ok(())
    }

    pub(super) fn cmov(&mut self, i: usize) -> Result<(), String> {
        let o = self.ops[i];
        let s = o.sources();
        let (c, a, b) = match s.len() {
            3 => (s[0], Some(s[1]), Some(s[2])),
            2 => (s[0], Some(s[1]), None),
            1 => (s[0], None, None),
            _ => (ValId::NONE, None, None),
        };
        let mut keep = Vec::new();
        let ra = match a {
            Some(v) => self.src(v, File::G, i, &keep),
            None => self.a.temp(File::G, i, &keep, &mut self.out),
        };
        keep.push(ra);
        let rb = b.map(|v| self.src(v, File::G, i, &keep));
        keep.extend(rb);
        self.flags_of(c, i, &keep);
        let d = self.dst(i, File::G, rb, &keep);
        let mut m = self.inst(OpClass::Cmov, Code::Cmovne_r64_rm64);
        m.ops = vec![Opnd::R(d), Opnd::R(ra)];
        m.uses = vec![Reg::Flags, d, ra];
        m.defs = vec![d];
        self.push(m, i);
        Ok(())
    }

    pub(super) fn int_op(&mut self, i: usize) -> Result<(), String> {
        let o = self.ops[i];
        let s = self.srcs(i, File::G);
        let dies = |this: &Self, k: usize| !this.a.live_after(o.sources()[k], i);
        let mut m = match (o.class, s.len()) {
            (OpClass::Alu, 0) => {
                let d = self.dst(i, File::G, None, &s);
                let mut m = self.inst(o.class, Code::Mov_r32_imm32);
                m.ops = vec![Opnd::R(d), Opnd::Imm(0)];
                m.defs = vec![d];
                m
            }
            (OpClass::Alu, 1) if dies(self, 0) => {
                let d = self.dst(i, File::G, Some(s[0]), &s);
                // `and r, r`: one ALU uop that keeps the value, so loop-carried
                // values settle (a shift or add would grow them every iteration).
                let mut m = self.inst(o.class, Code::And_rm64_r64);
                m.ops = vec![Opnd::R(d), Opnd::R(d)];
                m.uses = vec![d];
                m.defs = vec![d, Reg::Flags];
                m
            }
            (OpClass::Alu | OpClass::IMul, _)
                if s.len() >= 2 && (dies(self, 0) || dies(self, 1) || o.class == OpClass::IMul) =>
            {
                let (t, x) = if dies(self, 0) || !dies(self, 1) {
                    (s[0], s[1])
                } else {
                    (s[1], s[0])
                };
                let d = self.dst(i, File::G, Some(t), &s);
                let code = if o.class == OpClass::IMul {
                    Code::Imul_r64_rm64
                } else {
                    Code::And_rm64_r64
                };
                let mut m = self.inst(o.class, code);
                m.ops = vec![Opnd::R(d), Opnd::R(x)];
                m.uses = vec![d, x];
                m.defs = vec![d, Reg::Flags];
                m
            }
            (OpClass::IMul, 1) => {
                let d = self.dst(i, File::G, Some(s[0]), &s);
                let mut m = self.inst(o.class, Code::Imul_r64_rm64);
                m.ops = vec![Opnd::R(d), Opnd::R(d)];
                m.uses = vec![d];
                m.defs = vec![d, Reg::Flags];
                m
            }
            (OpClass::BitCnt, _) => {
                let d = self.dst(i, File::G, None, &s);
                let x = *s.first().unwrap_or(&d);
                let mut m = self.inst(o.class, Code::Popcnt_r64_rm64);
                m.ops = vec![Opnd::R(d), Opnd::R(x)];
                m.uses = vec![x];
                m.defs = vec![d, Reg::Flags];
                m
            }
            _ => {
                // lea: `[a]` or `[a + b]` for alu (a non-destructive form), three
                // components for lea3.
                let d = self.dst(i, File::G, None, &s);
                let mut m = self.inst(o.class, Code::Lea_r64_m);
                let base = s.first().copied();
                let index = if o.class == OpClass::Lea3 {
                    s.get(1).copied().or(base)
                } else {
                    s.get(1).copied()
                };
                let mut mr = crate::program::MemRef::at(
                    if o.class == OpClass::Lea3 { 8 } else { 0 },
                    0,
                    false,
                );
                mr.regs = base.into_iter().chain(index).collect();
                m.mem = Some(mr);
                m.ops = vec![Opnd::R(d), Opnd::M];
                m.uses = s.clone();
                m.defs = vec![d];
                m
            }
        };
        m.class = o.class;
        self.push(m, i);
        Ok(())
    }

    pub(super) fn mov_zero(&mut self, i: usize) -> Result<(), String> {
        let o = self.ops[i];
        let f = self.file_of(o.dst);
        if o.class == OpClass::Mov && !o.sources().is_empty() {
            let s = self.srcs(i, f);
            let d = self.dst(i, f, None, &s);
            let mut m = crate::alloc::copy(d, s[0], self.vbytes, self.avx512);
            m.recorded = true;
            self.push(m, i);
            return Ok(());
        }
        let d = self.dst(i, f, None, &[]);
        let code = match f {
            File::V if self.avx512 => Code::EVEX_Vxorps_zmm_k1z_zmm_zmmm512b32,
            File::V if self.vbytes == 32 => Code::VEX_Vxorps_ymm_ymm_ymmm256,
            File::V => Code::VEX_Vxorps_xmm_xmm_xmmm128,
            File::K => Code::VEX_Kxorw_kr_kr_kr,
            _ => Code::Xor_r32_rm32,
        };
        let mut m = self.inst(OpClass::Zero, code);
        m.ops = if code == Code::Xor_r32_rm32 {
            vec![Opnd::R(d), Opnd::R(d)]
        } else {
            vec![Opnd::R(d), Opnd::R(d), Opnd::R(d)]
        };
        m.defs = if f == File::G {
            vec![d, Reg::Flags]
        } else {
            vec![d]
        };
        self.push(m, i);
        Ok(())
    }
}

mod vector;
