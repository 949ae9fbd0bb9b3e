//! The text form of a trace: one op per line, writable by hand.
//! `traces/FORMAT.md` specifies it; in short:
//!
//! ```text
//! .trace 1
//! .isa avx2
//! .source hand:fma-loop
//! .param note=ten independent chains
//! .mem 1 rays rays 0x10003000 4096
//! .code core-loop
//! %1 = vload @rays+0x0:32
//! %2 = vfma %1 %1 %1
//! vstore %2 @rays+0x20:32
//! %3 = cmp %2
//! branch %3 site=1 taken
//! ```

use crate::class::OpClass;
use crate::flavour::FlavourId;
use crate::mem::{MemRegion, LUT_BYTES};
use crate::trace::{Op, Trace, FLAG_ADDR, FLAG_TAKEN};
use crate::trace_file::default_mask;
use crate::types::{Addr, LaneMask, MemId, MemKind, Region, ValId};
use std::fmt::{self, Write as _};

/// A malformed text trace: what is wrong and on which line (1-based).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TextError {
    /// Line number, 1-based.
    pub line: usize,
    /// What was wrong.
    pub msg: String,
}

impl fmt::Display for TextError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "line {}: {}", self.line, self.msg)
    }
}

impl std::error::Error for TextError {}

/// Write a trace as text.
#[must_use]
pub fn write(t: &Trace) -> String {
    let mut s = String::with_capacity(64 + t.ops.len() * 24);
    let _ = writeln!(s, "# rtsim trace, text form (traces/FORMAT.md)");
    let _ = writeln!(s, ".trace 1");
    let _ = writeln!(s, ".isa {}", t.flavour);
    let _ = writeln!(s, ".source {}", t.source);
    for (k, v) in &t.params {
        let _ = writeln!(s, ".param {k}={v}");
    }
    let names: Vec<String> = t
        .regions
        .iter()
        .map(|r| {
            let unique = t.regions.iter().filter(|o| o.name == r.name).count() == 1;
            let plain = !r.name.is_empty()
                && r.name
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
                && !r.name.chars().all(|c| c.is_ascii_digit());
            if unique && plain {
                r.name.clone()
            } else {
                r.id.0.to_string()
            }
        })
        .collect();
    for r in &t.regions {
        let _ = writeln!(
            s,
            ".mem {} {} {} {:#x} {}",
            r.id.0,
            r.kind.name(),
            sanitize(&r.name),
            r.base.0,
            r.size
        );
    }
    let full = LaneMask::full(t.flavour.lanes());
    let mut region = Region::Other;
    for op in &t.ops {
        if op.region != region {
            region = op.region;
            let _ = writeln!(s, ".code {}", region.name());
        }
        if op.dst.is_some() {
            let _ = write!(s, "%{} = ", op.dst.0);
        }
        s.push_str(op.class.name());
        let addr_src = op.class.is_store() && op.has_addr_src();
        for src in &op.sources()[usize::from(addr_src)..] {
            let _ = write!(s, " %{}", src.0);
        }
        if op.class.is_mem() {
            let r = &t.regions[op.mem.0 as usize];
            let name = &names[op.mem.0 as usize];
            if op.class.is_per_lane_mem() {
                let _ = write!(s, " @{name}[");
                for (i, a) in t.lanes_of(op).iter().enumerate() {
                    if i > 0 {
                        s.push(',');
                    }
                    let _ = write!(s, "{:#x}", a.0 - r.base.0);
                }
                let _ = write!(s, "]:{}", op.bytes);
            } else {
                let _ = write!(s, " @{name}+{:#x}:{}", op.addr.0 - r.base.0, op.bytes);
            }
        }
        if addr_src {
            let _ = write!(s, " addr=%{}", op.srcs[0].0);
        }
        if op.is_sited_load() && op.aux != 0 {
            let _ = write!(s, " site={}", op.aux);
        }
        if op.mask != default_mask(op.class, full) {
            let _ = write!(s, " mask={:#x}", op.mask.0);
        }
        if !op.class.is_mem() && op.bytes != 0 {
            let _ = write!(s, " w={}", op.bytes);
        }
        if op.ilen != 0 {
            let _ = write!(s, " len={}", op.ilen);
        }
        if op.lcp() {
            s.push_str(" lcp");
        }
        if op.complex() {
            s.push_str(" complex");
        }
        if op.flags & crate::trace::FLAG_FUSIBLE != 0 {
            s.push_str(" fusible");
        }
        if op.class == OpClass::Branch {
            let _ = write!(
                s,
                " site={} {}",
                op.aux,
                if op.taken() { "taken" } else { "not-taken" }
            );
        }
        s.push('\n');
    }
    s
}

