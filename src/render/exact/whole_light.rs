//! Points that see all of the light above their horizon (no occluder cuts
//! it, no plane clips it): the most common kind in a lit room. Their two
//! integrals are over the light's whole rectangle, so several such points
//! are taken side by side ([`WholeLights`]): their diffuse edge sums in
//! one set of vector lanes, their specular lobes' root cells in another.
//! Each lane does what the point alone would do, so every factor keeps its
//! bits; a point whose cubature would go beyond its root cell takes the
//! one-point path.

use glam::DVec2;

use super::cubature::{
    CubatureReport, LightSpan, Lobe, WHOLE_LANES, specular_factor, whole_light_specular,
};
use super::diffuse::{RECTS, edge_sum, rect_edge_sums};
use super::polygon::twice_area;
use super::{ExactFactors, ExactScratch};

/// Points taken side by side.
const WHOLE_POINTS: usize = if RECTS < WHOLE_LANES {
    RECTS
} else {
    WHOLE_LANES
};

/// A point that sees the whole light above its horizon: what its factors
/// need.
#[derive(Debug, Clone, Copy, Default)]
pub struct WholeLight {
    /// The light in the plane's coordinates seen from the point, and the
    /// diffuse integrand's (a, b, h) there (see `diffuse.rs`).
    pub(super) rect: [DVec2; 4],
    pub(super) a: DVec2,
    pub(super) b: f64,
    pub(super) h: f64,
    /// The light's area.
    pub(super) area: f64,
    /// The specular lobe, if the factor is asked for.
    pub(super) lobe: Option<Lobe>,
    pub(super) span: LightSpan,
}

impl WholeLight {
    /// The factors, one point alone. Not inlined: the hit loops that may
    /// call it stay as small as the other models' need.
    #[inline(never)]
    pub fn factors(&self, s: &mut ExactScratch) -> ExactFactors {
        let mut out = self.with_diffuse(edge_sum(&self.rect, self.a, self.b, self.h));
        if let Some(lobe) = &self.lobe {
            (out.specular, out.cubature) = self.specular_alone(lobe, s);
        }
        out
    }

    /// The factors with the light's edge sum `sum`, the specular factor
    /// not yet taken.
    fn with_diffuse(&self, sum: f64) -> ExactFactors {
        // As `diffuse_over_pieces` sums its one piece.
        let sum: f64 = std::iter::once(sum).sum();
        ExactFactors {
            diffuse: (sum / self.area).clamp(0.0, 1.0),
            pieces: 1,
            ..ExactFactors::default()
        }
    }

    /// The light's corners in its (a, b) coordinates (the unit square, to
    /// rounding).
    fn light_ab(&self) -> [DVec2; 4] {
        self.rect.map(super::to_ab(&self.rect))
    }

    /// The visible area in the (a, b) coordinates, as [`Pieces::area`]
    /// gives it for the light's square.
    ///
    /// [`Pieces::area`]: super::polygon::Pieces::area
    fn visible(&self) -> f64 {
        std::iter::once(twice_area(&self.light_ab())).sum::<f64>() * 0.5
    }

    fn specular_alone(&self, lobe: &Lobe, s: &mut ExactScratch) -> (f64, CubatureReport) {
        s.ab.clear();
        s.ab.verts.extend_from_slice(&self.light_ab());
        s.ab.ends.push(4);
        let (value, report) = specular_factor(lobe, &self.span, &s.ab, &mut s.cubature);
        (value.clamp(0.0, 1.0), report)
    }
}

/// Points of [`WholeLight`] waiting to be taken side by side, each with
/// its caller's tag.
#[derive(Debug, Default)]
pub struct WholeLights {
    waiting: Vec<(u32, WholeLight)>,
}

impl WholeLights {
    /// Adds the point [`exact_step`](super::exact_step) left in `s`; true
    /// when the lanes are full (time to [`flush`](WholeLights::flush)).
    pub fn push(&mut self, tag: u32, s: &ExactScratch) -> bool {
        self.waiting.push((tag, s.whole));
        self.waiting.len() >= WHOLE_POINTS
    }

    /// Forgets the waiting points (a cancelled tile).
    pub fn clear(&mut self) {
        self.waiting.clear();
    }

