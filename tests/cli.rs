//! The command line as a user runs it.

mod common;

use std::path::Path;
use std::process::Output;

use common::{files_in, penumbra};

fn scratch_dir(name: &str) -> common::Scratch {
    common::Scratch::new(&format!("cli-{name}"))
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

const SEED_ROOM: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/seed-room.json");

/// The seed room rendered small (64×36, 16 shadow rays) to `out`, with
/// `extra` arguments.
fn render_small(out: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "render",
        SEED_ROOM,
        "-o",
        out.to_str().unwrap(),
        "--width",
        "64",
        "--height",
        "36",
        "--shadow-rays",
        "16",
    ];
    args.extend_from_slice(extra);
    penumbra(&args)
}

/// The JSON a `--stats` file holds.
fn stats_at(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

#[test]
fn render_writes_a_png_of_the_requested_size_and_a_summary() {
    let dir = scratch_dir("render");
    let out = dir.join("room.png");
    let o = render_small(&out, &[]);
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
    // Both files named, each with its size.
    assert_eq!(
        common::refused(&o, "sizes differ"),
        format!(
            "penumbra: image sizes differ: {} is 16×9, {} is 17×9\n",
            a.display(),
            b.display()
        )
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
    let err = common::refused(&o, "a bad radius");
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
        common::refused(&o, format!("{args:?}"));
    }
}

/// Scripts that time penumbra against other renderers read the summary
/// line's first part: `W×H in R s: C camera, S shadow, F reflected rays
/// traced; K shadow rays answered without tracing; M Mray/s traced`, with R
/// the rendering alone, as the last line of standard error. The whole
/// command's time, loading and writing follow it.
#[test]
fn summary_line_keeps_the_form_scripts_read() {
    let dir = scratch_dir("summary-form");
    let (out, stats) = (dir.join("room.png"), dir.join("room.json"));
    let o = render_small(&out, &["--stats", stats.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let json = stats_at(&stats);
    let (rays, seconds) = (&json["rays"], &json["seconds"]);
    let count = |k: &str| rays[k].as_u64().unwrap();
    let secs = |k: &str| seconds[k].as_f64().unwrap();
    let rendering = secs("rendering");
    let start = format!(
        "64×36 in {:.3} s: {} camera, {} shadow, {} reflected rays traced; {} shadow rays answered without tracing; {:.1} Mray/s traced",
        rendering,
        count("camera"),
        count("shadow"),
        count("reflected"),
        count("shadow_skipped"),
        count("traced") as f64 / rendering / 1e6,
    );
    let err = stderr(&o);
    let line = err.trim_end().lines().last().unwrap();
    assert!(line.starts_with(&start), "{start}\n{line}");
    let end = format!(
        "; {:.3} s in all with {:.3} s loading and {:.3} s writing",
        secs("total"),
        secs("loading"),
        secs("writing")
    );
    assert!(line.ends_with(&end), "{end}\n{line}");
}

/// `--stats FILE`: the summary line's figures and every ray count as JSON,
/// consistent with the line and with a render that skips nothing.
#[test]
fn stats_json_has_the_summary_figures_and_every_ray_count() {
    let dir = scratch_dir("stats");
    let run = |name: &str, extra: &[&str]| {
        let (out, stats) = (
            dir.join(format!("{name}.png")),
            dir.join(format!("{name}.json")),
        );
        let mut args = vec!["--stats", stats.to_str().unwrap()];
        args.extend_from_slice(extra);
        let o = render_small(&out, &args);
        assert!(o.status.success(), "{}", stderr(&o));
        let json = stats_at(&stats);
        (json, stderr(&o))
    };
    let (on, line) = run("on", &[]);
    let count = |j: &serde_json::Value, k: &str| j["rays"][k].as_u64().unwrap();
    assert_eq!(
        (on["width"].as_u64(), on["height"].as_u64()),
        (Some(64), Some(36))
    );
    assert_eq!(on["skipping"], true);
    assert_eq!(count(&on, "camera"), 64 * 36);
    for k in ["camera", "shadow", "reflected"] {
        let phrase = format!("{} {k}", count(&on, k));
        assert!(line.contains(&phrase), "{phrase} in {line}");
    }
    let skipped = count(&on, "shadow_skipped");
    assert!(skipped > 0 && count(&on, "shadow") > 0, "{on}");
    assert!(
        line.contains(&format!("{skipped} shadow rays answered")),
        "{line}"
    );
    assert_eq!(
        count(&on, "traced"),
        count(&on, "camera") + count(&on, "reflected") + count(&on, "shadow")
    );
    assert_eq!(count(&on, "effective"), count(&on, "traced") + skipped);
    let seconds = |k: &str| on["seconds"][k].as_f64().unwrap();
    assert!(seconds("rendering") > 0.0 && seconds("rendering") <= seconds("total"));
    assert!(seconds("loading") <= seconds("total"));
    // The three parts are measured one after the other, inside the whole.
    let parts = seconds("loading") + seconds("rendering") + seconds("writing");
    assert!(
        seconds("writing") > 0.0 && parts <= seconds("total"),
        "{on}"
    );

    // Skipping answers exactly the rays it leaves untraced: with it off,
    // the same rays are all traced.
    let (off, _) = run("off", &["--no-skip"]);
    assert_eq!(off["skipping"], false);
    assert_eq!(count(&off, "shadow_skipped"), 0);
    assert_eq!(count(&off, "shadow"), count(&on, "shadow") + skipped);
    assert_eq!(count(&off, "effective"), count(&on, "effective"));

    // `-`: standard output, the JSON alone there (the line goes to
    // standard error).
    let out = dir.join("stdout.png");
    let o = render_small(&out, &["--stats", "-"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let printed: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(printed["rays"], on["rays"], "the same counts on stdout");

    // Through a symbolic link: the link stays, its target gets the JSON.
    #[cfg(unix)]
    {
        let (target, link) = (dir.join("target.json"), dir.join("link.json"));
        std::fs::write(&target, "{}").unwrap();
        std::os::unix::fs::symlink(&target, &link).unwrap();
        let o = render_small(&out, &["--stats", link.to_str().unwrap()]);
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(
            std::fs::symlink_metadata(&link)
                .unwrap()
                .file_type()
                .is_symlink()
        );
        let json = stats_at(&target);
        assert_eq!(json["rays"], on["rays"]);
    }

    // A stats file that would replace the image, a folder, or a file in a
    // folder that is not there: exit 2 before rendering, nothing written.
    let bad = dir.join("bad");
    std::fs::create_dir(&bad).unwrap();
    let out = bad.join("x.png");
    for stats in [
        out.clone(),
        bad.join(".").join("x.png"),
        bad.clone(),
        bad.join("missing").join("s.json"),
    ] {
        let o = penumbra(&[
            "render",
            "-o",
            out.to_str().unwrap(),
            "--stats",
            stats.to_str().unwrap(),
        ]);
        assert_eq!(
            o.status.code(),
            Some(2),
            "{}: {}",
            stats.display(),
            stderr(&o)
        );
        let err = stderr(&o);
        assert!(err.contains("--stats"), "{err}");
        assert!(files_in(&bad).is_empty(), "{:?}", files_in(&bad));
    }
}

/// `--width` or `--height` alone keeps the scene's aspect ratio: the same
/// image as both sides given; a side that follows out of range is named
/// with the option it follows.
#[test]
fn one_side_alone_keeps_the_scene_aspect_ratio() {
    let dir = scratch_dir("aspect");
    let scene = SEED_ROOM;
    let render = |name: &str, size: &[&str]| {
        let out = dir.join(name);
        let mut args = vec!["render", scene, "-o", out.to_str().unwrap()];
        args.extend_from_slice(size);
        let o = penumbra(&args);
        assert!(o.status.success(), "{size:?}: {}", stderr(&o));
        image::open(&out).unwrap().to_rgb8()
    };
    // The seed room is 960×540.
    let both = render("both.png", &["--width", "160", "--height", "90"]);
    let width = render("width.png", &["--width", "160"]);
    let height = render("height.png", &["--height", "90"]);
    assert_eq!(both.dimensions(), (160, 90));
    assert!(width == both && height == both, "the same image");
    // Rounded to the nearest pixel: 100 × 540/960 = 56.25.
    assert_eq!(
        render("round.png", &["--width", "100"]).dimensions(),
        (100, 56)
    );
    // Both given: as given, whatever the aspect.
    let narrow = render("narrow.png", &["--width", "40", "--height", "90"]);
    assert_eq!(narrow.dimensions(), (40, 90));

    let out = dir.join("big.png");
    let o = penumbra(&[
        "render",
        scene,
        "-o",
        out.to_str().unwrap(),
        "--height",
        "16384",
    ]);
    assert_eq!(o.status.code(), Some(2));
    let err = stderr(&o);
    assert!(
        err.contains("camera.width: 29127 is out of range") && err.contains("--height 16384"),
        "{err}"
    );
    assert!(!out.exists());
}

/// Outputs through a symbolic link replace the file it leads to and keep
/// the link (an image, and a stats file through a chain of two links to
/// a file not there yet); a FIFO is written in place, not replaced.
#[cfg(unix)]
#[test]
fn outputs_go_through_links_and_into_fifos() {
    let dir = scratch_dir("links");
    let (image, link) = (dir.join("image.png"), dir.join("link.png"));
    std::fs::write(&image, b"old").unwrap();
    std::os::unix::fs::symlink("image.png", &link).unwrap();
    let (stats, hop, first) = (
        dir.join("stats.json"),
        dir.join("hop.json"),
        dir.join("first.json"),
    );
    std::os::unix::fs::symlink(&hop, &first).unwrap();
    std::os::unix::fs::symlink("stats.json", &hop).unwrap();
    let o = render_small(&link, &["--stats", first.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    for l in [&link, &first, &hop] {
        let kind = std::fs::symlink_metadata(l).unwrap().file_type();
        assert!(kind.is_symlink(), "{} stays a link", l.display());
    }
    assert_eq!(image::open(&image).unwrap().width(), 64);
    let json = stats_at(&stats);
    assert_eq!(json["rays"]["camera"], 64 * 36);

    let fifo = dir.join("stats.fifo");
    let made = std::process::Command::new("mkfifo").arg(&fifo).status();
    if !made.is_ok_and(|s| s.success()) {
        return; // no mkfifo here: the links were the test
    }
    // Opened for reading first, without waiting for a writer: the JSON
    // waits in the pipe, and a FIFO replaced instead of written leaves
    // this end empty (no hang).
    let mut reader = {
        use std::os::unix::fs::OpenOptionsExt;
        std::fs::OpenOptions::new()
            .read(true)
            .custom_flags(libc::O_NONBLOCK)
            .open(&fifo)
            .unwrap()
    };
    let o = render_small(&dir.join("fifo.png"), &["--stats", fifo.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let mut text = String::new();
    std::io::Read::read_to_string(&mut reader, &mut text).unwrap();
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(json["rays"]["camera"], 64 * 36);
    let kind = std::fs::symlink_metadata(&fifo).unwrap().file_type();
    assert!(std::os::unix::fs::FileTypeExt::is_fifo(&kind));
}

/// An EXR into a pipe or a FIFO is the EXR a regular file gets, byte for
/// byte: its encoder goes back to fill in the offset table, which a pipe
/// cannot do (the reader got a broken file and the render failed with
/// "Illegal seek").
#[cfg(unix)]
#[test]
fn an_exr_into_a_pipe_or_a_fifo_is_whole() {
    let dir = scratch_dir("exr-pipe");
    let whole = dir.join("whole.exr");
    let o = render_small(&whole, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let want = std::fs::read(&whole).unwrap();

    // Standard output, a pipe here, through a link with the extension.
    let link = dir.join("out.exr");
    std::os::unix::fs::symlink("/dev/stdout", &link).unwrap();
    let o = render_small(&link, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        o.stdout == want,
        "{} bytes against {}",
        o.stdout.len(),
        want.len()
    );

    let fifo = dir.join("part.exr");
    let made = std::process::Command::new("mkfifo").arg(&fifo).status();
    if !made.is_ok_and(|s| s.success()) {
        return; // no mkfifo here: the pipe was the test
    }
    let reader = {
        let fifo = fifo.clone();
        std::thread::spawn(move || std::fs::read(fifo).unwrap())
    };
    let o = render_small(&fifo, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(reader.join().unwrap() == want);
    let region = render_small(&link, &["--region", "0,0,64,36"]);
    assert!(region.status.success(), "{}", stderr(&region));
    let part = dir.join("part-file.exr");
    std::fs::write(&part, &region.stdout).unwrap();
    let merged = penumbra(&[
        "merge",
        part.to_str().unwrap(),
        "-o",
        link.to_str().unwrap(),
    ]);
    assert!(merged.status.success(), "{}", stderr(&merged));
    assert!(merged.stdout == want, "the merge of the piped part");
}

/// An output in a folder that is not there is refused before any work
/// (exit 2, naming the folder), in `render`, `merge` and `compare --diff`
/// alike; nothing is rendered first and then lost.
#[test]
fn an_output_in_a_missing_folder_is_refused_before_any_work() {
    let dir = scratch_dir("missing-folder");
    let missing = dir.join("no-such-folder");
    let image = dir.join("a.exr");
    let o = penumbra(&[
        "render",
        "--width",
        "8",
        "--height",
        "8",
        "-o",
        image.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = |name: &str| missing.join(name).to_str().unwrap().to_string();
    let runs: [Vec<String>; 3] = [
        vec![
            "render".into(),
            "--width".into(),
            "4096".into(),
            "-o".into(),
            out("x.png"),
        ],
        vec![
            "merge".into(),
            image.to_str().unwrap().into(),
            "-o".into(),
            out("m.exr"),
        ],
        vec![
            "compare".into(),
            image.to_str().unwrap().into(),
            image.to_str().unwrap().into(),
            "--diff".into(),
            out("d.png"),
        ],
    ];
    for args in runs {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let start = std::time::Instant::now();
        let o = penumbra(&args);
        let err = common::refused(&o, format!("{args:?}"));
        assert!(
            err.contains(&format!("there is no folder {}", missing.display())),
            "{args:?}: {err}"
        );
        assert!(
            !err.contains("rays traced"),
            "{args:?}: rendered first: {err}"
        );
        assert!(start.elapsed() < std::time::Duration::from_secs(10));
        assert!(!missing.exists());
    }
}

/// `generate` writes OBJ text: another extension (or none, or `-`) is
/// refused, as a folder that is not there, before anything is written.
#[test]
fn generate_writes_only_obj_files_into_folders_that_are_there() {
    let dir = scratch_dir("generate");
    for (name, want) in [
        ("x.ply", "generate writes Wavefront OBJ (expected .obj)"),
        ("x", "expected .obj"),
        ("-", "expected .obj"),
        ("no-folder/x.obj", "there is no folder"),
    ] {
        let out = if name == "-" {
            "-".into()
        } else {
            dir.join(name)
        };
        let o = penumbra(&[
            "generate",
            "--triangles",
            "100",
            "-o",
            out.to_str().unwrap(),
        ]);
        let err = common::refused(&o, name);
        assert!(err.contains(want), "{name}: {err}");
        assert!(!out.exists() || name == "-", "{name}");
    }
    assert!(!std::path::Path::new("-").exists());
    let ok = dir.join("t.OBJ");
    let o = penumbra(&["generate", "--triangles", "100", "-o", ok.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        penumbra::render::mesh::read_obj(&std::fs::read(&ok).unwrap())
            .unwrap()
            .faces
            .len()
            >= 100
    );
}

/// A number out of range is quoted as typed: `--filter-width 1e-300` was
/// reported as "0 is out of range", `1e300` as "inf".
#[test]
fn an_out_of_range_number_is_quoted_as_typed() {
    let dir = scratch_dir("typed");
    let out = dir.join("x.png");
    for typed in ["1e-300", "1e300", "0.49999"] {
        let o = render_small(&out, &["--filter-width", typed]);
        let err = common::refused(&o, typed);
        assert!(
            err.contains(&format!(": {typed} is out of range, expected 0.5..=8")),
            "{typed}: {err}"
        );
    }
    assert!(!out.exists());
}

/// A negative number without `=` reaches the option's own range check,
/// which names the option (clap took `-5` for an unknown argument and
/// named none).
#[test]
fn a_negative_number_is_refused_by_its_option() {
    let dir = scratch_dir("negative");
    let out = dir.join("x.exr");
    let out = out.to_str().unwrap();
    let cases: [(&[&str], &str); 14] = [
        (&["render", "-o", out, "--width", "-5"], "--width"),
        (&["render", "-o", out, "--height", "-5"], "--height"),
        (&["render", "-o", out, "--spp", "-2"], "--spp"),
        (
            &["render", "-o", out, "--shadow-rays", "-1"],
            "--shadow-rays",
        ),
        (&["render", "-o", out, "--depth", "-1"], "--depth"),
        (&["render", "-o", out, "--threads", "-1"], "--threads"),
        (&["render", "-o", out, "--seed", "-1"], "--seed"),
        (
            &["render", "-o", out, "--scale", "-1"],
            "-1 is out of range",
        ),
        (
            &["render", "-o", out, "--filter-width", "-1"],
            "-1 is out of range",
        ),
        (
            &["render", "-o", out, "--terms", "-1,0,0"],
            "-1 is out of range",
        ),
        (&["render", "-o", out, "--region", "-1,0,10,10"], "--region"),
        (&["bench", "--width", "-5"], "--width"),
        (&["bench", "--spheres", "-1", "--scaling"], "--spheres"),
        (&["generate", "-o", out, "--triangles", "-5"], "--triangles"),
    ];
    for (args, want) in cases {
        let o = penumbra(args);
        let err = common::refused(&o, format!("{args:?}"));
        assert!(!err.contains("unexpected argument"), "{args:?}: {err}");
        assert!(err.contains(want), "{args:?}: {want:?} in {err}");
    }
    assert!(files_in(&dir).is_empty());
}

/// A seed out of its range, `--seed -1` included, is refused as every other
/// whole number out of range is (`-5 is not in 1..=16384`), where clap's
/// u64 parser said "invalid digit found in string"; the largest seed
/// renders.
#[test]
fn a_seed_out_of_range_gets_the_range_message_of_the_other_numbers() {
    let dir = scratch_dir("seed");
    let out = dir.join("x.png");
    let out = out.to_str().unwrap();
    let width = stderr(&penumbra(&["render", "-o", out, "--width", "-5"]));
    assert!(
        width.contains("for '--width <WIDTH>': -5 is not in 1..=16384"),
        "{width}"
    );
    let max = u64::MAX.to_string();
    let cases: [(&[&str], &str, &str); 4] = [
        (
            &["render", "-o", out, "--seed", "-1"],
            "--seed <SEED>",
            "-1",
        ),
        (
            &["render", "-o", out, "--seed", "18446744073709551616"],
            "--seed <SEED>",
            "18446744073709551616",
        ),
        (&["bench", "--seed", "-1"], "--seed <SEED>", "-1"),
        (
            &["bench", "--sphere-seed", "-1"],
            "--sphere-seed <SPHERE_SEED>",
            "-1",
        ),
    ];
    for (args, option, typed) in cases {
        let o = penumbra(args);
        let err = common::refused(&o, format!("{args:?}"));
        let want = format!("for '{option}': {typed} is not in 0..={max}");
        assert!(err.contains(&want), "{args:?}: {want:?} in {err}");
    }
    assert!(files_in(&dir).is_empty());
    let o = render_small(dir.join("max.png").as_path(), &["--seed", &max]);
    assert!(o.status.success(), "{}", stderr(&o));
}

/// An option followed by another option has no value: taking negative
/// numbers must not make `--width --height 5` read `--height` as the width,
/// nor taking any value beginning with `-` (the lists, for `--region
/// -1,0,10,10`) make `--region --width 5` read `--width` as the region.
#[test]
fn an_option_followed_by_another_option_is_missing_its_value() {
    for args in [
        &["render", "--width", "--height", "5"][..],
        &["render", "--depth", "--spp", "2"],
        &["bench", "--runs", "--quick"],
        &["render", "--region", "--width", "5"],
        &["render", "--terms", "--adaptive"],
        &["render", "--translate", "--scale", "2"],
        &["bench", "--counts", "--quick"],
        &["bench", "--spheres", "--scaling"],
        &["bench", "--meshes", "--quick"],
    ] {
        let o = penumbra(args);
        let err = common::refused(&o, format!("{args:?}"));
        assert!(
            err.contains(&format!("a value is required for '{}", args[1])),
            "{args:?}: {err}"
        );
    }
}

/// A value that looks like an option but was given (with `=`, or inside
/// a list) is a value, and a bad one: the message says what is wrong with
/// it, not that it is missing. A region's numbers out of range are named
/// with their range, as other numbers are.
#[test]
fn a_given_value_that_looks_like_an_option_says_what_is_wrong_with_it() {
    let dir = scratch_dir("given-values");
    let out = dir.join("x.exr");
    let out = out.to_str().unwrap();
    let cases: [(&[&str], &str); 6] = [
        (
            &["bench", "--meshes", "18,--quick"],
            "invalid value '--quick' for '--meshes <MESHES>'",
        ),
        (
            &["bench", "--counts", "1,--quick"],
            "invalid value '--quick' for '--counts <COUNTS>'",
        ),
        (
            &["render", "--region=--width", "-o", out],
            "invalid value '--width' for '--region <X,Y,W,H>': \"--width\": expected X,Y,W,H",
        ),
        (
            &["render", "--terms=--adaptive", "-o", out],
            "invalid value '--adaptive' for '--terms",
        ),
        (
            &["render", "--region", "-1,0,10,10", "-o", out],
            "X: -1 is not in 0..=16383",
        ),
        (
            &["render", "--region", "0,0,0,5", "-o", out],
            "W: 0 is not in 1..=16384",
        ),
    ];
    for (args, want) in cases {
        let o = penumbra(args);
        let err = common::refused(&o, format!("{args:?}"));
        assert!(!err.contains("a value is required"), "{args:?}: {err}");
        assert!(err.contains(want), "{args:?}: {want:?} in {err}");
    }
    assert!(files_in(&dir).is_empty());
}

/// `--filter-width` with `--filter box` is refused: the box has no width,
/// and the width was dropped without a word; so is a filter at one sample
/// a pixel.
#[test]
fn a_filter_width_with_the_box_filter_is_refused() {
    let dir = scratch_dir("box-width");
    let out = dir.join("x.png");
    let o = render_small(
        &out,
        &["--spp", "2", "--filter", "box", "--filter-width", "3"],
    );
    let err = common::refused(&o, "");
    assert!(
        err.contains("--filter-width 3") && err.contains("--filter box"),
        "{err}"
    );
    assert!(!out.exists());
    // At one sample a pixel (a ray through its centre) a filter would be
    // dropped without a word: refused, naming what to give.
    for extra in [&["--filter", "box"][..], &["--filter-width", "2"]] {
        let o = render_small(&out, extra);
        let err = common::refused(&o, format!("{extra:?}"));
        assert!(err.contains("give --spp N"), "{extra:?}: {err}");
    }
    assert!(!out.exists());
    // Each alone, and the width with Blackman–Harris, render.
    for extra in [
        &["--filter", "box"][..],
        &["--filter-width", "3"],
        &["--filter", "blackman-harris", "--filter-width", "3"],
    ] {
        let mut args = vec!["--spp", "2"];
        args.extend_from_slice(extra);
        let o = render_small(&out, &args);
        assert!(o.status.success(), "{extra:?}: {}", stderr(&o));
    }
}

/// `--scale` and `--translate` promise what holds: the same image to
/// within rounding, not bit for bit (a scale of 1e-7 moves some pixels by
/// a few 1e-8).
#[test]
fn scale_help_promises_the_same_image_within_rounding() {
    let o = penumbra(&["render", "--help"]);
    let help = String::from_utf8_lossy(&o.stdout);
    assert!(!help.contains("the image stays the same"), "{help}");
    let scale = &help[help.find("--scale").unwrap()..help.find("--translate").unwrap()];
    assert!(scale.contains("to within rounding"), "{scale}");
    assert!(scale.contains("not always bit for bit"), "{scale}");
}
