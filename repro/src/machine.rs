//! Machine-level reports: a trace timed on a machine (`rtsim sim`), the
//! calibration microkernels against the config (`rtsim calibrate`), every
//! fidelity mode against full timing (`rtsim fidelity`), the machine list,
//! and the statistics rows every timed report shares.

use crate::report::{Report, Row};
use crate::traces::{boxstream, load_trace_loop};
use crate::{AppError, AppResult};
use isa::{OpClass, Region, Trace};
use micro::{ChainOp, Kind, Micro, MicroParams, CHAIN_OPS};
use sim::config::{CoreKind, MachineConfig};
use sim::{simulate, Fidelity, PerRay, SimOptions, Stall, Stats};
use std::path::Path;
use std::time::Instant;

/// Report rows of a run's statistics; per-ray figures when `rays` is given.
#[must_use]
pub fn stats_rows(s: &Stats, m: &MachineConfig, rays: Option<u64>) -> Vec<Row> {
    let mut rows = vec![
        Row::new("cycles", s.cycles as f64).unit("cycles"),
        Row::new("instructions", s.ops as f64),
        Row::new("uops", s.uops as f64),
        Row::new("cpi", s.cpi()),
    ];
    for r in Region::ALL {
        if let Some(c) = s.region_cpi(r) {
            rows.push(Row::new("cpi", c).key("region", r.name()));
            rows.push(
                Row::new("instructions", s.region_ops[r as usize] as f64).key("region", r.name()),
            );
        }
    }
    for st in Stall::ALL {
        rows.push(
            Row::new("stall_cycles", s.stalls[st as usize] as f64)
                .key("reason", st.name())
                .unit("cycles"),
        );
    }
    rows.extend(cpi_stack_rows(s, m.core.ports as usize));
    rows.push(Row::new("lane_utilisation", s.lane_utilisation()));
    rows.push(Row::new("branches", s.branches as f64));
    rows.push(Row::new("mispredicts", s.mispredicts as f64));
    rows.push(Row::new("loads_forwarded", s.forwarded as f64));
    rows.push(Row::new("forward_fails", s.forward_fails as f64));
    rows.push(Row::new("ordering_clears", s.ordering_clears as f64));
    for (l, name) in s.levels.iter().zip(&s.level_names) {
        rows.push(Row::new("hits", l.total_hits() as f64).key("level", name));
        rows.push(Row::new("misses", l.total_misses() as f64).key("level", name));
    }
    rows.push(Row::new("dram_bytes_read", s.dram_read as f64).unit("B"));
    rows.push(Row::new("dram_bytes_written", s.dram_written as f64).unit("B"));
    if let Some(r) = rays {
        let p = PerRay::new(s, r, m.clock_ghz, m.cores);
        let chip =
            |metric: &str, v: f64, unit: &str| Row::new(metric, v).unit(unit).key("cores", m.cores);
        let core =
            |metric: &str, v: f64, unit: &str| Row::new(metric, v).unit(unit).key("cores", 1);
        rows.push(chip("mray_per_s", p.mray_per_s_chip, "Mray/s"));
        rows.push(core("mray_per_s", p.mray_per_s_core, "Mray/s"));
        rows.push(chip("s_per_gray", p.s_per_gray_chip, "s/Gray"));
        rows.push(core("s_per_gray", p.s_per_gray_core, "s/Gray"));
        rows.push(Row::new("bytes_per_ray", p.bytes_per_ray).unit("B/ray"));
    }
    for c in OpClass::ALL {
        let n = s.class_ops[*c as usize];
        if n > 0 {
            rows.push(Row::new("instructions", n as f64).key("class", c.name()));
        }
    }
    rows
}