    /// The factors of the waiting points, each handed to `each` with its
    /// tag (the same bits as [`WholeLight::factors`] of each).
    pub fn flush(&mut self, s: &mut ExactScratch, mut each: impl FnMut(u32, ExactFactors)) {
        for batch in self.waiting.chunks(WHOLE_POINTS) {
            let mut sums = [0.0; RECTS];
            rect_edge_sums(
                batch.len(),
                |i| {
                    let w = &batch[i].1;
                    (&w.rect, w.a, w.b, w.h)
                },
                &mut sums,
            );
            // The lobes asked for, and whose point each is.
            let none = Lobe::default();
            let mut lobes = [(&none, 0.0); WHOLE_LANES];
            let mut of = [0; WHOLE_LANES];
            let mut count = 0;
            for (i, (_, w)) in batch.iter().enumerate() {
                if let Some(lobe) = &w.lobe {
                    (lobes[count], of[count]) = ((lobe, w.visible()), i);
                    count += 1;
                }
            }
            let mut taken = [None; WHOLE_LANES];
            // One tile's points: one light, one span.
            whole_light_specular(&batch[0].1.span, &lobes[..count], &mut taken);
            let mut specular = [None; WHOLE_POINTS];
            for (&i, taken) in of[..count].iter().zip(taken) {
                specular[i] = taken.map(|(value, report)| (value.clamp(0.0, 1.0), report));
            }
            for (i, (tag, w)) in batch.iter().enumerate() {
                let mut out = w.with_diffuse(sums[i]);
                if let Some(lobe) = &w.lobe {
                    (out.specular, out.cubature) = match specular[i] {
                        Some(taken) => taken,
                        None => w.specular_alone(lobe, s),
                    };
                }
                each(*tag, out);
            }
        }
        self.waiting.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::WholeLights;
    use crate::render::exact::{
        CircleFit, ExactPoint, ExactScratch, ExactStep, exact_factors, exact_step,
    };
    use crate::render::scene::Loaded;
    use glam::DVec3;

    /// Points of the seed room's floor and walls, some in the boxes' and
    /// the sphere's shadows, some that see the whole light, a few without
    /// the specular factor: those left whole and taken side by side get
    /// the bits (and reports) of [`exact_factors`] of each alone.
    #[test]
    fn whole_lights_side_by_side_give_each_point_s_factors() {
        let room = Loaded::seed_room();
        let scene = &room.scene;
        let camera = DVec3::new(0.0, 4.0, -14.0);
        let mut points = Vec::new();
        for i in 0..40 {
            for j in 0..30 {
                let (u, w) = (-4.9 + 9.8 * i as f64 / 39.0, -4.9 + 9.8 * j as f64 / 29.0);
                let (y, z) = (0.1 + 7.8 * j as f64 / 29.0, w);
                for (p, n) in [
                    (DVec3::new(u, 0.0, z), DVec3::Y),
                    (DVec3::new(u, y, 5.0), DVec3::NEG_Z),
                    (DVec3::new(-5.0, y, w), DVec3::X),
                ] {
                    points.push(ExactPoint {
                        shadow_point: p,
                        normal: n,
                        geometric: n,
                        view: (camera - p).normalize(),
                        shininess: [20.0, 100.0, 500.0][(i + j) % 3],
                        object: u32::MAX,
                        inside: false,
                        shadows: true,
                    });
                }
            }
        }
        let mut s = ExactScratch::default();
        let mut lights = WholeLights::default();
        let mut got = vec![None; points.len()];
        let (mut whole, mut done) = (0, 0);
        for (k, p) in points.iter().enumerate() {
            let specular = k % 7 != 0;
            match exact_step(scene, p, specular, CircleFit::SameArea, &mut s) {
                Ok(ExactStep::Whole) => {
                    whole += 1;
                    if lights.push(k as u32, &s) {
                        lights.flush(&mut s, |i, f| got[i as usize] = Some(f));
                    }
                }
                Ok(ExactStep::Done(f)) => {
                    done += 1;
                    got[k] = Some(f);
                }
                Err(e) => panic!("point {k} fell back: {e:?}"),
            }
        }
        lights.flush(&mut s, |i, f| got[i as usize] = Some(f));
        assert!(whole > 1000 && done > 300, "{whole} {done}");
        for (k, p) in points.iter().enumerate() {
            let specular = k % 7 != 0;
            let want = exact_factors(scene, p, specular, CircleFit::SameArea, &mut s)
                .expect("no fallback");
            let got = got[k].expect("every point's factors");
            let bits = |f: &crate::render::exact::ExactFactors| {
                (
                    f.diffuse.to_bits(),
                    f.specular.to_bits(),
                    f.pieces,
                    f.cubature.cells,
                    f.cubature.error.to_bits(),
                )
            };
            assert_eq!(bits(&got), bits(&want), "point {k}: {:?}", p.shadow_point);
        }
    }
}
