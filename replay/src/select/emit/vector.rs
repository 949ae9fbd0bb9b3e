//! Vector and memory ops.

use super::super::Sel;
use crate::program::{File, Inst, Opnd, Reg};
use iced_x86::Code as C;
use isa::OpClass;

/// (SSE4 as VEX.128, AVX2, AVX-512) codes of a two-source op.
fn binary(class: OpClass) -> Option<(C, C, C)> {
    Some(match class {
        OpClass::VAdd => (
            C::VEX_Vaddps_xmm_xmm_xmmm128,
            C::VEX_Vaddps_ymm_ymm_ymmm256,
            C::EVEX_Vaddps_zmm_k1z_zmm_zmmm512b32_er,
        ),
        OpClass::VMul => (
            C::VEX_Vmulps_xmm_xmm_xmmm128,
            C::VEX_Vmulps_ymm_ymm_ymmm256,
            C::EVEX_Vmulps_zmm_k1z_zmm_zmmm512b32_er,
        ),
        OpClass::VDiv => (
            C::VEX_Vdivps_xmm_xmm_xmmm128,
            C::VEX_Vdivps_ymm_ymm_ymmm256,
            C::EVEX_Vdivps_zmm_k1z_zmm_zmmm512b32_er,
        ),
        OpClass::VMinMax => (
            C::VEX_Vminps_xmm_xmm_xmmm128,
            C::VEX_Vminps_ymm_ymm_ymmm256,
            C::EVEX_Vminps_zmm_k1z_zmm_zmmm512b32_sae,
        ),
        OpClass::VLogic => (
            C::VEX_Vandps_xmm_xmm_xmmm128,
            C::VEX_Vandps_ymm_ymm_ymmm256,
            C::EVEX_Vandps_zmm_k1z_zmm_zmmm512b32,
        ),
        OpClass::VIAdd => (
            C::VEX_Vpaddd_xmm_xmm_xmmm128,
            C::VEX_Vpaddd_ymm_ymm_ymmm256,
            C::EVEX_Vpaddd_zmm_k1z_zmm_zmmm512b32,
        ),
        OpClass::VIMul => (
            C::VEX_Vpmulld_xmm_xmm_xmmm128,
            C::VEX_Vpmulld_ymm_ymm_ymmm256,
            C::EVEX_Vpmulld_zmm_k1z_zmm_zmmm512b32,
        ),
        OpClass::VILogic => (
            C::VEX_Vpand_xmm_xmm_xmmm128,
            C::VEX_Vpand_ymm_ymm_ymmm256,
            C::EVEX_Vpandd_zmm_k1z_zmm_zmmm512b32,
        ),
        OpClass::VPerm => (
            C::VEX_Vpermilps_xmm_xmm_xmmm128,
            C::VEX_Vpermps_ymm_ymm_ymmm256,
            C::EVEX_Vpermps_zmm_k1z_zmm_zmmm512b32,
        ),
        OpClass::VCmp => (
            C::VEX_Vcmpps_xmm_xmm_xmmm128_imm8,
            C::VEX_Vcmpps_ymm_ymm_ymmm256_imm8,
            C::EVEX_Vcmpps_kr_k1_zmm_zmmm512b32_imm8_sae,
        ),
        OpClass::VICmp => (
            C::VEX_Vpcmpeqd_xmm_xmm_xmmm128,
            C::VEX_Vpcmpeqd_ymm_ymm_ymmm256,
            C::EVEX_Vpcmpeqd_kr_k1_zmm_zmmm512b32,
        ),
        OpClass::VShuf => (
            C::VEX_Vshufps_xmm_xmm_xmmm128_imm8,
            C::VEX_Vshufps_ymm_ymm_ymmm256_imm8,
            C::EVEX_Vshufps_zmm_k1z_zmm_zmmm512b32_imm8,
        ),
        OpClass::Div => (
            C::VEX_Vdivss_xmm_xmm_xmmm32,
            C::VEX_Vdivss_xmm_xmm_xmmm32,
            C::EVEX_Vdivss_xmm_k1z_xmm_xmmm32_er,
        ),
        _ => return None,
    })
}

