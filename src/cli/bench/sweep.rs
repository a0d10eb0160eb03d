//! The sweep: every sampling pattern × shadow-ray count × area-light model,
//! timed and compared with the model's converged reference.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::reference::{REFERENCE_RAYS, reference};
use super::{BenchArgs, BenchScene, CliError, build, scenes, si, timed};
use crate::render::compare::compare;
use crate::render::output::{FileKind, write_atomic};
use crate::render::sampling::points_per_hit;
use crate::render::stats::SAVINGS;
use crate::render::{AreaLightModel, RayStats, Sampling, SceneDesc};

/// The shadow-ray counts of a full sweep.
pub const COUNTS: [u32; 6] = [1, 4, 16, 64, 256, 1024];
/// The counts of `--quick`.
pub const QUICK_COUNTS: [u32; 5] = [1, 4, 16, 64, 256];

/// What to sweep.
#[derive(Debug, Clone)]
pub struct SweepPlan {
    pub samplings: Vec<Sampling>,
    pub models: Vec<AreaLightModel>,
    pub counts: Vec<u32>,
    /// Adaptive shadow rays off and/or on (`render.adaptive`).
    pub adaptive: Vec<bool>,
    pub runs: u32,
    /// Also render with skipping off.
    pub no_skip: bool,
    pub reference_rays: u32,
    pub cache_dir: PathBuf,
    pub fresh_reference: bool,
}

impl SweepPlan {
    /// Every pattern and model (from their `ALL` lists, so that new ones
    /// join the sweep by themselves) at the arguments' counts and runs.
    pub fn from_args(args: &BenchArgs) -> SweepPlan {
        let counts = match &args.counts {
            Some(c) => c.clone(),
            None if args.quick => QUICK_COUNTS.to_vec(),
            None => COUNTS.to_vec(),
        };
        SweepPlan {
            samplings: Sampling::ALL.to_vec(),
            models: AreaLightModel::ALL.to_vec(),
            counts,
            adaptive: if args.no_adaptive {
                vec![false]
            } else {
                vec![false, true]
            },
            runs: args.runs.unwrap_or(3),
            no_skip: args.no_skip,
            reference_rays: args.reference_rays,
            cache_dir: args.cache.clone(),
            fresh_reference: args.fresh_reference,
        }
    }

    /// A plan of the given counts over every pattern and model.
    pub fn new(counts: &[u32], cache_dir: &Path) -> SweepPlan {
        SweepPlan {
            samplings: Sampling::ALL.to_vec(),
            models: AreaLightModel::ALL.to_vec(),
            counts: counts.to_vec(),
            adaptive: vec![false],
            runs: 1,
            no_skip: false,
            reference_rays: REFERENCE_RAYS,
            cache_dir: cache_dir.to_owned(),
            fresh_reference: false,
        }
    }
}

/// The same configuration with skipping switched off.
#[derive(Debug, Clone, Copy)]
pub struct NoSkip {
    pub time_s: f64,
    pub stats: RayStats,
    /// RMSE between the images with skipping on and off.
    pub rmse_vs_skip: f64,
    pub max_diff_vs_skip: f64,
}

/// One measured configuration.
#[derive(Debug, Clone)]
pub struct Row {
    pub sampling: Sampling,
    pub model: AreaLightModel,
    /// Adaptive shadow rays (biased: a few first, the rest where they
    /// disagree).
    pub adaptive: bool,
    pub shadow_rays: u32,
    pub points_per_hit: usize,
    pub runs: u32,
    /// Median and fastest wall time, seconds.
    pub time_s: f64,
    pub time_min_s: f64,
    /// Median CPU seconds of all threads (NaN if unknown).
    pub cpu_s: f64,
    pub stats: RayStats,
    pub rmse: f64,
    pub psnr: f64,
    pub no_skip: Option<NoSkip>,
}

impl Row {
    /// Rays traced per second, millions.
    pub fn mrays(&self) -> f64 {
        self.stats.traced() as f64 / self.time_s / 1e6
    }
}