fn sanitize(name: &str) -> String {
    if name.is_empty() {
        return "_".into();
    }
    name.chars()
        .map(|c| if c.is_whitespace() { '_' } else { c })
        .collect()
}

fn parse_u64(s: &str) -> Option<u64> {
    if let Some(h) = s.strip_prefix("0x") {
        u64::from_str_radix(h, 16).ok()
    } else {
        s.parse().ok()
    }
}

/// What a text trace's directives have set so far.
struct TextState {
    have_isa: bool,
    have_version: bool,
    /// The code region of the ops that follow.
    region: Region,
    /// All lanes of the flavour.
    full: LaneMask,
}

/// Parse a text trace. Structure is checked here; call [`Trace::validate`]
/// for dependency order.
pub fn parse(text: &str) -> Result<Trace, TextError> {
    let mut t = Trace::new(FlavourId::Avx2, "");
    let mut st = TextState {
        have_isa: false,
        have_version: false,
        region: Region::Other,
        full: LaneMask::full(t.flavour.lanes()),
    };
    for (ln, raw) in text.lines().enumerate() {
        let line_no = ln + 1;
        let err = |msg: String| TextError { line: line_no, msg };
        let line = raw.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        if let Some(d) = line.strip_prefix('.') {
            let (key, rest) = d.split_once(char::is_whitespace).unwrap_or((d, ""));
            directive(&mut t, &mut st, key, rest.trim()).map_err(err)?;
            continue;
        }
        if !st.have_isa {
            return Err(err("an op before '.isa'".into()));
        }
        let op = op_line(&mut t, &st, line).map_err(err)?;
        t.ops.push(op);
    }
    let (have_version, have_isa) = (st.have_version, st.have_isa);
    if !have_version {
        return Err(TextError {
            line: 1,
            msg: "missing '.trace 1' header".into(),
        });
    }
    if !have_isa {
        return Err(TextError {
            line: 1,
            msg: "missing '.isa' header".into(),
        });
    }
    if t.regions.is_empty() {
        // Hand-written traces without memory still get the ISA's table region.
        t.regions.push(MemRegion {
            id: MemId(0),
            kind: MemKind::Lut,
            name: "isa-lut".into(),
            base: Addr(crate::mem::BASE),
            size: LUT_BYTES,
        });
    }
    Ok(t)
}

