//! Each class of bad scene is refused with its own message naming the
//! field's JSON path.

use penumbra::render::SEED_ROOM_JSON;
use penumbra::render::{Loaded, SceneDesc};
use serde_json::{Value, json};

fn seed() -> Value {
    serde_json::from_str(SEED_ROOM_JSON).unwrap()
}

/// The error for the seed room changed by `edit`.
fn error_of(edit: impl FnOnce(&mut Value)) -> String {
    let mut v = seed();
    edit(&mut v);
    match Loaded::from_json(&v.to_string()) {
        Ok(_) => panic!("accepted: {v}"),
        Err(e) => e.to_string(),
    }
}

fn assert_error(edit: impl FnOnce(&mut Value), path: &str, words: &str) {
    let e = error_of(edit);
    if !path.is_empty() {
        assert!(
            e.starts_with(&format!("{path}: ")),
            "expected path {path:?} in: {e}"
        );
    }
    assert!(e.contains(words), "expected {words:?} in: {e}");
}

#[test]
fn the_seed_room_round_trips() {
    let desc = SceneDesc::from_json(SEED_ROOM_JSON).unwrap();
    assert_eq!(SceneDesc::from_json(&desc.to_json()).unwrap(), desc);
    assert_eq!(desc.objects.len(), 8);
}

#[test]
fn saved_scenes_read_back_bit_for_bit() {
    let mut desc = SceneDesc::from_json(SEED_ROOM_JSON).unwrap();
    // Numbers with 17 significant digits, as generators and editors write.
    desc.camera.position = [0.1 + 0.2, 1.0 / 3.0, -14.000000000000002];
    desc.light.corner[1] = 7.99 * (1.0 + f64::EPSILON);
    let again = SceneDesc::from_json(&desc.to_json()).unwrap();
    assert_eq!(
        again.camera.position.map(f64::to_bits),
        desc.camera.position.map(f64::to_bits)
    );
    assert_eq!(again, desc);
}

#[test]
fn unknown_keys_are_refused() {
    assert_error(
        |v| v["camera"]["fov"] = json!(40),
        "camera.fov",
        "unknown field `fov`",
    );
    assert_error(
        |v| v["objects"][7]["radius_m"] = json!(1),
        "objects[7].radius_m",
        "unknown field",
    );
    assert_error(
        |v| v["render"]["terms"]["emissive"] = json!(1),
        "render.terms.emissive",
        "unknown field",
    );
    assert_error(|v| v["extra"] = json!(1), "extra", "unknown field");
    assert_error(
        |v| v["objects"][0]["type"] = json!("torus"),
        "objects[0].type",
        "unknown object type \"torus\"",
    );
}

#[test]
fn missing_required_fields_are_refused() {
    assert_error(
        |v| {
            v["camera"].as_object_mut().unwrap().remove("width");
        },
        "camera",
        "missing field `width`",
    );
    assert_error(
        |v| {
            v.as_object_mut().unwrap().remove("light");
        },
        "",
        "missing field `light`",
    );
    assert_error(
        |v| {
            v["objects"][7].as_object_mut().unwrap().remove("radius");
        },
        "objects[7]",
        "missing field `radius`",
    );
    assert_error(
        |v| {
            v["objects"][2].as_object_mut().unwrap().remove("type");
        },
        "objects[2]",
        "missing field `type`",
    );
}

#[test]
fn wrong_types_are_refused() {
    assert_error(
        |v| v["camera"]["width"] = json!("960"),
        "camera.width",
        "invalid type: string",
    );
    assert_error(
        |v| v["camera"]["position"] = json!([0, 4]),
        "camera.position",
        "invalid length 2",
    );
    assert_error(
        |v| v["objects"][7]["center"][1] = json!(null),
        "objects[7].center[1]",
        "invalid type: null",
    );
    assert_error(
        |v| v["render"]["sampling"] = json!("sobol-ish"),
        "render.sampling",
        "unknown variant",
    );
    assert_error(
        |v| v["materials"]["red"]["shininess"] = json!(true),
        "materials.red.shininess",
        "invalid type: boolean",
    );
    // A named choice given a number, a null or a list: its names, not
    // serde's "expected value at line …", which reads as a syntax error.
    assert_error(
        |v| v["render"]["sampling"] = json!(5),
        "render.sampling",
        "invalid type: number, expected one of `grid`, `random`",
    );
    assert_error(
        |v| v["render"]["area_light_model"] = json!(null),
        "render.area_light_model",
        "invalid type: null, expected one of `sampled`, `nearest_point`, `analytic`, `exact`",
    );
    assert_error(
        |v| v["render"]["sampling"] = json!(["grid"]),
        "render.sampling",
        "invalid type: array, expected one of",
    );
    assert_error(
        |v| {
            v["objects"]
                .as_array_mut()
                .unwrap()
                .push(json!({"type": "mesh", "file": "/m.obj", "material": "white", "shading": 1}))
        },
        "objects[8].shading",
        "invalid type: number, expected one of `auto`, `flat`, `smooth`",
    );
}

