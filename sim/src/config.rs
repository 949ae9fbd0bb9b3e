//! Machine configs: RON files in `configs/machines/`, every field checked
//! (`deny_unknown_fields`, value validation naming the field), every number
//! with a source comment in the file.

use isa::{FlavourId, OpClass};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fmt;
use std::path::Path;

/// Core kind.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum CoreKind {
    /// Out-of-order (Haswell class).
    OutOfOrder,
    /// In-order, multi-threaded (Larrabee class).
    InOrder,
}

/// The core.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CoreConfig {
    /// Out-of-order or in-order.
    pub kind: CoreKind,
    /// Fused-domain ops dispatched (OoO) or issued (in-order) per cycle.
    pub width: u32,
    /// Ops retired per cycle (OoO).
    #[serde(default)]
    pub retire_width: u32,
    /// Reorder buffer entries (OoO).
    #[serde(default)]
    pub rob: u32,
    /// Unified scheduler entries (OoO); with `fp_scheduler`, the entries of
    /// every uop not in it.
    #[serde(default)]
    pub scheduler: u32,
    /// A second scheduler for the uops whose ports all lie in its `ports`
    /// (AMD's floating-point scheduler; OoO). None: one scheduler.
    #[serde(default)]
    pub fp_scheduler: Option<FpScheduler>,
    /// Execution ports (OoO) or pipes (in-order: 0 = U, 1 = V).
    pub ports: u32,
    /// Store-to-load forwarding latency (OoO).
    #[serde(default)]
    pub store_forward_latency: u32,
    /// Extra cycles of a load that overlaps an older store it cannot take
    /// its bytes from (wider than the store, or spanning two stores): it
    /// waits for the stores to write the cache instead (OoO).
    #[serde(default)]
    pub store_forward_fail_penalty: u32,
    /// A load forwards from a store wider than 8 bytes only if it starts at
    /// the store's first byte (Core 2 and earlier: a 32-bit read of the
    /// second lane of a 128-bit store fails); otherwise any store that
    /// contains the load forwards (OoO).
    #[serde(default)]
    pub store_forward_wide_same_start: bool,
    /// Whether a load that overlaps a buffered store it cannot forward
    /// from waits until that store has retired and written the L1, then
    /// reads it there (OoO; at least `store_forward_fail_penalty` late
    /// either way); otherwise it pays the penalty alone.
    #[serde(default)]
    pub store_forward_fail_waits_commit: bool,
    /// Store buffer entries (OoO): a store dispatches only with a free
    /// entry, held until the store retires; loads forward from its stores.
    #[serde(default)]
    pub store_buffer: u32,
    /// Where a compare followed by the branch reading it is one uop: one
    /// dispatch slot, executed once on the branch's ports.
    #[serde(default = "fusion_off")]
    pub macro_fusion: MacroFusion,
    /// The code the kernels run as (64-bit by default: x86-64 builds, as
    /// the papers' were).
    #[serde(default)]
    pub code: CodeMode,
    /// A taken branch ends its issue group: the next op dispatches in the
    /// next cycle, however few slots the branch's cycle used (OoO; the
    /// front end delivers one taken branch's uops per cycle, as Intel's loop
    /// buffer does: a loop of 5 fused uops takes 2 cycles per iteration).
    #[serde(default)]
    pub taken_branch_ends_issue: bool,
    /// Ports a taken branch's uop may use, where they are fewer than the
    /// branch class's (OoO; Haswell: port 6 only). Empty: the class's ports.
    #[serde(default)]
    pub taken_branch_ports: Vec<u32>,
    /// The legacy decode pipeline, for ops that carry an instruction length
    /// (`len=` in a trace; OoO). None, or an op without a length: its uops
    /// come from the uop cache at the dispatch width.
    #[serde(default)]
    pub legacy_decode: Option<LegacyDecode>,
    /// Hardware threads per core: in-order, interleaved on the core (every
    /// run uses them all); out-of-order, simultaneous multithreading, used
    /// where a run asks for it (`sim::Session::with_threads`).
    #[serde(default = "one")]
    pub threads: u32,
    /// A thread cannot issue in two consecutive cycles (Knights Corner rule).
    #[serde(default)]
    pub no_back_to_back: bool,
    /// Cycles from a mispredicted branch's resolution to the first correct-path dispatch.
    pub mispredict_penalty: u32,
    /// Global history bits of the gshare predictor.
    pub history_bits: u32,
    /// log2 of the predictor's table of 2-bit counters.
    pub predictor_bits: u32,
    /// TAGE tagged tables over the gshare (which is then TAGE's base
    /// predictor); none: gshare alone.
    #[serde(default)]
    pub tage: Option<Tage>,
}

