//! Per-thread buffers of one hit point's shadow rays.

use super::cells::OccluderCells;
use super::packet::PacketScratch;
use super::ray_packet::{PACKET, RayBins};
use super::visibility::Candidate;
use crate::render::exact::ExactScratch;
use crate::render::scene::Scene;
use crate::render::scene_file::Sampling;

/// Per-thread buffers for one hit point's light points, reused from hit to
/// hit so that the hot loop never allocates.
#[derive(Debug, Default)]
pub struct ShadowBuffers {
    /// Light points in the light's (a, b) coordinates.
    pub a: Vec<f32>,
    pub b: Vec<f32>,
    /// Unnormalized directions from the hit point to the light points.
    pub dx: Vec<f32>,
    pub dy: Vec<f32>,
    pub dz: Vec<f32>,
    /// 1 where the light point is visible, 0 where it is blocked.
    pub vis: Vec<f32>,
    /// Per-point diffuse and specular contributions (shading scratch).
    pub term_d: Vec<f32>,
    pub term_s: Vec<f32>,
    /// Per-point unshadowed diffuse factor (the ratio estimator's weights).
    pub term_f: Vec<f32>,
    /// The fixed pattern whose points `a` and `b` already hold, if any.
    pub filled: Option<(Sampling, u32)>,
    pub(super) occluders: Vec<Candidate>,
    /// The objects that may block shadow rays from each small cube of
    /// space.
    pub(super) cells: OccluderCells,
    /// The light points binned per packet of 64 rays, and the fixed pattern
    /// they were binned for (a pattern drawn per hit point is binned anew).
    pub(super) bins: Vec<RayBins>,
    pub(super) bins_for: Option<(Sampling, u32)>,
    pub(super) scratch: PacketScratch,
    /// The `exact` model's polygons and cubature.
    pub(crate) exact: ExactScratch,
}

impl ShadowBuffers {
    /// Buffers for up to `points` light points. Lengths are rounded up to a
    /// multiple of 8 and the padding holds invisible points at a finite
    /// direction, so that vector loops may run over whole chunks.
    pub fn with_capacity(points: usize) -> ShadowBuffers {
        let len = points.next_multiple_of(8).max(8);
        let v = |x: f32| vec![x; len];
        ShadowBuffers {
            a: v(0.0),
            b: v(0.0),
            dx: v(0.0),
            dy: v(1.0),
            dz: v(0.0),
            vis: v(0.0),
            term_d: v(0.0),
            term_s: v(0.0),
            term_f: v(0.0),
            filled: None,
            occluders: Vec::with_capacity(16),
            cells: OccluderCells::kept(),
            bins: Vec::with_capacity(points.div_ceil(PACKET)),
            bins_for: None,
            scratch: PacketScratch::default(),
            exact: ExactScratch::default(),
        }
    }

    /// Before the hit points of one tile (all of `scene`, which the caller
    /// holds borrowed until [`Self::end_tile`]): the occluder lists are
    /// checked against the scene once instead of at every hit point.
    pub(crate) fn start_tile(&mut self, scene: &Scene) {
        self.cells.check_for(scene);
    }

    pub(crate) fn end_tile(&mut self) {
        self.cells.forget_check();
    }
}

impl Drop for ShadowBuffers {
    /// The occluder lists stay with the thread, for its next render.
    fn drop(&mut self) {
        std::mem::take(&mut self.cells).keep();
    }
}
