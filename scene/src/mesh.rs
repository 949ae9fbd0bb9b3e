//! Triangle meshes and their loaders: OBJ (through tobj) and PLY (ASCII and
//! binary, either endianness), each optionally gzipped; polygons are
//! triangulated as fans. Bad input — NaN or infinite vertices, indices out of
//! range, a truncated or malformed file — is an error naming the file and the
//! line (text) or byte offset (binary), never a panic.

use flate2::read::GzDecoder;
use std::fmt;
use std::io::Read;
use std::path::Path;

/// An indexed triangle mesh.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions.
    pub positions: Vec<[f32; 3]>,
    /// Triangles as vertex indices.
    pub tris: Vec<[u32; 3]>,
}

/// A loading error: file, where, what.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MeshError {
    /// File.
    pub file: String,
    /// `line N` or `byte N`, if known.
    pub at: Option<String>,
    /// What is wrong.
    pub msg: String,
}

impl fmt::Display for MeshError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.at {
            Some(a) => write!(f, "{}: {a}: {}", self.file, self.msg),
            None => write!(f, "{}: {}", self.file, self.msg),
        }
    }
}

impl std::error::Error for MeshError {}

impl Mesh {
    /// Number of triangles.
    #[must_use]
    pub fn len(&self) -> usize {
        self.tris.len()
    }
    /// Whether there are no triangles.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.tris.is_empty()
    }
    /// The three corners of triangle `i`.
    #[must_use]
    pub fn tri(&self, i: usize) -> [[f32; 3]; 3] {
        let t = self.tris[i];
        [
            self.positions[t[0] as usize],
            self.positions[t[1] as usize],
            self.positions[t[2] as usize],
        ]
    }
    /// Bounds (min, max) of all vertices referenced by triangles.
    #[must_use]
    pub fn bounds(&self) -> ([f32; 3], [f32; 3]) {
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for t in &self.tris {
            for &v in t {
                let p = self.positions[v as usize];
                for a in 0..3 {
                    lo[a] = lo[a].min(p[a]);
                    hi[a] = hi[a].max(p[a]);
                }
            }
        }
        (lo, hi)
    }
    /// Append another mesh, transformed by `f`.
    pub fn append(&mut self, other: &Mesh, f: impl Fn([f32; 3]) -> [f32; 3]) {
        let base = self.positions.len() as u32;
        self.positions.extend(other.positions.iter().map(|&p| f(p)));
        self.tris
            .extend(other.tris.iter().map(|t| t.map(|v| v + base)));
    }
    /// Check every vertex is finite and every index in range.
    pub fn check(&self, file: &str) -> Result<(), MeshError> {
        let err = |msg: String| MeshError {
            file: file.into(),
            at: None,
            msg,
        };
        if let Some((i, p)) = self
            .positions
            .iter()
            .enumerate()
            .find(|(_, p)| p.iter().any(|c| !c.is_finite()))
        {
            return Err(err(format!("vertex {i} is not finite: {p:?}")));
        }
        let n = self.positions.len() as u32;
        if let Some((i, t)) = self
            .tris
            .iter()
            .enumerate()
            .find(|(_, t)| t.iter().any(|&v| v >= n))
        {
            return Err(err(format!("triangle {i} indexes vertex {t:?} of {n}")));
        }
        Ok(())
    }
}

/// Read a file, gunzipping it if it ends in `.gz`.
pub(crate) fn read_all(path: &Path) -> Result<Vec<u8>, MeshError> {
    let file = path.display().to_string();
    let raw = std::fs::read(path).map_err(|e| MeshError {
        file: file.clone(),
        at: None,
        msg: e.to_string(),
    })?;
    if path.extension().is_some_and(|e| e == "gz") {
        let mut out = Vec::new();
        GzDecoder::new(&raw[..])
            .read_to_end(&mut out)
            .map_err(|e| MeshError {
                file,
                at: None,
                msg: format!("gzip: {e} (truncated or corrupt?)"),
            })?;
        Ok(out)
    } else {
        Ok(raw)
    }
}

