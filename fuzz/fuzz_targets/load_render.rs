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

mod common;

use libfuzzer_sys::fuzz_target;
use penumbra::render::SceneDesc;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(desc) = SceneDesc::from_json(text) else {
        return;
    };
    if let Some((i, p)) = common::first_non_finite_pixel(desc) {
        panic!("non-finite pixel {i}: {p:?}");
    }
});
