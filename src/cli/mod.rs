//! The command-line front end: argument types and the commands. Each
//! command returns a [`CliError`] whose exit code tells bad input (2) from
//! other failures (1).
//!
//! Every numeric option takes negative numbers as values
//! (`allow_negative_numbers`; the lists `--terms`, `--translate`,
//! `--region` and bench's `--counts`, `--spheres` and `--meshes` take any
//! value that begins with `-`, `-1,0,0` being no number): `--width -5`
//! then reaches the option's own range check, whose message names the
//! option and its range, where clap would have called `-5` an unexpected
//! argument. `--width --height 5` still says that `--width` wants a value,
//! and so does `--region --width 5` ([`ListValue`]).

pub mod bench;
mod compare_cmd;
mod merge_cmd;
pub mod out_of_memory;
mod render_cmd;
pub mod safety;

use std::ffi::OsStr;
use std::path::PathBuf;

use clap::builder::TypedValueParser;
use clap::error::{ContextKind, ContextValue, ErrorKind};
use clap::{Args, Parser, Subcommand};

pub use bench::{BenchArgs, bench};
pub use compare_cmd::compare;
pub use merge_cmd::merge;
pub use render_cmd::{load_desc, load_scene, render};

use crate::render::output::INTERRUPTED_MESSAGE;
use crate::render::{AreaLightModel, CancelToken, FilterKind, Sampling, TileRect};

#[derive(Debug, Parser)]
#[command(
    name = "penumbra",
    version,
    about = "Phong ray tracer with a rectangular area light: viewer and CLI"
)]
#[command(args_conflicts_with_subcommands = true)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Option<Command>,
    /// Without a command: the viewer's options (`penumbra --log-timings`,
    /// `penumbra scene.json`), as for `penumbra view`.
    #[command(flatten)]
    pub view: ViewArgs,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Open the interactive viewer (the default).
    View(ViewArgs),
    /// Render a scene to a PNG or EXR file.
    Render(RenderArgs),
    /// Compare two images (PNG or EXR): RMSE, PSNR, largest difference.
    Compare(CompareArgs),
    /// Stitch the parts of `render --region` into the whole image.
    Merge(MergeArgs),
    /// Run time against error: sweep sampling patterns, shadow-ray counts
    /// and area-light models against a converged reference.
    Bench(BenchArgs),
    /// Write a generated mesh for scale tests: a bumpy torus of N
    /// triangles, as OBJ.
    Generate(GenerateArgs),
}

#[derive(Debug, Args, Default)]
pub struct ViewArgs {
    /// Scene file (JSON); the built-in seed room if omitted.
    pub scene: Option<PathBuf>,
    /// Log UI frame times and render latencies to stderr.
    #[arg(long)]
    pub log_timings: bool,
    /// Neither read nor write the remembered window, last scene, recent
    /// files and view settings (for tests and scripts).
    #[arg(long)]
    pub no_persist: bool,
    /// Change the ambient slider by itself every SECS seconds (six times),
    /// to measure `--log-timings` without a person at the mouse.
    #[arg(long, allow_negative_numbers = true, value_name = "SECS", hide = true)]
    pub wiggle: Option<f64>,
    /// Once the requested quality is reached and nothing changes, refine
    /// the image with more camera samples per pixel up to this many (1:
    /// never; default 16).
    #[arg(long, allow_negative_numbers = true, value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub refine_spp: Option<u32>,
}

