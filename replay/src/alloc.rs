//! Register allocation over a window: each value gets a physical register
//! when it is produced (or first read, for a value produced before the
//! window), freed after its last use; when a file runs out, the value used
//! furthest ahead is spilled to a slot and reloaded where it is next read,
//! as a compiler's linear-scan allocator does.

use crate::program::{File, Inst, MemRef, Opnd, Reg};
use iced_x86::Code;
use isa::{OpClass, Region, ValId};
use std::collections::HashMap;

/// General registers handed out: all but rsp and r14 (the loop counter).
const GPRS: [u8; 14] = [0, 1, 2, 3, 5, 6, 7, 8, 9, 10, 11, 12, 13, 15];

/// The allocator's state.
pub struct Alloc {
    uses: HashMap<ValId, Vec<usize>>,
    reg_of: HashMap<ValId, Reg>,
    holder: HashMap<Reg, ValId>,
    free: Vec<Reg>,
    slot_of: HashMap<ValId, u64>,
    spill_base: u64,
    vbytes: u32,
    avx512: bool,
    next_temp: u32,
    /// Spills made.
    pub spills: usize,
}

impl Alloc {
    /// An allocator for a window whose values are read at `uses`.
    #[must_use]
    pub fn new(
        uses: HashMap<ValId, Vec<usize>>,
        vregs: u8,
        avx512: bool,
        vbytes: u32,
        spill_base: u64,
    ) -> Alloc {
        let mut free: Vec<Reg> = GPRS.iter().rev().map(|&g| Reg::G(g)).collect();
        free.extend((0..vregs).rev().map(Reg::V));
        if avx512 {
            free.extend((1..8).rev().map(Reg::K));
        }
        Alloc {
            uses,
            reg_of: HashMap::new(),
            holder: HashMap::new(),
            free,
            slot_of: HashMap::new(),
            spill_base,
            vbytes,
            avx512,
            next_temp: u32::MAX - 1,
            spills: 0,
        }
    }

    /// Spill slots used.
    #[must_use]
    pub fn slots(&self) -> usize {
        self.slot_of.len()
    }

    fn next_use(&self, v: ValId, after: usize) -> Option<usize> {
        let u = self.uses.get(&v)?;
        let k = u.partition_point(|&p| p <= after);
        u.get(k).copied()
    }

    /// Whether `v` is read after op `i`.
    #[must_use]
    pub fn live_after(&self, v: ValId, i: usize) -> bool {
        self.next_use(v, i).is_some()
    }

    /// The register holding `v`, if one does.
    #[must_use]
    pub fn reg(&self, v: ValId) -> Option<Reg> {
        self.reg_of.get(&v).copied()
    }

    /// The value `r` holds.
    #[must_use]
    pub fn holder(&self, r: Reg) -> Option<ValId> {
        self.holder.get(&r).copied()
    }

    /// A free register of `file` at op `i`, not one of `keep`; spills the
    /// value read furthest ahead when none is free.
    pub fn take(&mut self, file: File, i: usize, keep: &[Reg], out: &mut Vec<Inst>) -> Reg {
        let fits = |r: &Reg| {
            matches!(
                (file, r),
                (File::G | File::Flags, Reg::G(_)) | (File::V, Reg::V(_)) | (File::K, Reg::K(_))
            )
        };
        if let Some(k) = self.free.iter().rposition(|r| fits(r) && !keep.contains(r)) {
            return self.free.remove(k);
        }
        let victim = self
            .holder
            .iter()
            .filter(|(r, _)| fits(r) && !keep.contains(r))
            .max_by_key(|(r, v)| (self.next_use(**v, i).unwrap_or(usize::MAX), **r))
            .map(|(r, v)| (*r, *v))
            .expect("a register file with no register to spill");
        let (r, v) = victim;
        if self.live_after(v, i) {
            self.spill(v, r, out);
        }
        self.holder.remove(&r);
        self.reg_of.remove(&v);
        r
    }

    fn slot(&mut self, v: ValId) -> u64 {
        let n = self.slot_of.len() as u64;
        *self.slot_of.entry(v).or_insert(self.spill_base + 64 * n)
    }

    fn spill(&mut self, v: ValId, r: Reg, out: &mut Vec<Inst>) {
        if self.slot_of.contains_key(&v) {
            return; // already in its slot, unchanged since
        }
        self.spills += 1;
        let addr = self.slot(v);
        let (class, code, bytes) = self.move_code(r, true);
        let mut m = Inst::new(class, Region::Other, code);
        m.ops = vec![Opnd::M, Opnd::R(r)];
        m.uses = vec![r];
        m.mem = Some(MemRef::at(addr, bytes, true));
        m.recorded = false;
        out.push(m);
    }

