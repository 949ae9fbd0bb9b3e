//! The text form of a report: its long rows grouped into the tables a reader
//! expects. Rows with the same keys form a section (rows without keys are the
//! summary). A section keyed by scene (or dataset) prints one table per
//! metric in the papers' shape — the other keys as rows, scenes as columns,
//! each cell ours with its interval and the paper's figure beside it; any
//! other section prints its entities as rows and its metrics as columns.
//! JSON and CSV stay the long format.

use crate::report::{Format, Report, Row};
use std::fmt::Write as _;

/// Keys that become columns, in order of preference (the papers' tables put
/// scenes across).
const ACROSS: [&str; 4] = ["scene", "dataset", "region", "mem"];

/// Keys that lead a row when present (what it is before where it ran).
const LEAD: [&str; 3] = ["name", "method", "kernel"];

/// At most this many metric columns per table; wider sections are split.
const MAX_METRIC_COLUMNS: usize = 6;

/// A number as the long table prints it.
#[must_use]
pub fn num(v: f64) -> String {
    if v.fract() == 0.0 && v.abs() < 1e15 {
        format!("{}", v as i64)
    } else if v.abs() >= 100.0 {
        format!("{v:.1}")
    } else {
        format!("{v:.4}")
    }
}

/// One cell: ours, its interval, what a config implies and the paper's.
fn cell(r: &Row) -> String {
    let mut s = num(r.value);
    if let Some(c) = r.ci95 {
        let _ = write!(s, " ±{}", num(c));
    }
    if let Some(e) = r.expected {
        let _ = write!(s, " (exp {})", num(e));
    }
    if let Some(p) = r.paper {
        let _ = write!(s, " [{}]", num(p));
    }
    s
}

/// Values in first-seen order.
fn distinct<'a>(it: impl Iterator<Item = &'a str>) -> Vec<&'a str> {
    let mut v: Vec<&str> = Vec::new();
    for x in it {
        if !v.contains(&x) {
            v.push(x);
        }
    }
    v
}

/// Rows grouped by their key names, sections in first-seen order.
fn sections(rows: &[Row]) -> Vec<(Vec<&str>, Vec<&Row>)> {
    let mut out: Vec<(Vec<&str>, Vec<&Row>)> = Vec::new();
    for r in rows {
        let mut keys: Vec<&str> = r.keys.keys().map(String::as_str).collect();
        keys.sort_by_key(|k| LEAD.iter().position(|l| l == k).unwrap_or(LEAD.len()));
        match out.iter_mut().find(|(k, _)| *k == keys) {
            Some((_, v)) => v.push(r),
            None => out.push((keys, vec![r])),
        }
    }
    out
}

/// Aligned columns, two spaces apart, indented by two.
fn table(lines: &[Vec<String>], s: &mut String) {
    let n = lines.iter().map(Vec::len).max().unwrap_or(0);
    let widths: Vec<usize> = (0..n)
        .map(|c| {
            lines
                .iter()
                .map(|l| l.get(c).map_or(0, |x| x.chars().count()))
                .max()
                .unwrap_or(0)
        })
        .collect();
    for l in lines {
        let cells: Vec<String> = l
            .iter()
            .zip(&widths)
            .map(|(v, w)| format!("{v:<w$}"))
            .collect();
        let _ = writeln!(s, "  {}", cells.join("  ").trim_end());
    }
}

/// A metric's heading: its name and unit.
fn metric_name(rows: &[&Row], m: &str) -> String {
    match rows
        .iter()
        .find(|r| r.metric == m)
        .and_then(|r| r.unit.as_ref())
    {
        Some(u) => format!("{m} ({u})"),
        None => m.to_string(),
    }
}

/// The identity of a row within a section: its values of `keys`.
fn ident(r: &Row, keys: &[&str]) -> Vec<String> {
    keys.iter().map(|k| r.keys[*k].clone()).collect()
}

/// A section with no keys: one line per metric.
fn summary(rows: &[&Row], s: &mut String) {
    let lines: Vec<Vec<String>> = rows
        .iter()
        .map(|r| vec![metric_name(rows, &r.metric), cell(r)])
        .collect();
    table(&lines, s);
}