/// Runs the sweep over one scene; `progress` sees every row as it is done
/// and every reference as it is ready.
pub fn run_sweep(
    desc: &SceneDesc,
    plan: &SweepPlan,
    progress: &mut dyn FnMut(Progress),
) -> Result<Vec<Row>, CliError> {
    let mut rows = Vec::new();
    // `sampled` and `analytic` converge to the `exact` model's image: it is
    // their reference wherever the scene allows it (no hit point fell back
    // to an estimate).
    let exact_reference = if plan
        .models
        .iter()
        .any(|m| matches!(m, AreaLightModel::Sampled | AreaLightModel::Analytic))
    {
        let mut d = desc.clone();
        d.render.area_light_model = AreaLightModel::Exact;
        let r = super::render_once(&build(&d, true)?);
        let fallbacks = r.final_stats.exact_fallbacks;
        progress(Progress::ExactReference {
            fallbacks,
            secs: r.elapsed.as_secs_f64(),
        });
        (fallbacks == 0).then_some(r.film)
    } else {
        None
    };
    for &model in &plan.models {
        // The exact model is measured against the stratified reference of
        // `sampled` (its limit); the others against their own, or the
        // exact image.
        let reference_model = match model {
            AreaLightModel::Exact => AreaLightModel::Sampled,
            m => m,
        };
        let exact_ok = exact_reference.is_some()
            && matches!(model, AreaLightModel::Sampled | AreaLightModel::Analytic);
        let reference = if exact_ok {
            None
        } else {
            let r = reference(
                desc,
                reference_model,
                plan.reference_rays,
                &plan.cache_dir,
                plan.fresh_reference,
            )?;
            progress(Progress::Reference {
                model: reference_model,
                path: &r.path,
                cached: r.cached,
                secs: r.elapsed.as_secs_f64(),
            });
            Some(r.film)
        };
        let reference_film = match (&reference, &exact_reference) {
            (Some(f), _) | (None, Some(f)) => f,
            (None, None) => unreachable!("a reference is rendered when the exact one is not used"),
        };
        // The exact image does not depend on the pattern or the count: one
        // configuration.
        let (samplings, adaptives, counts) = if model == AreaLightModel::Exact {
            (&plan.samplings[..1], &[false][..], &plan.counts[..1])
        } else {
            (&plan.samplings[..], &plan.adaptive[..], &plan.counts[..])
        };
        for (&sampling, &adaptive) in samplings
            .iter()
            .flat_map(|s| adaptives.iter().map(move |a| (s, a)))
        {
            for &shadow_rays in counts {
                let mut d = desc.clone();
                d.render.sampling = sampling;
                d.render.shadow_rays = shadow_rays;
                d.render.area_light_model = model;
                d.render.adaptive = adaptive;
                let on = timed(&build(&d, true)?, plan.runs);
                let c = compare(&on.report.film, reference_film).map_err(CliError::other)?;
                let no_skip = if plan.no_skip {
                    let off = timed(&build(&d, false)?, plan.runs);
                    let diff =
                        compare(&on.report.film, &off.report.film).map_err(CliError::other)?;
                    Some(NoSkip {
                        time_s: off.median().as_secs_f64(),
                        stats: off.report.final_stats,
                        rmse_vs_skip: diff.rmse,
                        max_diff_vs_skip: diff.max_diff,
                    })
                } else {
                    None
                };
                let row = Row {
                    sampling,
                    model,
                    adaptive,
                    shadow_rays,
                    points_per_hit: points_per_hit(sampling, shadow_rays),
                    runs: plan.runs,
                    time_s: on.median().as_secs_f64(),
                    time_min_s: on.min().as_secs_f64(),
                    cpu_s: on.median_cpu().map_or(f64::NAN, |d| d.as_secs_f64()),
                    stats: on.report.final_stats,
                    rmse: c.rmse,
                    psnr: c.psnr,
                    no_skip,
                };
                progress(Progress::Row(&row));
                rows.push(row);
            }
        }
    }
    Ok(rows)
}

/// What [`run_sweep`] reports as it goes.
pub enum Progress<'a> {
    Reference {
        model: AreaLightModel,
        path: &'a Path,
        cached: bool,
        secs: f64,
    },
    /// The exact image, rendered as the reference of `sampled` and
    /// `analytic` (used only if no hit point fell back).
    ExactReference {
        fallbacks: u64,
        secs: f64,
    },
    Row(&'a Row),
}

/// The CSV's columns before and after the skip counters.
const CSV_HEAD: [&str; 17] = [
    "scene",
    "width",
    "height",
    "max_depth",
    "sampling",
    "model",
    "adaptive",
    "shadow_rays",
    "points_per_hit",
    "runs",
    "time_s",
    "time_min_s",
    "cpu_s",
    "rays_traced",
    "camera_rays",
    "shadow_traced",
    "reflected_traced",
];
const CSV_TAIL: [&str; 7] = [
    "mray_per_s",
    "rmse",
    "psnr_db",
    "noskip_time_s",
    "noskip_rays_traced",
    "rmse_skip_vs_noskip",
    "max_diff_skip_vs_noskip",
];