/// Per code region its CPI stack (cycles per instruction by stall reason,
/// summing to the region's CPI), its port-pressure part split by port and
/// each port's uops per cycle, and its bottleneck: the largest reason other
/// than issue bandwidth, with its share of the region's cycles (port
/// pressure also names its busiest port, `bottleneck_port_share`).
fn cpi_stack_rows(s: &Stats, ports: usize) -> Vec<Row> {
    let mut rows = Vec::new();
    for r in Region::ALL {
        let (Some(stack), Some((worst, share))) = (s.cpi_stack(r), s.bottleneck(r)) else {
            continue;
        };
        for st in Stall::ALL {
            rows.push(
                Row::new("cpi_stack", stack[st as usize])
                    .key("region", r.name())
                    .key("reason", st.name()),
            );
        }
        rows.extend(port_rows(s, r, ports));
        rows.push(
            Row::new("bottleneck_share", share)
                .key("region", r.name())
                .key("reason", worst.name()),
        );
        if worst == Stall::Ports {
            let cycles = s.region_cycles[r as usize] as f64;
            let by_port = &s.region_port_stalls[r as usize][..ports];
            let (p, &c) = by_port
                .iter()
                .enumerate()
                .max_by_key(|&(p, c)| (*c, std::cmp::Reverse(p)))
                .expect("at least one port");
            rows.push(
                Row::new("bottleneck_port_share", c as f64 / cycles)
                    .key("region", r.name())
                    .key("port", format!("p{p}")),
            );
        }
    }
    rows
}

/// Region `r`'s port-pressure CPI by port and uops per cycle per port.
fn port_rows(s: &Stats, r: Region, ports: usize) -> Vec<Row> {
    let (Some(stack), Some(pressure)) = (s.port_stack(r), s.port_pressure(r)) else {
        return Vec::new();
    };
    let mut rows = Vec::new();
    for p in 0..ports {
        let port = format!("p{p}");
        rows.push(
            Row::new("cpi_stack_ports", stack[p])
                .key("region", r.name())
                .key("port", &port),
        );
        rows.push(
            Row::new("port_uops_per_cycle", pressure[p])
                .key("region", r.name())
                .key("port", &port),
        );
    }
    rows
}

/// Hits and misses per cache level and data structure, DRAM bytes read per
/// data structure (names from the trace's memory regions).
#[must_use]
pub fn region_rows(s: &Stats, t: &Trace) -> Vec<Row> {
    let mut rows = Vec::new();
    for (r, reg) in t.regions.iter().enumerate() {
        for (l, name) in s.levels.iter().zip(&s.level_names) {
            let h = l.hits.get(r).copied().unwrap_or(0);
            let m = l.misses.get(r).copied().unwrap_or(0);
            if h + m > 0 {
                rows.push(
                    Row::new("hits", h as f64)
                        .key("level", name)
                        .key("mem", &reg.name),
                );
                rows.push(
                    Row::new("misses", m as f64)
                        .key("level", name)
                        .key("mem", &reg.name),
                );
            }
        }
        let d = s.dram_read_by_region.get(r).copied().unwrap_or(0);
        if d > 0 {
            rows.push(
                Row::new("dram_bytes_read", d as f64)
                    .key("mem", &reg.name)
                    .unit("B"),
            );
        }
    }
    rows
}

fn report(
    name: &str,
    m: &MachineConfig,
    fidelity: Fidelity,
    input: String,
    ops: u64,
    secs: f64,
    rows: Vec<Row>,
) -> Report {
    Report {
        report: name.into(),
        machine: Some(m.name.clone()),
        isa: Some(m.isa.clone()),
        fidelity: fidelity.name().into(),
        sample: None,
        input: Some(input),
        ops_simulated: ops,
        host_seconds: secs,
        rows,
        notes: Vec::new(),
    }
}

/// Successive windows of a loop agree within this share when it is steady.
pub const STEADY_TOLERANCE: f64 = 0.005;

/// A loop's steady state from runs of doubling length: each run's window
/// is its last half, (cycles(n) - cycles(n/2)) / (n - n/2), so the first
/// iterations' cold misses, predictor training and pipeline fill (and the
/// drain after the last) cancel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Steady {
    /// The longest run's window: cycles per iteration.
    pub per_iteration: f64,
    /// The shortest run from which every window agrees with the one before
    /// it within [`STEADY_TOLERANCE`] (`None`: the last two disagree).
    pub converged_after: Option<usize>,
    /// The last two windows' difference over the last.
    pub last_gap: f64,
}

