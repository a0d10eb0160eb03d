//! The bench's logic: sweep rows and CSV, error against ray count, the
//! reference cache and the sphere generator. Tiny images keep it fast.

mod common;

use common::{penumbra, penumbra_ok};
use penumbra::cli::bench::reference::{reference, reference_key};
use penumbra::cli::bench::sweep::{SweepPlan, csv, csv_columns, run_sweep};
use penumbra::render::SEED_ROOM_JSON;
use penumbra::render::generate::{
    Layout, MAX_SPHERES, ROOM_MAX, ROOM_MIN, ROOM_OBJECTS, floor_sphere_radius, generate,
    sphere_radius, spheres_in_room,
};
use penumbra::render::scene_file::{ObjectDesc, limits};
use penumbra::render::{AreaLightModel, Loaded, Sampling, SceneDesc};

fn tiny_room(width: u32, height: u32) -> SceneDesc {
    let mut d = SceneDesc::from_json(SEED_ROOM_JSON).unwrap();
    d.camera.width = width;
    d.camera.height = height;
    d
}

/// End to end through the CLI: one CSV line per pattern × count × model,
/// every line with every column, and the plot written.
#[test]
fn quick_sweep_writes_every_configuration() {
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("cache");
    let stdout = penumbra_ok(&[
        "bench",
        "--quick",
        "--width",
        "16",
        "--height",
        "9",
        "--counts",
        "1,4",
        "--runs",
        "1",
        "--reference-rays",
        "64",
        "--cache",
        cache.to_str().unwrap(),
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    let text = std::fs::read_to_string(dir.path().join("bench-seed-room.csv")).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines[0], csv_columns().join(","));
    // Patterns × 2 counts × models × adaptive off and on, and one row of
    // the exact model (it depends on neither).
    let expected = Sampling::ALL.len() * 2 * (AreaLightModel::ALL.len() - 1) * 2 + 1;
    assert_eq!(lines.len(), 1 + expected);
    let col = |name: &str| csv_columns().iter().position(|c| *c == name).unwrap();
    // The bench renders on all cores; the process's other threads (the
    // caller waiting in the pool, a progress ticker) add at most one more.
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get()) + 1;
    let mut seen = std::collections::HashSet::new();
    for line in &lines[1..] {
        let f: Vec<&str> = line.split(',').collect();
        assert_eq!(f.len(), csv_columns().len(), "{line}");
        assert_eq!((f[col("width")], f[col("height")]), ("16", "9"));
        let time_s = f[col("time_s")].parse::<f64>().unwrap();
        let cpu_s = f[col("cpu_s")].parse::<f64>().unwrap();
        assert!(time_s > 0.0, "{line}");
        // One run: the CPU time is that of the timed render, which kept
        // the threads busy for no longer than its wall time (plus the
        // moments around the timed span: 10 ms).
        assert!(
            cpu_s > 0.0 && cpu_s <= threads as f64 * time_s + 0.01,
            "cpu {cpu_s} s for {time_s} s on {threads} threads: {line}"
        );
        assert!(f[col("rays_traced")].parse::<u64>().unwrap() >= 16 * 9);
        assert!(f[col("rmse")].parse::<f64>().unwrap().is_finite());
        seen.insert((
            f[col("sampling")],
            f[col("model")],
            f[col("adaptive")],
            f[col("shadow_rays")],
        ));
    }
    assert_eq!(seen.len(), expected, "every configuration once");
    let png = std::fs::read(dir.path().join("bench-seed-room.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");
    assert!(stdout.contains("load average"), "{stdout}");
}

/// `penumbra bench --scaling` on 16×9 images, one run each, with `args`.
fn bench_scaling(args: &[&str]) -> String {
    let mut all = vec![
        "bench",
        "--scaling",
        "--runs",
        "1",
        "--width",
        "16",
        "--height",
        "9",
    ];
    all.extend(args);
    penumbra_ok(&all)
}

#[test]
fn scaling_prints_time_per_sphere_count_and_the_ratio() {
    let dir = tempfile::tempdir().unwrap();
    let stdout = bench_scaling(&[
        "--spheres",
        "10,50",
        "--save-scenes",
        dir.path().to_str().unwrap(),
    ]);
    let rows: Vec<&str> = stdout
        .lines()
        .filter(|l| l.trim_start().starts_with("10 ") || l.trim_start().starts_with("50 "))
        .collect();
    assert_eq!(rows.len(), 2, "{stdout}");
    assert!(stdout.contains("time ratio N=50 / N=10"), "{stdout}");
    assert!(stdout.contains("without shadow rays"), "{stdout}");
    let saved = std::fs::read_to_string(dir.path().join("spheres-50.json")).unwrap();
    assert_eq!(
        SceneDesc::from_json(&saved).unwrap(),
        {
            let mut d = spheres_in_room(50, 1);
            d.camera.width = 16;
            d.camera.height = 9;
            d
        },
        "the saved scene is the one timed"
    );
}

#[test]
fn error_falls_with_stratified_ray_count() {
    let dir = tempfile::tempdir().unwrap();
    let desc = tiny_room(48, 27);
    let plan = SweepPlan {
        samplings: vec![Sampling::Stratified],
        models: vec![AreaLightModel::Sampled],
        reference_rays: 1024,
        ..SweepPlan::new(&[1, 64], dir.path())
    };
    let rows = run_sweep(&desc, &plan, &mut |_| {}).unwrap();
    assert_eq!(rows.len(), 2);
    let (r1, r64) = (&rows[0], &rows[1]);
    assert_eq!((r1.shadow_rays, r64.shadow_rays), (1, 64));
    assert!(
        r64.rmse < r1.rmse / 3.0,
        "rmse {} at 1 ray, {} at 64",
        r1.rmse,
        r64.rmse
    );
    assert!(r64.psnr > r1.psnr);
    // More shadow rays are traced (or answered) at 64 per hit.
    assert!(r64.stats.effective() > 10 * r1.stats.effective());
    let text = csv("tiny", &desc, &rows);
    assert_eq!(text.lines().count(), 3);
}

#[test]
fn skipping_off_gives_the_same_image() {
    let dir = tempfile::tempdir().unwrap();
    let plan = SweepPlan {
        samplings: vec![Sampling::Grid],
        models: vec![AreaLightModel::Sampled],
        reference_rays: 16,
        no_skip: true,
        ..SweepPlan::new(&[16], dir.path())
    };
    let rows = run_sweep(&tiny_room(32, 18), &plan, &mut |_| {}).unwrap();
    let n = rows[0].no_skip.expect("measured with skipping off");
    assert_eq!(n.rmse_vs_skip, 0.0);
    // Skipping answers shadow rays without tracing them.
    assert!(rows[0].stats.shadow_skipped() > 0);
    assert!(n.stats.shadow > rows[0].stats.shadow);
}

#[test]
fn reference_is_cached_by_scene() {
    let dir = tempfile::tempdir().unwrap();
    let desc = tiny_room(12, 8);
    let model = AreaLightModel::Sampled;
    let first = reference(&desc, model, 16, dir.path(), false).unwrap();
    assert!(!first.cached);
    let modified = std::fs::metadata(&first.path).unwrap().modified().unwrap();
    let again = reference(&desc, model, 16, dir.path(), false).unwrap();
    assert!(again.cached);
    assert_eq!(again.path, first.path);
    assert_eq!(again.film, first.film);
    assert_eq!(
        std::fs::metadata(&again.path).unwrap().modified().unwrap(),
        modified,
        "a cache hit does not rewrite the file"
    );

    // The settings the sweep varies do not change the key; the scene does.
    let mut swept = desc.clone();
    swept.render.shadow_rays = 4;
    swept.render.sampling = Sampling::Random;
    swept.render.seed = 99;
    assert_eq!(
        reference_key(&swept, model, 16),
        reference_key(&desc, model, 16)
    );
    let mut moved = desc.clone();
    moved.camera.position[0] += 0.5;
    assert_ne!(
        reference_key(&moved, model, 16),
        reference_key(&desc, model, 16)
    );
    assert_ne!(
        reference_key(&desc, AreaLightModel::NearestPoint, 16),
        reference_key(&desc, model, 16)
    );
    assert_ne!(
        reference_key(&desc, model, 64),
        reference_key(&desc, model, 16)
    );
}

/// A scene names a mesh by a path beside it, so its JSON does not change
/// when the mesh does: the key hashes the mesh's content. An edited mesh
/// (or the same scene text beside another mesh) is rendered again, not
/// answered by the old mesh's reference; the same content keeps the key.
#[test]
fn a_mesh_scene_reference_follows_the_mesh_content() {
    let dir = tempfile::tempdir().unwrap();
    let write_scene = |folder: &str, obj: &str| {
        let folder = dir.path().join(folder);
        std::fs::create_dir_all(&folder).unwrap();
        std::fs::write(folder.join("tri.obj"), obj).unwrap();
        let mut value: serde_json::Value = serde_json::from_str(SEED_ROOM_JSON).unwrap();
        value["camera"]["width"] = 12.into();
        value["camera"]["height"] = 8.into();
        let material = value["objects"][0]["material"].clone();
        value["objects"]
            .as_array_mut()
            .unwrap()
            .push(serde_json::json!({
                "type": "mesh", "file": "tri.obj", "material": material
            }));
        let path = folder.join("scene.json");
        std::fs::write(&path, value.to_string()).unwrap();
        SceneDesc::load(&path).unwrap()
    };
    let small = "v -1 0 0\nv 1 0 0\nv 0 2 0\nf 1 2 3\n";
    let large = "v -3 0 -1\nv 3 0 -1\nv 0 6 -1\nf 1 2 3\n";
    let model = AreaLightModel::Sampled;
    let cache = dir.path().join("cache");

    let a = write_scene("a", small);
    let first = reference(&a, model, 16, &cache, false).unwrap();
    assert!(!first.cached);
    assert!(reference(&a, model, 16, &cache, false).unwrap().cached);

    // The same scene text beside another mesh: another key, rendered anew.
    let b = write_scene("b", large);
    assert_eq!(a.to_json(), b.to_json());
    assert_ne!(reference_key(&a, model, 16), reference_key(&b, model, 16));
    let other = reference(&b, model, 16, &cache, false).unwrap();
    assert!(!other.cached);
    assert_ne!(other.film, first.film, "the larger triangle shows");

    // The mesh edited in place: not the first entry, but the one of the
    // same content (the other folder's).
    let edited = write_scene("a", large);
    assert_eq!(
        reference_key(&edited, model, 16),
        reference_key(&b, model, 16)
    );
    let again = reference(&edited, model, 16, &cache, false).unwrap();
    assert_eq!(again.path, other.path);
    assert_eq!(again.film, other.film);
    // Back to the first content: the first entry's key again.
    let back = write_scene("a", small);
    assert_eq!(
        reference_key(&back, model, 16),
        reference_key(&a, model, 16)
    );
}

/// With several camera samples a pixel, a reference puts them where the
/// renders do (scrambled by the scene's seed, a part of its key): the
/// sweep's error is the light's. Against a reference with its own places
/// the exact model's row read the anti-aliasing's noise, ~2e-2.
#[test]
fn an_anti_aliased_sweep_measures_the_light_not_the_anti_aliasing() {
    let dir = tempfile::tempdir().unwrap();
    let mut desc = tiny_room(48, 27);
    desc.render.samples_per_pixel = 4;
    let plan = SweepPlan {
        samplings: vec![Sampling::Grid],
        models: vec![AreaLightModel::Exact, AreaLightModel::NearestPoint],
        reference_rays: 256,
        ..SweepPlan::new(&[256], dir.path())
    };
    let rows = run_sweep(&desc, &plan, &mut |_| {}).unwrap();
    assert_eq!(rows.len(), 2);
    for row in &rows {
        assert!(row.rmse < 3e-3, "{:?}: {}", row.model, row.rmse);
    }

    let model = AreaLightModel::Sampled;
    let mut reseeded = desc.clone();
    reseeded.render.seed += 1;
    assert_ne!(
        reference_key(&reseeded, model, 16),
        reference_key(&desc, model, 16)
    );
    desc.render.samples_per_pixel = 1;
    reseeded.render.samples_per_pixel = 1;
    assert_eq!(
        reference_key(&reseeded, model, 16),
        reference_key(&desc, model, 16)
    );
}

/// `--edits` on a tiny image, whose one-shot renders take less CPU time
/// than the clock counts: no ratio of CPU times is printed as "inf×".
#[test]
fn edits_on_a_tiny_image_print_finite_ratios() {
    let stdout = penumbra_ok(&["bench", "--edits", "--width", "1", "--threads", "1"]);
    assert!(
        stdout.contains("re-trace full quality / one-shot"),
        "{stdout}"
    );
    assert!(
        !stdout.contains("inf") && !stdout.contains("NaN"),
        "{stdout}"
    );
}

/// A size the bench's options make out of range is named as `render`
/// names it: the scene file, the field, and the option whose side followed
/// at the scene's aspect ratio (the bench said only the field).
#[test]
fn a_bench_size_out_of_range_names_the_file_and_the_option() {
    let dir = tempfile::tempdir().unwrap();
    let tall = dir.path().join("tall.json");
    let mut desc = tiny_room(1, 16384);
    desc.render.shadow_rays = 1;
    std::fs::write(&tall, desc.to_json()).unwrap();
    let o = penumbra(&[
        "bench",
        tall.to_str().unwrap(),
        "--quick",
        "--width",
        "16384",
    ]);
    let err = common::refused(&o, "");
    assert!(
        err.contains(&format!("{}: camera.height: ", tall.display()))
            && err.contains("the height that --width 16384 gives"),
        "{err}"
    );
}

/// The spheres of a scene.
fn spheres_of(desc: &SceneDesc) -> Vec<&penumbra::render::scene_file::SphereDesc> {
    desc.objects
        .iter()
        .filter_map(|o| match o {
            ObjectDesc::Sphere(s) => Some(s),
            _ => None,
        })
        .collect()
}

#[test]
fn generated_spheres_fill_the_room_without_touching_walls() {
    for n in [1usize, 10, 1000] {
        let desc = spheres_in_room(n, 7);
        let spheres = spheres_of(&desc);
        assert_eq!(spheres.len(), n);
        assert!(
            desc.objects
                .iter()
                .all(|o| matches!(o, ObjectDesc::Sphere(_) | ObjectDesc::Plane(_))),
            "the seed room's boxes are gone"
        );
        let r = sphere_radius(n);
        for s in &spheres {
            assert_eq!(s.radius, r);
            for i in 0..3 {
                assert!(s.center[i] - s.radius > ROOM_MIN[i], "{s:?}");
                assert!(s.center[i] + s.radius < ROOM_MAX[i], "{s:?}");
            }
        }
        // Builds (valid scene, BVH past a handful of objects).
        let loaded = Loaded::new(&desc).unwrap();
        assert_eq!(loaded.scene.bvh.is_empty(), n <= 8);
        assert_eq!(spheres_in_room(n, 7), desc, "deterministic");
    }
    assert_ne!(spheres_in_room(10, 1), spheres_in_room(10, 2));
    // Constant volume fraction: r ∝ N^(-1/3).
    let ratio = sphere_radius(10) / sphere_radius(10_000);
    assert!((ratio - 10.0).abs() < 1e-3, "{ratio}");
}

#[test]
fn floor_layout_lays_one_layer_on_the_floor() {
    for n in [1usize, 10, 1000] {
        let desc = generate(n, 7, Layout::Floor);
        let r = floor_sphere_radius(n);
        let spheres = spheres_of(&desc);
        assert_eq!(spheres.len(), n);
        for s in &spheres {
            assert_eq!(s.radius, r);
            let bottom = s.center[1] - s.radius;
            assert!(bottom > ROOM_MIN[1] && bottom < ROOM_MIN[1] + 1e-5, "{s:?}");
            for i in [0, 2] {
                assert!(s.center[i] - s.radius > ROOM_MIN[i], "{s:?}");
                assert!(s.center[i] + s.radius < ROOM_MAX[i], "{s:?}");
            }
        }
        assert_eq!(generate(n, 7, Layout::Floor), desc, "deterministic");
    }
    // Constant floor coverage: r ∝ N^(-1/2).
    let ratio = floor_sphere_radius(10) / floor_sphere_radius(10_000);
    assert!((ratio - 1000f64.sqrt()).abs() < 1e-3, "{ratio}");
    // The bench takes the layout.
    let stdout = bench_scaling(&["--spheres", "10,20", "--layout", "floor"]);
    assert!(stdout.contains("Floor layout"), "{stdout}");
    assert!(
        stdout.contains(&format!("{:.4}", floor_sphere_radius(20))),
        "{stdout}"
    );
}

/// The sweep's outputs are checked before any work: a plot that is not a
/// PNG, one file for the CSV and the plot, a missing folder, a file where
/// `--out` or `--cache` names a folder (each failed only after the whole
/// sweep, or silently lost the CSV).
#[test]
fn bench_outputs_are_refused_before_the_sweep() {
    let dir = std::env::temp_dir().join(format!("penumbra-bench-outputs-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("a-file");
    std::fs::write(&file, b"x").unwrap();
    let same = dir.join("same.png");
    let file_s = file.to_str().unwrap();
    let same_s = same.to_str().unwrap();
    let cases: [(&[&str], &str); 6] = [
        (
            &["--plot", "p.exr"],
            "p.exr: --plot writes a PNG: the name must end in .png",
        ),
        (&["--plot", "p"], "--plot writes a PNG"),
        (
            &["--csv", same_s, "--plot", same_s],
            "--csv and --plot name the same file",
        ),
        (
            &["--plot", "/no-such-folder/p.png"],
            "there is no folder /no-such-folder",
        ),
        (&["--out", file_s], "--out is a file, expected a folder"),
        (&["--cache", file_s], "--cache is a file, expected a folder"),
    ];
    for (extra, want) in cases {
        let mut args = vec!["bench", "--quick", "--counts", "1", "--runs", "1"];
        args.extend_from_slice(extra);
        let start = std::time::Instant::now();
        let o = penumbra(&args);
        let err = common::refused(&o, format!("{extra:?}"));
        assert!(err.contains(want), "{extra:?}: {want:?} in {err}");
        assert!(
            !String::from_utf8_lossy(&o.stdout).contains("reference"),
            "{extra:?}: the sweep ran first"
        );
        assert!(
            start.elapsed() < std::time::Duration::from_secs(20),
            "{extra:?}"
        );
        assert!(!same.exists());
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// Files where the default `--out` and `--cache` folders would go stop
/// only the modes that write there: `--scaling` writes neither and runs;
/// the sweep (both) and `--spp-split` (the cache) are refused, naming the
/// flag.
#[test]
fn a_file_at_a_default_folder_stops_only_the_modes_that_use_it() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("target")).unwrap();
    for name in ["penumbra-bench", "penumbra-cache"] {
        std::fs::write(dir.path().join("target").join(name), b"x").unwrap();
    }
    let run = |args: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_penumbra"))
            .current_dir(dir.path())
            .arg("bench")
            .args(args)
            .output()
            .unwrap()
    };
    let scaling = run(&[
        "--scaling",
        "--spheres",
        "1",
        "--width",
        "16",
        "--runs",
        "1",
    ]);
    let stdout = String::from_utf8_lossy(&scaling.stdout);
    assert!(
        scaling.status.success(),
        "{}",
        String::from_utf8_lossy(&scaling.stderr)
    );
    assert!(stdout.contains("load average at end"), "{stdout}");
    for (args, flag) in [
        (&["--quick", "--counts", "1", "--runs", "1"][..], "--out"),
        (&["--spp-split", "--width", "16"], "--cache"),
    ] {
        let o = run(args);
        let err = common::refused(&o, format!("{args:?}"));
        assert!(
            err.contains(&format!("{flag} is a file, expected a folder")),
            "{args:?}: {err}"
        );
    }
}

/// `args` refused by the option parser (exit 2, a conflict or a missing
/// option named) before any work: nothing on standard output.
fn assert_refused_by_the_parser(args: &[&str]) {
    let o = penumbra(args);
    let err = common::refused(&o, format!("{args:?}"));
    assert!(
        err.contains("cannot be used with") || err.contains("required arguments were not provided"),
        "{args:?}: {err}"
    );
    assert!(String::from_utf8_lossy(&o.stdout).is_empty(), "{args:?}");
}

/// `--save-scenes` writes as every output does: a file where its folder
/// would go and a read-only scene file are refused (exit 2) before any
/// work, and a write cut short (a file size limit) leaves the old file
/// whole, not a truncated JSON.
#[test]
fn saved_scenes_are_written_whole_or_refused_first() {
    let dir = tempfile::tempdir().unwrap();
    let saved = dir.path().join("saved");
    let bench = |extra: &str| {
        let o = std::process::Command::new("sh")
            .arg("-c")
            .arg(format!(
                "{extra} exec \"$0\" bench --scaling --spheres 2000 --width 16 --runs 1 --save-scenes \"$1\""
            ))
            .arg(env!("CARGO_BIN_EXE_penumbra"))
            .arg(&saved)
            .output()
            .unwrap();
        (
            o.status.code(),
            String::from_utf8_lossy(&o.stderr).into_owned(),
        )
    };
    let file = saved.join("spheres-2000.json");

    std::fs::write(&saved, b"x").unwrap();
    let (code, err) = bench("");
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("--save-scenes is a file, expected a folder"),
        "{err}"
    );
    std::fs::remove_file(&saved).unwrap();

    let (code, err) = bench("");
    assert_eq!(code, Some(0), "{err}");
    let whole = std::fs::read_to_string(&file).unwrap();
    assert_eq!(SceneDesc::from_json(&whole).unwrap().objects.len(), 2005);

    // 50 blocks of 512 bytes: less than the scene's JSON.
    assert!(whole.len() > 50 * 512);
    let (code, err) = bench("ulimit -f 50;");
    assert_eq!(code, Some(1), "{err}");
    assert_eq!(std::fs::read_to_string(&file).unwrap(), whole);

    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&file, std::fs::Permissions::from_mode(0o444)).unwrap();
    let (code, err) = bench("");
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("read-only"), "{err}");
    assert!(!err.contains("load average"), "{err}");
}

