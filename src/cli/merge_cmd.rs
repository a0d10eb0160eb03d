//! `penumbra merge`: the parts of `render --region` stitched into the whole
//! image.

use super::{CliError, MergeArgs};
use crate::render::CancelToken;
use crate::render::ImageError;
use crate::render::output::{FileKind, write_film};
use crate::render::region::{merge as merge_parts, read_part};

/// What an interrupted merge says, as an interrupted render does.
const INTERRUPTED: &str = "interrupted: no image written";

/// `penumbra merge`.
pub fn merge(args: &MergeArgs) -> Result<(), CliError> {
    super::safety::end_on_signals(INTERRUPTED);
    FileKind::of(&args.output).map_err(CliError::input)?;
    super::safety::refuse_missing_folder(&args.output, "output")?;
    super::safety::refuse_read_only(&args.output, "output")?;
    let inputs: Vec<(&str, &std::path::Path)> =
        args.parts.iter().map(|p| ("part", p.as_path())).collect();
    super::safety::refuse_overwriting_inputs(&args.output, "output", &inputs)?;
    let mut parts = Vec::with_capacity(args.parts.len());
    for path in &args.parts {
        let part = read_part(path).map_err(CliError::input)?;
        if let Some((count, (x, y))) = part.film.non_finite() {
            return Err(CliError::input(format!(
                "{}: {count} pixels are NaN or infinite, the first at ({x}, {y}) of the part",
                path.display()
            )));
        }
        parts.push((path.clone(), part));
    }
    let film = merge_parts(&parts).map_err(CliError::input)?;
    let count = parts.len();
    // The parts' memory goes to the write (a PNG's codes).
    drop(parts);
    // The write is stopped as render's is: it fails, the target untouched.
    super::safety::handle_signals(&CancelToken::new());
    write_film(&film, &args.output).map_err(|e| match e {
        ImageError::Memory { .. } => CliError::input(e),
        e => super::safety::write_failure(e, INTERRUPTED),
    })?;
    super::print_stderr(format_args!(
        "{}×{} from {count} parts",
        film.width, film.height
    ));
    Ok(())
}