impl Steady {
    /// From `(iterations, cycles)` runs, shortest first, each twice (or
    /// twice plus one) the one before.
    #[must_use]
    pub fn of(runs: &[(usize, u64)]) -> Steady {
        let windows: Vec<(usize, f64)> = runs
            .windows(2)
            .map(|w| {
                let ((h, ch), (n, cn)) = (w[0], w[1]);
                (n, cn.saturating_sub(ch) as f64 / (n - h) as f64)
            })
            .collect();
        let gap = |i: usize| {
            let (a, b) = (windows[i - 1].1, windows[i].1);
            (b - a).abs() / b.abs().max(f64::MIN_POSITIVE)
        };
        let k = windows.len();
        let first_steady = (1..k)
            .rev()
            .take_while(|&i| gap(i) <= STEADY_TOLERANCE)
            .last();
        Steady {
            per_iteration: windows.last().map_or(0.0, |w| w.1),
            converged_after: first_steady.map(|i| windows[i].0),
            last_gap: if k >= 2 { gap(k - 1) } else { f64::NAN },
        }
    }

    /// What the report says about it.
    fn note(&self, iterations: usize) -> String {
        let how = "cycles_per_iteration is the last half of the run: (cycles of N iterations - cycles of N/2) / (N - N/2), the first iterations' cold misses and pipeline fill cancelled; the same window is taken over runs of N/2, N/4, ... iterations";
        match self.converged_after {
            Some(n) => format!(
                "{how}. Steady: every window from {n} iterations on agrees with the one before within {:.1}% (the last two: {:.2}%). cycles_per_iteration_all is the mean over all {iterations}, warm-up included.",
                100.0 * STEADY_TOLERANCE,
                100.0 * self.last_gap
            ),
            None if self.last_gap.is_nan() => format!(
                "{how}. NOT STEADY: {iterations} iterations give one window, nothing to compare it with; give --iterations 4 or more."
            ),
            None => format!(
                "{how}. NOT STEADY: the windows of {iterations} and {} iterations differ by {:.2}% (more than {:.1}%); give --iterations {} or more.",
                iterations / 2,
                100.0 * self.last_gap,
                100.0 * STEADY_TOLERANCE,
                2 * iterations
            ),
        }
    }
}