/// The files the sweep and `--exact` write under `--out` by their default
/// names are refused before the work when read-only, as the same file
/// named by `--csv` is: not found read-only minutes later.
#[test]
fn read_only_default_outputs_are_refused_before_the_work() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    for (name, mode) in [
        ("bench-seed-room.csv", "--quick"),
        ("bench-seed-room.png", "--quick"),
        ("exact-error-seed-room.png", "--exact"),
    ] {
        let path = dir.path().join(name);
        std::fs::write(&path, b"old").unwrap();
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o444)).unwrap();
        let mut args = vec!["bench", mode, "--width", "16", "--out", out, "--cache", out];
        if mode == "--quick" {
            args.extend(["--counts", "1", "--runs", "1"]);
        }
        let o = penumbra(&args);
        let err = common::refused(&o, name);
        assert!(err.contains("read-only"), "{name}: {err}");
        assert!(
            !String::from_utf8_lossy(&o.stdout).contains("reference"),
            "{name}: the work ran first"
        );
        std::fs::remove_file(&path).unwrap();
    }
}

/// One mode a run, and the spheres' options only with spheres: a second
/// mode, or `--layout` without `--spheres`, was silently dropped.
#[test]
fn conflicting_bench_modes_are_refused() {
    for args in [
        &["bench", "--target", "--slopes"][..],
        &["bench", "--exact", "--edits"],
        &["bench", "--spp-split", "--target"],
        &["bench", "--layout", "floor"],
        &["bench", "--save-scenes", "/tmp"],
    ] {
        assert_refused_by_the_parser(args);
    }
}

