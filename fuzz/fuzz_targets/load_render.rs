//! Fuzz target: any bytes → load → validate → build → render at 8×8.
//!
//! A scene that is refused must be refused with an error (never a panic);
//! a scene that is accepted must render to finite pixels. The size, shadow
//! rays and depth are capped here so that each run takes microseconds.
//!
//! Run from the repository root (stable toolchain), seeded with the
//! example and stress scenes and a dictionary of the format's keys:
//! `RUSTC_BOOTSTRAP=1 cargo fuzz run -s none load_render fuzz/corpus/load_render scenes scenes/stress -- -dict=fuzz/scene.dict -max_len=8192 -max_total_time=600`

#![no_main]

use libfuzzer_sys::fuzz_target;
use penumbra::render::{RenderOptions, Scene, SceneDesc};

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(mut desc) = SceneDesc::from_json(text) else {
        return;
    };
    desc.camera.width = desc.camera.width.min(8);
    desc.camera.height = desc.camera.height.min(8);
    desc.render.shadow_rays = desc.render.shadow_rays.min(16);
    desc.render.max_depth = desc.render.max_depth.min(4);
    let scene = Scene::new(desc).expect("a validated scene stays valid with smaller caps");
    let options = RenderOptions {
        threads: Some(1),
        ..RenderOptions::default()
    };
    let report = penumbra::render::render(
        &scene,
        &options,
        &penumbra::render::CancelToken::new(),
        &|_| {},
    )
    .expect("not cancelled");
    if let Some((i, p)) = report
        .film
        .pixels
        .iter()
        .enumerate()
        .find(|(_, p)| !p.is_finite())
    {
        panic!("non-finite pixel {i}: {p:?}");
    }
});
