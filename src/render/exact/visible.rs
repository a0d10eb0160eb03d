//! The visible part of the light from one shadow point: the light's
//! rectangle in front of the surface, cut by the planes that hide part of
//! it, minus the union of the other occluders' shadows, as convex pieces.

use glam::DVec2;

use super::conic::ConicShadow;
use super::polygon::{HalfPlane, Pieces, Work, merge_close_vertices};
use super::projection::{
    CircleFit, LightView, ProjectScratch, Unsupported, box_shadow, rect_shadow, sphere_shadow,
    triangle_shadow,
};
use crate::render::geometry::{Primitive, Shape, Sphere};
use crate::render::scene::Scene;

/// Edges of a sphere's silhouette polygon where its diffuse factor is the
/// polygon's (see [`CONIC_SPHERE_EDGES`] for elsewhere).
pub const SPHERE_EDGES: usize = 128;

/// Edges of the same-area polygon of the one sphere whose diffuse factor
/// the conic gives (`conic.rs`): the polygon then only shapes the pieces of
/// the specular cubature, whose tolerance is 1e-4, and the same-area
/// polygon's error falls as N⁻⁴ (the specular factor of
/// `tests/exact_shadows.rs`'s sphere penumbrae within 5e-6 of a dense
/// integration at 64 edges, 1e-6 at 128, 9e-5 at 32). Half the edges,
/// half the pieces the polygon cuts the light into.
pub const CONIC_SPHERE_EDGES: usize = 64;

/// Occluding triangles in a hit point's pyramid above which the exact model
/// stops (each adds a shadow to subtract, and the pieces multiply): the
/// hit point falls back to the `analytic` estimate.
pub const MAX_TRIANGLES: usize = 48;

/// Visible pieces above which the hit point falls back likewise.
pub const MAX_PIECES: usize = 4096;

/// Why a hit point falls back to the `analytic` estimate.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fallback {
    Unsupported(Unsupported),
    TooManyTriangles,
    TooManyPieces,
    /// A light smaller than [`TINY_LIGHT`] of its height above the point:
    /// the frustum's planes lose their digits (a known defect, left for
    /// later), and the `analytic` estimate is exact wherever such a
    /// near-point light is wholly visible or hidden.
    TinyLight,
}

/// See [`Fallback::TinyLight`].
pub const TINY_LIGHT: f64 = 1e-4;

/// Scratch of [`visible_region`], and what it leaves for the diffuse
/// factor of spheres.
#[derive(Debug, Clone, Default)]
pub struct RegionScratch {
    pub work: Work,
    pub project: ProjectScratch,
    pub shadow: Vec<DVec2>,
    /// The spheres whose polygons were subtracted (last, after every other
    /// occluder), and the pieces before the first of them.
    pub spheres: Vec<Sphere>,
    pub before_spheres: Pieces,
}

/// The visible part of the light into `pieces` (the plane's coordinates of
/// `view`): the rectangle where `front` ≥ 0, minus what the `occluders`
/// (object index, and whether the point is inside it) hide.
pub fn visible_region(
    scene: &Scene,
    view: &LightView,
    front: HalfPlane,
    occluders: &[(u32, bool)],
    sphere: CircleFit,
    pieces: &mut Pieces,
    s: &mut RegionScratch,
) -> Result<(), Fallback> {
    // Pieces thinner than the rounding of the coordinates are dropped
    // (twice their area is below this).
    let magnitude = view
        .rect
        .iter()
        .map(|p| p.abs().max_element())
        .fold(0.0, f64::max);
    let min_area = (2e-14 * view.area).max(64.0 * f64::EPSILON * magnitude * view.side);
    pieces.clear();
    pieces.push(&view.rect, 0.0);
    pieces.clip(front, min_area, &mut s.work);
    if occluders.iter().any(|&(_, inside)| inside) {
        return Err(Fallback::Unsupported(Unsupported::Inside));
    }
    let triangles = occluders
        .iter()
        .filter(|&&(i, _)| {
            matches!(
                scene.primitive(i),
                Primitive::Shape(Shape::Triangle(_)) | Primitive::Face { .. }
            )
        })
        .count();
    if triangles > MAX_TRIANGLES {
        return Err(Fallback::TooManyTriangles);
    }
    s.spheres.clear();
    s.before_spheres.clear();
    // Umbra first: one box or sphere that hides the whole light spares
    // projecting and subtracting every shadow.
    let hides = |&(i, _): &(u32, bool)| match scene.primitive(i) {
        Primitive::Shape(Shape::Cuboid(c)) => view.box_hides_light(c),
        Primitive::Shape(Shape::Sphere(sp)) => view.sphere_hides_light(sp),
        _ => false,
    };
    if occluders.iter().any(hides) {
        pieces.clear();
        return Ok(());
    }
    // Planes first: a clip is cheaper than a subtraction, and it leaves
    // fewer pieces to subtract from.
    for &(i, _) in occluders {
        if pieces.is_empty() {
            return Ok(());
        }
        if let Primitive::Shape(Shape::Plane(pl)) = scene.primitive(i)
            && let Some(h) = view.plane_clear(pl)
        {
            pieces.clip(h, min_area, &mut s.work);
        }
    }
    // Spheres last, so that the pieces before them are what the diffuse
    // factor's conics are cut from.
    let is_sphere = |i: u32| matches!(scene.primitive(i), Primitive::Shape(Shape::Sphere(_)));
    let others = occluders.iter().filter(|&&(i, _)| !is_sphere(i));
    let spheres = occluders.iter().filter(|&&(i, _)| is_sphere(i));
    let mut first_sphere = true;
    // The conic gives the diffuse factor of one sphere alone (two may
    // overlap) whose silhouette stays below q's plane.
    let alone = || spheres.clone().count() == 1;
    let edges = |sp: &Sphere| match sphere {
        CircleFit::SameArea if alone() && ConicShadow::new(view, sp).is_some() => {
            CONIC_SPHERE_EDGES
        }
        _ => SPHERE_EDGES,
    };
    for &(i, _) in others.chain(spheres.clone()) {
        if pieces.is_empty() {
            return Ok(());
        }
        let shadow = &mut s.shadow;
        if let Primitive::Shape(Shape::Sphere(sp)) = scene.primitive(i) {
            if first_sphere {
                s.before_spheres.clone_from(pieces);
                first_sphere = false;
            }
            s.spheres.push(sp.clone());
        }
        match scene.primitive(i) {
            Primitive::Shape(Shape::Plane(_)) => continue,
            Primitive::Shape(Shape::Cuboid(c)) => box_shadow(view, c, &mut s.project, shadow),
            Primitive::Shape(Shape::Parallelogram(r)) => {
                rect_shadow(view, r, &mut s.project, shadow);
                Ok(())
            }
            Primitive::Shape(Shape::Triangle(t)) => {
                triangle_shadow(view, t.vertices(), &mut s.project, shadow);
                Ok(())
            }
            Primitive::Face { meshes, face } => {
                triangle_shadow(view, meshes.vertices(face), &mut s.project, shadow);
                Ok(())
            }
            Primitive::Shape(Shape::Sphere(sp)) => {
                sphere_shadow(view, sp, edges(sp), sphere, &mut s.project, shadow)
            }
        }
        .map_err(Fallback::Unsupported)?;
        merge_close_vertices(shadow);
        if shadow.len() >= 3 {
            pieces.subtract(shadow, min_area, &mut s.work);
        }
        if pieces.len() > MAX_PIECES {
            return Err(Fallback::TooManyPieces);
        }
    }
    Ok(())
}
