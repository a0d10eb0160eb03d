//! Reliability, round two: the numeric range the renderer supports (and
//! refuses beyond), bounded reads, outputs that would destroy inputs,
//! signals during the write, duplicate keys, long values in messages,
//! `compare`'s inputs, and the `nearest_point` model's singular case.
//! Each test checks what "Guarantees and limits" in the README promises.

mod common;

use std::io::Write;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::{files_in, penumbra, penumbra_within_memory};
use penumbra::render::SEED_ROOM_JSON;
use penumbra::render::compare::compare;
use penumbra::render::scene_file::limits;
use penumbra::render::{Film, Loaded, SceneDesc};
use proptest::prelude::*;

fn seed(width: u32, height: u32) -> SceneDesc {
    common::seed_room(width, height)
}

fn render(desc: &SceneDesc) -> Film {
    let scene = Loaded::new(desc).unwrap_or_else(|e| panic!("{e}"));
    let film = scene.render_image();
    if let Some((n, at)) = film.non_finite() {
        panic!("{n} non-finite pixels, the first at {at:?}");
    }
    film
}

fn stderr(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_penumbra"))
}

fn scratch() -> tempfile::TempDir {
    tempfile::Builder::new()
        .prefix("penumbra-reliability-")
        .tempdir()
        .unwrap()
}

// ---------------------------------------------------------------- item 1

/// The seed room at 40×24 with 16 shadow rays: small enough for many cases.
fn small_room() -> SceneDesc {
    let mut d = seed(40, 24);
    d.render.shadow_rays = 16;
    d
}

/// The supported scales of the seed room: its size from
/// `limits::MIN_SCENE_SIZE` up to where a coordinate reaches
/// `limits::MAX_COORD`.
fn scale_range() -> (f64, f64) {
    let d = small_room();
    let (size, offset) = d.size_and_offset();
    (limits::MIN_SCENE_SIZE / size, limits::MAX_COORD / offset)
}

/// The README's bound: RMSE against the same scene at scale 1 at the
/// origin, over the whole supported range of scale and translation.
const RMSE_BOUND: f64 = 1e-7;

proptest! {
    // PENUMBRA_RANGE_CASES=N runs N cases of each (48 by default).
    #![proptest_config(ProptestConfig {
        cases: std::env::var("PENUMBRA_RANGE_CASES").ok().and_then(|n| n.parse().ok()).unwrap_or(48),
        ..ProptestConfig::default()
    })]

    #[test]
    fn every_supported_scale_renders_finite_pixels_that_match_scale_one(t in 0.0f64..=1.0) {
        let (lo, hi) = scale_range();
        // Log-uniform over the whole range, both ends included.
        let s = lo * (hi / lo).powf(t) * (1.0 - 1e-12);
        let base = small_room();
        let reference = render(&base);
        let film = render(&base.clone().scaled(s));
        let c = compare(&reference, &film).unwrap();
        prop_assert!(c.rmse < RMSE_BOUND, "scale {s:e}: rmse {:e}, max diff {} at {:?}", c.rmse, c.max_diff, c.max_at);
    }

    #[test]
    fn every_supported_translation_renders_finite_pixels_that_match_the_origin(
        t in 0.0f64..=1.0, scale_t in 0.0f64..=1.0, dir in 0usize..26,
    ) {
        let (lo, hi) = scale_range();
        let s = lo * (hi / lo).powf(scale_t);
        let base = small_room().scaled(s);
        let (size, offset) = base.size_and_offset();
        // The translation that puts the scene's farthest point at up to
        // MAX_OFFSET sizes (and MAX_COORD), log-uniform from 1 size.
        let most = (limits::MAX_OFFSET * size).min(limits::MAX_COORD) - offset;
        prop_assume!(most > size);
        let d = size * (most / size).powf(t) * (1.0 - 1e-9);
        let (i, j, k) = (dir % 3, dir / 3 % 3, dir / 9 % 3);
        let sign = |n: usize| n as f64 - 1.0;
        let v = glam::DVec3::new(sign(i), sign(j), sign(k) + if dir == 13 { 1.0 } else { 0.0 });
        let v = v / v.abs().max_element() * d;
        let reference = render(&base);
        let film = render(&base.clone().translated(v.to_array()));
        let c = compare(&reference, &film).unwrap();
        prop_assert!(c.rmse < RMSE_BOUND, "scale {s:e} moved {v}: rmse {:e}, max diff {} at {:?}", c.rmse, c.max_diff, c.max_at);
    }
}

#[test]
fn scenes_outside_the_supported_range_are_refused_naming_the_field() {
    let (lo, hi) = scale_range();
    let base = small_room();
    for (what, desc, path, words) in [
        ("too small", base.clone().scaled(lo * 0.99), "", "across"),
        (
            "scale 1e-30",
            base.clone().scaled(1e-30),
            "",
            "at least 1e-6",
        ),
        (
            "too large",
            base.clone().scaled(hi * 1.01),
            "camera.position",
            "out of range",
        ),
        (
            "too far from the origin",
            base.clone().scaled(1e-3).translated([1e6, 0.0, 0.0]),
            "objects[2].point[0]",
            "scene sizes from the origin",
        ),
    ] {
        let e = Loaded::new(&desc)
            .err()
            .unwrap_or_else(|| panic!("{what}: accepted"));
        assert!(e.path.starts_with(path), "{what}: {e}");
        assert!(e.message.contains(words), "{what}: {e}");
    }
}

#[test]
fn the_cli_refuses_scale_and_translate_outside_the_range_with_exit_2() {
    let dir = scratch();
    let out = dir.path().join("x.exr");
    let o = out.to_str().unwrap();
    for args in [
        vec!["--scale", "1e-30"],
        vec!["--scale", "1e-12"],
        vec!["--scale", "1e-3", "--translate", "1e6,0,0"],
    ] {
        let mut full = vec!["render", "-o", o, "--width", "16", "--height", "9"];
        full.extend(&args);
        let r = penumbra(&full);
        let err = common::refused(&r, format!("{args:?}"));
        assert!(err.contains("(after --scale"), "{args:?}: {err}");
        assert!(!out.exists(), "{args:?}");
    }
}

#[test]
fn a_film_with_non_finite_pixels_is_not_written() {
    let dir = scratch();
    let mut film = Film::new(4, 3);
    film.pixels[5] = glam::Vec3::new(f32::NAN, 0.0, 0.0);
    film.pixels[7] = glam::Vec3::splat(f32::INFINITY);
    for name in ["x.exr", "x.png"] {
        let path = dir.path().join(name);
        let e = penumbra::render::output::write_film(&film, &path)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("2 pixels are NaN or infinite (the first at (1, 1))"),
            "{e}"
        );
        assert!(!path.exists());
    }
    assert!(files_in(dir.path()).is_empty());
}

// ---------------------------------------------------------------- item 2

/// The seed room's light shrunk about its centre to `edge` world units.
fn with_light(edge: f64) -> SceneDesc {
    let mut d = small_room();
    let l = &mut d.light;
    let c = [l.corner[0] + 1.0, l.corner[1], l.corner[2] + 1.0];
    l.corner = [c[0] - edge / 2.0, c[1], c[2] - edge / 2.0];
    l.edge_u = [edge, 0.0, 0.0];
    l.edge_v = [0.0, 0.0, edge];
    d
}

#[test]
fn lights_below_the_smallest_supported_size_are_refused() {
    let size = small_room().size_and_offset().0;
    for edge in [1e-200, 1e-15 * size, 0.99 * limits::MIN_FEATURE * size] {
        let e = Loaded::new(&with_light(edge))
            .err()
            .unwrap_or_else(|| panic!("{edge:e} accepted"));
        assert_eq!(e.path, "light.edge_u", "{e}");
        assert!(
            e.message.contains("below the smallest supported size"),
            "{e}"
        );
    }
    // A light that is long but nearly a line, and a sphere of 1e-320.
    let mut thin = small_room();
    thin.light.edge_v = [0.0, 0.0, 1e-12];
    let e = Loaded::new(&thin).unwrap_err();
    assert_eq!(e.path, "light.edge_v", "{e}");
    let mut line = small_room();
    line.light.edge_v = [2.0, 0.0, 1e-12];
    assert!(Loaded::new(&line).is_err());
    let mut dot = small_room();
    let penumbra::render::scene_file::ObjectDesc::Sphere(s) = &mut dot.objects[7] else {
        panic!("the seed room's object 7 is its sphere")
    };
    s.radius = 1e-320;
    assert_eq!(Loaded::new(&dot).unwrap_err().path, "objects[7].radius");
}

