//! Mesh files (`mesh` objects): read, checked, transformed and turned into
//! triangles. Errors are one line naming the line or element of the file
//! (the caller adds the file and the object's JSON path).

use std::path::{Path, PathBuf};

use glam::DVec3;

use super::geometry::MeshPart;
pub use super::mesh_gltf::read_gltf;
pub use super::mesh_ply::read_ply;
use super::scene_file::{MeshDesc, MeshShading, read_regular};

/// Limits of mesh input (documented in the README).
pub mod limits {
    /// Largest mesh file read, in bytes.
    pub const MAX_MESH_FILE_BYTES: u64 = 2 << 30;
    /// Most triangles in one scene, over all meshes and `triangle` objects.
    pub const MAX_TRIANGLES: usize = 20_000_000;
}

/// A mesh as read from its file, in the file's own coordinates.
#[derive(Debug, Default, Clone)]
pub struct RawMesh {
    pub positions: Vec<DVec3>,
    /// Vertex indices of each triangle (checked to be in range).
    pub faces: Vec<[u32; 3]>,
    /// Normals from the file, and each face's indices into them (in range;
    /// [`NO_NORMAL`] for a face without them), if any face has them.
    pub normals: Vec<DVec3>,
    pub face_normals: Option<Vec<[u32; 3]>>,
}

/// The normal indices of a face whose file gives it no normal at every
/// corner: `auto` shading makes that face flat.
pub const NO_NORMAL: [u32; 3] = [u32::MAX; 3];

/// The file of a mesh object: relative paths are resolved against the
/// scene file's folder.
pub fn resolve(file: &str, base_dir: Option<&Path>) -> Result<PathBuf, String> {
    let path = Path::new(file);
    if path.is_absolute() {
        return Ok(path.to_path_buf());
    }
    match base_dir {
        Some(dir) => Ok(dir.join(path)),
        None => Err(format!(
            "{:?} is a relative path, but the scene has no folder (it was not read from a file): give an absolute path",
            super::error::cut(file)
        )),
    }
}

/// A mesh object's file as messages quote it: cut, and escaped as
/// material names are (`{:?}`), so that a newline or a terminal escape in
/// the scene cannot split the message or reach the terminal.
pub fn quoted_file(file: &str) -> String {
    format!("{:?}", super::error::cut(file))
}

/// Reads, checks and transforms a mesh object's file. `budget`: the most
/// triangles it may add to the scene.
pub fn load(desc: &MeshDesc, base_dir: Option<&Path>, budget: usize) -> Result<MeshPart, String> {
    let path = resolve(&desc.file, base_dir)?;
    let name = quoted_file(&desc.file);
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    let read = |what: &str| -> Result<Vec<u8>, String> {
        read_regular(&path, limits::MAX_MESH_FILE_BYTES).map_err(|e| format!("{name}: {e}{what}"))
    };
    let raw = match ext.as_str() {
        "obj" => read_obj(&read("")?),
        "ply" => read_ply(&read("")?),
        "gltf" | "glb" => read_gltf(&read("")?, path.parent()),
        other => Err(format!(
            "unsupported mesh format {:?}, expected a file ending in .obj, .ply, .gltf or .glb",
            if other.is_empty() {
                "(none)".to_string()
            } else {
                super::error::cut(other)
            }
        )),
    }
    .map_err(|e| format!("{name}: {e}"))?;
    if raw.faces.len() > budget {
        return Err(format!(
            "{name}: {} triangles, more than the {} the scene has room for (at most {} triangles in a scene)",
            raw.faces.len(),
            budget,
            limits::MAX_TRIANGLES
        ));
    }
    Ok(build(raw, desc))
}

/// The transform of the format: `translate + R_y · (scale ∘ v)`.
#[derive(Debug, Clone, Copy)]
pub struct Transform {
    scale: DVec3,
    cos: f64,
    sin: f64,
    translate: DVec3,
}

impl Transform {
    pub fn of(desc: &MeshDesc) -> Transform {
        let (sin, cos) = desc.rotate_y_deg.to_radians().sin_cos();
        Transform {
            scale: desc.scale.per_axis().into(),
            cos,
            sin,
            translate: desc.translate.into(),
        }
    }