/// Overrides of a scene's settings.
#[derive(Debug, Args, Default, Clone)]
pub struct SceneOverrides {
    /// Image width in pixels (alone: the height follows at the scene's
    /// aspect ratio).
    #[arg(long, allow_negative_numbers = true, value_parser = clap::value_parser!(u32).range(1..=16384))]
    pub width: Option<u32>,
    /// Image height in pixels (alone: the width follows at the scene's
    /// aspect ratio).
    #[arg(long, allow_negative_numbers = true, value_parser = clap::value_parser!(u32).range(1..=16384))]
    pub height: Option<u32>,
    /// Shadow rays per hit point.
    #[arg(long, allow_negative_numbers = true, value_parser = clap::value_parser!(u32).range(1..=4096))]
    pub shadow_rays: Option<u32>,
    /// Placement of shadow-ray points on the light.
    #[arg(long, value_enum)]
    pub sampling: Option<SamplingArg>,
    /// Most surface hits along one camera path (1 = no reflections).
    #[arg(long, allow_negative_numbers = true, value_parser = clap::value_parser!(u32).range(1..=16))]
    pub depth: Option<u32>,
    /// Area-light model.
    #[arg(long, value_enum)]
    pub model: Option<ModelArg>,
    /// Random seed.
    #[arg(long, allow_negative_numbers = true, value_parser = parse_seed)]
    pub seed: Option<u64>,
    /// Multipliers of the ambient, diffuse and specular terms, e.g. 1,0,0.
    #[arg(long, allow_hyphen_values = true, value_parser = ListValue(parse_terms))]
    pub terms: Option<[f64; 3]>,
    /// Adaptive shadow rays: a few first, the rest only where they disagree
    /// (faster, biased).
    #[arg(long)]
    pub adaptive: bool,
    /// Cut-away: camera rays pass through planes seen from behind (as the
    /// viewer's "Cut-away" does; shadows and reflections unchanged).
    #[arg(long)]
    pub cutaway: bool,
    /// Multiply every coordinate and length of the scene (camera included)
    /// by this factor: the same image to within rounding (RMSE below 1e-7
    /// but for small images, and lights lying in a surface's plane: see the
    /// README's "Guarantees and limits"), not always bit for bit.
    #[arg(long, allow_negative_numbers = true, value_parser = parse_scale)]
    pub scale: Option<f64>,
    /// Move the whole scene (camera included) by x,y,z: the same image to
    /// within rounding, as --scale, not always bit for bit.
    #[arg(long, allow_hyphen_values = true, value_parser = ListValue(parse_vec3))]
    pub translate: Option<[f64; 3]>,
    /// Camera samples per pixel (anti-aliasing; `render.samples_per_pixel`).
    #[arg(long, allow_negative_numbers = true, value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub spp: Option<u32>,
    /// Reconstruction filter of several samples per pixel (default
    /// blackman-harris).
    #[arg(long, value_enum)]
    pub filter: Option<FilterArg>,
    /// Width of the Blackman–Harris filter in pixels (default 1.5).
    #[arg(long, allow_negative_numbers = true, value_parser = parse_filter_width)]
    pub filter_width: Option<f32>,
}