/// Load an OBJ or PLY mesh (optionally `.gz`), by extension.
pub fn load(path: &Path) -> Result<Mesh, MeshError> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_default();
    let stem = name.strip_suffix(".gz").unwrap_or(&name);
    let file = path.display().to_string();
    let bytes = read_all(path)?;
    let mesh = if stem.ends_with(".obj") {
        parse_obj(&bytes, &file)?
    } else if stem.ends_with(".ply") {
        parse_ply(&bytes, &file)?
    } else {
        return Err(MeshError {
            file,
            at: None,
            msg: "not a mesh: expected .obj or .ply (optionally .gz)".into(),
        });
    };
    mesh.check(&path.display().to_string())?;
    Ok(mesh)
}

/// Parse OBJ text (tobj does the triangulation). Before tobj, a pass over the
/// lines finds malformed vertices and faces so the error can name the line.
pub fn parse_obj(bytes: &[u8], file: &str) -> Result<Mesh, MeshError> {
    let text = std::str::from_utf8(bytes).map_err(|e| MeshError {
        file: file.into(),
        at: Some(format!("byte {}", e.valid_up_to())),
        msg: "not UTF-8 text".into(),
    })?;
    let mut nv = 0usize;
    for (i, line) in text.lines().enumerate() {
        let err = |msg: String| MeshError {
            file: file.into(),
            at: Some(format!("line {}", i + 1)),
            msg,
        };
        let mut f = line.split_whitespace();
        match f.next() {
            Some("v") => {
                let c: Vec<&str> = f.collect();
                if c.len() < 3 {
                    return Err(err(format!("vertex with {} coordinates", c.len())));
                }
                for x in &c[..3] {
                    let v: f32 = x
                        .parse()
                        .map_err(|_| err(format!("vertex coordinate '{x}' is not a number")))?;
                    if !v.is_finite() {
                        return Err(err(format!("vertex coordinate '{x}' is not finite")));
                    }
                }
                nv += 1;
            }
            Some("f") => {
                let idx: Vec<&str> = f.collect();
                if idx.len() < 3 {
                    return Err(err(format!("face with {} vertices", idx.len())));
                }
                for x in idx {
                    let v: i64 = x
                        .split('/')
                        .next()
                        .unwrap_or("")
                        .parse()
                        .map_err(|_| err(format!("face index '{x}' is not a number")))?;
                    let ok = if v > 0 {
                        v as usize <= nv
                    } else {
                        v < 0 && (-v) as usize <= nv
                    };
                    if !ok {
                        return Err(err(format!(
                            "face index {v} out of range (vertices so far: {nv})"
                        )));
                    }
                }
            }
            _ => {}
        }
    }
    let opts = tobj::LoadOptions {
        triangulate: true,
        single_index: false,
        ..Default::default()
    };
    let mut rd = std::io::BufReader::new(bytes);
    let (models, _) = tobj::load_obj_buf(&mut rd, &opts, |_| Err(tobj::LoadError::GenericFailure))
        .map_err(|e| MeshError {
            file: file.into(),
            at: None,
            msg: format!("OBJ: {e}"),
        })?;
    let mut m = Mesh::default();
    for model in models {
        let mm = &model.mesh;
        let base = m.positions.len() as u32;
        m.positions
            .extend(mm.positions.chunks_exact(3).map(|c| [c[0], c[1], c[2]]));
        m.tris.extend(
            mm.indices
                .chunks_exact(3)
                .map(|c| [c[0] + base, c[1] + base, c[2] + base]),
        );
    }
    Ok(m)
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum PlyFormat {
    Ascii,
    Le,
    Be,
}

/// Bytes of a PLY scalar type, and whether it is a float.
fn ply_type(t: &str) -> Option<(usize, bool, bool)> {
    // (size, float, signed)
    Some(match t {
        "char" | "int8" => (1, false, true),
        "uchar" | "uint8" => (1, false, false),
        "short" | "int16" => (2, false, true),
        "ushort" | "uint16" => (2, false, false),
        "int" | "int32" => (4, false, true),
        "uint" | "uint32" => (4, false, false),
        "float" | "float32" => (4, true, true),
        "double" | "float64" => (8, true, true),
        _ => return None,
    })
}

struct Prop {
    name: String,
    ty: (usize, bool, bool),
    list: Option<(usize, bool, bool)>,
}

struct Element {
    name: String,
    count: usize,
    props: Vec<Prop>,
}

/// Errors of one PLY file, at a line or a byte.
struct PlyErr<'a>(&'a str);

