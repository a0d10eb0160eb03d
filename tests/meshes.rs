//! Triangles and meshes: the primitive against the shapes it can stand in
//! for, the readers, the transform, exactness of the shadow shortcuts on a
//! non-convex mesh, and bad mesh files.

mod common;

use std::fmt::Write as _;
use std::path::Path;

use common::{box_obj, penumbra, seed_room};
use penumbra::render::compare::compare;
use penumbra::render::scene_file::{
    MeshDesc, MeshScale, MeshShading, ObjectDesc, RectDesc, TriangleDesc,
};
use penumbra::render::{
    AreaLightModel, CancelToken, Film, Loaded, RenderOptions, Sampling, SceneDesc, TileRect,
};

fn scratch(name: &str) -> common::Scratch {
    common::Scratch::new(&format!("mesh-{name}"))
}

fn small_room() -> SceneDesc {
    let mut d = seed_room(160, 90);
    d.render.shadow_rays = 16;
    d
}

fn render(desc: &SceneDesc, skip: bool) -> Film {
    let mut l = Loaded::new(desc).unwrap_or_else(|e| panic!("{e}"));
    l.settings.skip = skip;
    l.render_image()
}

fn rmse(a: &Film, b: &Film) -> (f64, f64) {
    let c = compare(a, b).unwrap();
    (c.rmse, c.max_diff)
}

fn mesh(file: &Path, material: &str) -> MeshDesc {
    MeshDesc {
        file: file.to_str().unwrap().into(),
        material: material.into(),
        scale: MeshScale::Uniform(1.0),
        rotate_y_deg: 0.0,
        translate: [0.0; 3],
        shading: MeshShading::Auto,
    }
}

#[test]
fn a_triangle_pair_renders_as_the_rect() {
    let mut rect = small_room();
    // A panel standing in the room, lit and shadowing the floor.
    let (c, u, v) = ([-3.5, 0.5, -2.0], [2.5, 0.0, 0.5], [0.3, 3.0, 0.2]);
    rect.objects.push(ObjectDesc::Rect(RectDesc {
        corner: c,
        edge_u: u,
        edge_v: v,
        material: "red".into(),
    }));
    let add = |a: [f64; 3], b: [f64; 3]| [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
    let mut tris = small_room();
    for vertices in [
        [c, add(c, u), add(add(c, u), v)],
        [c, add(add(c, u), v), add(c, v)],
    ] {
        tris.objects.push(ObjectDesc::Triangle(TriangleDesc {
            vertices,
            material: "red".into(),
        }));
    }
    for skip in [true, false] {
        let (e, _) = rmse(&render(&rect, skip), &render(&tris, skip));
        assert!(e <= 1e-6, "skip {skip}: rmse {e}");
    }
}

/// `room` with its boxes replaced by 12-triangle meshes of the same corners
/// (written into `dir`).
fn boxes_as_meshes(room: &SceneDesc, dir: &Path) -> SceneDesc {
    let mut meshes = room.clone();
    let mut replaced = 0;
    for (i, o) in room.objects.iter().enumerate() {
        let ObjectDesc::Box(b) = o else { continue };
        let half = [0, 1, 2].map(|k| (b.max[k] - b.min[k]) * 0.5);
        let centre = [0, 1, 2].map(|k| (b.max[k] + b.min[k]) * 0.5 + b.translate[k]);
        let file = dir.join(format!("box{i}.obj"));
        std::fs::write(&file, box_obj(half)).unwrap();
        let mut m = mesh(&file, &b.material);
        m.rotate_y_deg = b.rotate_y_deg;
        m.translate = centre;
        meshes.objects[i] = ObjectDesc::Mesh(m);
        replaced += 1;
    }
    assert_eq!(replaced, 2, "both boxes of the seed room");
    meshes
}

/// A crop of the image of `desc` (at its full size).
fn render_crop(desc: &SceneDesc, skip: bool, region: TileRect) -> Film {
    let mut l = Loaded::new(desc).unwrap_or_else(|e| panic!("{e}"));
    l.settings.skip = skip;
    l.render_region(
        region,
        &RenderOptions::default(),
        &CancelToken::new(),
        &|_| {},
    )
    .unwrap()
    .film
}

/// With every sampling pattern (the random ones draw the same numbers for
/// both, hit for hit) and both the sampled and the report's light model.
#[test]
fn a_twelve_triangle_box_renders_as_the_box() {
    let dir = scratch("box");
    let mut prims = small_room();
    let mut meshes = boxes_as_meshes(&prims, &dir);
    let loaded = Loaded::new(&meshes).unwrap();
    assert_eq!(loaded.scene.triangles, 24);
    for model in [AreaLightModel::Sampled, AreaLightModel::NearestPoint] {
        for sampling in Sampling::ALL {
            for d in [&mut prims, &mut meshes] {
                d.render.sampling = sampling;
                d.render.area_light_model = model;
            }
            for skip in [true, false] {
                let (e, max) = rmse(&render(&prims, skip), &render(&meshes, skip));
                assert!(
                    e <= 1e-6,
                    "{model:?}, {sampling:?}, skip {skip}: rmse {e}, max {max}"
                );
            }
        }
    }
}

/// At the seed room's own settings (960×540, 64 grid rays) one shadow ray
/// from the left wall, at pixel (787, 378), runs exactly through the top
/// edge of the tall box: the f32 slab test enters and leaves the box at the
/// same t. The box is closed, as its triangles are: the ray is blocked
/// either way.
#[test]
fn a_ray_through_a_box_edge_is_blocked_as_by_its_triangles() {
    let dir = scratch("box-edge");
    let prims = seed_room(960, 540);
    let meshes = boxes_as_meshes(&prims, &dir);
    let region = TileRect {
        x: 771,
        y: 362,
        w: 32,
        h: 32,
    };
    for skip in [true, false] {
        let (e, max) = rmse(
            &render_crop(&prims, skip, region),
            &render_crop(&meshes, skip, region),
        );
        assert!(e <= 1e-6 && max == 0.0, "skip {skip}: rmse {e}, max {max}");
    }
}

/// A wavy, non-convex height field under the light: it shadows itself.
fn wavy_obj(n: usize) -> String {
    let mut s = String::new();
    for i in 0..=n {
        for j in 0..=n {
            let (x, z) = (
                i as f64 / n as f64 * 4.0 - 2.0,
                j as f64 / n as f64 * 4.0 - 2.0,
            );
            let y = 0.6 * (2.5 * x).sin() * (2.0 * z).cos() + 0.8;
            writeln!(s, "v {x} {y} {z}").unwrap();
        }
    }
    for i in 0..n {
        for j in 0..n {
            let a = i * (n + 1) + j + 1;
            let (b, c, d) = (a + 1, a + n + 1, a + n + 2);
            writeln!(s, "f {a} {c} {d}\nf {a} {d} {b}").unwrap();
        }
    }
    s
}

#[test]
fn a_self_shadowing_mesh_is_the_same_with_and_without_skipping() {
    let dir = scratch("wavy");
    let file = dir.join("wavy.obj");
    // 2 × 24² = 1152 triangles: the light-frame packets are used.
    std::fs::write(&file, wavy_obj(24)).unwrap();
    for shading in [MeshShading::Flat, MeshShading::Smooth] {
        let mut d = small_room();
        let mut m = mesh(&file, "sand");
        m.shading = shading;
        m.rotate_y_deg = 30.0;
        m.translate = [0.0, 0.0, -1.0];
        d.objects.push(ObjectDesc::Mesh(m));
        let (on, off) = (render(&d, true), render(&d, false));
        let (e, max) = rmse(&on, &off);
        assert_eq!((e, max), (0.0, 0.0), "{shading:?}");
        // It does shadow itself: some mesh pixels are darker than others
        // beyond what the shading alone gives (checked loosely: the image
        // is not uniform).
        assert!(on.get(80, 60) != on.get(70, 55));
    }
}

#[test]
fn smooth_shading_has_no_faceted_terminator() {
    // A coarse sphere (an octahedron subdivided twice), lit from above:
    // smooth shading lets neighbouring faces blend, so the mean brightness
    // jump across triangle edges is lower than with flat faces.
    let dir = scratch("terminator");
    let file = dir.join("ball.obj");
    std::fs::write(&file, ball_obj(2)).unwrap();
    let mut images = Vec::new();
    for shading in [MeshShading::Flat, MeshShading::Smooth] {
        let mut d = small_room();
        let mut m = mesh(&file, "white");
        m.shading = shading;
        m.translate = [0.0, 2.0, -2.0];
        m.scale = MeshScale::Uniform(1.5);
        d.objects.push(ObjectDesc::Mesh(m));
        images.push(render(&d, true));
    }
    let roughness = |f: &Film| {
        let mut s = 0.0;
        for y in 30..70 {
            for x in 60..100 {
                s += (f.get(x + 1, y) - f.get(x, y)).abs().element_sum() as f64;
            }
        }
        s
    };
    assert!(
        roughness(&images[1]) < roughness(&images[0]),
        "{} {}",
        roughness(&images[1]),
        roughness(&images[0])
    );
}

fn ball_obj(levels: u32) -> String {
    let mut v: Vec<[f64; 3]> = vec![
        [1.0, 0.0, 0.0],
        [-1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.0, 0.0, 1.0],
        [0.0, 0.0, -1.0],
    ];
    let mut f: Vec<[usize; 3]> = vec![
        [0, 2, 4],
        [2, 1, 4],
        [1, 3, 4],
        [3, 0, 4],
        [2, 0, 5],
        [1, 2, 5],
        [3, 1, 5],
        [0, 3, 5],
    ];
    for _ in 0..levels {
        let mut next = Vec::new();
        let mut mid = std::collections::HashMap::new();
        let mut m = |a: usize, b: usize, v: &mut Vec<[f64; 3]>| {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                let p = [0, 1, 2].map(|k| (v[a][k] + v[b][k]) * 0.5);
                let l = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
                v.push(p.map(|c| c / l));
                v.len() - 1
            })
        };
        for [a, b, c] in f {
            let (ab, bc, ca) = (m(a, b, &mut v), m(b, c, &mut v), m(c, a, &mut v));
            next.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
        }
        f = next;
    }
    let mut s = String::new();
    for p in &v {
        writeln!(s, "v {} {} {}", p[0], p[1], p[2]).unwrap();
    }
    for t in &f {
        writeln!(s, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1).unwrap();
    }
    s
}

