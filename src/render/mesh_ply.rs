//! A small PLY reader (ASCII and both binary byte orders): `vertex` with
//! `x y z` and optionally `nx ny nz`, `face` with a `vertex_indices` (or
//! `vertex_index`) list; other elements and properties are skipped.
//! Polygons become fans. Written here rather than taken from a crate: the
//! PLY crates on crates.io are unmaintained, and this is the subset meshes
//! use. Every count the header claims is checked against the bytes left
//! before anything is allocated for it.

use glam::DVec3;

use super::mesh::RawMesh;

#[derive(Debug, Clone, Copy, PartialEq)]
enum Format {
    Ascii,
    Little,
    Big,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(s: &str) -> Option<Scalar> {
        Some(match s {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }
}

#[derive(Debug, Clone)]
struct Property {
    name: String,
    /// `Some(count type)` for a list.
    list: Option<Scalar>,
    kind: Scalar,
}

#[derive(Debug, Clone)]
struct Element {
    name: String,
    count: usize,
    props: Vec<Property>,
}

/// Reads values one after another from the body.
struct Body<'a> {
    format: Format,
    bytes: &'a [u8],
    pos: usize,
    /// ASCII: the tokens of the current line, and its number.
    line: std::vec::IntoIter<&'a str>,
    line_no: usize,
    lines: std::iter::Peekable<std::str::Lines<'a>>,
}

impl<'a> Body<'a> {
    fn value(&mut self, kind: Scalar, what: &dyn Fn() -> String) -> Result<f64, String> {
        match self.format {
            Format::Ascii => {
                let tok = self
                    .line
                    .next()
                    .ok_or_else(|| format!("line {}: {}: too few values", self.line_no, what()))?;
                tok.parse::<f64>().map_err(|_| {
                    format!(
                        "line {}: {}: {:?} is not a number",
                        self.line_no,
                        what(),
                        super::error::cut(tok)
                    )
                })
            }
            Format::Little | Format::Big => {
                let n = kind.size();
                let Some(b) = self.bytes.get(self.pos..self.pos + n) else {
                    return Err(format!("{}: the file ends early", what()));
                };
                self.pos += n;
                let le = self.format == Format::Little;
                let mut a = [0u8; 8];
                a[..n].copy_from_slice(b);
                if !le {
                    a[..n].reverse();
                }
                Ok(match kind {
                    Scalar::I8 => a[0] as i8 as f64,
                    Scalar::U8 => a[0] as f64,
                    Scalar::I16 => i16::from_le_bytes([a[0], a[1]]) as f64,
                    Scalar::U16 => u16::from_le_bytes([a[0], a[1]]) as f64,
                    Scalar::I32 => i32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
                    Scalar::U32 => u32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
                    Scalar::F32 => f32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
                    Scalar::F64 => f64::from_le_bytes(a),
                })
            }
        }
    }

    /// ASCII: moves to the next non-empty line (one element each).
    fn next_element(&mut self, what: &dyn Fn() -> String) -> Result<(), String> {
        if self.format != Format::Ascii {
            return Ok(());
        }
        loop {
            let Some(l) = self.lines.next() else {
                return Err(format!("{}: the file ends early", what()));
            };
            self.line_no += 1;
            let toks: Vec<&str> = l.split_whitespace().collect();
            if !toks.is_empty() {
                self.line = toks.into_iter();
                return Ok(());
            }
        }
    }

    fn end_element(&mut self, what: &dyn Fn() -> String) -> Result<(), String> {
        if self.format == Format::Ascii && self.line.next().is_some() {
            return Err(format!(
                "line {}: {}: too many values",
                self.line_no,
                what()
            ));
        }
        Ok(())
    }

