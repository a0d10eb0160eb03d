//! `--target`: the speed targets of issue 4, measured.
//!
//! The scene (the seed room by default) at 64 grid shadow rays and depth 4,
//! at 1920×1080 and 960×540, median of at least 5 runs; the same with
//! skipping off (time, rays each skip saved, RMSE between the images); and
//! the peak memory of a `penumbra render` at 1920×1080 (`/usr/bin/time -v`).

use std::fmt::Write as _;
use std::path::Path;
use std::process::Command;

use super::{BenchArgs, CliError, Timed, build, scenes, si, timed};
use crate::render::compare::compare;
use crate::render::stats::SAVINGS;
use crate::render::{RayStats, Sampling, SceneDesc};

/// The goals, from the issue.
pub const FULL_HD_GOAL_S: f64 = 1.0;
pub const HALF_HD_GOAL_S: f64 = 0.3;
pub const MRAYS_PER_CORE_GOAL: f64 = 20.0;
pub const PEAK_MEMORY_GOAL_MB: f64 = 64.0;

fn at_size(desc: &SceneDesc, width: u32, height: u32) -> SceneDesc {
    let mut d = desc.clone();
    d.camera.width = width;
    d.camera.height = height;
    d.render.shadow_rays = 64;
    d.render.sampling = Sampling::Grid;
    d.render.max_depth = 4;
    d
}

fn verdict(ok: bool) -> &'static str {
    if ok { "yes" } else { "NO" }
}

/// The rays each skip answered or saved, one per line.
pub fn savings(s: &RayStats) -> String {
    let mut out = String::new();
    for k in &SAVINGS {
        let _ = writeln!(out, "  {}: {}", k.label, si((k.count)(s)));
    }
    let _ = write!(
        out,
        "  traced {} of {} rays ({:.1}% skipped)",
        si(s.traced()),
        si(s.effective()),
        100.0 * s.shadow_skipped() as f64 / s.effective().max(1) as f64
    );
    out
}

pub fn run(args: &BenchArgs) -> Result<(), CliError> {
    let runs = args.runs.unwrap_or(5).max(5);
    let threads = rayon::current_num_threads();
    let scene = scenes(&BenchArgs {
        width: None,
        height: None,
        quick: false,
        ..args.clone()
    })?
    .into_iter()
    .next()
    .ok_or_else(|| CliError::input("no scene"))?;
    println!(
        "targets on {} ({} threads, median of {runs} runs)",
        scene.name, threads
    );

    let full = at_size(&scene.desc, 1920, 1080);
    let half = at_size(&scene.desc, 960, 540);
    let full_on = timed(&build(&full, true)?, runs);
    report_line("1920×1080 skip on", &full_on, threads);
    let half_on = timed(&build(&half, true)?, runs);
    report_line("960×540 skip on", &half_on, threads);
    let full_off = timed(&build(&full, false)?, runs);
    report_line("1920×1080 skip off", &full_off, threads);
    let diff = compare(&full_on.report.film, &full_off.report.film).map_err(CliError::other)?;
    println!(
        "rays saved by skipping at 1920×1080:\n{}",
        savings(&full_on.report.final_stats)
    );
    let memory = peak_memory_mb(args.scene.as_deref(), args.threads);

    let t_full = full_on.median().as_secs_f64();
    let t_half = half_on.median().as_secs_f64();
    let per_core = |t: &Timed, effective: bool| {
        let s = &t.report.final_stats;
        let n = if effective { s.effective() } else { s.traced() };
        n as f64 / t.median().as_secs_f64() / threads as f64 / 1e6
    };
    let mr_full = per_core(&full_on, false);
    let mr_half = per_core(&half_on, false);
    // Load-robust companions: CPU time / threads is the wall time with the
    // cores to ourselves; rays per CPU-second are rays per second per core.
    let idle = |t: &Timed| {
        t.median_cpu()
            .map_or(f64::NAN, |c| c.as_secs_f64() / threads as f64)
    };
    let per_cpu_s = |t: &Timed| {
        t.median_cpu().map_or(f64::NAN, |c| {
            t.report.final_stats.traced() as f64 / c.as_secs_f64() / 1e6
        })
    };
    println!();
    println!(
        "{:<48} {:>14} {:>10} {:>4}",
        "target", "measured", "goal", "met"
    );
    println!(
        "{:<48} {:>12.3} s {:>8} s {:>4}",
        "1920×1080, 64 grid, depth 4 (median)",
        t_full,
        FULL_HD_GOAL_S,
        verdict(t_full <= FULL_HD_GOAL_S)
    );
    println!(
        "{:<48} {:>12.3} s {:>8} s {:>4}",
        "960×540, 64 grid, depth 4 (median)",
        t_half,
        HALF_HD_GOAL_S,
        verdict(t_half <= HALF_HD_GOAL_S)
    );
    println!(
        "{:<48} {:>12.3} s {:>8} s {:>4}",
        "  CPU time / threads, 1920×1080",
        idle(&full_on),
        FULL_HD_GOAL_S,
        verdict(idle(&full_on) <= FULL_HD_GOAL_S)
    );
    println!(
        "{:<48} {:>12.3} s {:>8} s {:>4}",
        "  CPU time / threads, 960×540",
        idle(&half_on),
        HALF_HD_GOAL_S,
        verdict(idle(&half_on) <= HALF_HD_GOAL_S)
    );
    println!(
        "{:<48} {:>14.1} {:>10} {:>4}",
        "traced Mray/s per core, 1920×1080",
        mr_full,
        MRAYS_PER_CORE_GOAL,
        verdict(mr_full >= MRAYS_PER_CORE_GOAL)
    );
    println!(
        "{:<48} {:>14.1} {:>10} {:>4}",
        "traced Mray/s per core, 960×540",
        mr_half,
        MRAYS_PER_CORE_GOAL,
        verdict(mr_half >= MRAYS_PER_CORE_GOAL)
    );
    println!(
        "{:<48} {:>14.1} {:>10} {:>4}",
        "  traced Mray per CPU-second, 1920×1080",
        per_cpu_s(&full_on),
        MRAYS_PER_CORE_GOAL,
        verdict(per_cpu_s(&full_on) >= MRAYS_PER_CORE_GOAL)
    );
    println!(
        "{:<48} {:>14.1} {:>10} {:>4}",
        "  traced Mray per CPU-second, 960×540",
        per_cpu_s(&half_on),
        MRAYS_PER_CORE_GOAL,
        verdict(per_cpu_s(&half_on) >= MRAYS_PER_CORE_GOAL)
    );
    println!(
        "{:<48} {:>14.1} {:>10} {:>4}",
        "  incl. skipped shadow rays, 1920×1080",
        per_core(&full_on, true),
        "",
        ""
    );
    println!(
        "{:<48} {:>14.3e} {:>10} {:>4}",
        "RMSE skip on vs off, 1920×1080",
        diff.rmse,
        "0",
        verdict(diff.rmse == 0.0)
    );
    println!(
        "{:<48} {:>14.3e} {:>10} {:>4}",
        "  largest channel difference",
        diff.max_diff,
        "≤ 1e-6",
        verdict(diff.max_diff <= 1e-6)
    );
    println!(
        "{:<48} {:>12.2}× {:>10} {:>4}",
        "speed-up of skipping, 1920×1080",
        full_off.median().as_secs_f64() / t_full,
        "",
        ""
    );
    match memory {
        Some(mb) => println!(
            "{:<48} {:>11.1} MB {:>7} MB {:>4}",
            "peak memory, penumbra render 1920×1080 (png)",
            mb,
            PEAK_MEMORY_GOAL_MB,
            verdict(mb <= PEAK_MEMORY_GOAL_MB)
        ),
        None => println!(
            "peak memory: not measured (needs /usr/bin/time); run /usr/bin/time -v penumbra render --width 1920 --height 1080 -o out.png"
        ),
    }
    Ok(())
}

