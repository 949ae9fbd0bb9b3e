//! A window of a recorded kernel trace as an x86-64 loop: the same
//! instructions emitted (each op class as the instruction it names on the
//! recorded flavour), registers allocated from the trace's values, its
//! memory laid out at the trace's page offsets in one buffer, branches
//! going the recorded way; timed on this host in steady state, and the
//! same loop handed to the model as a trace. The model is then measured on
//! exactly what it is asked to predict, with no native backend between.
//!
//! The loop starts from zeroed registers and a zero-filled buffer (see
//! [`values`]): its values are known where they do not change between
//! iterations, so the replay keeps every dependency the recorded window
//! has, addresses computed from loaded values included, and reaches the
//! recorded addresses without faulting.

#![warn(missing_docs)]

pub mod alloc;
pub mod body;
pub mod encode;
pub mod files;
pub mod host;
pub mod layout;
pub mod program;
pub mod select;
pub mod values;

pub use program::{Changes, Program};

use isa::Trace;

/// A window ready to run on the host and on the model.
#[derive(Clone, Debug)]
pub struct Built {
    /// The instructions.
    pub program: Program,
    /// Their machine code.
    pub code: encode::Encoded,
    /// The same loop body as a trace for the model.
    pub body: Trace,
}

/// Build window `range` of `trace`.
///
/// # Errors
/// A flavour the host cannot run, an op the replay has no form for, or a
/// gather whose lanes the zero analysis cannot keep in the buffer.
pub fn build(trace: &Trace, range: std::ops::Range<usize>) -> Result<Built, String> {
    let mut program = select::select(trace, range)?;
    values::fix(&mut program)?;
    let code = encode::encode(&program, 0)?;
    let body = body::body_trace(&program, trace.flavour);
    Ok(Built {
        program,
        code,
        body,
    })
}

/// Core clock cycles per TSC tick on this host, from a loop of 100
/// dependent adds (one cycle each): the minimum-time estimate.
///
/// # Errors
/// The calibration loop could not run.
pub fn cycles_per_tick() -> Result<f64, String> {
    use program::{Inst, Opnd, Reg};
    let mut insts = Vec::new();
    for _ in 0..100 {
        let mut x = Inst::new(
            isa::OpClass::Alu,
            isa::Region::Other,
            iced_x86::Code::Add_rm64_r64,
        );
        x.ops = vec![Opnd::R(Reg::G(0)), Opnd::R(Reg::G(1))];
        x.uses = vec![Reg::G(0), Reg::G(1)];
        x.defs = vec![Reg::G(0), Reg::Flags];
        insts.push(x);
    }
    let p = Program {
        insts,
        vbytes: 32,
        lanes: 8,
        buffer_bytes: 4096,
        recorded_ops: 100,
        changes: Changes::default(),
        init_regs: Vec::new(),
        init_mem: Vec::new(),
    };
    let code = encode::encode(&p, 0)?;
    let t = host::time(&code, &[], 4096, 20, 2_000_000)?;
    Ok(100.0 / t.ticks_per_iteration)
}

/// The body as assembly text, one instruction per line with the class the
/// model prices it as (and `+` where the replay added it).
#[must_use]
pub fn listing(b: &Built) -> String {
    use iced_x86::{Decoder, Formatter, NasmFormatter};
    let body = &b.code.bytes[b.code.body_start..b.code.body_start + b.code.body_len];
    let mut d = Decoder::with_ip(64, body, 0, 0);
    let mut f = NasmFormatter::new();
    let mut out = String::new();
    let mut classes = b.program.insts.iter();
    for ins in &mut d {
        let mut s = String::new();
        f.format(&ins, &mut s);
        let x = classes.next();
        let (c, added) = x.map_or(("loop", false), |x| (x.class.name(), !x.recorded));
        let vals: Vec<String> = x
            .map(|x| {
                x.inputs
                    .iter()
                    .map(|v| v.map_or("?".to_string(), |v| format!("{v:#x}")))
                    .collect()
            })
            .unwrap_or_default();
        let line = format!(
            "{:06x} {:<12}{} {s}",
            ins.ip(),
            c,
            if added { "+" } else { " " }
        );
        if vals.is_empty() {
            out.push_str(&format!("{line}\n"));
        } else {
            out.push_str(&format!("{line:<64} ; {}\n", vals.join(" ")));
        }
    }
    out
}
