use std::io::IsTerminal;
use std::path::Path;

use indicatif::{ProgressBar, ProgressStyle};

use super::{CliError, RenderArgs, SceneOverrides};
use crate::render::output::{FileKind, write_film};
use crate::render::{
    CancelToken, Loaded, RenderOptions, RenderReport, Scene, SceneDesc, TileUpdate,
};

/// Loads and builds a scene (the built-in seed room for `None`) with
/// overrides.
pub fn load_scene(path: Option<&Path>, overrides: &SceneOverrides) -> Result<Loaded, CliError> {
    let desc = load_desc(path, overrides)?;
    let loaded = Loaded::new(&desc);
    match path {
        Some(p) => loaded.map_err(|e| CliError::input(e.in_file(p))),
        None => loaded.map_err(CliError::input),
    }
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
    if let Some(w) = o.width {
        desc.camera.width = w;
    }
    if let Some(h) = o.height {
        desc.camera.height = h;
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

/// `penumbra render`.
pub fn render(args: &RenderArgs) -> Result<(), CliError> {
    FileKind::of(&args.output).map_err(CliError::input)?;
    let mut loaded = load_scene(args.scene.as_deref(), &args.overrides)?;
    loaded.settings.skip = !args.no_skip;
    let scene = loaded.scene.clone();

    let cancel = CancelToken::new();
    {
        let cancel = cancel.clone();
        // Ctrl+C stops the render; no file is written. (Fails only if a
        // handler is already set, as in tests running several renders.)
        let _ = ctrlc::set_handler(move || cancel.cancel());
    }
    let options = RenderOptions {
        threads: args.threads.map(|n| n as usize),
        progressive: args.progressive,
        ..RenderOptions::default()
    };
    let bar = std::io::stderr().is_terminal().then(|| {
        let tiles = crate::render::progressive::tiles(
            scene.camera.width,
            scene.camera.height,
            options.tile_size,
        )
        .len();
        let bar = ProgressBar::new(tiles as u64);
        bar.set_style(
            ProgressStyle::with_template("{spinner} {msg} [{bar:40}] {pos}/{len} tiles, {elapsed}")
                .expect("valid template")
                .progress_chars("=> "),
        );
        bar
    });
    let on_tile = |t: &TileUpdate| {
        if let Some(bar) = &bar {
            if t.tiles_done == 1 {
                bar.set_position(0);
                bar.set_message(format!("pass {}/{}", t.pass_index + 1, t.pass_count));
            }
            bar.inc(1);
        }
    };
    let report = loaded.render(&options, &cancel, &on_tile);
    if let Some(bar) = &bar {
        bar.finish_and_clear();
    }
    let report = report.map_err(|_| CliError::other("interrupted: no image written"))?;
    if cancel.is_cancelled() {
        return Err(CliError::other("interrupted: no image written"));
    }
    write_film(&report.film, &args.output).map_err(CliError::other)?;
    eprintln!("{}", summary(&scene, &report, options.threads));
    Ok(())
}

/// One line: size, wall time, rays by kind, Mray/s.
pub fn summary(scene: &Scene, report: &RenderReport, threads: Option<usize>) -> String {
    let s = &report.stats;
    let secs = report.elapsed.as_secs_f64();
    let threads = threads.unwrap_or_else(rayon::current_num_threads);
    format!(
        "{}×{} in {:.3} s: {} camera, {} shadow, {} reflected rays traced; {} shadow rays answered without tracing; {:.1} Mray/s traced ({:.1} Mray/s with skipped) on {} threads",
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
    )
}