fn report_line(label: &str, t: &Timed, threads: usize) {
    let s = &t.report.final_stats;
    let secs = t.median().as_secs_f64();
    let times: Vec<String> = t
        .times
        .iter()
        .map(|d| format!("{:.3}", d.as_secs_f64()))
        .collect();
    let cpu = t.median_cpu().map_or(f64::NAN, |c| c.as_secs_f64());
    println!(
        "{label}: median {secs:.3} s (runs {} s), CPU {cpu:.3} s, {} rays traced, {:.1} Mray/s ({:.1} per core)",
        times.join(" "),
        si(s.traced()),
        s.traced() as f64 / secs / 1e6,
        s.traced() as f64 / secs / 1e6 / threads as f64
    );
}

/// Peak resident memory (MB) of `penumbra render` at 1920×1080, 64 grid
/// rays, depth 4, measured by `/usr/bin/time -v` in a child process so
/// the bench's own images do not count.
fn peak_memory_mb(scene: Option<&Path>, threads: Option<u32>) -> Option<f64> {
    let time = Path::new("/usr/bin/time");
    if !time.exists() {
        return None;
    }
    let exe = std::env::current_exe().ok()?;
    let dir = tempfile::tempdir().ok()?;
    let mut cmd = Command::new(time);
    cmd.arg("-v").arg(exe).arg("render");
    if let Some(s) = scene {
        cmd.arg(s);
    }
    cmd.args([
        "--width",
        "1920",
        "--height",
        "1080",
        "--shadow-rays",
        "64",
        "--sampling",
        "grid",
        "--depth",
        "4",
        "-o",
    ])
    .arg(dir.path().join("peak.png"));
    if let Some(n) = threads {
        cmd.args(["--threads", &n.to_string()]);
    }
    let out = cmd.output().ok()?;
    let text = String::from_utf8_lossy(&out.stderr);
    let kb: f64 = text
        .lines()
        .find_map(|l| l.trim().strip_prefix("Maximum resident set size (kbytes):"))?
        .trim()
        .parse()
        .ok()?;
    Some(kb / 1024.0)
}
