//! Trace files (binary and text) read and written with errors naming the
//! file, and the rows describing a trace.

use crate::io::write_atomic;
use crate::report::{Report, Row};
use crate::{AppError, AppResult};
use isa::{info, trace_file, trace_text, FlavourId, Trace};
use rt::boxtest::BoxStream;
use std::path::Path;

/// Read a binary or text trace; errors name the file and byte or line.
pub fn load_trace(path: &Path) -> AppResult<Trace> {
    load_trace_loop(path, false)
}

/// Read a trace; with `as_loop`, a source may be defined later in the body
/// (a loop-carried value), as for `rtsim sim --iterations`.
pub fn load_trace_loop(path: &Path, as_loop: bool) -> AppResult<Trace> {
    let bytes = std::fs::read(path).map_err(|e| AppError(format!("{}: {e}", path.display())))?;
    if bytes.starts_with(trace_file::MAGIC) {
        return trace_file::decode(&bytes)
            .map_err(|e| AppError(format!("{}: {e}", path.display())));
    }
    let text = std::str::from_utf8(&bytes).map_err(|e| {
        AppError(format!(
            "{}: byte {}: not an rtsim trace (no binary magic, not UTF-8 text)",
            path.display(),
            e.valid_up_to()
        ))
    })?;
    let t = trace_text::parse(text).map_err(|e| AppError(format!("{}: {e}", path.display())))?;
    let checked = if as_loop {
        t.validate_loop()
    } else {
        t.validate()
    };
    checked.map_err(|e| AppError(format!("{}: {e}", path.display())))?;
    Ok(t)
}

/// Whether a trace file name asks for the text form (`.txt`).
pub fn is_text_name(p: &Path) -> bool {
    p.extension().is_some_and(|e| e == "txt")
}

/// Encode a trace in the form the file name asks for.
pub fn save_trace(t: &Trace, path: &Path) -> AppResult<usize> {
    let bytes = if is_text_name(path) {
        trace_text::write(t).into_bytes()
    } else {
        trace_file::encode(t)
    };
    write_atomic(path, &bytes)?;
    Ok(bytes.len())
}

/// Rows describing a trace's contents.
#[must_use]
pub fn info_rows(t: &Trace) -> Vec<Row> {
    let i = info::info(t);
    let mut rows = vec![
        Row::new("ops", i.ops as f64).unit("ops"),
        Row::new("values", i.values as f64),
        Row::new("vector_ops", i.vector_ops as f64).unit("ops"),
        Row::new("lane_utilisation", i.lane_utilisation),
        Row::new("branches", i.branches as f64),
        Row::new("branches_taken", i.taken as f64),
    ];
    for (c, n) in &i.per_class {
        rows.push(Row::new("ops", *n as f64).key("class", c).unit("ops"));
    }
    for (r, n) in &i.per_region {
        rows.push(Row::new("ops", *n as f64).key("region", r).unit("ops"));
    }
    for m in &i.mem {
        let row = |metric: &str, v: u64, unit: &str| {
            Row::new(metric, v as f64)
                .key("mem", &m.name)
                .key("kind", &m.kind)
                .unit(unit)
        };
        rows.push(row("loads", m.loads, "accesses"));
        rows.push(row("stores", m.stores, "accesses"));
        rows.push(row("bytes_read", m.bytes_read, "B"));
        rows.push(row("bytes_written", m.bytes_written, "B"));
        rows.push(row("lines_touched", m.lines, "64B lines"));
    }
    rows
}

/// A report on a recorded trace (no machine, counts only).
pub fn base_report(name: &str, t: &Trace, input: String, secs: f64, rows: Vec<Row>) -> Report {
    Report {
        report: name.into(),
        machine: None,
        isa: Some(t.flavour.name().into()),
        fidelity: "counts".into(),
        sample: None,
        input: Some(input),
        ops_simulated: t.ops.len() as u64,
        host_seconds: secs,
        rows,
        notes: Vec::new(),
    }
}

/// The ray-vs-4-boxes workload of `rays` rays (a positive multiple of 4).
pub fn boxstream(rays: usize, seed: u64) -> AppResult<BoxStream> {
    if rays == 0 || !rays.is_multiple_of(4) {
        return Err(AppError(format!(
            "rays: {rays} is not a positive multiple of 4 (every ISA tests LANES/4 rays per step)"
        )));
    }
    Ok(BoxStream::generate(rays, seed))
}

/// Record microkernel `micro` or built-in kernel `kernel` (`boxtest`) on
/// flavour `fl` with `key=value` parameters; the trace and its source name.
pub fn record(
    micro: Option<&str>,
    kernel: Option<&str>,
    fl: FlavourId,
    params: &[(String, String)],
) -> AppResult<(Trace, String)> {
    Ok(if let Some(name) = micro {
        let k = micro::build(name, params)?;
        let src = format!("micro:{name}");
        (isa::record(&k, fl, &src).0, src)
    } else {
        let name = kernel.unwrap_or("boxtest");
        if name != "boxtest" {
            return Err(AppError(format!(
                "unknown kernel '{name}' (built in: boxtest)"
            )));
        }
        let (mut rays, mut seed) = (4096usize, 7u64);
        for (k, v) in params {
            let bad = || AppError(format!("--param {k}={v}: not a whole number"));
            match k.as_str() {
                "rays" => rays = v.parse().map_err(|_| bad())?,
                "seed" => seed = v.parse().map_err(|_| bad())?,
                _ => {
                    return Err(AppError(format!(
                        "unknown boxtest parameter '{k}' (rays, seed)"
                    )))
                }
            }
        }
        let w = boxstream(rays, seed)?;
        let mut t = isa::record(&w, fl, "kernel:boxtest").0;
        t.params.push(("seed".into(), seed.to_string()));
        (t, "kernel:boxtest".to_string())
    })
}