/// `rtsim sim`: `trace` (repeated `iterations` times as a loop body) timed
/// on `m` at `fidelity`. With two or more iterations, `cycles_per_iteration`
/// is the loop's steady state ([`Steady`]): the last half of the run, with
/// whether windows over runs of N/2, N/4, ... agree; the mean over all N
/// iterations is `cycles_per_iteration_all`. Every other row is of the N runs.
pub fn sim_report(
    m: &MachineConfig,
    trace: &Path,
    iterations: usize,
    fidelity: Fidelity,
    timeline: Option<&str>,
) -> AppResult<(Report, Vec<sim::OpTimes>)> {
    let start = Instant::now();
    if iterations == 0 {
        return Err(AppError("--iterations: must be at least 1".into()));
    }
    let body = load_trace_loop(trace, iterations > 1)?;
    if timeline.is_some() && (fidelity != Fidelity::Full || m.core.kind != CoreKind::OutOfOrder) {
        return Err(AppError(
            "--timeline: needs full fidelity on an out-of-order machine".into(),
        ));
    }
    let run = |n: usize| {
        let t = if n > 1 {
            sim::repeat(&body, n)
        } else {
            body.clone()
        };
        let window = match timeline {
            Some(spec) if n == iterations => Some(crate::timeline::window(spec, &t)?),
            _ => None,
        };
        let opt = SimOptions {
            fidelity,
            warmup_ops: 0,
            timeline: window,
        };
        simulate(m, &[&t], &opt)
            .map(|s| (s, t))
            .map_err(|e| AppError(format!("{}: {e}", trace.display())))
    };
    let (s, t) = run(iterations)?;
    let mut ops = t.ops.len() as u64;
    let mean = s.cycles as f64 / iterations as f64;
    let mut notes = Vec::new();
    let mut extra = Vec::new();
    let per_iteration = if iterations > 1 {
        let mut cycles = vec![(iterations, s.cycles)];
        let mut n = iterations / 2;
        while n >= 1 {
            let (h, th) = run(n)?;
            ops += th.ops.len() as u64;
            cycles.push((n, h.cycles));
            n /= 2;
        }
        cycles.reverse();
        let st = Steady::of(&cycles);
        notes.push(st.note(iterations));
        extra.push(Row::new(
            "converged_after_iterations",
            st.converged_after.map_or(f64::NAN, |n| n as f64),
        ));
        extra.push(Row::new("last_windows_gap", st.last_gap));
        st.per_iteration
    } else {
        notes.push(
            "one iteration: cycles_per_iteration is its cycles from cold, not a steady state \
             (give --iterations 2 or more)"
                .into(),
        );
        mean
    };
    let mut rows = vec![
        Row::new("cycles_per_iteration", per_iteration).unit("cycles"),
        Row::new("cycles_per_iteration_all", mean).unit("cycles"),
    ];
    rows.extend(extra);
    for c in OpClass::ALL {
        let n = s.class_ops[*c as usize];
        if n > 0 {
            // Steady cycles per op of this class: a steady iteration's cycles
            // over the class's ops in one iteration.
            let per_iter = n as f64 / iterations as f64;
            rows.push(
                Row::new("cycles_per_op", per_iteration / per_iter)
                    .key("class", c.name())
                    .unit("cycles"),
            );
        }
    }
    rows.extend(stats_rows(&s, m, None));
    rows.extend(region_rows(&s, &t));
    rows.extend(crate::timeline::rows(&s.timeline));
    let mut rep = report(
        "sim",
        m,
        fidelity,
        format!("{} x {}", trace.display(), iterations),
        ops,
        start.elapsed().as_secs_f64(),
        rows,
    );
    rep.notes = notes;
    Ok((rep, s.timeline))
}

/// One calibration measurement.
struct Cal {
    name: String,
    metric: &'static str,
    class: Option<&'static str>,
    value: f64,
    expected: f64,
    unit: &'static str,
}

fn run_micro(m: &MachineConfig, k: &Micro, copies: usize) -> AppResult<(Stats, Trace)> {
    let (t, ()) = isa::record(k, m.flavour(), "calibrate");
    let traces: Vec<&Trace> = vec![&t; copies];
    let s = simulate(m, &traces, &SimOptions::default()).map_err(AppError)?;
    Ok((s, t))
}

fn micro(kind: Kind, p: MicroParams) -> Micro {
    Micro { kind, params: p }
}

/// The one class a chain or stream microkernel exercises on this flavour
/// (None when the flavour expands it into several classes).
fn class_of(m: &MachineConfig, op: ChainOp) -> AppResult<Option<OpClass>> {
    let k = micro(
        Kind::Chain(op),
        MicroParams {
            iters: 1,
            unroll: 4,
            ..MicroParams::default()
        },
    );
    let k = if op == ChainOp::Cmp {
        micro(Kind::Streams(op), k.params)
    } else {
        k
    };
    let (t, ()) = isa::record(&k, m.flavour(), "probe");
    let loop_classes = [OpClass::Alu, OpClass::Cmp, OpClass::Branch];
    let mut body: Vec<OpClass> = t
        .ops
        .iter()
        .map(|o| o.class)
        .filter(|c| !loop_classes.contains(c))
        .collect();
    body.sort();
    body.dedup();
    Ok(match (op, body.as_slice()) {
        (ChainOp::Alu, []) => Some(OpClass::Alu),
        (_, [one]) => Some(*one),
        _ => None,
    })
}

