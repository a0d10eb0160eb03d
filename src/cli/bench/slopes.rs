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
use crate::render::shadow::{ShadowBuffers, ShadowQuery, visibility};
use crate::render::{Film, Loaded, RayStats, Sampling};

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
        let reference = with(Sampling::Stratified, REFERENCE_RAYS)?.render_image();
        let mask = penumbra_mask(&with(Sampling::Grid, 1024)?);
        let in_mask = mask.iter().filter(|&&m| m).count();
        println!(
            "{}: {}×{}, {in_mask} penumbra pixels; RMSE of the diffuse term in penumbrae against {REFERENCE_RAYS} stratified rays",
            bench_scene.name, desc.camera.width, desc.camera.height
        );
        print!("{:>14}", "rays");
        for c in COUNTS {
            print!("{c:>11}");
        }
        println!("{:>9}", "slope");
        for pattern in PATTERNS {
            let mut errors = Vec::new();
            for rays in COUNTS {
                let film: Film = with(pattern, rays)?.render_image();
                errors.push(rmse_masked(&film, &reference, &mask).map_err(CliError::other)?);
            }
            print!("{:>14}", pattern.name());
            for e in &errors {
                print!("{e:>11.3e}");
            }
            println!("{:>9.2}", fitted_slope(&COUNTS.map(f64::from), &errors));
        }
    }
    Ok(())
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

/// Least-squares slope of log(error) against log(rays).
pub fn fitted_slope(rays: &[f64], errors: &[f64]) -> f64 {
    let points: Vec<(f64, f64)> = rays
        .iter()
        .zip(errors)
        .filter(|(_, e)| **e > 0.0)
        .map(|(r, e)| (r.ln(), e.ln()))
        .collect();
    let n = points.len() as f64;
    let (mx, my) = points
        .iter()
        .fold((0.0, 0.0), |(a, b), p| (a + p.0 / n, b + p.1 / n));
    let (sxy, sxx) = points.iter().fold((0.0, 0.0), |(a, b), p| {
        (a + (p.0 - mx) * (p.1 - my), b + (p.0 - mx) * (p.0 - mx))
    });
    sxy / sxx
}

#[cfg(test)]
mod tests {
    use super::fitted_slope;

    #[test]
    fn slope_of_a_power_law() {
        let rays = [4.0, 16.0, 64.0, 256.0];
        let errors = rays.map(|r: f64| 3.0 * r.powf(-0.75));
        assert!((fitted_slope(&rays, &errors) + 0.75).abs() < 1e-12);
    }
}
