use super::{CliError, CompareArgs};
use crate::render::Film;
use crate::render::compare::{compare as compare_films, diff_image};
use crate::render::output::{FileKind, read_film, write_rgb8};

/// Refuses an image with NaN or infinite pixels: no difference to it means
/// anything (exit 2, with how many and where the first is).
fn finite(film: &Film, path: &std::path::Path) -> Result<(), CliError> {
    match film.non_finite() {
        None => Ok(()),
        Some((count, (x, y))) => Err(CliError::input(format!(
            "{}: {count} pixels are NaN or infinite, the first at ({x}, {y}): cannot compare",
            path.display()
        ))),
    }
}

/// `penumbra compare`.
pub fn compare(args: &CompareArgs) -> Result<(), CliError> {
    super::safety::remove_temp_files_on_signals();
    if let Some(path) = &args.diff {
        // The difference image is a PNG; anything else is bad input, as for
        // `render -o`.
        if !matches!(FileKind::of(path), Ok(FileKind::Png)) {
            return Err(CliError::input(format!(
                "{}: the difference image is a PNG (expected .png)",
                path.display()
            )));
        }
        super::safety::refuse_missing_folder(path, "difference image")?;
        super::safety::refuse_overwriting_inputs(
            path,
            "difference image",
            &[("first image", &args.a), ("second image", &args.b)],
        )?;
    }
    let a = read_film(&args.a).map_err(CliError::input)?;
    let b = read_film(&args.b).map_err(CliError::input)?;
    finite(&a, &args.a)?;
    finite(&b, &args.b)?;
    let c = compare_films(&a, &b).map_err(CliError::input)?;
    let mut report = format!(
        "rmse {:.6e}\npsnr {:.2} dB\nmax_diff {:.6e} at pixel ({}, {})\n",
        c.rmse, c.psnr, c.max_diff, c.max_at.0, c.max_at.1
    );
    if let Some(path) = &args.diff {
        let (rgb, scale) = diff_image(&a, &b, None).map_err(CliError::input)?;
        write_rgb8(path, a.width, a.height, &rgb).map_err(CliError::other)?;
        report += &format!(
            "diff {} (black = equal, white = {:.3e})\n",
            path.display(),
            scale
        );
    }
    super::print_stdout(&report)
}
