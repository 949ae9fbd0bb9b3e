//! # rtsim ISA layer
//!
//! The seam of rtsim: kernels are written once against [`Machine`] and run
//! either **traced** ([`Traced`]: every op computes its result and records the
//! machine instructions its flavour needs, with true data dependencies,
//! addresses and lane masks) or **native** ([`Native`]: the same code compiled
//! to real SIMD, nothing recorded). Flavours: [`Lrb16`], [`Avx512`], [`Avx2`],
//! [`Sse4`]. Recorded [`Trace`]s are saved as compact binary or readable text
//! files ([`trace_file`], [`trace_text`]) and summarised by [`info`].

#![warn(missing_docs)]
// Lane loops index several arrays in step (`r[i] = f(a[i], b[i])`): that is
// the shape LLVM vectorises, and clearer than zipped iterators here.
#![allow(clippy::needless_range_loop)]

pub mod class;
pub mod flavour;
pub mod host;
pub mod info;
pub mod lanes;
pub mod machine;
pub mod mem;
pub mod native;
pub mod program;
pub mod rng;
pub mod sites;
pub mod trace;
pub mod trace_file;
pub mod trace_text;
pub mod traced;
pub mod types;

pub use class::OpClass;
pub use flavour::{Avx2, Avx512, Flavour, FlavourId, Lrb16, Sse4, Wide32};
pub use lanes::{BinOp, Cmp, Fma, IOp, Shift};
pub use machine::{Float, Int, Logic, Machine, SOp};
pub use mem::{AddrSpace, At, Buf, MemRegion, OpenBuf, SpaceMark, PAD};
pub use native::{LogKind, Native, NoLog, WarmLog};
pub use program::{
    record, record_units, run_native, run_steps, run_units, Detail, Placed, Program, Step,
    UnitProgram, THREAD_SPAN,
};
pub use trace::{Op, Trace, WarmEvent};
pub use traced::{Traced, STREAM_CHUNK};
pub use types::{Addr, LaneMask, LineAddr, MemId, MemKind, Region, Site, ValId};
