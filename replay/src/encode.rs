//! The program as machine code: a function `fn(iterations: u64)` that
//! saves the callee-saved registers, zeroes every register it uses, runs
//! the body `iterations` times (`dec r14; jnz top`, the body 64-byte
//! aligned) and returns.

use crate::program::{Inst, Opnd, Program, Reg};
use iced_x86::{
    BlockEncoder, BlockEncoderOptions, Code, Instruction, InstructionBlock, OpCodeOperandKind as K,
    OpKind, Register,
};

/// Encoded code and where its loop body starts and ends.
#[derive(Clone, Debug)]
pub struct Encoded {
    /// The bytes (to be placed at `base`).
    pub bytes: Vec<u8>,
    /// Offset of the loop body's first byte.
    pub body_start: usize,
    /// Body bytes, the loop's `dec`/`jnz` included.
    pub body_len: usize,
}

fn gpr(n: u8, kind: &str) -> Register {
    let n = u32::from(n);
    match kind {
        "r64" => Register::RAX + n,
        "r32" => Register::EAX + n,
        "r16" => Register::AX + n,
        _ if n < 4 => Register::AL + n,
        _ if n < 8 => Register::SPL + (n - 4),
        _ => Register::R8L + (n - 8),
    }
}

/// The register name operand `kind` takes.
fn name(r: Reg, kind: K) -> Register {
    let k = format!("{kind:?}");
    match r {
        Reg::G(n) if k.starts_with("r64") => gpr(n, "r64"),
        Reg::G(n) if k.starts_with("r32") => gpr(n, "r32"),
        Reg::G(n) if k.starts_with("r16") => gpr(n, "r16"),
        Reg::G(n) => gpr(n, "r8"),
        Reg::V(n) if k.starts_with("zmm") => Register::ZMM0 + u32::from(n),
        Reg::V(n) if k.starts_with("ymm") => Register::YMM0 + u32::from(n),
        Reg::V(n) => Register::XMM0 + u32::from(n),
        Reg::K(n) => Register::K0 + u32::from(n),
        Reg::Flags => Register::None,
    }
}

fn set_mem(ins: &mut Instruction, i: u32, x: &Inst) -> Result<(), String> {
    let m = x.mem.as_ref().ok_or("a memory operand with no address")?;
    ins.set_op_kind(i, OpKind::Memory);
    let mut regs = m.regs.iter().map(|&r| name(r, K::r64_reg));
    ins.set_memory_base(regs.next().unwrap_or(Register::None));
    match m.vindex {
        Some(v) => {
            let vk = if x.code.op_code().op_kind(i) == K::mem_vsib32z {
                K::zmm_reg
            } else if x.code.op_code().op_kind(i) == K::mem_vsib32y {
                K::ymm_reg
            } else {
                K::xmm_reg
            };
            ins.set_memory_index(name(v, vk));
            ins.set_memory_index_scale(4);
        }
        None => {
            ins.set_memory_index(regs.next().unwrap_or(Register::None));
            ins.set_memory_index_scale(1);
        }
    }
    ins.set_memory_displacement64(m.disp);
    ins.set_memory_displ_size(8);
    ins.set_is_broadcast(m.bcast);
    Ok(())
}

/// One instruction.
fn build(x: &Inst) -> Result<Instruction, String> {
    let mut ins = Instruction::default();
    ins.set_code(x.code);
    let oc = x.code.op_code();
    if oc.op_count() as usize != x.ops.len() {
        return Err(format!(
            "{:?}: {} operands given, {} taken",
            x.code,
            x.ops.len(),
            oc.op_count()
        ));
    }
    for (i, o) in x.ops.iter().enumerate() {
        let i = i as u32;
        match *o {
            Opnd::R(r) => {
                ins.set_op_kind(i, OpKind::Register);
                ins.set_op_register(i, name(r, oc.op_kind(i)));
            }
            Opnd::M => set_mem(&mut ins, i, x)?,
            Opnd::Imm(v) => {
                if oc.op_kind(i) == K::imm8 {
                    ins.set_op_kind(i, OpKind::Immediate8);
                    ins.set_immediate8(v as u8);
                } else {
                    ins.set_op_kind(i, OpKind::Immediate32);
                    ins.set_immediate32(v as u32);
                }
            }
        }
    }
    if let Some(k) = x.opmask {
        ins.set_op_mask(name(k, K::k_reg));
    }
    Ok(ins)
}

fn plain(code: Code, regs: &[Register]) -> Instruction {
    let mut ins = Instruction::default();
    ins.set_code(code);
    for (i, &r) in regs.iter().enumerate() {
        ins.set_op_kind(i as u32, OpKind::Register);
        ins.set_op_register(i as u32, r);
    }
    ins
}

const SAVED: [Register; 6] = [
    Register::RBX,
    Register::RBP,
    Register::R12,
    Register::R13,
    Register::R14,
    Register::R15,
];