    fn remaining(&self) -> usize {
        self.bytes.len().saturating_sub(self.pos)
    }
}

pub fn read_ply(bytes: &[u8]) -> Result<RawMesh, String> {
    // The header is ASCII up to "end_header\n".
    let marker = b"end_header";
    let end = bytes
        .windows(marker.len())
        .take(1 << 20)
        .position(|w| w == marker)
        .ok_or("not a PLY file: no end_header in its first megabyte")?;
    let mut body_start = end + marker.len();
    if bytes.get(body_start) == Some(&b'\r') {
        body_start += 1;
    }
    if bytes.get(body_start) == Some(&b'\n') {
        body_start += 1;
    }
    let header = std::str::from_utf8(&bytes[..end]).map_err(|_| "the header is not text")?;
    let mut lines = header.lines().enumerate();
    match lines.next() {
        Some((_, l)) if l.trim() == "ply" => {}
        _ => return Err("not a PLY file: it does not start with \"ply\"".into()),
    }
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut header_lines = 1;
    for (n, line) in lines {
        header_lines = n + 1;
        let w: Vec<&str> = line.split_whitespace().collect();
        let bad = || {
            format!(
                "line {}: malformed header line {:?}",
                n + 1,
                super::error::cut(line)
            )
        };
        match w.first().copied() {
            None | Some("comment") | Some("obj_info") => {}
            Some("format") => {
                format = Some(match w.get(1).copied() {
                    Some("ascii") => Format::Ascii,
                    Some("binary_little_endian") => Format::Little,
                    Some("binary_big_endian") => Format::Big,
                    _ => return Err(bad()),
                })
            }
            Some("element") => {
                let (Some(name), Some(count)) = (w.get(1), w.get(2).and_then(|c| c.parse().ok()))
                else {
                    return Err(bad());
                };
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    props: Vec::new(),
                });
            }
            Some("property") => {
                let el = elements.last_mut().ok_or_else(bad)?;
                let p = if w.get(1) == Some(&"list") {
                    let (Some(c), Some(k), Some(name)) = (
                        w.get(2).and_then(|s| Scalar::parse(s)),
                        w.get(3).and_then(|s| Scalar::parse(s)),
                        w.get(4),
                    ) else {
                        return Err(bad());
                    };
                    Property {
                        name: name.to_string(),
                        list: Some(c),
                        kind: k,
                    }
                } else {
                    let (Some(k), Some(name)) = (w.get(1).and_then(|s| Scalar::parse(s)), w.get(2))
                    else {
                        return Err(bad());
                    };
                    Property {
                        name: name.to_string(),
                        list: None,
                        kind: k,
                    }
                };
                el.props.push(p);
            }
            Some(_) => return Err(bad()),
        }
    }
    let format = format.ok_or("the header has no format line")?;
    let body = &bytes[body_start..];
    let text = if format == Format::Ascii {
        std::str::from_utf8(body).map_err(|_| "the ASCII body is not text")?
    } else {
        ""
    };
    let mut b = Body {
        format,
        bytes: body,
        pos: 0,
        line: Vec::new().into_iter(),
        line_no: header_lines + 1,
        lines: text.lines().peekable(),
    };
    let mut raw = RawMesh::default();
    let mut normals = Vec::new();
    let mut has_normals = false;
    let mut vertex_seen = false;
    for el in &elements {
        // Each element takes at least one byte (binary) or two (ASCII: a
        // value and a line end): a claimed count beyond that is refused
        // before any allocation.
        let least = match format {
            Format::Ascii => 2,
            _ => el
                .props
                .iter()
                .map(|p| p.list.unwrap_or(p.kind).size())
                .sum::<usize>()
                .max(1),
        };
        if el.count > b.remaining() / least {
            return Err(format!(
                "the header claims {} {} elements, more than the {} bytes after it can hold",
                el.count,
                el.name,
                b.remaining()
            ));
        }
        let find = |n: &str| {
            el.props
                .iter()
                .position(|p| p.name == n && p.list.is_none())
        };
        match el.name.as_str() {
            "vertex" => {
                vertex_seen = true;
                let xyz = [find("x"), find("y"), find("z")];
                if xyz.iter().any(Option::is_none) {
                    return Err("the vertex element has no x, y and z properties".into());
                }
                let nxyz = [find("nx"), find("ny"), find("nz")];
                has_normals = nxyz.iter().all(Option::is_some);
                raw.positions.reserve(el.count);
                let mut vals = vec![0.0; el.props.len()];
                for i in 0..el.count {
                    let what = || format!("vertex {i}");
                    b.next_element(&what)?;
                    for (k, p) in el.props.iter().enumerate() {
                        vals[k] = read_prop(&mut b, p, &what)?;
                    }
                    b.end_element(&what)?;
                    let get = |ix: [Option<usize>; 3]| {
                        DVec3::new(
                            vals[ix[0].unwrap()],
                            vals[ix[1].unwrap()],
                            vals[ix[2].unwrap()],
                        )
                    };
                    let v = get(xyz);
                    if !v.is_finite() {
                        return Err(format!("vertex {i}: {v} is not finite, expected numbers"));
                    }
                    raw.positions.push(v);
                    if has_normals {
                        normals.push(get(nxyz));
                    }
                }
            }
            "face" => {
                let Some(list) = el.props.iter().position(|p| {
                    p.list.is_some() && (p.name == "vertex_indices" || p.name == "vertex_index")
                }) else {
                    return Err("the face element has no vertex_indices list".into());
                };
                // Elements may come in any order: faces before the vertices
                // are checked against the count the header gives them.
                let nv = if vertex_seen {
                    raw.positions.len()
                } else {
                    elements
                        .iter()
                        .find(|e| e.name == "vertex")
                        .map(|e| e.count)
                        .ok_or("the file has faces but no vertex element")?
                };
                for i in 0..el.count {
                    let what = || format!("face {i}");
                    b.next_element(&what)?;
                    for (k, p) in el.props.iter().enumerate() {
                        if k != list {
                            skip_prop(&mut b, p, &what)?;
                            continue;
                        }
                        let count = b.value(p.list.unwrap(), &what)?;
                        if !((0.0..=1e6).contains(&count) && count.fract() == 0.0) {
                            return Err(format!("face {i}: {count} vertices, expected 3 to 10⁶"));
                        }
                        let mut idx = Vec::with_capacity(count as usize);
                        for _ in 0..count as usize {
                            let v = b.value(p.kind, &what)?;
                            if !(v >= 0.0 && v < nv as f64 && v.fract() == 0.0) {
                                return Err(format!(
                                    "face {i}: vertex index {v} is out of range, the file has {nv} vertices"
                                ));
                            }
                            idx.push(v as u32);
                        }
                        if idx.len() < 3 {
                            return Err(format!(
                                "face {i}: {} vertices, expected at least 3",
                                idx.len()
                            ));
                        }
                        for j in 1..idx.len() - 1 {
                            raw.faces.push([idx[0], idx[j], idx[j + 1]]);
                        }
                    }
                    b.end_element(&what)?;
                }
            }
            _ => {
                for i in 0..el.count {
                    let what = || format!("{} {i}", el.name);
                    b.next_element(&what)?;
                    for p in &el.props {
                        skip_prop(&mut b, p, &what)?;
                    }
                    b.end_element(&what)?;
                }
            }
        }
    }
    if has_normals && !raw.faces.is_empty() {
        raw.face_normals = Some(raw.faces.clone());
        raw.normals = normals;
    }
    Ok(raw)
}

fn read_prop(b: &mut Body, p: &Property, what: &dyn Fn() -> String) -> Result<f64, String> {
    match p.list {
        None => b.value(p.kind, what),
        Some(_) => {
            skip_prop(b, p, what)?;
            Ok(0.0)
        }
    }
}

fn skip_prop(b: &mut Body, p: &Property, what: &dyn Fn() -> String) -> Result<(), String> {
    match p.list {
        None => b.value(p.kind, what).map(|_| ()),
        Some(c) => {
            let n = b.value(c, what)?;
            if !(0.0..=1e6).contains(&n) {
                return Err(format!("{}: a list of {n} values", what()));
            }
            for _ in 0..n as usize {
                b.value(p.kind, what)?;
            }
            Ok(())
        }
    }
}