/// A directive line (`.trace`, `.isa`, `.source`, `.param`, `.mem`, `.code`).
fn directive(t: &mut Trace, st: &mut TextState, key: &str, rest: &str) -> Result<(), String> {
    let err = |msg: String| msg;
    match key {
        "trace" => {
            if rest != "1" {
                return Err(err(format!(
                    "unsupported text trace version '{rest}' (this rtsim reads 1)"
                )));
            }
            st.have_version = true;
        }
        "isa" => {
            if !t.ops.is_empty() {
                return Err(err(".isa after the first op".into()));
            }
            t.flavour = FlavourId::from_name(rest).ok_or_else(|| {
                err(format!(
                    "unknown ISA flavour '{rest}' (lrb16, avx512, avx2, sse4, wide32)"
                ))
            })?;
            st.full = LaneMask::full(t.flavour.lanes());
            st.have_isa = true;
        }
        "source" => t.source = rest.to_string(),
        "param" => {
            let (k, v) = rest
                .split_once('=')
                .ok_or_else(|| err(format!("parameter '{rest}' is not key=value")))?;
            t.params.push((k.trim().to_string(), v.trim().to_string()));
        }
        "mem" => {
            let f: Vec<&str> = rest.split_whitespace().collect();
            if f.len() != 5 {
                return Err(err("expected '.mem ID KIND NAME BASE SIZE'".into()));
            }
            let id = f[0]
                .parse::<u16>()
                .map_err(|_| err(format!("bad region id '{}'", f[0])))?;
            if id as usize != t.regions.len() {
                return Err(err(format!(
                    "region ids must count up from 0: expected {}, found {id}",
                    t.regions.len()
                )));
            }
            let kind = MemKind::from_name(f[1])
                .ok_or_else(|| err(format!("unknown memory kind '{}'", f[1])))?;
            let base =
                parse_u64(f[3]).ok_or_else(|| err(format!("bad base address '{}'", f[3])))?;
            let size = parse_u64(f[4]).ok_or_else(|| err(format!("bad size '{}'", f[4])))?;
            t.regions.push(MemRegion {
                id: MemId(id),
                kind,
                name: f[2].to_string(),
                base: Addr(base),
                size,
            });
        }
        "code" => {
            st.region = Region::from_name(rest)
                .ok_or_else(|| err(format!("unknown code region '{rest}'")))?;
        }
        _ => return Err(err(format!("unknown directive '.{key}'"))),
    }
    Ok(())
}