/// A section keyed by `across` among others: a table per metric, the other
/// keys down, `across` along.
fn pivoted(keys: &[&str], across: &str, rows: &[&Row], s: &mut String) {
    let down: Vec<&str> = keys.iter().copied().filter(|k| *k != across).collect();
    let cols = distinct(rows.iter().map(|r| r.keys[across].as_str()));
    for (i, m) in distinct(rows.iter().map(|r| r.metric.as_str()))
        .into_iter()
        .enumerate()
    {
        if i > 0 {
            let _ = writeln!(s);
        }
        let _ = writeln!(s, "  {}", metric_name(rows, m));
        let mine: Vec<&Row> = rows.iter().copied().filter(|r| r.metric == m).collect();
        let mut head: Vec<String> = down.iter().map(|k| (*k).to_string()).collect();
        head.extend(cols.iter().map(|c| (*c).to_string()));
        let mut lines = vec![head];
        let mut ids: Vec<Vec<String>> = Vec::new();
        for r in &mine {
            let id = ident(r, &down);
            if !ids.contains(&id) {
                ids.push(id);
            }
        }
        for id in ids {
            let mut l = id.clone();
            for c in &cols {
                let r = mine
                    .iter()
                    .find(|r| r.keys[across] == *c && ident(r, &down) == id);
                l.push(r.map_or(String::new(), |r| cell(r)));
            }
            lines.push(l);
        }
        table(&lines, s);
    }
}

/// Any other section: entities down, metrics along (split when wide).
fn wide(keys: &[&str], rows: &[&Row], s: &mut String) {
    let metrics = distinct(rows.iter().map(|r| r.metric.as_str()));
    let mut ids: Vec<Vec<String>> = Vec::new();
    for r in rows {
        let id = ident(r, keys);
        if !ids.contains(&id) {
            ids.push(id);
        }
    }
    for chunk in metrics.chunks(MAX_METRIC_COLUMNS) {
        let mut head: Vec<String> = keys.iter().map(|k| (*k).to_string()).collect();
        head.extend(chunk.iter().map(|m| metric_name(rows, m)));
        let mut lines = vec![head];
        for id in &ids {
            let mut l = id.clone();
            for m in chunk {
                let r = rows
                    .iter()
                    .find(|r| r.metric == *m && ident(r, keys) == *id);
                l.push(r.map_or(String::new(), |r| cell(r)));
            }
            lines.push(l);
        }
        table(&lines, s);
    }
}

/// The header: what ran, on what, how much, how long.
fn header(r: &Report, s: &mut String) {
    let _ = write!(s, "{}", r.report);
    if let Some(i) = &r.input {
        let _ = write!(s, " — {i}");
    }
    let _ = writeln!(s);
    let mut facts = Vec::new();
    if let Some(i) = &r.isa {
        facts.push(format!("isa {i}"));
    }
    if let Some(m) = &r.machine {
        facts.push(format!("machine {m}"));
    }
    facts.push(format!("fidelity {}", r.fidelity));
    facts.push(format!("{} ops", r.ops_simulated));
    facts.push(format!("{:.2} s host time", r.host_seconds));
    let _ = writeln!(s, "{}", facts.join(", "));
    for (k, v) in r.sample.iter().flatten() {
        let v = v.as_str().map_or_else(|| v.to_string(), str::to_string);
        let _ = writeln!(s, "sample {k}: {v}");
    }
}

impl Report {
    /// Render in `f`.
    #[must_use]
    pub fn render(&self, f: Format) -> String {
        match f {
            Format::Json => {
                let mut s = serde_json::to_string_pretty(self).expect("report serialises");
                s.push('\n');
                s
            }
            Format::Csv => self.csv(),
            Format::Text => render(self),
        }
    }
}