/// Where a core fuses a compare with the branch reading it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum MacroFusion {
    /// Never.
    Off,
    /// In 32-bit code only (Core 2: not in 64-bit mode).
    In32BitCode,
    /// In 32- and 64-bit code (Nehalem and later, AMD).
    On,
}

fn fusion_off() -> MacroFusion {
    MacroFusion::Off
}

/// The mode the kernels' code runs in.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum CodeMode {
    /// 32-bit (IA-32) code.
    Bits32,
    /// 64-bit (x86-64) code.
    #[default]
    Bits64,
}

impl CoreConfig {
    /// Whether compare-and-branch pairs fuse in the configured code mode.
    #[must_use]
    pub fn fuses(&self) -> bool {
        match self.macro_fusion {
            MacroFusion::Off => false,
            MacroFusion::In32BitCode => self.code == CodeMode::Bits32,
            MacroFusion::On => true,
        }
    }
}

/// A second scheduler: the uops that can issue only on `ports` wait in its
/// `entries`, the others in the core's `scheduler`.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FpScheduler {
    /// Its ports.
    pub ports: Vec<u32>,
    /// Its entries.
    pub entries: u32,
}

/// The tagged tables of a TAGE predictor (Seznec and Michaud 2006).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Tage {
    /// Tagged tables (1 to 16).
    pub tables: u32,
    /// log2 of each table's entries (4 to 16).
    pub table_bits: u32,
    /// Partial tag bits (4 to 15).
    pub tag_bits: u32,
    /// The shortest table's global history length in branches.
    pub min_history: u32,
    /// The longest table's (at most 2048); the others in a geometric series.
    pub max_history: u32,
}

/// The most tagged tables a TAGE config may ask for.
pub const MAX_TAGE_TABLES: usize = 16;

fn one() -> u32 {
    1
}

/// The legacy (x86 instruction) decoders of an out-of-order core's front
/// end: one fetch block of instruction bytes is predecoded per cycle, at
/// most `predecode_width` instructions of it a cycle, into the instruction
/// queue; the decoders take instructions in order from it, only the first
/// decoder takes one of several fused uops or a complex-only instruction,
/// and put their uops in the decoded-uop queue the core dispatches from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LegacyDecode {
    /// Bytes fetched and predecoded per cycle (an aligned block).
    pub fetch_bytes: u32,
    /// Instructions predecoded per cycle (at most; a block with more takes
    /// another cycle).
    pub predecode_width: u32,
    /// Instruction queue entries between the predecoder and the decoders.
    pub instruction_queue: u32,
    /// Instructions decoded per cycle.
    pub decoders: u32,
    /// Whether an instruction that can macro-fuse (cmp, test, add, sub,
    /// and, inc, dec) is kept off the last decoder.
    pub fusible_not_last: bool,
    /// Decoded-uop queue entries (fused uops) between the decoders and
    /// dispatch, for one thread; halved per thread when two share the core.
    pub decoded_queue: u32,
    /// Extra predecode cycles of an instruction with a length-changing
    /// prefix (it and everything after it wait).
    pub lcp_penalty: u32,
}

/// Most unfused uops one class may have (a config with more is rejected).
pub const MAX_UOPS: usize = 16;