/// Codes of a one-source op.
fn unary(class: OpClass) -> Option<(C, C, C)> {
    Some(match class {
        OpClass::VSqrt => (
            C::VEX_Vsqrtps_xmm_xmmm128,
            C::VEX_Vsqrtps_ymm_ymmm256,
            C::EVEX_Vsqrtps_zmm_k1z_zmmm512b32_er,
        ),
        OpClass::VRcp => (
            C::VEX_Vrcpps_xmm_xmmm128,
            C::VEX_Vrcpps_ymm_ymmm256,
            C::EVEX_Vrcp14ps_zmm_k1z_zmmm512b32,
        ),
        OpClass::VRsqrt => (
            C::VEX_Vrsqrtps_xmm_xmmm128,
            C::VEX_Vrsqrtps_ymm_ymmm256,
            C::EVEX_Vrsqrt14ps_zmm_k1z_zmmm512b32,
        ),
        OpClass::VCvt => (
            C::VEX_Vcvtdq2ps_xmm_xmmm128,
            C::VEX_Vcvtdq2ps_ymm_ymmm256,
            C::EVEX_Vcvtdq2ps_zmm_k1z_zmmm512b32_er,
        ),
        OpClass::VIShift => (
            C::VEX_Vpslld_xmm_xmm_imm8,
            C::VEX_Vpslld_ymm_ymm_imm8,
            C::EVEX_Vpslld_zmm_k1z_zmmm512b32_imm8,
        ),
        OpClass::VBcast => (
            C::VEX_Vbroadcastss_xmm_xmm,
            C::VEX_Vbroadcastss_ymm_xmm,
            C::EVEX_Vbroadcastss_zmm_k1z_xmmm32,
        ),
        _ => return None,
    })
}