    /// Rotation about y, as the `box` object's (x towards −z for positive
    /// angles).
    fn rotate(&self, v: DVec3) -> DVec3 {
        DVec3::new(
            v.x * self.cos + v.z * self.sin,
            v.y,
            -v.x * self.sin + v.z * self.cos,
        )
    }

    pub fn point(&self, v: DVec3) -> DVec3 {
        self.translate + self.rotate(self.scale * v)
    }

    /// Normals go through the inverse transpose: R · (n / scale).
    pub fn normal(&self, n: DVec3) -> DVec3 {
        self.rotate(n / self.scale)
    }
}

/// The faces of a checked raw mesh under the object's transform and
/// shading (degenerate ones still in: the scene leaves them out).
pub fn build(raw: RawMesh, desc: &MeshDesc) -> MeshPart {
    let tf = Transform::of(desc);
    let RawMesh {
        mut positions,
        faces,
        normals: file_normals,
        face_normals,
    } = raw;
    for p in &mut positions {
        *p = tf.point(*p);
    }
    let normals = match desc.shading {
        MeshShading::Flat => Vec::new(),
        MeshShading::Smooth => {
            // Area-weighted: the unnormalized face normal is twice the area
            // times the unit normal.
            let mut acc = vec![DVec3::ZERO; positions.len()];
            for f in &faces {
                let [a, b, c] = f.map(|i| positions[i as usize]);
                let n = (b - a).cross(c - a);
                if n.is_finite() {
                    for &i in f {
                        acc[i as usize] += n;
                    }
                }
            }
            acc
        }
        MeshShading::Auto => match face_normals {
            None => Vec::new(),
            Some(fnorm) if fnorm == faces => {
                // Normals indexed as the positions: one per vertex.
                let mut n = vec![DVec3::ZERO; positions.len()];
                for (n, &q) in n.iter_mut().zip(&file_normals) {
                    *n = tf.normal(q);
                }
                n
            }
            Some(fnorm) => {
                return split_vertices(positions, faces, &fnorm, &file_normals, &tf);
            }
        },
    };
    MeshPart {
        positions,
        normals,
        faces,
    }
}

/// A mesh whose faces index positions and normals apart (OBJ's `f 1//7`):
/// one vertex per pair of indices used, so that normals can be shared by
/// position index. A face without normals ([`NO_NORMAL`]) gets vertices of
/// normal zero: flat (see `Meshes::add`).
fn split_vertices(
    positions: Vec<DVec3>,
    faces: Vec<[u32; 3]>,
    fnorm: &[[u32; 3]],
    file_normals: &[DVec3],
    tf: &Transform,
) -> MeshPart {
    let mut index = std::collections::HashMap::new();
    let mut part = MeshPart::default();
    for (f, nf) in faces.iter().zip(fnorm) {
        let face = std::array::from_fn(|k| {
            *index.entry((f[k], nf[k])).or_insert_with(|| {
                part.positions.push(positions[f[k] as usize]);
                part.normals.push(if *nf == NO_NORMAL {
                    DVec3::ZERO
                } else {
                    tf.normal(file_normals[nf[k] as usize])
                });
                (part.positions.len() - 1) as u32
            })
        });
        part.faces.push(face);
    }
    part
}

/// Wavefront OBJ: plain files through the fast reader of `mesh_obj.rs`,
/// any other through `tobj` (polygons as fans, points and lines ignored,
/// `mtllib` not read), after a scan of the text that names the first line
/// either reader would refuse or drop (a face of fewer than three corners,
/// an index out of range, a malformed number). A byte-order mark, classic
/// Mac line ends (CR alone) and comments after a statement are read as
/// the tools that write them mean them.
pub fn read_obj(bytes: &[u8]) -> Result<RawMesh, String> {
    let bytes = clean_obj(bytes);
    if let Some(raw) = super::mesh_obj::read_plain_obj(&bytes) {
        return Ok(raw);
    }
    if let Some(e) = obj_diagnosis(&bytes) {
        return Err(e);
    }
    read_obj_tobj(&bytes)
}