/// Timing of one op class.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClassTiming {
    /// Result latency in cycles (loads: the load-to-use latency of an L1 hit;
    /// the cache model gives the L1 and deeper levels, and a class slower than
    /// the L1, such as a Zen FP load, adds the difference).
    pub lat: u32,
    /// Unfused uops, each with the ports that can execute it.
    pub uops: Vec<Vec<u32>>,
    /// Cycles each uop keeps its port busy (non-pipelined units: divide, sqrt).
    #[serde(default = "one")]
    pub occ: u32,
    /// Fused-domain uops: dispatch slots the op takes.
    #[serde(default = "one")]
    pub fused: u32,
    /// Extra port cycles per distinct cache line beyond the first (gather/scatter).
    #[serde(default)]
    pub per_line: u32,
    /// Timing on operands of at most 16 bytes where it differs from the
    /// full width (an xmm divide on a 256-bit machine; for a load or store,
    /// an access of at most 16 bytes: a ymm load on a machine whose zmm
    /// loads take a port two cycles); out-of-order cores.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub narrow: Option<Narrow>,
    /// Result latency through the op's first source, its condition (a
    /// cmov's flags, as the kernels' selects record it), where it differs
    /// from `lat` (which is then the latency through the other sources);
    /// out-of-order cores.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cond_lat: Option<u32>,
}

/// A class's latency and port occupancy on narrow (<= 16-byte) operands.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Narrow {
    /// Result latency in cycles.
    pub lat: u32,
    /// Cycles each uop keeps its port busy.
    #[serde(default = "one")]
    pub occ: u32,
}

/// One cache level.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CacheConfig {
    /// Name (`l1d`, `l2`, `l3`, `l4`): `--set l2.size_kib=128` uses it.
    pub name: String,
    /// Capacity in KiB.
    pub size_kib: u32,
    /// Associativity.
    pub ways: u32,
    /// Line size in bytes (a power of two).
    pub line: u32,
    /// Load-to-use latency of a hit at this level, in core cycles.
    pub latency: u32,
    /// Shared by all cores (else private per core).
    #[serde(default)]
    pub shared: bool,
}

/// Main memory.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DramConfig {
    /// Load-to-use latency of a DRAM access in core cycles (all levels missed).
    pub latency: u32,
    /// Sustained bandwidth in GB/s (10^9 bytes), shared by all cores.
    pub bandwidth_gbs: f64,
}

/// The data TLBs of a core: levels closest first, and the page walk
/// (the memory model's `Tlbs`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TlbConfig {
    /// Page size in KiB (4: a process without huge pages).
    pub page_kib: u32,
    /// TLB levels, closest first.
    pub levels: Vec<TlbLevel>,
    /// Extra load-to-use cycles of a translation every level missed (the
    /// page walk, its paging entries found in the caches).
    pub walk: u32,
}

/// One TLB level.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TlbLevel {
    /// Name (`dtlb`, `stlb`, ...).
    pub name: String,
    /// Entries (pages).
    pub entries: u32,
    /// Associativity.
    pub ways: u32,
    /// Extra load-to-use cycles of a translation found here (the first
    /// level's is 0: it is looked up beside the L1).
    pub latency: u32,
    /// Loads only (Core 2's DTLB0): stores look up the next level.
    #[serde(default)]
    pub loads_only: bool,
}

/// Hardware prefetcher.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Prefetch {
    /// None.
    None,
    /// On a miss in the last private level, also fetch the next line into it.
    NextLine,
    /// A stream prefetcher on the last private level: two misses to adjacent
    /// lines start a stream; every demand access in it keeps prefetches this
    /// many lines ahead.
    Stream(u32),
}

