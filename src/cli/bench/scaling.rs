//! `--spheres N,… --scaling`: how render time grows with object count.

use std::time::Instant;

use super::{BenchArgs, CliError, build, scenes, si, timed};
use crate::render::generate::{self, Layout, VOLUME_FRACTION};

/// One scene size's measurement.
#[derive(Debug, Clone, Copy)]
pub struct ScalingRow {
    pub spheres: u32,
    pub radius: f64,
    pub build_s: f64,
    pub time_s: f64,
    /// Median CPU seconds of all threads (NaN if unknown).
    pub cpu_s: f64,
    pub rays_traced: u64,
    /// Median wall time with shadow rays switched off: camera and mirror
    /// rays only, the closest-hit work of the BVH.
    pub no_shadow_s: f64,
}

/// Mean distance a ray travels between spheres of radius `r` filling
/// [`VOLUME_FRACTION`] of the room: 4r / 3φ (none for the floor layout).
fn free_path(layout: Layout, r: f64) -> Option<f64> {
    (layout == Layout::Volume).then(|| 4.0 * r / (3.0 * VOLUME_FRACTION))
}

pub fn run(args: &BenchArgs) -> Result<(), CliError> {
    let Some(counts) = &args.spheres else {
        return Err(CliError::input(
            "--scaling needs --spheres, e.g. --spheres 10,100,1000,10000",
        ));
    };
    let runs = args.runs.unwrap_or(if args.quick { 1 } else { 5 });
    let scenes = scenes(args)?;
    let layout = Layout::from(args.layout);
    if let Some(s) = scenes.first() {
        let r = &s.desc.render;
        outln!(
            "generated rooms ({:?} layout, sphere seed {}): {}×{}, {} {} shadow rays, depth {}, {}; median of {runs} runs",
            layout,
            args.sphere_seed,
            s.desc.camera.width,
            s.desc.camera.height,
            r.shadow_rays,
            r.sampling.name(),
            r.max_depth,
            r.area_light_model.name()
        );
    }
    outln!(
        "{:>8} {:>8} {:>9} {:>9} {:>10} {:>9} {:>9} {:>7} {:>10} {:>9} {:>9} {:>12}",
        "spheres",
        "radius",
        "free path",
        "build ms",
        "render ms",
        "cpu ms",
        "traced",
        "Mray/s",
        "cpu ns/ray",
        "vs first",
        "cpu vs first",
        "no-shadow ms"
    );
    let mut rows: Vec<ScalingRow> = Vec::new();
    for (scene, &n) in scenes.iter().zip(counts) {
        let start = Instant::now();
        let built = build(&scene.desc, true)?;
        let build_s = start.elapsed().as_secs_f64();
        let t = timed(&built, runs);
        let mut dark = built.clone();
        dark.settings.shadows = false;
        let no_shadow = timed(&dark, runs);
        let row = ScalingRow {
            spheres: n,
            radius: generate::radius(layout, n as usize),
            build_s,
            time_s: t.median().as_secs_f64(),
            cpu_s: t.median_cpu().map_or(f64::NAN, |c| c.as_secs_f64()),
            rays_traced: t.report.final_stats.traced(),
            no_shadow_s: no_shadow.median().as_secs_f64(),
        };
        let first = rows.first().copied().unwrap_or(row);
        outln!(
            "{:>8} {:>8.4} {:>9} {:>9.2} {:>10.2} {:>9.2} {:>9} {:>7.1} {:>10.1} {:>8.2}× {:>8.2}× {:>12.2}",
            row.spheres,
            row.radius,
            free_path(layout, row.radius).map_or("-".into(), |f| format!("{f:.2}")),
            row.build_s * 1e3,
            row.time_s * 1e3,
            row.cpu_s * 1e3,
            si(row.rays_traced),
            row.rays_traced as f64 / row.time_s / 1e6,
            row.cpu_s * 1e9 / row.rays_traced.max(1) as f64,
            row.time_s / first.time_s,
            row.cpu_s / first.cpu_s,
            row.no_shadow_s * 1e3
        );
        rows.push(row);
    }
    let lo = rows.iter().min_by_key(|r| r.spheres);
    let hi = rows.iter().max_by_key(|r| r.spheres);
    if let (Some(lo), Some(hi)) = (lo, hi)
        && lo.spheres != hi.spheres
    {
        outln!(
            "time ratio N={} / N={}: {:.2} wall, {:.2} CPU (target ≤ 4 for 10000 / 10)",
            hi.spheres,
            lo.spheres,
            hi.time_s / lo.time_s,
            hi.cpu_s / lo.cpu_s
        );
        outln!(
            "without shadow rays (camera and mirror rays: the BVH's closest hits): {:.2} wall",
            hi.no_shadow_s / lo.no_shadow_s
        );
        if layout == Layout::Volume {
            outln!(
                "(the spheres fill {:.0} % of the room at every N, so a ray's free path shrinks as N^(-1/3): \
                 a shadow ray that reaches the light passes ever more spheres on the way; \
                 --layout floor keeps what a shadow ray crosses constant)",
                VOLUME_FRACTION * 100.0
            );
        }
    }
    Ok(())
}