#[test]
fn the_smallest_supported_light_lights_the_room_under_every_model() {
    use penumbra::render::AreaLightModel;
    let size = small_room().size_and_offset().0;
    let tiny = 1.01 * limits::MIN_FEATURE * size;
    for model in AreaLightModel::ALL {
        let mut small = with_light(1e-6);
        small.render.area_light_model = model;
        let mut smallest = with_light(tiny);
        smallest.render.area_light_model = model;
        let (a, b) = (render(&small), render(&smallest));
        let c = compare(&a, &b).unwrap();
        // Both are point lights for this room: the same image to rounding.
        assert!(
            c.rmse < 1e-6,
            "{model:?}: rmse {:e} against a 1e-3 light",
            c.rmse
        );
        let lit: f32 = b.pixels.iter().map(|p| p.max_element()).sum();
        let mut dark = smallest.clone();
        dark.render.terms.diffuse = 0.0;
        dark.render.terms.specular = 0.0;
        let ambient: f32 = render(&dark).pixels.iter().map(|p| p.max_element()).sum();
        assert!(
            lit > 1.5 * ambient,
            "{model:?}: the light went dark ({lit} vs ambient {ambient})"
        );
    }
}

// ---------------------------------------------------------------- item 3

#[test]
fn a_device_of_endless_bytes_is_refused_promptly_with_exit_2() {
    let dir = scratch();
    let out = dir.path().join("x.png");
    let start = Instant::now();
    let r = penumbra(&["render", "/dev/zero", "-o", out.to_str().unwrap()]);
    let err = common::refused(&r, "");
    // Refused for what it is, before a byte is read.
    assert!(
        err.contains("/dev/zero: a character device, not a regular file"),
        "{err}"
    );
    assert!(
        start.elapsed() < Duration::from_secs(20),
        "{:?}",
        start.elapsed()
    );
    assert!(!out.exists());
    // An image to compare or merge is refused from its first bytes (not
    // after reading 3 GB of zeros).
    let png = dir.path().join("a.png");
    std::fs::write(&png, b"not an image").unwrap();
    let merged = dir.path().join("m.exr");
    for (args, says) in [
        (
            vec!["compare", "/dev/zero", png.to_str().unwrap()],
            "penumbra: /dev/zero: not a PNG or OpenEXR image\n",
        ),
        (
            vec!["merge", "/dev/zero", "-o", merged.to_str().unwrap()],
            "penumbra: /dev/zero: not an OpenEXR file (a region part is one)\n",
        ),
    ] {
        let start = Instant::now();
        let r = penumbra(&args);
        common::refused(&r, "");
        assert_eq!(stderr(&r), says);
        assert!(
            start.elapsed() < Duration::from_secs(2),
            "{:?}",
            start.elapsed()
        );
    }
    assert!(!merged.exists());
}