impl PlyErr<'_> {
    fn line(&self, l: usize, msg: String) -> MeshError {
        MeshError {
            file: self.0.into(),
            at: Some(format!("line {l}")),
            msg,
        }
    }
    fn byte(&self, b: usize, msg: String) -> MeshError {
        MeshError {
            file: self.0.into(),
            at: Some(format!("byte {b}")),
            msg,
        }
    }
    fn at(&self, at: &str, msg: String) -> MeshError {
        MeshError {
            file: self.0.into(),
            at: Some(at.into()),
            msg,
        }
    }
}

/// A PLY header: format, elements, the body's first byte and the header's
/// last line number.
struct PlyHeader {
    format: PlyFormat,
    elements: Vec<Element>,
    body: usize,
    lines: usize,
}

/// Parse a PLY file (ASCII or binary, either endianness); vertices `x y z`,
/// faces `vertex_indices` (or `vertex_index`) lists, fan-triangulated.
pub fn parse_ply(bytes: &[u8], file: &str) -> Result<Mesh, MeshError> {
    let e = PlyErr(file);
    let h = ply_header(bytes, &e)?;
    let (format, line_no) = (h.format, h.lines);
    let mut pos = h.body;
    let mut m = Mesh::default();
    let mut ascii_lines = if format == PlyFormat::Ascii {
        Some(
            std::str::from_utf8(&bytes[pos..])
                .map_err(|_| e.byte(pos, "ASCII body is not text".into()))?
                .lines()
                .enumerate(),
        )
    } else {
        None
    };
    for el in &h.elements {
        let xyz: Vec<Option<usize>> = ["x", "y", "z"]
            .iter()
            .map(|n| el.props.iter().position(|p| p.name == *n))
            .collect();
        if el.name == "vertex" && xyz.iter().any(Option::is_none) {
            return Err(e.line(line_no, "vertex element lacks x, y or z".into()));
        }
        for k in 0..el.count {
            let (vals, list, where_) = if let Some(lines) = ascii_lines.as_mut() {
                ply_ascii_record(lines, el, k, line_no, &e)?
            } else {
                let at = format!("byte {pos}");
                let (vals, list) = ply_binary_record(bytes, &mut pos, el, format, &e)?;
                (vals, list, at)
            };
            add_ply_record(&mut m, el, k, (&vals, &list, &xyz), |msg| {
                e.at(&where_, msg)
            })?;
        }
    }
    Ok(m)
}

/// The header: `ply` magic, format, elements and their properties.
fn ply_header(bytes: &[u8], e: &PlyErr<'_>) -> Result<PlyHeader, MeshError> {
    let (e_line, e_byte) = (|l, msg| e.line(l, msg), |b, msg| e.byte(b, msg));
    let mut pos = 0usize;
    let mut line_no = 0usize;
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        let end = bytes[pos..]
            .iter()
            .position(|&b| b == b'\n')
            .ok_or_else(|| e_byte(pos, "header does not end (no end_header)".into()))?;
        let line = std::str::from_utf8(&bytes[pos..pos + end])
            .map_err(|_| e_byte(pos, "header is not text".into()))?
            .trim();
        pos += end + 1;
        line_no += 1;
        if line_no == 1 {
            if line != "ply" {
                return Err(e_line(1, "not a PLY file (no 'ply' magic)".into()));
            }
            continue;
        }
        let f: Vec<&str> = line.split_whitespace().collect();
        match f.first().copied() {
            Some("format") => {
                format = Some(match f.get(1).copied() {
                    Some("ascii") => PlyFormat::Ascii,
                    Some("binary_little_endian") => PlyFormat::Le,
                    Some("binary_big_endian") => PlyFormat::Be,
                    other => return Err(e_line(line_no, format!("unknown PLY format {other:?}"))),
                });
            }
            Some("element") => {
                let count = f
                    .get(2)
                    .and_then(|c| c.parse().ok())
                    .ok_or_else(|| e_line(line_no, "element without a count".into()))?;
                elements.push(Element {
                    name: f.get(1).unwrap_or(&"").to_string(),
                    count,
                    props: Vec::new(),
                });
            }
            Some("property") => {
                let el = elements
                    .last_mut()
                    .ok_or_else(|| e_line(line_no, "property before any element".into()))?;
                let bad = |t: &str| e_line(line_no, format!("unknown property type '{t}'"));
                if f.get(1) == Some(&"list") {
                    let ct = f.get(2).copied().unwrap_or("");
                    let it = f.get(3).copied().unwrap_or("");
                    el.props.push(Prop {
                        name: f.get(4).unwrap_or(&"").to_string(),
                        ty: ply_type(it).ok_or_else(|| bad(it))?,
                        list: Some(ply_type(ct).ok_or_else(|| bad(ct))?),
                    });
                } else {
                    let t = f.get(1).copied().unwrap_or("");
                    el.props.push(Prop {
                        name: f.get(2).unwrap_or(&"").to_string(),
                        ty: ply_type(t).ok_or_else(|| bad(t))?,
                        list: None,
                    });
                }
            }
            Some("end_header") => break,
            _ => {}
        }
    }
    let format = format.ok_or_else(|| e_line(line_no, "no format line".into()))?;
    Ok(PlyHeader {
        format,
        elements,
        body: pos,
        lines: line_no,
    })
}

