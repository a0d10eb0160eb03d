//! Hostile input: a generator of broken scene files — truncated JSON, wrong
//! types, NaN/Inf literals, 1e308 and 1e400, huge arrays, deep nesting,
//! unknown keys, missing materials, negative and zero sizes, more work than
//! the cap — each refused with a message naming the field's JSON path and
//! never a panic; through the CLI, exit code 2 and no output file, and an
//! existing output untouched by a failed or interrupted render.

mod common;

use std::process::Command;

use common::{files_in, penumbra};

use penumbra::render::SEED_ROOM_JSON;
use penumbra::render::scene_file::limits;
use penumbra::render::{SceneDesc, SceneError};
use serde_json::{Value, json};

fn seed() -> Value {
    serde_json::from_str(SEED_ROOM_JSON).unwrap()
}

/// The value at a path like `objects[7].radius` (created if missing).
fn at<'a>(v: &'a mut Value, path: &str) -> &'a mut Value {
    let mut v = v;
    for part in path.split('.') {
        let (key, index) = match part.find('[') {
            Some(i) => (
                &part[..i],
                Some(part[i + 1..part.len() - 1].parse::<usize>().unwrap()),
            ),
            None => (part, None),
        };
        if !key.is_empty() {
            v = &mut v[key];
        }
        if let Some(i) = index {
            v = &mut v[i];
        }
    }
    v
}

/// A broken scene: its JSON text and the path its error must name.
struct Case {
    what: String,
    text: String,
    path: String,
}

/// The seed room with the value at `path` replaced by `value`.
fn set(path: &str, value: Value, expect: &str) -> Case {
    let mut v = seed();
    *at(&mut v, path) = value.clone();
    Case {
        what: format!("{path} = {value}"),
        text: v.to_string(),
        path: expect.into(),
    }
}

/// The seed room with the value at `path` replaced by raw JSON text (for
/// what serde_json cannot hold: NaN, Infinity, 1e400, malformed text).
fn raw(path: &str, literal: &str, expect: &str) -> Case {
    let mut v = seed();
    *at(&mut v, path) = json!("@@HOLE@@");
    Case {
        what: format!("{path} = {literal}"),
        text: v.to_string().replace("\"@@HOLE@@\"", literal),
        path: expect.into(),
    }
}

/// The seed room without the key at `path`.
fn remove(path: &str, expect: &str) -> Case {
    let mut v = seed();
    let (parent, key) = path.rsplit_once('.').unwrap_or(("", path));
    let p = if parent.is_empty() {
        &mut v
    } else {
        at(&mut v, parent)
    };
    p.as_object_mut().unwrap().remove(key).expect("key exists");
    Case {
        what: format!("without {path}"),
        text: v.to_string(),
        path: expect.into(),
    }
}

fn nested(depth: usize, leaf: &str) -> String {
    format!("{}{leaf}{}", "[".repeat(depth), "]".repeat(depth))
}