/// The core's issue facts the expectations depend on: threads that share
/// it (in order) and the least gap between dependent issues.
fn issue_facts(m: &MachineConfig) -> (bool, usize, f64) {
    let inorder = m.core.kind == CoreKind::InOrder;
    let threads = if inorder { m.core.threads as usize } else { 1 };
    let issue_gap = if inorder && m.core.no_back_to_back {
        2.0
    } else {
        1.0
    };
    (inorder, threads, issue_gap)
}

/// Calibration rows: every microkernel through the model next to what the config implies.
fn calibrate_rows(m: &MachineConfig) -> AppResult<Vec<Cal>> {
    let mut out = Vec::new();
    op_class_rows(m, &mut out)?;
    // The caches' and DRAM's latencies as measured with huge pages: 1 GiB
    // pages keep every chase inside the first TLB level. The TLB rows
    // measure translation with the machine's own pages.
    let huge = match m.tlb {
        Some(_) => m
            .with_sets(&["tlb.page_kib=1048576".into()])
            .map_err(|e| AppError(e.to_string()))?,
        None => m.clone(),
    };
    cache_latency_rows(&huge, &mut out)?;
    tlb_rows(m, &mut out)?;
    out.push(dram_stream_row(m)?);
    out.push(mispredict_row(m)?);
    Ok(out)
}

/// Latency (dependent chains) and reciprocal throughput (16 independent
/// streams) of every op class a chain microkernel exercises alone.
fn op_class_rows(m: &MachineConfig, out: &mut Vec<Cal>) -> AppResult<()> {
    let (_, threads, issue_gap) = issue_facts(m);
    // Differences of two runs cancel start-up and warm-up: (n2 - n1) iterations.
    let (n1, n2) = (20usize, 60usize);
    for &(op, name) in CHAIN_OPS {
        let Some(class) = class_of(m, op)? else {
            continue;
        };
        let t = m.class(class);
        let per_step = if op == ChainOp::Cvt { 2.0 } else { 1.0 };
        if op != ChainOp::Cmp {
            let p = |iters| MicroParams {
                iters,
                unroll: 64,
                ..MicroParams::default()
            };
            let (a, _) = run_micro(m, &micro(Kind::Chain(op), p(n1)), 1)?;
            let (b, _) = run_micro(m, &micro(Kind::Chain(op), p(n2)), 1)?;
            let ops = ((n2 - n1) * 64) as f64 * per_step;
            out.push(Cal {
                name: format!("{name}-chain"),
                metric: "latency",
                class: Some(class.name()),
                value: (b.cycles - a.cycles) as f64 / ops,
                expected: f64::from(t.lat).max(issue_gap),
                unit: "cycles",
            });
        }
        let p = |iters| MicroParams {
            iters,
            unroll: 16,
            streams: 16,
            ..MicroParams::default()
        };
        let (a, _) = run_micro(m, &micro(Kind::Streams(op), p(n1)), threads)?;
        let (b, _) = run_micro(m, &micro(Kind::Streams(op), p(n2)), threads)?;
        let ops = ((n2 - n1) * 16 * 16 * threads) as f64 * per_step;
        let rt = m.recip_throughput(class);
        let lat_bound = f64::from(t.lat) / 16.0 / threads as f64;
        out.push(Cal {
            name: format!("{name}-streams"),
            metric: "recip_throughput",
            class: Some(class.name()),
            value: (b.cycles - a.cycles) as f64 / ops,
            expected: rt.max(lat_bound),
            unit: "cycles",
        });
    }
    Ok(())
}