/// An image too small to hold a penumbra pixel is refused (exit 2, with a
/// width that has some): it printed "0 penumbra pixels", RMSE 0 everywhere
/// and a slope of NaN, with exit 0.
#[test]
fn slopes_refuse_an_image_without_penumbra_pixels() {
    for size in [&["--width", "1", "--height", "1"][..], &["--width", "3"]] {
        let mut args = vec!["bench", "--slopes"];
        args.extend_from_slice(size);
        let o = penumbra(&args);
        let (out, err) = (
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr),
        );
        assert_eq!(o.status.code(), Some(2), "{size:?}: {out}{err}");
        assert!(
            err.contains("--slopes: no penumbra pixels at")
                && err.contains("no error to fit; the smallest width with some is --width "),
            "{size:?}: {err}"
        );
        assert!(!out.contains("NaN") && !err.contains("NaN"), "{out}{err}");
    }
}

/// `--spheres` takes what the room can hold: the room's own objects and
/// the spheres within the format's object limit (1 000 000 spheres were
/// taken and then refused as "1000005 objects", naming no option).
#[test]
fn spheres_stop_at_what_the_room_holds() {
    assert_eq!(
        generate(1, 1, Layout::Volume).objects.len(),
        ROOM_OBJECTS + 1
    );
    assert_eq!(MAX_SPHERES + ROOM_OBJECTS, limits::MAX_OBJECTS);
    let o = penumbra(&["bench", "--spheres", "10,1000000", "--scaling"]);
    let err = common::refused(&o, "");
    assert!(
        err.contains("--spheres") && err.contains(&format!("1..={MAX_SPHERES}")),
        "{err}"
    );
}

