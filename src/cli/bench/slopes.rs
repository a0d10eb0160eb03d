//! `penumbra bench --slopes`: how fast each pattern's error falls with the
//! shadow-ray count inside penumbrae, where visibility is partial — the
//! fitted slope of log RMSE against log rays (Mitchell 1996: −0.5 for
//! random points, down to −0.75 for stratified ones across visibility
//! edges).
//!
//! Only the diffuse term of camera-ray hits is rendered (depth 1, terms
//! 0,1,0), so the error is the visibility integral's. The penumbra mask
//! holds the pixels whose first hit sees between 2 % and 98 % of the light
//! (1024 grid points); the reference uses 16384 stratified rays per hit.

use super::{BenchArgs, scenes};
use crate::cli::CliError;
use crate::render::compare::rmse_masked;
use crate::render::rng::Rng;
use crate::render::sampling::Pattern;
use crate::render::scene::HitTarget;
use crate::render::scene_file::limits::MAX_SIDE;
use crate::render::shadow::{ShadowBuffers, ShadowQuery, visibility};
use crate::render::{Film, Loaded, RayStats, Sampling, SceneDesc};

/// Shadow-ray counts of the fit.
const COUNTS: [u32; 5] = [4, 16, 64, 256, 1024];
const PATTERNS: [Sampling; 5] = [
    Sampling::Random,
    Sampling::Grid,
    Sampling::Stratified,
    Sampling::Sobol,
    Sampling::RotatedGrid,
];
/// Stratified rays per hit of the reference (beyond the format's 4096,
/// which only bounds scene files).
const REFERENCE_RAYS: u32 = 16384;

pub fn run(args: &BenchArgs) -> Result<(), CliError> {
    for bench_scene in scenes(args)? {
        let mut desc = bench_scene.desc;
        desc.render.max_depth = 1;
        desc.render.terms.ambient = 0.0;
        desc.render.terms.specular = 0.0;
        desc.render.adaptive = false;
        let with = |sampling: Sampling, rays: u32| -> Result<Loaded, CliError> {
            let mut d = desc.clone();
            d.render.sampling = sampling;
            d.render.shadow_rays = rays.min(4096);
            let mut loaded = Loaded::new(&d).map_err(CliError::input)?;
            // Past the format's limit: the reference is a render setting,
            // not a scene.
            loaded.settings.shadow_rays = rays;
            Ok(loaded)
        };
        let mask = penumbra_mask(&with(Sampling::Grid, 1024)?);
        let in_mask = mask.iter().filter(|&&m| m).count();
        let (width, height) = (desc.camera.width, desc.camera.height);
        if in_mask == 0 {
            // An RMSE over no pixels is 0 and its slope NaN: refused, with
            // a larger width that has some.
            let larger = match larger_size_with_penumbrae(&desc)? {
                // Every width to 16 is tried: the first found is the smallest.
                Some((w, h, n)) if w <= 16 => {
                    format!("the smallest width with some is --width {w} ({n} at {w}×{h})")
                }
                Some((w, h, n)) => format!("--width {w} has some ({n} at {w}×{h})"),
                None => format!("nor at any size up to {LARGEST_TRIED} pixels wide"),
            };
            return Err(CliError::input(format!(
                "{}: --slopes: no penumbra pixels at {width}×{height} (none whose first hit sees part of the light), \
                 so no error to fit; {larger}",
                bench_scene.name
            )));
        }
        let reference = with(Sampling::Stratified, REFERENCE_RAYS)?.render_image();
        outln!(
            "{}: {}×{}, {in_mask} penumbra pixels; RMSE of the diffuse term in penumbrae against {REFERENCE_RAYS} stratified rays",
            bench_scene.name,
            desc.camera.width,
            desc.camera.height
        );
        out!("{:>14}", "rays");
        for c in COUNTS {
            out!("{c:>11}");
        }
        outln!("{:>9}", "slope");
        for pattern in PATTERNS {
            let mut errors = Vec::new();
            for rays in COUNTS {
                let film: Film = with(pattern, rays)?.render_image();
                errors.push(rmse_masked(&film, &reference, &mask).map_err(CliError::other)?);
            }
            out!("{:>14}", pattern.name());
            for e in &errors {
                out!("{e:>11.3e}");
            }
            match fitted_slope(&COUNTS.map(f64::from), &errors) {
                Some(slope) => outln!("{slope:>9.2}"),
                None => outln!("{:>9}", "-"),
            }
        }
    }
    Ok(())
}

/// Widest image [`larger_size_with_penumbrae`] tries.
const LARGEST_TRIED: u32 = 256;