impl SceneOverrides {
    /// The filter these options ask for, if they name one. A width with
    /// `--filter box` is refused (exit 2) rather than dropped: the box has
    /// no width, and an image that quietly ignores an option passes for
    /// one made with it.
    pub fn filter(&self) -> Result<Option<FilterKind>, CliError> {
        match (self.filter, self.filter_width) {
            (None, None) => Ok(None),
            (Some(FilterArg::Box), Some(w)) => Err(CliError::input(format!(
                "--filter-width {w} sets the width of the Blackman–Harris filter; \
                 --filter box has none: give one of the two"
            ))),
            (Some(FilterArg::Box), None) => Ok(Some(FilterKind::Box)),
            (_, w) => Ok(Some(FilterKind::BlackmanHarris {
                width: w.unwrap_or(FilterKind::DEFAULT.width()),
            })),
        }
    }
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum FilterArg {
    Box,
    BlackmanHarris,
}

fn parse_filter_width(s: &str) -> Result<f32, String> {
    let w: f32 = s.parse().map_err(|_| format!("{s:?} is not a number"))?;
    if (0.5..=8.0).contains(&w) {
        Ok(w)
    } else {
        // The text as typed: the f32 it parses to may be 0 or inf.
        Err(format!("{s} is out of range, expected 0.5..=8 pixels"))
    }
}

#[derive(Debug, Args)]
pub struct RenderArgs {
    /// Scene file (JSON); the built-in seed room if omitted.
    pub scene: Option<PathBuf>,
    /// Output image: .png (sRGB 8-bit) or .exr (linear f32).
    #[arg(short, long)]
    pub output: PathBuf,
    #[command(flatten)]
    pub overrides: SceneOverrides,
    /// Worker threads (default: all cores).
    #[arg(long, allow_negative_numbers = true, value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub threads: Option<u32>,
    /// Trace every shadow ray, skipping nothing (to measure what skipping
    /// saves; the image is the same).
    #[arg(long)]
    pub no_skip: bool,
    /// Render progressively (preview and intermediate passes), as the
    /// viewer does; the image is the same.
    #[arg(long)]
    pub progressive: bool,
    /// Render only the crop window X,Y,W,H (pixels from the top-left) into
    /// an EXR that records its place in the whole image; `penumbra merge`
    /// stitches such parts into the image a whole render gives.
    #[arg(long, allow_hyphen_values = true, value_name = "X,Y,W,H", value_parser = ListValue(parse_region), conflicts_with = "progressive")]
    pub region: Option<TileRect>,
    /// Also write the render's times and every ray count to FILE as JSON,
    /// for scripts (`-`: standard output). Of the line on standard error,
    /// only the first part, `W×H in R s: C camera, …`, stays fixed.
    #[arg(long, value_name = "FILE")]
    pub stats: Option<PathBuf>,
}

/// `penumbra merge`'s arguments.
#[derive(Debug, Args)]
pub struct MergeArgs {
    /// Parts written by `penumbra render --region`.
    #[arg(required = true)]
    pub parts: Vec<PathBuf>,
    /// The whole image: .png (sRGB 8-bit) or .exr (linear f32).
    #[arg(short, long)]
    pub output: PathBuf,
}

fn parse_region(s: &str) -> Result<TileRect, String> {
    crate::render::region::parse_region(s)
}

#[derive(Debug, Args)]
pub struct GenerateArgs {
    /// About this many triangles (the torus has 2 · around · across).
    #[arg(long, allow_negative_numbers = true, default_value_t = 1_000_000, value_parser = clap::value_parser!(u32).range(18..=20_000_000))]
    pub triangles: u32,
    /// The OBJ file to write.
    #[arg(short, long)]
    pub output: PathBuf,
}

/// `penumbra generate`.
pub fn generate(args: &GenerateArgs) -> Result<(), CliError> {
    // What it writes is OBJ text: under another name a scene would read it
    // as that format and fail.
    let obj = args
        .output
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("obj"));
    if !obj {
        return Err(CliError::input(format!(
            "{}: generate writes Wavefront OBJ (expected .obj)",
            args.output.display()
        )));
    }
    safety::refuse_missing_folder(&args.output, "output")?;
    safety::refuse_read_only(&args.output, "output")?;
    // SIGINT, SIGTERM and SIGHUP stop the write as they stop render's: no
    // file is written and an existing one is untouched.
    safety::handle_signals(&CancelToken::new());
    let n = crate::render::generate_mesh::write_torus_obj(&args.output, args.triangles as usize)
        .map_err(|e| safety::write_failure(e, INTERRUPTED_MESSAGE))?;
    print_stdout(&format!(
        "{}: a torus of {n} triangles\n",
        args.output.display()
    ))
}

