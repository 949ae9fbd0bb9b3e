//! Loads, stores, gathers, scatters and compress-stores.

use super::super::super::Sel;
use super::with_mem;
use crate::files::data_sources;
use crate::program::{File, Opnd, Reg};
use iced_x86::Code as C;
use isa::OpClass;

impl Sel<'_> {
    /// The data sources of memory op `i` (after its address sources), in
    /// the files `files` give, each in a register.
    fn data(&mut self, i: usize, files: &[File], keep: &mut Vec<Reg>) -> Vec<Reg> {
        let o = self.ops[i];
        let n = data_sources(o.class, self.mask_regs);
        let s = o.sources();
        let first = s.len().saturating_sub(n);
        let mut regs = Vec::new();
        for (j, f) in files.iter().enumerate() {
            let r = match s.get(first + j).filter(|_| first + j < s.len() && j < n) {
                Some(&v) => self.src(v, *f, i, keep),
                None => self.a.temp(*f, i, keep, &mut self.out),
            };
            keep.push(r);
            regs.push(r);
        }
        regs
    }

    fn vload_code(&self, bytes: u32) -> C {
        match (self.avx512, bytes) {
            (true, 64) => C::EVEX_Vmovups_zmm_k1z_zmmm512,
            (true, 32) => C::EVEX_Vmovups_ymm_k1z_ymmm256,
            (true, 16) => C::EVEX_Vmovups_xmm_k1z_xmmm128,
            (true, _) => C::EVEX_Vmovss_xmm_k1z_m32,
            (false, 32) => C::VEX_Vmovups_ymm_ymmm256,
            (false, 16) => C::VEX_Vmovups_xmm_xmmm128,
            _ => C::VEX_Vmovss_xmm_m32,
        }
    }

    fn vstore_code(&self, bytes: u32) -> C {
        match (self.avx512, bytes) {
            (true, 64) => C::EVEX_Vmovups_zmmm512_k1z_zmm,
            (true, 32) => C::EVEX_Vmovups_ymmm256_k1z_ymm,
            (true, 16) => C::EVEX_Vmovups_xmmm128_k1z_xmm,
            (true, _) => C::EVEX_Vmovss_m32_k1_xmm,
            (false, 32) => C::VEX_Vmovups_ymmm256_ymm,
            (false, 16) => C::VEX_Vmovups_xmmm128_xmm,
            _ => C::VEX_Vmovss_m32_xmm,
        }
    }

    fn bcast_code(&self, bytes: u32) -> C {
        match (self.avx512, self.vbytes, bytes) {
            (true, _, 32) => C::EVEX_Vbroadcastf32x8_zmm_k1z_m256,
            (true, _, 16) => C::EVEX_Vbroadcastf32x4_zmm_k1z_m128,
            (true, ..) => C::EVEX_Vbroadcastss_zmm_k1z_xmmm32,
            (false, 32, 16) => C::VEX_Vbroadcastf128_ymm_m128,
            (false, 32, _) => C::VEX_Vbroadcastss_ymm_m32,
            _ => C::VEX_Vbroadcastss_xmm_m32,
        }
    }

    pub(in crate::select) fn mem_op(&mut self, i: usize) -> Result<(), String> {
        let o = self.ops[i];
        let mut keep = Vec::new();
        let mem = self.mem(i, &mut keep);
        let lanes = o.mask.0;
        let mut m = match o.class {
            OpClass::Load | OpClass::LoadFold => {
                let f = self.file_of(o.dst);
                let f = if f == File::Flags { File::G } else { f };
                let d = self.dst(i, f, None, &keep);
                let code = match (f, o.bytes) {
                    (File::G, 1) => C::Movzx_r32_rm8,
                    (File::G, 2) => C::Movzx_r32_rm16,
                    (File::G, 8) => C::Mov_r64_rm64,
                    (File::G, _) => C::Mov_r32_rm32,
                    _ => self.vload_code(4),
                };
                let mut m = self.inst(o.class, code);
                m.ops = vec![Opnd::R(d), Opnd::M];
                m.defs = vec![d];
                m
            }
            OpClass::VLoad | OpClass::VLoadFold | OpClass::VLoadBcast => {
                let d = self.dst(i, File::V, None, &keep);
                let bcast = o.class == OpClass::VLoadBcast
                    || (o.class == OpClass::VLoadFold && o.bytes < self.vbytes);
                let code = if bcast {
                    self.bcast_code(o.bytes)
                } else {
                    self.vload_code(o.bytes.max(4))
                };
                // A folded operand loads on its own here: the model prices
                // what the host runs.
                let class = if bcast {
                    OpClass::VLoadBcast
                } else {
                    OpClass::VLoad
                };
                let mut m = self.inst(class, code);
                m.ops = vec![Opnd::R(d), Opnd::M];
                m.defs = vec![d];
                m
            }
            OpClass::VLoadMasked if self.mask_regs => {
                let r = self.data(i, &[File::K, File::V], &mut keep);
                let d = self.dst(i, File::V, Some(r[1]), &keep);
                let mut m = self.inst(o.class, C::EVEX_Vmovups_zmm_k1z_zmmm512);
                m.opmask = Some(r[0]);
                m.ops = vec![Opnd::R(d), Opnd::M];
                m.uses = vec![r[0], d];
                m.defs = vec![d];
                m
            }
            OpClass::VLoadMasked => {
                let r = self.data(i, &[File::V], &mut keep);
                let d = self.dst(i, File::V, None, &keep);
                let code = if self.vbytes == 32 {
                    C::VEX_Vmaskmovps_ymm_ymm_m256
                } else {
                    C::VEX_Vmaskmovps_xmm_xmm_m128
                };
                let mut m = self.inst(o.class, code);
                m.ops = vec![Opnd::R(d), Opnd::R(r[0]), Opnd::M];
                m.uses = vec![r[0]];
                m.defs = vec![d];
                m
            }
            OpClass::VStore | OpClass::Store => {
                let df = match o.sources().len() {
                    0 => File::V,
                    n => self.src_file(i, n - 1).unwrap_or(File::V),
                };
                let r = self.data(i, &[df], &mut keep);
                let code = match (df, o.bytes) {
                    (File::G, 8) => C::Mov_rm64_r64,
                    (File::G, 2) => C::Mov_rm16_r16,
                    (File::G, 1) => C::Mov_rm8_r8,
                    (File::G, _) => C::Mov_rm32_r32,
                    _ => self.vstore_code(o.bytes.max(4)),
                };
                let mut m = self.inst(o.class, code);
                m.ops = vec![Opnd::M, Opnd::R(r[0])];
                m.uses = vec![r[0]];
                m
            }
            OpClass::VStoreMasked if self.mask_regs => {
                let r = self.data(i, &[File::K, File::V], &mut keep);
                let mut m = self.inst(o.class, C::EVEX_Vmovups_zmmm512_k1z_zmm);
                m.opmask = Some(r[0]);
                m.ops = vec![Opnd::M, Opnd::R(r[1])];
                m.uses = r;
                m
            }
            OpClass::VStoreMasked => {
                let r = self.data(i, &[File::V, File::V], &mut keep);
                let code = if self.vbytes == 32 {
                    C::VEX_Vmaskmovps_m256_ymm_ymm
                } else {
                    C::VEX_Vmaskmovps_m128_xmm_xmm
                };
                let mut m = self.inst(o.class, code);
                m.ops = vec![Opnd::M, Opnd::R(r[0]), Opnd::R(r[1])];
                m.uses = r;
                m
            }
            OpClass::VCompress if self.mask_regs => {
                let r = self.data(i, &[File::K, File::V], &mut keep);
                let mut m = self.inst(o.class, C::EVEX_Vcompressps_zmmm512_k1z_zmm);
                m.opmask = Some(r[0]);
                m.ops = vec![Opnd::M, Opnd::R(r[1])];
                m.uses = r;
                m
            }
            OpClass::VGather => return self.gather(i, mem, keep),
            OpClass::VScatter if self.mask_regs => {
                let r = self.data(i, &[File::V, File::K, File::V], &mut keep);
                let k = self.clobbered_mask(i, r[1], &keep);
                let mut mem = mem;
                mem.vindex = Some(r[0]);
                let mut m = self.inst(o.class, C::EVEX_Vscatterdps_vm32z_k1_zmm);
                m.opmask = Some(k);
                m.ops = vec![Opnd::M, Opnd::R(r[2])];
                m.uses = vec![r[0], k, r[2]];
                m.defs = vec![k];
                m.lanes = lanes;
                self.push(with_mem(m, mem), i);
                return Ok(());
            }
            c => {
                return Err(format!(
                    "memory op {} has no replay form on this flavour",
                    c.name()
                ))
            }
        };
        m.lanes = lanes;
        self.push(with_mem(m, mem), i);
        Ok(())
    }

    /// A mask register the instruction may clear (gathers and scatters
    /// clear theirs): `k` itself when its value is not read again, else a
    /// copy.
    fn clobbered_mask(&mut self, i: usize, k: Reg, keep: &[Reg]) -> Reg {
        let held = self.a.holder(k);
        if held.is_some_and(|v| !self.a.live_after(v, i)) {
            return k;
        }
        let f = if self.mask_regs { File::K } else { File::V };
        let t = self.a.temp(f, i, keep, &mut self.out);
        self.out
            .push(crate::alloc::copy(t, k, self.vbytes, self.avx512));
        t
    }

    fn gather(
        &mut self,
        i: usize,
        mut mem: crate::program::MemRef,
        mut keep: Vec<Reg>,
    ) -> Result<(), String> {
        let o = self.ops[i];
        let mf = if self.mask_regs { File::K } else { File::V };
        let r = self.data(i, &[File::V, mf, File::V], &mut keep);
        let k = self.clobbered_mask(i, r[1], &keep);
        keep.push(k);
        let merge = if r[2] == r[0] || r[2] == k {
            None
        } else {
            Some(r[2])
        };
        let d = self.dst(i, File::V, merge, &keep);
        mem.vindex = Some(r[0]);
        let mut m = if self.mask_regs {
            let mut m = self.inst(o.class, C::EVEX_Vgatherdps_zmm_k1_vm32z);
            m.opmask = Some(k);
            m.ops = vec![Opnd::R(d), Opnd::M];
            m
        } else {
            let code = if self.vbytes == 32 {
                C::VEX_Vgatherdps_ymm_vm32y_ymm
            } else {
                C::VEX_Vgatherdps_xmm_vm32x_xmm
            };
            let mut m = self.inst(o.class, code);
            m.ops = vec![Opnd::R(d), Opnd::M, Opnd::R(k)];
            m
        };
        m.uses = vec![d, r[0], k];
        m.defs = vec![d, k];
        m.lanes = o.mask.0;
        self.push(with_mem(m, mem), i);
        Ok(())
    }
}
