//! Run one kernel on a flavour chosen at run time, traced or native.

use crate::flavour::FlavourId;
use crate::machine::Machine;
use crate::native::Native;
use crate::trace::Trace;
use crate::traced::Traced;
use crate::{Avx2, Avx512, Lrb16, Sse4};

/// A kernel with its inputs: anything that can run on any [`Machine`].
pub trait Program {
    /// What the run yields besides its trace (hit counts, images, ...).
    type Out;
    /// Run on `m`.
    fn run<M: Machine>(&self, m: &mut M) -> Self::Out;
    /// Header parameters to record with a trace.
    fn params(&self) -> Vec<(String, String)> {
        Vec::new()
    }
}

/// Run `p` on the traced machine of `flavour`; the trace's source is `source`.
pub fn record<P: Program>(p: &P, flavour: FlavourId, source: &str) -> (Trace, P::Out) {
    fn go<P: Program, M: Machine>(
        p: &P,
        mut m: M,
        fin: impl FnOnce(M) -> Trace,
    ) -> (Trace, P::Out) {
        let out = p.run(&mut m);
        let mut t = fin(m);
        t.params.extend(p.params());
        (t, out)
    }
    match flavour {
        FlavourId::Lrb16 => go(p, Traced::<Lrb16, 16>::new(source), Traced::finish),
        FlavourId::Avx512 => go(p, Traced::<Avx512, 16>::new(source), Traced::finish),
        FlavourId::Avx2 => go(p, Traced::<Avx2, 8>::new(source), Traced::finish),
        FlavourId::Sse4 => go(p, Traced::<Sse4, 4>::new(source), Traced::finish),
    }
}

/// A kernel over many units of work (a frame's tiles or ray streams) that
/// lays its data out once and runs every unit on the same machine, as a
/// renderer does: memory and values carry from unit to unit.
pub trait UnitProgram {
    /// What [`UnitProgram::lay_out`] leaves for the units (buffer handles).
    type Laid;
    /// One unit's input.
    type Unit;
    /// What a unit yields besides its ops.
    type Out;
    /// Lay the shared data out on `m` (its ops are not kept).
    fn lay_out<M: Machine>(&self, m: &mut M) -> Self::Laid;
    /// Run one unit. Buffers it allocates are released after it.
    fn unit<M: Machine>(&self, m: &mut M, laid: &Self::Laid, u: &Self::Unit) -> Self::Out;
}

/// Where a unit runs: its simulated thread (its buffers get addresses of
/// their own, `THREAD_SPAN` apart), and the unit.
#[derive(Clone, Debug)]
pub struct Placed<U> {
    /// Simulated thread (0-based).
    pub thread: usize,
    /// The unit.
    pub unit: U,
}

/// Address space between the per-unit buffers of two simulated threads.
pub const THREAD_SPAN: u64 = 1 << 30;

/// Record `units` of `p` in order on one traced machine of `flavour`; each
/// unit's ops go to `each` as a trace of their own (with the regions live
/// while it ran), with the unit and its output. Stops at `each`'s first error.
pub fn record_units<P: UnitProgram, E>(
    p: &P,
    flavour: FlavourId,
    source: &str,
    units: impl IntoIterator<Item = Placed<P::Unit>>,
    mut each: impl FnMut(&Placed<P::Unit>, Trace, P::Out) -> Result<(), E>,
) -> Result<(), E> {
    fn go<P: UnitProgram, FL: crate::Flavour<N>, const N: usize, E>(
        p: &P,
        source: &str,
        units: impl IntoIterator<Item = Placed<P::Unit>>,
        each: &mut impl FnMut(&Placed<P::Unit>, Trace, P::Out) -> Result<(), E>,
    ) -> Result<(), E> {
        let mut m = Traced::<FL, N>::new(source);
        let laid = p.lay_out(&mut m);
        let _ = m.take();
        for u in units {
            let mark = m.space().mark();
            m.space().skip(u.thread as u64 * THREAD_SPAN);
            let out = p.unit(&mut m, &laid, &u.unit);
            let t = m.take();
            m.space().release(mark);
            each(&u, t, out)?;
        }
        Ok(())
    }
    match flavour {
        FlavourId::Lrb16 => go::<P, Lrb16, 16, E>(p, source, units, &mut each),
        FlavourId::Avx512 => go::<P, Avx512, 16, E>(p, source, units, &mut each),
        FlavourId::Avx2 => go::<P, Avx2, 8, E>(p, source, units, &mut each),
        FlavourId::Sse4 => go::<P, Sse4, 4, E>(p, source, units, &mut each),
    }
}

/// Run `p` natively with the semantics of `flavour`.
pub fn run_native<P: Program>(p: &P, flavour: FlavourId) -> P::Out {
    match flavour {
        FlavourId::Lrb16 => p.run(&mut Native::<Lrb16, 16>::new()),
        FlavourId::Avx512 => p.run(&mut Native::<Avx512, 16>::new()),
        FlavourId::Avx2 => p.run(&mut Native::<Avx2, 8>::new()),
        FlavourId::Sse4 => p.run(&mut Native::<Sse4, 4>::new()),
    }
}
