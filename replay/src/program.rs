//! What a window becomes: x86-64 instructions over physical registers, each
//! with the op class the model prices it as.

use iced_x86::Code;
use isa::{OpClass, Region};

/// A physical register, or the flags.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Reg {
    /// A general register by number (rax = 0 ... r15 = 15).
    G(u8),
    /// A vector register by number (xmm, ymm or zmm by the flavour).
    V(u8),
    /// An AVX-512 mask register k1 to k7.
    K(u8),
    /// The flags.
    Flags,
}

/// A register file a value lives in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum File {
    /// General registers.
    G,
    /// Vector registers (scalar floats too: the low lane).
    V,
    /// AVX-512 mask registers.
    K,
    /// The flags (a compare's or test's result read by a branch or cmov).
    Flags,
}

/// One operand of an instruction.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Opnd {
    /// A register.
    R(Reg),
    /// The instruction's memory operand ([`Inst::mem`]).
    M,
    /// An immediate.
    Imm(i32),
}

/// The memory an instruction touches, in the replay buffer's layout.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MemRef {
    /// Host address of the first byte accessed (for `lea`, its
    /// displacement).
    pub addr: u64,
    /// The displacement encoded: `addr` less what the address registers
    /// hold when the loop runs (the value analysis).
    pub disp: u64,
    /// Bytes accessed (per lane for a gather or scatter).
    pub bytes: u32,
    /// Address registers (base, then index): kept where the value
    /// analysis knows what they hold, so the address is the recorded one.
    pub regs: Vec<Reg>,
    /// A gather's or scatter's vector index register.
    pub vindex: Option<Reg>,
    /// Whether it writes memory.
    pub store: bool,
    /// An embedded broadcast (AVX-512 `{1to16}`).
    pub bcast: bool,
}

/// One emitted instruction.
#[derive(Clone, Debug)]
pub struct Inst {
    /// The class the model prices it as.
    pub class: OpClass,
    /// The code region of the recorded op it stands for.
    pub region: Region,
    /// The instruction.
    pub code: Code,
    /// Its operands in Intel order.
    pub ops: Vec<Opnd>,
    /// An AVX-512 write mask (`{k}`).
    pub opmask: Option<Reg>,
    /// Registers it writes.
    pub defs: Vec<Reg>,
    /// Registers it reads (the address registers are in [`Inst::mem`]).
    pub uses: Vec<Reg>,
    /// Its memory operand.
    pub mem: Option<MemRef>,
    /// A conditional branch: whether it jumps when ZF is set (`je`) or
    /// clear (`jne`); its target is the next instruction either way.
    pub jump_if_zero: Option<bool>,
    /// A branch's recorded direction.
    pub taken: bool,
    /// A memory operand folded into it that the model prices as a
    /// `vloadfold` op of its own.
    pub folded: bool,
    /// Lanes a masked memory op moves (the model's mask).
    pub lanes: u32,
    /// What its inputs hold in the steady state (address registers, then
    /// the registers it reads; `None`: differs between iterations).
    pub inputs: Vec<Option<u64>>,
    /// Whether it stands for a recorded op (false: a copy, spill, reload or
    /// flags test the register allocation or instruction forms added).
    pub recorded: bool,
}

impl Inst {
    /// An instruction with no operands set.
    #[must_use]
    pub fn new(class: OpClass, region: Region, code: Code) -> Inst {
        Inst {
            class,
            region,
            code,
            ops: Vec::new(),
            opmask: None,
            defs: Vec::new(),
            uses: Vec::new(),
            mem: None,
            jump_if_zero: None,
            taken: false,
            folded: false,
            lanes: 1,
            inputs: Vec::new(),
            recorded: true,
        }
    }
}

/// A window as a loop body, ready to encode, run and simulate.
#[derive(Clone, Debug)]
pub struct Program {
    /// The body, in order.
    pub insts: Vec<Inst>,
    /// Vector width in bytes (16, 32 or 64).
    pub vbytes: u32,
    /// Lanes of the recorded flavour.
    pub lanes: u32,
    /// Bytes the replay buffer spans.
    pub buffer_bytes: u64,
    /// Recorded ops the window holds.
    pub recorded_ops: usize,
    /// Counts of what the replay changed, for the report.
    pub changes: Changes,
    /// Registers set before the loop (the steady state's values; the
    /// rest start at 0): general registers in full, a vector's every lane,
    /// a mask's bits.
    pub init_regs: Vec<(Reg, u64)>,
    /// Buffer bytes set before the loop (the rest start at 0).
    pub init_mem: Vec<(u64, u8)>,
}

/// What the replay changed from the recorded window.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Changes {
    /// Instructions added: register copies for two-operand forms, spills
    /// and reloads, flag tests.
    pub added: usize,
    /// Address registers dropped (not provably zero, or not a general
    /// register): those accesses use the recorded address without the
    /// dependency.
    pub dropped_address_deps: usize,
    /// Branches whose direction the replay could not make the recorded one.
    pub unknown_branches: usize,
    /// Values spilled to memory.
    pub spills: usize,
}

/// Where the replay buffer is mapped: a fixed address under 2 GiB, so an
/// absolute 32-bit displacement reaches every byte.
pub const BUFFER_BASE: u64 = 0x2000_0000;
