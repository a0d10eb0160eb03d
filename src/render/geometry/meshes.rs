//! The faces of every mesh object of a scene, stored once: shared vertex
//! buffers (f64 positions and unit vertex normals) and 32-bit indices, 13
//! bytes per face beside the vertices. A face becomes a [`Triangle`]'s
//! computations on demand, with the same operations in the same order, so
//! a mesh face and a `triangle` object with its vertices give the same
//! numbers.

use glam::DVec3;
use rayon::prelude::*;

use super::triangle::{self, Triangle, TriangleOccluder};
use super::{Aabb, Ray, SurfacePoint};

/// How a face is shaded.
const FLAT: u8 = 0;
/// With its vertex normals as stored.
const SMOOTH: u8 = 1;
/// With its vertex normals negated (they pointed against the face).
const SMOOTH_FLIPPED: u8 = 2;

/// One mesh object's faces: from `first_face` to the next part's.
#[derive(Debug, Clone, Copy)]
struct Part {
    first_face: u32,
    material: u32,
}

#[derive(Debug, Clone, Default)]
pub struct Meshes {
    positions: Vec<DVec3>,
    /// Unit vertex normals, by position index (empty if no face is smooth;
    /// zero where a vertex has none).
    normals: Vec<DVec3>,
    faces: Vec<[u32; 3]>,
    /// [`FLAT`], [`SMOOTH`] or [`SMOOTH_FLIPPED`], by face.
    shading: Vec<u8>,
    parts: Vec<Part>,
}

/// One mesh object's faces in world space, before they join the scene.
#[derive(Debug, Default)]
pub struct MeshPart {
    pub positions: Vec<DVec3>,
    /// Vertex normals (any length), by position index, or empty (flat).
    pub normals: Vec<DVec3>,
    /// Vertex indices, checked to be in range; degenerate faces are still
    /// there.
    pub faces: Vec<[u32; 3]>,
}

impl MeshPart {
    /// An error naming the first face with a vertex beyond ±`limit`
    /// (degenerate faces included: a face whose area overflows is not
    /// degenerate, only too large).
    pub fn check_range(&self, limit: f64) -> Result<(), String> {
        // Most meshes have every vertex in range: one parallel look at the
        // vertices answers them; only otherwise are the faces searched.
        if self
            .positions
            .par_iter()
            .with_min_len(4096)
            .all(|v| v.is_finite() && v.abs().max_element() <= limit)
        {
            return Ok(());
        }
        for (k, f) in self.faces.iter().enumerate() {
            for v in f.map(|i| self.positions[i as usize]) {
                // (A NaN of inf − inf in the transform counts as beyond.)
                if !v.is_finite() || v.abs().max_element() > limit {
                    return Err(format!(
                        "triangle {k} has the vertex [{:?}, {:?}, {:?}] after the transform, expected coordinates within ±{limit:e}",
                        v.x, v.y, v.z
                    ));
                }
            }
        }
        Ok(())
    }
}

impl Meshes {
    /// Faces of every part.
    pub fn len(&self) -> usize {
        self.faces.len()
    }

    pub fn is_empty(&self) -> bool {
        self.faces.is_empty()
    }

