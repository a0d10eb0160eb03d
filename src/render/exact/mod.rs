//! The `exact` area-light model: the visible part of the light, without
//! sampling.
//!
//! Every other model estimates the average over the light's area of
//! visibility × the Phong factor. Here, from each shadow point:
//! 1. the occluders are those the shadow rays' culling keeps (objects whose
//!    bounds meet the pyramid from the point to the light);
//! 2. each one's shadow on the light's plane is projected from the point
//!    (`projection.rs`: boxes, rects and triangles exactly as convex
//!    polygons, spheres as the polygon of their silhouette);
//! 3. the visible region is the light in front of the surface, cut by the
//!    planes and minus the shadows, as convex pieces (`visible.rs`,
//!    `polygon.rs`);
//! 4. the diffuse factor max(0, N·L) is integrated over the pieces in
//!    closed form (the edge sums of `analytic.rs` along the outline of the
//!    pieces, `diffuse.rs`), with spheres' shadows as the conics they are
//!    (`conic.rs`: over the pieces before the spheres were subtracted,
//!    minus each sphere's part, whose arcs are integrated by an adaptive
//!    Gauss–Legendre rule), the specular factor max(0, N·H)^s by an
//!    adaptive cubature with an error estimate below 1e-4 (`cubature.rs`);
//! 5. a point that sees the whole light above its horizon (most points of
//!    a lit room) is left to its caller at step 4 ([`ExactStep::Whole`]):
//!    a tile takes several such points' integrals side by side
//!    (`whole_light.rs`), each lane doing what the point alone would, so
//!    the factors keep their bits.
//!
//! It is the integrand of `sampled` — the same directions (from the shadow
//! point), the same visibility test (blocked at t in (0, `RAY_END`), light
//! points behind the geometric normal hidden), the same factors — so
//! `sampled` with many rays converges to it.
//!
//! Limits (the hit point then falls back to the `analytic` model's estimate
//! with the scene's shadow rays, counted in `RayStats::exact_fallbacks`): a
//! point inside an occluder (hit from inside), a sphere reaching within
//! 10⁻⁴ of the ray's length of the light's plane, more than
//! [`MAX_TRIANGLES`] triangles in the pyramid, more than [`MAX_PIECES`]
//! visible pieces, a light smaller than [`TINY_LIGHT`] of its height above
//! the point. Spheres: the visible pieces and the specular factor use the
//! polygon with the silhouette's area (the inscribed and circumscribed
//! polygons bracket the exact value); the diffuse factor uses the conic,
//! within 1e-6 relative of a dense integration (measured ~1e-9,
//! `tests/exact_shadows.rs`), except where two spheres' shadow cones may
//! overlap or a silhouette reaches within 10⁻³ of the light's height of
//! q's plane: there the polygon's value stands, and the polygon has
//! [`SPHERE_EDGES`] edges; elsewhere [`CONIC_SPHERE_EDGES`] (only the
//! specular factor sees it).

mod conic;
mod cubature;
mod diffuse;
mod polygon;
mod projection;
mod visible;
mod whole_light;

use glam::{DVec2, DVec3};

pub use cubature::{CubatureReport, TOLERANCE};
pub use projection::{CircleFit, Unsupported};
pub use visible::{
    CONIC_SPHERE_EDGES, Fallback, MAX_PIECES, MAX_TRIANGLES, SPHERE_EDGES, TINY_LIGHT,
};
pub use whole_light::{WholeLight, WholeLights};

use conic::{ArcScratch, ConicShadow};
use cubature::{CubatureScratch, LightSpan, Lobe, specular_factor};
use diffuse::{Outline, diffuse_over_pieces, small_light};
use polygon::{HalfPlane, Pieces, twice_area};
use projection::{LightFrame, LightView};
use visible::{RegionScratch, visible_region};

use crate::render::scene::Scene;
use crate::render::shadow::{OccluderCells, ShadowQuery, possible_occluders};

/// A hit point as the exact model sees it.
#[derive(Debug, Clone, Copy)]
pub struct ExactPoint {
    /// Where the shadow rays start (the shading point, lifted on smooth
    /// triangles).
    pub shadow_point: DVec3,
    /// Unit shading normal (the factors' N).
    pub normal: DVec3,
    /// Unit geometric normal: light points behind it are hidden.
    pub geometric: DVec3,
    /// Unit direction to the viewer.
    pub view: DVec3,
    pub shininess: f64,
    /// The hit object (left out of its own shadow test as the shadow rays
    /// do), `u32::MAX` for none.
    pub object: u32,
    pub inside: bool,
    /// `false`: shadows are off (`render.shadows`), only the surface's own
    /// horizon hides part of the light.
    pub shadows: bool,
}