/// An op line: `[%D =] CLASS [%S ...] [@REGION+OFFSET:BYTES ...] [addr=%A]
/// [mask=M] [w=BYTES] [len=BYTES [lcp] [complex] [fusible]] [site=N]
/// [taken|not-taken]`.
fn op_line(t: &mut Trace, st: &TextState, line: &str) -> Result<Op, String> {
    let err = |msg: String| msg;
    let mut toks = line.split_whitespace().peekable();
    let mut op;
    let first = toks.next().expect("non-empty line");
    let class_tok = if let Some(d) = first.strip_prefix('%') {
        let id: u32 = d
            .parse()
            .ok()
            .filter(|&v| v > 0)
            .ok_or_else(|| err(format!("bad value id '{first}' (ids are %1, %2, ...)")))?;
        if toks.next() != Some("=") {
            return Err(err(format!("expected '=' after {first}")));
        }
        let c = toks.next().ok_or_else(|| err("missing op class".into()))?;
        op = Op::new(class_of(c).map_err(&err)?, st.region);
        op.dst = ValId(id);
        c
    } else {
        op = Op::new(class_of(first).map_err(&err)?, st.region);
        first
    };
    op.mask = default_mask(op.class, st.full);
    let mut has_mem = false;
    let mut has_site = false;
    for tok in toks {
        if let Some(d) = tok.strip_prefix('%') {
            let id: u32 = d
                .parse()
                .ok()
                .filter(|&v| v > 0)
                .ok_or_else(|| err(format!("bad source '{tok}'")))?;
            if op.nsrc as usize == crate::trace::MAX_SRCS {
                return Err(err(format!("more than {} sources", crate::trace::MAX_SRCS)));
            }
            op.push_src(ValId(id));
        } else if let Some(m) = tok.strip_prefix('@') {
            if !op.class.is_mem() {
                return Err(err(format!("'{class_tok}' does not access memory")));
            }
            parse_mem(t, &mut op, m).map_err(&err)?;
            has_mem = true;
        } else if let Some(v) = tok.strip_prefix("mask=") {
            let m = parse_u64(v).ok_or_else(|| err(format!("bad mask '{v}'")))?;
            if m & !u64::from(st.full.0) != 0 {
                return Err(err(format!(
                    "mask {m:#x} has lanes beyond {}",
                    t.flavour.lanes()
                )));
            }
            op.mask = LaneMask(m as u32);
        } else if let Some(v) = tok.strip_prefix("w=") {
            if op.class.is_mem() {
                return Err(err(format!(
                    "w= on '{class_tok}': a memory op's width is its access size"
                )));
            }
            op.bytes = v
                .parse()
                .ok()
                .filter(|w: &u32| w.is_power_of_two() && *w <= 4 * t.flavour.lanes() as u32)
                .ok_or_else(|| {
                    err(format!(
                        "bad operand width 'w={v}' (bytes: a power of two up to {})",
                        4 * t.flavour.lanes()
                    ))
                })?;
        } else if let Some(v) = tok.strip_prefix("addr=%") {
            if !op.class.is_store() || op.class.is_per_lane_mem() || op.has_addr_src() {
                return Err(err(format!(
                    "addr= on '{class_tok}': one address source, on a store (not a scatter)"
                )));
            }
            if op.nsrc as usize == crate::trace::MAX_SRCS {
                return Err(err(format!("more than {} sources", crate::trace::MAX_SRCS)));
            }
            let id: u32 = v
                .parse()
                .ok()
                .filter(|&v| v > 0)
                .ok_or_else(|| err(format!("bad address source '{tok}'")))?;
            op.srcs.copy_within(0..op.nsrc as usize, 1);
            op.srcs[0] = ValId(id);
            op.nsrc += 1;
            op.flags |= FLAG_ADDR;
        } else if let Some(v) = tok.strip_prefix("site=") {
            if op.class != OpClass::Branch && !op.is_sited_load() {
                return Err(err(
                    "site= on an op that is neither a branch nor a load".into()
                ));
            }
            op.aux = v
                .parse()
                .map_err(|_| err(format!("bad branch site '{v}'")))?;
            has_site = true;
        } else if let Some(v) = tok.strip_prefix("len=") {
            op.ilen = v
                .parse()
                .ok()
                .filter(|l| (1..=crate::trace::MAX_ILEN).contains(l))
                .ok_or_else(|| {
                    err(format!(
                        "bad instruction length 'len={v}' (bytes: 1 to {})",
                        crate::trace::MAX_ILEN
                    ))
                })?;
        } else if tok == "lcp" {
            op.flags |= crate::trace::FLAG_LCP;
        } else if tok == "complex" {
            op.flags |= crate::trace::FLAG_COMPLEX;
        } else if tok == "fusible" {
            op.flags |= crate::trace::FLAG_FUSIBLE;
        } else if tok == "taken" || tok == "not-taken" {
            if op.class != OpClass::Branch {
                return Err(err(format!("'{tok}' on an op that is not a branch")));
            }
            if tok == "taken" {
                op.flags |= FLAG_TAKEN;
            }
        } else {
            return Err(err(format!("unexpected '{tok}'")));
        }
    }
    if op.class.is_mem() && !has_mem {
        return Err(err(format!(
            "'{class_tok}' needs a memory operand @REGION+OFFSET:BYTES"
        )));
    }
    if op.class == OpClass::Branch && !has_site {
        return Err(err("branch needs site=N".into()));
    }
    let decode_facts =
        crate::trace::FLAG_LCP | crate::trace::FLAG_COMPLEX | crate::trace::FLAG_FUSIBLE;
    if op.flags & decode_facts != 0 && op.ilen == 0 {
        return Err(err(
            "lcp, complex and fusible need len=N (they are legacy-decode facts)".into(),
        ));
    }
    if op.class.is_per_lane_mem() {
        let n = t.lane_addrs.len() - op.aux as usize;
        if n != op.mask.count() as usize {
            return Err(err(format!(
                "{n} lane addresses for {} active lanes (mask= must match)",
                op.mask.count()
            )));
        }
    }
    Ok(op)
}

fn class_of(s: &str) -> Result<OpClass, String> {
    OpClass::from_name(s).ok_or_else(|| format!("unknown op class '{s}'"))
}