/// The report as grouped text tables.
#[must_use]
pub fn render(r: &Report) -> String {
    let mut s = String::new();
    header(r, &mut s);
    if r.rows.iter().any(|x| x.paper.is_some()) {
        let _ = writeln!(
            s,
            "cells: ours ±95% interval (exp what the config implies) [the paper's]"
        );
    }
    for (keys, rows) in sections(&r.rows) {
        let _ = writeln!(s);
        match (keys.is_empty(), ACROSS.iter().find(|a| keys.contains(a))) {
            (true, _) => {
                let _ = writeln!(s, "summary");
                summary(&rows, &mut s);
            }
            (false, Some(across)) if keys.len() > 1 => {
                let _ = writeln!(s, "by {} (across)", keys.join(", "));
                pivoted(&keys, across, &rows, &mut s);
            }
            _ => {
                let _ = writeln!(s, "by {}", keys.join(", "));
                wide(&keys, &rows, &mut s);
            }
        }
    }
    if !r.notes.is_empty() {
        let _ = writeln!(s);
    }
    for n in &r.notes {
        let _ = writeln!(s, "note: {n}");
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn report(rows: Vec<Row>) -> Report {
        Report {
            report: "t".into(),
            machine: Some("m".into()),
            isa: None,
            fidelity: "full".into(),
            sample: None,
            input: None,
            ops_simulated: 3,
            host_seconds: 0.5,
            rows,
            notes: vec!["n".into()],
        }
    }

    fn long_sample() -> Report {
        report(vec![
            Row::new("ops", 3.0),
            Row::new("ops", 2.0).key("class", "vfma").unit("ops"),
            Row::new("ratio", 0.25).key("name", "a,b"),
        ])
    }

    #[test]
    fn scenes_go_across_methods_down_one_table_per_metric() {
        let r =
            |me: &str, sc: &str, m: &str, v: f64| Row::new(m, v).key("method", me).key("scene", sc);
        let t = render(&report(vec![
            Row {
                paper: Some(2.0),
                ci95: Some(0.25),
                ..r("a", "x", "mrays", 1.5)
            },
            r("a", "y", "mrays", 2.0),
            r("b", "x", "mrays", 3.0),
            r("a", "x", "cpi", 0.5),
        ]));
        let lines: Vec<&str> = t.lines().collect();
        let at = lines.iter().position(|l| l.trim() == "mrays").unwrap();
        assert_eq!(
            lines[at + 1].split_whitespace().collect::<Vec<_>>(),
            ["method", "x", "y"]
        );
        assert_eq!(
            lines[at + 2].split_whitespace().collect::<Vec<_>>(),
            ["a", "1.5000", "±0.2500", "[2]", "2"]
        );
        assert_eq!(
            lines[at + 3].split_whitespace().collect::<Vec<_>>(),
            ["b", "3"]
        );
        assert!(lines.iter().any(|l| l.trim() == "cpi"), "{t}");
        assert!(t.ends_with("note: n\n"), "{t}");
    }

    #[test]
    fn other_sections_put_metrics_across_and_keyless_rows_in_the_summary() {
        let t = render(&report(vec![
            Row::new("ops", 7.0),
            Row::new("cpi", 0.5).key("region", "leaf"),
            Row::new("mpki", 2.0).key("region", "leaf").unit("1/kinstr"),
            Row::new("cpi", 0.75).key("region", "node"),
        ]));
        assert!(t.contains("summary\n  ops  7\n"), "{t}");
        let lines: Vec<&str> = t.lines().collect();
        let at = lines.iter().position(|l| *l == "by region").unwrap();
        assert_eq!(
            lines[at + 1].split_whitespace().collect::<Vec<_>>(),
            ["region", "cpi", "mpki", "(1/kinstr)"]
        );
        assert_eq!(
            lines[at + 3].split_whitespace().collect::<Vec<_>>(),
            ["node", "0.7500"]
        );
    }

    #[test]
    fn wide_sections_are_split() {
        let rows = (0..8)
            .map(|i| Row::new(&format!("m{i}"), f64::from(i)).key("k", "v"))
            .collect();
        let t = render(&report(rows));
        assert_eq!(t.matches("  k  ").count(), 2, "{t}");
    }

    #[test]
    fn text_has_every_row() {
        let t = long_sample().render(Format::Text);
        assert!(t.contains("vfma") && t.contains("0.2500"), "{t}");
        // header (2), then per section: a blank line, a title, a header
        // line (not for the summary) and its rows; a blank line and the note.
        assert_eq!(t.lines().count(), 2 + 3 + 4 + 4 + 2, "{t}");
    }
}