/// The OBJ box as PLY: ASCII or binary of either byte order.
fn box_ply(h: [f64; 3], format: &str) -> Vec<u8> {
    let obj = box_obj(h);
    let verts: Vec<[f64; 3]> = obj
        .lines()
        .filter(|l| l.starts_with("v "))
        .map(|l| {
            let w: Vec<f64> = l[2..]
                .split_whitespace()
                .map(|x| x.parse().unwrap())
                .collect();
            [w[0], w[1], w[2]]
        })
        .collect();
    let faces: Vec<[i32; 3]> = obj
        .lines()
        .filter(|l| l.starts_with("f "))
        .map(|l| {
            let w: Vec<i32> = l[2..]
                .split_whitespace()
                .map(|x| x.parse().unwrap())
                .collect();
            [w[0] - 1, w[1] - 1, w[2] - 1]
        })
        .collect();
    let mut out = format!(
        "ply\nformat {format} 1.0\ncomment a box\nelement vertex {}\nproperty double x\nproperty double y\nproperty double z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        verts.len(),
        faces.len()
    )
    .into_bytes();
    let le = format == "binary_little_endian";
    for v in &verts {
        if format == "ascii" {
            out.extend(format!("{} {} {}\n", v[0], v[1], v[2]).bytes());
        } else {
            for c in v {
                out.extend(if le { c.to_le_bytes() } else { c.to_be_bytes() });
            }
        }
    }
    for f in &faces {
        if format == "ascii" {
            out.extend(format!("3 {} {} {}\n", f[0], f[1], f[2]).bytes());
        } else {
            out.push(3);
            for i in f {
                out.extend(if le { i.to_le_bytes() } else { i.to_be_bytes() });
            }
        }
    }
    out
}

