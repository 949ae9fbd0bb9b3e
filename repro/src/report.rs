//! One report schema for every command that prints figures (ARCHITECTURE.md,
//! "Report output"): long-format rows, printed as text, JSON or CSV.

use serde::Serialize;
use std::collections::BTreeMap;
use std::fmt::Write as _;

/// Output format.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Format {
    /// A readable table.
    #[default]
    Text,
    /// One JSON object.
    Json,
    /// CSV rows with a header.
    Csv,
}

impl Format {
    /// Every format with what it is.
    pub const ALL: [(Format, &'static str, &'static str); 3] = [
        (Format::Text, "text", "a readable table"),
        (Format::Json, "json", "one JSON object"),
        (Format::Csv, "csv", "CSV rows with a header"),
    ];
    /// The format called `s`, or an error listing them.
    pub fn from_name(s: &str) -> Result<Format, String> {
        Format::ALL
            .iter()
            .find(|f| f.1 == s)
            .map(|f| f.0)
            .ok_or_else(|| format!("unknown format '{s}' (text, json, csv)"))
    }
    /// File extension of a report written in this format.
    #[must_use]
    pub fn ext(self) -> &'static str {
        match self {
            Format::Text => "txt",
            Format::Json => "json",
            Format::Csv => "csv",
        }
    }
}

/// One figure: string keys saying what it is, the value, optional extras.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Row {
    /// What the row is about (method, scene, class, region, ...).
    #[serde(flatten)]
    pub keys: BTreeMap<String, String>,
    /// Metric name (lower-case, stable).
    pub metric: String,
    /// The number.
    pub value: f64,
    /// Unit, if any.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unit: Option<String>,
    /// 95% confidence half-width.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ci95: Option<f64>,
    /// What a config implies.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub expected: Option<f64>,
    /// The paper's own figure.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub paper: Option<f64>,
}

impl Row {
    /// A row with a metric and value and no keys.
    #[must_use]
    pub fn new(metric: &str, value: f64) -> Row {
        Row {
            keys: BTreeMap::new(),
            metric: metric.to_string(),
            value,
            unit: None,
            ci95: None,
            expected: None,
            paper: None,
        }
    }
    /// Add a key.
    #[must_use]
    pub fn key(mut self, k: &str, v: impl ToString) -> Row {
        self.keys.insert(k.to_string(), v.to_string());
        self
    }
    /// Set the unit.
    #[must_use]
    pub fn unit(mut self, u: &str) -> Row {
        self.unit = Some(u.to_string());
        self
    }
}

/// A whole report.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// Report name (e.g. `trace-info`).
    pub report: String,
    /// Machine config used, if timed.
    pub machine: Option<String>,
    /// ISA flavour.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub isa: Option<String>,
    /// Fidelity mode (`counts` when nothing is timed).
    pub fidelity: String,
    /// Sample description, if sampled.
    pub sample: Option<BTreeMap<String, serde_json::Value>>,
    /// What was read or run.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub input: Option<String>,
    /// Ops simulated or recorded.
    pub ops_simulated: u64,
    /// Host time of the command (the only figure that differs between runs).
    pub host_seconds: f64,
    /// The figures.
    pub rows: Vec<Row>,
    /// Why figures differ from the paper's, and what the sample leaves out.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub notes: Vec<String>,
}

impl Report {
    fn key_columns(&self) -> Vec<String> {
        let mut cols: Vec<String> = Vec::new();
        for r in &self.rows {
            for k in r.keys.keys() {
                if !cols.contains(k) {
                    cols.push(k.clone());
                }
            }
        }
        cols
    }

    /// The long rows as CSV with a header.
    pub(crate) fn csv(&self) -> String {
        let cols = self.key_columns();
        let mut s = String::new();
        let esc = |v: &str| {
            if v.contains([',', '"', '\n']) {
                format!("\"{}\"", v.replace('"', "\"\""))
            } else {
                v.to_string()
            }
        };
        let mut header: Vec<String> = cols.clone();
        header.extend(["metric", "value", "unit", "ci95", "expected", "paper"].map(String::from));
        let _ = writeln!(s, "{}", header.join(","));
        for r in &self.rows {
            let mut f: Vec<String> = cols
                .iter()
                .map(|c| esc(r.keys.get(c).map_or("", String::as_str)))
                .collect();
            f.push(esc(&r.metric));
            f.push(format!("{}", r.value));
            f.push(esc(r.unit.as_deref().unwrap_or("")));
            for o in [r.ci95, r.expected, r.paper] {
                f.push(o.map_or(String::new(), |v| format!("{v}")));
            }
            let _ = writeln!(s, "{}", f.join(","));
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Report {
        Report {
            report: "t".into(),
            machine: None,
            isa: Some("avx2".into()),
            fidelity: "counts".into(),
            sample: None,
            input: None,
            ops_simulated: 3,
            host_seconds: 0.5,
            rows: vec![
                Row::new("ops", 3.0),
                Row::new("ops", 2.0).key("class", "vfma").unit("ops"),
                Row::new("ratio", 0.25).key("name", "a,b"),
            ],
            notes: Vec::new(),
        }
    }

    #[test]
    fn json_is_long_format() {
        let v: serde_json::Value = serde_json::from_str(&sample().render(Format::Json)).unwrap();
        assert_eq!(v["rows"][1]["class"], "vfma");
        assert_eq!(v["rows"][1]["metric"], "ops");
        assert_eq!(v["rows"][1]["value"], 2.0);
        assert!(v["rows"][0].get("unit").is_none());
        assert!(v["machine"].is_null());
    }

    #[test]
    fn csv_quotes_and_aligns_columns() {
        let c = sample().render(Format::Csv);
        let lines: Vec<&str> = c.lines().collect();
        assert_eq!(lines[0], "class,name,metric,value,unit,ci95,expected,paper");
        assert_eq!(lines[2], "vfma,,ops,2,ops,,,");
        assert_eq!(lines[3], ",\"a,b\",ratio,0.25,,,,");
    }
}
