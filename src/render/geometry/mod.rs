//! What is seen: rays, primitives, bounds and the BVH, all in f64 world
//! space so that a room far from the origin or at any scale keeps its
//! precision. (Shadow rays use a faster f32 form relative to the hit point,
//! see `shadow/`.)

mod aabb;
mod bvh;
mod bvh4;
mod cuboid;
mod meshes;
mod offset;
mod parallelogram;
mod plane;
mod ray;
mod sphere;
mod triangle;

pub use aabb::Aabb;
pub use bvh::{Bvh, NodeContent};
pub use bvh4::{Bvh4, Node4, Slot};
pub use cuboid::Cuboid;
pub use meshes::{MeshPart, Meshes};
pub use offset::spawn_origin;
pub use parallelogram::Parallelogram;
pub use plane::Plane;
pub use ray::Ray;
pub use sphere::Sphere;
pub use triangle::{Triangle, TriangleOccluder, VertexNormals};

use glam::DVec3;

/// One primitive of the scene: the registry of primitives. Each lives in
/// its own file with everything it needs (intersection, surface, bounds,
/// its `FLAT` and `CONVEX` properties); the shadow rays' f32 form
/// (`shadow/occluder.rs`) and light-frame bounds (`shadow/light_frame.rs`)
/// match on this enum, so a new variant fails to compile until it has them.
#[derive(Debug, Clone)]
pub enum Shape {
    Plane(Plane),
    Parallelogram(Parallelogram),
    Cuboid(Cuboid),
    Sphere(Sphere),
    Triangle(Triangle),
}

/// A primitive of a scene, by id: an object's shape or a face of a mesh
/// (see `Scene::primitive`).
#[derive(Debug, Clone, Copy)]
pub enum Primitive<'a> {
    Shape(&'a Shape),
    Face { meshes: &'a Meshes, face: u32 },
}

impl Primitive<'_> {
    /// See [`Shape::convex`].
    #[inline]
    pub fn convex(&self) -> bool {
        match self {
            Primitive::Shape(s) => s.convex(),
            Primitive::Face { .. } => Triangle::CONVEX,
        }
    }

    /// See [`Shape::skips_itself`].
    #[inline]
    pub fn skips_itself(&self, inside: bool) -> bool {
        match self {
            Primitive::Shape(s) => s.skips_itself(inside),
            Primitive::Face { .. } => Triangle::FLAT || (Triangle::CONVEX && !inside),
        }
    }
}

/// Where a ray meets a surface.
#[derive(Debug, Clone, Copy)]
pub struct SurfacePoint {
    /// The hit point, re-projected onto the surface to cut rounding error.
    pub point: DVec3,
    /// Unit outward (geometric) normal; not yet flipped towards the ray.
    pub normal: DVec3,
    /// Unit shading normal, on the same side as `normal` (equal to it but
    /// for smooth triangles).
    pub shading: DVec3,
    /// Where shadow rays start, relative to `point` (zero but for smooth
    /// triangles, see `triangle.rs`), on the side the ray came from.
    pub shadow_offset: DVec3,
}

impl SurfacePoint {
    /// A point shaded with its geometric normal.
    #[inline]
    pub fn flat(point: DVec3, normal: DVec3) -> SurfacePoint {
        SurfacePoint {
            point,
            normal,
            shading: normal,
            shadow_offset: DVec3::ZERO,
        }
    }
}

impl Shape {
    /// Nearest intersection with `t` in (0, t_max), if any.
    #[inline]
    pub fn intersect(&self, ray: &Ray, t_max: f64) -> Option<f64> {
        match self {
            Shape::Plane(s) => s.intersect(ray, t_max),
            Shape::Parallelogram(s) => s.intersect(ray, t_max),
            Shape::Cuboid(s) => s.intersect(ray, t_max),
            Shape::Sphere(s) => s.intersect(ray, t_max),
            Shape::Triangle(s) => s.intersect(ray, t_max),
        }
    }

    /// The surface point and normal of a hit found by [`Shape::intersect`].
    #[inline(always)]
    pub fn surface(&self, ray: &Ray, t: f64) -> SurfacePoint {
        match self {
            Shape::Plane(s) => s.surface(ray, t),
            Shape::Parallelogram(s) => s.surface(ray, t),
            Shape::Cuboid(s) => s.surface(ray, t),
            Shape::Sphere(s) => s.surface(ray, t),
            Shape::Triangle(s) => s.surface(ray, t),
        }
    }

    /// Bounds, or `None` for an infinite plane.
    pub fn bounds(&self) -> Option<Aabb> {
        match self {
            Shape::Plane(_) => None,
            Shape::Parallelogram(s) => Some(s.bounds()),
            Shape::Cuboid(s) => Some(s.bounds()),
            Shape::Sphere(s) => Some(s.bounds()),
            Shape::Triangle(s) => Some(s.bounds()),
        }
    }

    /// Flat: no ray leaving the surface at a point of it meets it again, on
    /// either side, so a hit's own object can be left out of its shadow
    /// test whichever side was hit.
    #[inline]
    pub fn flat(&self) -> bool {
        match self {
            Shape::Plane(_) => Plane::FLAT,
            Shape::Parallelogram(_) => Parallelogram::FLAT,
            Shape::Cuboid(_) => Cuboid::FLAT,
            Shape::Sphere(_) => Sphere::FLAT,
            Shape::Triangle(_) => Triangle::FLAT,
        }
    }

    /// Convex: the shadow rays from a point that the shape blocks form a
    /// convex cone, so blocking the four light corners blocks the whole
    /// light (the umbra shortcut), and a ray leaving it on the outer side
    /// never meets it again (its own object is left out of the shadow test
    /// of an outside hit). A shape that is neither flat nor convex (none is
    /// yet) stays in its own shadow test and out of the umbra shortcut.
    #[inline]
    pub fn convex(&self) -> bool {
        match self {
            Shape::Plane(_) => Plane::CONVEX,
            Shape::Parallelogram(_) => Parallelogram::CONVEX,
            Shape::Cuboid(_) => Cuboid::CONVEX,
            Shape::Sphere(_) => Sphere::CONVEX,
            Shape::Triangle(_) => Triangle::CONVEX,
        }
    }

    /// Whether a hit on this shape (from outside, or `inside`) may leave
    /// the shape itself out of its shadow test: exact for flat shapes on
    /// both sides and for convex ones hit from outside.
    #[inline]
    pub fn skips_itself(&self, inside: bool) -> bool {
        self.flat() || (self.convex() && !inside)
    }
}

/// The first of `near <= far` (entry and exit of a convex shape) inside
/// (0, t_max): the entry, or the exit for a ray starting inside.
#[inline]
fn first_in_range(near: f64, far: f64, t_max: f64) -> Option<f64> {
    if near > 0.0 && near < t_max {
        Some(near)
    } else if far > 0.0 && far < t_max {
        Some(far)
    } else {
        None
    }
}
