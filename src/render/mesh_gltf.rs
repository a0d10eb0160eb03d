//! glTF 2.0 meshes: `.gltf` with external or embedded (`data:`) buffers,
//! and `.glb`. Every triangle primitive (lists, strips and fans) of the
//! default scene (or the first), its node transforms applied; points and
//! lines have no area and are left out.
//!
//! The `gltf` crate parses and validates the document; the accessors are
//! read here, each element checked to lie inside its buffer view and the
//! view inside its buffer, so that a malformed file is one error naming the
//! accessor, never a panic in the crate's reader or a mesh that silently
//! lost its indices.

use std::path::{Path, PathBuf};

use glam::{DMat3, DMat4, DVec3};
use gltf::Semantic;
use gltf::accessor::{Accessor, DataType, Dimensions};
use gltf::mesh::Mode;

use super::mesh::{RawMesh, limits};
use super::scene_file::read_regular;

/// Elements an accessor without a buffer view (all zeros, or sparse) may
/// claim: as many as the vertices of the triangles a scene may hold.
const MAX_VIEWLESS_ELEMENTS: usize = 3 * limits::MAX_TRIANGLES;

/// glTF 2.0 (see the module): the mesh in the file's coordinates after its
/// node transforms. `dir`: the folder external buffers are relative to.
pub fn read_gltf(bytes: &[u8], dir: Option<&Path>) -> Result<RawMesh, String> {
    // A GLB header whose length is below its own 12 bytes makes the crate
    // subtract past zero (found by the `read_gltf` fuzz target): refused
    // here, by name.
    if let Some(length) = bytes
        .strip_prefix(b"glTF")
        .and_then(|rest| rest.get(4..8))
        .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        && (length < 12 || length as usize > bytes.len())
    {
        return Err(format!(
            "the GLB header gives the file's length as {length} bytes, expected 12 to {} (the file's size)",
            bytes.len()
        ));
    }
    // gltf-json's validation can panic on some malformed documents (found
    // by the mutation test): caught and reported as a refusal.
    let g = std::panic::catch_unwind(|| gltf::Gltf::from_slice(bytes))
        .map_err(|_| "not a valid glTF file (its validation failed)".to_string())?
        // The crate quotes the offending JSON value whole (found by the
        // fuzz target): long ones are cut.
        .map_err(|e| {
            format!(
                "not a valid glTF file: {}",
                super::error::cut_quoted(&e.to_string())
            )
        })?;
    let mut buffers: Vec<Vec<u8>> = Vec::new();
    for b in g.buffers() {
        let data = match b.source() {
            gltf::buffer::Source::Bin => g.blob.clone().ok_or_else(|| {
                format!(
                    "buffer {} is the GLB binary chunk, which is missing",
                    b.index()
                )
            })?,
            gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
                data_uri(uri).map_err(|e| format!("buffer {}: its data: URI {e}", b.index()))?
            }
            gltf::buffer::Source::Uri(uri) => {
                let shown = super::error::cut(uri);
                let file = percent_decoded(uri)
                    .map_err(|e| format!("buffer {} ({shown}): {e}", b.index()))?;
                let path = dir.map_or_else(|| PathBuf::from(&file), |d| d.join(&file));
                read_regular(&path, limits::MAX_MESH_FILE_BYTES)
                    .map_err(|e| format!("buffer {} ({shown}): {e}", b.index()))?
            }
        };
        if data.len() < b.length() {
            return Err(format!(
                "buffer {}: {} bytes, the file claims {}",
                b.index(),
                data.len(),
                b.length()
            ));
        }
        buffers.push(data);
    }
    let scene = g
        .default_scene()
        .or_else(|| g.scenes().next())
        .ok_or("the file has no scene")?;
    let mut raw = RawMesh::default();
    let mut any_normals = false;
    let mut stack: Vec<(gltf::Node, DMat4, usize)> =
        scene.nodes().map(|n| (n, DMat4::IDENTITY, 0)).collect();
    let mut visited = 0usize;
    while let Some((node, parent, depth)) = stack.pop() {
        visited += 1;
        if depth > 256 || visited > 1_000_000 {
            return Err("the node hierarchy is too deep or cyclic".into());
        }
        let local = DMat4::from_cols_array_2d(&node.transform().matrix().map(|c| c.map(f64::from)));
        let m = parent * local;
        let normal_m = DMat3::from_mat4(m).inverse().transpose();
        if let Some(mesh) = node.mesh() {
            for prim in mesh.primitives() {
                let what = format!("mesh {} primitive {}", mesh.index(), prim.index());
                let mode = prim.mode();
                if !matches!(
                    mode,
                    Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
                ) {
                    continue;
                }
                let attribute = |semantic: Semantic, name: &str| {
                    prim.get(&semantic)
                        .map(|a| {
                            vec3s(&a, &buffers).map_err(|e| {
                                format!("{what}: {name} (accessor {}): {e}", a.index())
                            })
                        })
                        .transpose()
                };
                let pos = attribute(Semantic::Positions, "POSITION")?
                    .ok_or_else(|| format!("{what}: no POSITION attribute"))?;
                let nor = attribute(Semantic::Normals, "NORMAL")?;
                let n = pos.len();
                let indices = match prim.indices() {
                    Some(a) => indices(&a, &buffers)
                        .map_err(|e| format!("{what}: indices (accessor {}): {e}", a.index()))?,
                    None => (0..n as u32).collect(),
                };
                if let Some(bad) = indices.iter().find(|&&i| i as usize >= n) {
                    return Err(format!(
                        "{what}: vertex index {bad} is out of range, the primitive has {n} vertices"
                    ));
                }
                let base = raw.positions.len();
                for (k, p) in pos.iter().enumerate() {
                    let v = m.transform_point3(*p);
                    if !v.is_finite() {
                        return Err(format!("{what}: vertex {k} is not finite"));
                    }
                    raw.positions.push(v);
                }
                // A primitive without normals has them zero: flat faces.
                match &nor {
                    Some(nor) if nor.len() == n => {
                        any_normals = true;
                        raw.normals.extend(nor.iter().map(|q| normal_m * *q))
                    }
                    _ => raw.normals.resize(raw.positions.len(), DVec3::ZERO),
                }
                let b = base as u32;
                triangles(mode, &indices, |f| raw.faces.push(f.map(|i| i + b)));
            }
        }
        for child in node.children() {
            stack.push((child, m, depth + 1));
        }
    }
    if any_normals && !raw.faces.is_empty() && raw.normals.len() == raw.positions.len() {
        raw.face_normals = Some(raw.faces.clone());
    } else {
        raw.normals.clear();
    }
    Ok(raw)
}