/// The exact light factors of one point.
#[derive(Debug, Clone, Copy, Default)]
pub struct ExactFactors {
    /// Average over the light's area of visibility × max(0, N·L).
    pub diffuse: f64,
    /// Average of visibility × max(0, N·H)^s (0 unless asked for).
    pub specular: f64,
    /// Visible pieces.
    pub pieces: usize,
    pub cubature: CubatureReport,
}

/// Scratch of the exact model (one per thread, kept warm).
#[derive(Debug, Default)]
pub struct ExactScratch {
    /// The frame of the last light seen, and its span for the cubature.
    frame: Option<(LightFrame, LightSpan)>,
    /// The objects that may block a shadow ray from each small cube of
    /// space (the shadow rays' own lists, kept here for the exact model).
    cells: OccluderCells,
    occluders: Vec<(u32, bool)>,
    pieces: Pieces,
    lit: Pieces,
    ab: Pieces,
    region: RegionScratch,
    cubature: CubatureScratch,
    conics: Vec<ConicShadow>,
    arcs: ArcScratch,
    before: Pieces,
    outline: Outline,
    /// The point [`exact_step`] last left to its caller.
    whole: WholeLight,
}

/// The diffuse integral with the spheres' shadows as their conics: over
/// the pieces before the spheres (clipped to the horizon) minus each
/// sphere's part of them, or `None` where there is no sphere, or the conic
/// cannot stand in for the polygon (a silhouette near q's plane, shadows
/// of two spheres that may overlap).
fn conic_diffuse(view: &LightView, a: DVec2, b: f64, h: f64, s: &mut ExactScratch) -> Option<f64> {
    let spheres = &s.region.spheres;
    if spheres.is_empty() {
        return None;
    }
    s.conics.clear();
    for sp in spheres {
        s.conics.push(ConicShadow::new(view, sp)?);
    }
    for (i, c) in s.conics.iter().enumerate() {
        if s.conics[..i].iter().any(|o| !c.disjoint(o)) {
            return None;
        }
    }
    s.before.clone_from(&s.region.before_spheres);
    s.before
        .clip(HalfPlane { n: a, c: b }, 0.0, &mut s.region.work);
    let mut total = diffuse_over_pieces(&s.before, &view.rect, a, b, h, &mut s.outline);
    for poly in s.before.iter() {
        for c in &s.conics {
            total -= c.diffuse_inside(poly, a, b, view.area, &mut s.arcs);
        }
    }
    Some(total)
}

/// The exact factors of `p`, or why the point falls back. `specular`:
/// whether to compute the specular factor (the costly one).
pub fn exact_factors(
    scene: &Scene,
    p: &ExactPoint,
    specular: bool,
    sphere: CircleFit,
    s: &mut ExactScratch,
) -> Result<ExactFactors, Fallback> {
    Ok(match exact_step(scene, p, specular, sphere, s)? {
        ExactStep::Done(factors) => factors,
        ExactStep::Whole => s.whole_point().factors(s),
    })
}

/// What [`exact_step`] leaves of a point.
#[derive(Debug, Clone, Copy)]
pub enum ExactStep {
    Done(ExactFactors),
    /// A point that sees the whole light above its horizon, left in the
    /// scratch: its integrals over the whole rectangle, which
    /// [`WholeLights`] takes for several points side by side
    /// ([`WholeLight::factors`] for one).
    Whole,
}

impl ExactScratch {
    /// The point [`exact_step`] last left as [`ExactStep::Whole`].
    pub fn whole_point(&self) -> WholeLight {
        self.whole
    }
}

