//! Binary trace files (`.rtt`), format version 4 (versions 1 to 3 still read). `traces/FORMAT.md` is the
//! specification; this is its implementation.
//!
//! ```text
//! magic "RTSIMTRC" | version u16 LE | header (varints, strings) | ops | FNV-1a-64 of all before it, u64 LE
//! ```
//! Ops are delta-encoded: a produced value's id is implicit when it is the
//! previous one plus one, sources are distances back from it, addresses are
//! deltas from the previous address; a typical op takes 3 to 6 bytes.

use crate::class::OpClass;
use crate::flavour::FlavourId;
use crate::mem::MemRegion;
use crate::trace::{
    Op, Trace, FLAG_ADDR, FLAG_COMPLEX, FLAG_FUSIBLE, FLAG_LCP, FLAG_TAKEN, MAX_ILEN, MAX_SRCS,
};
use crate::types::{Addr, LaneMask, MemId, MemKind, Region, ValId};
use std::fmt;

/// File magic.
pub const MAGIC: &[u8; 8] = b"RTSIMTRC";
/// Format version written and read.
pub const VERSION: u16 = 4;
/// The oldest version still read (version 1 has no operand widths,
/// version 2 no instruction lengths).
pub const OLDEST: u16 = 1;
/// Class byte bit: an extension varint follows the mask (version 4:
/// operand width << 7 | fusible << 6 | complex << 5 | length-changing
/// prefix << 4 | instruction length; version 3: operand width << 5 | lcp
/// << 4 | instruction length; version 2: the operand width alone).
const C_EXT: u8 = 0x80;
/// Extension bit: a length-changing prefix (versions 3 and 4).
const X_LCP: u64 = 0x10;
/// Extension bits: the instruction length (versions 3 and 4).
const X_ILEN: u64 = 0x0F;
/// Extension bit: a complex-decoder instruction (version 4).
const X_COMPLEX: u64 = 0x20;
/// Extension bit: a macro-fusible instruction (version 4).
const X_FUSIBLE: u64 = 0x40;

const F_NSRC: u8 = 0b0000_0111;
const F_DST: u8 = 0b0000_1000;
const F_DST_EXPLICIT: u8 = 0b0001_0000;
const F_MASK: u8 = 0b0010_0000;
const F_REGION: u8 = 0b0100_0000;
const F_TAKEN: u8 = 0b1000_0000;

/// A malformed file: what is wrong and at which byte.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FormatError {
    /// Byte offset where decoding failed.
    pub offset: usize,
    /// What was wrong.
    pub msg: String,
}

impl fmt::Display for FormatError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "byte {}: {}", self.offset, self.msg)
    }
}

impl std::error::Error for FormatError {}