/// The first larger size at the scene's aspect ratio whose image has
/// penumbra pixels (every width up to 16, then 32, 64, … up to
/// [`LARGEST_TRIED`]), and how many: for the message of a size that has
/// none. Small images cost little to try.
fn larger_size_with_penumbrae(desc: &SceneDesc) -> Result<Option<(u32, u32, usize)>, CliError> {
    let c = &desc.camera;
    let aspect = c.height as f64 / c.width as f64;
    let widths = (c.width + 1..=16).chain(
        [32, 64, 128, LARGEST_TRIED]
            .into_iter()
            .filter(|&w| w > c.width),
    );
    for width in widths {
        let mut d = desc.clone();
        d.camera.width = width;
        d.camera.height = ((width as f64 * aspect).round() as u32).clamp(1, MAX_SIDE);
        d.render.sampling = Sampling::Grid;
        d.render.shadow_rays = 1024;
        let loaded = Loaded::new(&d).map_err(CliError::input)?;
        let count = penumbra_mask(&loaded).iter().filter(|&&m| m).count();
        if count > 0 {
            return Ok(Some((width, d.camera.height, count)));
        }
    }
    Ok(None)
}

/// Pixels whose camera-ray hit sees part, not all or none, of the light.
fn penumbra_mask(loaded: &Loaded) -> Vec<bool> {
    let scene = &loaded.scene;
    let pattern = Pattern::new(Sampling::Grid, 1024);
    let mut buf = ShadowBuffers::with_capacity(pattern.count());
    pattern.fill(&mut Rng::new(0), &mut buf.a, &mut buf.b);
    let mut stats = RayStats::default();
    let (w, h) = (scene.camera.width, scene.camera.height);
    let mut mask = Vec::with_capacity((w * h) as usize);
    for y in 0..h {
        for x in 0..w {
            let ray = scene.camera.pixel_ray(x, y);
            let partial = match scene.closest_hit(&ray) {
                Some((HitTarget::Object(object), t)) if scene.light.illuminates(ray.at(t)) => {
                    let surface = scene.surface(object, &ray, t);
                    let inside = surface.normal.dot(ray.dir) > 0.0;
                    let query = ShadowQuery {
                        point: surface.point,
                        normal: if inside {
                            -surface.normal
                        } else {
                            surface.normal
                        },
                        object,
                        inside,
                    };
                    visibility(
                        scene,
                        &loaded.settings,
                        &query,
                        pattern.count(),
                        &mut buf,
                        &mut stats,
                    );
                    let seen =
                        buf.vis[..pattern.count()].iter().sum::<f32>() / pattern.count() as f32;
                    seen > 0.02 && seen < 0.98
                }
                _ => false,
            };
            mask.push(partial);
        }
    }
    mask
}

/// Least-squares slope of log(error) against log(rays), over the errors
/// above 0; none where fewer than two are (no line to fit).
pub fn fitted_slope(rays: &[f64], errors: &[f64]) -> Option<f64> {
    let points: Vec<(f64, f64)> = rays
        .iter()
        .zip(errors)
        .filter(|(_, e)| **e > 0.0)
        .map(|(r, e)| (r.ln(), e.ln()))
        .collect();
    if points.len() < 2 {
        return None;
    }
    let n = points.len() as f64;
    let (mx, my) = points
        .iter()
        .fold((0.0, 0.0), |(a, b), p| (a + p.0 / n, b + p.1 / n));
    let (sxy, sxx) = points.iter().fold((0.0, 0.0), |(a, b), p| {
        (a + (p.0 - mx) * (p.1 - my), b + (p.0 - mx) * (p.0 - mx))
    });
    Some(sxy / sxx)
}

#[cfg(test)]
mod tests {
    use super::fitted_slope;

    #[test]
    fn slope_of_a_power_law() {
        let rays = [4.0, 16.0, 64.0, 256.0];
        let errors = rays.map(|r: f64| 3.0 * r.powf(-0.75));
        assert!((fitted_slope(&rays, &errors).unwrap() + 0.75).abs() < 1e-12);
    }

    /// Errors of 0 (no pixels, or exact images) leave no line: the slope
    /// was NaN.
    #[test]
    fn no_slope_without_two_errors_above_zero() {
        let rays = [4.0, 16.0, 64.0, 256.0];
        assert_eq!(fitted_slope(&rays, &[0.0; 4]), None);
        assert_eq!(fitted_slope(&rays, &[0.1, 0.0, 0.0, 0.0]), None);
        assert!(fitted_slope(&rays, &[0.1, 0.05, 0.0, 0.0]).is_some());
    }
}