/// [`exact_factors`] up to the integrals of a point that sees the whole
/// light, left to the caller.
pub fn exact_step(
    scene: &Scene,
    p: &ExactPoint,
    specular: bool,
    sphere: CircleFit,
    s: &mut ExactScratch,
) -> Result<ExactStep, Fallback> {
    let light = &scene.light.shape;
    let (frame, span) = match &s.frame {
        Some((f, span)) if f.is_of(light) => (f, *span),
        _ => {
            let f = LightFrame::new(light);
            let (edge_u, edge_v) = f.edges();
            let (f, span) = s.frame.insert((f, LightSpan::new(edge_u, edge_v)));
            (&*f, *span)
        }
    };
    let Some(view) = LightView::new(light, frame, p.shadow_point) else {
        return Ok(ExactStep::Done(ExactFactors::default()));
    };
    if view.side < TINY_LIGHT * view.h {
        return Err(Fallback::TinyLight);
    }
    let query = ShadowQuery {
        point: p.shadow_point,
        normal: p.geometric,
        object: p.object,
        inside: p.inside,
    };
    s.occluders.clear();
    if p.shadows {
        possible_occluders(scene, &query, &mut s.cells, &mut s.occluders);
    }
    let front = view.front_of(p.geometric);
    let n = view.local_dir(p.normal);
    let (a, b, h) = (DVec2::new(n.x, n.y), -view.h * n.z, -view.h);
    let horizon = HalfPlane { n: a, c: b };
    // Nothing in the pyramid and the whole light in front of the surface
    // and above its horizon (most points of a lit room): the region would
    // be the light's rectangle as it is (a clip that keeps every corner
    // keeps the piece), so it is not built.
    if s.occluders.is_empty()
        && view
            .rect
            .iter()
            .all(|&y| front.eval(y) >= 0.0 && horizon.eval(y) >= 0.0)
        && twice_area(&view.rect) > 0.0
        && !small_light(&view.rect, h)
    {
        s.whole = whole_light(&view, a, b, h, n, p, specular, span);
        return Ok(ExactStep::Whole);
    }
    visible_region(
        scene,
        &view,
        front,
        &s.occluders,
        sphere,
        &mut s.pieces,
        &mut s.region,
    )?;
    let mut out = ExactFactors {
        pieces: s.pieces.len(),
        ..ExactFactors::default()
    };
    if s.pieces.is_empty() {
        return Ok(ExactStep::Done(out));
    }

    // Diffuse: (1/A) ∫ max(0, N·L) over the pieces, each clipped to the
    // shading normal's horizon where N·L ≥ 0.
    // Pieces wholly above the horizon (on a flat surface the front's clip
    // made them so) are lit as they are: no copy to clip (the clip would
    // keep them).
    let all_lit = s.pieces.verts.iter().all(|&y| horizon.eval(y) >= 0.0);
    if !all_lit {
        s.lit.clone_from(&s.pieces);
        s.lit.clip(horizon, 0.0, &mut s.region.work);
    }
    // The whole light, above the horizon, with no sphere's conic to take
    // and not small against its distance (`diffuse_over_pieces` then takes
    // the rectangle's edge sum).
    if all_lit
        && s.pieces.len() == 1
        && s.pieces.piece(0) == view.rect
        && s.region.spheres.is_empty()
        && !small_light(&view.rect, h)
    {
        s.whole = whole_light(&view, a, b, h, n, p, specular, span);
        return Ok(ExactStep::Whole);
    }
    let conic = match sphere {
        CircleFit::SameArea => conic_diffuse(&view, a, b, h, s),
        _ => None,
    };
    let lit = if all_lit { &s.pieces } else { &s.lit };
    let diffuse =
        conic.unwrap_or_else(|| diffuse_over_pieces(lit, &view.rect, a, b, h, &mut s.outline));
    out.diffuse = (diffuse / view.area).clamp(0.0, 1.0);

    if specular {
        s.ab.clear();
        let to_ab = to_ab(&view.rect);
        for poly in s.pieces.iter() {
            s.ab.verts.extend(poly.iter().map(|&y| to_ab(y)));
            s.ab.ends.push(s.ab.verts.len());
        }
        let lobe = lobe_of(&view, n, p);
        let (value, report) = specular_factor(&lobe, &span, &s.ab, &mut s.cubature);
        out.specular = value.clamp(0.0, 1.0);
        out.cubature = report;
    }
    Ok(ExactStep::Done(out))
}

/// What a point that sees the whole light leaves to [`WholeLights`]: the
/// light seen from it, the diffuse integrand's (a, b, h), and its lobe if
/// the specular factor is asked for (`n`: the shading normal in the
/// light's frame).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn whole_light(
    view: &LightView,
    a: DVec2,
    b: f64,
    h: f64,
    n: DVec3,
    p: &ExactPoint,
    specular: bool,
    span: LightSpan,
) -> WholeLight {
    WholeLight {
        rect: view.rect,
        a,
        b,
        h,
        area: view.area,
        lobe: specular.then(|| lobe_of(view, n, p)),
        span,
    }
}

/// The map from the light's plane to the light's (a, b) coordinates, the
/// light `rect` seen in the plane: y = corner + a u + b v (its edges and
/// determinant taken once).
#[inline]
fn to_ab(rect: &[DVec2; 4]) -> impl Fn(DVec2) -> DVec2 {
    let (u, v) = (rect[1] - rect[0], rect[3] - rect[0]);
    let det = u.perp_dot(v);
    let o = rect[0];
    move |y| {
        let d = y - o;
        DVec2::new(d.perp_dot(v) / det, u.perp_dot(d) / det)
    }
}

/// The specular lobe of `p` (shading normal `n` in the light's frame).
fn lobe_of(view: &LightView, n: DVec3, p: &ExactPoint) -> Lobe {
    Lobe {
        n,
        v: view.local_dir(p.view),
        shininess: p.shininess,
        corner: view.corner,
        edge_u: view.edge_u,
        edge_v: view.edge_v,
    }
}