/// Every broken scene of the generator, with the path its error must name.
fn cases() -> Vec<Case> {
    let mut c = vec![
        // Wrong types.
        set("format", json!("1"), "format"),
        set("camera", json!(null), "camera"),
        set("camera.width", json!("960"), "camera.width"),
        set("camera.width", json!(960.5), "camera.width"),
        set("camera.width", json!(-960), "camera.width"),
        set("camera.position", json!([0, 4]), "camera.position"),
        set("camera.position", json!([0, 4, -14, 1]), "camera.position"),
        set("camera.position[1]", json!(true), "camera.position[1]"),
        set("render.shadow_rays", json!(-1), "render.shadow_rays"),
        set("render.sampling", json!(3), "render.sampling"),
        set("render.sampling", json!("sobol-ish"), "render.sampling"),
        set("render.seed", json!(1.5), "render.seed"),
        set("light.corner", json!({"x": 0}), "light.corner"),
        set("materials", json!([]), "materials"),
        set(
            "materials.white.shininess",
            json!([]),
            "materials.white.shininess",
        ),
        set("objects", json!({}), "objects"),
        set("objects[3]", json!(7), "objects[3]"),
        set("objects[7].type", json!(5), "objects[7].type"),
        set("objects[7].type", json!("torus"), "objects[7].type"),
        set("objects[7].radius", json!("1"), "objects[7].radius"),
        set(
            "objects[5].rotate_y_deg",
            json!(null),
            "objects[5].rotate_y_deg",
        ),
        // Non-finite literals (not JSON, but people write them).
        raw("camera.position[0]", "NaN", "camera.position[0]"),
        raw("light.corner[1]", "Infinity", "light.corner[1]"),
        raw("objects[7].radius", "-Infinity", "objects[7].radius"),
        raw(
            "materials.red.ambient[2]",
            "nan",
            "materials.red.ambient[2]",
        ),
        // Huge numbers: 1e308 parses and is refused by range, 1e400 does
        // not parse as an f64.
        set("light.corner[1]", json!(1e308), "light.corner[1]"),
        set("objects[5].min[0]", json!(-1e308), "objects[5].min[0]"),
        set("objects[7].radius", json!(1e308), "objects[7].radius"),
        set(
            "materials.white.shininess",
            json!(1e308),
            "materials.white.shininess",
        ),
        set("render.terms.diffuse", json!(1e308), "render.terms.diffuse"),
        set("camera.fov_y_deg", json!(1e308), "camera.fov_y_deg"),
        set(
            "objects[6].rotate_y_deg",
            json!(1e308),
            "objects[6].rotate_y_deg",
        ),
        set("camera.width", json!(1e308), "camera.width"),
        raw("objects[0].normal[1]", "1e400", "objects[0].normal[1]"),
        raw("camera.look_at[2]", "-1e400", "camera.look_at[2]"),
        raw("render.shadow_rays", "1e400", "render.shadow_rays"),
        raw("render.seed", "99999999999999999999999", "render.seed"),
        // Zero and negative sizes.
        set("objects[7].radius", json!(0.0), "objects[7].radius"),
        set("objects[7].radius", json!(-1), "objects[7].radius"),
        // Unknown keys (misspellings are not silently ignored).
        set("camera.focus", json!(1), "camera.focus"),
        set("render.shadowrays", json!(16), "render.shadowrays"),
        set("render.terms.ambiant", json!(1), "render.terms.ambiant"),
        set("light.colour", json!([1, 1, 1]), "light.colour"),
        set(
            "materials.white.roughness",
            json!(1),
            "materials.white.roughness",
        ),
        set("objects[7].centre", json!([0, 0, 0]), "objects[7].centre"),
        set("extra", json!({}), "extra"),
        // Missing parts and missing materials.
        remove("materials", ""),
        remove("camera.width", "camera"),
        remove("light.edge_v", "light"),
        remove("objects[7].material", "objects[7]"),
        remove("objects[7].type", "objects[7]"),
        set("materials", json!({}), "objects[0].material"),
        set(
            "objects[7].material",
            json!("chrome"),
            "objects[7].material",
        ),
        set("objects[7].material", json!(""), "objects[7].material"),
        // Negative and zero sizes, degenerate shapes, out-of-range settings.
        set("camera.width", json!(0), "camera.width"),
        set(
            "camera.height",
            json!(limits::MAX_SIDE + 1),
            "camera.height",
        ),
        set("camera.fov_y_deg", json!(0), "camera.fov_y_deg"),
        set("camera.fov_y_deg", json!(180), "camera.fov_y_deg"),
        set("camera.look_at", json!([0, 4, -14]), "camera.look_at"),
        set("camera.up", json!([0, -0.5, 14]), "camera.up"),
        set("camera.up", json!([0, 0, 0]), "camera.up"),
        set("render.shadow_rays", json!(0), "render.shadow_rays"),
        set("render.shadow_rays", json!(4097), "render.shadow_rays"),
        set("render.max_depth", json!(0), "render.max_depth"),
        set("render.max_depth", json!(17), "render.max_depth"),
        set("render.terms.specular", json!(-1), "render.terms.specular"),
        set("render.background[0]", json!(-0.5), "render.background[0]"),
        set("light.edge_u", json!([0, 0, 0]), "light.edge_u"),
        set("light.edge_v", json!([4, 0, 0]), "light.edge_v"),
        set("light.edge_v", json!([2, 0, 1e-12]), "light.edge_v"),
        set("light.diffuse[1]", json!(-1), "light.diffuse[1]"),
        set(
            "materials.white.shininess",
            json!(0),
            "materials.white.shininess",
        ),
        set(
            "materials.white.reflectivity",
            json!(1.5),
            "materials.white.reflectivity",
        ),
        set(
            "materials.white.reflectivity",
            json!(-0.1),
            "materials.white.reflectivity",
        ),
        set("objects[0].normal", json!([0, 0, 0]), "objects[0].normal"),
        set("objects[5].max", json!([1, -5, 1]), "objects[5].min[1]"),
        set("objects[1].point[2]", json!(2e9), "objects[1].point[2]"),
        set("format", json!(2), "format"),
    ];
    // Huge arrays.
    c.push(set(
        "camera.position",
        Value::Array(vec![json!(0); 1_000_000]),
        "camera.position",
    ));
    c.push(set(
        "objects",
        Value::Array(vec![json!(0); limits::MAX_OBJECTS + 1]),
        "objects",
    ));
    let many: serde_json::Map<String, Value> = (0..=limits::MAX_MATERIALS)
        .map(|i| (format!("m{i}"), seed()["materials"]["white"].clone()))
        .collect();
    c.push(set("materials", Value::Object(many), "materials"));
    // Deep nesting, as values and as the whole document.
    c.push(raw(
        "camera.position",
        &nested(100_000, "0"),
        "camera.position",
    ));
    c.push(raw("objects[2]", &nested(100_000, "{}"), "objects[2]"));
    c.push(raw(
        "materials.white",
        &format!("{}{}", "{\"a\":".repeat(100_000), "}".repeat(100_000)),
        "materials.white.a",
    ));
    c
}

