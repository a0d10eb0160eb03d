use std::io::{IsTerminal, Write as _};
use std::path::Path;
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressStyle};

use super::{CliError, RenderArgs, SceneOverrides};
use crate::render::output::{FileKind, PngCodes, write_atomic, write_film};
use crate::render::region::{Part, check_region, fingerprint, write_part};
use crate::render::{
    CancelToken, Loaded, RenderOptions, Scene, SceneDesc, TileRect, TileUpdate, on_threads,
};

/// Loads and builds a scene (the built-in seed room for `None`) with
/// overrides; also returns the description it was built from. `before_load`
/// sees the description before its meshes are read, which may take long
/// (a refusal then comes at once).
pub fn load_scene(
    path: Option<&Path>,
    overrides: &SceneOverrides,
    before_load: impl FnOnce(&SceneDesc) -> Result<(), CliError>,
) -> Result<(SceneDesc, Loaded), CliError> {
    let filter = overrides.filter()?;
    let desc = load_desc(path, overrides)?;
    // One sample a pixel is a ray through its centre: a filter would be
    // dropped without a word.
    if filter.is_some() && desc.render.samples_per_pixel == 1 {
        let given = match (overrides.filter, overrides.filter_width) {
            (Some(_), Some(_)) => "--filter and --filter-width weigh",
            (Some(_), None) => "--filter weighs",
            _ => "--filter-width sets the reach of",
        };
        return Err(CliError::input(format!(
            "{given} several camera samples a pixel, and this image has one: \
             give --spp N (or render.samples_per_pixel in the scene)"
        )));
    }
    before_load(&desc)?;
    let _working = crate::render::memory::working(
        crate::render::memory::Work::File,
        match path {
            Some(p) => p.display().to_string(),
            None => "the built-in seed room".to_string(),
        },
    );
    let o = overrides;
    // --scale and --translate go through the same validation as the file;
    // the message says that they made the scene what it is.
    let n = |v: f64| {
        if v == 0.0 || (1e-4..1e9).contains(&v.abs()) {
            format!("{v}")
        } else {
            format!("{v:e}")
        }
    };
    let scale = o.scale.map(|s| format!(" --scale {}", n(s)));
    let translate = o
        .translate
        .map(|t| format!(" --translate {},{},{}", n(t[0]), n(t[1]), n(t[2])));
    let moved: String = [scale, translate].into_iter().flatten().collect();
    let moved = if moved.is_empty() {
        moved
    } else {
        format!(" (after{moved})")
    };
    let loaded = Loaded::new(&desc).map_err(|mut e| {
        super::name_followed_side(&mut e, o.width, o.height);
        e.message += &moved;
        e
    });
    let loaded = loaded.map(|mut l| {
        if let Some(f) = filter {
            l.settings.filter = f;
        }
        l
    });
    if let Ok(l) = &loaded
        && (l.scene.triangles > 0 || l.scene.degenerate_triangles > 0)
    {
        super::print_stderr(format_args!(
            "triangles: {} ({} degenerate skipped)",
            l.scene.triangles, l.scene.degenerate_triangles
        ));
    }
    let loaded = match path {
        Some(p) => loaded.map_err(|e| CliError::input(e.in_file(p))),
        None => loaded.map_err(CliError::input),
    }?;
    Ok((desc, loaded))
}

/// Loads a scene description (the built-in seed room for `None`) and
/// applies overrides; not validated yet.
pub fn load_desc(path: Option<&Path>, overrides: &SceneOverrides) -> Result<SceneDesc, CliError> {
    let mut desc = match path {
        Some(p) => SceneDesc::load(p).map_err(CliError::input)?,
        None => {
            SceneDesc::from_json(crate::render::scene::SEED_ROOM_JSON).map_err(CliError::input)?
        }
    };
    let o = overrides;
    let c = &mut desc.camera;
    match (o.width, o.height) {
        (Some(w), Some(h)) => (c.width, c.height) = (w, h),
        // One side alone: the other follows at the scene's aspect ratio
        // (the same view at another size, as `bench` sizes it), unless
        // the scene's own size is out of range (validation then names it).
        (Some(w), None) => {
            c.height = at_aspect(w, c.height, c.width).unwrap_or(c.height);
            c.width = w;
        }
        (None, Some(h)) => {
            c.width = at_aspect(h, c.width, c.height).unwrap_or(c.width);
            c.height = h;
        }
        (None, None) => {}
    }
    let r = &mut desc.render;
    if let Some(n) = o.shadow_rays {
        r.shadow_rays = n;
    }
    if let Some(s) = o.sampling {
        r.sampling = s.into();
    }
    if let Some(d) = o.depth {
        r.max_depth = d;
    }
    if let Some(m) = o.model {
        r.area_light_model = m.into();
    }
    if let Some(s) = o.seed {
        r.seed = s;
    }
    if let Some([a, d, s]) = o.terms {
        r.terms.ambient = a;
        r.terms.diffuse = d;
        r.terms.specular = s;
    }
    if o.adaptive {
        r.adaptive = true;
    }
    if let Some(n) = o.spp {
        r.samples_per_pixel = n;
    }
    if o.cutaway {
        r.cutaway = true;
    }
    if let Some(f) = o.scale {
        desc = desc.scaled(f);
    }
    if let Some(t) = o.translate {
        desc = desc.translated(t);
    }
    Ok(desc)
}