#[test]
fn obj_and_ply_readers_give_the_same_image() {
    let dir = scratch("readers");
    let h = [1.0, 1.25, 0.75];
    std::fs::write(dir.join("b.obj"), box_obj(h)).unwrap();
    let mut images = Vec::new();
    for (name, bytes) in [
        ("b.obj", box_obj(h).into_bytes()),
        ("a.ply", box_ply(h, "ascii")),
        ("le.ply", box_ply(h, "binary_little_endian")),
        ("be.ply", box_ply(h, "binary_big_endian")),
    ] {
        std::fs::write(dir.join(name), bytes).unwrap();
        let mut d = small_room();
        let mut m = mesh(Path::new(name), "green");
        m.translate = [0.5, 1.25, -2.0];
        m.rotate_y_deg = 35.0;
        d.objects.push(ObjectDesc::Mesh(m));
        // A relative path resolves against the scene file's folder.
        let scene = dir.join(format!("{name}.json"));
        std::fs::write(&scene, d.to_json()).unwrap();
        let loaded = Loaded::load(&scene).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(loaded.scene.triangles, 12, "{name}");
        images.push(loaded.render_image());
    }
    for img in &images[1..] {
        assert_eq!(rmse(&images[0], img), (0.0, 0.0));
    }
}

#[test]
fn relative_mesh_paths_need_a_scene_folder() {
    let mut d = small_room();
    d.objects
        .push(ObjectDesc::Mesh(mesh(Path::new("models/x.obj"), "white")));
    let e = Loaded::new(&d).unwrap_err();
    assert_eq!(e.path, "objects[8].file");
    assert!(e.message.contains("relative path"), "{e}");
}

#[test]
fn the_transform_scales_then_rotates_then_translates() {
    let dir = scratch("transform");
    let file = dir.join("t.obj");
    std::fs::write(&file, "v 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\n").unwrap();
    let mut m = mesh(&file, "white");
    m.scale = MeshScale::PerAxis([2.0, 3.0, 4.0]);
    m.rotate_y_deg = 90.0;
    m.translate = [10.0, 20.0, 30.0];
    let mut d = small_room();
    d.objects.push(ObjectDesc::Mesh(m));
    let loaded = Loaded::new(&d).unwrap();
    assert_eq!(loaded.scene.meshes.len(), 1);
    // R_y(90°) maps x to −z and z to x (as the box's rotation does).
    let want = [[10.0, 20.0, 28.0], [10.0, 23.0, 30.0], [14.0, 20.0, 30.0]];
    for (v, w) in loaded.scene.meshes.vertices(0).iter().zip(want) {
        assert!((*v - glam::DVec3::from(w)).length() < 1e-12, "{v} {w:?}");
    }
}

#[test]
fn degenerate_triangles_are_skipped_and_counted() {
    let dir = scratch("degenerate");
    let file = dir.join("d.obj");
    std::fs::write(
        &file,
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nf 1 2 3\nf 1 2 4\nf 1 1 3\n",
    )
    .unwrap();
    let mut d = small_room();
    d.objects.push(ObjectDesc::Mesh(mesh(&file, "white")));
    d.objects.push(ObjectDesc::Triangle(TriangleDesc {
        vertices: [[0.0; 3], [1.0, 1.0, 1.0], [2.0, 2.0, 2.0]],
        material: "white".into(),
    }));
    let l = Loaded::new(&d).unwrap();
    assert_eq!((l.scene.triangles, l.scene.degenerate_triangles), (1, 3));
}

#[test]
fn the_triangle_budget_is_one_clear_error() {
    let dir = scratch("budget");
    let file = dir.join("b.obj");
    std::fs::write(&file, box_obj([1.0; 3])).unwrap();
    let e = penumbra::render::mesh::load(&mesh(&file, "white"), None, 11).unwrap_err();
    assert!(e.contains("12 triangles") && e.contains("20000000"), "{e}");
}

