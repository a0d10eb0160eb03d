//! `penumbra bench`: run time against error.
//!
//! - the default mode sweeps sampling patterns × shadow-ray counts ×
//!   area-light models against a converged, cached reference and writes a
//!   CSV, a log-log plot of RMSE against time and a table ([`sweep`]);
//! - `--spheres N,… --scaling` times generated scenes of N spheres
//!   ([`scaling`]);
//! - `--target` measures the figures of the speed targets ([`target`]);
//! - `--meshes N,…` times meshes of N triangles in the room ([`meshes`]);
//! - `--edits` times the viewer's answer to each class of edit ([`edits`]);
//! - `--exact` measures the `exact` model's accuracy and cost targets
//!   ([`exact`]);
//! - `--spp-split` shares a pixel's rays between camera samples and shadow
//!   rays ([`split`]).
//!
//! Every time is the median of `--runs` renders (wall time of the render
//! alone, not of building the scene), and every mode prints the machine's
//! load, since the measurements share the machine with other work.
//!
//! Numeric options take values that begin with `-`, as `render`'s do (see
//! [`crate::cli`]): a negative number gets the option's range message.

/// `print!` for the bench's report: a failed write to standard output
/// (`> /dev/full`) is kept for the end, a closed pipe (`| head`) ignored,
/// instead of `print!`'s panic (exit 101) mid-run; the result files are
/// written either way.
macro_rules! out {
    ($($arg:tt)*) => {
        $crate::cli::bench::write_out(format_args!($($arg)*))
    };
}

/// `println!` as [`out!`].
macro_rules! outln {
    () => {
        $crate::cli::bench::write_out(format_args!("\n"))
    };
    ($($arg:tt)*) => {
        $crate::cli::bench::write_out(format_args!("{}\n", format_args!($($arg)*)))
    };
}

pub mod edits;
pub mod exact;
pub mod memory;
pub mod meshes;
pub mod plot;
pub mod reference;
pub mod scaling;
pub mod slopes;
pub mod split;
pub mod sweep;
pub mod target;

use std::path::{Path, PathBuf};
use std::time::Duration;

use clap::Args;

use super::{CliError, ListValue, SceneOverrides, load_desc, parse_seed};
use crate::render::{CancelToken, Loaded, RenderOptions, RenderReport, SceneDesc, generate};

pub use reference::{Reference, reference, reference_key};
pub use sweep::{Row, SweepPlan, run_sweep, write_csv};

// An option a mode does not use is refused with it rather than silently
// ignored: these are the modes that leave each group of options unused.
/// Every mode but the default sweep.
const NOT_SWEEP: [&str; 7] = [
    "target",
    "slopes",
    "edits",
    "spp_split",
    "exact",
    "meshes",
    "scaling",
];
/// The modes that render no cached reference.
const NO_REFERENCE: [&str; 5] = ["target", "slopes", "edits", "meshes", "scaling"];
/// The modes that write no file under --out.
const NO_OUT: [&str; 6] = [
    "target",
    "slopes",
    "edits",
    "spp_split",
    "meshes",
    "scaling",
];

#[derive(Debug, Args, Default, Clone)]
// One mode a run: a second one was silently dropped.
#[command(group(clap::ArgGroup::new("mode")
    .multiple(false)
    .args(["target", "slopes", "edits", "spp_split", "exact", "meshes", "scaling"])))]