impl Sel<'_> {
    fn reg_or_temp(&mut self, s: &[Reg], k: usize, file: File, i: usize) -> Reg {
        match s.get(k) {
            Some(&r) => r,
            None => self.a.temp(file, i, s, &mut self.out),
        }
    }

    pub(in crate::select) fn vec_op(&mut self, i: usize) -> Result<(), String> {
        let o = self.ops[i];
        let dfile = self.file_of(o.dst);
        match o.class {
            OpClass::VFma => return self.fma(i),
            OpClass::VBlend | OpClass::VMaskMov => return self.blend(i),
            OpClass::VInsert => return self.insert(i),
            OpClass::KLogic => return self.klogic(i),
            OpClass::MovMsk => return self.movmsk(i),
            OpClass::VCvt
                if o.mask.0 == 1 && dfile != File::V || self.src_file(i, 0) == Some(File::G) =>
            {
                return self.scalar_cvt(i)
            }
            OpClass::VBcast if self.src_file(i, 0) == Some(File::G) && self.avx512 => {
                let s = self.srcs(i, File::G);
                let d = self.dst(i, File::V, None, &s);
                let mut m = self.inst(o.class, C::EVEX_Vpbroadcastd_zmm_k1z_r32);
                m.ops = vec![Opnd::R(d), Opnd::R(s[0])];
                m.uses = s;
                m.defs = vec![d];
                self.push(m, i);
                return Ok(());
            }
            _ => {}
        }
        if let Some(w) = binary(o.class) {
            let s = self.srcs(i, File::V);
            let a = self.reg_or_temp(&s, 0, File::V, i);
            let b = *s.get(1).unwrap_or(&a);
            let df = if matches!(o.class, OpClass::VCmp | OpClass::VICmp) && self.mask_regs {
                File::K
            } else {
                File::V
            };
            let d = self.dst(i, df, None, &[a, b]);
            let code = self.w(w);
            let mut m = self.inst(o.class, code);
            m.ops = vec![Opnd::R(d), Opnd::R(a), Opnd::R(b)];
            match o.class {
                // vcmpeqps.
                OpClass::VCmp => m.ops.push(Opnd::Imm(0)),
                OpClass::VShuf => m.ops.push(Opnd::Imm(0)),
                _ => {}
            }
            m.uses = vec![a, b];
            m.defs = vec![d];
            self.push(m, i);
            return Ok(());
        }
        if let Some(w) = unary(o.class) {
            let s = self.srcs(i, File::V);
            let a = self.reg_or_temp(&s, 0, File::V, i);
            let d = self.dst(i, File::V, None, &[a]);
            let mut m = self.inst(o.class, self.w(w));
            m.ops = vec![Opnd::R(d), Opnd::R(a)];
            if o.class == OpClass::VIShift {
                m.ops.push(Opnd::Imm(2));
            }
            m.uses = vec![a];
            m.defs = vec![d];
            self.push(m, i);
            return Ok(());
        }
        Err(format!("op class {} has no replay form", o.class.name()))
    }

    fn src_file(&self, i: usize, k: usize) -> Option<File> {
        self.ops[i]
            .sources()
            .get(k)
            .map(|&v| match self.file_of(v) {
                File::Flags => File::G,
                f => f,
            })
    }

    fn fma(&mut self, i: usize) -> Result<(), String> {
        let o = self.ops[i];
        let s = self.srcs(i, File::V);
        let a = self.reg_or_temp(&s, 0, File::V, i);
        let b = *s.get(1).unwrap_or(&a);
        let c = *s.last().unwrap_or(&a);
        let d = self.dst(i, File::V, Some(c), &[a, b]);
        let code = self.w((
            C::VEX_Vfmadd231ps_xmm_xmm_xmmm128,
            C::VEX_Vfmadd231ps_ymm_ymm_ymmm256,
            C::EVEX_Vfmadd231ps_zmm_k1z_zmm_zmmm512b32_er,
        ));
        let mut m = self.inst(o.class, code);
        m.ops = vec![Opnd::R(d), Opnd::R(a), Opnd::R(b)];
        m.uses = vec![d, a, b];
        m.defs = vec![d];
        self.push(m, i);
        Ok(())
    }

    /// `k ? t : f` (sources f, t, k): vblendvps, or vblendmps under a mask register.
    fn blend(&mut self, i: usize) -> Result<(), String> {
        let o = self.ops[i];
        let mf = if self.mask_regs { File::K } else { File::V };
        let n = o.sources().len();
        let mut keep = Vec::new();
        let mut regs = Vec::new();
        for (j, &v) in o.sources().iter().enumerate() {
            let f = if j + 1 == n && n == 3 { mf } else { File::V };
            let r = self.src(v, f, i, &keep);
            keep.push(r);
            regs.push(r);
        }
        let f = self.reg_or_temp(&regs, 0, File::V, i);
        let t = *regs.get(1).unwrap_or(&f);
        let k = match regs.get(2) {
            Some(&k) => k,
            None => self.a.temp(mf, i, &[f, t], &mut self.out),
        };
        let d = self.dst(i, File::V, None, &[f, t, k]);
        let mut m = if self.mask_regs {
            let mut m = self.inst(o.class, C::EVEX_Vblendmps_zmm_k1z_zmm_zmmm512b32);
            m.opmask = Some(k);
            m.ops = vec![Opnd::R(d), Opnd::R(f), Opnd::R(t)];
            m
        } else {
            let code = self.w((
                C::VEX_Vblendvps_xmm_xmm_xmmm128_xmm,
                C::VEX_Vblendvps_ymm_ymm_ymmm256_ymm,
                C::VEX_Vblendvps_ymm_ymm_ymmm256_ymm,
            ));
            let mut m = self.inst(o.class, code);
            m.ops = vec![Opnd::R(d), Opnd::R(f), Opnd::R(t), Opnd::R(k)];
            m
        };
        m.uses = vec![f, t, k];
        m.defs = vec![d];
        self.push(m, i);
        Ok(())
    }

    fn insert(&mut self, i: usize) -> Result<(), String> {
        let o = self.ops[i];
        let acc = match o.sources().first() {
            Some(&v) => self.src(v, File::V, i, &[]),
            None => self.a.temp(File::V, i, &[], &mut self.out),
        };
        let x = o.sources().get(1).copied();
        let xf = x.map(|v| self.file_of(v));
        let (code, xr) = match (x, xf) {
            (Some(v), Some(File::G | File::Flags)) => {
                let c = if self.avx512 {
                    C::EVEX_Vpinsrd_xmm_xmm_rm32_imm8
                } else {
                    C::VEX_Vpinsrd_xmm_xmm_rm32_imm8
                };
                (c, self.src(v, File::G, i, &[acc]))
            }
            (Some(v), _) => {
                let c = if self.avx512 {
                    C::EVEX_Vinsertps_xmm_xmm_xmmm32_imm8
                } else {
                    C::VEX_Vinsertps_xmm_xmm_xmmm32_imm8
                };
                (c, self.src(v, File::V, i, &[acc]))
            }
            (None, _) => (C::VEX_Vinsertps_xmm_xmm_xmmm32_imm8, acc),
        };
        let d = self.dst(i, File::V, None, &[acc, xr]);
        let mut m = self.inst(o.class, code);
        m.ops = vec![Opnd::R(d), Opnd::R(acc), Opnd::R(xr), Opnd::Imm(0x10)];
        m.uses = vec![acc, xr];
        m.defs = vec![d];
        self.push(m, i);
        Ok(())
    }

    fn klogic(&mut self, i: usize) -> Result<(), String> {
        let o = self.ops[i];
        if self.src_file(i, 0) == Some(File::G) {
            let s = self.srcs(i, File::G);
            let d = self.dst(i, File::K, None, &s);
            let mut m = self.inst(o.class, C::VEX_Kmovw_kr_r32);
            m.ops = vec![Opnd::R(d), Opnd::R(s[0])];
            m.uses = s;
            m.defs = vec![d];
            self.push(m, i);
            return Ok(());
        }
        let s = self.srcs(i, File::K);
        let a = self.reg_or_temp(&s, 0, File::K, i);
        let d = self.dst(i, File::K, None, &[a]);
        let mut m = if s.len() >= 2 {
            let mut m = self.inst(o.class, C::VEX_Kandw_kr_kr_kr);
            m.ops = vec![Opnd::R(d), Opnd::R(a), Opnd::R(s[1])];
            m.uses = vec![a, s[1]];
            m
        } else {
            let mut m = self.inst(o.class, C::VEX_Knotw_kr_kr);
            m.ops = vec![Opnd::R(d), Opnd::R(a)];
            m.uses = vec![a];
            m
        };
        m.defs = vec![d];
        self.push(m, i);
        Ok(())
    }

    fn movmsk(&mut self, i: usize) -> Result<(), String> {
        let o = self.ops[i];
        let (f, code) = match (self.mask_regs, self.vbytes) {
            (true, _) => (File::K, C::VEX_Kmovw_r32_kr),
            (_, 32) => (File::V, C::VEX_Vmovmskps_r32_ymm),
            _ => (File::V, C::VEX_Vmovmskps_r32_xmm),
        };
        let s = self.srcs(i, f);
        let a = self.reg_or_temp(&s, 0, f, i);
        let d = self.dst(i, File::G, None, &[a]);
        let mut m = self.inst(o.class, code);
        m.ops = vec![Opnd::R(d), Opnd::R(a)];
        m.uses = vec![a];
        m.defs = vec![d];
        self.push(m, i);
        Ok(())
    }

    /// int -> float (`vxorps` then `vcvtsi2ss`, as compilers break the
    /// merge dependency) or float -> int (`vcvttss2si`).
    fn scalar_cvt(&mut self, i: usize) -> Result<(), String> {
        let o = self.ops[i];
        if self.src_file(i, 0) == Some(File::G) {
            let s = self.srcs(i, File::G);
            let d = self.dst(i, File::V, None, &s);
            let z = if self.avx512 {
                C::EVEX_Vxorps_zmm_k1z_zmm_zmmm512b32
            } else {
                C::VEX_Vxorps_xmm_xmm_xmmm128
            };
            let mut x = self.inst(OpClass::Zero, z);
            x.ops = vec![Opnd::R(d), Opnd::R(d), Opnd::R(d)];
            x.defs = vec![d];
            x.recorded = false;
            self.push(x, i);
            let c = if self.avx512 {
                C::EVEX_Vcvtsi2ss_xmm_xmm_rm32_er
            } else {
                C::VEX_Vcvtsi2ss_xmm_xmm_rm32
            };
            let mut m = self.inst(o.class, c);
            m.ops = vec![Opnd::R(d), Opnd::R(d), Opnd::R(s[0])];
            m.uses = vec![d, s[0]];
            m.defs = vec![d];
            self.push(m, i);
            return Ok(());
        }
        let s = self.srcs(i, File::V);
        let a = self.reg_or_temp(&s, 0, File::V, i);
        let d = self.dst(i, File::G, None, &[a]);
        let c = if self.avx512 {
            C::EVEX_Vcvttss2si_r32_xmmm32_sae
        } else {
            C::VEX_Vcvttss2si_r32_xmmm32
        };
        let mut m = self.inst(o.class, c);
        m.ops = vec![Opnd::R(d), Opnd::R(a)];
        m.uses = vec![a];
        m.defs = vec![d];
        self.push(m, i);
        Ok(())
    }
}

mod memory;

/// An instruction with a memory operand.
pub(crate) fn with_mem(mut m: Inst, mem: crate::program::MemRef) -> Inst {
    m.mem = Some(mem);
    m
}