/// A scene file given with `--spheres` or `--meshes` (which make their own
/// scenes) is refused in one line, exit 2: it was silently left out. So is
/// an option the mode does not use.
#[test]
fn a_scene_or_option_a_mode_does_not_use_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("room.json");
    std::fs::write(&scene, SEED_ROOM_JSON).unwrap();
    let scene = scene.to_str().unwrap();
    for (args, want) in [
        (
            &[
                "bench",
                scene,
                "--spheres",
                "10",
                "--scaling",
                "--runs",
                "1",
            ][..],
            "--spheres generates its own scenes",
        ),
        (
            &[
                "bench",
                scene,
                "--spheres",
                "10",
                "--quick",
                "--counts",
                "1",
            ],
            "--spheres generates its own scenes",
        ),
        (
            &["bench", scene, "--meshes", "18", "--runs", "1"],
            "--meshes measures its own scenes",
        ),
    ] {
        let o = penumbra(args);
        let err = common::refused(&o, format!("{args:?}"));
        assert!(err.contains(want) && err.contains("room.json"), "{err}");
        assert_eq!(err.trim().lines().count(), 1, "{err}");
        assert!(String::from_utf8_lossy(&o.stdout).is_empty(), "{args:?}");
    }
    for args in [
        &["bench", "--target", "--width", "16"][..],
        &["bench", "--target", "--depth", "2"],
        &["bench", "--target", "--spheres", "10"],
        &["bench", "--slopes", "--runs", "2"],
        &["bench", "--slopes", "--depth", "2"],
        &["bench", "--edits", "--cache", "c"],
        &["bench", "--exact", "--counts", "1"],
        &["bench", "--spp-split", "--out", "o"],
        &["bench", "--spp-split", "--reference-rays", "16"],
        &["bench", "--meshes", "18", "--spheres", "10"],
        &["bench", "--meshes", "18", "--no-skip"],
        &[
            "bench",
            "--spheres",
            "10",
            "--scaling",
            "--plot-time",
            "cpu",
        ],
        &["bench", "--sphere-seed", "3"],
        &["bench", "--spp-split", "--spp", "4"],
    ] {
        assert_refused_by_the_parser(args);
    }
}