/// The side that goes with `given` at the aspect ratio `side` : `other`
/// (rounded, at least 1), or `None` where that ratio is not of a valid
/// image size.
fn at_aspect(given: u32, side: u32, other: u32) -> Option<u32> {
    let valid = 1..=crate::render::scene_file::limits::MAX_SIDE;
    (valid.contains(&side) && valid.contains(&other))
        .then(|| ((given as f64 * side as f64 / other as f64).round() as u32).max(1))
}

/// What an interrupted render says.
const INTERRUPTED: &str = "interrupted: no image written";

/// `penumbra render`.
pub fn render(args: &RenderArgs) -> Result<(), CliError> {
    let start = Instant::now();
    // Until the render starts, SIGINT, SIGTERM and SIGHUP end the process
    // at once with the line, even in a blocking read of a FIFO scene; the
    // render's own handling takes over after loading.
    super::safety::end_on_signals(INTERRUPTED);
    FileKind::of(&args.output).map_err(CliError::input)?;
    super::safety::refuse_missing_folder(&args.output, "output")?;
    super::safety::refuse_read_only(&args.output, "output")?;
    if let Some(scene) = &args.scene {
        super::safety::refuse_overwriting_inputs(&args.output, "output", &[("scene", scene)])?;
    }
    if let Some(stats) = &args.stats {
        check_stats_path(stats, args)?;
    }
    if args.region.is_some() && FileKind::of(&args.output).ok() != Some(FileKind::Exr) {
        return Err(CliError::input(format!(
            "{}: --region writes an OpenEXR part (.exr): only it records where the region sits",
            args.output.display()
        )));
    }
    // The scene's meshes are inputs too, known once it is read: refused
    // before they are loaded (a large mesh takes a while).
    let refuse_mesh_outputs = |desc: &SceneDesc| {
        let meshes = desc.mesh_files();
        let meshes: Vec<(&str, &Path)> = meshes.iter().map(|m| ("mesh", m.as_path())).collect();
        super::safety::refuse_overwriting_inputs(&args.output, "output", &meshes)?;
        if let Some(stats) = args.stats.as_deref().filter(|s| s.as_os_str() != "-") {
            super::safety::refuse_overwriting_inputs(stats, "--stats file", &meshes)?;
        }
        Ok(())
    };
    let (desc, mut loaded) =
        load_scene(args.scene.as_deref(), &args.overrides, refuse_mesh_outputs)?;
    loaded.settings.skip = !args.no_skip;
    let scene = loaded.scene.clone();
    if let Some(region) = args.region {
        check_region(region, scene.camera.width, scene.camera.height)
            .map_err(|e| CliError::input(format!("--region: {e}")))?;
    }
    let area = args.region.unwrap_or(TileRect::whole(&scene.camera));
    let threads = args.threads.map(|n| n as usize);
    check_memory(area, FileKind::of(&args.output).ok(), threads)?;
    let loading = start.elapsed();
    // Ctrl+C, SIGTERM and SIGHUP stop the render, or the write; no file is
    // written and an existing one is untouched.
    let cancel = CancelToken::new();
    super::safety::handle_signals(&cancel);

    // One pool of worker threads renders and then encodes the image.
    let options = RenderOptions {
        threads: None,
        progressive: args.progressive,
        ..RenderOptions::default()
    };
    let whole = TileRect::whole(&scene.camera);
    let bar = std::io::stderr().is_terminal().then(|| {
        let area = args.region.unwrap_or(whole);
        let tiles = crate::render::progressive::tiles_of(area, options.tile_size).len();
        let bar = ProgressBar::new(tiles as u64);
        bar.set_style(
            ProgressStyle::with_template("{spinner} {msg} [{bar:40}] {pos}/{len} tiles, {elapsed}")
                .expect("valid template")
                .progress_chars("=> "),
        );
        bar
    });
    // A whole image's PNG codes are encoded as its final pass's tiles finish.
    let png = (args.region.is_none() && FileKind::of(&args.output).ok() == Some(FileKind::Png))
        .then(|| PngCodes::new(whole.w, whole.h));
    let on_tile = |t: &TileUpdate| {
        if let Some(png) = &png
            && t.pass_index + 1 == t.pass_count
        {
            png.put(t.rect, t.pixels);
        }
        if let Some(bar) = &bar {
            if t.tiles_done == 1 {
                bar.set_position(0);
                bar.set_message(format!("pass {}/{}", t.pass_index + 1, t.pass_count));
            }
            bar.inc(1);
        }
    };
    let (report, writing, threads) = on_threads(threads, || {
        let report = match args.region {
            Some(region) => loaded.render_region(region, &options, &cancel, &on_tile),
            None => loaded.render(&options, &cancel, &on_tile),
        };
        if let Some(bar) = &bar {
            bar.finish_and_clear();
        }
        let report = report.map_err(|_| CliError::other(INTERRUPTED))?;
        if cancel.is_cancelled() {
            return Err(CliError::other(INTERRUPTED));
        }
        let writing = Instant::now();
        let written = match args.region {
            Some(region) => {
                let part = Part {
                    region,
                    full: (whole.w, whole.h),
                    scene: fingerprint(&desc, &loaded.settings),
                    version: env!("CARGO_PKG_VERSION").to_string(),
                    film: report.film.clone(),
                };
                write_part(&part, &args.output)
            }
            None => match &png {
                Some(png) => png.write(&report.film, &args.output),
                None => write_film(&report.film, &args.output),
            },
        };
        written.map_err(|e| super::safety::write_failure(e, INTERRUPTED))?;
        Ok((report, writing.elapsed(), rayon::current_num_threads()))
    })
    .ok_or_else(|| CliError::other("cannot start the worker threads"))??;
    let times = Times {
        total: start.elapsed(),
        loading,
        rendering: report.elapsed,
        writing,
    };
    let line = summary(&scene, &report.stats, threads, &times);
    match args.region {
        Some(r) => super::print_stderr(format_args!(
            "region {},{},{},{} of {line}",
            r.x, r.y, r.w, r.h
        )),
        None => super::print_stderr(line),
    }
    if let Some(path) = &args.stats {
        let json = stats_json(args, &scene, &report.stats, threads, &times);
        write_stats(path, &json)?;
    }
    Ok(())
}