#[test]
fn a_scene_piped_through_stdin_is_bounded_too() {
    let dir = scratch();
    let out = dir.path().join("x.png");
    let feed = |extra: usize| {
        let mut child = bin()
            .args(["render", "/dev/stdin", "-o", out.to_str().unwrap()])
            .args(["--width", "8", "--height", "8"])
            .stdin(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let mut stdin = child.stdin.take().unwrap();
        let writer = std::thread::spawn(move || {
            // JSON allows any amount of white space after the value.
            let _ = stdin.write_all(SEED_ROOM_JSON.as_bytes());
            let chunk = vec![b' '; 1 << 20];
            let mut left = extra;
            while left > 0 {
                let n = left.min(chunk.len());
                if stdin.write_all(&chunk[..n]).is_err() {
                    break;
                }
                left -= n;
            }
        });
        let o = child.wait_with_output().unwrap();
        writer.join().unwrap();
        o
    };
    let o = feed(1 << 20);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = feed(65 << 20);
    common::refused(&o, "");
    assert!(
        stderr(&o).contains("more than 67108864 bytes"),
        "{}",
        stderr(&o)
    );
}

// ---------------------------------------------------------------- item 6

fn mkfifo(path: &Path) {
    let c = std::ffi::CString::new(path.to_str().unwrap()).unwrap();
    // SAFETY: a NUL-terminated path and a mode, no other pointers.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0, "mkfifo");
}

#[test]
fn a_fifo_as_the_scene_or_a_mesh_is_refused_at_once_with_exit_2() {
    let dir = scratch();
    let fifo = dir.path().join("scene.json");
    mkfifo(&fifo);
    let out = dir.path().join("x.png");
    // Nobody writes to the FIFO: reading it would wait for ever.
    let start = Instant::now();
    let r = penumbra(&[
        "render",
        fifo.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    let err = common::refused(&r, "");
    assert!(
        err.contains(&format!("{}: a FIFO, not a regular file", fifo.display())),
        "{err}"
    );
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(start.elapsed() < Duration::from_secs(20));
    assert!(!out.exists());

    // A mesh file that is a FIFO, the same.
    let mesh_fifo = dir.path().join("m.obj");
    mkfifo(&mesh_fifo);
    let mut desc = seed(16, 9);
    desc.objects
        .push(penumbra::render::scene_file::ObjectDesc::Mesh(
            penumbra::render::scene_file::MeshDesc {
                file: mesh_fifo.to_str().unwrap().into(),
                material: "white".into(),
                scale: penumbra::render::scene_file::MeshScale::Uniform(1.0),
                rotate_y_deg: 0.0,
                translate: [0.0; 3],
                shading: penumbra::render::scene_file::MeshShading::Auto,
            },
        ));
    let scene = dir.path().join("with-mesh.json");
    std::fs::write(&scene, desc.to_json()).unwrap();
    let r = penumbra(&[
        "render",
        scene.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    let err = common::refused(&r, "");
    assert!(err.contains("a FIFO, not a regular file"), "{err}");
}

// ---------------------------------------------------------------- item 4

#[test]
fn an_output_that_is_an_input_is_refused_through_links() {
    let dir = scratch();
    let d = dir.path();
    let scene = d.join("s.png");
    std::fs::write(&scene, SEED_ROOM_JSON).unwrap();
    std::os::unix::fs::symlink(&scene, d.join("link.png")).unwrap();
    std::fs::hard_link(&scene, d.join("hard.png")).unwrap();
    for out in ["s.png", "link.png", "hard.png"] {
        let r = penumbra(&[
            "render",
            scene.to_str().unwrap(),
            "-o",
            d.join(out).to_str().unwrap(),
            "--width",
            "8",
            "--height",
            "8",
        ]);
        let err = common::refused(&r, out);
        assert!(
            err.contains("is the same file as the scene"),
            "{out}: {err}"
        );
        assert_eq!(std::fs::read_to_string(&scene).unwrap(), SEED_ROOM_JSON);
    }
    // compare --diff over either input.
    let a = d.join("a.png");
    let b = d.join("b.png");
    for p in [&a, &b] {
        let r = penumbra(&[
            "render",
            "-o",
            p.to_str().unwrap(),
            "--width",
            "8",
            "--height",
            "8",
        ]);
        assert!(r.status.success(), "{}", stderr(&r));
    }
    std::os::unix::fs::symlink(&b, d.join("b-link.png")).unwrap();
    let before = std::fs::read(&b).unwrap();
    for diff in ["a.png", "b.png", "b-link.png"] {
        let r = penumbra(&[
            "compare",
            a.to_str().unwrap(),
            b.to_str().unwrap(),
            "--diff",
            d.join(diff).to_str().unwrap(),
        ]);
        let err = common::refused(&r, diff);
        assert!(err.contains("is the same file as the"), "{diff}: {err}");
    }
    assert_eq!(std::fs::read(&b).unwrap(), before);
    // The bench's CSV and plot.
    let json = d.join("scene.json");
    std::fs::write(&json, SEED_ROOM_JSON).unwrap();
    for flag in ["--csv", "--plot"] {
        let r = penumbra(&[
            "bench",
            json.to_str().unwrap(),
            flag,
            json.to_str().unwrap(),
            "--quick",
        ]);
        common::refused(&r, flag);
        assert_eq!(std::fs::read_to_string(&json).unwrap(), SEED_ROOM_JSON);
    }
}

/// The seed room with a mesh object reading `mesh` (relative to the
/// scene's folder), written to `scene`.
fn write_room_with_mesh(scene: &Path, mesh: &str) {
    let mut json: serde_json::Value = serde_json::from_str(SEED_ROOM_JSON).unwrap();
    let material = json["materials"]
        .as_object()
        .unwrap()
        .keys()
        .next()
        .unwrap()
        .clone();
    json["objects"]
        .as_array_mut()
        .unwrap()
        .push(serde_json::json!({"type": "mesh", "file": mesh, "material": material}));
    std::fs::write(scene, json.to_string()).unwrap();
}

/// A generated mesh of about `triangles` at `mesh` and the seed room with
/// it at `scene` (the mesh named by its file name, beside the scene).
fn generated_mesh_room(triangles: &str, mesh: &Path, scene: &Path) {
    let r = penumbra(&[
        "generate",
        "--triangles",
        triangles,
        "-o",
        mesh.to_str().unwrap(),
    ]);
    assert!(r.status.success(), "{}", stderr(&r));
    write_room_with_mesh(scene, mesh.file_name().unwrap().to_str().unwrap());
}

#[test]
fn an_output_that_is_a_mesh_of_the_scene_is_refused() {
    let dir = scratch();
    let d = dir.path();
    let (mesh, scene) = (d.join("gm.obj"), d.join("gsc.json"));
    generated_mesh_room("18", &mesh, &scene);
    let before = std::fs::read(&mesh).unwrap();
    std::os::unix::fs::symlink(&mesh, d.join("mesh-link.png")).unwrap();
    std::os::unix::fs::symlink(&mesh, d.join("mesh-link.csv")).unwrap();
    // Where `bench --exact` writes its error image for the scene gsc.json.
    std::os::unix::fs::symlink(&mesh, d.join("exact-error-gsc.png")).unwrap();
    let (scene, out) = (scene.to_str().unwrap(), d.join("o.png"));
    let (out, link) = (out.to_str().unwrap(), d.join("mesh-link.png"));
    let link = link.to_str().unwrap();
    let csv = d.join("mesh-link.csv");
    let folder = d.to_str().unwrap();
    let cases: [&[&str]; 4] = [
        &[
            "render",
            scene,
            "--width",
            "8",
            "-o",
            out,
            "--stats",
            mesh.to_str().unwrap(),
        ],
        &["render", scene, "--width", "8", "-o", link],
        &["bench", scene, "--quick", "--csv", csv.to_str().unwrap()],
        &[
            "bench", scene, "--exact", "--width", "8", "--runs", "5", "--out", folder, "--cache",
            folder,
        ],
    ];
    for args in cases {
        let r = penumbra(args);
        let err = common::refused(&r, format!("{args:?}"));
        assert!(
            err.contains("is the same file as the mesh"),
            "{args:?}: {err}"
        );
        assert_eq!(std::fs::read(&mesh).unwrap(), before, "{args:?}");
    }
}

/// An output that is a mesh of the scene is refused once the scene is
/// read, before any mesh is loaded (a large one takes a while): here a
/// second mesh that does not parse would otherwise be reported first.
#[test]
fn an_output_that_is_a_mesh_is_refused_before_the_meshes_load() {
    let dir = scratch();
    let d = dir.path();
    let (mesh, scene) = (d.join("gm.obj"), d.join("two.json"));
    generated_mesh_room("18", &mesh, &scene);
    std::fs::write(d.join("bad.obj"), "v 1 2\n").unwrap();
    let mut json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&scene).unwrap()).unwrap();
    let mut bad = json["objects"].as_array().unwrap().last().unwrap().clone();
    bad["file"] = "bad.obj".into();
    json["objects"].as_array_mut().unwrap().push(bad);
    std::fs::write(&scene, json.to_string()).unwrap();
    std::os::unix::fs::symlink(&mesh, d.join("mesh-link.png")).unwrap();
    let r = bin()
        .arg("render")
        .arg(&scene)
        .args(["--width", "8", "-o"])
        .arg(d.join("mesh-link.png"))
        .output()
        .unwrap();
    let err = common::refused(&r, "");
    assert!(err.contains("is the same file as the mesh"), "{err}");
}

#[test]
fn an_output_that_is_the_scene_read_from_standard_input_is_refused() {
    let dir = scratch();
    let d = dir.path();
    let scene = d.join("s.json");
    std::fs::write(&scene, SEED_ROOM_JSON).unwrap();
    std::os::unix::fs::symlink(&scene, d.join("out.png")).unwrap();
    let r = bin()
        .args(["render", "-", "--width", "16", "-o"])
        .arg(d.join("out.png"))
        .stdin(std::fs::File::open(&scene).unwrap())
        .output()
        .unwrap();
    let err = common::refused(&r, "");
    assert!(err.contains("is the same file as the scene"), "{err}");
    assert_eq!(std::fs::read_to_string(&scene).unwrap(), SEED_ROOM_JSON);
}

/// A read-only file is not replaced: `generate` replaced it (the write's
/// rename takes no heed of permissions), and so did `render`. Every
/// command refuses it before its work (exit 2, naming the file), and a
/// write that reaches one fails. The mode bits are checked themselves:
/// root may write any file.
#[test]
fn a_read_only_output_is_refused_before_the_work() {
    use std::os::unix::fs::PermissionsExt;
    let dir = scratch();
    let d = dir.path();
    let file = |name: &str| d.join(name).to_str().unwrap().to_owned();
    let (part, image) = (file("part.exr"), file("image.png"));
    let r = penumbra(&["render", "--width", "8", "--region", "0,0,8,4", "-o", &part]);
    assert!(r.status.success(), "{}", stderr(&r));
    let r = penumbra(&["render", "--width", "8", "-o", &image]);
    assert!(r.status.success(), "{}", stderr(&r));
    let read_only = |name: &str| {
        let path = d.join(name);
        std::fs::write(&path, b"precious").unwrap();
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o444)).unwrap();
        path.to_str().unwrap().to_owned()
    };
    let (obj, png, json, exr, diff) = (
        read_only("ro.obj"),
        read_only("ro.png"),
        read_only("ro.json"),
        read_only("ro.exr"),
        read_only("diff.png"),
    );
    let (out, csv) = (file("o.png"), read_only("ro.csv"));
    // A render large enough that rendering first would take far longer.
    let big = ["--width", "4000", "--height", "4000", "--shadow-rays", "1"];
    let cases: [(Vec<&str>, &str); 6] = [
        (vec!["generate", "--triangles", "18", "-o", &obj], &obj),
        ([&["render", "-o", &png][..], &big].concat(), &png),
        (
            [&["render", "-o", &out, "--stats", &json][..], &big].concat(),
            &json,
        ),
        (vec!["merge", &part, "-o", &exr], &exr),
        (vec!["compare", &image, &image, "--diff", &diff], &diff),
        (vec!["bench", "--quick", "--csv", &csv], &csv),
    ];
    for (args, target) in &cases {
        let r = penumbra(args);
        let err = common::refused(&r, format!("{args:?}"));
        assert!(
            err.starts_with(&format!("penumbra: {target}: the ")) && err.contains("read-only"),
            "{args:?}: {err}"
        );
        assert_eq!(err.trim().lines().count(), 1, "{err}");
        assert_eq!(std::fs::read(target).unwrap(), b"precious", "{args:?}");
    }
    assert!(!Path::new(&out).exists(), "rendered first");
    // The write itself refuses one too (made read-only after the checks).
    let film = Film::new(2, 2);
    let err = penumbra::render::output::write_film(&film, Path::new(&png)).unwrap_err();
    assert!(err.to_string().contains("read-only"), "{err}");
    assert_eq!(std::fs::read(&png).unwrap(), b"precious");
    // Made writable, it is replaced as any file.
    std::fs::set_permissions(&obj, std::fs::Permissions::from_mode(0o644)).unwrap();
    let r = penumbra(&["generate", "--triangles", "18", "-o", &obj]);
    assert!(r.status.success(), "{}", stderr(&r));
    assert_ne!(std::fs::read(&obj).unwrap(), b"precious");
    let leftovers: Vec<String> = files_in(d)
        .into_iter()
        .filter(|f| f.ends_with(".part"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

#[test]
fn an_output_link_into_a_missing_folder_or_looping_is_refused_before_rendering() {
    let dir = scratch();
    let d = dir.path();
    std::os::unix::fs::symlink("nodir/x.png", d.join("dl.png")).unwrap();
    std::os::unix::fs::symlink("loop.png", d.join("loop.png")).unwrap();
    let (dangling, looping) = (d.join("dl.png"), d.join("loop.png"));
    let (dangling, looping) = (dangling.to_str().unwrap(), looping.to_str().unwrap());
    let image = d.join("o.png");
    let image = image.to_str().unwrap();
    // Large enough that rendering first would take far longer than refusing.
    let big = ["--width", "4000", "--height", "4000", "--shadow-rays", "1"];
    let cases: [(&[&str], &str); 3] = [
        (&["-o", dangling], "there is no folder"),
        (&["-o", image, "--stats", dangling], "there is no folder"),
        (&["-o", looping], "loops"),
    ];
    for (outputs, says) in cases {
        let r = bin()
            .arg("render")
            .args(big)
            .args(outputs)
            .output()
            .unwrap();
        let err = common::refused(&r, format!("{outputs:?}"));
        assert!(err.contains(says), "{outputs:?}: {err}");
        assert!(!Path::new(image).exists(), "{outputs:?}: rendered first");
    }
    assert!(std::fs::symlink_metadata(looping).unwrap().is_symlink());
}

#[test]
fn a_mesh_path_from_the_scene_is_escaped_in_messages() {
    let dir = scratch();
    let scene = dir.path().join("s.json");
    write_room_with_mesh(&scene, "x\ny\u{1b}[2J.obj");
    let out = dir.path().join("o.png");
    let r = bin()
        .arg("render")
        .arg(&scene)
        .arg("-o")
        .arg(&out)
        .output()
        .unwrap();
    let err = common::refused(&r, "");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(!err.contains('\u{1b}') && err.contains("\\u{1b}"), "{err}");
}

// ---------------------------------------------------------------- item 5

/// Starts a render of a large EXR over `target` (which holds "precious"),
/// waits until its temporary file appears (the write has begun: rendering
/// an ambient-only image takes moments, writing 200 MB longer), sends
/// `signal`, and returns the exit status and stderr.
fn signal_during_write(signal: &str) -> (std::process::ExitStatus, String, Vec<String>) {
    let render = [
        "render",
        "--width",
        "4096",
        "--height",
        "4096",
        "--shadow-rays",
        "1",
        "--depth",
        "1",
        "--terms",
        "1,0,0",
    ];
    signal_during_write_of(&render, "big.exr", signal)
}

/// [`signal_during_write`] for the command `args`, which writes `-o
/// target` (a name in a scratch folder) for long enough to be stopped.
fn signal_during_write_of(
    args: &[&str],
    target: &str,
    signal: &str,
) -> (std::process::ExitStatus, String, Vec<String>) {
    let dir = scratch();
    let target = dir.path().join(target);
    std::fs::write(&target, b"precious").unwrap();
    let mut child = bin()
        .args(args)
        .args(["-o", target.to_str().unwrap()])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    let part = loop {
        let part = files_in(dir.path())
            .into_iter()
            .find(|f| f.ends_with(".part"));
        if let Some(p) = part {
            break p;
        }
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "no temporary file appeared"
        );
        assert!(
            child.try_wait().unwrap().is_none(),
            "finished before writing"
        );
        std::thread::sleep(Duration::from_micros(200));
    };
    let sent = Command::new("kill")
        .args([&format!("-{signal}"), &child.id().to_string()])
        .status()
        .unwrap();
    assert!(sent.success());
    let o = child.wait_with_output().unwrap();
    assert_eq!(
        std::fs::read(&target).unwrap(),
        b"precious",
        "{signal}: target touched"
    );
    let left = files_in(dir.path());
    assert!(!left.contains(&part), "{signal}: {part} left behind");
    (o.status, stderr(&o), left)
}

#[test]
fn sigterm_sighup_and_sigint_during_the_write_leave_no_temporary_file() {
    for signal in ["TERM", "HUP", "INT"] {
        let (status, err, left) = signal_during_write(signal);
        assert_eq!(status.code(), Some(1), "{signal}: {err}");
        assert!(
            err.contains("interrupted: no image written"),
            "{signal}: {err}"
        );
        assert_eq!(left, vec!["big.exr"], "{signal}");
    }
}

#[test]
fn other_fatal_signals_during_the_write_remove_the_temporary_file() {
    use std::os::unix::process::ExitStatusExt;
    for (signal, number) in [("USR1", libc::SIGUSR1), ("QUIT", libc::SIGQUIT)] {
        let (status, _, left) = signal_during_write(signal);
        assert_eq!(status.signal(), Some(number), "{signal}");
        assert_eq!(left, vec!["big.exr"], "{signal}");
    }
}

/// `generate` writes as `render` does: a signal stops the write, the
/// target untouched and no temporary file left (it wrote the OBJ in
/// place, and a signal left it cut short).
#[test]
fn a_signal_during_generate_leaves_the_target_untouched() {
    // 150 MB of OBJ text: about a second of writing.
    let generate = ["generate", "--triangles", "4000000"];
    for signal in ["TERM", "HUP", "INT"] {
        let (status, err, left) = signal_during_write_of(&generate, "torus.obj", signal);
        assert_eq!(status.code(), Some(1), "{signal}: {err}");
        assert_eq!(
            err.trim(),
            "penumbra: interrupted: no file written",
            "{signal}"
        );
        assert_eq!(left, vec!["torus.obj"], "{signal}");
    }
    use std::os::unix::process::ExitStatusExt;
    let (status, _, left) = signal_during_write_of(&generate, "torus.obj", "USR1");
    assert_eq!(status.signal(), Some(libc::SIGUSR1));
    assert_eq!(left, vec!["torus.obj"]);
}

#[test]
fn sigterm_during_the_render_stops_it_without_a_file() {
    let dir = scratch();
    let out = dir.path().join("keep.png");
    std::fs::write(&out, b"precious").unwrap();
    let child = bin()
        .args(["render", "-o", out.to_str().unwrap()])
        .args([
            "--width",
            "1920",
            "--height",
            "1080",
            "--shadow-rays",
            "4096",
        ])
        .args(["--threads", "1"])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(500));
    let sent = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(sent.success());
    let o = child.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("interrupted: no image written"));
    assert_eq!(std::fs::read(&out).unwrap(), b"precious");
    assert_eq!(files_in(dir.path()), vec!["keep.png"]);
}

#[test]
fn a_file_size_limit_fails_the_write_with_its_own_words() {
    let dir = scratch();
    let out = dir.path().join("big.exr");
    // 100 blocks of 1 KiB: far less than the 200×150 EXR (360 kB).
    let script = format!(
        "ulimit -f 100; exec '{}' render -o '{}' --width 200 --height 150 --shadow-rays 1",
        env!("CARGO_BIN_EXE_penumbra"),
        out.display()
    );
    let o = Command::new("sh").args(["-c", &script]).output().unwrap();
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("File too large"), "{err}");
    assert!(!err.to_lowercase().contains("decod"), "{err}");
    assert!(
        files_in(dir.path()).is_empty(),
        "{:?}",
        files_in(dir.path())
    );
}

