//! The command line as a user runs it.

mod common;

use std::process::Output;

use common::{files_in, penumbra};

fn scratch_dir(name: &str) -> common::Scratch {
    common::Scratch::new(&format!("cli-{name}"))
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn render_writes_a_png_of_the_requested_size_and_a_summary() {
    let dir = scratch_dir("render");
    let out = dir.join("room.png");
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/seed-room.json");
    let o = penumbra(&[
        "render",
        scene,
        "-o",
        out.to_str().unwrap(),
        "--width",
        "64",
        "--height",
        "36",
        "--shadow-rays",
        "16",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let img = image::open(&out).unwrap();
    assert_eq!((img.width(), img.height()), (64, 36));
    let summary = stderr(&o);
    assert!(summary.contains("2304 camera"), "{summary}");
    assert!(summary.contains("Mray/s"), "{summary}");
    assert_eq!(files_in(&dir), vec!["room.png"], "no temporary files left");
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let mode = std::fs::metadata(&out).unwrap().permissions().mode() & 0o777;
        assert_eq!(
            mode, 0o644,
            "a new image is readable by others, like any new file"
        );
    }

    // The built-in scene is used without a scene argument; EXR keeps linear values.
    let exr = dir.join("room.exr");
    let o = penumbra(&[
        "render",
        "-o",
        exr.to_str().unwrap(),
        "--width",
        "64",
        "--height",
        "36",
        "--shadow-rays",
        "16",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));

    let o = penumbra(&["compare", out.to_str().unwrap(), out.to_str().unwrap()]);
    assert!(o.status.success());
    let report = String::from_utf8_lossy(&o.stdout);
    assert!(report.contains("rmse 0.000000e0"), "{report}");
    assert!(report.contains("psnr inf dB"), "{report}");

    // The PNG is exactly the sRGB 8-bit encoding of the EXR's linear values.
    let linear = penumbra::render::output::read_film(&exr).unwrap();
    let png = image::open(&out).unwrap().into_rgb8();
    assert_eq!(linear.to_srgb8(), png.into_raw());

    let diff = dir.join("diff.png");
    let o = penumbra(&[
        "compare",
        out.to_str().unwrap(),
        exr.to_str().unwrap(),
        "--diff",
        diff.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let report = String::from_utf8_lossy(&o.stdout);
    let rmse: f64 = report
        .lines()
        .next()
        .unwrap()
        .trim_start_matches("rmse ")
        .parse()
        .unwrap();
    assert!(rmse > 0.0 && rmse < 0.05, "{report}");
    assert_eq!(image::open(&diff).unwrap().width(), 64);
}

#[test]
fn compare_of_different_sizes_exits_2() {
    let dir = scratch_dir("sizes");
    let (a, b) = (dir.join("a.png"), dir.join("b.png"));
    for (p, w) in [(&a, "16"), (&b, "17")] {
        let o = penumbra(&[
            "render",
            "-o",
            p.to_str().unwrap(),
            "--width",
            w,
            "--height",
            "9",
            "--shadow-rays",
            "1",
        ]);
        assert!(o.status.success());
    }
    let o = penumbra(&["compare", a.to_str().unwrap(), b.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("sizes differ: 16×9 vs 17×9"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn bad_scene_exits_2_with_the_field_and_leaves_no_file() {
    let dir = scratch_dir("bad");
    let scene = dir.join("bad.json");
    let text = penumbra::render::SEED_ROOM_JSON.replace(r#""radius": 1"#, r#""radius": -1"#);
    std::fs::write(&scene, text).unwrap();
    let out = dir.join("out.png");
    let o = penumbra(&[
        "render",
        scene.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    let err = stderr(&o);
    assert_eq!(err.lines().count(), 1, "one line: {err}");
    assert!(
        err.contains("bad.json: objects[7].radius: -1 is out of range"),
        "{err}"
    );
    assert_eq!(files_in(&dir), vec!["bad.json"]);

    // An existing output is not touched by a failed render.
    std::fs::write(&out, b"precious").unwrap();
    let o = penumbra(&[
        "render",
        scene.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert_eq!(std::fs::read(&out).unwrap(), b"precious");

    // Missing file, bad option value, unknown output format: also exit 2.
    for args in [
        vec!["render", "/nonexistent/scene.json", "-o", "x.png"],
        vec!["render", "-o", "x.png", "--shadow-rays", "0"],
        vec!["render", "-o", "x.bmp"],
    ] {
        let o = penumbra(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
    }
}