/// One value of type `ty` (bytes, float, signed) at `pos` of a binary body.
fn ply_read_bin(
    bytes: &[u8],
    pos: &mut usize,
    ty: (usize, bool, bool),
    format: PlyFormat,
    e: &PlyErr<'_>,
) -> Result<f64, MeshError> {
    let (n, float, signed) = ty;
    let b = bytes
        .get(*pos..*pos + n)
        .ok_or_else(|| e.byte(*pos, "file ends inside the data (truncated?)".into()))?;
    let mut a = [0u8; 8];
    a[..n].copy_from_slice(b);
    if format == PlyFormat::Be {
        a[..n].reverse();
    }
    *pos += n;
    Ok(match (n, float, signed) {
        (4, true, _) => f64::from(f32::from_le_bytes([a[0], a[1], a[2], a[3]])),
        (8, true, _) => f64::from_le_bytes(a),
        (1, false, true) => f64::from(a[0] as i8),
        (1, false, false) => f64::from(a[0]),
        (2, false, true) => f64::from(i16::from_le_bytes([a[0], a[1]])),
        (2, false, false) => f64::from(u16::from_le_bytes([a[0], a[1]])),
        (4, false, true) => f64::from(i32::from_le_bytes([a[0], a[1], a[2], a[3]])),
        _ => f64::from(u32::from_le_bytes([a[0], a[1], a[2], a[3]])),
    })
}

/// Record `k` of element `el` from the ASCII body: its property values (0
/// for lists), its vertex index list, and where it is.
fn ply_ascii_record<'t>(
    lines: &mut impl Iterator<Item = (usize, &'t str)>,
    el: &Element,
    k: usize,
    line_no: usize,
    e: &PlyErr<'_>,
) -> Result<(Vec<f64>, Vec<f64>, String), MeshError> {
    let e_line = |l, msg| e.line(l, msg);
    let mut vals: Vec<f64> = Vec::with_capacity(el.props.len());
    let mut list: Vec<f64> = Vec::new();
    let (ln, text) = lines.find(|(_, l)| !l.trim().is_empty()).ok_or_else(|| {
        e_line(
            line_no,
            format!(
                "file ends in element '{}' {k} of {} (truncated?)",
                el.name, el.count
            ),
        )
    })?;
    let body_line = line_no + ln + 1;
    let mut toks = text.split_whitespace();
    for p in &el.props {
        let mut next = || -> Result<f64, MeshError> {
            let t = toks
                .next()
                .ok_or_else(|| e_line(body_line, format!("too few values for '{}'", el.name)))?;
            t.parse::<f64>()
                .map_err(|_| e_line(body_line, format!("'{t}' is not a number")))
        };
        if p.list.is_some() {
            let n = next()? as usize;
            let v: Result<Vec<f64>, _> = (0..n).map(|_| next()).collect();
            let v = v?;
            if p.name.starts_with("vertex_ind") {
                list = v;
            }
            vals.push(0.0);
        } else {
            vals.push(next()?);
        }
    }
    Ok((vals, list, format!("line {body_line}")))
}

/// Record `k` of element `el` from the binary body at `pos`: its property
/// values (0 for lists) and its vertex index list.
fn ply_binary_record(
    bytes: &[u8],
    pos: &mut usize,
    el: &Element,
    format: PlyFormat,
    e: &PlyErr<'_>,
) -> Result<(Vec<f64>, Vec<f64>), MeshError> {
    let mut vals: Vec<f64> = Vec::with_capacity(el.props.len());
    let mut list: Vec<f64> = Vec::new();
    for p in &el.props {
        if let Some(ct) = p.list {
            let n = ply_read_bin(bytes, pos, ct, format, e)? as usize;
            let mut v = Vec::with_capacity(n);
            for _ in 0..n {
                v.push(ply_read_bin(bytes, pos, p.ty, format, e)?);
            }
            if p.name.starts_with("vertex_ind") {
                list = v;
            }
            vals.push(0.0);
        } else {
            vals.push(ply_read_bin(bytes, pos, p.ty, format, e)?);
        }
    }
    Ok((vals, list))
}