/// FNV-1a, 64-bit.
#[must_use]
pub fn fnv1a64(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

fn put_varint(out: &mut Vec<u8>, mut v: u64) {
    while v >= 0x80 {
        out.push((v as u8) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

fn zigzag(v: i64) -> u64 {
    ((v << 1) ^ (v >> 63)) as u64
}

fn unzigzag(v: u64) -> i64 {
    ((v >> 1) as i64) ^ -((v & 1) as i64)
}

fn put_str(out: &mut Vec<u8>, s: &str) {
    put_varint(out, s.len() as u64);
    out.extend_from_slice(s.as_bytes());
}

/// Encode a trace.
#[must_use]
pub fn encode(t: &Trace) -> Vec<u8> {
    let mut out = Vec::with_capacity(64 + t.ops.len() * 5);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&VERSION.to_le_bytes());
    out.push(t.flavour as u8);
    put_str(&mut out, &t.source);
    put_varint(&mut out, t.params.len() as u64);
    for (k, v) in &t.params {
        put_str(&mut out, k);
        put_str(&mut out, v);
    }
    put_varint(&mut out, t.regions.len() as u64);
    for r in &t.regions {
        out.push(r.kind as u8);
        put_str(&mut out, &r.name);
        put_varint(&mut out, r.base.0);
        put_varint(&mut out, r.size);
    }
    put_varint(&mut out, t.ops.len() as u64);
    put_varint(&mut out, t.lane_addrs.len() as u64);

    let full = LaneMask::full(t.flavour.lanes());
    let mut last_dst = 0u32;
    let mut region = Region::Other;
    let mut prev_addr = 0u64;
    for op in &t.ops {
        let ext = extension(op);
        out.push(op.class as u8 | if ext != 0 { C_EXT } else { 0 });
        let implicit = last_dst + 1;
        let mut flags = op.nsrc & F_NSRC;
        if op.dst.is_some() {
            flags |= F_DST;
            if op.dst.0 != implicit {
                flags |= F_DST_EXPLICIT;
            }
        }
        if op.mask != default_mask(op.class, full) {
            flags |= F_MASK;
        }
        if op.region != region {
            flags |= F_REGION;
        }
        if op.taken() {
            flags |= F_TAKEN;
        }
        out.push(flags);
        if flags & F_REGION != 0 {
            out.push(op.region as u8);
            region = op.region;
        }
        if flags & F_DST_EXPLICIT != 0 {
            put_varint(&mut out, u64::from(op.dst.0));
        }
        let reference = if op.dst.is_some() { op.dst.0 } else { implicit };
        for s in op.sources() {
            put_varint(&mut out, zigzag(i64::from(reference) - i64::from(s.0)));
        }
        if flags & F_MASK != 0 {
            put_varint(&mut out, u64::from(op.mask.0));
        }
        if ext != 0 {
            put_varint(&mut out, ext);
        }
        if op.class.is_mem() {
            put_varint(&mut out, u64::from(op.mem.0));
            put_varint(&mut out, mem_size_word(op));
            if op.class.is_per_lane_mem() {
                for a in t.lanes_of(op) {
                    put_varint(&mut out, zigzag(a.0 as i64 - prev_addr as i64));
                    prev_addr = a.0;
                }
            } else {
                put_varint(&mut out, zigzag(op.addr.0 as i64 - prev_addr as i64));
                prev_addr = op.addr.0;
                if op.is_sited_load() && op.aux != 0 {
                    put_varint(&mut out, u64::from(op.aux));
                }
            }
        }
        if op.class == OpClass::Branch {
            put_varint(&mut out, u64::from(op.aux));
        }
        if op.dst.is_some() {
            last_dst = op.dst.0;
        }
    }
    let sum = fnv1a64(&out);
    out.extend_from_slice(&sum.to_le_bytes());
    out
}

/// The mask an op has unless stated: every lane for vector ops, one for scalar.
#[must_use]
pub fn default_mask(class: OpClass, full: LaneMask) -> LaneMask {
    if class.is_vector() {
        full
    } else {
        LaneMask(1)
    }
}

struct Reader<'a> {
    b: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    fn err<T>(&self, at: usize, msg: impl Into<String>) -> Result<T, FormatError> {
        Err(FormatError {
            offset: at,
            msg: msg.into(),
        })
    }
    fn u8(&mut self, what: &str) -> Result<u8, FormatError> {
        match self.b.get(self.pos) {
            Some(&v) => {
                self.pos += 1;
                Ok(v)
            }
            None => self.err(self.pos, format!("file ends inside {what} (truncated?)")),
        }
    }
    fn varint(&mut self, what: &str) -> Result<u64, FormatError> {
        let start = self.pos;
        let mut v = 0u64;
        for shift in (0..64).step_by(7) {
            let b = self.u8(what)?;
            v |= u64::from(b & 0x7f) << shift;
            if b & 0x80 == 0 {
                return Ok(v);
            }
        }
        self.err(start, format!("{what}: varint longer than 10 bytes"))
    }
    fn u32v(&mut self, what: &str) -> Result<u32, FormatError> {
        let at = self.pos;
        let v = self.varint(what)?;
        u32::try_from(v).or_else(|_| self.err(at, format!("{what} {v} does not fit in 32 bits")))
    }
    fn str(&mut self, what: &str) -> Result<String, FormatError> {
        let at = self.pos;
        let n = self.varint(what)? as usize;
        if n > self.b.len().saturating_sub(self.pos) {
            return self.err(
                at,
                format!("{what}: length {n} runs past the end of the file"),
            );
        }
        let s = &self.b[self.pos..self.pos + n];
        self.pos += n;
        String::from_utf8(s.to_vec()).or_else(|_| self.err(at, format!("{what} is not UTF-8")))
    }
}

/// What decoding an op carries from the ops before it.
struct OpState {
    /// The last destination id (an implicit destination is the next).
    last_dst: u32,
    /// The code region in force.
    region: Region,
    /// The last address (addresses are deltas).
    prev_addr: u64,
    /// The file's format version.
    version: u16,
}

/// A memory op's size word (version 2): the access size shifted left once,
/// bit 0 a store's address-source flag or a load's "a site follows".
fn mem_size_word(op: &Op) -> u64 {
    let bit = if op.class.is_per_lane_mem() {
        false
    } else if op.class.is_store() {
        op.has_addr_src()
    } else {
        op.aux != 0
    };
    u64::from(op.bytes) << 1 | u64::from(bit)
}

/// Decode a trace, checking structure, ids, regions and the checksum (on
/// a second thread, beside the decoding: a 92 MB file's byte-serial hash
/// took a tenth of `rtsim sim --trace`).
pub fn decode(bytes: &[u8]) -> Result<Trace, FormatError> {
    check_preamble(bytes)?;
    let body_end = bytes.len() - 8;
    std::thread::scope(|s| {
        let sum = s.spawn(|| fnv1a64(&bytes[..body_end]));
        let t = decode_body(bytes, body_end)?;
        check_sum(bytes, body_end, sum.join().expect("the checksum thread"))?;
        t.validate().map_err(|m| FormatError {
            offset: 10,
            msg: format!("inconsistent trace: {m}"),
        })?;
        Ok(t)
    })
}

/// [`decode`] but the checksum and the consistency check.
fn decode_body(bytes: &[u8], body_end: usize) -> Result<Trace, FormatError> {
    let mut r = Reader {
        b: &bytes[..body_end],
        pos: 10,
    };
    let at = r.pos;
    let fl = r.u8("header")?;
    let flavour = FlavourId::from_id(fl).ok_or_else(|| FormatError {
        offset: at,
        msg: format!("unknown ISA flavour id {fl}"),
    })?;
    let source = r.str("source")?;
    let np = r.varint("parameter count")?;
    let mut params = Vec::new();
    for _ in 0..np {
        let k = r.str("parameter name")?;
        let v = r.str("parameter value")?;
        params.push((k, v));
    }
    let regions = read_regions(&mut r)?;
    let nops = r.varint("op count")?;
    let nlanes = r.varint("lane address count")?;
    let remaining = body_end - r.pos;
    let mut ops = Vec::with_capacity((nops as usize).min(remaining / 2));
    let mut lane_addrs = Vec::with_capacity((nlanes as usize).min(remaining));
    let mut st = OpState {
        last_dst: 0,
        region: Region::Other,
        prev_addr: 0,
        version: u16::from_le_bytes([bytes[8], bytes[9]]),
    };
    for i in 0..nops {
        let op = read_op(
            &mut r,
            i,
            &mut st,
            (flavour, regions.len()),
            &mut lane_addrs,
        )?;
        ops.push(op);
    }
    check_tail(&r, body_end, (nlanes, lane_addrs.len()))?;
    Ok(Trace {
        flavour,
        source,
        params,
        regions,
        ops,
        lane_addrs,
    })
}

/// Length, magic and version.
fn check_preamble(bytes: &[u8]) -> Result<(), FormatError> {
    if bytes.len() < MAGIC.len() + 2 + 8 {
        return Err(FormatError {
            offset: bytes.len(),
            msg: format!(
                "file is {} bytes, too short for a trace (truncated?)",
                bytes.len()
            ),
        });
    }
    if &bytes[..8] != MAGIC {
        return Err(FormatError {
            offset: 0,
            msg: "not an rtsim binary trace (bad magic)".into(),
        });
    }
    let version = u16::from_le_bytes([bytes[8], bytes[9]]);
    if !(OLDEST..=VERSION).contains(&version) {
        return Err(FormatError {
            offset: 8,
            msg: format!(
                "unsupported trace format version {version} (this rtsim reads {OLDEST} to {VERSION})"
            ),
        });
    }
    Ok(())
}

/// The memory regions table.
fn read_regions(r: &mut Reader<'_>) -> Result<Vec<MemRegion>, FormatError> {
    let nr = r.varint("region count")?;
    if nr > u64::from(u16::MAX) {
        return r.err(r.pos, format!("{nr} memory regions (at most 65535)"));
    }
    let mut regions = Vec::new();
    for i in 0..nr {
        let at = r.pos;
        let k = r.u8("region kind")?;
        let kind = MemKind::from_id(k).ok_or_else(|| FormatError {
            offset: at,
            msg: format!("unknown memory kind {k}"),
        })?;
        let name = r.str("region name")?;
        let base = r.varint("region base")?;
        let size = r.varint("region size")?;
        regions.push(MemRegion {
            id: MemId(i as u16),
            kind,
            name,
            base: Addr(base),
            size,
        });
    }
    Ok(regions)
}

/// Op `i`: class, flags, region change, destination, sources, mask, taken
/// flag, memory access, branch site.
fn read_op(
    r: &mut Reader<'_>,
    i: u64,
    st: &mut OpState,
    (flavour, regions): (FlavourId, usize),
    lane_addrs: &mut Vec<Addr>,
) -> Result<Op, FormatError> {
    let full = LaneMask::full(flavour.lanes());
    let at = r.pos;
    let byte = r.u8("op")?;
    let ext = byte & C_EXT != 0 && st.version >= 2;
    let c = if st.version >= 2 { byte & !C_EXT } else { byte };
    let class = OpClass::from_id(c).ok_or_else(|| FormatError {
        offset: at,
        msg: format!("op {i}: unknown op class {c}"),
    })?;
    let flags = r.u8("op flags")?;
    let mut op = Op::new(class, st.region);
    if flags & F_REGION != 0 {
        let rat = r.pos;
        let rid = r.u8("region")?;
        st.region = Region::from_id(rid).ok_or_else(|| FormatError {
            offset: rat,
            msg: format!("op {i}: unknown code region {rid}"),
        })?;
        op.region = st.region;
    }
    let implicit = st.last_dst + 1;
    if flags & F_DST != 0 {
        op.dst = ValId(if flags & F_DST_EXPLICIT != 0 {
            r.u32v("destination id")?
        } else {
            implicit
        });
        if !op.dst.is_some() {
            return r.err(at, format!("op {i}: destination id 0"));
        }
    } else if flags & F_DST_EXPLICIT != 0 {
        return r.err(at + 1, format!("op {i}: explicit id without a destination"));
    }
    let nsrc = (flags & F_NSRC) as usize;
    if nsrc > MAX_SRCS {
        return r.err(
            at + 1,
            format!("op {i}: {nsrc} sources (at most {MAX_SRCS})"),
        );
    }
    let reference = if op.dst.is_some() { op.dst.0 } else { implicit };
    for _ in 0..nsrc {
        let sat = r.pos;
        let d = unzigzag(r.varint("source")?);
        let s = i64::from(reference) - d;
        if s <= 0 || s > i64::from(u32::MAX) {
            return r.err(sat, format!("op {i}: source id {s} out of range"));
        }
        op.push_src(ValId(s as u32));
    }
    op.mask = if flags & F_MASK != 0 {
        let mat = r.pos;
        let m = r.u32v("mask")?;
        if m & !full.0 != 0 {
            return r.err(
                mat,
                format!("op {i}: mask {m:#x} has lanes beyond {}", flavour.lanes()),
            );
        }
        LaneMask(m)
    } else {
        default_mask(class, full)
    };
    if ext {
        read_extension(r, &mut op, i, flavour, st.version)?;
    }
    if flags & F_TAKEN != 0 {
        if class != OpClass::Branch {
            return r.err(at + 1, format!("op {i}: taken flag on a {class}"));
        }
        op.flags |= FLAG_TAKEN;
    }
    if class.is_mem() {
        read_mem(r, &mut op, i, regions, (lane_addrs, st))?;
    }
    if class == OpClass::Branch {
        op.aux = r.u32v("branch site")?;
    }
    if op.dst.is_some() {
        st.last_dst = op.dst.0;
    }
    Ok(op)
}

/// An op's extension word (version 4): operand width, the legacy-decode
/// facts and instruction length; 0 when it has none of them.
fn extension(op: &Op) -> u64 {
    let width = if op.class.is_mem() {
        0
    } else {
        u64::from(op.bytes)
    };
    let bit = |flag: u8, x: u64| if op.flags & flag != 0 { x } else { 0 };
    width << 7
        | bit(FLAG_FUSIBLE, X_FUSIBLE)
        | bit(FLAG_COMPLEX, X_COMPLEX)
        | bit(FLAG_LCP, X_LCP)
        | u64::from(op.ilen)
}

/// The extension varint after the mask: version 2 the operand width alone,
/// version 3 width, lcp and length, version 4 [`extension`]'s word.
fn read_extension(
    r: &mut Reader<'_>,
    op: &mut Op,
    i: u64,
    flavour: FlavourId,
    version: u16,
) -> Result<(), FormatError> {
    let wat = r.pos;
    let word = r.varint("operand width")?;
    let (w, lcp, ilen) = if version >= 3 {
        let shift = if version >= 4 { 7 } else { 5 };
        (word >> shift, word & X_LCP != 0, (word & X_ILEN) as u8)
    } else {
        (word, false, 0)
    };
    let facts = if version >= 4 {
        word & (X_COMPLEX | X_FUSIBLE)
    } else {
        0
    };
    let class = op.class;
    if w != 0 && (class.is_mem() || !w.is_power_of_two() || w > 4 * flavour.lanes() as u64)
        || version < 3 && w == 0
    {
        return r.err(wat, format!("op {i}: bad operand width {w} on a {class}"));
    }
    if ilen > MAX_ILEN || (lcp || facts != 0) && ilen == 0 || version >= 3 && word == 0 {
        return r.err(
            wat,
            format!("op {i}: bad instruction length {ilen} (lcp {lcp}, decode facts {facts:#x})"),
        );
    }
    if facts & X_COMPLEX != 0 {
        op.flags |= FLAG_COMPLEX;
    }
    if facts & X_FUSIBLE != 0 {
        op.flags |= FLAG_FUSIBLE;
    }
    op.bytes = if class.is_mem() { op.bytes } else { w as u32 };
    op.ilen = ilen;
    if lcp {
        op.flags |= FLAG_LCP;
    }
    Ok(())
}

/// A memory op's region, size and address (per lane for gathers and
/// scatters), addresses as deltas from the previous one.
fn read_mem(
    r: &mut Reader<'_>,
    op: &mut Op,
    i: u64,
    regions: usize,
    (lane_addrs, st): (&mut Vec<Addr>, &mut OpState),
) -> Result<(), FormatError> {
    let prev_addr = &mut st.prev_addr;
    let mat = r.pos;
    let m = r.varint("memory region")?;
    if m >= regions as u64 {
        return r.err(mat, format!("op {i}: memory region {m} does not exist"));
    }
    op.mem = MemId(m as u16);
    let sat = r.pos;
    let word = r.varint("access size")?;
    let (bytes, bit) = if st.version >= 2 {
        (word >> 1, word & 1 != 0)
    } else {
        (word, false)
    };
    op.bytes =
        u32::try_from(bytes).or_else(|_| r.err(sat, format!("op {i}: access size {bytes}")))?;
    if bit && op.class.is_per_lane_mem() {
        return r.err(sat, format!("op {i}: a flag on a {}", op.class));
    }
    if bit && op.class.is_store() {
        if op.nsrc == 0 {
            return r.err(
                sat,
                format!("op {i}: an address source on a store with none"),
            );
        }
        op.flags |= FLAG_ADDR;
    }
    if op.class.is_per_lane_mem() {
        op.aux = lane_addrs.len() as u32;
        for _ in 0..op.mask.count() {
            let d = unzigzag(r.varint("lane address")?);
            *prev_addr = (*prev_addr as i64).wrapping_add(d) as u64;
            lane_addrs.push(Addr(*prev_addr));
        }
        op.addr = lane_addrs.get(op.aux as usize).copied().unwrap_or(Addr(0));
    } else {
        let d = unzigzag(r.varint("address")?);
        *prev_addr = (*prev_addr as i64).wrapping_add(d) as u64;
        op.addr = Addr(*prev_addr);
        if bit && op.class.is_load() {
            let at = r.pos;
            op.aux = r.u32v("load site")?;
            if op.aux == 0 {
                return r.err(at, format!("op {i}: load site 0 written"));
            }
        }
    }
    Ok(())
}

/// Nothing after the last op, and the lane address count.
fn check_tail(
    r: &Reader<'_>,
    body_end: usize,
    (nlanes, got): (u64, usize),
) -> Result<(), FormatError> {
    if r.pos != body_end {
        return r.err(
            r.pos,
            format!("{} unexpected bytes after the last op", body_end - r.pos),
        );
    }
    if got as u64 != nlanes {
        return r.err(
            body_end,
            format!("header says {nlanes} lane addresses, ops hold {got}"),
        );
    }
    Ok(())
}

/// The stored checksum against `computed`, the body's.
fn check_sum(bytes: &[u8], body_end: usize, computed: u64) -> Result<(), FormatError> {
    let stored = u64::from_le_bytes(bytes[body_end..].try_into().expect("8 bytes"));
    if stored != computed {
        return Err(FormatError {
            offset: body_end,
            msg: format!(
                "checksum mismatch (stored {stored:#018x}, computed {computed:#018x}): the file is corrupt"
            ),
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn varints_and_zigzag() {
        for v in [0u64, 1, 127, 128, 300, u64::MAX] {
            let mut b = Vec::new();
            put_varint(&mut b, v);
            let mut r = Reader { b: &b, pos: 0 };
            assert_eq!(r.varint("x").unwrap(), v);
        }
        for v in [0i64, -1, 1, i64::MIN, i64::MAX] {
            assert_eq!(unzigzag(zigzag(v)), v);
        }
    }

    #[test]
    fn fnv_known_value() {
        assert_eq!(fnv1a64(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a64(b"a"), 0xaf63_dc4c_8601_ec8c);
    }
}
