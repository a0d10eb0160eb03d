//! The converged reference of a scene: what the benchmark's errors and the
//! viewer's error readout are measured against. One definition for both.

use super::error::SceneError;
use super::scene::Loaded;
use super::scene_file::{AreaLightModel, Sampling, SceneDesc};

/// Shadow rays per hit point of a reference unless told otherwise (the
/// format's largest count).
pub const REFERENCE_RAYS: u32 = 4096;

/// Its pattern: one jittered point per cell of a 64×64 grid.
pub const REFERENCE_SAMPLING: Sampling = Sampling::Stratified;

/// The reference's seed: fixed, so a reference does not depend on the
/// seed of the image compared with it, and unlike the default seed 1, so
/// that its random numbers are not that image's.
pub const REFERENCE_SEED: u64 = 0x7265_6665_7265_6e63;

/// The scene as its reference renders it: the same scene, size and depth
/// under `model`, at `rays` stratified shadow rays with the reference seed,
/// adaptive rays off (the converged answer is the unbiased one).
pub fn reference_desc(desc: &SceneDesc, model: AreaLightModel, rays: u32) -> SceneDesc {
    let mut d = desc.clone();
    d.render.sampling = REFERENCE_SAMPLING;
    d.render.shadow_rays = rays;
    d.render.seed = REFERENCE_SEED;
    d.render.area_light_model = model;
    d.render.adaptive = false;
    d
}

/// The runtime scene of `reference` (a [`reference_desc`], its seed
/// perhaps changed) as the reference of the image of `image`: with several
/// camera samples a pixel they lie where the image's do, scrambled by the
/// image's seed, so that the two differ by the light alone, not by the
/// anti-aliasing.
pub fn reference_scene(reference: &SceneDesc, image: &SceneDesc) -> Result<Loaded, SceneError> {
    let mut scene = Loaded::new(reference)?;
    scene.settings.camera_seed = image.render.seed;
    Ok(scene)
}