/// A scene with one mesh file of the given content, rendered by the CLI.
fn cli_with_mesh(name: &str, file: &str, content: &[u8]) -> (i32, String, bool) {
    let dir = scratch(name);
    std::fs::write(dir.join(file), content).unwrap();
    let mut d = small_room();
    d.objects
        .push(ObjectDesc::Mesh(mesh(Path::new(file), "white")));
    let scene = dir.join("scene.json");
    std::fs::write(&scene, d.to_json()).unwrap();
    let out = dir.join("out.png");
    let o = penumbra(&[
        "render",
        scene.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    (
        o.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&o.stderr).into_owned(),
        out.exists(),
    )
}

#[test]
fn bad_mesh_files_exit_2_naming_the_file_and_line() {
    let cases: [(&str, &str, &[u8], &[&str]); 7] = [
        ("malformed", "m.obj", b"v 0 0 0\nv 1 0 0\nv 0 x 0\nf 1 2 3\n", &["m.obj", "line 3", "objects[8].file"]),
        ("range", "r.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n", &["r.obj", "line 4", "out of range"]),
        ("nan", "n.obj", b"v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n", &["n.obj", "line 2", "not finite"]),
        ("ply-nan", "n.ply", b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 nan 0\n0 1 0\n3 0 1 2\n", &["n.ply", "vertex 1", "not finite"]),
        ("ply-range", "r.ply", b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n", &["r.ply", "face 0", "out of range"]),
        ("ply-claim", "c.ply", b"ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\nproperty float y\nproperty float z\nend_header\n\0\0\0\0", &["c.ply", "claims 4000000000"]),
        ("missing", "gone.obj", b"", &["gone.obj"]),
    ];
    for (name, file, content, want) in cases {
        let (code, err, written) = if name == "missing" {
            let (dir, f) = (scratch(name), file);
            let mut d = small_room();
            d.objects
                .push(ObjectDesc::Mesh(mesh(Path::new(f), "white")));
            let scene = dir.join("scene.json");
            std::fs::write(&scene, d.to_json()).unwrap();
            let out = dir.join("out.png");
            let o = penumbra(&[
                "render",
                scene.to_str().unwrap(),
                "-o",
                out.to_str().unwrap(),
            ]);
            (
                o.status.code().unwrap_or(-1),
                String::from_utf8_lossy(&o.stderr).into_owned(),
                out.exists(),
            )
        } else {
            cli_with_mesh(name, file, content)
        };
        assert_eq!(code, 2, "{name}: {err}");
        assert!(!written, "{name}: nothing written");
        for w in want {
            assert!(err.contains(w), "{name}: {w:?} in {err}");
        }
        assert!(err.contains("scene.json"), "{name}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{name}: one line: {err}");
    }
}

#[test]
fn degenerate_triangles_are_reported_by_the_cli() {
    let (code, err, written) = cli_with_mesh(
        "cli-degenerate",
        "d.obj",
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nf 1 2 3\nf 1 2 4\n",
    );
    assert_eq!(code, 0, "{err}");
    assert!(written);
    assert!(err.contains("triangles: 1 (1 degenerate skipped)"), "{err}");
}

/// A cheap stand-in for fuzzing, run with every test: valid files with
/// bytes flipped, dropped and cut off are read or refused, never a panic,
/// and whatever is read has its indices in range.
#[test]
fn mutated_mesh_files_are_read_or_refused_without_panics() {
    use penumbra::render::mesh::{NO_NORMAL, RawMesh, read_gltf, read_obj, read_ply};
    let check = |r: Result<RawMesh, String>| {
        if let Ok(raw) = r {
            let n = raw.positions.len() as u32;
            assert!(raw.faces.iter().flatten().all(|&i| i < n));
            if let Some(f) = &raw.face_normals {
                let m = raw.normals.len() as u32;
                assert_eq!(f.len(), raw.faces.len());
                assert!(
                    f.iter()
                        .all(|f| *f == NO_NORMAL || f.iter().all(|&i| i < m))
                );
            }
        } else if let Err(e) = r {
            assert!(!e.is_empty() && e.len() < 1000, "{e}");
        }
    };
    let h = [1.0, 2.0, 0.5];
    let obj = format!(
        "{}vn 0 1 0\nf 1//1 2//1 3//1 4//1\nf -1 -2 -3\n",
        box_obj(h)
    );
    let seeds: Vec<Vec<u8>> = vec![
        obj.into_bytes(),
        box_ply(h, "ascii"),
        box_ply(h, "binary_little_endian"),
        box_ply(h, "binary_big_endian"),
        box_glb(h, 0.25),
    ];
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    let alphabet = b" \n0123456789-./eEnaifvxyzlp\xff\x00";
    for (k, seed) in seeds.iter().enumerate() {
        for _ in 0..3000 {
            let mut b = seed.clone();
            for _ in 0..1 + next() % 4 {
                let at = (next() as usize) % b.len().max(1);
                match next() % 4 {
                    0 if !b.is_empty() => b[at] = alphabet[(next() as usize) % alphabet.len()],
                    1 if !b.is_empty() => {
                        b.remove(at);
                    }
                    2 => b.insert(
                        at.min(b.len()),
                        alphabet[(next() as usize) % alphabet.len()],
                    ),
                    _ => b.truncate(at),
                }
            }
            match k {
                0 => check(read_obj(&b)),
                4 => check(read_gltf(&b, None)),
                _ => check(read_ply(&b)),
            }
        }
    }
}

/// The OBJ box as a GLB (f32 positions, u32 indices) under a node that
/// moves it by `shift` along x.
fn box_glb(h: [f64; 3], shift: f64) -> Vec<u8> {
    let obj = box_obj(h);
    let mut bin = Vec::new();
    let mut count = 0;
    for l in obj.lines().filter(|l| l.starts_with("v ")) {
        for x in l[2..].split_whitespace() {
            bin.extend((x.parse::<f64>().unwrap() as f32).to_le_bytes());
        }
        count += 1;
    }
    let pos_len = bin.len();
    let mut n_idx = 0;
    for l in obj.lines().filter(|l| l.starts_with("f ")) {
        for x in l[2..].split_whitespace() {
            bin.extend((x.parse::<u32>().unwrap() - 1).to_le_bytes());
            n_idx += 1;
        }
    }
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],
        "nodes":[{{"translation":[{shift},0,0],"children":[1]}},{{"mesh":0}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1}}]}}],
        "buffers":[{{"byteLength":{}}}],
        "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":{pos_len}}},{{"buffer":0,"byteOffset":{pos_len},"byteLength":{}}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":{count},"type":"VEC3","min":[{},{},{}],"max":[{},{},{}]}},
                     {{"bufferView":1,"componentType":5125,"count":{n_idx},"type":"SCALAR"}}]}}"#,
        bin.len(),
        bin.len() - pos_len,
        -h[0],
        -h[1],
        -h[2],
        h[0],
        h[1],
        h[2]
    );
    let mut j = json.into_bytes();
    while j.len() % 4 != 0 {
        j.push(b' ');
    }
    let total = 12 + 8 + j.len() + 8 + bin.len();
    let mut out = Vec::new();
    out.extend(b"glTF");
    out.extend(2u32.to_le_bytes());
    out.extend((total as u32).to_le_bytes());
    out.extend((j.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(j);
    out.extend((bin.len() as u32).to_le_bytes());
    out.extend(b"BIN\0");
    out.extend(bin);
    out
}

#[test]
fn a_glb_box_with_a_node_transform_renders_as_the_obj_box() {
    let dir = scratch("glb");
    let h = [1.0, 1.25, 0.75];
    let images: Vec<Film> = [("b.obj", 0.5), ("b.glb", 0.0)]
        .into_iter()
        .map(|(name, extra)| {
            let file = dir.join(name);
            if name.ends_with("obj") {
                std::fs::write(&file, box_obj(h)).unwrap();
            } else {
                std::fs::write(&file, box_glb(h, 0.5)).unwrap();
            }
            let mut d = small_room();
            let mut m = mesh(&file, "green");
            // The node's shift applies before the object's transform.
            m.translate = [extra, 1.25, -2.0];
            d.objects.push(ObjectDesc::Mesh(m));
            let l = Loaded::new(&d).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_eq!(l.scene.triangles, 12);
            l.render_image()
        })
        .collect();
    assert_eq!(rmse(&images[0], &images[1]), (0.0, 0.0));
    // A GLB cut short is one clear error.
    let glb = box_glb(h, 0.5);
    let e = penumbra::render::mesh::read_gltf(&glb[..glb.len() - 40], None).unwrap_err();
    assert!(!e.is_empty() && e.len() < 300, "{e}");
}

/// The fast reader of plain OBJ and `tobj` give the same triangles (the
/// same vertices, normals and order; only the vertex numbering differs).
#[test]
fn the_fast_obj_reader_agrees_with_tobj() {
    use penumbra::render::mesh::{RawMesh, read_obj, read_obj_tobj};
    let corners = |r: &RawMesh| -> Vec<[glam::DVec3; 3]> {
        r.faces
            .iter()
            .map(|f| f.map(|i| r.positions[i as usize]))
            .collect()
    };
    let normals = |r: &RawMesh| -> Option<Vec<[glam::DVec3; 3]>> {
        r.face_normals
            .as_ref()
            .map(|f| f.iter().map(|f| f.map(|i| r.normals[i as usize])).collect())
    };
    let bunny = std::fs::read("scenes/models/bunny.obj").unwrap();
    let crafted = "# a quad, a pentagon, negative indices, groups and normals\n\
        mtllib none.mtl\no thing\nv 0 0 0\nv 1 0 0\nv 1 1 0\r\nv 0 1 0\nv 0.5 2 0.25\n\
        vn 0 0 1\nvn 0 0.6 0.8\nvt 0 0\ng a\nusemtl m\ns off\n\
        f 1//1 2//1 3//2 4//2\nf -5/1/1 -4/1/1 -3/1/2 -1/1/2 4/1/1\n\
        g b\nf 2//1 3//1 5//2\nl 1 2\n";
    let no_normals = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\nf 4 3 2\n";
    for (name, text) in [
        ("bunny", bunny),
        ("crafted", crafted.as_bytes().to_vec()),
        ("no normals", no_normals.as_bytes().to_vec()),
    ] {
        let fast = read_obj(&text).unwrap();
        let slow = read_obj_tobj(&text).unwrap();
        assert!(!fast.faces.is_empty(), "{name}");
        assert_eq!(corners(&fast), corners(&slow), "{name}");
        assert_eq!(normals(&fast), normals(&slow), "{name}");
    }
    // Outside the plain subset (vertex colours), or wrong: tobj decides
    // and the error names the line.
    let e = read_obj(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n").unwrap_err();
    assert!(e.contains("line 4"), "{e}");
    let colours = "v 0 0 0 1 0 0\nv 1 0 0 1 0 0\nv 0 1 0 1 0 0\nf 1 2 3\n";
    assert_eq!(read_obj(colours.as_bytes()).unwrap().faces.len(), 1);
}

/// Found by the `read_gltf` fuzz target: a GLB header claiming a length
/// below its own 12 bytes made the gltf crate subtract past zero (a panic
/// where overflow is checked). It is one clear error naming the header.
#[test]
fn a_glb_header_shorter_than_itself_is_refused() {
    let mut glb = box_glb([1.0, 1.0, 1.0], 0.0);
    for length in [0u32, 11, glb.len() as u32 + 1] {
        glb[8..12].copy_from_slice(&length.to_le_bytes());
        let e = penumbra::render::mesh::read_gltf(&glb, None).unwrap_err();
        assert!(
            e.contains(&format!(
                "GLB header gives the file's length as {length} bytes"
            )),
            "{e}"
        );
    }
}

/// Found by the `read_gltf` fuzz target: the glTF crate's error quotes an
/// offending JSON string whole; the message stays short.
#[test]
fn a_glb_with_a_huge_bad_value_gives_a_short_error() {
    let long = "7".repeat(100_000);
    let json = format!("{{\"asset\": {{\"version\": \"2.0\"}}, \"scenes\": \"{long}\"}}");
    let e = penumbra::render::mesh::read_gltf(json.as_bytes(), None).unwrap_err();
    assert!(
        e.starts_with("not a valid glTF file") && e.len() < 1000,
        "{} characters",
        e.len()
    );
}

/// The report's scene (the seed room with the nearest-point light model) at
/// 960×540: with random and mixed sampling one shadow ray from pixel (691,
/// 353) and one from (801, 439) graze a box within 1e-7 of their length
/// from an edge (the f32 triangle test got the first wrong, the f32 slab
/// test the second). The box and its triangles must give them the same
/// answer.
#[test]
fn a_ray_grazing_a_box_edge_is_decided_as_by_its_triangles() {
    let dir = scratch("box-graze");
    let mut prims = seed_room(960, 540);
    prims.render.area_light_model = AreaLightModel::NearestPoint;
    let mut meshes = boxes_as_meshes(&prims, &dir);
    for (x, y) in [(691, 353), (801, 439)] {
        let region = TileRect {
            x: x - 8,
            y: y - 8,
            w: 16,
            h: 16,
        };
        for sampling in [Sampling::Random, Sampling::Mixed] {
            for d in [&mut prims, &mut meshes] {
                d.render.sampling = sampling;
            }
            for skip in [true, false] {
                let (e, max) = rmse(
                    &render_crop(&prims, skip, region),
                    &render_crop(&meshes, skip, region),
                );
                assert!(
                    max == 0.0,
                    "({x}, {y}), {sampling:?}, skip {skip}: rmse {e}, max {max}"
                );
            }
        }
    }
}

// ------------------------------------------- malformed and unusual mesh files

/// Base64 of `bytes` (for `data:` URIs).
fn base64(bytes: &[u8]) -> String {
    const A: &[u8] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for c in bytes.chunks(3) {
        let n = c
            .iter()
            .enumerate()
            .fold(0u32, |n, (k, &b)| n | (b as u32) << (16 - 8 * k));
        for k in 0..=c.len() {
            out.push(A[(n >> (18 - 6 * k) & 63) as usize] as char);
        }
        out.push_str(&"=".repeat(3 - c.len()));
    }
    out
}

/// The bytes of base64 text (the inverse of [`base64`]).
fn unbase64(text: &str) -> Vec<u8> {
    const A: &str = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = Vec::new();
    let (mut acc, mut bits) = (0u32, 0);
    for c in text.chars().filter(|&c| c != '=') {
        acc = acc << 6 | A.find(c).unwrap() as u32;
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    out
}

/// A glTF of the unit square in z = 0 (corners (0,0), (1,0), (1,1),
/// (0,1)), its one buffer embedded as base64: positions (accessor 0,
/// view 0) and u16 indices (accessor 1, view 1) drawn with `mode`;
/// `edit` changes the JSON before it is written.
fn square_gltf(mode: u32, indices: &[u16], edit: impl FnOnce(&mut serde_json::Value)) -> Vec<u8> {
    let mut bin = Vec::new();
    for p in [
        [0.0f32, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
    ] {
        for x in p {
            bin.extend(x.to_le_bytes());
        }
    }
    for i in indices {
        bin.extend(i.to_le_bytes());
    }
    let mut j = serde_json::json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "mode": mode}]}],
        "buffers": [{"byteLength": bin.len(),
                     "uri": format!("data:application/octet-stream;base64,{}", base64(&bin))}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48},
                        {"buffer": 0, "byteOffset": 48, "byteLength": 2 * indices.len()}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                       "min": [0, 0, 0], "max": [1, 1, 0]},
                      {"bufferView": 1, "componentType": 5123, "count": indices.len(), "type": "SCALAR"}]
    });
    edit(&mut j);
    j.to_string().into_bytes()
}

