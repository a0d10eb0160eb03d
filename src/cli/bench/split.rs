//! `penumbra bench --spp-split`: how to spend a pixel's shadow rays. A
//! pixel pays `samples_per_pixel × shadow_rays`; for each budget the
//! splits from one camera sample with all the rays to one ray per sample
//! are timed and compared with a converged anti-aliased reference (64
//! samples per pixel × 256 stratified shadow rays), so edges and penumbrae
//! both count.

use super::{BenchArgs, CliError, reference, scenes, timed};
use crate::render::compare::compare;
use crate::render::{Loaded, Sampling};

/// Shadow rays per pixel to share between camera samples and shadow rays.
const BUDGETS: [u32; 3] = [16, 64, 256];
/// The reference's camera samples and shadow rays per sample.
const REFERENCE_SPP: u32 = 64;
const REFERENCE_RAYS: u32 = 256;

pub fn run(args: &BenchArgs) -> Result<(), CliError> {
    let runs = args.runs.unwrap_or(3);
    for scene in scenes(args)? {
        let desc = scene.desc;
        let model = desc.render.area_light_model;
        let mut rdesc = desc.clone();
        rdesc.render.samples_per_pixel = REFERENCE_SPP;
        // The reference converges the anti-aliasing too: its camera
        // samples scrambled apart from the splits' (a shared scramble
        // would put a split's samples on the reference's first ones).
        rdesc.render.seed = crate::render::REFERENCE_SEED;
        let reference = reference(
            &rdesc,
            model,
            REFERENCE_RAYS,
            &args.cache,
            args.fresh_reference,
        )?;
        outln!(
            "{}: {}×{}, {} sampling, {} model, depth {}; reference {REFERENCE_SPP} spp × {REFERENCE_RAYS} stratified rays ({})",
            scene.name,
            desc.camera.width,
            desc.camera.height,
            desc.render.sampling.name(),
            model.name(),
            desc.render.max_depth,
            if reference.cached {
                "cached"
            } else {
                "rendered"
            },
        );
        outln!(
            "{:>12} {:>7} {:>12} {:>10} {:>10} {:>11} {:>9} {:>12}",
            "sampling",
            "budget",
            "spp × rays",
            "wall ms",
            "cpu ms",
            "rmse",
            "psnr dB",
            "rmse² × cpu s"
        );
        // The scene's pattern, and stratified: a fixed pattern (the grid)
        // gives every camera sample the same light points, so only a
        // pattern drawn per sample gains from more samples.
        let mut patterns = vec![desc.render.sampling];
        if desc.render.sampling != Sampling::Stratified {
            patterns.push(Sampling::Stratified);
        }
        for sampling in patterns {
            for budget in BUDGETS {
                let mut best: Option<(f64, String)> = None;
                let mut efficient: Option<(f64, String)> = None;
                let mut spp = 1;
                while spp <= budget {
                    let rays = budget / spp;
                    let mut d = desc.clone();
                    d.render.samples_per_pixel = spp;
                    d.render.shadow_rays = rays;
                    d.render.sampling = sampling;
                    let loaded = Loaded::new(&d).map_err(CliError::input)?;
                    let t = timed(&loaded, runs);
                    let c = compare(&t.report.film, &reference.film).map_err(CliError::other)?;
                    let cpu = t.median_cpu().map_or(t.median(), |c| c).as_secs_f64();
                    let cost = c.rmse * c.rmse * cpu;
                    let split = format!("{spp} × {rays}");
                    outln!(
                        "{:>12} {budget:>7} {split:>12} {:>10.1} {:>10.1} {:>11.3e} {:>9.2} {cost:>12.3e}",
                        sampling.name(),
                        t.median().as_secs_f64() * 1e3,
                        cpu * 1e3,
                        c.rmse,
                        c.psnr,
                    );
                    if best.as_ref().is_none_or(|(e, _)| c.rmse < *e) {
                        best = Some((c.rmse, split.clone()));
                    }
                    if efficient.as_ref().is_none_or(|(e, _)| cost < *e) {
                        efficient = Some((cost, split));
                    }
                    spp *= 4;
                }
                if let (Some((e, b)), Some((_, f))) = (best, efficient) {
                    outln!(
                        "{:>12} {budget:>7} lowest error: {b} (rmse {e:.3e}); lowest error for the time: {f}",
                        sampling.name()
                    );
                }
            }
        }
    }
    Ok(())
}