/// The triangles of a primitive's vertex list under its mode, as the glTF
/// specification numbers them: lists by threes, strips with every other
/// triangle's first two corners swapped (so all face one way), fans
/// around the first vertex. Trailing vertices that make no triangle are
/// left out.
fn triangles(mode: Mode, v: &[u32], mut each: impl FnMut([u32; 3])) {
    match mode {
        Mode::Triangles => v.chunks_exact(3).for_each(|f| each([f[0], f[1], f[2]])),
        Mode::TriangleStrip => {
            for i in 0..v.len().saturating_sub(2) {
                let odd = i % 2;
                each([v[i], v[i + 1 + odd], v[i + 2 - odd]]);
            }
        }
        Mode::TriangleFan => {
            for i in 1..v.len().saturating_sub(1) {
                each([v[i], v[i + 1], v[0]]);
            }
        }
        _ => {}
    }
}

/// A VEC3 FLOAT accessor's elements (positions, normals).
fn vec3s(a: &Accessor, buffers: &[Vec<u8>]) -> Result<Vec<DVec3>, String> {
    let elements = elements::<3>(a, buffers, Dimensions::Vec3, &[DataType::F32])?;
    Ok(elements.into_iter().map(DVec3::from).collect())
}

/// A SCALAR accessor of unsigned integers (vertex indices).
fn indices(a: &Accessor, buffers: &[Vec<u8>]) -> Result<Vec<u32>, String> {
    let allowed = [DataType::U8, DataType::U16, DataType::U32];
    let elements = elements::<1>(a, buffers, Dimensions::Scalar, &allowed)?;
    // Unsigned integers below 2³², exact in f64.
    Ok(elements.into_iter().map(|[i]| i as u32).collect())
}