#[test]
fn arrays_in_place_of_objects_are_refused() {
    assert_error(
        |v| v["render"]["terms"] = json!([1, 0, 0]),
        "render.terms",
        "expected an object",
    );
    assert_error(
        |v| {
            v["materials"]["red"] =
                json!([[0.8, 0.2, 0.2], [0.8, 0.2, 0.2], [0.3, 0.3, 0.3], 20, 0])
        },
        "materials.red",
        "expected an object",
    );
    assert_error(
        |v| v["camera"] = json!([[0, 4, -14], [0, 3.5, 0], [0, 1, 0], 36, 960, 540]),
        "camera",
        "expected an object",
    );
    let e = Loaded::from_json("[1, {}, {}, {}, {}, []]")
        .unwrap_err()
        .to_string();
    assert!(e.contains("expected an object"), "{e}");
}

#[test]
fn non_finite_numbers_are_refused() {
    let text = SEED_ROOM_JSON.replace(r#""fov_y_deg": 36"#, r#""fov_y_deg": NaN"#);
    let e = Loaded::from_json(&text).unwrap_err().to_string();
    assert!(e.starts_with("camera.fov_y_deg: expected value"), "{e}");
    let text = SEED_ROOM_JSON.replace(r#""radius": 1"#, r#""radius": 1e999"#);
    let e = Loaded::from_json(&text).unwrap_err().to_string();
    assert!(
        e.starts_with("objects[7].radius: number out of range"),
        "{e}"
    );
    let text = SEED_ROOM_JSON.replace(r#""radius": 1"#, r#""radius": Infinity"#);
    assert!(
        Loaded::from_json(&text)
            .unwrap_err()
            .to_string()
            .starts_with("objects[7].radius")
    );
}

#[test]
fn out_of_range_values_are_refused() {
    assert_error(
        |v| v["format"] = json!(2),
        "format",
        "unsupported format 2, expected 1",
    );
    assert_error(
        |v| v["camera"]["fov_y_deg"] = json!(180),
        "camera.fov_y_deg",
        "expected degrees in (0, 180)",
    );
    assert_error(
        |v| v["camera"]["width"] = json!(0),
        "camera.width",
        "expected 1..=16384",
    );
    assert_error(
        |v| v["camera"]["height"] = json!(16385),
        "camera.height",
        "expected 1..=16384",
    );
    assert_error(
        |v| v["camera"]["width"] = json!(-5),
        "camera.width",
        "-5 is out of range, expected 1..=16384 pixels",
    );
    assert_error(
        |v| v["render"]["shadow_rays"] = json!(4097),
        "render.shadow_rays",
        "expected 1..=4096",
    );
    assert_error(
        |v| v["render"]["max_depth"] = json!(0),
        "render.max_depth",
        "expected 1..=16",
    );
    assert_error(
        |v| v["render"]["terms"]["diffuse"] = json!(-1),
        "render.terms.diffuse",
        "out of range",
    );
    assert_error(
        |v| v["materials"]["red"]["reflectivity"] = json!(1.5),
        "materials.red.reflectivity",
        "[0, 1]",
    );
    assert_error(
        |v| v["materials"]["red"]["shininess"] = json!(0),
        "materials.red.shininess",
        "> 0",
    );
    assert_error(
        |v| v["materials"]["red"]["diffuse"][1] = json!(-0.2),
        "materials.red.diffuse[1]",
        "out of range",
    );
    assert_error(
        |v| v["objects"][7]["radius"] = json!(0),
        "objects[7].radius",
        "expected a number > 0",
    );
    assert_error(
        |v| v["objects"][7]["center"][0] = json!(1e300),
        "objects[7].center[0]",
        "within ±1e9",
    );
}

#[test]
fn camera_degeneracies_are_refused() {
    assert_error(
        |v| v["camera"]["look_at"] = v["camera"]["position"].clone(),
        "camera.look_at",
        "equals camera.position",
    );
    assert_error(
        |v| v["camera"]["up"] = json!([0, -1, 28]),
        "camera.up",
        "parallel to the view direction",
    );
    assert_error(
        |v| v["camera"]["up"] = json!([0, 0, 0]),
        "camera.up",
        "zero vector",
    );
}

#[test]
fn unknown_materials_are_refused() {
    assert_error(
        |v| v["objects"][5]["material"] = json!("chrome"),
        "objects[5].material",
        "unknown material \"chrome\"",
    );
}

#[test]
fn zero_normals_are_refused() {
    assert_error(
        |v| v["objects"][1]["normal"] = json!([0, 0, 0]),
        "objects[1].normal",
        "zero vector",
    );
}

#[test]
fn degenerate_lights_and_rects_are_refused() {
    assert_error(
        |v| v["light"]["edge_u"] = json!([0, 0, 0]),
        "light.edge_u",
        "area is zero",
    );
    assert_error(
        |v| v["light"]["edge_v"] = json!([4, 0, 0]),
        "light.edge_v",
        "parallel to edge_u",
    );
    assert_error(
        |v| v["objects"][0] = json!({"type": "rect", "corner": [0, 0, 0], "edge_u": [1, 1, 1], "edge_v": [-2, -2, -2], "material": "white"}),
        "objects[0].edge_v",
        "parallel to edge_u",
    );
}

#[test]
fn boxes_with_min_above_max_are_refused() {
    assert_error(
        |v| v["objects"][5]["min"][1] = json!(6),
        "objects[5].min[1]",
        "min 6 is greater than max 5",
    );
}

#[test]
fn errors_from_files_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let dir = dir.path();
    let path = dir.join("truncated.json");
    std::fs::write(&path, &SEED_ROOM_JSON[..200]).unwrap();
    let e = Loaded::load(&path).unwrap_err().to_string();
    assert!(e.starts_with(&format!("{}: ", path.display())), "{e}");
    assert!(e.contains("EOF while parsing"), "{e}");
}

/// JSON has one number type: a whole-number field takes `64.0` and `6.4e1`
/// as 64 (they were refused as "expected u32"), and a fraction, a negative
/// value or one beyond the field's type is refused with the field's range.
#[test]
fn whole_number_fields_take_any_spelling_of_a_whole_number() {
    // The seed room with `number` written for one field, as it stands.
    let with = |[section, name]: [&str; 2], number: &str| {
        let mut v = seed();
        v[section][name] = json!(123456789);
        v.to_string().replace("123456789", number)
    };
    for (field, number, value) in [
        (["camera", "width"], "96.0", 96u64),
        (["camera", "height"], "5.4e1", 54),
        (["render", "shadow_rays"], "64.0", 64),
        (["render", "max_depth"], "4e0", 4),
        (["render", "seed"], "7.0", 7),
        (["render", "samples_per_pixel"], "2.0", 2),
    ] {
        let desc = SceneDesc::from_json(&with(field, number))
            .unwrap_or_else(|e| panic!("{field:?} = {number}: {e}"));
        let read = match field[1] {
            "width" => desc.camera.width as u64,
            "height" => desc.camera.height as u64,
            "shadow_rays" => desc.render.shadow_rays as u64,
            "max_depth" => desc.render.max_depth as u64,
            "seed" => desc.render.seed,
            _ => desc.render.samples_per_pixel as u64,
        };
        assert_eq!(read, value, "{field:?} = {number}");
    }
    let format = seed().to_string().replace("\"format\":1", "\"format\":1.0");
    assert_eq!(SceneDesc::from_json(&format).unwrap().format, 1);

    for (field, number, words) in [
        (
            ["camera", "width"],
            "-1",
            "-1 is out of range, expected 1..=16384 pixels",
        ),
        (
            ["camera", "width"],
            "96.5",
            "floating point `96.5`, expected a whole number in 1..=16384 pixels",
        ),
        (
            ["camera", "height"],
            "5000000000",
            "5000000000 is out of range, expected 1..=16384 pixels",
        ),
        (
            ["render", "shadow_rays"],
            "1e300",
            "1e300 is out of range, expected 1..=4096",
        ),
        (
            ["render", "max_depth"],
            "\"4\"",
            "invalid type: string \"4\", expected a whole number in 1..=16",
        ),
        (["render", "seed"], "-3", "-3 is out of range"),
    ] {
        let e = SceneDesc::from_json(&with(field, number))
            .unwrap_err()
            .to_string();
        let path = format!("{}.{}: ", field[0], field[1]);
        assert!(
            e.starts_with(&path) && e.contains(words),
            "{field:?} = {number}: {e}"
        );
    }
}

/// `shininess_override` is a number or absent: `null` was taken as absent.
#[test]
fn a_null_shininess_override_is_refused() {
    assert_error(
        |v| v["render"]["shininess_override"] = Value::Null,
        "render.shininess_override",
        "invalid type: null, expected a number, or the field left out",
    );
    let mut v = seed();
    v["render"]["shininess_override"] = json!(30);
    let desc = SceneDesc::from_json(&v.to_string()).unwrap();
    assert_eq!(desc.render.shininess_override, Some(30.0));
}

/// A part that makes the scene huge puts ordinary features below the
/// floor of 1e-9 of its size: the message names that part too (a sphere
/// of radius 1e9, which its own range allows, was refused as a light too
/// small, with no word of the sphere).
#[test]
fn a_part_that_makes_the_scene_huge_is_named_with_the_feature_it_shrinks() {
    let huge_sphere =
        json!({"type": "sphere", "center": [0, -1e9, 0], "radius": 1e9, "material": "white"});
    assert_error(
        |v| {
            v["objects"]
                .as_array_mut()
                .unwrap()
                .push(huge_sphere.clone())
        },
        "light.edge_u",
        "because of objects[8], a sphere of radius 1.000e9",
    );
    let far_triangle = json!({"type": "triangle", "vertices": [[0, 0, 0], [1, 0, 0], [0, 0, 9e8]], "material": "white"});
    assert_error(
        |v| {
            v["light"]["edge_u"] = json!([0.5, 0, 0]);
            v["objects"].as_array_mut().unwrap().push(far_triangle);
        },
        "light.edge_u",
        "because of objects[8], a triangle (",
    );
    // A light too small for an ordinary room blames no other part.
    let e = error_of(|v| v["light"]["edge_u"] = json!([1e-12, 0, 0]));
    assert!(e.starts_with("light.edge_u: "), "{e}");
    assert!(e.contains("below the smallest supported size"), "{e}");
    assert!(!e.contains("because of"), "{e}");
}

/// Messages of malformed arrays and objects say what is wrong where: an
/// array of four for a vector read "trailing characters", a trailing comma
/// had the path "render.?", and a missing top-level field pointed at the
/// end of the file.
#[test]
fn array_lengths_trailing_commas_and_missing_fields_read_plainly() {
    let e = error_of(|v| v["camera"]["position"] = json!([0, 4, -14, 1]));
    assert!(
        e.starts_with("camera.position: too many elements, expected an array of 3"),
        "{e}"
    );
    let e = error_of(|v| {
        v["objects"]
            .as_array_mut()
            .unwrap()
            .push(json!({"type": "triangle",
            "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], "material": "white"}))
    });
    assert!(
        e.starts_with("objects[8].vertices: invalid length 4, expected an array of 3"),
        "{e}"
    );
    let text = SEED_ROOM_JSON.replace("\"seed\": 1,", "\"seed\": 1,,");
    let e = SceneDesc::from_json(&text).unwrap_err().to_string();
    assert!(e.starts_with("render: "), "{e}");
    let mut v = seed();
    v.as_object_mut().unwrap().remove("format");
    let e = SceneDesc::from_json(&v.to_string())
        .unwrap_err()
        .to_string();
    assert_eq!(e, "missing field `format`");
}
