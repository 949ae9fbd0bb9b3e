//! `rtsim trace record|info|text`.

use crate::cli::TraceCmd;
use isa::{trace_file, trace_text};
use repro::io::write_atomic;
use repro::report::Row;
use repro::traces::{base_report, info_rows, load_trace, record, save_trace};
use repro::{AppError, AppResult};
use std::time::Instant;

fn split_params(params: &[String]) -> AppResult<Vec<(String, String)>> {
    params
        .iter()
        .map(|p| {
            p.split_once('=')
                .map(|(k, v)| (k.trim().to_string(), v.trim().to_string()))
                .ok_or_else(|| AppError(format!("--param '{p}': expected KEY=VALUE")))
        })
        .collect()
}

/// `rtsim trace ...`.
pub fn trace(cmd: TraceCmd) -> AppResult<()> {
    match cmd {
        TraceCmd::Record {
            micro,
            kernel,
            isa: fl,
            params,
            out,
        } => {
            let params = split_params(&params)?;
            let (t, source) = record(micro.as_deref(), kernel.as_deref(), fl, &params)?;
            let n = save_trace(&t, &out)?;
            println!(
                "wrote {}: {source} on {fl}, {} ops, {n} bytes ({:.2} bytes/op)",
                out.display(),
                t.ops.len(),
                n as f64 / t.ops.len().max(1) as f64
            );
            Ok(())
        }
        TraceCmd::Info { file, format } => {
            let start = Instant::now();
            let t = load_trace(&file)?;
            let size = std::fs::metadata(&file)?.len();
            let mut rows = vec![
                Row::new("file_bytes", size as f64).unit("B"),
                Row::new("bytes_per_op", size as f64 / t.ops.len().max(1) as f64).unit("B"),
            ];
            rows.extend(info_rows(&t));
            let mut rep = base_report(
                "trace-info",
                &t,
                format!("{} ({})", file.display(), t.source),
                start.elapsed().as_secs_f64(),
                rows,
            );
            rep.sample = None;
            print!("{}", rep.render(format));
            Ok(())
        }
        TraceCmd::Text { input, output } => {
            let t = load_trace(&input)?;
            let binary_in = std::fs::read(&input)?.starts_with(trace_file::MAGIC);
            let bytes = if binary_in {
                trace_text::write(&t).into_bytes()
            } else {
                trace_file::encode(&t)
            };
            write_atomic(&output, &bytes)?;
            println!(
                "wrote {} ({} form, {} ops, {} bytes)",
                output.display(),
                if binary_in { "text" } else { "binary" },
                t.ops.len(),
                bytes.len()
            );
            Ok(())
        }
    }
}