/// A whole machine.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MachineConfig {
    /// Name.
    pub name: String,
    /// What it models, in a few words.
    pub about: String,
    /// ISA flavour its kernels use.
    pub isa: String,
    /// Clock in GHz.
    pub clock_ghz: f64,
    /// Cores.
    pub cores: u32,
    /// The core.
    pub core: CoreConfig,
    /// Op class timings (every class a trace may hold).
    pub classes: BTreeMap<String, ClassTiming>,
    /// Cache levels, closest first.
    pub caches: Vec<CacheConfig>,
    /// Outstanding L1 misses per core.
    pub mshrs: u32,
    /// Prefetcher.
    pub prefetch: Prefetch,
    /// Main memory.
    pub dram: DramConfig,
    /// Data TLBs (none: addresses are not translated; every built-in
    /// machine has them, `--set tlb=null` removes them).
    #[serde(default)]
    pub tlb: Option<TlbConfig>,
}

/// A config error: file, line if known, field, message.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ConfigError {
    /// File (or machine name).
    pub file: String,
    /// Line, 1-based, if known.
    pub line: Option<usize>,
    /// Field path (e.g. `caches[1].ways`).
    pub field: String,
    /// What is wrong.
    pub msg: String,
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file)?;
        if let Some(l) = self.line {
            write!(f, ": line {l}")?;
        }
        if !self.field.is_empty() {
            write!(f, ": {}", self.field)?;
        }
        write!(f, ": {}", self.msg)
    }
}

impl std::error::Error for ConfigError {}

/// The built-in machines: name and RON text (the files in `configs/machines/`).
pub const BUILTIN: &[(&str, &str)] = &[
    (
        "haswell-i7-4750hq",
        include_str!("../../configs/machines/haswell-i7-4750hq.ron"),
    ),
    (
        "haswell-e5-2650v3",
        include_str!("../../configs/machines/haswell-e5-2650v3.ron"),
    ),
    (
        "larrabee",
        include_str!("../../configs/machines/larrabee.ron"),
    ),
    (
        "core2-q6600",
        include_str!("../../configs/machines/core2-q6600.ron"),
    ),
    (
        "core2-penryn-2ghz",
        include_str!("../../configs/machines/core2-penryn-2ghz.ron"),
    ),
    (
        "nehalem-x5550",
        include_str!("../../configs/machines/nehalem-x5550.ron"),
    ),
    (
        "nehalem-x5550-dual",
        include_str!("../../configs/machines/nehalem-x5550-dual.ron"),
    ),
    (
        "nehalem-w5580",
        include_str!("../../configs/machines/nehalem-w5580.ron"),
    ),
    (
        "dunnington-x7460",
        include_str!("../../configs/machines/dunnington-x7460.ron"),
    ),
    ("zen1", include_str!("../../configs/machines/zen1.ron")),
    ("zen3", include_str!("../../configs/machines/zen3.ron")),
    ("zen4", include_str!("../../configs/machines/zen4.ron")),
    (
        "zen4-avx512",
        include_str!("../../configs/machines/zen4-avx512.ron"),
    ),
    (
        "icelake-sp",
        include_str!("../../configs/machines/icelake-sp.ron"),
    ),
];

impl MachineConfig {
    /// Parse RON text; `file` names it in errors.
    pub fn parse(text: &str, file: &str) -> Result<MachineConfig, ConfigError> {
        let c: MachineConfig = ron::from_str(text).map_err(|e| ConfigError {
            file: file.to_string(),
            line: Some(e.position.line),
            field: String::new(),
            msg: e.code.to_string(),
        })?;
        c.validate().map_err(|(field, msg)| ConfigError {
            file: file.to_string(),
            line: find_line(text, &field),
            field,
            msg,
        })?;
        Ok(c)
    }