/// Each face's area and the z of its normal (the square's two halves:
/// 0.5 and +1 each).
fn faces_of(raw: &penumbra::render::mesh::RawMesh) -> Vec<(f64, f64)> {
    raw.faces
        .iter()
        .map(|f| {
            let [a, b, c] = f.map(|i| raw.positions[i as usize]);
            let n = (b - a).cross(c - a);
            (0.5 * n.length(), n.z.signum())
        })
        .collect()
}

/// glTF's three triangle modes (lists, strips and fans) give the same
/// square, both halves facing one way; the buffer is a base64 `data:` URI.
#[test]
fn gltf_triangle_lists_strips_and_fans_give_the_same_square() {
    use penumbra::render::mesh::read_gltf;
    for (mode, indices) in [
        (4, &[0u16, 1, 2, 0, 2, 3][..]),
        (5, &[0, 1, 3, 2]),
        (6, &[0, 1, 2, 3]),
    ] {
        let raw = read_gltf(&square_gltf(mode, indices, |_| {}), None).unwrap();
        assert_eq!(faces_of(&raw), [(0.5, 1.0), (0.5, 1.0)], "mode {mode}");
    }
    // Points and lines have no area: left out.
    let raw = read_gltf(&square_gltf(1, &[0, 1, 2, 3], |_| {}), None).unwrap();
    assert!(raw.faces.is_empty());
}

