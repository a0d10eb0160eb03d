//! What a render is asked to do: the scene file's `render` section as the
//! tracer reads it. Editing any of it never rebuilds the scene.

use glam::{DVec3, Vec3};

use super::pixel_filter::FilterKind;
use super::scene_file::{AreaLightModel, Sampling, SceneDesc};

/// Settings of one render, from the scene's `render` section.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderSettings {
    /// Shadow rays asked for per hit point (`sampling::points_per_hit` is
    /// how many the pattern casts).
    pub shadow_rays: u32,
    pub sampling: Sampling,
    pub max_depth: u32,
    pub seed: u64,
    /// The seed that scrambles the camera samples' places in each pixel
    /// (with several samples): `seed`, but for a reference, which keeps
    /// the compared image's so that both sample the same places and their
    /// difference is the light's alone.
    pub camera_seed: u64,
    pub model: AreaLightModel,
    /// Multipliers of the ambient, diffuse and specular terms.
    pub terms: Vec3,
    pub background: Vec3,
    /// `false`: every shadow ray arrives.
    pub shadows: bool,
    /// Trace a few shadow rays first and the rest only where they disagree
    /// (faster, biased).
    pub adaptive: bool,
    /// Camera rays (only they) pass through planes seen from behind.
    pub cutaway: bool,
    /// Skip work whose result is known (exact; see `shadow/`). Only
    /// switched off to measure what the skipping saves.
    pub skip: bool,
    /// Camera samples per pixel; 1: one ray through the pixel centre.
    pub samples_per_pixel: u32,
    /// How samples are placed and weighed when there are several.
    pub filter: FilterKind,
}

impl RenderSettings {
    pub fn from_desc(desc: &SceneDesc) -> RenderSettings {
        let r = &desc.render;
        RenderSettings {
            shadow_rays: r.shadow_rays,
            sampling: r.sampling,
            max_depth: r.max_depth,
            seed: r.seed,
            camera_seed: r.seed,
            model: r.area_light_model,
            terms: Vec3::new(
                r.terms.ambient as f32,
                r.terms.diffuse as f32,
                r.terms.specular as f32,
            ),
            background: DVec3::from(r.background).as_vec3(),
            shadows: r.shadows,
            adaptive: r.adaptive,
            cutaway: r.cutaway,
            skip: true,
            samples_per_pixel: r.samples_per_pixel,
            filter: FilterKind::DEFAULT,
        }
    }
}