#[derive(Debug, Args)]
pub struct CompareArgs {
    pub a: PathBuf,
    pub b: PathBuf,
    /// Write a false-colour difference image (PNG).
    #[arg(long)]
    pub diff: Option<PathBuf>,
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum SamplingArg {
    Grid,
    Random,
    Mixed,
    Stratified,
    Sobol,
    #[value(alias = "rotated_grid")]
    RotatedGrid,
}

impl From<SamplingArg> for Sampling {
    fn from(s: SamplingArg) -> Sampling {
        match s {
            SamplingArg::Grid => Sampling::Grid,
            SamplingArg::Random => Sampling::Random,
            SamplingArg::Mixed => Sampling::Mixed,
            SamplingArg::Stratified => Sampling::Stratified,
            SamplingArg::Sobol => Sampling::Sobol,
            SamplingArg::RotatedGrid => Sampling::RotatedGrid,
        }
    }
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum ModelArg {
    Sampled,
    #[value(alias = "nearest_point")]
    NearestPoint,
    Analytic,
    Exact,
}

impl From<ModelArg> for AreaLightModel {
    fn from(m: ModelArg) -> AreaLightModel {
        match m {
            ModelArg::Sampled => AreaLightModel::Sampled,
            ModelArg::NearestPoint => AreaLightModel::NearestPoint,
            ModelArg::Analytic => AreaLightModel::Analytic,
            ModelArg::Exact => AreaLightModel::Exact,
        }
    }
}

/// The value parser of a list option that takes values beginning with `-`
/// (`allow_hyphen_values`, so that `--region -1,0,10,10` reaches the range
/// check): a value that looks like a long option, `--` and a letter, and
/// came as the next argument is the next option, not this one's value
/// (`--region --width 5`), and is refused as clap refuses `--width
/// --height 5`: a value is required for `--region`. Anything else, given
/// values that look like options too (`--region=--width`, `--meshes
/// 18,--quick`), goes to the list's own parser `P`, which says what is
/// wrong with it.
#[derive(Clone)]
pub struct ListValue<P>(pub P);

impl<P: TypedValueParser> TypedValueParser for ListValue<P> {
    type Value = P::Value;

    fn parse_ref(
        &self,
        cmd: &clap::Command,
        arg: Option<&clap::Arg>,
        value: &OsStr,
    ) -> Result<P::Value, clap::Error> {
        let long = arg.and_then(clap::Arg::get_long);
        if !is_long_option(value) || !long.is_some_and(|l| is_next_argument(l, value)) {
            return self.0.parse_ref(cmd, arg, value);
        }
        // clap's own error for an option without a value: an empty
        // InvalidValue, "a value is required for '--region <X,Y,W,H>' but
        // none was supplied".
        let mut e = clap::Error::new(ErrorKind::InvalidValue).with_cmd(cmd);
        let name = arg.map_or_else(|| "...".to_owned(), |a| a.to_string());
        e.insert(ContextKind::InvalidArg, ContextValue::String(name));
        e.insert(
            ContextKind::InvalidValue,
            ContextValue::String(String::new()),
        );
        Err(e)
    }
}

/// Whether `value` came on the command line as the argument after the
/// option `--long`, on its own (`--region --width`): the next option, not
/// a value. Given with `=` (`--region=--width`) or inside a list
/// (`--meshes 18,--quick`) it is a value, and a bad one. clap does not
/// tell a value parser how the value came; the command line it parses
/// does.
fn is_next_argument(long: &str, value: &OsStr) -> bool {
    let option = format!("--{long}");
    let args: Vec<std::ffi::OsString> = std::env::args_os().collect();
    args.windows(2)
        .any(|w| w[0] == option.as_str() && w[1] == value)
}

/// Whether `value` looks like a long option's name: `--` and a letter.
fn is_long_option(value: &OsStr) -> bool {
    matches!(value.as_encoded_bytes(), [b'-', b'-', c, ..] if c.is_ascii_alphabetic())
}

/// Three comma-separated finite numbers (`names` says which), each at
/// least `min`.
fn parse_triple(s: &str, names: &str, min: f64) -> Result<[f64; 3], String> {
    let parts: Vec<&str> = s.split(',').collect();
    if parts.len() != 3 {
        return Err(format!("expected three comma-separated numbers: {names}"));
    }
    let mut out = [0.0; 3];
    for (o, p) in out.iter_mut().zip(parts) {
        let v: f64 = p
            .trim()
            .parse()
            .map_err(|_| format!("{p:?} is not a number"))?;
        if !(v.is_finite() && v >= min) {
            let bound = if min > f64::MIN {
                format!(" >= {min}")
            } else {
                String::new()
            };
            return Err(format!(
                "{p} is out of range, expected a finite number{bound}"
            ));
        }
        *o = v;
    }
    Ok(out)
}

fn parse_vec3(s: &str) -> Result<[f64; 3], String> {
    parse_triple(s, "x,y,z", f64::MIN)
}

fn parse_terms(s: &str) -> Result<[f64; 3], String> {
    parse_triple(s, "ambient,diffuse,specular", 0.0)
}

/// A seed: any u64. A whole number outside that range (`-1`) is refused
/// in the words of the other numeric options' range check (`-5 is not in
/// 1..=16384`), where clap's u64 parser said "invalid digit found in
/// string"; anything else as clap says it.
fn parse_seed(s: &str) -> Result<u64, String> {
    if let Some(seed) = s.parse::<i128>().ok().and_then(|n| u64::try_from(n).ok()) {
        return Ok(seed);
    }
    let digits = s.strip_prefix(['-', '+']).unwrap_or(s);
    if !digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit()) {
        return Err(format!("{s} is not in 0..={}", u64::MAX));
    }
    s.parse::<u64>().map_err(|e| e.to_string())
}

fn parse_scale(s: &str) -> Result<f64, String> {
    let v: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("{s:?} is not a number"))?;
    if !(v.is_finite() && v > 0.0) {
        return Err(format!("{s} is out of range, expected a number > 0"));
    }
    Ok(v)
}