/// A malformed accessor is one error naming the primitive, the accessor
/// and what is wrong (the glTF crate's reader panicked on some and quietly
/// dropped the indices of others, drawing a different mesh).
#[test]
fn malformed_gltf_accessors_are_one_error_naming_the_accessor() {
    use penumbra::render::mesh::read_gltf;
    type Edit = fn(&mut serde_json::Value);
    let cases: [(&str, Edit, &str); 8] = [
        (
            "float indices",
            |j| j["accessors"][1]["componentType"] = 5126.into(),
            "indices (accessor 1): component type FLOAT, expected UNSIGNED_BYTE, UNSIGNED_SHORT, UNSIGNED_INT",
        ),
        (
            "signed indices",
            |j| j["accessors"][1]["componentType"] = 5122.into(),
            "component type SHORT",
        ),
        (
            "VEC3 indices",
            |j| j["accessors"][1]["type"] = "VEC3".into(),
            "indices (accessor 1): type VEC3, expected SCALAR",
        ),
        (
            "too many indices",
            |j| j["accessors"][1]["count"] = 100.into(),
            "indices (accessor 1): 100 elements of 2 bytes from byte 0 every 2 bytes reach beyond bufferView 1 (12 bytes)",
        ),
        (
            "view past the buffer",
            |j| j["bufferViews"][1]["byteOffset"] = 10000.into(),
            "bufferView 1 (12 bytes from byte 10000) reaches beyond buffer 0 (60 bytes)",
        ),
        (
            "stride below an element",
            |j| j["bufferViews"][0]["byteStride"] = 8.into(),
            "POSITION (accessor 0): bufferView 0: byteStride 8 is smaller than an element (12 bytes)",
        ),
        (
            "too many positions",
            |j| j["accessors"][0]["count"] = 100.into(),
            "POSITION (accessor 0): 100 elements",
        ),
        (
            "VEC2 positions",
            |j| j["accessors"][0]["type"] = "VEC2".into(),
            "POSITION (accessor 0): type VEC2, expected VEC3",
        ),
    ];
    for (name, edit, want) in cases {
        let e = read_gltf(&square_gltf(4, &[0, 1, 2, 0, 2, 3], edit), None).unwrap_err();
        assert!(e.starts_with("mesh 0 primitive 0: "), "{name}: {e}");
        assert!(e.contains(want), "{name}: {want:?} in {e}");
    }
    // Through the CLI: exit 2, one line, no panic printed.
    let (code, err, written) = cli_with_mesh(
        "gltf-float-indices",
        "f.gltf",
        &square_gltf(4, &[0, 1, 2, 0, 2, 3], |j| {
            j["accessors"][1]["componentType"] = 5126.into()
        }),
    );
    assert_eq!(code, 2, "{err}");
    assert!(!written);
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
}

/// Sparse accessors: substitutions read from their views, and views too
/// short for them refused by name.
#[test]
fn gltf_sparse_accessors_substitute_and_are_checked() {
    use penumbra::render::mesh::read_gltf;
    // The index list 0 1 2 0 2 3 with its second triangle's last index
    // (index 5) replaced by 1: (0 2 1), the first half run backwards.
    let sparse = |short: bool| {
        move |j: &mut serde_json::Value| {
            let uri = j["buffers"][0]["uri"].as_str().unwrap().to_string();
            let (head, data) = uri.split_once(',').unwrap();
            let mut bin = unbase64(data);
            let at = bin.len();
            bin.extend(5u16.to_le_bytes());
            bin.extend(1u16.to_le_bytes());
            j["buffers"][0]["uri"] = format!("{head},{}", base64(&bin)).into();
            j["buffers"][0]["byteLength"] = bin.len().into();
            j["bufferViews"]
                .as_array_mut()
                .unwrap()
                .push(serde_json::json!(
                {"buffer": 0, "byteOffset": at, "byteLength": 2}));
            j["bufferViews"]
                .as_array_mut()
                .unwrap()
                .push(serde_json::json!(
                {"buffer": 0, "byteOffset": at + 2, "byteLength": if short { 1 } else { 2 }}));
            j["accessors"][1]["sparse"] = serde_json::json!({
                "count": 1,
                "indices": {"bufferView": 2, "componentType": 5123},
                "values": {"bufferView": 3}
            });
        }
    };
    let raw = read_gltf(&square_gltf(4, &[0, 1, 2, 0, 2, 3], sparse(false)), None).unwrap();
    assert_eq!(raw.faces, [[0, 1, 2], [0, 2, 1]]);
    let e = read_gltf(&square_gltf(4, &[0, 1, 2, 0, 2, 3], sparse(true)), None).unwrap_err();
    assert!(
        e.contains("indices (accessor 1): sparse values: 2 bytes from byte 0 reach beyond bufferView 3 (1 bytes)"),
        "{e}"
    );
}

