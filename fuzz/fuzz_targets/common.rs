//! What both fuzz targets do with a scene the loader accepted.

use penumbra::render::scene_file::ObjectDesc;
use penumbra::render::{CancelToken, Loaded, RenderOptions, SceneDesc};

/// Renders a validated scene at most 8×8 with at most 16 shadow rays and
/// depth 4 (so each run takes microseconds) and returns the first pixel
/// that is not finite, if any.
pub fn first_non_finite_pixel(mut desc: SceneDesc) -> Option<(usize, [f32; 3])> {
    // One worker in rayon's global pool, made once, before anything
    // uses the pool (the scene's build does), and that worker is this
    // thread: a pool per run (as `threads: Some(1)` builds) costs more than
    // the render itself, and handing each run to another thread a tenth.
    static POOL: std::sync::Once = std::sync::Once::new();
    POOL.call_once(|| {
        let _ = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .use_current_thread()
            .build_global();
    });
    desc.camera.width = desc.camera.width.min(8);
    desc.camera.height = desc.camera.height.min(8);
    desc.render.shadow_rays = desc.render.shadow_rays.min(16);
    desc.render.max_depth = desc.render.max_depth.min(4);
    // A mesh is read from its file when the scene is built, so a valid
    // description may still be refused then (a missing or bad file), with
    // an error; anything else stays valid with smaller caps.
    let has_mesh = desc.objects.iter().any(|o| matches!(o, ObjectDesc::Mesh(_)));
    let loaded = match Loaded::new(&desc) {
        Ok(loaded) => loaded,
        Err(_) if has_mesh => return None,
        Err(e) => panic!("a validated scene stays valid with smaller caps: {e}"),
    };
    let options = RenderOptions::default();
    let report = loaded
        .render(&options, &CancelToken::new(), &|_| {})
        .expect("not cancelled");
    let (i, p) = report
        .film
        .pixels
        .iter()
        .enumerate()
        .find(|(_, p)| !p.is_finite())?;
    Some((i, p.to_array()))
}
