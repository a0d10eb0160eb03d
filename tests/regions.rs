//! Crop windows: `render --region` parts merged by `penumbra merge` equal a
//! one-shot render bit for bit; bad sets of parts are refused.

mod common;

use std::path::{Path, PathBuf};
use std::process::Output;

use common::{penumbra, penumbra_within_memory};
use penumbra::render::output::read_film;
use penumbra::render::region::{read_part, write_part};

fn scratch_dir(name: &str) -> common::Scratch {
    common::Scratch::new(&format!("regions-{name}"))
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// The standard error of a command refused as bad input (exit 2).
fn refused(o: &Output) -> String {
    assert_eq!(o.status.code(), Some(2), "{}", stderr(o));
    stderr(o)
}

const SCENE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/seed-room.json");

/// The same settings for the whole image and every part: an odd size,
/// anti-aliasing (its filter reaches across part borders), reflections and
/// random shadow rays.
fn render_args<'a>(out: &'a str, extra: &[&'a str]) -> Vec<&'a str> {
    let mut args = vec![
        "render",
        SCENE,
        "-o",
        out,
        "--width",
        "161",
        "--height",
        "97",
        "--shadow-rays",
        "9",
        "--sampling",
        "random",
        "--spp",
        "2",
        "--depth",
        "3",
    ];
    args.extend_from_slice(extra);
    args
}

fn render_part(dir: &Path, name: &str, region: &str, extra: &[&str]) -> PathBuf {
    let out = dir.join(name);
    let out_s = out.to_str().unwrap().to_string();
    let mut extra = extra.to_vec();
    extra.extend_from_slice(&["--region", region]);
    let o = penumbra(&render_args(&out_s, &extra));
    assert!(o.status.success(), "{region}: {}", stderr(&o));
    assert!(stderr(&o).starts_with(&format!("region {region} of 161×97")));
    out
}

fn merge(parts: &[PathBuf], out: &Path) -> Output {
    let mut args = vec!["merge".to_string()];
    args.extend(parts.iter().map(|p| p.to_str().unwrap().to_string()));
    args.extend(["-o".to_string(), out.to_str().unwrap().to_string()]);
    let refs: Vec<&str> = args.iter().map(String::as_str).collect();
    penumbra(&refs)
}

#[test]
fn seven_uneven_regions_merge_into_the_one_shot_image() {
    let dir = scratch_dir("seven");
    let whole = dir.join("whole.exr");
    let o = penumbra(&render_args(whole.to_str().unwrap(), &[]));
    assert!(o.status.success(), "{}", stderr(&o));
    // Uneven, not tile-aligned, one of them overlapping two others (same
    // pixels, so the overlap agrees), one rendered with skipping off and
    // one on a single thread.
    let regions: [(&str, &[&str]); 7] = [
        ("0,0,161,13", &[]),
        ("0,13,50,40", &["--threads", "1"]),
        ("50,13,111,21", &[]),
        ("50,34,111,19", &["--no-skip"]),
        ("0,53,7,44", &[]),
        ("7,53,154,44", &[]),
        ("40,30,20,30", &[]),
    ];
    let parts: Vec<PathBuf> = regions
        .iter()
        .enumerate()
        .map(|(i, (r, extra))| render_part(&dir, &format!("part{i}.exr"), r, extra))
        .collect();
    let part = read_part(&parts[1]).unwrap();
    assert_eq!(part.full, (161, 97));
    assert_eq!(
        (part.region.x, part.region.y, part.region.w, part.region.h),
        (0, 13, 50, 40)
    );
    let merged = dir.join("merged.exr");
    let o = merge(&parts, &merged);
    assert!(o.status.success(), "{}", stderr(&o));
    let (a, b) = (read_film(&whole).unwrap(), read_film(&merged).unwrap());
    assert_eq!((a.width, a.height), (b.width, b.height));
    let differing = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .filter(|(p, q)| p.to_array().map(f32::to_bits) != q.to_array().map(f32::to_bits))
        .count();
    assert_eq!(differing, 0, "merged pixels equal the one-shot render's");
    // A part's pixels are the whole image's at its place.
    assert_eq!(part.film.get(3, 5), a.get(3, 13 + 5));

    // PNG output of the merge equals the PNG of the whole render.
    let merged_png = dir.join("merged.png");
    let whole_png = dir.join("whole.png");
    assert!(merge(&parts, &merged_png).status.success());
    assert!(
        penumbra(&render_args(whole_png.to_str().unwrap(), &[]))
            .status
            .success()
    );
    assert_eq!(
        image::open(&merged_png).unwrap().to_rgb8().into_raw(),
        image::open(&whole_png).unwrap().to_rgb8().into_raw()
    );
}

#[test]
fn gaps_foreign_parts_and_disagreeing_overlaps_are_refused() {
    let dir = scratch_dir("refused");
    let top = render_part(&dir, "top.exr", "0,0,161,50", &[]);
    let bottom = render_part(&dir, "bottom.exr", "0,50,161,47", &[]);
    let out = dir.join("out.exr");

    // A gap: the bottom rows are missing.
    let o = merge(std::slice::from_ref(&top), &out);
    let msg = refused(&o);
    assert!(
        msg.contains("a gap: 7567 pixels of the 161×97 image are in no part, the first at (0, 50)"),
        "{msg}"
    );

    // Another scene (another seed) is refused by name.
    let foreign = render_part(&dir, "foreign.exr", "0,50,161,47", &["--seed", "7"]);
    let o = merge(&[top.clone(), foreign.clone()], &out);
    let msg = refused(&o);
    assert!(
        msg.contains("foreign.exr is a part of another scene than") && msg.contains("top.exr"),
        "{msg}"
    );

    // An overlap whose pixels differ (one value changed in the file).
    let mut tampered = read_part(&bottom).unwrap();
    tampered.region.y -= 1;
    tampered.region.h += 1;
    let w = tampered.film.width;
    let mut pixels = vec![glam::Vec3::splat(0.25); w as usize];
    pixels.extend_from_slice(&tampered.film.pixels);
    tampered.film.pixels = pixels;
    tampered.film.height += 1;
    let tampered_path = dir.join("tampered.exr");
    write_part(&tampered, &tampered_path).unwrap();
    let o = merge(&[top.clone(), tampered_path], &out);
    let msg = refused(&o);
    assert!(
        msg.contains("overlap and disagree at pixel (0, 49)"),
        "{msg}"
    );

    // An image that is not a part, and a part of another size.
    let plain = dir.join("plain.exr");
    assert!(
        penumbra(&render_args(plain.to_str().unwrap(), &[]))
            .status
            .success()
    );
    let o = merge(&[top.clone(), plain], &out);
    let msg = refused(&o);
    assert!(msg.contains("not a region part"), "{msg}");
    assert!(!out.exists(), "nothing written after refusals");

    // A PNG cannot be a part; a region past the image is refused.
    let png = dir.join("part.png");
    let o = penumbra(&render_args(
        png.to_str().unwrap(),
        &["--region", "0,0,8,8"],
    ));
    let msg = refused(&o);
    assert!(msg.contains("OpenEXR"), "{msg}");
    let o = penumbra(&render_args(
        dir.join("far.exr").to_str().unwrap(),
        &["--region", "150,0,12,8"],
    ));
    let msg = refused(&o);
    assert!(
        msg.contains("--region: the region 150,0,12,8 reaches past the 161×97 image"),
        "{msg}"
    );

    // The good pair still merges.
    let o = merge(&[top, bottom], &out);
    assert!(o.status.success(), "{}", stderr(&o));
}

/// `compare` of a part with the whole image compares the part's region of
/// it (a part is not a whole image with black around it); parts compare
/// with parts of the same region; anything else is refused by name.
#[test]
fn compare_takes_a_part_against_its_region_of_the_whole_image() {
    let dir = scratch_dir("compare");
    let whole = dir.join("whole.exr");
    let o = penumbra(&render_args(whole.to_str().unwrap(), &[]));
    assert!(o.status.success(), "{}", stderr(&o));
    let part = render_part(&dir, "p.exr", "40,30,50,20", &[]);
    let other = render_part(&dir, "q.exr", "0,0,50,20", &[]);
    let reseeded = render_part(&dir, "r.exr", "40,30,50,20", &["--seed", "9"]);
    let run = |a: &Path, b: &Path| {
        let o = penumbra(&["compare", a.to_str().unwrap(), b.to_str().unwrap()]);
        (
            o.status.code(),
            String::from_utf8_lossy(&o.stdout).into_owned(),
            stderr(&o),
        )
    };
    for (a, b) in [(&part, &whole), (&whole, &part), (&part, &part)] {
        let (code, out, err) = run(a, b);
        assert_eq!(code, Some(0), "{err}");
        assert!(out.starts_with("rmse 0.000000e0\n"), "{out}");
        assert!(
            out.contains("region 40,30,50,20 of the 161×97 image"),
            "{out}"
        );
    }
    // A different seed differs, and the largest difference is named in the
    // whole image's pixels, inside the region.
    let (code, out, err) = run(&reseeded, &whole);
    assert_eq!(code, Some(0), "{err}");
    assert!(!out.starts_with("rmse 0.000000e0"), "{out}");
    let at = out.split("at pixel (").nth(1).unwrap();
    let (x, y) = at.split_once(')').unwrap().0.split_once(", ").unwrap();
    let (x, y): (u32, u32) = (x.parse().unwrap(), y.parse().unwrap());
    assert!((40..90).contains(&x) && (30..50).contains(&y), "{out}");
    // Refused: parts of different regions, a whole image of another size.
    let (code, _, err) = run(&part, &other);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("parts of different regions"), "{err}");
    let small = rendered(&dir, "small.exr", &["--width", "16"]);
    let (code, _, err) = run(&part, &small);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("is the region 40,30,50,20 of a 161×97 image, but") && err.contains("is 16×9"),
        "{err}"
    );
}