fn parse_mem(t: &mut Trace, op: &mut Op, m: &str) -> Result<(), String> {
    let (loc, bytes) = m
        .rsplit_once(':')
        .ok_or_else(|| format!("memory operand '@{m}' lacks ':BYTES'"))?;
    op.bytes = bytes
        .parse()
        .map_err(|_| format!("bad access size '{bytes}'"))?;
    let (name, rest, per_lane) = if let Some(i) = loc.find('[') {
        let inner = loc[i + 1..]
            .strip_suffix(']')
            .ok_or_else(|| format!("unclosed '[' in '@{m}'"))?;
        (&loc[..i], inner, true)
    } else {
        let (n, o) = loc.split_once('+').unwrap_or((loc, "0"));
        (n, o, false)
    };
    let region = t
        .regions
        .iter()
        .find(|r| r.name == name)
        .or_else(|| name.parse::<usize>().ok().and_then(|i| t.regions.get(i)))
        .ok_or_else(|| format!("unknown memory region '{name}' (declare it with .mem)"))?
        .clone();
    op.mem = region.id;
    if per_lane != op.class.is_per_lane_mem() {
        return Err(if per_lane {
            format!("'{}' takes one address, not a lane list", op.class)
        } else {
            format!(
                "'{}' takes a lane list @REGION[off,off,...]:BYTES",
                op.class
            )
        });
    }
    let check = |off: u64| -> Result<Addr, String> {
        if off + u64::from(op.bytes) > region.size {
            Err(format!(
                "offset {off:#x}+{} lies outside region '{}' of {} bytes",
                op.bytes, region.name, region.size
            ))
        } else {
            Ok(Addr(region.base.0 + off))
        }
    };
    if per_lane {
        op.aux = t.lane_addrs.len() as u32;
        for (i, o) in rest.split(',').filter(|s| !s.is_empty()).enumerate() {
            let off = parse_u64(o.trim()).ok_or_else(|| format!("bad lane offset '{o}'"))?;
            let a = check(off)?;
            if i == 0 {
                op.addr = a;
            }
            t.lane_addrs.push(a);
        }
    } else {
        let off = parse_u64(rest).ok_or_else(|| format!("bad offset '{rest}'"))?;
        op.addr = check(off)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hand_written_loop_parses() {
        let src = "\
.trace 1
.isa avx2
.source hand
.mem 0 lut isa-lut 0x10000000 8192
.mem 1 rays rays 0x10003000 4096
.code core-loop
%1 = vload @rays+0x0:32
%2 = vfma %1 %1 %1   # a comment
vstore %2 @rays+0x20:32
%3 = cmp %2
branch %3 site=1 taken
%4 = vgather %3 @rays[0x4,0x8]:4 mask=0x3
";
        let t = parse(src).unwrap();
        assert_eq!(t.ops.len(), 6);
        assert_eq!(t.ops[1].class, OpClass::VFma);
        assert_eq!(t.ops[1].region, Region::CoreLoop);
        assert!(t.ops[4].taken());
        assert_eq!(t.lanes_of(&t.ops[5]).len(), 2);
        t.validate().unwrap();
        let again = parse(&write(&t)).unwrap();
        assert_eq!(again, t);
    }

    #[test]
    fn errors_name_the_line() {
        let e = parse(".trace 1\n.isa avx2\n%1 = vfmaa %2\n").unwrap_err();
        assert_eq!(e.line, 3);
        assert!(e.msg.contains("unknown op class"), "{e}");
        let e = parse(".trace 1\n.isa avx2\nvload @nowhere+0:32\n").unwrap_err();
        assert!(e.msg.contains("unknown memory region"), "{e}");
        let e = parse(".trace 2\n").unwrap_err();
        assert!(e.msg.contains("version"), "{e}");
        let e = parse(
            ".trace 1\n.isa avx2\n.mem 0 other d 0x1000 64\n%1 = vgather @d[0x0]:4 mask=0x3\n",
        )
        .unwrap_err();
        assert!(e.msg.contains("lane addresses"), "{e}");
    }
}