/// The CSV's columns, in order: the skip counters in the middle.
pub fn csv_columns() -> Vec<&'static str> {
    let skips = SAVINGS.iter().map(|k| k.key);
    CSV_HEAD.into_iter().chain(skips).chain(CSV_TAIL).collect()
}

/// The CSV text of a sweep: a header, then one line per row.
pub fn csv(scene: &str, desc: &SceneDesc, rows: &[Row]) -> String {
    let mut out = csv_columns().join(",");
    out.push('\n');
    for r in rows {
        let s = &r.stats;
        let (nt, nr, nd, nm) = match &r.no_skip {
            Some(n) => (
                format!("{:.6}", n.time_s),
                n.stats.traced().to_string(),
                format!("{:e}", n.rmse_vs_skip),
                format!("{:e}", n.max_diff_vs_skip),
            ),
            None => Default::default(),
        };
        // Scene names come from file names: keep the CSV parseable.
        let name: String = scene
            .chars()
            .map(|c| if c == ',' || c == '"' { '_' } else { c })
            .collect();
        let skips: String = SAVINGS
            .iter()
            .map(|k| format!(",{}", (k.count)(s)))
            .collect();
        let _ = writeln!(
            out,
            "{name},{},{},{},{},{},{},{},{},{},{:.6},{:.6},{:.6},{},{},{},{}{skips},{:.3},{:e},{:.3},{nt},{nr},{nd},{nm}",
            desc.camera.width,
            desc.camera.height,
            desc.render.max_depth,
            r.sampling.name(),
            r.model.name(),
            r.adaptive,
            r.shadow_rays,
            r.points_per_hit,
            r.runs,
            r.time_s,
            r.time_min_s,
            r.cpu_s,
            s.traced(),
            s.camera,
            s.shadow,
            s.reflected,
            r.mrays(),
            r.rmse,
            r.psnr,
        );
    }
    out
}

/// Writes [`csv`] atomically.
pub fn write_csv(path: &Path, scene: &str, desc: &SceneDesc, rows: &[Row]) -> Result<(), CliError> {
    let text = csv(scene, desc, rows);
    write_atomic(path, |w| {
        std::io::Write::write_all(w, text.as_bytes()).map_err(|e| e.to_string())
    })
    .map_err(CliError::other)
}

/// The table the sweep prints: one line per configuration, with the shadow
/// rays each skip answered without tracing.
pub fn table(rows: &[Row]) -> String {
    let mut out = String::new();
    let no_skip = rows.iter().any(|r| r.no_skip.is_some());
    let _ = write!(
        out,
        "{:<12} {:<13} {:>4} {:>5} {:>5} {:>9} {:>9} {:>8} {:>7} {:>10} {:>7} | skipped:",
        "sampling",
        "model",
        "adap",
        "rays",
        "pts",
        "time ms",
        "cpu ms",
        "traced",
        "Mray/s",
        "rmse",
        "psnr",
    );
    for k in &SAVINGS {
        let _ = write!(out, " {:>7}", k.short);
    }
    if no_skip {
        let _ = write!(
            out,
            " | {:>9} {:>7} {:>9}",
            "noskip ms", "speedup", "rmse on/off"
        );
    }
    out.push('\n');
    for r in rows {
        let s = &r.stats;
        let _ = write!(
            out,
            "{:<12} {:<13} {:>4} {:>5} {:>5} {:>9.2} {:>9.2} {:>8} {:>7.1} {:>10.3e} {:>7.2} | skipped:",
            r.sampling.name(),
            r.model.name(),
            if r.adaptive { "on" } else { "off" },
            r.shadow_rays,
            r.points_per_hit,
            r.time_s * 1e3,
            r.cpu_s * 1e3,
            si(s.traced()),
            r.mrays(),
            r.rmse,
            r.psnr,
        );
        for k in &SAVINGS {
            let _ = write!(out, " {:>7}", si((k.count)(s)));
        }
        if let Some(n) = &r.no_skip {
            let _ = write!(
                out,
                " | {:>9.2} {:>6.2}× {:>9.1e}",
                n.time_s * 1e3,
                n.time_s / r.time_s,
                n.rmse_vs_skip
            );
        }
        out.push('\n');
    }
    out
}

fn output_path(
    args: &BenchArgs,
    explicit: &Option<PathBuf>,
    scene: &BenchScene,
    ext: &str,
) -> PathBuf {
    explicit
        .clone()
        .unwrap_or_else(|| args.out.join(format!("bench-{}.{ext}", scene.name)))
}