/// A gap is named from the parts' rectangles before the whole image's
/// memory is taken (a 1×1 part of a 16384² image), a merge that does not
/// fit in the memory the process may have is refused (exit 2), and the
/// same region rendered twice is the same bytes (the crate writes its
/// attribute maps in an order that changes from run to run: one of ours
/// in each).
#[test]
fn merge_refuses_gaps_and_lack_of_memory_early_and_parts_are_the_same_bytes() {
    let dir = scratch_dir("early");
    let one = dir.join("one.exr");
    let o = penumbra(&[
        "render",
        SCENE,
        "-o",
        one.to_str().unwrap(),
        "--width",
        "16384",
        "--height",
        "16384",
        "--region",
        "0,0,1,1",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let start = std::time::Instant::now();
    let merged = dir.join("m.exr");
    let o = penumbra_within_memory(
        1_000_000,
        &[
            "merge",
            one.to_str().unwrap(),
            "-o",
            merged.to_str().unwrap(),
        ],
    );
    let msg = refused(&o);
    assert!(
        msg.contains(
            "a gap: 268435455 pixels of the 16384×16384 image are in no part, the first at (1, 0)"
        ),
        "{msg}"
    );
    assert!(start.elapsed() < std::time::Duration::from_secs(5));

    // Two halves of a 4000×3000 image under a limit that holds them but
    // not the merged image as well.
    let halves = ambient_halves(&dir);
    let o = penumbra_within_memory(
        250_000,
        &[
            "merge",
            halves[0].to_str().unwrap(),
            halves[1].to_str().unwrap(),
            "-o",
            merged.to_str().unwrap(),
        ],
    );
    let msg = refused(&o);
    assert!(
        msg.contains("the merged 4000×3000 image needs about"),
        "{msg}"
    );
    let o = merge(&halves, &merged);
    assert!(o.status.success(), "{}", stderr(&o));

    let bytes: Vec<Vec<u8>> = (0..8)
        .map(|_| {
            let p = render_part(&dir, "same.exr", "3,3,30,20", &[]);
            std::fs::read(p).unwrap()
        })
        .collect();
    assert!(
        bytes.iter().all(|b| *b == bytes[0]),
        "a region's bytes changed from run to run"
    );
}

/// Merging to a PNG under every memory limit from ample down to too
/// little either writes the image or is refused with exit 2: it aborted
/// (exit 134) where the parts and the merged image fit but not the PNG's
/// codes as well, and panicked (exit 101) where rayon's pool, first used
/// by the write, could not start its threads.
#[test]
fn a_merge_to_png_under_any_memory_limit_writes_or_is_refused() {
    let dir = scratch_dir("merge-limits");
    let halves = ambient_halves(&dir);
    let merged = dir.join("m.png");
    let (mut written, mut refusals) = (0, 0);
    for kib in (150_000..=500_000).rev().step_by(10_000) {
        let kib_text = kib.to_string();
        let o = penumbra_within_memory(
            kib,
            &[
                "merge",
                halves[0].to_str().unwrap(),
                halves[1].to_str().unwrap(),
                "-o",
                merged.to_str().unwrap(),
            ],
        );
        match o.status.code() {
            Some(0) => {
                written += 1;
                assert_eq!(image::image_dimensions(&merged).unwrap(), (4000, 3000));
            }
            Some(2) => {
                refusals += 1;
                let err = stderr(&o);
                let named =
                    err.contains("needs about") && err.contains("more than this process can have");
                assert!(named, "{kib_text}: {err}");
                assert_eq!(err.trim().lines().count(), 1, "{kib_text}: {err}");
            }
            _ => panic!("{kib_text} KiB: {:?}: {}", o.status, stderr(&o)),
        }
    }
    assert!(
        written > 0 && refusals > 0,
        "{written} written, {refusals} refused"
    );
}

/// The top and bottom halves of a 4000×3000 render of the seed room, its
/// ambient term alone, as parts in `dir` (h0.exr, h1.exr).
fn ambient_halves(dir: &Path) -> Vec<PathBuf> {
    ["0,0,4000,1500", "0,1500,4000,1500"]
        .iter()
        .enumerate()
        .map(|(k, r)| {
            rendered(
                dir,
                &format!("h{k}.exr"),
                &[
                    "--width", "4000", "--height", "3000", "--region", r, "--terms", "1,0,0",
                    "--depth", "1",
                ],
            )
        })
        .collect()
}

/// A small part of a `width`×`height` render of the seed room.
fn small_part(dir: &Path, name: &str, width: &str, height: &str, region: &str) -> PathBuf {
    rendered(
        dir,
        name,
        &[
            "--width",
            width,
            "--height",
            height,
            "--shadow-rays",
            "1",
            "--region",
            region,
        ],
    )
}

/// `dir/name`, the seed room rendered with `args`.
fn rendered(dir: &Path, name: &str, args: &[&str]) -> PathBuf {
    let out = dir.join(name);
    let mut all = vec!["render", SCENE, "-o", out.to_str().unwrap()];
    all.extend_from_slice(args);
    let o = penumbra(&all);
    assert!(o.status.success(), "{name}: {}", stderr(&o));
    out
}

/// Refusals name the real difference: a part of another size is refused
/// for its size (not as another scene, though its fingerprint differs
/// too), an attribute from the file is quoted cut to 80 characters on one
/// line, and an empty data window is called empty.
#[test]
fn merge_names_the_real_difference_of_parts() {
    let dir = scratch_dir("named");
    let top = small_part(&dir, "top.exr", "64", "36", "0,0,64,18");
    let taller = small_part(&dir, "taller.exr", "64", "40", "0,18,64,22");
    let out = dir.join("out.exr");
    let o = merge(&[top.clone(), taller], &out);
    let msg = refused(&o);
    assert!(
        msg.contains("taller.exr is a part of a 64×40 image, ") && msg.contains("of a 64×36 one"),
        "{msg}"
    );

    // A crafted fingerprint of 5000 characters, with a line break.
    let mut crafted = read_part(&top).unwrap();
    crafted.region.y = 18;
    crafted.scene = format!("x\n{}", "f".repeat(5000));
    let crafted_path = dir.join("crafted.exr");
    write_part(&crafted, &crafted_path).unwrap();
    let o = merge(&[top.clone(), crafted_path], &out);
    let msg = refused(&o);
    assert!(msg.contains("is a part of another scene than"), "{msg}");
    assert!(msg.contains("… (5003 characters)"), "{msg}");
    assert!(msg.len() < 400, "{} bytes: {msg}", msg.len());
    assert_eq!(msg.lines().count(), 1, "{msg}");

    // A data window whose x ends are reversed (0..-1): empty.
    let mut bytes = std::fs::read(&top).unwrap();
    let key = b"dataWindow\0box2i\0";
    let at = bytes.windows(key.len()).position(|w| w == key).unwrap() + key.len() + 4;
    bytes[at + 8..at + 12].copy_from_slice(&(-1i32).to_le_bytes());
    let empty = dir.join("empty.exr");
    std::fs::write(&empty, bytes).unwrap();
    let o = merge(std::slice::from_ref(&empty), &out);
    let msg = refused(&o);
    assert!(
        msg.ends_with("empty.exr: its data window is empty (x 0..-1)\n"),
        "{msg}"
    );
    assert!(!out.exists());
    // `compare` says the same of it: a part, broken, not an image whose
    // decoder fails in its own words.
    let o = penumbra(&["compare", empty.to_str().unwrap(), top.to_str().unwrap()]);
    let msg = refused(&o);
    assert!(
        msg.ends_with("empty.exr: its data window is empty (x 0..-1)\n"),
        "{msg}"
    );
}