/// A damaged cache entry (an EXR cut short, a .json of garbage, as an
/// interrupted bench could leave) is rendered again and the bench
/// succeeds; the next run finds the entry whole.
#[test]
fn a_damaged_reference_cache_entry_is_rendered_again() {
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("cache");
    let sweep = || {
        penumbra_ok(&[
            "bench",
            "--width",
            "12",
            "--height",
            "8",
            "--counts",
            "1",
            "--runs",
            "1",
            "--no-adaptive",
            "--reference-rays",
            "16",
            "--cache",
            cache.to_str().unwrap(),
            "--out",
            dir.path().to_str().unwrap(),
        ])
    };
    sweep();
    let entries: Vec<std::path::PathBuf> = std::fs::read_dir(&cache)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    let exrs: Vec<_> = entries
        .iter()
        .filter(|p| p.extension().is_some_and(|e| e == "exr"))
        .collect();
    assert!(!exrs.is_empty(), "{entries:?}");
    for exr in &exrs {
        let bytes = std::fs::read(exr).unwrap();
        std::fs::write(exr, &bytes[..bytes.len() / 2]).unwrap();
        std::fs::write(exr.with_extension("json"), b"{\"camera\": [garbage").unwrap();
    }
    let stdout = sweep();
    for exr in &exrs {
        let film = penumbra::render::output::read_film(exr).unwrap();
        assert_eq!((film.width, film.height), (12, 8));
        let json = std::fs::read_to_string(exr.with_extension("json")).unwrap();
        SceneDesc::from_json(&json).unwrap();
    }
    assert!(!stdout.contains("cached"), "{stdout}");
    assert!(sweep().contains("cached"));
}