/// A failed command: the message for stderr and the exit code.
#[derive(Debug)]
pub struct CliError {
    pub code: i32,
    pub message: String,
}

impl CliError {
    /// Bad input (scene, arguments, image sizes): exit code 2.
    pub fn input(message: impl ToString) -> CliError {
        CliError {
            code: 2,
            message: message.to_string(),
        }
    }
    /// Anything else (I/O, interrupted): exit code 1.
    pub fn other(message: impl ToString) -> CliError {
        CliError {
            code: 1,
            message: message.to_string(),
        }
    }
}

/// A side that followed the other's option (`--width` or `--height`
/// alone) at the scene's aspect ratio is named as such where it is out of
/// range: the file never said it.
pub fn name_followed_side(
    e: &mut crate::render::SceneError,
    width: Option<u32>,
    height: Option<u32>,
) {
    let followed = match (width, height) {
        (Some(w), None) => Some(("height", "--width", w, "--height")),
        (None, Some(h)) => Some(("width", "--height", h, "--width")),
        _ => None,
    };
    if let Some((side, option, value, other)) = followed
        && e.path == format!("camera.{side}")
    {
        e.message += &format!(
            " (the {side} that {option} {value} gives at the scene's aspect ratio; give {other} too)"
        );
    }
}

/// Writes a line to stderr, ignoring a failed write (`2>/dev/full`, a
/// closed pipe): `eprintln!` would panic with exit 101, and a message no
/// one can read should not change the command's exit code.
pub fn print_stderr(line: impl std::fmt::Display) {
    use std::io::Write;
    let _ = writeln!(std::io::stderr().lock(), "{line}");
}

/// Prints to stdout; a closed pipe (`penumbra compare … | head -1`) is not
/// an error worth a panic or a message.
pub fn print_stdout(text: &str) -> Result<(), CliError> {
    use std::io::Write;
    match std::io::stdout().lock().write_all(text.as_bytes()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => {
            Err(CliError::other(format!("stdout: {e}")))
        }
        _ => Ok(()),
    }
}