/// The OBJ text without a UTF-8 byte-order mark, with CR line ends as LF
/// where the file has no LF at all, without comments that follow a
/// statement on its line (`v 1 2 3 # top`), and with line continuations (a
/// backslash ending a line) joined into one line, the line ends they took
/// put after it so that later lines keep their numbers (neither reader
/// joins them: `tobj` read the backslash as an index); borrowed where none
/// of these is there.
fn clean_obj(bytes: &[u8]) -> std::borrow::Cow<'_, [u8]> {
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    let cr_only = bytes.contains(&b'\r') && !bytes.contains(&b'\n');
    let trailing_comment = |line: &[u8]| {
        line.iter()
            .position(|&b| b == b'#')
            .is_some_and(|at| !line[..at].trim_ascii().is_empty())
    };
    // A comment line is not continued (`# C:\models\`).
    let continued = |line: &[u8]| {
        line.trim_ascii_end().ends_with(b"\\") && !line.trim_ascii_start().starts_with(b"#")
    };
    let break_byte = if cr_only { b'\r' } else { b'\n' };
    if !cr_only
        && !bytes
            .split(|&b| b == b'\n')
            .any(|line| trailing_comment(line) || continued(line))
    {
        return std::borrow::Cow::Borrowed(bytes);
    }
    let mut out = Vec::with_capacity(bytes.len());
    let mut joined = 0;
    for line in bytes.split(|&b| b == break_byte) {
        let kept = match line.iter().position(|&b| b == b'#') {
            Some(at) if trailing_comment(line) => &line[..at],
            _ => line,
        };
        if continued(kept) {
            let body = kept.trim_ascii_end();
            out.extend_from_slice(&body[..body.len() - 1]);
            out.push(b' ');
            joined += 1;
            continue;
        }
        out.extend_from_slice(kept);
        out.extend(std::iter::repeat_n(b'\n', 1 + joined));
        joined = 0;
    }
    std::borrow::Cow::Owned(out)
}

/// Whether every corner of every `f` statement names a normal (`v/t/n` or
/// `v//n`), line continuations joined.
fn every_corner_has_a_normal(bytes: &[u8]) -> bool {
    let text = String::from_utf8_lossy(bytes)
        .replace("\\\r\n", " ")
        .replace("\\\n", " ");
    text.lines().all(|line| {
        let mut words = line.split_whitespace();
        words.next() != Some("f")
            || words.all(|corner| corner.split('/').nth(2).is_some_and(|n| !n.is_empty()))
    })
}

/// Wavefront OBJ through `tobj` alone (see [`read_obj`]).
pub fn read_obj_tobj(bytes: &[u8]) -> Result<RawMesh, String> {
    let options = tobj::LoadOptions {
        single_index: false,
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
    };
    let loaded = tobj::load_obj_buf(&mut &bytes[..], &options, |_| {
        Err(tobj::LoadError::OpenFileFailed)
    });
    let models = match loaded {
        Ok((models, _materials)) => models,
        Err(e) => {
            return Err(obj_diagnosis(bytes).unwrap_or_else(|| format!("{e}")));
        }
    };
    let mut raw = RawMesh::default();
    let mut face_normals = Vec::new();
    let every_face_has_normals = every_corner_has_a_normal(bytes);
    for m in &models {
        let mesh = &m.mesh;
        let base = raw.positions.len() as u32;
        let nbase = raw.normals.len() as u32;
        raw.positions.extend(
            mesh.positions
                .chunks_exact(3)
                .map(|p| DVec3::new(p[0], p[1], p[2])),
        );
        raw.normals.extend(
            mesh.normals
                .chunks_exact(3)
                .map(|p| DVec3::new(p[0], p[1], p[2])),
        );
        let count = mesh.positions.len() / 3;
        for f in mesh.indices.chunks_exact(3) {
            if f.iter().any(|&i| i as usize >= count) {
                return Err(obj_diagnosis(bytes)
                    .unwrap_or_else(|| "a face's vertex index is out of range".into()));
            }
            raw.faces.push([f[0] + base, f[1] + base, f[2] + base]);
        }
        // `tobj` gives a model's normal indices only as one list, and gives
        // a face without them one of the file's normals: the file's faces
        // all have normals, or none is used.
        let ncount = mesh.normals.len() / 3;
        let with_normals = every_face_has_normals
            && mesh.normal_indices.len() == mesh.indices.len()
            && ncount > 0
            && mesh.normal_indices.iter().all(|&i| (i as usize) < ncount);
        if with_normals {
            face_normals.extend(
                mesh.normal_indices
                    .chunks_exact(3)
                    .map(|f| [f[0] + nbase, f[1] + nbase, f[2] + nbase]),
            );
        } else {
            face_normals.resize(raw.faces.len(), NO_NORMAL);
        }
    }
    if raw.positions.iter().any(|p| !p.is_finite()) {
        return Err(obj_diagnosis(bytes).unwrap_or_else(|| "a vertex is not finite".into()));
    }
    if face_normals.iter().any(|f| *f != NO_NORMAL) {
        raw.face_normals = Some(face_normals);
    }
    Ok(raw)
}