/// Add a vertex (finite) or a face (fan-triangulated, indices in range).
fn add_ply_record(
    m: &mut Mesh,
    el: &Element,
    k: usize,
    (vals, list, xyz): (&[f64], &[f64], &[Option<usize>]),
    at: impl Fn(String) -> MeshError,
) -> Result<(), MeshError> {
    let (is_vertex, is_face) = (el.name == "vertex", el.name == "face");
    if is_vertex {
        let p = [
            vals[xyz[0].unwrap()] as f32,
            vals[xyz[1].unwrap()] as f32,
            vals[xyz[2].unwrap()] as f32,
        ];
        if p.iter().any(|c| !c.is_finite()) {
            return Err(at(format!("vertex {k} is not finite: {p:?}")));
        }
        m.positions.push(p);
    } else if is_face {
        if list.len() < 3 {
            return Err(at(format!("face {k} has {} vertices", list.len())));
        }
        let nv = m.positions.len() as f64;
        if let Some(v) = list.iter().find(|&&v| v < 0.0 || v >= nv) {
            return Err(at(format!("face {k} indexes vertex {v} of {nv}")));
        }
        for j in 1..list.len() - 1 {
            m.tris
                .push([list[0] as u32, list[j] as u32, list[j + 1] as u32]);
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    const TRI_PLY: &str = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n";

    #[test]
    fn ascii_ply_quad_is_two_triangles() {
        let m = parse_ply(TRI_PLY.as_bytes(), "t.ply").unwrap();
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.tris, vec![[0, 1, 2], [0, 2, 3]]);
    }

    fn binary(le: bool) -> Vec<u8> {
        let mut b = format!(
            "ply\nformat binary_{}_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n",
            if le { "little" } else { "big" }
        )
        .into_bytes();
        for v in [0f32, 0., 0., 1., 0., 0., 0., 1., 0.] {
            b.extend(if le { v.to_le_bytes() } else { v.to_be_bytes() });
        }
        b.push(3);
        for i in [0i32, 1, 2] {
            b.extend(if le { i.to_le_bytes() } else { i.to_be_bytes() });
        }
        b
    }

    #[test]
    fn binary_ply_both_endiannesses() {
        for le in [true, false] {
            let m = parse_ply(&binary(le), "b.ply").unwrap();
            assert_eq!(m.positions[1], [1.0, 0.0, 0.0]);
            assert_eq!(m.tris, vec![[0, 1, 2]]);
        }
    }

    #[test]
    fn errors_name_line_or_byte() {
        let b = binary(true);
        let e = parse_ply(&b[..b.len() - 3], "t.ply").unwrap_err();
        assert!(
            e.to_string().contains("byte") && e.msg.contains("truncated"),
            "{e}"
        );
        let e = parse_ply(TRI_PLY.replace("1 1 0", "1 nan 0").as_bytes(), "t.ply").unwrap_err();
        assert!(
            e.to_string().contains("line 12") && e.msg.contains("finite"),
            "{e}"
        );
        let e = parse_ply(
            TRI_PLY.replace("4 0 1 2 3", "4 0 1 2 9").as_bytes(),
            "t.ply",
        )
        .unwrap_err();
        assert!(
            e.to_string().contains("line 14") && e.msg.contains("indexes vertex 9"),
            "{e}"
        );
        let e = parse_obj(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "t.obj").unwrap_err();
        assert!(
            e.to_string().contains("t.obj: line 4") && e.msg.contains("out of range"),
            "{e}"
        );
        let e = parse_obj(b"v 0 0 0\nv 1 NaN 0\n", "t.obj").unwrap_err();
        assert!(e.to_string().contains("line 2"), "{e}");
    }

    #[test]
    fn obj_polygons_are_triangulated() {
        let m = parse_obj(b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n", "q.obj").unwrap();
        assert_eq!(m.tris.len(), 2);
    }
}