/// An external buffer's URI is percent-decoded (exporters write a space
/// as %20).
#[test]
fn gltf_buffer_uris_are_percent_decoded() {
    use penumbra::render::mesh::read_gltf;
    let dir = scratch("gltf-uri");
    let doc = square_gltf(4, &[0, 1, 2, 0, 2, 3], |_| {});
    let mut j: serde_json::Value = serde_json::from_slice(&doc).unwrap();
    let uri = j["buffers"][0]["uri"].as_str().unwrap().to_string();
    let embedded = read_gltf(&doc, None).unwrap();
    // The same bytes in a file whose name has a space.
    let bin = unbase64(uri.split_once(',').unwrap().1);
    std::fs::write(dir.join("my buf.bin"), &bin).unwrap();
    j["buffers"][0]["uri"] = "my%20buf.bin".into();
    let raw = read_gltf(j.to_string().as_bytes(), Some(&dir)).unwrap();
    assert_eq!(raw.faces, embedded.faces);
    assert_eq!(raw.positions, embedded.positions);
}

/// OBJ text as the tools that write it mean it: a byte-order mark, classic
/// Mac line ends and comments after a statement read as the plain file.
#[test]
fn obj_byte_order_marks_cr_line_ends_and_trailing_comments_read_as_meant() {
    use penumbra::render::mesh::read_obj;
    let plain = "v -1 -1 0\nv 1 -1 0\nv 0 1 0\nv 3 3 0\nf 1 2 3\n";
    let want = read_obj(plain.as_bytes()).unwrap();
    assert_eq!(want.faces, [[0, 1, 2]]);
    let variants = [
        format!("\u{feff}{plain}"),
        plain.replace('\n', "\r"),
        plain
            .replace("v 0 1 0", "v 0 1 0 # apex")
            .replace("f 1 2 3", "f 1 2 3 # the face"),
        // Through the `tobj` path (a vertex colour), with both quirks.
        format!(
            "\u{feff}{}",
            plain.replace("v 3 3 0", "v 3 3 0 1 0 0 # red")
        ),
        // Line continuations, in a face, in a vertex (with CR LF ends and
        // a comment after), and a comment line that ends in a backslash.
        plain.replace("f 1 2 3", "f 1 2 \\\n3"),
        format!("# C:\\models\\\n{}", plain.replace('\n', "\r\n"))
            .replace("v 1 -1 0", "v 1 \\\r\n-1 0 # right"),
    ];
    for text in variants {
        let got = read_obj(text.as_bytes()).unwrap_or_else(|e| panic!("{text:?}: {e}"));
        assert_eq!(got.faces, want.faces, "{text:?}");
        assert_eq!(&got.positions[..3], &want.positions[..3], "{text:?}");
    }
}

/// What either OBJ reader would refuse or silently drop is one error
/// naming the line.
#[test]
fn obj_faces_of_fewer_than_three_corners_and_bad_lines_name_the_line() {
    use penumbra::render::mesh::read_obj;
    let v = "v -1 -1 0\nv 1 -1 0\nv 0 1 0\n";
    let cases = [
        (
            format!("{v}f 1 2\n"),
            "line 4: malformed face \"f 1 2\", expected at least three vertices",
        ),
        (
            format!("{v}f 1\nf 1 2 3\n"),
            "line 4: malformed face \"f 1\"",
        ),
        (
            format!("{v}vt 0 0\nf 1/1 2/1\n"),
            "line 5: malformed face \"f 1/1 2/1\", expected at least three",
        ),
        (
            format!("{v}vt 0 0\nf 1/1 2/1 3/5\n"),
            "line 5: face \"f 1/1 2/1 3/5\": texture index 5 is out of range",
        ),
        (
            format!("{v}f 1/1/1/1 2 3\n"),
            "line 4: malformed face \"f 1/1/1/1 2 3\": corner \"1/1/1/1\"",
        ),
        (
            "v -1 -1 0 foo\n".to_string(),
            "line 1: malformed v line \"v -1 -1 0 foo\"",
        ),
        (
            "v -1 -1 0 1 2 3 4\n".to_string(),
            "line 1: malformed v line",
        ),
        (
            "v -1 -1 0 nan\n".to_string(),
            "line 1: vertex 1 is not finite",
        ),
    ];
    for (text, want) in &cases {
        let e = read_obj(text.as_bytes()).unwrap_err();
        assert!(e.contains(want), "{text:?}: {want:?} in {e}");
    }
    // Lines after a continuation keep their numbers.
    let e = read_obj(format!("v -1 \\\n-1 0\n{}f 1 2\n", &v[10..]).as_bytes()).unwrap_err();
    assert!(e.contains("line 5: malformed face \"f 1 2\""), "{e}");
    // A line that is not UTF-8 where `tobj` would read it (the fast
    // reader leaves files with a backslash, a line continuation, to it;
    // it reads bytes and passes over a name that is not UTF-8).
    let mut bytes = b"# C:\\models\nv -1 -1 0\nv 1 -1 0\nv 0 1 0\n".to_vec();
    bytes.extend(b"g caf\xff\nf 1 2 3\n");
    assert_eq!(read_obj(&bytes).unwrap_err(), "line 5 is not UTF-8 text");
    let fast = read_obj(&bytes[bytes.iter().position(|&b| b == b'\n').unwrap() + 1..]).unwrap();
    assert_eq!(fast.faces, [[0, 1, 2]]);
}

/// PLY elements may come in any order: faces before the vertices read
/// as the usual order.
#[test]
fn ply_faces_before_vertices_read_as_the_usual_order() {
    use penumbra::render::mesh::read_ply;
    let head = "ply\nformat ascii 1.0\n";
    let vertex = "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n";
    let face = "element face 1\nproperty list uchar int vertex_indices\n";
    let (vs, fs) = ("0 0 0\n1 0 0\n0 1 0\n", "3 0 1 2\n");
    let usual = read_ply(format!("{head}{vertex}{face}end_header\n{vs}{fs}").as_bytes()).unwrap();
    let swapped = read_ply(format!("{head}{face}{vertex}end_header\n{fs}{vs}").as_bytes()).unwrap();
    assert_eq!(swapped.faces, usual.faces);
    assert_eq!(swapped.positions, usual.positions);
    let out = read_ply(format!("{head}{face}{vertex}end_header\n3 0 1 3\n{vs}").as_bytes());
    assert!(
        out.unwrap_err()
            .contains("face 0: vertex index 3 is out of range, the file has 3 vertices")
    );
}