/// The first line of an OBJ text that is wrong, as a message: a line that
/// is not UTF-8, a `v` line without 3, 4 (with w) or 6 (with a colour)
/// finite numbers, a `vn` line without three numbers, a face with fewer
/// than three corners, a malformed corner, or an index out of range.
fn obj_diagnosis(bytes: &[u8]) -> Option<String> {
    let mut vertices: i64 = 0;
    let mut normals: i64 = 0;
    let mut texcoords: i64 = 0;
    for (n, line) in bytes.split(|&b| b == b'\n').enumerate() {
        let line_no = n + 1;
        let Ok(line) = std::str::from_utf8(line) else {
            return Some(format!("line {line_no} is not UTF-8 text"));
        };
        let mut words = line.split_whitespace();
        let Some(key) = words.next() else { continue };
        let shown = super::error::cut(line.trim());
        match key {
            "v" | "vn" => {
                let nums: Vec<Option<f64>> = words.map(|w| w.parse().ok()).collect();
                let counts: &[usize] = if key == "v" { &[3, 4, 6] } else { &[3] };
                if !counts.contains(&nums.len()) || nums.iter().any(Option::is_none) {
                    let expected = if key == "v" {
                        "three numbers (or four with w, or six with a colour)"
                    } else {
                        "three numbers"
                    };
                    return Some(format!(
                        "line {line_no}: malformed {key} line {shown:?}, expected {expected}"
                    ));
                }
                if key == "v" && nums.iter().any(|x| !x.is_some_and(f64::is_finite)) {
                    return Some(format!(
                        "line {line_no}: vertex {} is not finite ({shown:?}), expected numbers",
                        vertices + 1
                    ));
                }
                if key == "v" {
                    vertices += 1;
                } else {
                    normals += 1;
                }
            }
            "vt" => texcoords += 1,
            "f" => {
                let mut count = 0;
                for w in words {
                    count += 1;
                    let parts: Vec<&str> = w.split('/').collect();
                    let check = |s: &str, total: i64, what: &str, plural: &str| -> Option<String> {
                        let Ok(i) = s.parse::<i64>() else {
                            let s = super::error::cut(s);
                            return Some(format!(
                                "line {line_no}: malformed face {shown:?}: {what} index {s:?} is not a number"
                            ));
                        };
                        let ok = (i > 0 && i <= total) || (i < 0 && -i <= total);
                        (!ok).then(|| {
                            format!(
                                "line {line_no}: face {shown:?}: {what} index {i} is out of range, the file has {total} {plural} before this line"
                            )
                        })
                    };
                    if parts.len() > 3 {
                        let w = super::error::cut(w);
                        return Some(format!(
                            "line {line_no}: malformed face {shown:?}: corner {w:?}, expected v, v/t, v//n or v/t/n"
                        ));
                    }
                    let found = check(parts[0], vertices, "vertex", "vertices")
                        .or_else(|| {
                            let t = parts.get(1).filter(|s| !s.is_empty())?;
                            check(t, texcoords, "texture", "texture coordinates")
                        })
                        .or_else(|| {
                            let n = parts.get(2).filter(|s| !s.is_empty())?;
                            check(n, normals, "normal", "normals")
                        });
                    if found.is_some() {
                        return found;
                    }
                }
                if count < 3 {
                    return Some(format!(
                        "line {line_no}: malformed face {shown:?}, expected at least three vertices"
                    ));
                }
            }
            _ => {}
        }
    }
    None
}