/// The elements of an accessor of type `dims` (`N` components) with a
/// component type among `allowed`, read from its buffer view (zeros
/// without one), its sparse substitutions applied. Every element must lie
/// inside its view and the view inside its buffer.
fn elements<const N: usize>(
    a: &Accessor,
    buffers: &[Vec<u8>],
    dims: Dimensions,
    allowed: &[DataType],
) -> Result<Vec<[f64; N]>, String> {
    if a.dimensions() != dims {
        return Err(format!(
            "type {}, expected {}",
            dims_name(a.dimensions()),
            dims_name(dims)
        ));
    }
    let kind = a.data_type();
    if !allowed.contains(&kind) {
        let names: Vec<&str> = allowed.iter().map(|&k| type_name(k)).collect();
        return Err(format!(
            "component type {}, expected {}",
            type_name(kind),
            names.join(", ")
        ));
    }
    let (count, size) = (a.count(), kind.size());
    let element = N * size;
    let mut out = match a.view() {
        Some(view) => {
            let data = view_bytes(&view, buffers)?;
            let stride = view.stride().unwrap_or(element);
            if stride < element {
                return Err(format!(
                    "bufferView {}: byteStride {stride} is smaller than an element ({element} bytes)",
                    view.index()
                ));
            }
            let start = a.offset();
            let end = count
                .checked_sub(1)
                .map_or(Some(start), |last| {
                    last.checked_mul(stride)?
                        .checked_add(start)?
                        .checked_add(element)
                })
                .filter(|&end| end <= data.len());
            if end.is_none() {
                return Err(format!(
                    "{count} elements of {element} bytes from byte {start} every {stride} bytes reach beyond bufferView {} ({} bytes)",
                    view.index(),
                    data.len()
                ));
            }
            (0..count)
                .map(|k| read_element::<N>(&data[start + k * stride..], kind))
                .collect()
        }
        None if count > MAX_VIEWLESS_ELEMENTS => {
            return Err(format!(
                "{count} elements without a bufferView, expected at most {MAX_VIEWLESS_ELEMENTS}"
            ));
        }
        None => vec![[0.0; N]; count],
    };
    if let Some(sparse) = a.sparse() {
        let n = sparse.count();
        if n > count {
            return Err(format!(
                "{n} sparse substitutions, more than its {count} elements"
            ));
        }
        let (iv, vv) = (sparse.indices(), sparse.values());
        let index_kind = match iv.index_type() {
            gltf::accessor::sparse::IndexType::U8 => DataType::U8,
            gltf::accessor::sparse::IndexType::U16 => DataType::U16,
            gltf::accessor::sparse::IndexType::U32 => DataType::U32,
        };
        let index_bytes = span(&iv.view(), buffers, iv.offset(), n * index_kind.size())
            .map_err(|e| format!("sparse indices: {e}"))?;
        let value_bytes = span(&vv.view(), buffers, vv.offset(), n * element)
            .map_err(|e| format!("sparse values: {e}"))?;
        for s in 0..n {
            let [i] = read_element::<1>(&index_bytes[s * index_kind.size()..], index_kind);
            let Some(slot) = out.get_mut(i as usize) else {
                return Err(format!(
                    "sparse index {i} is out of range, the accessor has {count} elements"
                ));
            };
            *slot = read_element::<N>(&value_bytes[s * element..], kind);
        }
    }
    Ok(out)
}

/// `length` bytes of `data` from `start`, if they lie inside it.
fn within(data: &[u8], start: usize, length: usize) -> Option<&[u8]> {
    let end = start.checked_add(length)?;
    data.get(start..end)
}

/// The bytes of a buffer view, checked to lie inside its buffer.
fn view_bytes<'b>(view: &gltf::buffer::View, buffers: &'b [Vec<u8>]) -> Result<&'b [u8], String> {
    let buffer = &buffers[view.buffer().index()];
    let (start, length) = (view.offset(), view.length());
    within(buffer, start, length).ok_or_else(|| {
        format!(
            "bufferView {} ({length} bytes from byte {start}) reaches beyond buffer {} ({} bytes)",
            view.index(),
            view.buffer().index(),
            buffer.len()
        )
    })
}

/// `length` bytes from `offset` in a view, checked.
fn span<'b>(
    view: &gltf::buffer::View,
    buffers: &'b [Vec<u8>],
    offset: usize,
    length: usize,
) -> Result<&'b [u8], String> {
    let data = view_bytes(view, buffers)?;
    within(data, offset, length).ok_or_else(|| {
        format!(
            "{length} bytes from byte {offset} reach beyond bufferView {} ({} bytes)",
            view.index(),
            data.len()
        )
    })
}

/// One element of `N` little-endian components of type `kind` at the
/// start of `bytes` (checked by the caller to hold it).
fn read_element<const N: usize>(bytes: &[u8], kind: DataType) -> [f64; N] {
    let size = kind.size();
    std::array::from_fn(|c| {
        let b = &bytes[c * size..(c + 1) * size];
        match kind {
            DataType::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            DataType::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            DataType::U16 => u16::from_le_bytes([b[0], b[1]]) as f64,
            DataType::U8 => b[0] as f64,
            DataType::I16 => i16::from_le_bytes([b[0], b[1]]) as f64,
            DataType::I8 => b[0] as i8 as f64,
        }
    })
}