    /// A built-in machine by name, or a RON file by path.
    pub fn load(name_or_path: &str) -> Result<MachineConfig, ConfigError> {
        if let Some((_, text)) = BUILTIN.iter().find(|(n, _)| *n == name_or_path) {
            return MachineConfig::parse(text, &format!("configs/machines/{name_or_path}.ron"));
        }
        let p = Path::new(name_or_path);
        if p.exists() || name_or_path.ends_with(".ron") {
            let text = std::fs::read_to_string(p).map_err(|e| ConfigError {
                file: name_or_path.to_string(),
                line: None,
                field: String::new(),
                msg: e.to_string(),
            })?;
            return MachineConfig::parse(&text, name_or_path);
        }
        let names: Vec<&str> = BUILTIN.iter().map(|(n, _)| *n).collect();
        Err(ConfigError {
            file: name_or_path.to_string(),
            line: None,
            field: String::new(),
            msg: format!("no such machine or file (built in: {})", names.join(", ")),
        })
    }

    /// Apply `path=value` overrides (e.g. `core.width=6`, `l2.size_kib=128`,
    /// `classes.vfma.lat=6`); the result is validated again.
    pub fn with_sets(&self, sets: &[String]) -> Result<MachineConfig, ConfigError> {
        if sets.is_empty() {
            return Ok(self.clone());
        }
        let err = |field: &str, msg: String| ConfigError {
            file: format!("--set on {}", self.name),
            line: None,
            field: field.to_string(),
            msg,
        };
        let mut v = serde_json::to_value(self).expect("config serialises");
        for s in sets {
            let (path, value) = s
                .split_once('=')
                .ok_or_else(|| err(s, "expected KEY=VALUE".into()))?;
            let mut parts: Vec<String> = path.split('.').map(str::to_string).collect();
            if let Some(i) = self.caches.iter().position(|c| c.name == parts[0]) {
                parts.splice(0..1, ["caches".to_string(), i.to_string()]);
            }
            let mut cur = &mut v;
            for part in &parts {
                cur = match cur {
                    serde_json::Value::Object(m) => {
                        if !m.contains_key(part) {
                            return Err(err(path, format!("unknown field '{part}'")));
                        }
                        m.entry(part.clone()).or_insert(serde_json::Value::Null)
                    }
                    serde_json::Value::Array(a) => {
                        let i: usize = part
                            .parse()
                            .map_err(|_| err(path, format!("'{part}' is not an index")))?;
                        let n = a.len();
                        a.get_mut(i)
                            .ok_or_else(|| err(path, format!("index {i} out of range (0..{n})")))?
                    }
                    _ => {
                        return Err(err(
                            path,
                            format!("'{part}' is inside a value, not a struct"),
                        ))
                    }
                };
            }
            *cur =
                serde_json::from_str(value).unwrap_or(serde_json::Value::String(value.to_string()));
        }
        let c: MachineConfig =
            serde_json::from_value(v).map_err(|e| err(&sets.join(" "), e.to_string()))?;
        c.validate().map_err(|(field, msg)| err(&field, msg))?;
        Ok(c)
    }

    /// The ISA flavour.
    #[must_use]
    pub fn flavour(&self) -> FlavourId {
        FlavourId::from_name(&self.isa).expect("validated")
    }

    /// Timing of a class.
    #[must_use]
    pub fn class(&self, c: OpClass) -> &ClassTiming {
        &self.classes[c.name()]
    }

    /// Check every value; Err((field, message)).
    pub fn validate(&self) -> Result<(), (String, String)> {
        let e = |f: &str, m: &str| Err((f.to_string(), m.to_string()));
        if FlavourId::from_name(&self.isa).is_none() {
            return e(
                "isa",
                &format!(
                    "unknown ISA flavour '{}' (lrb16, avx512, avx2, sse4, wide32)",
                    self.isa
                ),
            );
        }
        if self.clock_ghz.is_nan() || self.clock_ghz <= 0.0 || self.clock_ghz >= 100.0 {
            return e("clock_ghz", "must be between 0 and 100");
        }
        if self.cores == 0 || self.cores > 1024 {
            return e("cores", "must be 1 to 1024");
        }
        self.validate_core()?;
        self.validate_classes()?;
        self.validate_caches()?;
        if self.dram.latency <= self.caches.last().map_or(0, |l| l.latency) {
            return e("dram.latency", "must exceed the last cache level's");
        }
        if self.dram.bandwidth_gbs.is_nan() || self.dram.bandwidth_gbs <= 0.0 {
            return e("dram.bandwidth_gbs", "must be positive");
        }
        if self.mshrs == 0 {
            return e("mshrs", "must be at least 1");
        }
        if let Prefetch::Stream(d) = self.prefetch {
            if d == 0 || d > 64 {
                return e("prefetch", "Stream degree must be 1 to 64");
            }
        }
        if let Some(t) = &self.tlb {
            validate_tlb(t)?;
        }
        Ok(())
    }

