use super::{CliError, CompareArgs};
use crate::render::compare::{compare as compare_films, diff_image};
use crate::render::output::{read_film, write_rgb8};

/// `penumbra compare`.
pub fn compare(args: &CompareArgs) -> Result<(), CliError> {
    let a = read_film(&args.a).map_err(CliError::input)?;
    let b = read_film(&args.b).map_err(CliError::input)?;
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