fn type_name(kind: DataType) -> &'static str {
    match kind {
        DataType::I8 => "BYTE",
        DataType::U8 => "UNSIGNED_BYTE",
        DataType::I16 => "SHORT",
        DataType::U16 => "UNSIGNED_SHORT",
        DataType::U32 => "UNSIGNED_INT",
        DataType::F32 => "FLOAT",
    }
}

fn dims_name(dims: Dimensions) -> &'static str {
    match dims {
        Dimensions::Scalar => "SCALAR",
        Dimensions::Vec2 => "VEC2",
        Dimensions::Vec3 => "VEC3",
        Dimensions::Vec4 => "VEC4",
        Dimensions::Mat2 => "MAT2",
        Dimensions::Mat3 => "MAT3",
        Dimensions::Mat4 => "MAT4",
    }
}

/// The bytes of a `data:` URI: base64 after `;base64,`, else
/// percent-encoded text after the comma (RFC 2397).
fn data_uri(uri: &str) -> Result<Vec<u8>, String> {
    let Some((head, body)) = uri.split_once(',') else {
        return Err("has no comma before its data".into());
    };
    if head.ends_with(";base64") {
        base64(body)
    } else {
        percent_bytes(body)
    }
}

/// Standard or URL-safe base64, padding optional, whitespace ignored.
fn base64(text: &str) -> Result<Vec<u8>, String> {
    let mut out = Vec::with_capacity(text.len() / 4 * 3);
    let (mut acc, mut bits) = (0u32, 0);
    for (at, c) in text.bytes().enumerate() {
        let value = match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' | b'-' => 62,
            b'/' | b'_' => 63,
            b'=' => break,
            c if c.is_ascii_whitespace() => continue,
            _ => return Err(format!("has a byte 0x{c:02x} at {at} that is not base64")),
        };
        acc = acc << 6 | value as u32;
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    Ok(out)
}

/// A URI's `%XX` escapes decoded into bytes.
fn percent_bytes(text: &str) -> Result<Vec<u8>, String> {
    let b = text.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' {
            let hex = b
                .get(i + 1..i + 3)
                .and_then(|h| std::str::from_utf8(h).ok())
                .and_then(|h| u8::from_str_radix(h, 16).ok())
                .ok_or_else(|| format!("has a malformed escape at byte {i}"))?;
            out.push(hex);
            i += 3;
        } else {
            out.push(b[i]);
            i += 1;
        }
    }
    Ok(out)
}

/// A relative URI's path with its `%XX` escapes decoded (exporters write a
/// space as `%20`).
fn percent_decoded(uri: &str) -> Result<String, String> {
    String::from_utf8(percent_bytes(uri)?).map_err(|_| "decodes to a path that is not UTF-8".into())
}

#[cfg(test)]
mod tests {
    use super::{Mode, base64, percent_decoded, triangles};

    #[test]
    fn base64_decodes_with_and_without_padding() {
        assert_eq!(base64("aGVsbG8=").unwrap(), b"hello");
        assert_eq!(base64("aGVsbG8").unwrap(), b"hello");
        assert_eq!(base64("aGVs\nbG8h").unwrap(), b"hello!");
        assert_eq!(base64("-_-_").unwrap(), base64("+/+/").unwrap());
        assert!(base64("aGV*").is_err());
    }

    #[test]
    fn percent_escapes_decode() {
        assert_eq!(percent_decoded("my%20buf.bin").unwrap(), "my buf.bin");
        assert_eq!(percent_decoded("a%2Fb").unwrap(), "a/b");
        assert!(percent_decoded("bad%2").is_err());
        assert!(percent_decoded("bad%zz").is_err());
    }

    #[test]
    fn strips_and_fans_number_their_triangles_as_the_specification() {
        let mut got = Vec::new();
        triangles(Mode::TriangleStrip, &[0, 1, 2, 3, 4], |f| got.push(f));
        assert_eq!(got, [[0, 1, 2], [1, 3, 2], [2, 3, 4]]);
        got.clear();
        triangles(Mode::TriangleFan, &[0, 1, 2, 3], |f| got.push(f));
        assert_eq!(got, [[1, 2, 0], [2, 3, 0]]);
        got.clear();
        triangles(Mode::Triangles, &[0, 1, 2, 3, 4], |f| got.push(f));
        assert_eq!(got, [[0, 1, 2]]);
        got.clear();
        triangles(Mode::TriangleStrip, &[0, 1], |f| got.push(f));
        assert!(got.is_empty());
    }
}
