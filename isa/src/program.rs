//! Run one kernel on a flavour chosen at run time, traced or native.

use crate::flavour::FlavourId;
use crate::machine::Machine;
use crate::native::{Native, WarmLog};
use crate::trace::Trace;
use crate::traced::Traced;
use crate::{Avx2, Avx512, Lrb16, Sse4, Wide32};
use std::sync::mpsc::{sync_channel, Receiver};

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
        FlavourId::Wide32 => go(p, Traced::<Wide32, 32>::new(source), Traced::finish),
    }
}

/// A kernel over many units of work (a frame's tiles or ray streams) that
/// lays its data out once and runs every unit on the same machine, as a
/// renderer does: memory and values carry from unit to unit.
pub trait UnitProgram {
    /// What [`UnitProgram::lay_out`] leaves for the units (buffer handles;
    /// cloned for a second machine, sharing the buffers' bytes).
    type Laid: Clone;
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

/// How a unit of [`run_units`] runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Detail {
    /// Recorded op by op, for full timing.
    Timed,
    /// Run natively, only its memory accesses and branches logged (the ones
    /// the traced run would record), for functional warming.
    Warmed,
}

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
    run_units(
        p,
        flavour,
        source,
        units.into_iter().map(|u| (u, Detail::Timed)),
        |u, _, t, out| each(u, t, out),
    )
}

/// Run `units` of `p` in order, each in its [`Detail`]: timed units on one
/// traced machine (their full traces), warmed units on one logging native
/// machine (traces of their memory and branch ops only). The data is laid
/// out once, the native machine starting from the traced one's address
/// space, and each unit's buffers get the same addresses on either, so a
/// unit touches the same memory in either detail. `each` gets the unit, its
/// detail, its trace and its output; stops at `each`'s first error.
pub fn run_units<P: UnitProgram, E>(
    p: &P,
    flavour: FlavourId,
    source: &str,
    units: impl IntoIterator<Item = (Placed<P::Unit>, Detail)>,
    mut each: impl FnMut(&Placed<P::Unit>, Detail, Trace, P::Out) -> Result<(), E>,
) -> Result<(), E> {
    fn go<P: UnitProgram, FL: crate::Flavour<N>, const N: usize, E>(
        p: &P,
        source: &str,
        units: impl IntoIterator<Item = (Placed<P::Unit>, Detail)>,
        each: &mut impl FnMut(&Placed<P::Unit>, Detail, Trace, P::Out) -> Result<(), E>,
    ) -> Result<(), E> {
        let mut traced = Traced::<FL, N>::new(source);
        let laid = p.lay_out(&mut traced);
        let _ = traced.take();
        // The warming machine: the same address space and laid-out buffers
        // (their bytes shared), made when the first warmed unit comes.
        let mut native: Option<(Native<FL, N, WarmLog>, P::Laid)> = None;
        for (u, d) in units {
            let (t, out) = match d {
                Detail::Timed => run_unit(p, &mut traced, &laid, &u, Traced::take),
                Detail::Warmed => {
                    let (m, laid) = warming(&mut native, &mut traced, &laid, source);
                    run_unit(p, m, laid, &u, Native::take_log)
                }
            };
            each(&u, d, t, out)?;
        }
        Ok(())
    }
    match flavour {
        FlavourId::Lrb16 => go::<P, Lrb16, 16, E>(p, source, units, &mut each),
        FlavourId::Avx512 => go::<P, Avx512, 16, E>(p, source, units, &mut each),
        FlavourId::Avx2 => go::<P, Avx2, 8, E>(p, source, units, &mut each),
        FlavourId::Sse4 => go::<P, Sse4, 4, E>(p, source, units, &mut each),
        FlavourId::Wide32 => go::<P, Wide32, 32, E>(p, source, units, &mut each),
    }
}

/// Run unit `u` of `p` on `m` in its simulated thread's part of the address
/// space (released after it), then `finish` the machine's record of it.
fn run_unit<P: UnitProgram, M: Machine, R>(
    p: &P,
    m: &mut M,
    laid: &P::Laid,
    u: &Placed<P::Unit>,
    finish: impl FnOnce(&mut M) -> R,
) -> (R, P::Out) {
    let mark = m.space().mark();
    m.space().skip(u.thread as u64 * THREAD_SPAN);
    let out = p.unit(m, laid, &u.unit);
    let r = finish(m);
    m.space().release(mark);
    (r, out)
}

/// The warming machine: the traced one's address space and laid-out
/// buffers (their bytes shared), made when the first warmed unit comes.
fn warming<'a, FL: crate::Flavour<N>, const N: usize, L: Clone>(
    native: &'a mut Option<(Native<FL, N, WarmLog>, L)>,
    traced: &mut Traced<FL, N>,
    laid: &L,
    source: &str,
) -> &'a mut (Native<FL, N, WarmLog>, L) {
    native.get_or_insert_with(|| {
        let space = traced.space().clone();
        (
            Native::<FL, N, WarmLog>::logging_in(space, source),
            laid.clone(),
        )
    })
}