/// Load-to-use latency of each cache level and of DRAM.
fn cache_latency_rows(m: &MachineConfig, out: &mut Vec<Cal>) -> AppResult<()> {
    // Load-to-use latency of each level: a warm chase sized to miss the level
    // above and fit this one; DRAM: a cold chase.
    let chase = |ws: usize, iters: usize| {
        micro(
            Kind::PointerChase,
            MicroParams {
                iters,
                ws,
                unroll: 256,
                ..MicroParams::default()
            },
        )
    };
    let mut prev = 0usize;
    for (i, l) in m.caches.iter().enumerate() {
        let size = l.size_kib as usize * 1024;
        let ws = if i == 0 {
            size / 2
        } else {
            (2 * prev).max(size / 2)
        };
        prev = size;
        let nodes = ws / micro::CHASE_STRIDE;
        // A pass: at least one full cycle of the chase, in whole unrolls.
        let per = nodes.div_ceil(256) * 256;
        let passes = |n: usize| n * per;
        let (a, _) = run_micro(m, &chase(ws, passes(1)), 1)?;
        let (b, _) = run_micro(m, &chase(ws, passes(2)), 1)?;
        out.push(Cal {
            name: format!("pointer-chase-{}", l.name),
            metric: "load_latency",
            class: None,
            value: (b.cycles - a.cycles) as f64 / (passes(2) - passes(1)) as f64,
            expected: f64::from(l.latency),
            unit: "cycles",
        });
    }
    let cold = 1 << 20;
    let (a, _) = run_micro(m, &chase(cold, 2048), 1)?;
    let (b, _) = run_micro(m, &chase(cold, 6144), 1)?;
    debug_assert!(6144 * micro::CHASE_STRIDE <= cold);
    out.push(Cal {
        name: "pointer-chase-dram".into(),
        metric: "load_latency",
        class: None,
        value: (b.cycles - a.cycles) as f64 / 4096.0,
        expected: f64::from(m.dram.latency),
        unit: "cycles",
    });
    Ok(())
}

/// Translation cost of each TLB level past the first and of the walk: a
/// warm chase with one node per page (a page and a line apart), over twice
/// the pages the level before holds (each of its sets then cycles through
/// more pages than it has ways: every lookup misses) and, for a level,
/// no more than it holds. Expected: the level's latency (or the walk) plus
/// the latency of the first cache level whose sets hold the chased lines.
fn tlb_rows(m: &MachineConfig, out: &mut Vec<Cal>) -> AppResult<()> {
    let Some(t) = &m.tlb else {
        return Ok(());
    };
    let page = t.page_kib as usize * 1024;
    let stride = page + m.caches[0].line as usize;
    let mut cases: Vec<(String, usize, u32)> = t
        .levels
        .windows(2)
        .filter(|w| 2 * w[0].entries <= w[1].entries)
        .map(|w| (w[1].name.clone(), 2 * w[0].entries as usize, w[1].latency))
        .collect();
    let last = t.levels.last().expect("validated: one level or more");
    cases.push(("walk".into(), 2 * last.entries as usize, t.walk));
    for (name, least, cost) in cases {
        // Twice the pages the level before holds, or more where the chased
        // lines would half-fit a cache level.
        let Some((pages, line_latency)) = [1, 2, 4]
            .iter()
            .find_map(|k| chased_line_latency(m, k * least, stride).map(|l| (k * least, l)))
        else {
            continue;
        };
        let chase = |iters: usize| {
            micro(
                Kind::PointerChase,
                MicroParams {
                    iters,
                    ws: pages * stride,
                    stride,
                    unroll: 256,
                    ..MicroParams::default()
                },
            )
        };
        let per = pages.div_ceil(256) * 256;
        let (a, _) = run_micro(m, &chase(per), 1)?;
        let (b, _) = run_micro(m, &chase(2 * per), 1)?;
        out.push(Cal {
            name: format!("pointer-chase-tlb-{name}"),
            metric: "load_latency",
            class: None,
            value: (b.cycles - a.cycles) as f64 / per as f64,
            expected: f64::from(cost + line_latency),
            unit: "cycles",
        });
    }
    Ok(())
}