    fn move_code(&self, r: Reg, store: bool) -> (OpClass, Code, u32) {
        match (r, store, self.vbytes, self.avx512) {
            (Reg::G(_), true, ..) => (OpClass::Store, Code::Mov_rm64_r64, 8),
            (Reg::G(_), false, ..) => (OpClass::Load, Code::Mov_r64_rm64, 8),
            (Reg::K(_), true, ..) => (OpClass::Store, Code::VEX_Kmovw_m16_kr, 2),
            (Reg::K(_), false, ..) => (OpClass::Load, Code::VEX_Kmovw_kr_km16, 2),
            (_, true, _, true) => (OpClass::VStore, Code::EVEX_Vmovups_zmmm512_k1z_zmm, 64),
            (_, false, _, true) => (OpClass::VLoad, Code::EVEX_Vmovups_zmm_k1z_zmmm512, 64),
            (_, true, 32, _) => (OpClass::VStore, Code::VEX_Vmovups_ymmm256_ymm, 32),
            (_, false, 32, _) => (OpClass::VLoad, Code::VEX_Vmovups_ymm_ymmm256, 32),
            (_, true, ..) => (OpClass::VStore, Code::VEX_Vmovups_xmmm128_xmm, 16),
            (_, false, ..) => (OpClass::VLoad, Code::VEX_Vmovups_xmm_xmmm128, 16),
        }
    }

    /// A register holding `v` (in `file`), reloading it from its slot or,
    /// for a value produced before the window, giving it a register (its
    /// value is whatever the register holds: zero at the start).
    pub fn read(
        &mut self,
        v: ValId,
        file: File,
        i: usize,
        keep: &[Reg],
        out: &mut Vec<Inst>,
    ) -> Reg {
        if let Some(r) = self.reg(v) {
            return r;
        }
        let r = self.take(file, i, keep, out);
        if let Some(&addr) = self.slot_of.get(&v) {
            let (class, code, bytes) = self.move_code(r, false);
            let mut m = Inst::new(class, Region::Other, code);
            m.ops = vec![Opnd::R(r), Opnd::M];
            m.defs = vec![r];
            m.mem = Some(MemRef::at(addr, bytes, false));
            m.recorded = false;
            out.push(m);
        }
        self.bind(v, r);
        r
    }

    /// `v` now lives in `r`.
    pub fn bind(&mut self, v: ValId, r: Reg) {
        if let Some(old) = self.holder.insert(r, v) {
            self.reg_of.remove(&old);
        }
        self.reg_of.insert(v, r);
        self.slot_of.remove(&v);
    }

    /// A scratch register for one instruction (freed by [`Alloc::release`]).
    pub fn temp(&mut self, file: File, i: usize, keep: &[Reg], out: &mut Vec<Inst>) -> Reg {
        let r = self.take(file, i, keep, out);
        let t = ValId(self.next_temp);
        self.next_temp -= 1;
        self.bind(t, r);
        r
    }

    /// Free the registers of values not read after op `i` (and scratch
    /// registers).
    pub fn release(&mut self, i: usize) {
        let dead: Vec<ValId> = self
            .reg_of
            .keys()
            .copied()
            .filter(|&v| v.0 >= self.next_temp || !self.live_after(v, i))
            .collect();
        for v in dead {
            if let Some(r) = self.reg_of.remove(&v) {
                self.holder.remove(&r);
                self.free.push(r);
            }
        }
    }
}

impl MemRef {
    /// An access of `bytes` at host address `addr` with no address registers.
    #[must_use]
    pub fn at(addr: u64, bytes: u32, store: bool) -> MemRef {
        MemRef {
            addr,
            disp: addr,
            bytes,
            regs: Vec::new(),
            vindex: None,
            store,
            bcast: false,
        }
    }
}

/// A register-to-register copy (`mov`, `vmovaps`, `kmovw`).
#[must_use]
pub fn copy(d: Reg, s: Reg, vbytes: u32, avx512: bool) -> Inst {
    let code = match (d, avx512, vbytes) {
        (Reg::G(_), ..) => Code::Mov_r64_rm64,
        (Reg::K(_), ..) => Code::VEX_Kmovw_kr_km16,
        (_, true, _) => Code::EVEX_Vmovaps_zmm_k1z_zmmm512,
        (_, _, 32) => Code::VEX_Vmovaps_ymm_ymmm256,
        _ => Code::VEX_Vmovaps_xmm_xmmm128,
    };
    let mut m = Inst::new(OpClass::Mov, Region::Other, code);
    m.ops = vec![Opnd::R(d), Opnd::R(s)];
    m.defs = vec![d];
    m.uses = vec![s];
    m.recorded = false;
    m
}
