use super::{CliError, CompareArgs};
use crate::render::compare::{compare as compare_films, diff_image};
use crate::render::output::{read_film, write_rgb8};

/// `penumbra compare`.
pub fn compare(args: &CompareArgs) -> Result<(), CliError> {
    let a = read_film(&args.a).map_err(CliError::input)?;
    let b = read_film(&args.b).map_err(CliError::input)?;
    let c = compare_films(&a, &b).map_err(CliError::input)?;
    println!("rmse {:.6e}", c.rmse);
    println!("psnr {:.2} dB", c.psnr);
    println!(
        "max_diff {:.6e} at pixel ({}, {})",
        c.max_diff, c.max_at.0, c.max_at.1
    );
    if let Some(path) = &args.diff {
        let (rgb, scale) = diff_image(&a, &b, None).map_err(CliError::input)?;
        write_rgb8(path, a.width, a.height, &rgb).map_err(CliError::other)?;
        println!(
            "diff {} (black = equal, white = {:.3e})",
            path.display(),
            scale
        );
    }
    Ok(())
}