/// Load-to-use latency of `nodes` lines `stride` bytes apart chased in a
/// fixed cycle: the first cache level none of whose sets receives more of
/// them than half its ways (half leaves room for the prefetcher's lines, as
/// the cache rows fill each level half), every level before it receiving
/// more than its ways in some set (such a set misses on every visit, LRU),
/// or DRAM. None where a level lies between: its hits are not certain.
fn chased_line_latency(m: &MachineConfig, nodes: usize, stride: usize) -> Option<u32> {
    for c in &m.caches {
        let sets = c.size_kib as usize * 1024 / c.line as usize / c.ways as usize;
        let mut per_set = vec![0u32; sets];
        for i in 0..nodes {
            per_set[(i * stride / c.line as usize) % sets] += 1;
        }
        if per_set.iter().all(|&k| 2 * k <= c.ways) {
            return Some(c.latency);
        }
        if per_set.iter().all(|&k| k <= c.ways) {
            return None;
        }
    }
    Some(m.dram.latency)
}

/// DRAM bandwidth of a streaming load without the prefetcher.
fn dram_stream_row(m: &MachineConfig) -> AppResult<Cal> {
    // Streaming from DRAM without the prefetcher: limited by bandwidth or by
    // the miss slots (mshrs lines in flight per DRAM latency).
    let np = m
        .with_sets(&["prefetch=\"None\"".into()])
        .map_err(|e| AppError(e.to_string()))?;
    let stream = |iters| {
        micro(
            Kind::StreamLoad,
            MicroParams {
                iters,
                ws: 64 << 20,
                unroll: 8,
                ..MicroParams::default()
            },
        )
    };
    let (a, _) = run_micro(&np, &stream(8192), 1)?;
    let (b, _) = run_micro(&np, &stream(24576), 1)?;
    let line = f64::from(m.caches[0].line);
    Ok(Cal {
        name: "stream-load-dram".into(),
        metric: "dram_bandwidth",
        class: None,
        value: (b.dram_read - a.dram_read) as f64 / (b.cycles - a.cycles) as f64,
        expected: (m.dram.bandwidth_gbs / m.clock_ghz)
            .min(f64::from(m.mshrs) * line / f64::from(m.dram.latency)),
        unit: "B/cycle",
    })
}

/// Cycles per extra mispredict: random branches against predictable ones.
fn mispredict_row(m: &MachineConfig) -> AppResult<Cal> {
    let (inorder, _, issue_gap) = issue_facts(m);
    // Mispredict cost: random minus predictable, per extra mispredict. A
    // mispredicted iteration takes resolution + penalty instead of the
    // predictable iteration's own time, so that time is subtracted.
    let iters = 4000;
    let br = |kind| {
        micro(
            kind,
            MicroParams {
                iters,
                ..MicroParams::default()
            },
        )
    };
    let (p, _) = run_micro(m, &br(Kind::BranchPredictable), 1)?;
    let (r, _) = run_micro(m, &br(Kind::BranchRandom), 1)?;
    // Each iteration's load waits for the previous outcome, so a mispredict
    // adds exactly: the branch's latency after its source, the penalty, and
    // the redirected op's dispatch-to-issue cycle (out of order) — in order,
    // the thread waits for the branch's latency and the penalty, less the issue
    // gap it would have waited anyway.
    let penalty = f64::from(m.core.mispredict_penalty);
    let extra = (r.mispredicts - p.mispredicts).max(1) as f64;
    let blat = f64::from(m.class(OpClass::Branch).lat);
    let expected = if inorder {
        penalty + blat - issue_gap
    } else {
        penalty + blat + 1.0
    };
    Ok(Cal {
        name: "branch-random".into(),
        metric: "mispredict_cost",
        class: None,
        value: (r.cycles - p.cycles) as f64 / extra,
        expected,
        unit: "cycles",
    })
}

/// Calibration report of one machine; also used by tests.
pub fn calibrate_report(m: &MachineConfig) -> AppResult<Report> {
    let start = Instant::now();
    let cal = calibrate_rows(m)?;
    if let Some(c) = cal.iter().find(|c| !c.value.is_finite()) {
        return Err(AppError(format!(
            "calibrate {}: measured {} (a microkernel ran no ops)",
            c.name, c.value
        )));
    }
    let rows = cal
        .into_iter()
        .map(|c| {
            let mut r = Row::new(c.metric, c.value)
                .key("name", &c.name)
                .unit(c.unit);
            if let Some(cl) = c.class {
                r = r.key("class", cl);
            }
            r.expected = Some(c.expected);
            r
        })
        .collect();
    Ok(report(
        "calibrate",
        m,
        Fidelity::Full,
        format!("microkernels on {}", m.name),
        0,
        start.elapsed().as_secs_f64(),
        rows,
    ))
}

