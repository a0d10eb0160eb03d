//! What is seen: rays, primitives, bounds and the BVH, all in f64 world
//! space so that a room far from the origin or at any scale keeps its
//! precision. (Shadow rays use a faster f32 form relative to the hit point,
//! see `shadow/`.)

mod aabb;
mod bvh;
mod bvh4;
mod cuboid;
mod offset;
mod parallelogram;
mod plane;
mod ray;
mod sphere;

pub use aabb::Aabb;
pub use bvh::{Bvh, NodeContent};
pub use bvh4::{Bvh4, Node4, Slot};
pub use cuboid::Cuboid;
pub use offset::spawn_origin;
pub use parallelogram::Parallelogram;
pub use plane::Plane;
pub use ray::Ray;
pub use sphere::Sphere;

use glam::DVec3;

/// One primitive of the scene.
#[derive(Debug, Clone)]
pub enum Shape {
    Plane(Plane),
    Parallelogram(Parallelogram),
    Cuboid(Cuboid),
    Sphere(Sphere),
}

/// Where a ray meets a surface.
#[derive(Debug, Clone, Copy)]
pub struct SurfacePoint {
    /// The hit point, re-projected onto the surface to cut rounding error.
    pub point: DVec3,
    /// Unit outward (geometric) normal; not yet flipped towards the ray.
    pub normal: DVec3,
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
        }
    }

    /// The surface point and normal of a hit found by [`Shape::intersect`].
    pub fn surface(&self, ray: &Ray, t: f64) -> SurfacePoint {
        match self {
            Shape::Plane(s) => s.surface(ray, t),
            Shape::Parallelogram(s) => s.surface(ray, t),
            Shape::Cuboid(s) => s.surface(ray, t),
            Shape::Sphere(s) => s.surface(ray, t),
        }
    }

    /// Bounds, or `None` for an infinite plane.
    pub fn bounds(&self) -> Option<Aabb> {
        match self {
            Shape::Plane(_) => None,
            Shape::Parallelogram(s) => Some(s.bounds()),
            Shape::Cuboid(s) => Some(s.bounds()),
            Shape::Sphere(s) => Some(s.bounds()),
        }
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
