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

/// Run `p` natively with the semantics of `flavour`.
pub fn run_native<P: Program>(p: &P, flavour: FlavourId) -> P::Out {
    match flavour {
        FlavourId::Lrb16 => p.run(&mut Native::<Lrb16, 16>::new()),
        FlavourId::Avx512 => p.run(&mut Native::<Avx512, 16>::new()),
        FlavourId::Avx2 => p.run(&mut Native::<Avx2, 8>::new()),
        FlavourId::Sse4 => p.run(&mut Native::<Sse4, 4>::new()),
    }
}