/// `rtsim fidelity`: every mode, host time and error against full timing,
/// on `trace` or else the ray-vs-4-boxes workload of `rays` rays.
pub fn fidelity_report(m: &MachineConfig, trace: Option<&Path>, rays: usize) -> AppResult<Report> {
    let start = Instant::now();
    let rays_in = rays;
    let (t, rays, input) = match trace {
        Some(p) => (load_trace_loop(p, false)?, None, p.display().to_string()),
        None => {
            let w = boxstream(rays_in, 7)?;
            let (t, _) = isa::record(&w, m.flavour(), "kernel:boxtest");
            (
                t,
                Some(rays_in as u64),
                format!("boxtest, {} rays", rays_in),
            )
        }
    };
    let mut runs = Vec::new();
    for f in Fidelity::ALL {
        let t0 = Instant::now();
        let s = simulate(
            m,
            &[&t],
            &SimOptions {
                fidelity: f,
                ..SimOptions::default()
            },
        )
        .map_err(AppError)?;
        runs.push((f, s, t0.elapsed().as_secs_f64()));
    }
    let full = runs.last().expect("full").1.clone();
    let per = |s: &Stats| {
        rays.map_or(
            (s.dram_read + s.dram_written) as f64 / s.ops.max(1) as f64,
            |r| PerRay::new(s, r, m.clock_ghz, m.cores).bytes_per_ray,
        )
    };
    let mut rows = Vec::new();
    for (f, s, secs) in &runs {
        let err = |a: f64, b: f64| if b == 0.0 { 0.0 } else { 100.0 * (a - b) / b };
        let k = |r: Row| r.key("mode", f.name());
        rows.push(k(Row::new("host_seconds", *secs).unit("s")));
        rows.push(k(Row::new(
            "mops_per_host_second",
            t.ops.len() as f64 / secs / 1e6,
        )
        .unit("Mops/s")));
        rows.push(k(Row::new("cycles", s.cycles as f64)));
        rows.push(k(Row::new(
            "cycles_error",
            err(s.cycles as f64, full.cycles as f64),
        )
        .unit("%")));
        rows.push(k(Row::new("cpi", s.cpi())));
        rows.push(k(Row::new("cpi_error", err(s.cpi(), full.cpi())).unit("%")));
        let (b, bf) = (per(s), per(&full));
        rows.push(k(Row::new(
            if rays.is_some() {
                "bytes_per_ray"
            } else {
                "bytes_per_op"
            },
            b,
        )));
        rows.push(k(Row::new("bytes_error", err(b, bf)).unit("%")));
    }
    let rep = report(
        "fidelity",
        m,
        Fidelity::Full,
        input,
        3 * t.ops.len() as u64,
        start.elapsed().as_secs_f64(),
        rows,
    );
    Ok(rep)
}

/// `rtsim list micro` rows.
#[must_use]
pub fn micro_rows() -> Vec<Row> {
    micro::list()
        .into_iter()
        .map(|m| {
            Row::new("available", 1.0)
                .key("name", &m.name)
                .key("what", &m.what)
        })
        .collect()
}

/// `rtsim list machines` rows.
#[must_use]
pub fn machine_rows() -> Vec<Row> {
    sim::config::BUILTIN
        .iter()
        .map(|(name, _)| {
            let m = MachineConfig::load(name).expect("built-in machines are valid");
            Row::new("cores", f64::from(m.cores))
                .key("name", name)
                .key("isa", &m.isa)
                .key("clock_ghz", m.clock_ghz)
                .key("about", &m.about)
        })
        .collect()
}
