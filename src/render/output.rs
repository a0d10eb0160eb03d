//! Reading and writing images. Writes are atomic: the data goes to a
//! temporary file beside the target, which is renamed over it only once
//! complete, so a failed or interrupted write never leaves a partial file
//! and never touches an existing one.

use std::io::{BufWriter, Write};
use std::path::Path;

use glam::Vec3;
use image::{ImageFormat, ImageReader};

use super::error::ImageError;
use super::film::{Film, decode_channel};

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FileKind {
    /// sRGB-encoded 8-bit PNG.
    Png,
    /// Linear f32 OpenEXR.
    Exr,
}

impl FileKind {
    pub fn of(path: &Path) -> Result<FileKind, ImageError> {
        match path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .as_deref()
        {
            Some("png") => Ok(FileKind::Png),
            Some("exr") => Ok(FileKind::Exr),
            _ => Err(ImageError::Format {
                path: path.to_owned(),
            }),
        }
    }
}

/// Writes `path` atomically with the bytes `write` produces.
pub fn write_atomic(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<std::fs::File>) -> Result<(), String>,
) -> Result<(), ImageError> {
    let fail = |message: String| ImageError::Write {
        path: path.to_owned(),
        message,
    };
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let mut builder = tempfile::Builder::new();
    builder.prefix(".penumbra-").suffix(".part");
    // The new file keeps an existing file's permissions, or gets the usual
    // rw-r--r-- (tempfile's own default is owner-only).
    #[cfg(unix)]
    builder.permissions(
        std::fs::metadata(path)
            .map(|m| m.permissions())
            .unwrap_or_else(|_| {
                use std::os::unix::fs::PermissionsExt;
                std::fs::Permissions::from_mode(0o644)
            }),
    );
    let tmp = builder
        .tempfile_in(dir)
        .map_err(|e| fail(format!("cannot create a file in {}: {e}", dir.display())))?;
    let mut out = BufWriter::new(tmp.reopen().map_err(|e| fail(e.to_string()))?);
    write(&mut out).map_err(&fail)?;
    out.flush().map_err(|e| fail(e.to_string()))?;
    drop(out);
    tmp.persist(path).map_err(|e| fail(e.error.to_string()))?;
    Ok(())
}

/// Writes a film as PNG (sRGB 8-bit) or EXR (linear f32), by extension.
pub fn write_film(film: &Film, path: &Path) -> Result<(), ImageError> {
    match FileKind::of(path)? {
        FileKind::Png => write_rgb8(path, film.width, film.height, &film.to_srgb8()),
        FileKind::Exr => {
            let data: Vec<f32> = film.pixels.iter().flat_map(|p| p.to_array()).collect();
            let img = image::Rgb32FImage::from_raw(film.width, film.height, data)
                .expect("buffer matches size");
            write_atomic(path, |w| {
                img.write_to(w, ImageFormat::OpenExr)
                    .map_err(|e| e.to_string())
            })
        }
    }
}

/// Writes 8-bit sRGB RGB data as a PNG.
pub fn write_rgb8(path: &Path, width: u32, height: u32, rgb: &[u8]) -> Result<(), ImageError> {
    if FileKind::of(path)? != FileKind::Png {
        return Err(ImageError::Format {
            path: path.to_owned(),
        });
    }
    let img = image::RgbImage::from_raw(width, height, rgb.to_vec()).expect("buffer matches size");
    write_atomic(path, |w| {
        img.write_to(w, ImageFormat::Png).map_err(|e| e.to_string())
    })
}

/// Reads a PNG (decoded from sRGB to linear) or EXR (linear) image.
pub fn read_film(path: &Path) -> Result<Film, ImageError> {
    let kind = FileKind::of(path)?;
    let fail = |message: String| ImageError::Read {
        path: path.to_owned(),
        message,
    };
    let img = ImageReader::open(path)
        .map_err(|e| fail(e.to_string()))?
        .with_guessed_format()
        .map_err(|e| fail(e.to_string()))?
        .decode()
        .map_err(|e| fail(e.to_string()))?;
    let (width, height) = (img.width(), img.height());
    let pixels = match kind {
        FileKind::Png => img
            .into_rgb8()
            .pixels()
            .map(|p| {
                Vec3::new(
                    decode_channel(p[0]),
                    decode_channel(p[1]),
                    decode_channel(p[2]),
                )
            })
            .collect(),
        FileKind::Exr => img
            .into_rgb32f()
            .pixels()
            .map(|p| Vec3::new(p[0], p[1], p[2]))
            .collect(),
    };
    Ok(Film {
        width,
        height,
        pixels,
    })
}
