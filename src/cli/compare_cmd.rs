use super::{CliError, CompareArgs};
use crate::render::CancelToken;
use crate::render::Film;
use crate::render::TileRect;
use crate::render::compare::{SizeMismatch, compare as compare_films, diff_image};
use crate::render::memory::{amount, check_image_memory};
use crate::render::output::{FileKind, read_film, write_rgb8};
use crate::render::region::{Part, read_if_part};

/// What `compare --diff` says when interrupted, as an interrupted render
/// does.
const INTERRUPTED_BEFORE_DIFF: &str = "interrupted: no difference image written";

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
    let interrupted = if args.diff.is_some() {
        INTERRUPTED_BEFORE_DIFF
    } else {
        "interrupted"
    };
    super::safety::end_on_signals(interrupted);
    if let Some(path) = &args.diff {
        // The difference image is a PNG, chosen by the name: anything else
        // is bad input, as for `render -o`.
        if !matches!(FileKind::of(path), Ok(FileKind::Png)) {
            return Err(CliError::input(format!(
                "{}: --diff writes a PNG: the name must end in .png",
                path.display()
            )));
        }
        super::safety::refuse_missing_folder(path, "difference image")?;
        super::safety::refuse_read_only(path, "difference image")?;
        super::safety::refuse_overwriting_inputs(
            path,
            "difference image",
            &[("first image", &args.a), ("second image", &args.b)],
        )?;
    }
    let (a, b, region) = read_pair(&args.a, &args.b)?;
    finite(&a, &args.a)?;
    finite(&b, &args.b)?;
    let c = compare_films(&a, &b).map_err(|SizeMismatch(aw, ah, bw, bh)| {
        CliError::input(format!(
            "image sizes differ: {} is {aw}×{ah}, {} is {bw}×{bh}",
            args.a.display(),
            args.b.display(),
        ))
    })?;
    // Pixels are named in the whole image's coordinates.
    let (x0, y0) = region.map_or((0, 0), |(r, _)| (r.x, r.y));
    let mut report = format!(
        "rmse {:.6e}\npsnr {:.2} dB\nmax_diff {:.6e} at pixel ({}, {})\n",
        c.rmse,
        c.psnr,
        c.max_diff,
        c.max_at.0 + x0,
        c.max_at.1 + y0
    );
    if let Some((r, (w, h))) = region {
        report += &format!(
            "region {},{},{},{} of the {w}×{h} image\n",
            r.x, r.y, r.w, r.h
        );
    }
    if let Some(path) = &args.diff {
        // The difference image's codes and the PNG encoder's buffer (3
        // bytes a pixel each), refused before they abort the process.
        check_image_memory(a.width, a.height, 6)
            .map_err(|e| CliError::input(format!("{}: {e}", path.display())))?;
        let (rgb, scale) = diff_image(&a, &b, None).map_err(CliError::input)?;
        // The write is stopped as render's is: it fails, the target
        // untouched.
        super::safety::handle_signals(&CancelToken::new());
        write_rgb8(path, a.width, a.height, &rgb)
            .map_err(|e| super::safety::write_failure(e, INTERRUPTED_BEFORE_DIFF))?;
        report += &format!(
            "diff {} (black = equal, white = {:.3e})\n",
            path.display(),
            scale
        );
    }
    super::print_stdout(&report)
}

/// The two images to compare. A region part (`render --region`) is
/// compared with the same region of a whole image of its full size, or
/// with a part of the same region: its pixels, not the whole image it
/// would sit in (which would count everything outside it as black).
/// Returns the region and the full size where parts were involved.
#[allow(clippy::type_complexity)]
fn read_pair(
    a_path: &std::path::Path,
    b_path: &std::path::Path,
) -> Result<(Film, Film, Option<(TileRect, (u32, u32))>), CliError> {
    // Any file that is no part is read as a whole image; one that says it
    // is a part but is broken, or too large for the memory left, is
    // refused as what it is.
    let part = |p: &std::path::Path| read_if_part(p).map_err(CliError::input);
    let whole = |p: &std::path::Path| read_film(p).map_err(CliError::input);
    let describe = |p: &Part| {
        let r = p.region;
        format!(
            "region {},{},{},{} of a {}×{} image",
            r.x, r.y, r.w, r.h, p.full.0, p.full.1
        )
    };
    match (part(a_path)?, part(b_path)?) {
        (None, None) => Ok((whole(a_path)?, whole(b_path)?, None)),
        (Some(a), Some(b)) => {
            if (a.region, a.full) != (b.region, b.full) {
                return Err(CliError::input(format!(
                    "{} is the {}, {} the {}: parts of different regions",
                    a_path.display(),
                    describe(&a),
                    b_path.display(),
                    describe(&b)
                )));
            }
            Ok((a.film, b.film, Some((a.region, a.full))))
        }
        (Some(p), None) => {
            let w = whole(b_path)?;
            let crop = crop_of(&w, &p, b_path, a_path, &describe)?;
            Ok((p.film, crop, Some((p.region, p.full))))
        }
        (None, Some(p)) => {
            let w = whole(a_path)?;
            let crop = crop_of(&w, &p, a_path, b_path, &describe)?;
            Ok((crop, p.film, Some((p.region, p.full))))
        }
    }
}

/// The pixels of `whole` under part `p`'s region, if `whole` has the
/// part's full size.
fn crop_of(
    whole: &Film,
    p: &Part,
    whole_path: &std::path::Path,
    part_path: &std::path::Path,
    describe: &dyn Fn(&Part) -> String,
) -> Result<Film, CliError> {
    if (whole.width, whole.height) != p.full {
        return Err(CliError::input(format!(
            "{} is the {}, but {} is {}×{}: compare a part with a whole image of its size, or merge the parts first",
            part_path.display(),
            describe(p),
            whole_path.display(),
            whole.width,
            whole.height
        )));
    }
    let r = p.region;
    // The crop's buffer may not fit beside the two images: refused, where
    // its allocation would abort.
    let mut pixels = Vec::new();
    crate::render::memory::probing(|| pixels.try_reserve_exact(r.w as usize * r.h as usize))
        .map_err(|_| {
            CliError::input(format!(
                "{}: {}×{} needs about {} to compare, more than this process can have",
                whole_path.display(),
                r.w,
                r.h,
                amount(r.w as usize * r.h as usize * 12)
            ))
        })?;
    pixels.resize(r.w as usize * r.h as usize, glam::Vec3::ZERO);
    let mut crop = Film {
        width: r.w,
        height: r.h,
        pixels,
    };
    for y in 0..r.h {
        for x in 0..r.w {
            crop.pixels[(y * r.w + x) as usize] = whole.get(r.x + x, r.y + y);
        }
    }
    Ok(crop)
}
