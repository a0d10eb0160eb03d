//! `penumbra bench --edits`: what an edit costs in the viewer. A fixed
//! sequence of edits of each class goes through the viewer's own render
//! worker (`app::render_job`, the core's `LiveRender` behind it), headless,
//! and each is timed from the request to its last tile in the mailbox
//! (converted for the texture), and for re-traces to its first tile. After
//! each re-trace a one-shot render of the same description is timed, over
//! the same scene (interleaved, so that both meet the same load on a
//! shared machine). The re-traces are two light moves (which the core
//! runs as relights over the recorded paths) to one camera move; they are
//! reported together and by kind.

use std::time::Duration;

use super::{BenchArgs, CliError, cpu_time, scenes};
use crate::app::render_job::{JobState, RenderJob};
use crate::render::scene_file::SceneDesc;
use crate::render::{
    CancelToken, EditClass, Loaded, RenderOptions, RenderSettings, ShadingParams, TileUpdate,
};

/// Edits per class (after one warm-up edit).
const EDITS: usize = 9;

/// The `k`-th edit of a class, applied to `desc` (each differs from the
/// previous one, so none is a no-op); returns the class the core must give
/// it (a re-trace edit that moves the light relights).
fn apply(class: EditClass, k: usize, desc: &mut SceneDesc) -> EditClass {
    let f = 0.5 + 0.05 * (k % 8) as f64;
    let first = desc.materials.keys().next().cloned().unwrap_or_default();
    let mut got = class;
    match (class, k % 3) {
        (EditClass::Recombine, 0) => desc.render.terms.specular = f,
        (EditClass::Recombine, 1) => desc.light.diffuse = [f, f, f],
        (EditClass::Recombine, _) => {
            if let Some(m) = desc.materials.get_mut(&first) {
                m.diffuse = [f, 0.5, 0.3];
            }
        }
        (EditClass::Reshade, 0 | 1) => desc.render.shininess_override = Some(10.0 + 40.0 * f),
        (EditClass::Reshade, _) => {
            desc.render.shininess_override = None;
            for m in desc.materials.values_mut() {
                if m.reflectivity > 0.0 {
                    m.reflectivity = (m.reflectivity * (0.9 + 0.1 * f)).min(1.0);
                }
            }
        }
        (_, 0 | 1) => {
            desc.light.corner[0] += if k.is_multiple_of(2) { 0.05 } else { -0.04 };
            got = EditClass::Relight;
        }
        _ => desc.camera.position[1] += 0.01,
    }
    got
}

/// Median and 90th percentile of `times`, in ms.
fn median_p90(times: &[Duration]) -> (f64, f64) {
    let mut sorted = times.to_vec();
    sorted.sort();
    (quantile_ms(&sorted, 0.5), quantile_ms(&sorted, 0.9))
}

/// The median of `ratios`.
fn median(mut ratios: Vec<f64>) -> f64 {
    ratios.sort_by(f64::total_cmp);
    ratios[ratios.len() / 2]
}

/// One re-trace edit against the one-shot render of its description.
struct Retrace {
    class: EditClass,
    full: Duration,
    one_shot: Duration,
    /// The process's CPU time during each (steadier on a shared machine).
    cpu: Option<(Duration, Duration)>,
}

/// The `q`-quantile of sorted durations, in ms.
fn quantile_ms(sorted: &[Duration], q: f64) -> f64 {
    let i = ((sorted.len() - 1) as f64 * q).round() as usize;
    sorted[i].as_secs_f64() * 1e3
}