/// A [`UnitProgram`] whose timed steps can be recorded on several host
/// threads ([`run_steps`]).
pub trait StepProgram: UnitProgram<Laid: Sync, Unit: Sync, Out: Send> + Sync {}
impl<P: UnitProgram<Laid: Sync, Unit: Sync, Out: Send> + Sync> StepProgram for P {}

/// A step of [`run_steps`]: units that start together, one per simulated
/// thread, all timed or all warmed.
#[derive(Clone, Debug)]
pub struct Step<U> {
    /// The units, each on its own simulated thread.
    pub units: Vec<Placed<U>>,
    /// How they run.
    pub detail: Detail,
}

/// Run `steps` of `p` in order. A warmed step's units run natively one
/// after another, as [`run_units`] runs them, each going to `warm` with its
/// log and output. A timed step's units are recorded at once, each on its
/// simulated thread's own traced machine (a copy of the machine the data
/// was laid out on) and its own host thread, their ops handed in chunks of
/// [`crate::traced::STREAM_CHUNK`] to `timed`, which times them as they come
/// (a recorder waits while its next chunks are not taken, so no unit's
/// whole trace is held); `done` then gets the step's units, their outputs
/// and what `timed` returned. Stops at the first error.
///
/// # Panics
/// If a timed step has two units on one simulated thread.
#[allow(clippy::type_complexity)]
pub fn run_steps<P: StepProgram, E, T>(
    p: &P,
    flavour: FlavourId,
    source: &str,
    steps: impl IntoIterator<Item = Step<P::Unit>>,
    mut warm: impl FnMut(&Placed<P::Unit>, Trace, P::Out) -> Result<(), E>,
    mut timed: impl FnMut(&[Placed<P::Unit>], &mut [Receiver<Trace>]) -> Result<T, E>,
    mut done: impl FnMut(&[Placed<P::Unit>], Vec<P::Out>, T) -> Result<(), E>,
) -> Result<(), E> {
    let mut h = Handlers {
        warm: &mut warm,
        timed: &mut timed,
        done: &mut done,
    };
    match flavour {
        FlavourId::Lrb16 => steps_on::<P, Lrb16, 16, E, T>(p, source, steps, &mut h),
        FlavourId::Avx512 => steps_on::<P, Avx512, 16, E, T>(p, source, steps, &mut h),
        FlavourId::Avx2 => steps_on::<P, Avx2, 8, E, T>(p, source, steps, &mut h),
        FlavourId::Sse4 => steps_on::<P, Sse4, 4, E, T>(p, source, steps, &mut h),
        FlavourId::Wide32 => steps_on::<P, Wide32, 32, E, T>(p, source, steps, &mut h),
    }
}

/// [`run_steps`]'s three callbacks.
#[allow(clippy::type_complexity)]
struct Handlers<'a, U, O, E, T> {
    warm: &'a mut dyn FnMut(&Placed<U>, Trace, O) -> Result<(), E>,
    timed: &'a mut dyn FnMut(&[Placed<U>], &mut [Receiver<Trace>]) -> Result<T, E>,
    done: &'a mut dyn FnMut(&[Placed<U>], Vec<O>, T) -> Result<(), E>,
}

/// [`run_steps`] on flavour `FL`.
fn steps_on<P: StepProgram, FL: crate::Flavour<N> + Send + Sync, const N: usize, E, T>(
    p: &P,
    source: &str,
    steps: impl IntoIterator<Item = Step<P::Unit>>,
    h: &mut Handlers<'_, P::Unit, P::Out, E, T>,
) -> Result<(), E> {
    let mut traced = Traced::<FL, N>::new(source);
    let laid = p.lay_out(&mut traced);
    let _ = traced.take();
    let mut native: Option<(Native<FL, N, WarmLog>, P::Laid)> = None;
    let mut recorders: Vec<Traced<FL, N>> = Vec::new();
    for step in steps {
        if step.detail == Detail::Warmed {
            let (m, laid) = warming(&mut native, &mut traced, &laid, source);
            for u in &step.units {
                let (t, out) = run_unit(p, m, laid, u, Native::take_log);
                (h.warm)(u, t, out)?;
            }
            continue;
        }
        let need = step.units.iter().map(|u| u.thread + 1).max().unwrap_or(0);
        while recorders.len() < need {
            recorders.push(traced.clone());
        }
        let (r, outs) = record_step(p, &laid, &mut recorders, &step.units, &mut *h.timed);
        (h.done)(&step.units, outs, r?)?;
    }
    Ok(())
}

