//! The pipeline timeline of a window of ops (`rtsim sim --timeline`): which
//! ops, as rows, and a text view as llvm-mca's `-timeline` draws it.

use crate::report::Row;
use crate::{AppError, AppResult};
use isa::{Region, Trace};
use sim::OpTimes;

/// The most ops a timeline shows.
pub const MAX_OPS: usize = 1000;

/// The ops of `t` a window spec names, as (first index, count):
/// `START:LEN` (trace indices) or `REGION:START:LEN` (from the START-th op
/// of that code region, LEN ops of any region).
///
/// # Errors
/// A malformed spec, an unknown region, a window outside the trace, or more
/// than [`MAX_OPS`] ops.
pub fn window(spec: &str, t: &Trace) -> AppResult<(usize, usize)> {
    let bad = |why: &str| AppError(format!("--timeline '{spec}': {why}"));
    let parts: Vec<&str> = spec.split(':').collect();
    let num = |s: &str| {
        s.parse::<usize>()
            .map_err(|_| bad(&format!("'{s}' is not a count")))
    };
    let (region, start, len) = match parts.as_slice() {
        [s, l] => (None, num(s)?, num(l)?),
        [r, s, l] => {
            let reg = Region::ALL
                .into_iter()
                .find(|x| x.name() == *r)
                .ok_or_else(|| {
                    let names: Vec<&str> = Region::ALL.iter().map(|x| x.name()).collect();
                    bad(&format!("unknown region '{r}' ({})", names.join(", ")))
                })?;
            (Some(reg), num(s)?, num(l)?)
        }
        _ => return Err(bad("expected START:LEN or REGION:START:LEN")),
    };
    if len == 0 || len > MAX_OPS {
        return Err(bad(&format!("LEN must be 1 to {MAX_OPS}")));
    }
    let first = match region {
        None => start,
        Some(r) => t
            .ops
            .iter()
            .enumerate()
            .filter(|(_, o)| o.region == r)
            .nth(start)
            .map(|(i, _)| i)
            .ok_or_else(|| {
                bad(&format!(
                    "the trace has no op {start} in region {}",
                    r.name()
                ))
            })?,
    };
    if first >= t.ops.len() {
        return Err(bad(&format!("the trace has {} ops", t.ops.len())));
    }
    Ok((first, len.min(t.ops.len() - first)))
}

/// Rows per op: dispatch, issue, complete and retire cycles (from the
/// window's first dispatch) and the stall reason its retire was charged to.
#[must_use]
pub fn rows(ops: &[OpTimes]) -> Vec<Row> {
    let base = ops.iter().map(|o| o.dispatch).min().unwrap_or(0);
    let mut rows = Vec::new();
    for o in ops {
        let row = |metric: &str, c: u64| {
            Row::new(metric, (c - base) as f64)
                .key("op", o.index)
                .key("class", o.class.name())
                .key("region", o.region.name())
                .key("reason", o.stall.name())
                .unit("cycle")
        };
        rows.push(row("dispatch", o.dispatch));
        rows.push(row("issue", o.issue));
        rows.push(row("complete", o.complete));
        rows.push(row("retire", o.retire));
    }
    rows
}

/// The llvm-mca style view: a line per op, a column per cycle from the
/// window's first dispatch. `D` dispatched, `=` waiting for its operands or
/// a port, `e` executing, `E` result ready, `-` waiting to retire, `R`
/// retired.
#[must_use]
pub fn view(ops: &[OpTimes]) -> String {
    let Some(base) = ops.iter().map(|o| o.dispatch).min() else {
        return String::new();
    };
    let end = ops.iter().map(|o| o.retire).max().unwrap_or(base);
    let width = (end - base + 1) as usize;
    let mut out = format!(
        "Timeline (cycle 0 = {base}; D dispatch, = wait, e execute, E done, - wait to retire, R retire)\n"
    );
    let ruler: String = (0..width)
        .map(|c| char::from(b'0' + (c % 10) as u8))
        .collect();
    out += &format!("{:>8}  {:<10} {:<11} {ruler}\n", "op", "class", "region");
    for o in ops {
        let mut line = vec![b' '; width];
        let at = |c: u64| (c - base) as usize;
        for c in o.dispatch + 1..o.issue {
            line[at(c)] = b'=';
        }
        for c in o.issue..o.complete {
            line[at(c)] = b'e';
        }
        for c in o.complete + 1..o.retire {
            line[at(c)] = b'-';
        }
        line[at(o.dispatch)] = b'D';
        if o.complete > o.dispatch {
            line[at(o.complete)] = b'E';
        }
        line[at(o.retire)] = b'R';
        out += &format!(
            "{:>8}  {:<10} {:<11} {}\n",
            o.index,
            o.class.name(),
            o.region.name(),
            String::from_utf8_lossy(&line).trim_end()
        );
    }
    out
}

/// The timeline as a PNG at `path`: a bar per op, waiting (dispatch to
/// issue), executing (issue to complete) and waiting to retire (complete to
/// retire), cycles from the window's first dispatch.
///
/// # Errors
/// The file cannot be written.
pub fn png(path: &std::path::Path, ops: &[OpTimes]) -> AppResult<()> {
    let base = ops.iter().map(|o| o.dispatch).min().unwrap_or(0) as f64;
    let lanes: Vec<crate::plot::Lane> = ops
        .iter()
        .map(|o| {
            let c = |x: u64| x as f64 - base;
            crate::plot::Lane {
                label: format!("{} {}", o.index, o.class.name()),
                segments: vec![
                    (c(o.dispatch), c(o.issue).max(c(o.dispatch) + 0.2), 0),
                    (c(o.issue), c(o.complete).max(c(o.issue) + 0.2), 1),
                    (c(o.complete), c(o.retire) + 1.0, 2),
                ],
            }
        })
        .collect();
    crate::plot::write_lanes(
        path,
        "pipeline timeline",
        "cycle",
        &[
            "dispatched, waiting",
            "executing",
            "done, waiting to retire",
        ],
        &lanes,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use isa::OpClass;
    use sim::Stall;

    #[test]
    fn the_view_marks_each_stage_in_its_cycle() {
        let op = |index, d, i, c, r| OpTimes {
            index,
            class: OpClass::VFma,
            region: Region::CoreLoop,
            dispatch: d,
            issue: i,
            complete: c,
            retire: r,
            stall: Stall::Issue,
        };
        let v = view(&[op(7, 10, 12, 15, 17), op(8, 10, 11, 12, 17)]);
        let lines: Vec<&str> = v.lines().collect();
        assert!(lines[2].ends_with("D=eeeE-R"), "{v}");
        assert!(lines[3].ends_with("DeE----R"), "{v}");
        let r = rows(&[op(7, 10, 12, 15, 17)]);
        let vals: Vec<f64> = r.iter().map(|r| r.value).collect();
        assert_eq!(vals, [0.0, 2.0, 5.0, 7.0]);
    }
}