/// Refuses (exit 2) an image too large for the memory the process may
/// take: its film (12 bytes a pixel), the output's encoding buffer (an
/// EXR's 12, a PNG's 3) and the worker threads that render it (`threads`,
/// or rayon's default).
fn check_memory(
    area: TileRect,
    output: Option<FileKind>,
    threads: Option<usize>,
) -> Result<(), CliError> {
    let per_pixel = if output == Some(FileKind::Png) {
        15
    } else {
        24
    };
    let threads = threads.unwrap_or_else(rayon::current_num_threads);
    crate::render::memory::check_render_memory(area.w, area.h, per_pixel, threads)
        .map_err(CliError::input)
}

/// Writes the `--stats` JSON: to standard output for `-`, else as the
/// images are written.
fn write_stats(path: &Path, json: &serde_json::Value) -> Result<(), CliError> {
    let text = serde_json::to_string_pretty(json).map_err(CliError::other)? + "\n";
    if path.as_os_str() == "-" {
        let mut out = std::io::stdout().lock();
        return out
            .write_all(text.as_bytes())
            .and_then(|()| out.flush())
            .map_err(|e| CliError::other(format!("--stats: standard output: {e}")));
    }
    write_atomic(path, |w| {
        w.write_all(text.as_bytes()).map_err(|e| e.to_string())
    })
    .map_err(|e| CliError::other(format!("--stats: {e}")))
}