/// Record `units` at once, each on its thread's machine of `recorders` on a
/// host thread of its own, streaming to `timed`; (its result, the outputs).
#[allow(clippy::type_complexity)]
fn record_step<P: StepProgram, FL: crate::Flavour<N> + Send + Sync, const N: usize, E, T>(
    p: &P,
    laid: &P::Laid,
    recorders: &mut [Traced<FL, N>],
    units: &[Placed<P::Unit>],
    timed: &mut dyn FnMut(&[Placed<P::Unit>], &mut [Receiver<Trace>]) -> Result<T, E>,
) -> (Result<T, E>, Vec<P::Out>) {
    let (txs, mut rxs): (Vec<_>, Vec<_>) = units.iter().map(|_| sync_channel(2)).unzip();
    let mut machines: Vec<Option<&mut Traced<FL, N>>> = recorders.iter_mut().map(Some).collect();
    std::thread::scope(|sc| {
        let handles: Vec<_> = units
            .iter()
            .zip(txs)
            .map(|(u, tx)| {
                let m = machines[u.thread]
                    .take()
                    .expect("one unit per simulated thread in a timed step");
                sc.spawn(move || {
                    m.stream_to(tx);
                    run_unit(p, m, laid, u, Traced::end_stream).1
                })
            })
            .collect();
        let r = timed(units, &mut rxs);
        // A recorder waiting on a full channel sees it closed and finishes.
        drop(rxs);
        let outs = handles
            .into_iter()
            .map(|h| h.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
            .collect();
        (r, outs)
    })
}

/// Run `p` natively with the semantics of `flavour`.
pub fn run_native<P: Program>(p: &P, flavour: FlavourId) -> P::Out {
    match flavour {
        FlavourId::Lrb16 => p.run(&mut Native::<Lrb16, 16>::new()),
        FlavourId::Avx512 => p.run(&mut Native::<Avx512, 16>::new()),
        FlavourId::Avx2 => p.run(&mut Native::<Avx2, 8>::new()),
        FlavourId::Sse4 => p.run(&mut Native::<Sse4, 4>::new()),
        FlavourId::Wide32 => p.run(&mut Native::<Wide32, 32>::new()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::machine::Int;
    use crate::mem::{At, Buf};
    use crate::types::{MemKind, Site};

    /// Every memory op of the machine trait once per unit, with lane masks
    /// and indices from the unit, and a branch on a loaded value.
    struct AllMemOps;

    impl UnitProgram for AllMemOps {
        type Laid = Buf;
        type Unit = u32;
        type Out = i64;
        fn lay_out<M: Machine>(&self, m: &mut M) -> Buf {
            let v: Vec<f32> = (0..4096).map(|i| i as f32).collect();
            m.space().alloc_f32(MemKind::Nodes, "data", &v, 64)
        }
        fn unit<M: Machine>(&self, m: &mut M, data: &Buf, &bits: &u32) -> i64 {
            let n = M::LANES;
            let mut out = m.space().alloc(MemKind::Rays, "out", 16384, 64);
            let k = m.mask(bits & crate::LaneMask::full(n).0);
            let at = |i: usize| At::off(4 * i);
            let a = m.load(data, at(64));
            let b = m.loadu(data, at(3));
            let c = m.load_bcast(data, at(7));
            let d = m.load_repeat(data, at(128), 4);
            let e = m.load_operand(data, at(256), 4);
            let f = m.load_masked(k, a, data, at(300));
            let idx: Vec<i32> = (0..n as i32).map(|i| 97 * i + (bits % 64) as i32).collect();
            let ix = m.consts_i(&idx);
            let g = m.gather(k, b, data, at(0), ix, 4);
            let s = m.add(c, d);
            let s = m.add(s, e);
            let s = m.add(s, f);
            let s = m.add(s, g);
            m.store(&mut out, at(0), s);
            m.storeu(&mut out, at(33), s);
            m.store_masked(k, &mut out, at(64), s);
            m.scatter(k, &mut out, at(128), ix, 4, s);
            let packed = m.compress_store(k, &mut out, at(900), s);
            let i = m.int(bits as i64 % 50);
            let x = m.s_load(data, At::idx(i, 4, 0), 4, false);
            m.s_store(&mut out, At::idx(i, 8, 2048), 8, x);
            let y = m.x_load(data, at(999));
            m.x_store(&mut out, at(1000), y);
            let one = m.int(1);
            let odd = m.s_op(crate::SOp::And, packed, one);
            let taken = m.branch(Site(1), odd);
            i64::from(taken) + m.s_load(&out, At::off(2048), 8, false).get()
        }
    }

    #[test]
    fn a_warmed_unit_touches_what_its_recorded_trace_touches_on_every_flavour() {
        for fl in [
            FlavourId::Sse4,
            FlavourId::Avx2,
            FlavourId::Avx512,
            FlavourId::Lrb16,
        ] {
            let masks = [0u32, 1, 0b1011, 0xFFFF, 0x5A5A, 0x8001];
            let units = masks.iter().enumerate().flat_map(|(j, &bits)| {
                [Detail::Timed, Detail::Warmed].map(|d| {
                    let u = Placed {
                        thread: j % 3,
                        unit: bits,
                    };
                    (u, d)
                })
            });
            let mut views = Vec::new();
            run_units(&AllMemOps, fl, "t", units, |_, d, t, out| {
                views.push((d, t.warming_view(), out));
                Ok::<(), ()>(())
            })
            .unwrap();
            for (j, pair) in views.chunks(2).enumerate() {
                assert_eq!(pair[0].0, Detail::Timed);
                assert_eq!(pair[1].0, Detail::Warmed);
                assert_eq!(pair[0].2, pair[1].2, "{fl} unit {j}: same result");
                assert!(pair[0].1.len() >= 12, "{fl} unit {j}");
                assert_eq!(pair[0].1, pair[1].1, "{fl} unit {j} (mask {:#x})", masks[j]);
            }
        }
    }

    /// [`AllMemOps`]' unit `REPEAT` times: enough ops to cross chunks.
    struct Repeated;
    const REPEAT: usize = 1400;

    impl UnitProgram for Repeated {
        type Laid = Buf;
        type Unit = u32;
        type Out = i64;
        fn lay_out<M: Machine>(&self, m: &mut M) -> Buf {
            AllMemOps.lay_out(m)
        }
        fn unit<M: Machine>(&self, m: &mut M, data: &Buf, bits: &u32) -> i64 {
            (0..REPEAT).map(|_| AllMemOps.unit(m, data, bits)).sum()
        }
    }

    /// `t`'s ops with value ids numbered by first appearance (recorders on
    /// different machines number their values apart).
    fn canonical(t: &Trace) -> Vec<crate::trace::Op> {
        let mut ids = std::collections::HashMap::new();
        let mut name = |v: crate::ValId| {
            if v.is_some() {
                let n = ids.len() as u32 + 1;
                crate::ValId(*ids.entry(v.0).or_insert(n))
            } else {
                v
            }
        };
        t.ops
            .iter()
            .map(|o| {
                let mut o = *o;
                for s in &mut o.srcs[..o.nsrc as usize] {
                    *s = name(*s);
                }
                o.dst = name(o.dst);
                o
            })
            .collect()
    }

    #[test]
    fn streamed_steps_record_what_one_machine_records() {
        for fl in [FlavourId::Sse4, FlavourId::Avx2, FlavourId::Lrb16] {
            let masks = [0b1011u32, 0xFFFF, 0x5A5A];
            let placed = |j: usize| Placed {
                thread: j,
                unit: masks[j],
            };
            let mut want = Vec::new();
            let units = (0..3).map(|j| (placed(j), Detail::Timed));
            run_units(&Repeated, fl, "t", units, |_, _, t, out| {
                want.push((canonical(&t), t.lane_addrs.clone(), out));
                Ok::<(), ()>(())
            })
            .unwrap();
            assert!(
                want[0].0.len() > crate::traced::STREAM_CHUNK,
                "{fl}: crosses a chunk"
            );
            let steps = [
                Step {
                    units: vec![placed(2)],
                    detail: Detail::Warmed,
                },
                Step {
                    units: (0..3).map(placed).collect(),
                    detail: Detail::Timed,
                },
            ];
            let mut got = Vec::new();
            let mut warmed = 0;
            run_steps(
                &Repeated,
                fl,
                "t",
                steps,
                |_, _, _| {
                    warmed += 1;
                    Ok::<(), ()>(())
                },
                |_, rxs| {
                    // Taken in turns, as a timing loop would.
                    let mut whole: Vec<Option<Trace>> = vec![None; rxs.len()];
                    let mut open = vec![true; rxs.len()];
                    while open.iter().any(|&o| o) {
                        for (k, rx) in rxs.iter_mut().enumerate() {
                            match (open[k], rx.recv()) {
                                (true, Ok(c)) => match &mut whole[k] {
                                    Some(w) => w.append(&c),
                                    w => *w = Some(c),
                                },
                                _ => open[k] = false,
                            }
                        }
                    }
                    Ok(whole)
                },
                |_, outs, whole| {
                    for (t, out) in whole.into_iter().zip(outs) {
                        let t = t.expect("a first chunk");
                        got.push((canonical(&t), t.lane_addrs.clone(), out));
                    }
                    Ok(())
                },
            )
            .unwrap();
            assert_eq!(warmed, 1);
            assert_eq!(got.len(), 3);
            for (j, (g, w)) in got.iter().zip(&want).enumerate() {
                assert!(g == w, "{fl} unit {j}: streamed differs from recorded");
            }
        }
    }
}