pub fn run(args: &BenchArgs) -> Result<(), CliError> {
    let ctx = egui::Context::default();
    for scene in scenes(args)? {
        let mut desc = scene.desc;
        let c = &desc.camera;
        outln!(
            "{}: {}×{}, {} {} shadow rays, depth {}, {} threads",
            scene.name,
            c.width,
            c.height,
            desc.render.shadow_rays,
            desc.render.sampling.name(),
            desc.render.max_depth,
            rayon::current_num_threads()
        );
        let job = RenderJob::new(ctx.clone());
        let mut peak = 0;
        let mut render = |desc: &SceneDesc| -> Result<(EditClass, Duration, Duration), CliError> {
            job.restart(desc.clone());
            if !job.wait(Duration::from_secs(600)) {
                return Err(CliError::other("an edit did not finish in 10 minutes"));
            }
            let first = job.first_tile_after().unwrap_or_default();
            match job.state() {
                JobState::Finished(f) => {
                    peak = peak.max(f.record_bytes);
                    Ok((f.class, first, f.since_request))
                }
                JobState::Failed(e) => Err(CliError::input(e)),
                _ => Err(CliError::other("the render was cancelled")),
            }
        };
        render(&desc)?;
        let mut retraces: Vec<Retrace> = Vec::new();
        for class in [EditClass::Recombine, EditClass::Reshade, EditClass::Retrace] {
            let mut full = Vec::new();
            let mut first = Vec::new();
            for k in 0..=EDITS {
                let want = apply(class, k, &mut desc);
                let cpu_before = cpu_time();
                let (got, f, t) = render(&desc)?;
                let cpu = cpu_time().zip(cpu_before).map(|(b, a)| b.saturating_sub(a));
                if got != want {
                    return Err(CliError::other(format!(
                        "a {} edit ran as {}",
                        want.name(),
                        got.name()
                    )));
                }
                if k > 0 {
                    full.push(t);
                    first.push(f);
                    if class == EditClass::Retrace {
                        let cpu_before = cpu_time();
                        let one_shot = one_shot_render(&job, &desc)?;
                        let one_shot_cpu =
                            cpu_time().zip(cpu_before).map(|(b, a)| b.saturating_sub(a));
                        retraces.push(Retrace {
                            class: got,
                            full: t,
                            one_shot,
                            cpu: cpu.zip(one_shot_cpu),
                        });
                    }
                }
            }
            let (median_ms, p90_ms) = median_p90(&full);
            out!(
                "edit {} median_ms {median_ms:.1} p90_ms {p90_ms:.1}",
                class.name()
            );
            if class == EditClass::Retrace {
                let (median_ms, p90_ms) = median_p90(&first);
                out!(" first_pixels_median_ms {median_ms:.1} first_pixels_p90_ms {p90_ms:.1}");
            }
            outln!();
        }
        drop(job);
        // Each re-trace against the one-shot render right after it: all of
        // them, then the light moves and the camera moves apart.
        for (kind, of_kind) in [
            ("", None),
            (".light", Some(EditClass::Relight)),
            (".camera", Some(EditClass::Retrace)),
        ] {
            let runs: Vec<&Retrace> = retraces
                .iter()
                .filter(|r| of_kind.is_none_or(|k| k == r.class))
                .collect();
            let full: Vec<Duration> = runs.iter().map(|r| r.full).collect();
            let one_shot: Vec<Duration> = runs.iter().map(|r| r.one_shot).collect();
            let ratio = |(r, o): (Duration, Duration)| r.as_secs_f64() / o.as_secs_f64();
            let pairs = median(runs.iter().map(|r| ratio((r.full, r.one_shot))).collect());
            let (median_ms, p90_ms) = median_p90(&full);
            let (cli, _) = median_p90(&one_shot);
            if of_kind.is_some() {
                out!("edit retrace{kind} median_ms {median_ms:.1} p90_ms {p90_ms:.1}; ");
            }
            out!(
                "re-trace{kind} full quality / one-shot {:.2}× (one-shot median_ms {cli:.1}; median of the {} pairs {pairs:.2}×",
                median_ms / cli,
                runs.len()
            );
            let cpu: Option<Vec<(Duration, Duration)>> = runs.iter().map(|r| r.cpu).collect();
            match cpu {
                // CPU time comes in clock ticks: a tiny image's one-shot
                // render may take none, and no ratio can be had.
                Some(cpu) if cpu.iter().any(|(_, one_shot)| one_shot.is_zero()) => {
                    out!(", their CPU times below the clock's resolution")
                }
                Some(cpu) => out!(
                    ", of their CPU times {:.2}×",
                    median(cpu.into_iter().map(ratio).collect())
                ),
                None => {}
            }
            outln!(")");
        }
        outln!("record peak_bytes {peak} ({:.1} MB)", peak as f64 / 1e6);
    }
    Ok(())
}

/// The time of the CLI's one-shot render of `desc` (render only, as
/// `penumbra render` reports it) over the scene the job just rendered.
fn one_shot_render(job: &RenderJob, desc: &SceneDesc) -> Result<Duration, CliError> {
    let scene = match job.scene() {
        Some(scene) => scene,
        None => Loaded::new(desc).map_err(CliError::input)?.scene,
    };
    let report = crate::render::render(
        &scene,
        &RenderSettings::from_desc(desc),
        &ShadingParams::from_desc(desc),
        &RenderOptions::default(),
        &CancelToken::new(),
        &|_: &TileUpdate| {},
    )
    .expect("an uncancellable render finishes");
    Ok(report.elapsed)
}
