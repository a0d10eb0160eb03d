//! The AVX-512, AVX2 and portable (baseline x86-64 or other CPUs) builds of
//! the same loops give the same image bit for bit. Its own test binary: the
//! in-process test switches a process-wide choice (the other runs the
//! `penumbra` binary once per choice).

use penumbra::render::math::force_portable_kernels;
use penumbra::render::{CancelToken, EditClass, LiveRender, Loaded, RenderOptions};

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
        // The viewer's frames, which record every path (and a light edit's,
        // which follow the records), through the portable kernels too.
        let mut live = LiveRender::default();
        let options = RenderOptions {
            threads: Some(2),
            progressive: false,
            tile_size: 16,
        };
        let mut recorded = vec![];
        let mut relit_desc = desc.clone();
        relit_desc.light.corner[0] += 0.25;
        for (d, class) in [
            (&desc, EditClass::Rebuild),
            (&relit_desc, EditClass::Relight),
        ] {
            let report = live
                .render(d, &options, &CancelToken::new(), &|_| {})
                .unwrap();
            assert_eq!(report.class, class, "{name}");
            recorded.push(report.film);
        }
        force_portable_kernels(false);
        let relit_fresh = Loaded::new(&relit_desc).unwrap().render_image();
        let differing = |a: &penumbra::render::Film, b: &penumbra::render::Film| {
            a.pixels
                .iter()
                .zip(&b.pixels)
                .filter(|(a, b)| a.to_array().map(f32::to_bits) != b.to_array().map(f32::to_bits))
                .count()
        };
        assert_eq!(
            differing(&fast, &portable),
            0,
            "{name}: AVX2 ({avx2}) against portable"
        );
        assert_eq!(
            differing(&fast, &recorded[0]),
            0,
            "{name}: recorded, portable"
        );
        assert_eq!(
            differing(&relit_fresh, &recorded[1]),
            0,
            "{name}: relit, portable"
        );
        eprintln!("{name}: identical (AVX2 kernels available: {avx2})");
    }
}

/// The sixteen-lane (AVX-512) kernels, the eight-lane ones
/// (`PENUMBRA_KERNELS=avx2`) and the portable build write the same EXR
/// bytes (the exact model too), with skipping on and off and with few and many shadow rays (the
/// wide kernels take hit points of 16 light points on). The choice is made
/// once per process, so each variant is a run of the binary.
#[test]
fn wide_narrow_and_portable_kernels_write_the_same_files() {
    // A fresh folder: files of an earlier run must not stand in for ones
    // a variant failed to write.
    let scratch = tempfile::tempdir().unwrap();
    let dir = scratch.path();
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let cases: [(&str, &[&str]); 6] = [
        ("scenes/seed-room.json", &[]),
        ("scenes/seed-room.json", &["--no-skip"]),
        ("scenes/seed-room.json", &["--shadow-rays", "1"]),
        ("scenes/mirrors.json", &["--model", "analytic"]),
        // The exact model's specular lobe kernels.
        ("scenes/seed-room.json", &["--model", "exact"]),
        (
            "scenes/stress/shininess-high.json",
            &["--shadow-rays", "20"],
        ),
    ];
    for (k, (scene, extra)) in cases.iter().enumerate() {
        let mut files = Vec::new();
        for kernels in [None, Some("avx2"), Some("portable")] {
            let out = dir.join(format!("{k}-{}.exr", kernels.unwrap_or("default")));
            let mut cmd = std::process::Command::new(env!("CARGO_BIN_EXE_penumbra"));
            cmd.arg("render")
                .arg(root.join(scene))
                .args(["--width", "160", "--height", "90", "-o"])
                .arg(&out)
                .args(*extra);
            match kernels {
                Some(v) => cmd.env("PENUMBRA_KERNELS", v),
                None => cmd.env_remove("PENUMBRA_KERNELS"),
            };
            let status = cmd.output().expect("runs").status;
            assert!(
                status.success(),
                "{scene} {extra:?} ({kernels:?}): {status}"
            );
            files.push((kernels, std::fs::read(&out).unwrap()));
        }
        for (kernels, bytes) in &files[1..] {
            assert!(
                *bytes == files[0].1,
                "{scene} {extra:?}: {kernels:?} kernels differ from the default"
            );
        }
    }
}