fn prologue(p: &Program) -> Vec<Instruction> {
    let mut v: Vec<Instruction> = SAVED.iter().map(|&r| plain(Code::Push_r64, &[r])).collect();
    v.push(plain(Code::Mov_r64_rm64, &[Register::R14, Register::RDI]));
    for n in [0u32, 1, 2, 3, 5, 6, 7, 8, 9, 10, 11, 12, 13, 15] {
        let r = Register::EAX + n;
        v.push(plain(Code::Xor_r32_rm32, &[r, r]));
    }
    if p.vbytes == 64 {
        for n in 0..32 {
            let z = Register::ZMM0 + n;
            v.push(plain(Code::EVEX_Vpxord_zmm_k1z_zmm_zmmm512b32, &[z, z, z]));
        }
        for n in 1..8 {
            let k = Register::K0 + n;
            v.push(plain(Code::VEX_Kxorw_kr_kr_kr, &[k, k, k]));
        }
    } else {
        v.push(plain(Code::VEX_Vzeroall, &[]));
    }
    v.extend(init(p));
    v
}

/// Set the steady state's register values: masks and vectors through rax
/// first, general registers last.
fn init(p: &Program) -> Vec<Instruction> {
    let mut v = Vec::new();
    let imm = |r: Register, x: u64| {
        let mut i = plain(Code::Mov_r64_imm64, &[r]);
        i.set_op1_kind(OpKind::Immediate64);
        i.set_immediate64(x);
        i
    };
    let mut regs = p.init_regs.clone();
    regs.sort_by_key(|(r, _)| matches!(r, Reg::G(_)));
    for (r, x) in regs {
        match r {
            Reg::G(n) => v.push(imm(Register::RAX + u32::from(n), x)),
            Reg::K(n) => {
                v.push(imm(Register::RAX, x));
                v.push(plain(
                    Code::VEX_Kmovw_kr_r32,
                    &[Register::K0 + u32::from(n), Register::EAX],
                ));
            }
            Reg::V(n) if p.vbytes == 64 => {
                v.push(imm(Register::RAX, x));
                v.push(plain(
                    Code::EVEX_Vpbroadcastd_zmm_k1z_r32,
                    &[Register::ZMM0 + u32::from(n), Register::EAX],
                ));
            }
            Reg::V(n) => {
                let x_ = Register::XMM0 + u32::from(n);
                v.push(imm(Register::RAX, x));
                v.push(plain(Code::VEX_Vmovd_xmm_rm32, &[x_, Register::EAX]));
                let y = if p.vbytes == 32 {
                    Register::YMM0 + u32::from(n)
                } else {
                    x_
                };
                let c = if p.vbytes == 32 {
                    Code::VEX_Vpbroadcastd_ymm_xmmm32
                } else {
                    Code::VEX_Vpbroadcastd_xmm_xmmm32
                };
                v.push(plain(c, &[y, x_]));
            }
            Reg::Flags => {}
        }
    }
    if !p.init_regs.iter().any(|(r, _)| *r == Reg::G(0)) {
        v.push(plain(Code::Xor_r32_rm32, &[Register::EAX, Register::EAX]));
    }
    v
}

fn epilogue() -> Vec<Instruction> {
    let mut v = vec![plain(Code::VEX_Vzeroupper, &[])];
    v.extend(SAVED.iter().rev().map(|&r| plain(Code::Pop_r64, &[r])));
    v.push(Instruction::with(Code::Retnq));
    v
}

/// The body with its loop branch, at virtual addresses `ip0 + n` (branch
/// targets refer to them; the block encoder relocates).
fn body(p: &Program, ip0: u64) -> Result<Vec<Instruction>, String> {
    let mut v = Vec::with_capacity(p.insts.len() + 2);
    for (n, x) in p.insts.iter().enumerate() {
        let ip = ip0 + n as u64;
        let mut ins = match x.jump_if_zero {
            Some(z) => {
                let c = if z {
                    Code::Je_rel32_64
                } else {
                    Code::Jne_rel32_64
                };
                Instruction::with_branch(c, ip + 1).map_err(|e| e.to_string())?
            }
            None => build(x)?,
        };
        ins.set_ip(ip);
        v.push(ins);
    }
    let n = p.insts.len() as u64;
    let mut dec = plain(Code::Dec_rm64, &[Register::R14]);
    dec.set_ip(ip0 + n);
    let mut jnz = Instruction::with_branch(Code::Jne_rel32_64, ip0).map_err(|e| e.to_string())?;
    jnz.set_ip(ip0 + n + 1);
    v.push(dec);
    v.push(jnz);
    Ok(v)
}

fn block(ins: &[Instruction], rip: u64) -> Result<Vec<u8>, String> {
    BlockEncoder::encode(
        64,
        InstructionBlock::new(ins, rip),
        BlockEncoderOptions::NONE,
    )
    .map(|r| r.code_buffer)
    .map_err(|e| e.to_string())
}

/// Encode `p` to run at address `base`.
///
/// # Errors
/// An instruction the encoder rejects (a bug in selection: named).
pub fn encode(p: &Program, base: u64) -> Result<Encoded, String> {
    let mut bytes = block(&prologue(p), base)?;
    while bytes.len() % 64 != 0 {
        bytes.push(0x90);
    }
    let body_start = bytes.len();
    let b = block(&body(p, 0x1000_0000)?, base + body_start as u64)?;
    let body_len = b.len();
    bytes.extend(b);
    bytes.extend(block(&epilogue(), base + bytes.len() as u64)?);
    Ok(Encoded {
        bytes,
        body_start,
        body_len,
    })
}