/// The .json beside a cached reference is replaced whole, never rewritten
/// in place (as the EXR is): an interrupted write leaves the old entry or
/// none, not half of one. A second name for the old file keeps it.
#[test]
fn a_reference_cache_json_is_replaced_not_rewritten() {
    use std::os::unix::fs::MetadataExt;
    let dir = tempfile::tempdir().unwrap();
    let desc = tiny_room(12, 8);
    let model = AreaLightModel::Sampled;
    let first = reference(&desc, model, 16, dir.path(), false).unwrap();
    let json = first.path.with_extension("json");
    let old = dir.path().join("old.json");
    std::fs::hard_link(&json, &old).unwrap();
    reference(&desc, model, 16, dir.path(), true).unwrap();
    let (new, kept) = (
        std::fs::metadata(&json).unwrap(),
        std::fs::metadata(&old).unwrap(),
    );
    assert_ne!(new.ino(), kept.ino(), "the .json was rewritten in place");
    assert_eq!(kept.nlink(), 1);
}

/// `--exact` with several generated scenes measures each of them, not
/// only the first, each with its own error image.
#[test]
fn exact_measures_every_scene_of_spheres() {
    let dir = tempfile::tempdir().unwrap();
    let stdout = penumbra_ok(&[
        "bench",
        "--exact",
        "--spheres",
        "3,4",
        "--width",
        "16",
        "--height",
        "9",
        "--cache",
        dir.path().join("cache").to_str().unwrap(),
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    for name in ["spheres-3", "spheres-4"] {
        assert!(
            stdout.contains(&format!("exact model on {name}: 16×9")),
            "{stdout}"
        );
        assert!(dir.path().join(format!("exact-error-{name}.png")).is_file());
    }
}