/// Refuses (exit 2), before rendering, a `--stats` file that cannot be
/// written (a folder, or in a folder that is not there), or that is the
/// image being written or the scene being read.
fn check_stats_path(stats: &Path, args: &RenderArgs) -> Result<(), CliError> {
    if stats.as_os_str() == "-" {
        return Ok(());
    }
    super::safety::refuse_missing_folder(stats, "--stats file")?;
    super::safety::refuse_read_only(stats, "--stats file")?;
    let absolute = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_owned());
    if absolute(stats) == absolute(&args.output) || super::safety::same_file(stats, &args.output) {
        return Err(CliError::input(format!(
            "{}: --stats: names the output image too: give it a file of its own",
            stats.display()
        )));
    }
    match &args.scene {
        Some(scene) => {
            super::safety::refuse_overwriting_inputs(stats, "--stats file", &[("scene", scene)])
        }
        None => Ok(()),
    }
}

/// Wall times of one `penumbra render`: in all, reading and building the
/// scene, rendering, and writing the image (the rest is starting the
/// worker threads and the film's memory).
struct Times {
    total: Duration,
    loading: Duration,
    rendering: Duration,
    writing: Duration,
}

/// What `--stats` writes: the summary line's figures, and every count of
/// [`RayStats`](crate::render::RayStats) by name.
fn stats_json(
    args: &RenderArgs,
    scene: &Scene,
    s: &crate::render::RayStats,
    threads: usize,
    t: &Times,
) -> serde_json::Value {
    let rendering = t.rendering.as_secs_f64();
    let per_second = |rays: u64| {
        if rendering > 0.0 {
            rays as f64 / rendering
        } else {
            0.0
        }
    };
    serde_json::json!({
        "scene": args.scene.as_ref().map(|p| p.display().to_string()),
        "output": args.output.display().to_string(),
        "width": scene.camera.width,
        "height": scene.camera.height,
        "region": args.region.map(|r| [r.x, r.y, r.w, r.h]),
        "threads": threads,
        "skipping": !args.no_skip,
        "seconds": {
            "total": t.total.as_secs_f64(),
            "loading": t.loading.as_secs_f64(),
            "rendering": rendering,
            "writing": t.writing.as_secs_f64(),
        },
        "rays": {
            "camera": s.camera,
            "reflected": s.reflected,
            "shadow": s.shadow,
            "shadow_backfacing": s.shadow_backfacing,
            "shadow_unoccluded": s.shadow_unoccluded,
            "shadow_umbra": s.shadow_umbra,
            "shadow_disabled": s.shadow_disabled,
            "shadow_unneeded": s.shadow_unneeded,
            "shadow_adaptive": s.shadow_adaptive,
            "shadow_skipped": s.shadow_skipped(),
            "traced": s.traced(),
            "effective": s.effective(),
        },
        "rays_per_second": {
            "traced": per_second(s.traced()),
            "effective": per_second(s.effective()),
        },
        "exact": {
            "hits": s.exact_hits,
            "fallbacks": s.exact_fallbacks,
        },
    })
}

/// One line: size, rendering time, rays by kind, Mray/s, then the whole
/// command's time with its loading and writing. It begins as it always
/// has, `W×H in R s: C camera, S shadow, F reflected rays traced; K shadow
/// rays answered without tracing; M Mray/s traced`, with R the rendering
/// alone: scripts that compare penumbra with other renderers read that
/// part (see `tests/cli.rs`, `summary_line_keeps_the_form_scripts_read`).
fn summary(scene: &Scene, s: &crate::render::RayStats, threads: usize, t: &Times) -> String {
    let secs = t.rendering.as_secs_f64();
    let exact = if s.exact_hits + s.exact_fallbacks > 0 {
        format!(
            "; exact model: {} hit points exact, {} fell back to the analytic estimate",
            s.exact_hits, s.exact_fallbacks
        )
    } else {
        String::new()
    };
    format!(
        "{}×{} in {:.3} s: {} camera, {} shadow, {} reflected rays traced; {} shadow rays answered without tracing; {:.1} Mray/s traced ({:.1} Mray/s with skipped) on {} threads{exact}; {:.3} s in all with {:.3} s loading and {:.3} s writing",
        scene.camera.width,
        scene.camera.height,
        secs,
        s.camera,
        s.shadow,
        s.reflected,
        s.shadow_skipped(),
        s.traced() as f64 / secs / 1e6,
        s.effective() as f64 / secs / 1e6,
        threads,
        t.total.as_secs_f64(),
        t.loading.as_secs_f64(),
        t.writing.as_secs_f64(),
    )
}