/// A failed `generate` (here a file-size limit, which killed it with
/// SIGXFSZ half way through the file) says so in one line naming the
/// file, and leaves an existing file as it was and no temporary file.
#[test]
fn a_failed_generate_keeps_the_existing_file() {
    let dir = scratch();
    let out = dir.path().join("torus.obj");
    std::fs::write(&out, b"precious").unwrap();
    // 100 blocks of 1 KiB: far less than the OBJ of 100 000 triangles (4 MB).
    let script = format!(
        "ulimit -f 100; exec '{}' generate --triangles 100000 -o '{}'",
        env!("CARGO_BIN_EXE_penumbra"),
        out.display()
    );
    let o = Command::new("sh").args(["-c", &script]).output().unwrap();
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    let named = format!("penumbra: {}: ", out.display());
    assert!(err.starts_with(&named), "{err}");
    assert!(err.contains("File too large"), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert_eq!(std::fs::read(&out).unwrap(), b"precious");
    assert_eq!(files_in(dir.path()), vec!["torus.obj"]);
}

// ---------------------------------------------------------------- item 7

#[test]
fn duplicate_keys_are_refused_with_their_path() {
    let materials = r#""materials": {"#;
    assert!(SEED_ROOM_JSON.contains(materials));
    let twice = SEED_ROOM_JSON.replacen(
        materials,
        r#""materials": { "red": { "ambient": [0, 0, 0], "diffuse": [0, 0, 0], "specular": [0, 0, 0], "shininess": 1, "reflectivity": 0 },"#,
        1,
    );
    let e = SceneDesc::from_json(&twice).unwrap_err();
    assert_eq!(e.path, "materials.red", "{e}");
    assert!(e.message.contains("duplicate material name \"red\""), "{e}");

    let radius = r#""radius": 1"#;
    assert!(SEED_ROOM_JSON.contains(radius));
    let e =
        SceneDesc::from_json(&SEED_ROOM_JSON.replacen(radius, r#""radius": 1, "radius": 2"#, 1))
            .unwrap_err();
    assert_eq!(e.path, "objects[7].radius", "{e}");
    assert!(e.message.contains("duplicate key"), "{e}");

    let e = SceneDesc::from_json(&SEED_ROOM_JSON.replacen(
        r#""format": 1"#,
        r#""format": 1, "format": 1"#,
        1,
    ))
    .unwrap_err();
    assert_eq!(e.path, "format", "{e}");
}

#[test]
fn long_values_are_cut_in_error_lines() {
    let long = "x".repeat(10_000_000);
    let unknown =
        SEED_ROOM_JSON.replacen(r#""format": 1"#, &format!(r#""format": 1, "{long}": 0"#), 1);
    let material = SEED_ROOM_JSON.replacen(
        r#""material": "white""#,
        &format!(r#""material": "{long}""#),
        1,
    );
    let name = SEED_ROOM_JSON.replacen(
        r#""materials": {"#,
        &format!(r#""materials": {{ "{long}": {{ "shininess": -1, "ambient": [0, 0, 0], "diffuse": [0, 0, 0], "specular": [0, 0, 0], "reflectivity": 0 }},"#),
        1,
    );
    for text in [&unknown, &material, &name] {
        assert!(text.len() > 10_000_000);
    }
    for (what, text) in [
        ("unknown key", unknown),
        ("unknown material", material),
        ("material name", name),
    ] {
        let e = SceneDesc::from_json(&text).unwrap_err().to_string();
        assert!(e.len() < 2000, "{what}: a line of {} bytes", e.len());
        assert!(e.contains("(10000000 characters)"), "{what}: {e}");
    }
}

#[test]
fn a_byte_order_mark_is_accepted() {
    let dir = scratch();
    let path = dir.path().join("bom.json");
    std::fs::write(&path, format!("\u{feff}{SEED_ROOM_JSON}")).unwrap();
    let desc = SceneDesc::load(&path).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(desc, SceneDesc::from_json(SEED_ROOM_JSON).unwrap());
}

#[test]
fn compare_refuses_non_finite_pixels_with_count_and_position() {
    let dir = scratch();
    let mut film = Film::new(5, 4);
    film.pixels[7] = glam::Vec3::new(0.0, f32::NAN, 0.0);
    film.pixels[12] = glam::Vec3::splat(f32::NEG_INFINITY);
    // Written by hand: write_film itself refuses such a film.
    let data: Vec<f32> = film.pixels.iter().flat_map(|p| p.to_array()).collect();
    let nan = dir.path().join("nan.exr");
    image::Rgb32FImage::from_raw(5, 4, data)
        .unwrap()
        .save(&nan)
        .unwrap();
    let fine = dir.path().join("fine.exr");
    penumbra::render::output::write_film(&Film::new(5, 4), &fine).unwrap();
    let diff = dir.path().join("d.png");
    let r = penumbra(&[
        "compare",
        fine.to_str().unwrap(),
        nan.to_str().unwrap(),
        "--diff",
        diff.to_str().unwrap(),
    ]);
    let err = common::refused(&r, "");
    assert!(
        err.contains("nan.exr: 2 pixels are NaN or infinite, the first at (2, 1)"),
        "{err}"
    );
    assert!(!diff.exists());
}

/// Finite pixels near f32's limit differ by more than f32 holds: the
/// figures and the difference image's scale are still finite and right.
#[test]
fn compare_of_huge_finite_values_gives_finite_figures() {
    let dir = scratch();
    let (a, b) = (dir.path().join("a.exr"), dir.path().join("b.exr"));
    let mut film = Film::new(4, 3);
    film.pixels.fill(glam::Vec3::splat(3.4e38));
    penumbra::render::output::write_film(&film, &a).unwrap();
    film.pixels.fill(glam::Vec3::splat(-3.4e38));
    film.pixels[5] = glam::Vec3::splat(3.4e38);
    penumbra::render::output::write_film(&film, &b).unwrap();
    let diff = dir.path().join("d.png");
    let out = common::penumbra_ok(&[
        "compare",
        a.to_str().unwrap(),
        b.to_str().unwrap(),
        "--diff",
        diff.to_str().unwrap(),
    ]);
    let figure = |name: &str| -> f64 {
        let line = out.lines().find(|l| l.starts_with(name)).unwrap();
        line.split_whitespace().nth(1).unwrap().parse().unwrap()
    };
    // 11 of 12 pixels differ by 6.8e38 in each channel.
    let rmse = 6.8e38 * (11.0f64 / 12.0).sqrt();
    assert!((figure("rmse") / rmse - 1.0).abs() < 1e-6, "{out}");
    assert!((figure("psnr") + 20.0 * rmse.log10()).abs() < 0.01, "{out}");
    assert!(
        out.contains("max_diff 6.800000e38 at pixel (0, 0)"),
        "{out}"
    );
    assert!(out.contains("white = 6.800e38)"), "{out}");
    let rgb = image::open(&diff).unwrap().into_rgb8().into_raw();
    let white = rgb.chunks(3).filter(|p| *p == [255, 255, 255]).count();
    let black = rgb.chunks(3).filter(|p| *p == [0, 0, 0]).count();
    assert_eq!((white, black), (11, 1));
}

#[test]
fn compare_decodes_by_content_and_exits_2_for_a_bad_diff_name() {
    let dir = scratch();
    let d = dir.path();
    let png = d.join("a.png");
    let r = penumbra(&[
        "render",
        "-o",
        png.to_str().unwrap(),
        "--width",
        "16",
        "--height",
        "9",
    ]);
    assert!(r.status.success());
    // PNG bytes under an .exr name: decoded as the PNG they are.
    let disguised = d.join("a.exr");
    std::fs::copy(&png, &disguised).unwrap();
    let out = common::penumbra_ok(&[
        "compare",
        png.to_str().unwrap(),
        disguised.to_str().unwrap(),
    ]);
    assert!(out.starts_with("rmse 0.000000e0"), "{out}");
    // The name says what is written: one without .png is refused as such
    // (not as though the file were some PNG).
    for name in ["x.jpg", "x.exr", "noext", "/dev/null"] {
        let target = d.join(name);
        let r = penumbra(&[
            "compare",
            png.to_str().unwrap(),
            png.to_str().unwrap(),
            "--diff",
            target.to_str().unwrap(),
        ]);
        common::refused(&r, name);
        assert_eq!(
            stderr(&r),
            format!(
                "penumbra: {}: --diff writes a PNG: the name must end in .png\n",
                target.display()
            )
        );
        assert!(name.starts_with('/') || !target.exists());
    }
    let r = render_tiny(&d.join("x.jpg"));
    assert_eq!(r.status.code(), Some(2));
}

/// The built-in seed room rendered 8×8 to `out`.
fn render_tiny(out: &Path) -> std::process::Output {
    penumbra(&[
        "render",
        "-o",
        out.to_str().unwrap(),
        "--width",
        "8",
        "--height",
        "8",
    ])
}

#[test]
fn an_existing_output_is_replaced_whole_and_keeps_its_permissions() {
    use std::os::unix::fs::PermissionsExt;
    let dir = scratch();
    let out = dir.path().join("x.png");
    assert!(render_tiny(&out).status.success());
    std::fs::set_permissions(&out, std::fs::Permissions::from_mode(0o600)).unwrap();
    let r = penumbra(&[
        "render",
        "-o",
        out.to_str().unwrap(),
        "--width",
        "16",
        "--height",
        "8",
    ]);
    assert!(r.status.success(), "{}", stderr(&r));
    let film = penumbra::render::output::read_film(&out).unwrap();
    assert_eq!((film.width, film.height), (16, 8));
    let mode = std::fs::metadata(&out).unwrap().permissions().mode();
    assert_eq!(mode & 0o777, 0o600);
    assert_eq!(files_in(dir.path()), ["x.png"]);

    // A folder named like an image is neither replaced nor moved away.
    let folder = dir.path().join("f.png");
    std::fs::create_dir(&folder).unwrap();
    let r = render_tiny(&folder);
    common::refused(&r, "");
    assert!(
        stderr(&r).contains("the output is a folder, not a file"),
        "{}",
        stderr(&r)
    );
    assert!(folder.is_dir());
    assert_eq!(files_in(dir.path()), ["f.png", "x.png"]);
}

#[test]
fn a_missing_output_folder_is_named_before_rendering_without_the_temporary_file() {
    let dir = scratch();
    let out = dir.path().join("no/such/folder/x.png");
    let r = render_tiny(&out);
    // Refused before rendering, as bad input.
    let err = common::refused(&r, "a missing folder");
    assert!(err.contains("there is no folder"), "{err}");
    assert!(err.contains("no/such/folder"), "{err}");
    assert!(
        !err.contains(".part") && !err.contains(".penumbra-"),
        "{err}"
    );
}

#[test]
fn the_summary_line_counts_loading() {
    let dir = scratch();
    let out = dir.path().join("x.png");
    let r = render_tiny(&out);
    let err = stderr(&r);
    assert!(r.status.success(), "{err}");
    // "8×8 in R s: … ; T s in all with L s loading and W s writing" with
    // T >= L + R + W: the line's last part counts the loading and the
    // writing, each measured on its own.
    let number_before = |text: &str, words: &str| -> f64 {
        let at = text
            .find(words)
            .unwrap_or_else(|| panic!("{words:?} in {text}"));
        let head = &text[..at];
        let from = head.rfind(' ').map_or(0, |i| i + 1);
        head[from..].parse().unwrap()
    };
    let rendering = number_before(&err, " s: ");
    let total = number_before(&err, " s in all");
    let loading = number_before(&err, " s loading");
    let writing = number_before(&err, " s writing");
    assert!(total + 0.002 >= loading + rendering + writing, "{err}");
}

// ---------------------------------------------------------------- item 8

fn camera_in_light_plane(lift: f64) -> SceneDesc {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/stress/camera-in-light-plane.json");
    let mut d = SceneDesc::load(&path).unwrap();
    assert_eq!(
        d.camera.position[1], d.light.corner[1],
        "the camera is in the light's plane"
    );
    d.camera.position[1] += lift;
    d.camera.look_at[1] += lift;
    d
}

#[test]
fn the_nearest_point_model_is_continuous_as_the_camera_reaches_the_lights_plane() {
    let at = render(&camera_in_light_plane(0.0));
    let centre_row = at.height / 2;
    for lift in [1e-12, 1e-9, 1e-5] {
        let above = render(&camera_in_light_plane(lift));
        let c = compare(&at, &above).unwrap();
        // Left out: the row that looks along the plane (it grazes the sand
        // box's top, which lies in it), and single pixels whose ray meets
        // an edge of the room exactly.
        let off: Vec<(u32, u32)> = (0..at.pixels.len() as u32)
            .map(|i| (i % at.width, i / at.width))
            .filter(|&(x, y)| {
                y != centre_row && (at.get(x, y) - above.get(x, y)).abs().max_element() > 1e-3
            })
            .collect();
        assert!(
            off.len() <= 8,
            "lift {lift:e}: {} pixels differ, e.g. {:?} (rmse {:e})",
            off.len(),
            &off[..off.len().min(8)],
            c.rmse
        );
    }
}

// ------------------------------------------------- attacks of a later round

/// An output (or `--stats` file) that is a FIFO no one reads: the write
/// waits for a reader, as a blocking open would, but SIGTERM ends it (a
/// blocking open slept through the signal, whose handler only raises a
/// flag).
#[test]
fn sigterm_ends_a_write_to_a_fifo_that_no_one_reads() {
    for stats in [false, true] {
        let dir = scratch();
        let fifo = dir
            .path()
            .join(if stats { "stats.json" } else { "out.png" });
        mkfifo(&fifo);
        let mut cmd = bin();
        cmd.args(["render", "--width", "16", "--height", "9", "-o"]);
        if stats {
            cmd.arg(dir.path().join("x.exr")).arg("--stats").arg(&fifo);
        } else {
            cmd.arg(&fifo);
        }
        let mut child = cmd.stderr(Stdio::piped()).spawn().unwrap();
        // Time to render and reach the open.
        std::thread::sleep(Duration::from_millis(1500));
        assert!(child.try_wait().unwrap().is_none(), "stats {stats}: waits");
        let sent = Command::new("kill")
            .args(["-TERM", &child.id().to_string()])
            .status()
            .unwrap();
        assert!(sent.success());
        let start = Instant::now();
        while child.try_wait().unwrap().is_none() {
            assert!(
                start.elapsed() < Duration::from_secs(10),
                "stats {stats}: still waiting after SIGTERM"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
        let o = child.wait_with_output().unwrap();
        assert_eq!(o.status.code(), Some(1), "stats {stats}: {}", stderr(&o));
        assert!(stderr(&o).contains("interrupted"), "{}", stderr(&o));
    }
}

/// A FIFO that is read gets the image, as before.
#[test]
fn a_fifo_with_a_reader_gets_the_image() {
    let dir = scratch();
    let fifo = dir.path().join("out.png");
    mkfifo(&fifo);
    let reader = {
        let fifo = fifo.clone();
        std::thread::spawn(move || std::fs::read(&fifo).unwrap())
    };
    let o = penumbra(&[
        "render",
        "--width",
        "16",
        "--height",
        "9",
        "-o",
        fifo.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let bytes = reader.join().unwrap();
    assert!(bytes.starts_with(b"\x89PNG"), "{} bytes", bytes.len());
}

/// An image too large for the memory the process may have is refused
/// before rendering (exit 2), where the film's allocation failing would
/// abort; the limit is the address space `ulimit -v` sets.
#[test]
fn an_image_too_large_for_the_memory_limit_is_refused_with_exit_2() {
    let dir = scratch();
    let out = dir.path().join("big.exr");
    std::fs::write(&out, b"precious").unwrap();
    let o = penumbra_within_memory(
        2_000_000,
        &[
            "render",
            "--width",
            "16384",
            "--height",
            "16384",
            "--threads",
            "2",
            "-o",
            out.to_str().unwrap(),
        ],
    );
    let err = common::refused(&o, "");
    // The film and the EXR's buffer (6.4 GB), and room for the threads.
    assert!(
        err.contains("16384×16384 needs about 6.5 GB of memory"),
        "{err}"
    );
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert_eq!(std::fs::read(&out).unwrap(), b"precious");
}

/// An image file too large to decode in the memory the process may have
/// is refused (exit 2, one line naming the file) before its pixels are
/// allocated: `compare` and `merge` aborted with "memory allocation of N
/// bytes failed" and a backtrace (exit 134). Each limit sits between the
/// file's bytes and the bytes and the decoder's buffers, with margin for
/// the process's own.
#[test]
fn an_image_too_large_to_read_in_the_memory_limit_is_refused_with_exit_2() {
    let dir = scratch();
    let file = |name: &str| dir.path().join(name).to_str().unwrap().to_owned();
    let size = ["--width", "2000", "--height", "1500", "--shadow-rays", "1"];
    for (name, extra) in [
        ("whole.exr", &[][..]),
        ("whole.png", &[][..]),
        ("part.exr", &["--region", "0,0,2000,1500"][..]),
    ] {
        let out = file(name);
        let args: Vec<&str> = ["render", "--depth", "1", "-o", &out]
            .iter()
            .chain(&size)
            .chain(extra)
            .copied()
            .collect();
        let o = penumbra(&args);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    // A 36 MB EXR decodes through 72 MB of buffers; a PNG through 45 MB;
    // a part's 36 MB into a 36 MB film.
    let (exr, png, part, merged) = (
        file("whole.exr"),
        file("whole.png"),
        file("part.exr"),
        file("merged.exr"),
    );
    let cases: [(u64, &str, Vec<&str>); 3] = [
        (90_000, "whole.exr", vec!["compare", &exr, &exr]),
        (50_000, "whole.png", vec!["compare", &png, &png]),
        (75_000, "part.exr", vec!["merge", &part, "-o", &merged]),
    ];
    for (kib, name, args) in cases {
        let o = penumbra_within_memory(kib, &args);
        let err = common::refused(&o, format!("{args:?}"));
        assert!(err.contains(&format!("{name}: ")), "{err}");
        assert!(
            err.contains("needs about") && err.contains("more than this process can have"),
            "{err}"
        );
        assert_eq!(err.trim().lines().count(), 1, "{err}");
    }
    assert!(!Path::new(&merged).exists());
    // Without the limit, the same commands read them.
    for args in [
        vec!["compare", &exr, &png],
        vec!["merge", &part, "-o", &merged],
    ] {
        let o = penumbra(&args);
        assert!(o.status.success(), "{args:?}: {}", stderr(&o));
    }
}

/// An EXR larger than the image decoder's default 512 MiB (RGB f32) reads
/// back: `compare` and the viewer take the images `render` writes, up to
/// 16384².
#[test]
fn an_exr_beyond_the_decoders_default_limit_reads_back() {
    use penumbra::render::output::{read_film, write_film};
    let dir = scratch();
    let path = dir.path().join("wide.exr");
    // 45.9 M pixels: 551 MB as RGB f32.
    let mut film = Film::new(16384, 2800);
    film.pixels[16384 * 2799 + 16383] = glam::Vec3::new(0.25, 0.5, 1.0);
    write_film(&film, &path).unwrap();
    let back = read_film(&path).unwrap();
    assert_eq!((back.width, back.height), (16384, 2800));
    assert_eq!(
        back.pixels[16384 * 2799 + 16383],
        glam::Vec3::new(0.25, 0.5, 1.0)
    );
}

/// `fifo` opened for writing once a reader has it open (until then a
/// non-blocking open fails): the reader is then past its start, its
/// signal handlers set, and waits for the bytes.
fn writer_once_read(fifo: &Path, reader: &mut std::process::Child) -> std::fs::File {
    use std::os::unix::fs::OpenOptionsExt;
    let start = Instant::now();
    loop {
        let opened = std::fs::OpenOptions::new()
            .write(true)
            .custom_flags(libc::O_NONBLOCK)
            .open(fifo);
        if let Ok(file) = opened {
            return file;
        }
        assert!(reader.try_wait().unwrap().is_none(), "ended before reading");
        assert!(start.elapsed() < Duration::from_secs(60), "never opened");
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// `merge` and `compare` stopped by SIGINT, SIGTERM or SIGHUP say so and
/// exit 1, as `render` does (they ended silently with 130 or 143): while
/// reading a part or an image (a FIFO a writer holds open) and while
/// writing (a FIFO output no one reads). The target is untouched.
#[test]
fn an_interrupted_merge_or_compare_says_so_and_exits_1() {
    let dir = scratch();
    let part = dir.path().join("part.exr");
    let o = penumbra(&[
        "render",
        "--width",
        "16",
        "--height",
        "9",
        "--region",
        "0,0,16,9",
        "-o",
        part.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let target = dir.path().join("whole.exr");
    std::fs::write(&target, b"precious").unwrap();
    let (input, output) = (dir.path().join("in.exr"), dir.path().join("out.png"));
    mkfifo(&input);
    mkfifo(&output);
    let diff = dir.path().join("diff.png");
    let (part, target, diff, input_s, output_s) = (
        part.to_str().unwrap(),
        target.to_str().unwrap(),
        diff.to_str().unwrap(),
        input.to_str().unwrap(),
        output.to_str().unwrap(),
    );
    let no_image = "penumbra: interrupted: no image written";
    let no_diff = "penumbra: interrupted: no difference image written";
    let reading: [(&[&str], &str, &str); 3] = [
        (&["merge", input_s, part, "-o", target], "TERM", no_image),
        (&["compare", part, input_s, "--diff", diff], "INT", no_diff),
        (&["compare", input_s, part], "HUP", "penumbra: interrupted"),
    ];
    for (args, signal, said) in reading {
        let mut child = bin().args(args).stderr(Stdio::piped()).spawn().unwrap();
        let writer = writer_once_read(&input, &mut child);
        let sent = Command::new("kill")
            .args([&format!("-{signal}"), &child.id().to_string()])
            .status()
            .unwrap();
        assert!(sent.success());
        let o = child.wait_with_output().unwrap();
        drop(writer);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {}", stderr(&o));
        assert_eq!(stderr(&o).trim(), said, "{args:?}");
    }
    let writing: [(&[&str], &str); 2] = [
        (&["merge", part, "-o", output_s], no_image),
        (&["compare", part, part, "--diff", output_s], no_diff),
    ];
    for (args, said) in writing {
        let mut child = bin().args(args).stderr(Stdio::piped()).spawn().unwrap();
        // Time to read the part and reach the output's open.
        std::thread::sleep(Duration::from_millis(1500));
        assert!(child.try_wait().unwrap().is_none(), "{args:?}: waits");
        let sent = Command::new("kill")
            .args(["-TERM", &child.id().to_string()])
            .status()
            .unwrap();
        assert!(sent.success());
        let o = child.wait_with_output().unwrap();
        assert_eq!(o.status.code(), Some(1), "{args:?}: {}", stderr(&o));
        assert_eq!(stderr(&o).trim(), said, "{args:?}");
    }
    assert_eq!(std::fs::read(target).unwrap(), b"precious");
    assert_eq!(
        files_in(dir.path()),
        ["in.exr", "out.png", "part.exr", "whole.exr"]
    );
}

/// A stderr that cannot be written (`2>/dev/full`) changes nothing: the
/// image is written and the exit code is the command's own (0, 2 for bad
/// input, 1 for I/O), where the failed message used to panic (exit 101).
#[test]
fn a_full_stderr_keeps_the_exit_code() {
    let dir = scratch();
    let out = dir.path().join("x.png");
    let exit_with_full_stderr = |args: &[&str]| {
        let full = std::fs::OpenOptions::new()
            .write(true)
            .open("/dev/full")
            .unwrap();
        bin().args(args).stderr(full).status().unwrap().code()
    };
    let render_to = |output: &str| {
        exit_with_full_stderr(&["render", "--width", "8", "--height", "8", "-o", output])
    };
    assert_eq!(render_to(out.to_str().unwrap()), Some(0));
    assert!(out.exists());
    let jpg = dir.path().join("x.jpg");
    assert_eq!(render_to(jpg.to_str().unwrap()), Some(2));
    // A folder that is there but cannot be written: an I/O failure.
    assert_eq!(render_to("/proc/x.png"), Some(1));
}

/// A full standard output (`>/dev/full`) or a closed pipe (`| head -1`)
/// under `bench` and `generate`: the bench runs to its end and writes its
/// files, then says what failed (exit 1); a closed pipe is no error; both
/// used to panic (exit 101) at the first line.
#[test]
fn a_full_or_closed_stdout_is_reported_not_panicked() {
    let dir = scratch();
    let full = || {
        std::fs::OpenOptions::new()
            .write(true)
            .open("/dev/full")
            .unwrap()
    };
    let bench = [
        "bench",
        "--quick",
        "--width",
        "16",
        "--counts",
        "1",
        "--runs",
        "1",
        "--out",
        dir.path().to_str().unwrap(),
        "--cache",
        dir.path().to_str().unwrap(),
    ];
    let o = bin().args(bench).stdout(full()).output().unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert_eq!(
        stderr(&o).lines().last(),
        Some("penumbra: standard output: No space left on device (os error 28)")
    );
    assert!(dir.path().join("bench-seed-room.csv").exists());

    // The reader gone after the first line.
    let mut child = bin()
        .args(bench)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut first = [0u8; 8];
    std::io::Read::read_exact(child.stdout.as_mut().unwrap(), &mut first).unwrap();
    drop(child.stdout.take());
    let o = child.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(!stderr(&o).contains("panicked"), "{}", stderr(&o));

    let obj = dir.path().join("t.obj");
    let o = bin()
        .args(["generate", "--triangles", "18", "-o", obj.to_str().unwrap()])
        .stdout(full())
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("No space left on device"),
        "{}",
        stderr(&o)
    );
}

/// A signal while `render` reads its scene (standard input that never
/// ends) ends it promptly with exit 1 and the one line, as during the
/// render; it used to end it silently with 143.
#[test]
fn sigterm_while_render_reads_its_scene_says_so_and_exits_1() {
    let dir = scratch();
    let out = dir.path().join("x.png");
    let mut child = bin()
        .args(["render", "-", "-o", out.to_str().unwrap()])
        .stdin(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    stdin.write_all(b"{\"camera\": ").unwrap();
    // Time to start and block in the read.
    std::thread::sleep(Duration::from_millis(1000));
    assert!(child.try_wait().unwrap().is_none(), "waits for the scene");
    let sent = Instant::now();
    let killed = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let o = child.wait_with_output().unwrap();
    assert!(
        sent.elapsed() < Duration::from_secs(5),
        "{:?}",
        sent.elapsed()
    );
    drop(stdin);
    assert_eq!(o.status.code(), Some(1), "{:?}: {}", o.status, stderr(&o));
    assert_eq!(stderr(&o).trim(), "penumbra: interrupted: no image written");
    assert_eq!(files_in(dir.path()), Vec::<String>::new());
}

/// A size that passed the memory check aborted (SIGABRT, exit 134): the
/// film's allocation failed when the check left out threads' address
/// space (their malloc arenas, made as they first run), and a noisy
/// image's PNG write failed when the encoder held the whole compressed
/// image (as large as its codes) in memory. Down from a size well beyond
/// 1 GB, every size is refused with exit 2 until the largest that passes
/// the check, which renders: the size at the check's edge. Once for a
/// smooth image, once for a noisy one (one random shadow ray a pixel).
#[test]
fn a_render_that_passes_the_memory_check_does_not_abort() {
    let dir = scratch();
    let out = dir.path().join("big.png");
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/stress/box-on-floor.json");
    let smooth = ["render", scene.to_str().unwrap()];
    let noisy = ["render", "--sampling", "random"];
    for (case, first) in [("smooth", &smooth[..]), ("noisy", &noisy[..])] {
        let render = |side: &str| {
            let mut args = first.to_vec();
            args.extend([
                "--width",
                side,
                "--height",
                side,
                "--shadow-rays",
                "1",
                "--depth",
                "1",
                "--threads",
                "2",
                "-o",
                out.to_str().unwrap(),
            ]);
            penumbra_within_memory(1_000_000, &args)
        };
        // 12 bytes a pixel of film and 3 of PNG codes: 1 GB holds about 8100².
        let mut rendered = None;
        for side in (6000..=9000).rev().step_by(25) {
            let o = render(&side.to_string());
            match o.status.code() {
                Some(2) => {
                    let err = stderr(&o);
                    let expected = format!("{side}×{side} needs about");
                    assert!(err.contains(&expected), "{case} {side}: {err}");
                }
                Some(0) => {
                    rendered = Some(side);
                    break;
                }
                _ => panic!("{case} {side}: {:?}: {}", o.status, stderr(&o)),
            }
        }
        let side = rendered.expect("a size from 6000² up renders in 1 GB");
        assert!(side < 9000, "{case}: 9000² is refused");
        assert_eq!(
            image::image_dimensions(&out).unwrap(),
            (side, side),
            "{case}"
        );
    }
}

/// A large mesh under any memory limit from ample down to too little
/// renders or is refused with exit 2 and one line naming the scene (and
/// the mesh or the scene's trees): its trees, or its parse, aborted
/// (SIGABRT, exit 134) when an allocation failed. The trees are checked
/// before they are built; a parse that runs out is ended by the allocator.
#[test]
fn a_large_mesh_under_any_memory_limit_renders_or_is_refused() {
    let dir = scratch();
    let (mesh, scene) = (dir.path().join("torus.obj"), dir.path().join("room.json"));
    generated_mesh_room("500000", &mesh, &scene);
    let out = dir.path().join("x.png");
    let (mut rendered, mut out_of_memory, mut trees) = (0, 0, 0);
    for kib in (40_000..=200_000).rev().step_by(10_000) {
        let o = penumbra_within_memory(
            kib,
            &[
                "render",
                scene.to_str().unwrap(),
                "--width",
                "64",
                "--height",
                "36",
                "-o",
                out.to_str().unwrap(),
            ],
        );
        let err = stderr(&o);
        match o.status.code() {
            Some(0) => rendered += 1,
            Some(2) => {
                // After the mesh's count ("triangles: …"), one error line.
                let errors: Vec<&str> = err
                    .lines()
                    .filter(|l| l.starts_with("penumbra: "))
                    .collect();
                assert_eq!(errors.len(), 1, "{kib} KiB: {err}");
                assert_eq!(
                    err.trim().lines().last(),
                    Some(errors[0]),
                    "{kib} KiB: {err}"
                );
                assert!(
                    err.contains("more than this process can have"),
                    "{kib} KiB: {err}"
                );
                if err.contains("room.json: objects: the trees of ")
                    && err.contains(" objects and triangles need about")
                {
                    trees += 1;
                }
                if err.contains("out of memory") {
                    out_of_memory += 1;
                    assert!(err.contains("room.json: "), "{kib} KiB: {err}");
                    let named = err.contains(".file \"torus.obj\"") || err.contains("the trees of");
                    assert!(named, "{kib} KiB: {err}");
                }
            }
            _ => panic!("{kib} KiB: {:?}: {err}", o.status),
        }
    }
    assert!(
        rendered > 0 && trees > 0 && out_of_memory > 0,
        "{rendered} rendered, {trees} refused for the trees, {out_of_memory} out of memory"
    );
    assert_eq!(files_in(dir.path()).len(), 3, "{:?}", files_in(dir.path()));
}

/// A bench whose renders are too large for the memory the process may
/// have is refused before any render (exit 2, one line), as `render` is:
/// it aborted (SIGABRT, exit 134) when a film's allocation failed. Every
/// mode checks its largest size (`--target` its own 1920×1080).
#[test]
fn a_bench_too_large_for_the_memory_limit_is_refused_with_exit_2() {
    let dir = scratch();
    let (cache, out) = (dir.path().join("cache"), dir.path().join("out"));
    let (cache, out) = (cache.to_str().unwrap(), out.to_str().unwrap());
    let big = ["--width", "16384", "--height", "16384", "--threads", "2"];
    let with = |mode: &[&str], extra: &[&str]| -> Vec<String> {
        let mut args = vec!["bench"];
        args.extend_from_slice(mode);
        args.extend_from_slice(extra);
        args.iter().map(|s| s.to_string()).collect()
    };
    let cases = [
        with(
            &[
                "--counts", "1", "--runs", "1", "--cache", cache, "--out", out,
            ],
            &big,
        ),
        with(
            &["--exact", "--runs", "5", "--cache", cache, "--out", out],
            &big,
        ),
        with(&["--spp-split", "--runs", "1", "--cache", cache], &big),
        with(&["--slopes"], &big),
        with(&["--edits"], &big),
        with(&["--meshes", "18", "--runs", "1"], &big),
        with(&["--spheres", "10", "--scaling", "--runs", "1"], &big),
        with(
            &[
                "--spheres",
                "10",
                "--counts",
                "1",
                "--runs",
                "1",
                "--cache",
                cache,
                "--out",
                out,
            ],
            &big,
        ),
    ];
    for args in &cases {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = penumbra_within_memory(2_000_000, &args);
        let err = common::refused(&o, format!("{args:?}"));
        assert!(
            err.contains("16384×16384 needs about")
                && err.contains("more than this process can have"),
            "{args:?}: {err}"
        );
        assert_eq!(err.trim().lines().count(), 1, "{args:?}: {err}");
        assert!(!String::from_utf8_lossy(&o.stdout).contains("reference"));
    }
    // `--target` renders 1920×1080 whatever the scene's size.
    let o = penumbra_within_memory(150_000, &["bench", "--target", "--threads", "2"]);
    let err = common::refused(&o, "");
    assert!(err.contains("1920×1080 needs about"), "{err}");
    assert_eq!(files_in(dir.path()), Vec::<String>::new());
}
