//! The AVX2 kernels and the portable (baseline x86-64 or other CPUs) build
//! of the same loops give the same image bit for bit. One test in its own
//! binary: it switches a process-wide choice.

use penumbra::render::Loaded;
use penumbra::render::math::force_portable_kernels;

#[test]
fn avx2_and_portable_kernels_render_the_same_bits() {
    let scenes = [
        "scenes/seed-room.json",
        "scenes/mirrors.json",
        "scenes/random-16.json",
        "scenes/stress/shininess-high.json",
        "scenes/bunny.json",
    ];
    for name in scenes {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(name);
        let mut desc = penumbra::render::SceneDesc::load(&path).unwrap();
        desc.camera.width = 160;
        desc.camera.height = 90;
        let loaded = Loaded::new(&desc).unwrap();
        let avx2 = force_portable_kernels(false);
        let fast = loaded.render_image();
        assert!(!force_portable_kernels(true));
        let portable = loaded.render_image();
        force_portable_kernels(false);
        let differing = fast
            .pixels
            .iter()
            .zip(&portable.pixels)
            .filter(|(a, b)| a.to_array().map(f32::to_bits) != b.to_array().map(f32::to_bits))
            .count();
        assert_eq!(differing, 0, "{name}: AVX2 ({avx2}) against portable");
        eprintln!("{name}: identical (AVX2 kernels available: {avx2})");
    }
}