fn refuse(text: &str) -> SceneError {
    match std::panic::catch_unwind(|| SceneDesc::from_json(text)) {
        Ok(Ok(_)) => panic!("accepted"),
        Ok(Err(e)) => e,
        Err(_) => panic!("panicked"),
    }
}

#[test]
fn every_generated_broken_scene_is_refused_with_its_field() {
    let mut failures = Vec::new();
    for case in cases() {
        let e = match std::panic::catch_unwind(|| refuse(&case.text)) {
            Ok(e) => e,
            Err(_) => {
                failures.push(format!("{}: accepted or panicked", case.what));
                continue;
            }
        };
        let message = e.to_string();
        let named = if case.path.is_empty() {
            e.path.is_empty()
        } else {
            e.path.starts_with(&case.path) && message.starts_with(&format!("{}: ", e.path))
        };
        // A clear message says what was wrong, not only where, in one short
        // line (no 309-digit numbers, no echo of a huge value).
        if !named || e.message.len() < 12 || e.message.len() > 240 || e.message.contains('\n') {
            failures.push(format!(
                "{}: expected path {:?}, got {message:?}",
                case.what, case.path
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Every range of the format may be used at its top at once (the format
/// says scenes within its ranges load): 16384² pixels × 1024 samples ×
/// 4096 shadow rays × depth 16 was refused as beyond a cap of 2^41 rays.
#[test]
fn a_scene_at_the_top_of_every_range_loads() {
    let mut v = seed();
    v["camera"]["width"] = json!(16384);
    v["camera"]["height"] = json!(16384);
    v["render"]["shadow_rays"] = json!(4096);
    v["render"]["max_depth"] = json!(16);
    v["render"]["samples_per_pixel"] = json!(1024);
    let desc = SceneDesc::from_json(&v.to_string()).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(
        (
            desc.camera.width,
            desc.render.shadow_rays,
            desc.render.samples_per_pixel
        ),
        (16384, 4096, 1024)
    );
}

#[test]
fn every_truncation_of_a_scene_is_refused() {
    // Every prefix of the seed room (compact and pretty), and the same
    // with the last byte changed to a stray character.
    for text in [SEED_ROOM_JSON.to_string(), seed().to_string()] {
        let text = text.trim_end();
        for end in 0..text.len() {
            if !text.is_char_boundary(end) {
                continue;
            }
            let e = refuse(&text[..end]);
            assert!(
                e.message.contains("EOF") || e.message.contains("expected"),
                "prefix {end}: {e}"
            );
            let mut broken = text[..end].to_string();
            broken.push('#');
            refuse(&broken);
        }
    }
}

#[test]
fn bad_files_are_refused_with_the_file_name() {
    let dir = scratch("files");
    let empty = dir.join("empty.json");
    std::fs::write(&empty, "").unwrap();
    let binary = dir.join("binary.json");
    std::fs::write(&binary, [0xff, 0xfe, 0x00, 0x7b]).unwrap();
    // Larger than the limit: a sparse file, nothing is written or read.
    let big = dir.join("big.json");
    std::fs::File::create(&big)
        .unwrap()
        .set_len(limits::MAX_FILE_BYTES + 1)
        .unwrap();
    for (path, words) in [
        (&empty, "EOF"),
        (&binary, "not UTF-8"),
        (&big, "at most"),
        (&dir.to_path_buf(), "a directory, not a regular file"),
        (&dir.join("missing.json"), "cannot read"),
    ] {
        let e = SceneDesc::load(path).unwrap_err();
        let message = e.to_string();
        assert!(
            message.starts_with(&path.display().to_string()),
            "{message}"
        );
        assert!(message.contains(words), "{message}");
    }
}

fn scratch(name: &str) -> common::Scratch {
    common::Scratch::new(&format!("hostile-{name}"))
}

#[test]
fn the_cli_refuses_broken_scenes_with_exit_2_and_writes_nothing() {
    let dir = scratch("cli");
    let all = cases();
    // A sample of every kind (the CLI runs a process per case).
    let sample: Vec<&Case> = all
        .iter()
        .filter(|c| c.text.len() < 100_000)
        .step_by(4)
        .collect();
    assert!(sample.len() > 15);
    for (i, case) in sample.iter().enumerate() {
        let scene = dir.join(format!("case{i}.json"));
        std::fs::write(&scene, &case.text).unwrap();
        let out = dir.join(format!("case{i}.png"));
        let o = penumbra(&[
            "render",
            scene.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{}: {err}", case.what);
        assert_eq!(err.lines().count(), 1, "{}: one line: {err}", case.what);
        assert!(
            err.contains(&format!("case{i}.json: {}", case.path)),
            "{}: {err}",
            case.what
        );
        assert!(!out.exists(), "{}: wrote {}", case.what, out.display());
    }
    // Only the scene files: no image, no temporary file.
    assert!(
        files_in(&dir).iter().all(|f| f.ends_with(".json")),
        "{:?}",
        files_in(&dir)
    );
}

#[test]
fn the_cli_refuses_bad_overrides_with_exit_2_and_keeps_an_existing_file() {
    let dir = scratch("overrides");
    let out = dir.join("keep.png");
    std::fs::write(&out, b"precious").unwrap();
    let o = out.to_str().unwrap();
    for (args, words) in [
        (vec!["--width", "16385", "--shadow-rays", "4096"], "--width"),
        (vec!["--scale", "0"], "--scale"),
        (vec!["--scale=-1"], "--scale"),
        (vec!["--scale", "NaN"], "--scale"),
        (vec!["--scale", "inf"], "--scale"),
        (vec!["--scale", "1e300"], "camera.position[1]"),
        (vec!["--translate", "1e300,0,0"], "camera.position[0]"),
        (vec!["--translate", "0,nan,0"], "nan"),
        (vec!["--terms", "1,-1,1"], "-1"),
        (vec!["--width", "0"], "0"),
    ] {
        let mut full = vec!["render", "-o", o];
        full.extend(&args);
        let r = penumbra(&full);
        let err = common::refused(&r, format!("{args:?}"));
        assert!(err.contains(words), "{args:?}: {err}");
        assert_eq!(std::fs::read(&out).unwrap(), b"precious", "{args:?}");
    }
    assert_eq!(files_in(&dir), vec!["keep.png"]);
}

#[test]
fn an_interrupted_render_leaves_no_file_and_keeps_an_existing_one() {
    let dir = scratch("interrupt");
    let out = dir.join("keep.png");
    std::fs::write(&out, b"precious").unwrap();
    // Long enough to be interrupted (minutes uninterrupted).
    let child = Command::new(env!("CARGO_BIN_EXE_penumbra"))
        .args([
            "render",
            "-o",
            out.to_str().unwrap(),
            "--width",
            "1920",
            "--height",
            "1080",
            "--shadow-rays",
            "4096",
            "--threads",
            "1",
        ])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(700));
    let killed = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let o = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("interrupted: no image written"), "{err}");
    assert_eq!(std::fs::read(&out).unwrap(), b"precious");
    assert_eq!(files_in(&dir), vec!["keep.png"]);
}

/// Odd but valid scenes: accepted, and rendered to finite pixels.
#[test]
fn extreme_but_valid_scenes_render_finite_pixels() {
    let m = limits::MAX_COORD;
    type Edit = Box<dyn Fn(&mut Value)>;
    let cases: Vec<(&str, Edit)> = vec![
        (
            // The smallest radius supported (a subnormal one is refused).
            "smallest radius",
            Box::new(|v| {
                let d: SceneDesc = SceneDesc::from_json(&v.to_string()).unwrap();
                let r = 1.01 * limits::MIN_FEATURE * d.size_and_offset().0;
                v["objects"][7]["radius"] = json!(r);
            }),
        ),
        (
            "coordinates at the limit",
            Box::new(move |v| {
                v["camera"]["position"] = json!([m, m, -m]);
                v["camera"]["look_at"] = json!([-m, -m, m]);
                v["light"]["corner"] = json!([-m, m, -m]);
                v["light"]["edge_u"] = json!([m, 0, 0]);
                v["light"]["edge_v"] = json!([0, 0, m]);
                v["objects"][7]["center"] = json!([0, 0, 0]);
                v["objects"][7]["radius"] = json!(m);
            }),
        ),
        (
            "largest colours, terms and intensities, depth 16",
            Box::new(|v| {
                let big = json!([1e6, 1e6, 1e6]);
                for k in ["ambient", "diffuse", "specular"] {
                    v["light"][k] = big.clone();
                    v["render"]["terms"][k] = json!(1e6);
                    v["materials"]["mirror"][k] = big.clone();
                }
                v["materials"]["mirror"]["reflectivity"] = json!(1);
                v["materials"]["mirror"]["shininess"] = json!(1e6);
                v["render"]["max_depth"] = json!(16);
            }),
        ),
        (
            "a light nearly a line",
            Box::new(|v| v["light"]["edge_v"] = json!([2, 0, 1e-7])),
        ),
        (
            "tiny scene far away",
            Box::new(|v| {
                let d: SceneDesc = SceneDesc::from_json(&v.to_string()).unwrap();
                *v = serde_json::from_str(&d.scaled(1e-4).translated([1e3, -1e3, 1e3]).to_json())
                    .unwrap();
            }),
        ),
    ];
    for (what, f) in cases {
        let mut v = seed();
        f(&mut v);
        let mut desc =
            SceneDesc::from_json(&v.to_string()).unwrap_or_else(|e| panic!("{what}: {e}"));
        desc.camera.width = 32;
        desc.camera.height = 18;
        desc.render.shadow_rays = 16;
        let film = penumbra::render::Loaded::new(&desc).unwrap().render_image();
        assert!(!film.has_non_finite(), "{what}: non-finite pixels");
    }
}

/// Found by the `read_obj` fuzz target: a face's bad index was quoted whole
/// (a 4 KB token gave a 20 KB message); every value a mesh error quotes is
/// cut, and so is a long file name.
#[test]
fn mesh_errors_quote_long_values_cut() {
    use penumbra::render::Loaded;
    use penumbra::render::mesh::read_obj;
    let long = "7x".repeat(50_000);
    let e = read_obj(format!("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 {long}\n").as_bytes()).unwrap_err();
    assert!(e.starts_with("line 4: malformed face"), "{e:.200}");
    assert!(
        e.contains("(100000 characters)") && e.len() < 400,
        "{} characters",
        e.len()
    );

    let dir = scratch("long-mesh-name");
    let mut v = seed();
    let name = format!("{}.obj", "m".repeat(100_000));
    v["objects"]
        .as_array_mut()
        .unwrap()
        .push(json!({"type": "mesh", "file": name, "material": "white"}));
    let mut desc = SceneDesc::from_json(&v.to_string()).unwrap();
    desc.base_dir = Some(dir.to_path_buf());
    let Err(e) = Loaded::new(&desc) else {
        panic!("no such mesh file")
    };
    let e = e.to_string();
    assert!(
        e.contains("(100004 characters)") && e.len() < 1000,
        "{} characters: {e:.200}",
        e.len()
    );
}
