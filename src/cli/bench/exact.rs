//! `--exact`: the targets of the `exact` area-light model, measured.
//!
//! - accuracy: RMSE of the exact image against a 65 536-ray stratified
//!   `sampled` reference. The format allows at most 4096 shadow rays per
//!   hit, so that reference is the mean of 16 renders of 4096 stratified
//!   rays under 16 seeds (independent jitter in each 64×64 grid cell: 16
//!   points per cell, 65 536 per hit point), cached like the other
//!   references; the RMSE of one 4096-ray render against it is printed as
//!   the noise scale. The error image (false colour, white = the printed
//!   scale) is written beside the CSVs to look for noise or bands;
//! - cost: the exact render and 64 grid rays of `sampled`, timed in one
//!   interleaved loop (median of `--runs`, at least 5);
//! - what fell back to the `analytic` estimate (hits counted).

use std::path::{Path, PathBuf};

use super::reference::{REFERENCE_RAYS, cached_film, reference_key};
use super::{BenchArgs, BenchScene, CliError, build, median, render_once, scenes};
use crate::render::compare::{compare, diff_image};
use crate::render::output::{write_film, write_rgb8};
use crate::render::{
    AreaLightModel, Film, REFERENCE_SEED, Sampling, SceneDesc, reference_desc, reference_scene,
};

/// Renders of 4096 stratified rays averaged into the 65 536-ray reference.
pub const REFERENCE_RENDERS: u32 = 16;

/// The mean of `renders` stratified `sampled` renders of `rays` rays each,
/// seeds REFERENCE_SEED + k, cached under the cache directory.
pub fn averaged_reference(
    desc: &SceneDesc,
    renders: u32,
    cache: &Path,
    fresh: bool,
) -> Result<Film, CliError> {
    let key = reference_key(desc, AreaLightModel::Sampled, REFERENCE_RAYS);
    let path = cache.join(format!("ref-mean{renders}-sampled-{key}.exr"));
    let (w, h) = (desc.camera.width, desc.camera.height);
    if !fresh && let Some(film) = cached_film(&path, (w, h))? {
        outln!("65 536-ray reference: cached {}", path.display());
        return Ok(film);
    }
    let mut sum = vec![glam::DVec3::ZERO; (w * h) as usize];
    for k in 0..renders {
        let mut d = reference_desc(desc, AreaLightModel::Sampled, REFERENCE_RAYS);
        d.render.seed = REFERENCE_SEED.wrapping_add(k as u64);
        let report = render_once(&reference_scene(&d, desc).map_err(CliError::input)?);
        for (s, p) in sum.iter_mut().zip(&report.film.pixels) {
            *s += p.as_dvec3();
        }
        outln!(
            "  reference render {}/{renders}: {:.1} s",
            k + 1,
            report.elapsed.as_secs_f64()
        );
    }
    let mut film = Film::new(w, h);
    for (p, s) in film.pixels.iter_mut().zip(&sum) {
        *p = (*s / renders as f64).as_vec3();
    }
    std::fs::create_dir_all(cache)
        .map_err(|e| CliError::other(format!("{}: {e}", cache.display())))?;
    write_film(&film, &path).map_err(CliError::other)?;
    outln!("65 536-ray reference: stored {}", path.display());
    Ok(film)
}

pub fn run(args: &BenchArgs) -> Result<(), CliError> {
    let scenes = scenes(args)?;
    // The error images are written after minutes of renders: each refused
    // first if it would overwrite its scene or a mesh, or is read-only.
    let error_image = |scene: &BenchScene| args.out.join(format!("exact-error-{}.png", scene.name));
    for scene in &scenes {
        super::refuse_overwriting_scene(args, scene, &error_image(scene), "error image")?;
        crate::cli::safety::refuse_read_only(&error_image(scene), "error image")?;
    }
    // Each scene of `--spheres N,M,…` in turn.
    for scene in &scenes {
        run_scene(args, scene, error_image(scene))?;
    }
    Ok(())
}

/// The exact model's time and error on `scene`, its error image written
/// to `error_image`.
fn run_scene(args: &BenchArgs, scene: &BenchScene, error_image: PathBuf) -> Result<(), CliError> {
    let runs = args.runs.unwrap_or(5).max(5);
    let d = &scene.desc;
    outln!(
        "exact model on {}: {}×{}, depth {}, {} threads, median of {runs} interleaved runs",
        scene.name,
        d.camera.width,
        d.camera.height,
        d.render.max_depth,
        rayon::current_num_threads()
    );
    let mut exact = d.clone();
    exact.render.area_light_model = AreaLightModel::Exact;
    let mut grid = d.clone();
    grid.render.area_light_model = AreaLightModel::Sampled;
    grid.render.sampling = Sampling::Grid;
    grid.render.shadow_rays = 64;
    let (exact_scene, grid_scene) = (build(&exact, true)?, build(&grid, true)?);
    let (mut te, mut tg) = (Vec::new(), Vec::new());
    let (mut exact_report, mut grid_report) = (None, None);
    for _ in 0..runs {
        let r = render_once(&exact_scene);
        te.push(r.elapsed);
        exact_report.get_or_insert(r);
        let r = render_once(&grid_scene);
        tg.push(r.elapsed);
        grid_report.get_or_insert(r);
    }
    te.sort();
    tg.sort();
    let (exact_report, grid_report) = (exact_report.expect("runs"), grid_report.expect("runs"));
    let (me, mg) = (median(&te).as_secs_f64(), median(&tg).as_secs_f64());
    let s = &exact_report.final_stats;
    outln!(
        "time: exact {:.1} ms, sampled 64 grid {:.1} ms (exact / grid {:.2}×; goal ≤ 1×)",
        me * 1e3,
        mg * 1e3,
        me / mg
    );
    outln!(
        "exact hit points: {} exact, {} fell back to the analytic estimate",
        s.exact_hits,
        s.exact_fallbacks
    );

    let reference = averaged_reference(d, REFERENCE_RENDERS, &args.cache, args.fresh_reference)?;
    let rmse = |f: &Film| {
        compare(f, &reference)
            .map(|c| c.rmse)
            .map_err(CliError::other)
    };
    let e_exact = rmse(&exact_report.film)?;
    let e_grid = rmse(&grid_report.film)?;
    let one_desc = reference_desc(d, AreaLightModel::Sampled, REFERENCE_RAYS);
    let one = render_once(&reference_scene(&one_desc, d).map_err(CliError::input)?);
    let e_one = rmse(&one.film)?;
    outln!(
        "RMSE against the 65 536-ray stratified reference: exact {e_exact:.3e} (goal ≤ 1e-4), \
         sampled 64 grid {e_grid:.3e}, one 4096-ray stratified render {e_one:.3e} \
         (the reference's own noise is about a quarter of that)"
    );
    std::fs::create_dir_all(&args.out)
        .map_err(|e| CliError::other(format!("{}: {e}", args.out.display())))?;
    let path = error_image;
    let scale = 5e-4;
    let (rgb, _) =
        diff_image(&exact_report.film, &reference, Some(scale)).map_err(CliError::other)?;
    write_rgb8(&path, d.camera.width, d.camera.height, &rgb).map_err(CliError::other)?;
    outln!("error image (white = {scale:e}): {}", path.display());
    Ok(())
}