    /// The core's widths, window and predictor.
    fn validate_core(&self) -> Result<(), (String, String)> {
        let e = |f: &str, m: &str| Err((f.to_string(), m.to_string()));
        let c = &self.core;
        if c.width == 0 || c.width > 64 {
            return e("core.width", "must be 1 to 64");
        }
        if c.ports == 0 || c.ports > 16 {
            return e("core.ports", "must be 1 to 16");
        }
        if c.kind == CoreKind::OutOfOrder {
            if c.rob == 0 || c.rob > 4096 {
                return e("core.rob", "must be 1 to 4096");
            }
            if c.scheduler == 0 || c.scheduler > c.rob {
                return e("core.scheduler", "must be 1 to rob");
            }
            if c.retire_width == 0 {
                return e("core.retire_width", "must be at least 1");
            }
            if c.store_buffer == 0 || c.store_buffer > 1024 {
                return e("core.store_buffer", "must be 1 to 1024");
            }
        }
        if c.threads == 0 || c.threads > 16 {
            return e("core.threads", "must be 1 to 16");
        }
        if let Some(p) = c.taken_branch_ports.iter().find(|&&p| p >= c.ports) {
            return Err((
                "core.taken_branch_ports".into(),
                format!("port {p} does not exist (core.ports = {})", c.ports),
            ));
        }
        if let Some(f) = &c.fp_scheduler {
            if c.kind != CoreKind::OutOfOrder {
                return e("core.fp_scheduler", "is modelled on out-of-order cores");
            }
            if let Some(p) = f.ports.iter().find(|&&p| p >= c.ports) {
                return Err((
                    "core.fp_scheduler.ports".into(),
                    format!("port {p} does not exist (core.ports = {})", c.ports),
                ));
            }
            if f.ports.is_empty() || f.entries == 0 || f.entries > c.rob {
                return e(
                    "core.fp_scheduler",
                    "needs at least one port and 1 to rob entries",
                );
            }
        }
        if let Some(l) = c.legacy_decode {
            if !l.fetch_bytes.is_power_of_two() || l.fetch_bytes < 16 || l.fetch_bytes > 64 {
                return e(
                    "core.legacy_decode.fetch_bytes",
                    "must be 16, 32 or 64 (an aligned block at least one instruction long)",
                );
            }
            if l.decoders == 0 || l.decoders > 16 {
                return e("core.legacy_decode.decoders", "must be 1 to 16");
            }
            if l.predecode_width == 0 || l.predecode_width > 16 {
                return e("core.legacy_decode.predecode_width", "must be 1 to 16");
            }
            if l.instruction_queue < l.predecode_width || l.instruction_queue > 1024 {
                return e(
                    "core.legacy_decode.instruction_queue",
                    "must hold a predecode cycle's instructions, at most 1024",
                );
            }
            if l.decoded_queue < 2 * MAX_UOPS as u32 || l.decoded_queue > 4096 {
                return e(
                    "core.legacy_decode.decoded_queue",
                    "must be 32 to 4096 (two threads' halves each hold an instruction's uops)",
                );
            }
            if l.lcp_penalty > 100 {
                return e("core.legacy_decode.lcp_penalty", "must be 0 to 100");
            }
        }
        if c.kind != CoreKind::OutOfOrder
            && (c.taken_branch_ends_issue
                || !c.taken_branch_ports.is_empty()
                || c.legacy_decode.is_some())
        {
            return e(
                "core",
                "the front-end rules (taken_branch_ends_issue, taken_branch_ports, legacy_decode) are modelled on out-of-order cores",
            );
        }
        if c.history_bits > 24 || c.predictor_bits == 0 || c.predictor_bits > 24 {
            return e(
                "core.predictor_bits",
                "history_bits at most 24, predictor_bits 1 to 24",
            );
        }
        if let Some(t) = &c.tage {
            let ok = (1..=MAX_TAGE_TABLES as u32).contains(&t.tables)
                && (4..=16).contains(&t.table_bits)
                && (4..=15).contains(&t.tag_bits)
                && t.min_history >= 1
                && t.min_history < t.max_history
                && t.max_history <= 2048;
            if !ok {
                return e(
                    "core.tage",
                    "tables 1 to 16, table_bits 4 to 16, tag_bits 4 to 15, 1 <= min_history < max_history <= 2048",
                );
            }
        }
        Ok(())
    }