/// `penumbra bench [SCENE]` without `--scaling` or `--target`.
pub fn run(args: &BenchArgs) -> Result<(), CliError> {
    let scenes = scenes(args)?;
    if scenes.len() > 1 && (args.csv.is_some() || args.plot.is_some()) {
        return Err(CliError::input(
            "--csv and --plot name one file: use --out with several --spheres counts",
        ));
    }
    // Refused before any work: a plot that is not a PNG, one file for both
    // the CSV and the plot, an output in a folder that is not there (its
    // own folder when named; `--out` is made), and an output that is the
    // scene file.
    if let Some(plot) = &args.plot
        && !matches!(FileKind::of(plot), Ok(FileKind::Png))
    {
        return Err(CliError::input(format!(
            "{}: --plot writes a PNG: the name must end in .png",
            plot.display()
        )));
    }
    if let (Some(csv), Some(plot)) = (&args.csv, &args.plot)
        && (csv == plot || crate::cli::safety::same_file(csv, plot))
    {
        return Err(CliError::input(format!(
            "{}: --csv and --plot name the same file",
            csv.display()
        )));
    }
    for (explicit, what) in [(&args.csv, "CSV"), (&args.plot, "plot")] {
        if let Some(path) = explicit {
            crate::cli::safety::refuse_missing_folder(path, what)?;
            crate::cli::safety::refuse_read_only(path, what)?;
        }
    }
    for scene in &scenes {
        for (explicit, ext, what) in [(&args.csv, "csv", "CSV"), (&args.plot, "png", "plot")] {
            let out = output_path(args, explicit, scene, ext);
            super::refuse_overwriting_scene(args, scene, &out, what)?;
            // The default names under --out too, not only those given.
            crate::cli::safety::refuse_read_only(&out, what)?;
        }
    }
    let plan = SweepPlan::from_args(args);
    for scene in &scenes {
        let d = &scene.desc;
        outln!(
            "{}: {}×{}, depth {}, {} objects; {} runs per configuration, reference: the exact model where the scene allows it, else {} stratified rays",
            scene.name,
            d.camera.width,
            d.camera.height,
            d.render.max_depth,
            d.objects.len(),
            plan.runs,
            plan.reference_rays
        );
        let rows = run_sweep(d, &plan, &mut |p| match p {
            Progress::Reference {
                model,
                path,
                cached,
                secs,
            } => {
                if cached {
                    outln!("reference ({}): cached {}", model.name(), path.display());
                } else {
                    outln!(
                        "reference ({}): rendered in {secs:.2} s, stored {}",
                        model.name(),
                        path.display()
                    );
                }
            }
            Progress::ExactReference { fallbacks, secs } => {
                if fallbacks == 0 {
                    outln!(
                        "reference (sampled, analytic): the exact model's image, rendered in {secs:.2} s"
                    );
                } else {
                    outln!(
                        "reference (sampled, analytic): not the exact model ({fallbacks} hit points fell back to an estimate), \
                         {} stratified rays",
                        plan.reference_rays
                    );
                }
            }
            Progress::Row(r) => crate::cli::print_stderr(format_args!(
                "  {} {}{} {}: {:.2} ms, rmse {:.3e}",
                r.sampling.name(),
                r.model.name(),
                if r.adaptive { " adaptive" } else { "" },
                r.shadow_rays,
                r.time_s * 1e3,
                r.rmse
            )),
        })?;
        out!("{}", table(&rows));
        if let Some(worst) = rows
            .iter()
            .filter_map(|r| r.no_skip.map(|n| n.rmse_vs_skip))
            .max_by(f64::total_cmp)
        {
            outln!("largest RMSE between skipping on and off: {worst:e}");
        }
        let csv_path = output_path(args, &args.csv, scene, "csv");
        let plot_path = output_path(args, &args.plot, scene, "png");
        for p in [&csv_path, &plot_path] {
            if let Some(dir) = p.parent().filter(|d| !d.as_os_str().is_empty()) {
                std::fs::create_dir_all(dir).map_err(|e| {
                    CliError::other(format!("cannot create {}: {e}", dir.display()))
                })?;
            }
        }
        write_csv(&csv_path, &scene.name, d, &rows)?;
        let title = format!(
            "{}: {}×{}, depth {}, {} to {} shadow rays per hit, median of {} run(s)",
            scene.name,
            d.camera.width,
            d.camera.height,
            d.render.max_depth,
            plan.counts.iter().min().unwrap_or(&0),
            plan.counts.iter().max().unwrap_or(&0),
            plan.runs
        );
        super::plot::plot(
            &plot_path,
            &title,
            &rows,
            args.plot_time,
            rayon::current_num_threads(),
        )?;
        outln!("wrote {} and {}", csv_path.display(), plot_path.display());
    }
    Ok(())
}