pub struct BenchArgs {
    /// Scene file (JSON); the built-in seed room if omitted.
    pub scene: Option<PathBuf>,
    /// A small sweep that finishes in well under a minute: a 160-pixel-wide
    /// image and counts 1 to 256.
    #[arg(long, conflicts_with = "target")]
    pub quick: bool,
    /// Renders per measurement; the median time is reported (default 3;
    /// 5 for --scaling and at least 5 for --target).
    #[arg(long, allow_negative_numbers = true, value_parser = clap::value_parser!(u32).range(1..=1000), conflicts_with_all = ["slopes", "edits"])]
    pub runs: Option<u32>,
    /// Shadow-ray counts to sweep, e.g. 1,4,16 (default 1,4,16,64,256,1024).
    #[arg(long, allow_hyphen_values = true, value_delimiter = ',', value_parser = ListValue(clap::value_parser!(u32).range(1..=4096)), conflicts_with_all = NOT_SWEEP)]
    pub counts: Option<Vec<u32>>,
    /// Stratified shadow rays per hit of the reference image.
    #[arg(long, allow_negative_numbers = true, default_value_t = reference::REFERENCE_RAYS, value_parser = clap::value_parser!(u32).range(1..=4096), conflicts_with_all = NOT_SWEEP)]
    pub reference_rays: u32,
    /// Where references are cached (EXR, keyed by a hash of the scene).
    #[arg(long, default_value = "target/penumbra-cache", conflicts_with_all = NO_REFERENCE)]
    pub cache: PathBuf,
    /// Render the reference again even if it is cached.
    #[arg(long, conflicts_with_all = NO_REFERENCE)]
    pub fresh_reference: bool,
    /// Directory of the CSV and plot (bench-SCENE.csv / .png).
    #[arg(long, default_value = "target/penumbra-bench", conflicts_with_all = NO_OUT)]
    pub out: PathBuf,
    /// Write the CSV here instead (one scene only).
    #[arg(long, conflicts_with_all = NOT_SWEEP)]
    pub csv: Option<PathBuf>,
    /// Write the plot (PNG) here instead (one scene only).
    #[arg(long, conflicts_with_all = NOT_SWEEP)]
    pub plot: Option<PathBuf>,
    /// Image width in pixels (default: the scene's; 160 with --quick).
    #[arg(long, allow_negative_numbers = true, value_parser = clap::value_parser!(u32).range(1..=16384), conflicts_with = "target")]
    pub width: Option<u32>,
    /// Image height in pixels (default: the width at the scene's aspect).
    #[arg(long, allow_negative_numbers = true, value_parser = clap::value_parser!(u32).range(1..=16384), conflicts_with = "target")]
    pub height: Option<u32>,
    /// Most surface hits along one camera path.
    #[arg(long, allow_negative_numbers = true, value_parser = clap::value_parser!(u32).range(1..=16), conflicts_with_all = ["target", "slopes"])]
    pub depth: Option<u32>,
    /// Random seed of the renders (the reference uses its own).
    #[arg(long, allow_negative_numbers = true, value_parser = parse_seed)]
    pub seed: Option<u64>,
    /// Worker threads (default: all cores).
    #[arg(long, allow_negative_numbers = true, value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub threads: Option<u32>,
    /// Replace the scene with the seed room holding N random spheres; a
    /// comma-separated list runs each N (at most 999 995: with the room's
    /// own 5 objects, the format's 1 000 000).
    #[arg(long, allow_hyphen_values = true, value_delimiter = ',', value_parser = ListValue(clap::value_parser!(u32).range(1..=generate::MAX_SPHERES as i64)))]
    pub spheres: Option<Vec<u32>>,
    /// Seed of the sphere generator.
    #[arg(long, allow_negative_numbers = true, default_value_t = 1, value_parser = parse_seed, requires = "spheres")]
    pub sphere_seed: u64,
    /// With --spheres: anywhere in the room (5 % of its volume; more
    /// spheres make a denser fog) or one layer on the floor (30 % of it).
    #[arg(long, value_enum, default_value_t = LayoutArg::Volume, requires = "spheres")]
    pub layout: LayoutArg,
    /// With --spheres: also write each generated scene as DIR/spheres-N.json
    /// (to render or view it).
    #[arg(long, value_name = "DIR", requires = "spheres")]
    pub save_scenes: Option<PathBuf>,
    /// With --spheres: time each N at the scene's own settings (no sweep)
    /// and print the ratio of the largest N to the smallest.
    #[arg(long)]
    pub scaling: bool,
    /// Leave adaptive shadow rays out of the sweep (by default every
    /// configuration is also measured with `render.adaptive` on, to show
    /// its error next to its time).
    #[arg(long, conflicts_with_all = NOT_SWEEP)]
    pub no_adaptive: bool,
    /// Also render every configuration with skipping switched off: time,
    /// speed-up and the RMSE between the two images (expected 0).
    #[arg(long, conflicts_with_all = NOT_SWEEP)]
    pub no_skip: bool,
    /// Time axis of the plot: the median wall time, or the median CPU time
    /// divided by the threads (the wall time with the cores to itself:
    /// steadier on a machine shared with other work).
    #[arg(long, value_enum, default_value_t = PlotTime::Wall, conflicts_with_all = NOT_SWEEP)]
    pub plot_time: PlotTime,
    /// Measure the speed targets (960×540 at 1 shadow ray; 960×540 and
    /// 1920×1080 at 64 grid rays; depth 4; shadow rays per core with
    /// skipping off; peak memory), each with its goal and ratio.
    #[arg(long, conflicts_with = "spheres")]
    pub target: bool,
    /// Fit the slope of log RMSE against log shadow rays in penumbra
    /// regions for each pattern (diffuse term, camera-ray hits).
    #[arg(long)]
    pub slopes: bool,
    /// Time the viewer's answer to edits of each class (recombine,
    /// re-shade, re-trace) through its own render worker, against a
    /// one-shot render of the same settings.
    #[arg(long)]
    pub edits: bool,
    /// Share each pixel's shadow-ray budget (16, 64, 256) between camera
    /// samples and shadow rays (1 × 64, 4 × 16, 16 × 4, …) and compare each
    /// split with an anti-aliased reference.
    #[arg(long)]
    pub spp_split: bool,
    /// Measure the `exact` model's targets: RMSE against a 65 536-ray
    /// stratified reference (the mean of 16 renders of 4096 rays), its
    /// error image, and its time against 64 grid rays of `sampled`.
    #[arg(long)]
    pub exact: bool,
    /// Camera samples per pixel of the renders (anti-aliasing; not with
    /// --spp-split, whose splits choose their own).
    #[arg(long, allow_negative_numbers = true, value_parser = clap::value_parser!(u32).range(1..=1024), conflicts_with = "spp_split")]
    pub spp: Option<u32>,
    /// Time the seed room, the bunny room and the room with a generated
    /// torus of each of these triangle counts (load and render).
    #[arg(long, allow_hyphen_values = true, value_delimiter = ',', value_parser = ListValue(clap::value_parser!(u32).range(18..=20_000_000)), conflicts_with = "spheres")]
    pub meshes: Option<Vec<u32>>,
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum PlotTime {
    #[default]
    Wall,
    Cpu,
}

/// The first failed write to standard output of [`out!`], other than to
/// a closed pipe.
static STDOUT_ERROR: std::sync::Mutex<Option<String>> = std::sync::Mutex::new(None);

/// What [`out!`] and [`outln!`] call.
pub fn write_out(text: std::fmt::Arguments) {
    use std::io::Write;
    if let Err(e) = std::io::stdout().lock().write_fmt(text)
        && e.kind() != std::io::ErrorKind::BrokenPipe
    {
        let mut first = STDOUT_ERROR.lock().unwrap_or_else(|p| p.into_inner());
        first.get_or_insert_with(|| e.to_string());
    }
}

/// `penumbra bench`.
pub fn bench(args: &BenchArgs) -> Result<(), CliError> {
    crate::cli::safety::end_on_signals("interrupted");
    // The folders a mode writes into are made as needed: refused before
    // any work where a file stands in their place (only for the modes that
    // use them: a file at the default place does not concern the others).
    let modes = [
        ("target", args.target),
        ("slopes", args.slopes),
        ("edits", args.edits),
        ("spp_split", args.spp_split),
        ("exact", args.exact),
        ("meshes", args.meshes.is_some()),
        ("scaling", args.scaling),
    ];
    let unused_by = |list: &[&str]| modes.iter().any(|(m, on)| *on && list.contains(m));
    if !unused_by(&NO_OUT) {
        refuse_file_for_folder(&args.out, "--out")?;
    }
    if !unused_by(&NO_REFERENCE) {
        refuse_file_for_folder(&args.cache, "--cache")?;
    }
    refuse_unused_scene(args)?;
    outln!("load average at start: {}", load_average());
    let pool = thread_pool(args.threads)?;
    let result = pool.install(|| {
        if args.exact {
            exact::run(args)
        } else if args.edits {
            edits::run(args)
        } else if args.spp_split {
            split::run(args)
        } else if args.meshes.is_some() {
            meshes::run(args)
        } else if args.target {
            target::run(args)
        } else if args.slopes {
            slopes::run(args)
        } else if args.scaling {
            scaling::run(args)
        } else {
            sweep::run(args)
        }
    });
    outln!("load average at end: {}", load_average());
    let failed = STDOUT_ERROR
        .lock()
        .unwrap_or_else(|p| p.into_inner())
        .take();
    match (result, failed) {
        (Ok(()), Some(e)) => Err(CliError::other(format!("standard output: {e}"))),
        (result, _) => result,
    }
}

/// Refuses (exit 2), before any work, a file where the folder `flag`
/// names (made as needed) would go.
fn refuse_file_for_folder(dir: &Path, flag: &str) -> Result<(), CliError> {
    if dir.exists() && !dir.is_dir() {
        return Err(CliError::input(format!(
            "{}: {flag} is a file, expected a folder",
            dir.display()
        )));
    }
    Ok(())
}

/// Refuses (exit 2) a scene file given to a mode that makes its own
/// scenes: it was silently left out.
fn refuse_unused_scene(args: &BenchArgs) -> Result<(), CliError> {
    let Some(scene) = &args.scene else {
        return Ok(());
    };
    let why = if args.spheres.is_some() {
        "--spheres generates its own scenes (the seed room with N spheres)"
    } else if args.meshes.is_some() {
        "--meshes measures its own scenes (the seed room with each mesh)"
    } else {
        return Ok(());
    };
    Err(CliError::input(format!(
        "{}: {why}: leave out the scene file",
        scene.display()
    )))
}

fn thread_pool(threads: Option<u32>) -> Result<rayon::ThreadPool, CliError> {
    let mut b = rayon::ThreadPoolBuilder::new().thread_name(|i| format!("penumbra-bench-{i}"));
    if let Some(n) = threads {
        b = b.num_threads(n as usize);
    }
    b.build().map_err(CliError::other)
}

/// The machine's 1, 5 and 15 minute load averages (Linux), or "unknown".
pub fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_else(|| "unknown".into())
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum LayoutArg {
    #[default]
    Volume,
    Floor,
}

impl From<LayoutArg> for generate::Layout {
    fn from(l: LayoutArg) -> generate::Layout {
        match l {
            LayoutArg::Volume => generate::Layout::Volume,
            LayoutArg::Floor => generate::Layout::Floor,
        }
    }
}

/// A scene to measure, with the name its output files get.
pub struct BenchScene {
    pub name: String,
    pub desc: SceneDesc,
}

/// The scenes the arguments ask for: the scene file or the seed room, or
/// one generated room per `--spheres` count; size, depth and seed
/// overridden, and each size checked against the memory the process may
/// take before any render.
pub fn scenes(args: &BenchArgs) -> Result<Vec<BenchScene>, CliError> {
    let base: Vec<BenchScene> = match &args.spheres {
        Some(counts) => counts
            .iter()
            .map(|&n| BenchScene {
                name: match args.layout {
                    LayoutArg::Volume => format!("spheres-{n}"),
                    LayoutArg::Floor => format!("floor-spheres-{n}"),
                },
                desc: generate::generate(n as usize, args.sphere_seed, args.layout.into()),
            })
            .collect(),
        None => {
            let desc = load_desc(args.scene.as_deref(), &SceneOverrides::default())?;
            let name = args
                .scene
                .as_deref()
                .and_then(Path::file_stem)
                .map_or("seed-room".into(), |s| s.to_string_lossy().into_owned());
            vec![BenchScene { name, desc }]
        }
    };
    let quick_width = args.quick.then_some(160);
    base.into_iter()
        .map(|mut s| {
            let c = &mut s.desc.camera;
            if let Some(w) = args.width.or(quick_width) {
                if args.height.is_none() {
                    // Keep the scene's aspect ratio.
                    c.height =
                        ((w as f64 * c.height as f64 / c.width as f64).round() as u32).max(1);
                }
                c.width = w;
            }
            if let Some(h) = args.height {
                c.height = h;
            }
            if let Some(d) = args.depth {
                s.desc.render.max_depth = d;
            }
            if let Some(seed) = args.seed {
                s.desc.render.seed = seed;
            }
            if let Some(spp) = args.spp {
                s.desc.render.samples_per_pixel = spp;
            }
            // Named as render names it: the file, and the option that
            // made the size what it is.
            s.desc.validate().map_err(|mut e| {
                super::name_followed_side(&mut e, args.width.or(quick_width), args.height);
                match (&args.scene, &args.spheres) {
                    (Some(file), None) => CliError::input(e.in_file(file)),
                    _ => CliError::input(e),
                }
            })?;
            memory::check(args, &s)?;
            Ok(s)
        })
        .collect::<Result<Vec<_>, CliError>>()
        .and_then(|scenes| {
            if let (Some(dir), Some(_)) = (&args.save_scenes, &args.spheres) {
                save_scenes(dir, &scenes)?;
            }
            Ok(scenes)
        })
}

/// `--save-scenes DIR`: each scene as DIR/NAME.json, written as every
/// output is (whole or not at all); a file where the folder would go, or
/// a read-only scene file, refused (exit 2) before any is written.
fn save_scenes(dir: &Path, scenes: &[BenchScene]) -> Result<(), CliError> {
    refuse_file_for_folder(dir, "--save-scenes")?;
    let path = |s: &BenchScene| dir.join(format!("{}.json", s.name));
    for s in scenes {
        crate::cli::safety::refuse_read_only(&path(s), "saved scene")?;
    }
    std::fs::create_dir_all(dir).map_err(|e| {
        CliError::other(format!(
            "cannot create the folder {} (--save-scenes): {e}",
            dir.display()
        ))
    })?;
    for s in scenes {
        let json = s.desc.to_json();
        crate::render::output::write_atomic(&path(s), |w| {
            std::io::Write::write_all(w, json.as_bytes()).map_err(|e| e.to_string())
        })
        .map_err(CliError::other)?;
    }
    Ok(())
}

/// Refuses (exit 2) an output of the bench that is the scene file or one
/// of the scene's meshes: writing it would destroy an input. Every mode
/// that writes a file checks it before its work.
pub fn refuse_overwriting_scene(
    args: &BenchArgs,
    scene: &BenchScene,
    output: &Path,
    what: &str,
) -> Result<(), CliError> {
    let meshes = scene.desc.mesh_files();
    let inputs: Vec<(&str, &Path)> = args
        .scene
        .iter()
        .map(|s| ("scene", s.as_path()))
        .chain(meshes.iter().map(|m| ("mesh", m.as_path())))
        .collect();
    crate::cli::safety::refuse_overwriting_inputs(output, what, &inputs)
}

/// Builds the runtime scene of a description.
pub fn build(desc: &SceneDesc, skip: bool) -> Result<Loaded, CliError> {
    let mut loaded = Loaded::new(desc).map_err(CliError::input)?;
    loaded.settings.skip = skip;
    Ok(loaded)
}

/// One render in the current thread pool (the final image only).
pub fn render_once(loaded: &Loaded) -> RenderReport {
    let options = RenderOptions::default();
    loaded
        .render(&options, &CancelToken::new(), &|_| {})
        .expect("an uncancellable render finishes")
}

/// A scene rendered `runs` times: the first report (every run gives the
/// same image and counts), the wall times and the CPU times, each sorted.
pub struct Timed {
    pub report: RenderReport,
    pub times: Vec<Duration>,
    /// CPU time of all the process's threads per run (empty where
    /// `/proc` is missing).
    pub cpu: Vec<Duration>,
}

impl Timed {
    pub fn median(&self) -> Duration {
        median(&self.times)
    }
    pub fn min(&self) -> Duration {
        self.times[0]
    }
    /// Median CPU time: on a machine shared with other work it varies far
    /// less than the wall time, and CPU time / threads estimates the wall
    /// time the render would take with the cores to itself.
    pub fn median_cpu(&self) -> Option<Duration> {
        (!self.cpu.is_empty()).then(|| median(&self.cpu))
    }
}

pub fn timed(scene: &Loaded, runs: u32) -> Timed {
    let mut report = None;
    let mut times = Vec::new();
    let mut cpu = Vec::new();
    for _ in 0..runs.max(1) {
        let before = cpu_time();
        let r = render_once(scene);
        if let (Some(a), Some(b)) = (before, cpu_time()) {
            cpu.push(b.saturating_sub(a));
        }
        times.push(r.elapsed);
        report.get_or_insert(r);
    }
    times.sort();
    cpu.sort();
    if cpu.len() != times.len() {
        cpu.clear();
    }
    Timed {
        report: report.expect("at least one run"),
        times,
        cpu,
    }
}

/// CPU time used so far by all live threads of this process (Linux:
/// nanoseconds on CPU from /proc/self/task/*/schedstat).
pub fn cpu_time() -> Option<Duration> {
    let mut ns = 0u64;
    for task in std::fs::read_dir("/proc/self/task").ok()? {
        let text = std::fs::read_to_string(task.ok()?.path().join("schedstat")).ok()?;
        ns += text.split_whitespace().next()?.parse::<u64>().ok()?;
    }
    Some(Duration::from_nanos(ns))
}

/// Median of sorted durations (mean of the middle two for an even count).
pub fn median(sorted: &[Duration]) -> Duration {
    let n = sorted.len();
    if n == 0 {
        return Duration::ZERO;
    }
    if n % 2 == 1 {
        sorted[n / 2]
    } else {
        (sorted[n / 2 - 1] + sorted[n / 2]) / 2
    }
}

/// Compact count: 1234567 → "1.23M".
pub fn si(n: u64) -> String {
    let x = n as f64;
    if x >= 1e9 {
        format!("{:.2}G", x / 1e9)
    } else if x >= 1e6 {
        format!("{:.2}M", x / 1e6)
    } else if x >= 1e4 {
        format!("{:.1}k", x / 1e3)
    } else {
        n.to_string()
    }
}