    /// Every op class has a timing on ports that exist; no unknown class.
    fn validate_classes(&self) -> Result<(), (String, String)> {
        let c = &self.core;
        for class in OpClass::ALL {
            let Some(t) = self.classes.get(class.name()) else {
                return Err((
                    format!("classes.{}", class.name()),
                    "missing: every op class needs a timing".into(),
                ));
            };
            let f = format!("classes.{}", class.name());
            if t.uops.len() > MAX_UOPS {
                return Err((format!("{f}.uops"), format!("at most {MAX_UOPS} uops")));
            }
            let renamed = matches!(class, OpClass::Branch | OpClass::Mov | OpClass::Zero);
            if t.uops.is_empty() && !renamed && t.fused > 0 {
                // Branches may be fused away, moves and zero idioms done at
                // rename; everything else executes somewhere.
                return Err((format!("{f}.uops"), "needs at least one uop".into()));
            }
            for u in &t.uops {
                if u.is_empty() {
                    return Err((format!("{f}.uops"), "a uop with no port".into()));
                }
                if let Some(p) = u.iter().find(|&&p| p >= c.ports) {
                    return Err((
                        format!("{f}.uops"),
                        format!("port {p} does not exist (core.ports = {})", c.ports),
                    ));
                }
            }
            if t.occ == 0 {
                return Err((format!("{f}.occ"), "must be at least 1".into()));
            }
            if let Some(n) = t.narrow {
                if c.kind != CoreKind::OutOfOrder || class.is_per_lane_mem() {
                    return Err((
                        format!("{f}.narrow"),
                        "narrow timings are modelled on out-of-order cores, for every class but gather and scatter"
                            .into(),
                    ));
                }
                if n.occ == 0 || n.lat == 0 || n.lat > 10_000 {
                    return Err((
                        format!("{f}.narrow"),
                        "lat 1 to 10000, occ at least 1".into(),
                    ));
                }
            }
            if (t.lat == 0 && !t.uops.is_empty()) || t.lat > 10_000 {
                return Err((
                    format!("{f}.lat"),
                    "must be 1 to 10000 cycles (0 only for a class with no uops)".into(),
                ));
            }
        }
        if let Some(k) = self
            .classes
            .keys()
            .find(|k| OpClass::from_name(k).is_none())
        {
            return Err((
                format!("classes.{k}"),
                "unknown op class (rtsim list classes)".into(),
            ));
        }
        Ok(())
    }