/// A vertex so far out that the triangle's area overflows is out of range
/// (as 1e12 is), not a degenerate triangle skipped.
#[test]
fn vertices_far_beyond_the_range_are_refused_not_skipped() {
    for (name, x) in [("e12", "1e12"), ("e200", "1e200"), ("e300", "-1e300")] {
        let obj = format!("v {x} 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
        let (code, err, written) = cli_with_mesh(&format!("huge-{name}"), "h.obj", obj.as_bytes());
        assert_eq!(code, 2, "{x}: {err}");
        assert!(!written);
        assert!(
            err.contains("triangle 0 has the vertex [")
                && err.contains("expected coordinates within ±1e9"),
            "{x}: {err}"
        );
        assert!(err.len() < 400, "{x}: short: {err}");
    }
}

/// Five faces of a curved patch; the first four carry `vn` normals, the
/// last has none (`with_normals` and `without` pick which are written).
fn patch_obj(with_normals: bool, without: bool) -> String {
    let mut s = String::from(
        "v -1 1 0\nv 1 1 0.6\nv 1 3 0\nv -1 3 0.3\nv 0 2 -0.5\nv 2.5 2 0.2\n\
         vn 0.1847 0.2855 0.9404\nvn -0.2733 0.3973 0.8761\nvn -0.1625 -0.0100 0.9867\n\
         vn 0.3482 -0.3482 0.8704\nvn -0.0535 0.0535 0.9971\n",
    );
    if with_normals {
        s += "f 1//1 2//2 5//5\nf 2//2 3//3 5//5\nf 3//3 4//4 5//5\nf 4//4 1//1 5//5\n";
    }
    if without {
        s += "f 2 6 3\n";
    }
    s
}

/// `auto` shading takes the file's normals on the faces that have them and
/// leaves the others flat, face by face: a file whose last face has no
/// normals renders as its other faces with their normals plus that face
/// alone (it made the whole mesh flat).
#[test]
fn auto_shading_uses_the_normals_of_the_faces_that_have_them() {
    let dir = scratch("auto-normals");
    let write = |name: &str, text: String| {
        let file = dir.join(name);
        std::fs::write(&file, text).unwrap();
        file
    };
    let mixed = write("mixed.obj", patch_obj(true, true));
    let smooth_part = write("smooth.obj", patch_obj(true, false));
    let flat_part = write("flat.obj", patch_obj(false, true));
    let place = |m: &mut MeshDesc| m.translate = [0.0, 0.5, -2.0];
    let with_meshes = |files: &[(&Path, MeshShading)]| {
        let mut d = small_room();
        for (file, shading) in files {
            let mut m = mesh(file, "red");
            m.shading = *shading;
            place(&mut m);
            d.objects.push(ObjectDesc::Mesh(m));
        }
        render(&d, true)
    };
    let auto = with_meshes(&[(&mixed, MeshShading::Auto)]);
    let by_face = with_meshes(&[
        (&smooth_part, MeshShading::Auto),
        (&flat_part, MeshShading::Auto),
    ]);
    let flat = with_meshes(&[(&mixed, MeshShading::Flat)]);
    assert_eq!(rmse(&auto, &by_face), (0.0, 0.0));
    let (to_flat, _) = rmse(&auto, &flat);
    assert!(to_flat > 1e-3, "the normals were used: rmse {to_flat}");

    // glTF: a primitive without NORMAL is flat beside one with it.
    use penumbra::render::mesh::{build, read_gltf};
    let mut normals = Vec::new();
    for _ in 0..4 {
        for x in [0.0f32, 0.6, 0.8] {
            normals.extend(x.to_le_bytes());
        }
    }
    let gltf = square_gltf(4, &[0, 1, 2, 0, 2, 3], |j| {
        j["buffers"]
            .as_array_mut()
            .unwrap()
            .push(serde_json::json!({
            "byteLength": 48,
            "uri": format!("data:application/octet-stream;base64,{}", base64(&normals))}));
        j["bufferViews"]
            .as_array_mut()
            .unwrap()
            .push(serde_json::json!(
            {"buffer": 1, "byteOffset": 0, "byteLength": 48}));
        j["accessors"]
            .as_array_mut()
            .unwrap()
            .push(serde_json::json!(
            {"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC3"}));
        j["meshes"][0]["primitives"] = serde_json::json!([
            {"attributes": {"POSITION": 0, "NORMAL": 2}, "indices": 1, "mode": 4},
            {"attributes": {"POSITION": 0}, "indices": 1, "mode": 4}]);
    });
    let raw = read_gltf(&gltf, None).unwrap();
    let part = build(raw, &mesh(Path::new("square.gltf"), "red"));
    let unit = |n: glam::DVec3| (n - glam::DVec3::new(0.0, 0.6, 0.8)).length() < 1e-7;
    let with: Vec<bool> = part
        .faces
        .iter()
        .map(|f| f.iter().all(|&i| unit(part.normals[i as usize])))
        .collect();
    let without: Vec<bool> = part
        .faces
        .iter()
        .map(|f| {
            f.iter()
                .all(|&i| part.normals[i as usize] == glam::DVec3::ZERO)
        })
        .collect();
    assert_eq!(with, [true, true, false, false]);
    assert_eq!(without, [false, false, true, true]);
}

/// Through `tobj` (a statement our reader does not know sends the file
/// there), normals are used only if every face has them: `tobj` gives a
/// face without normals one of the file's (here the smooth object's), so
/// such a file is flat as a whole rather than shaded with a normal it does
/// not have.
#[test]
fn tobj_files_use_normals_only_if_every_face_has_them() {
    use penumbra::render::mesh::read_obj;
    let smooth = "vp 0.5 0.5\no smooth\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1\n";
    let raw = read_obj(smooth.as_bytes()).unwrap();
    let normals = raw.face_normals.expect("every face has normals");
    assert_eq!(raw.normals[normals[0][0] as usize], glam::DVec3::Z);
    let mixed = format!("{smooth}o flat\nv 0 0 1\nv 1 0 1\nv 0 1 1\nf 4 5 6\n");
    let raw = read_obj(mixed.as_bytes()).unwrap();
    assert_eq!(raw.faces, [[0, 1, 2], [3, 4, 5]]);
    assert!(raw.face_normals.is_none(), "{:?}", raw.face_normals);
}