    /// Adds a mesh object's faces (leaving out and counting the degenerate
    /// ones); returns the count of degenerate faces, or an error if the
    /// scene's buffers would outgrow their 32-bit indices.
    pub fn add(&mut self, part: MeshPart, material: u32) -> Result<usize, String> {
        let MeshPart {
            positions,
            normals,
            mut faces,
        } = part;
        let base = self.positions.len();
        if base + positions.len() > u32::MAX as usize
            || self.faces.len() + faces.len() > u32::MAX as usize / 2
        {
            return Err("too many vertices in the scene's meshes".into());
        }
        // Unit normals once per vertex (what a triangle's `with_normals`
        // computes for each corner).
        let unit: Vec<DVec3> = normals
            .par_iter()
            .with_min_len(4096)
            .map(|n| n.normalize_or_zero())
            .collect();
        // Each face's shading, or `DEGENERATE`, on all threads.
        const DEGENERATE: u8 = u8::MAX;
        let mut shading: Vec<u8> = faces
            .par_iter()
            .with_min_len(4096)
            .map(|f| {
                let v = f.map(|i| positions[i as usize]);
                let Some(normal) = Triangle::face_normal(&v) else {
                    return DEGENERATE;
                };
                if unit.is_empty() {
                    return FLAT;
                }
                let n = f.map(|i| unit[i as usize]);
                if n.iter().any(|n| *n == DVec3::ZERO || !n.is_finite()) {
                    FLAT
                } else if n.iter().map(|n| n.dot(normal)).sum::<f64>() < 0.0 {
                    SMOOTH_FLIPPED
                } else {
                    SMOOTH
                }
            })
            .collect();
        let before = faces.len();
        let mut k = 0;
        faces.retain(|_| {
            k += 1;
            shading[k - 1] != DEGENERATE
        });
        shading.retain(|&s| s != DEGENERATE);
        let degenerate = before - faces.len();
        if faces.is_empty() {
            return Ok(degenerate);
        }
        self.parts.push(Part {
            first_face: self.faces.len() as u32,
            material,
        });
        let smooth = shading.iter().any(|&s| s != FLAT);
        if smooth && self.normals.len() < base {
            self.normals.resize(base, DVec3::ZERO);
        }
        if base == 0 && self.faces.is_empty() {
            self.positions = positions;
            self.faces = faces;
            self.shading = shading;
            if smooth {
                self.normals = unit;
            }
        } else {
            let b = base as u32;
            self.positions.extend_from_slice(&positions);
            self.faces.extend(faces.iter().map(|f| f.map(|i| i + b)));
            self.shading.extend_from_slice(&shading);
            if smooth {
                self.normals.extend_from_slice(&unit);
            } else if !self.normals.is_empty() {
                self.normals.resize(self.positions.len(), DVec3::ZERO);
            }
        }
        Ok(degenerate)
    }

    /// The vertices of face `f`.
    #[inline(always)]
    pub fn vertices(&self, f: u32) -> [DVec3; 3] {
        self.faces[f as usize].map(|i| self.positions[i as usize])
    }

    /// Material index of face `f`.
    pub fn material(&self, f: u32) -> u32 {
        let k = self.parts.partition_point(|p| p.first_face <= f);
        self.parts[k - 1].material
    }

    /// See [`Triangle::intersect`].
    #[inline(always)]
    pub fn intersect(&self, f: u32, ray: &Ray, t_max: f64) -> Option<f64> {
        triangle::intersect(&self.vertices(f), ray, t_max)
    }

    /// See [`Triangle::surface`].
    #[inline(always)]
    pub fn surface(&self, f: u32, ray: &Ray, t: f64) -> SurfacePoint {
        let v = self.vertices(f);
        let normal = Triangle::face_normal(&v).expect("degenerate faces are left out");
        let smooth = match self.shading[f as usize] {
            FLAT => None,
            s => {
                let n = self.faces[f as usize].map(|i| self.normals[i as usize]);
                Some(if s == SMOOTH_FLIPPED {
                    n.map(|n| -n)
                } else {
                    n
                })
            }
        };
        triangle::surface(&v, normal, smooth.as_ref(), ray, t)
    }

    /// See [`Triangle::bounds`].
    #[inline]
    pub fn bounds(&self, f: u32) -> Aabb {
        Aabb::from_points(&self.vertices(f)).padded()
    }

    /// See [`Triangle::occluder`]. Always inlined: the shadow kernels call
    /// it for every face they test, and a call leaves their CPU features
    /// (the same operations, so the same bits).
    #[inline(always)]
    pub fn occluder(&self, f: u32, p: DVec3, reach: f32) -> TriangleOccluder {
        TriangleOccluder::new(&self.vertices(f), p, reach)
    }

    /// Bytes held (vertex buffers, faces, shading flags).
    pub fn size_bytes(&self) -> usize {
        (self.positions.len() + self.normals.len()) * 24 + self.faces.len() * 13
    }
}