    /// Cache levels: ways, line size, whole sets, latencies growing.
    fn validate_caches(&self) -> Result<(), (String, String)> {
        let e = |f: &str, m: &str| Err((f.to_string(), m.to_string()));
        if self.caches.is_empty() {
            return e("caches", "at least one cache level");
        }
        for (i, l) in self.caches.iter().enumerate() {
            let f = |x: &str| format!("caches[{i}].{x}");
            if l.ways == 0 {
                return Err((f("ways"), "must be at least 1".into()));
            }
            if !l.line.is_power_of_two() || l.line < 8 {
                return Err((
                    f("line"),
                    format!("{} is not a power of two of at least 8", l.line),
                ));
            }
            let bytes = u64::from(l.size_kib) * 1024;
            let sets = bytes / (u64::from(l.ways) * u64::from(l.line));
            if sets == 0 || sets * u64::from(l.ways) * u64::from(l.line) != bytes {
                return Err((
                    f("size_kib"),
                    format!(
                        "{} KiB is not a whole number of sets of {} ways x {} B",
                        l.size_kib, l.ways, l.line
                    ),
                ));
            }
            if l.line != self.caches[0].line {
                return Err((f("line"), "all levels must share one line size".into()));
            }
            if i > 0 && l.latency <= self.caches[i - 1].latency {
                return Err((f("latency"), "must exceed the level above".into()));
            }
        }
        Ok(())
    }

    /// Reciprocal throughput of a class implied by its uops and ports: the
    /// most loaded set of ports, max over port sets S of (occupancy of the uops
    /// that can only run in S) / |S|.
    #[must_use]
    pub fn recip_throughput(&self, c: OpClass) -> f64 {
        let t = self.class(c);
        let n = self.core.ports;
        let mut best = 0f64;
        for s in 1u32..(1 << n) {
            let load: u32 = t
                .uops
                .iter()
                .filter(|u| u.iter().all(|&p| s >> p & 1 == 1))
                .map(|_| t.occ)
                .sum();
            best = best.max(f64::from(load) / f64::from(s.count_ones()));
        }
        best
    }
}

/// The line of a field in RON text: for `caches[i].x` the (i+1)-th `x:`,
/// for `classes.name...` the line naming `"name"`, else the first `x:`.
fn find_line(text: &str, field: &str) -> Option<usize> {
    let lines: Vec<&str> = text.lines().collect();
    if let Some(rest) = field.strip_prefix("classes.") {
        let name = rest.split('.').next()?;
        let pat = format!("\"{name}\"");
        return lines.iter().position(|l| l.contains(&pat)).map(|i| i + 1);
    }
    let last = field.rsplit('.').next()?;
    let key = last.split('[').next()?;
    let nth = field
        .split('[')
        .nth(1)
        .and_then(|s| s.split(']').next())
        .and_then(|s| s.parse::<usize>().ok())
        .unwrap_or(0);
    let pat = format!("{key}:");
    lines
        .iter()
        .enumerate()
        .filter(|(_, l)| l.split("//").next().unwrap_or("").contains(&pat))
        .nth(nth)
        .map(|(i, _)| i + 1)
}

/// A TLB config's page size, levels and walk.
fn validate_tlb(t: &TlbConfig) -> Result<(), (String, String)> {
    let e = |f: String, m: &str| Err((f, m.to_string()));
    if !t.page_kib.is_power_of_two() || t.page_kib > 1 << 20 {
        return e("tlb.page_kib".into(), "must be a power of two up to 1 GiB");
    }
    if t.levels.is_empty() || t.levels.len() > 4 {
        return e("tlb.levels".into(), "one to four levels");
    }
    for (i, l) in t.levels.iter().enumerate() {
        let f = |x: &str| format!("tlb.levels[{i}].{x}");
        if l.ways == 0 || l.entries == 0 || !l.entries.is_multiple_of(l.ways) || l.entries > 1 << 16
        {
            return e(f("entries"), "must be 1 to 65536 and a multiple of ways");
        }
        if i == 0 && l.latency != 0 {
            return e(
                f("latency"),
                "the first level is looked up beside the L1: 0",
            );
        }
        if l.latency > 1000 {
            return e(f("latency"), "must be 0 to 1000");
        }
        if l.loads_only && i + 1 == t.levels.len() {
            return e(
                f("loads_only"),
                "stores need a level after a loads-only one",
            );
        }
    }
    if t.walk == 0 || t.walk > 10_000 {
        return e("tlb.walk".into(), "must be 1 to 10000");
    }
    Ok(())
}
