//! What a trace holds, without timing: op counts per class and region, SIMD
//! lane utilisation, branches, and bytes and cache lines touched per memory region.

use crate::class::OpClass;
use crate::trace::Trace;
use crate::types::Region;
use std::collections::{BTreeMap, HashSet};

/// Line size used for the "distinct lines touched" figure.
pub const INFO_LINE: u64 = 64;

/// Per memory region traffic.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct MemStats {
    /// Region name.
    pub name: String,
    /// Region kind name.
    pub kind: String,
    /// Load accesses (a gather counts one per active lane).
    pub loads: u64,
    /// Store accesses.
    pub stores: u64,
    /// Bytes read.
    pub bytes_read: u64,
    /// Bytes written.
    pub bytes_written: u64,
    /// Distinct 64-byte lines touched.
    pub lines: u64,
}

/// Summary of a trace.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TraceInfo {
    /// All ops (machine instructions).
    pub ops: u64,
    /// Ops per class (classes with none are left out).
    pub per_class: BTreeMap<&'static str, u64>,
    /// Ops per code region.
    pub per_region: BTreeMap<&'static str, u64>,
    /// Vector ops.
    pub vector_ops: u64,
    /// Mean active lanes / lanes over vector ops.
    pub lane_utilisation: f64,
    /// Conditional branches.
    pub branches: u64,
    /// Of which taken.
    pub taken: u64,
    /// Values produced.
    pub values: u64,
    /// Traffic per memory region, by region id (regions never touched left out).
    pub mem: Vec<MemStats>,
}

/// Summarise a trace.
#[must_use]
pub fn info(t: &Trace) -> TraceInfo {
    let lanes = t.flavour.lanes() as u64;
    let mut per_class = [0u64; 256];
    let mut per_region = [0u64; Region::COUNT];
    let mut active = 0u64;
    let mut vector_ops = 0u64;
    let mut branches = 0u64;
    let mut taken = 0u64;
    let mut values = 0u64;
    let mut mem: Vec<MemStats> = t
        .regions
        .iter()
        .map(|r| MemStats {
            name: r.name.clone(),
            kind: r.kind.name().to_string(),
            ..MemStats::default()
        })
        .collect();
    let mut lines: Vec<HashSet<u64>> = vec![HashSet::new(); t.regions.len()];
    for op in &t.ops {
        per_class[op.class as usize] += 1;
        per_region[op.region as usize] += 1;
        if op.class.is_vector() {
            vector_ops += 1;
            active += u64::from(op.mask.count());
        }
        if op.class == OpClass::Branch {
            branches += 1;
            taken += u64::from(op.taken());
        }
        values += u64::from(op.dst.is_some());
        if op.class.is_mem() {
            let m = &mut mem[op.mem.0 as usize];
            let set = &mut lines[op.mem.0 as usize];
            for (a, n) in t.accesses(op) {
                if op.class.is_load() {
                    m.loads += 1;
                    m.bytes_read += u64::from(n);
                } else {
                    m.stores += 1;
                    m.bytes_written += u64::from(n);
                }
                if n > 0 {
                    let first = a.0 / INFO_LINE;
                    let last = (a.0 + u64::from(n) - 1) / INFO_LINE;
                    set.extend(first..=last);
                }
            }
        }
    }
    for (m, s) in mem.iter_mut().zip(&lines) {
        m.lines = s.len() as u64;
    }
    TraceInfo {
        ops: t.ops.len() as u64,
        per_class: OpClass::ALL
            .iter()
            .filter(|c| per_class[**c as usize] > 0)
            .map(|c| (c.name(), per_class[*c as usize]))
            .collect(),
        per_region: Region::ALL
            .iter()
            .filter(|r| per_region[**r as usize] > 0)
            .map(|r| (r.name(), per_region[*r as usize]))
            .collect(),
        vector_ops,
        lane_utilisation: if vector_ops == 0 {
            0.0
        } else {
            active as f64 / (vector_ops * lanes) as f64
        },
        branches,
        taken,
        values,
        mem: mem.into_iter().filter(|m| m.loads + m.stores > 0).collect(),
    }
}
