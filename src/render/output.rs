//! Reading and writing images. Writes are atomic: the data goes to a
//! temporary file beside the target, which is renamed over it only once
//! complete, so a failed or interrupted write never leaves a partial file
//! and never touches an existing one.

use std::io::{BufWriter, Cursor, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicPtr, Ordering};

use glam::Vec3;
use image::{ImageDecoder, ImageFormat, ImageReader};

use super::display::DisplayTransform;
use super::error::ImageError;
use super::film::{Film, decode_channel, encode_srgb8_each};
use super::progressive::TileRect;

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

/// Largest image file read (`compare`, the bench's cache, the viewer's
/// reference): an uncompressed 16384×16384 f32 RGB OpenEXR, the largest
/// image penumbra writes, and room for its headers. The limit holds before
/// anything is buffered, for pipes and devices too.
pub const MAX_IMAGE_BYTES: u64 = 16384 * 16384 * 12 + (1 << 20);

static INTERRUPTED: AtomicBool = AtomicBool::new(false);

/// Makes every atomic write in progress or to come fail (the CLI calls it
/// on SIGINT, SIGTERM and SIGHUP): its temporary file is removed and the
/// target left untouched.
pub fn interrupt_writes() {
    INTERRUPTED.store(true, Ordering::SeqCst);
}

/// Whether [`interrupt_writes`] was called.
pub fn writes_interrupted() -> bool {
    INTERRUPTED.load(Ordering::SeqCst)
}

/// The message of a write stopped by [`interrupt_writes`].
pub const INTERRUPTED_MESSAGE: &str = "interrupted: no file written";

/// Temporary files being written, as C strings, for
/// [`remove_temp_files`] to find from a signal handler. A slot's string
/// is never freed (a handler may be reading it): a few dozen bytes per
/// write.
static TEMP_FILES: [AtomicPtr<libc::c_char>; 16] =
    [const { AtomicPtr::new(std::ptr::null_mut()) }; 16];

/// A temporary file's entry in [`TEMP_FILES`], cleared when dropped.
struct Registered(Option<usize>);

impl Registered {
    fn new(path: &Path) -> Registered {
        use std::os::unix::ffi::OsStrExt;
        let Ok(c) = std::ffi::CString::new(path.as_os_str().as_bytes()) else {
            return Registered(None);
        };
        let ptr = c.into_raw();
        for (i, slot) in TEMP_FILES.iter().enumerate() {
            if slot
                .compare_exchange(
                    std::ptr::null_mut(),
                    ptr,
                    Ordering::SeqCst,
                    Ordering::SeqCst,
                )
                .is_ok()
            {
                return Registered(Some(i));
            }
        }
        // More writes at once than slots: this one is not cleaned up by a
        // fatal signal (the others are).
        drop(unsafe { std::ffi::CString::from_raw(ptr) });
        Registered(None)
    }
}

impl Drop for Registered {
    fn drop(&mut self) {
        if let Some(i) = self.0 {
            TEMP_FILES[i].store(std::ptr::null_mut(), Ordering::SeqCst);
        }
    }
}

/// Removes every temporary file being written. Async-signal-safe (atomic
/// loads and unlink(2) only): for a handler of a fatal signal, which then
/// lets the signal end the process.
pub fn remove_temp_files() {
    for slot in &TEMP_FILES {
        let p = slot.load(Ordering::SeqCst);
        if !p.is_null() {
            // SAFETY: a registered pointer is a NUL-terminated string that
            // is never freed.
            unsafe { libc::unlink(p) };
        }
    }
}

/// The file an atomic write writes to: fails every write once
/// [`interrupt_writes`] is called, and keeps the first error of the file
/// itself, so that a full disk is reported as such rather than in the
/// encoder's words.
pub struct AtomicFile {
    file: std::fs::File,
    first_error: Option<String>,
}

impl AtomicFile {
    fn check(&self) -> std::io::Result<()> {
        if writes_interrupted() {
            return Err(std::io::Error::other(INTERRUPTED_MESSAGE));
        }
        Ok(())
    }

    fn keep<T>(&mut self, r: std::io::Result<T>) -> std::io::Result<T> {
        if let Err(e) = &r
            && self.first_error.is_none()
        {
            self.first_error = Some(os_message(e));
        }
        r
    }
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.check()?;
        let r = self.file.write(buf);
        self.keep(r)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.check()?;
        let r = self.file.flush();
        self.keep(r)
    }
}

impl Seek for AtomicFile {
    fn seek(&mut self, pos: SeekFrom) -> std::io::Result<u64> {
        self.check()?;
        let r = self.file.seek(pos);
        self.keep(r)
    }
}

/// An I/O error's own words, without the path some wrappers (tempfile)
/// add: the temporary file's name is no business of the user's.
fn os_message(e: &std::io::Error) -> String {
    let mut source: Option<&(dyn std::error::Error + 'static)> = Some(e);
    while let Some(s) = source {
        if let Some(io) = s.downcast_ref::<std::io::Error>()
            && let Some(code) = io.raw_os_error()
        {
            return std::io::Error::from_raw_os_error(code).to_string();
        }
        source = s.source();
    }
    if e.get_ref()
        .is_some_and(|inner| inner.to_string() == INTERRUPTED_MESSAGE)
    {
        return INTERRUPTED_MESSAGE.into();
    }
    e.kind().to_string()
}

/// Writes `path` atomically with the bytes `write` produces. A symbolic
/// link is written through (the file it leads to is replaced, the link
/// stays); an existing file that is not a regular one (a FIFO,
/// `/dev/stdout`) is written in place, which a rename would replace.
pub fn write_atomic(
    user_path: &Path,
    write: impl FnOnce(&mut BufWriter<AtomicFile>) -> Result<(), String>,
) -> Result<(), ImageError> {
    let fail = |message: String| ImageError::Write {
        path: user_path.to_owned(),
        message,
    };
    if std::fs::metadata(user_path).is_ok_and(|m| !m.is_file() && !m.is_dir()) {
        return write_in_place(user_path, write).map_err(fail);
    }
    let path = &through_links(user_path).ok_or_else(|| fail(LINK_LOOPS.into()))?;
    // A rename would replace it, permissions or not.
    if is_read_only(path) {
        return Err(fail(READ_ONLY.into()));
    }
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    match std::fs::metadata(dir) {
        Ok(m) if m.is_dir() => {}
        Ok(_) => return Err(fail(format!("{} is not a folder", dir.display()))),
        Err(e) => {
            return Err(fail(format!(
                "cannot write into the folder {}: {}",
                dir.display(),
                os_message(&e)
            )));
        }
    }
    if writes_interrupted() {
        return Err(fail(INTERRUPTED_MESSAGE.into()));
    }
    let mut builder = tempfile::Builder::new();
    builder.prefix(".penumbra-").suffix(".part");
    // The new file keeps an existing file's permissions, or gets the usual
    // rw-r--r-- (tempfile's own default is owner-only).
    let permissions = std::fs::metadata(path)
        .map(|m| m.permissions())
        .unwrap_or_else(|_| {
            use std::os::unix::fs::PermissionsExt;
            std::fs::Permissions::from_mode(0o644)
        });
    // The name is registered for the signal handlers before the file
    // exists: a signal between the two would otherwise leave the file.
    let mut registered = None;
    let tmp = builder
        .make_in(dir, |p| {
            registered = Some(Registered::new(p));
            let file = std::fs::OpenOptions::new()
                .read(true)
                .write(true)
                .create_new(true)
                .open(p)?;
            file.set_permissions(permissions.clone())?;
            Ok(file)
        })
        .map_err(|e| {
            fail(format!(
                "cannot create a file in {}: {}",
                dir.display(),
                os_message(&e)
            ))
        })?;
    let file = tmp.reopen().map_err(|e| fail(os_message(&e)))?;
    write_into(file, write).map_err(fail)?;
    if writes_interrupted() {
        return Err(fail(INTERRUPTED_MESSAGE.into()));
    }
    put_in_place(tmp, path).map_err(|e| fail(os_message(&e)))?;
    drop(registered);
    Ok(())
}

/// Runs `write` into `file` through a buffer, flushed; returns the file.
/// On failure, the file's own error (a full disk) says more than the
/// encoder's account of it, and an interruption says it all.
fn write_into(
    file: std::fs::File,
    write: impl FnOnce(&mut BufWriter<AtomicFile>) -> Result<(), String>,
) -> Result<std::fs::File, String> {
    let mut out = BufWriter::new(AtomicFile {
        file,
        first_error: None,
    });
    let written = write(&mut out).and_then(|()| out.flush().map_err(|e| os_message(&e)));
    let inner = match out.into_inner() {
        Ok(f) => f,
        Err(e) => e.into_parts().1.into_parts().0,
    };
    match written {
        Ok(()) => Ok(inner.file),
        Err(_) if writes_interrupted() => Err(INTERRUPTED_MESSAGE.into()),
        Err(message) => Err(inner.first_error.unwrap_or(message)),
    }
}

/// Why an existing read-only file is not written.
pub const READ_ONLY: &str = "a read-only file: not replaced (make it writable to allow it)";

/// Whether `path` (through links) is an existing regular file that is
/// read-only: no write permission bit is set, or the user may not write
/// it. The bits are checked themselves: root may write any file, and a
/// rename replaces one whatever its permissions, but a file made
/// read-only is meant to stay as it is.
pub fn is_read_only(path: &Path) -> bool {
    use std::os::unix::ffi::OsStrExt;
    use std::os::unix::fs::PermissionsExt;
    let Ok(meta) = std::fs::metadata(path) else {
        return false;
    };
    if !meta.is_file() {
        return false;
    }
    if meta.permissions().mode() & 0o222 == 0 {
        return true;
    }
    let Ok(c) = std::ffi::CString::new(path.as_os_str().as_bytes()) else {
        return false;
    };
    // SAFETY: access(2) on a NUL-terminated path that lives across the call.
    unsafe { libc::access(c.as_ptr(), libc::W_OK) != 0 }
}

/// Why a path whose chain of symbolic links never ends is not written.
pub const LINK_LOOPS: &str = "a symbolic link that loops (or a chain of more than 40 links)";

/// Where a write to `path` lands: the file a chain of symbolic links
/// leads to (the last link's target, which may not exist yet), else
/// `path` itself; `None` for a chain longer than the kernel's own limit
/// (a loop), which a rename would otherwise replace with a file.
pub fn through_links(path: &Path) -> Option<PathBuf> {
    let mut p = path.to_path_buf();
    for _ in 0..=40 {
        match std::fs::read_link(&p) {
            // Relative to the link's folder (an absolute target replaces it).
            Ok(target) => p = p.parent().unwrap_or(Path::new("")).join(target),
            Err(_) => return Some(p),
        }
    }
    None
}

/// [`write_atomic`] into an existing file that is not a regular one, in
/// place. The bytes are made in an unnamed temporary file first and then
/// copied: an EXR's encoder goes back to fill in its offset table, which a
/// pipe cannot do (a reader got a broken file), and a failed encoding
/// sends nothing.
fn write_in_place(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<AtomicFile>) -> Result<(), String>,
) -> Result<(), String> {
    let spill = tempfile::tempfile()
        .map_err(|e| format!("cannot make a temporary file: {}", os_message(&e)))?;
    let mut spill = write_into(spill, write)?;
    spill.seek(SeekFrom::Start(0)).map_err(|e| os_message(&e))?;
    let mut file = AtomicFile {
        file: open_for_writing(path)?,
        first_error: None,
    };
    std::io::copy(&mut spill, &mut file).map_err(|e| os_message(&e))?;
    file.flush().map_err(|e| os_message(&e))
}

/// Opens an existing file that is not a regular one for writing. A FIFO
/// that no one reads yet is waited for, as a blocking open waits, but in
/// steps that a signal ([`interrupt_writes`]) ends: a blocking open would
/// sleep through SIGTERM, whose handler only raises a flag.
fn open_for_writing(path: &Path) -> Result<std::fs::File, String> {
    use std::os::unix::fs::OpenOptionsExt;
    use std::os::unix::io::AsRawFd;
    let file = loop {
        let opened = std::fs::OpenOptions::new()
            .write(true)
            .custom_flags(libc::O_NONBLOCK)
            .open(path);
        match opened {
            Ok(file) => break file,
            // ENXIO: a FIFO without a reader.
            Err(e) if e.raw_os_error() == Some(libc::ENXIO) => {
                if writes_interrupted() {
                    return Err(INTERRUPTED_MESSAGE.into());
                }
                std::thread::sleep(std::time::Duration::from_millis(20));
            }
            Err(e) => return Err(os_message(&e)),
        }
    };
    // Blocking writes again, as the file would have had them.
    let fd = file.as_raw_fd();
    // SAFETY: fcntl on a descriptor this function owns, with valid flags.
    unsafe {
        let flags = libc::fcntl(fd, libc::F_GETFL);
        if flags >= 0 {
            libc::fcntl(fd, libc::F_SETFL, flags & !libc::O_NONBLOCK);
        }
    }
    Ok(file)
}

/// Moves the finished temporary file to `path`. An existing file is
/// swapped with it (one atomic step, as a rename) and then removed under
/// the temporary name: ext4 writes a new file's data out inside a rename
/// over an existing file (its auto_da_alloc guard for writers that do not
/// fsync), which made a PNG write take 0.1 to 140 ms on a busy disk; the
/// swap leaves the data to the usual write-back, as a write to a new file.
fn put_in_place(tmp: tempfile::NamedTempFile, path: &Path) -> std::io::Result<()> {
    #[cfg(target_os = "linux")]
    if std::fs::symlink_metadata(path).is_ok_and(|m| m.is_file()) {
        use std::os::unix::ffi::OsStrExt;
        let c = |p: &Path| std::ffi::CString::new(p.as_os_str().as_bytes());
        if let (Ok(from), Ok(to)) = (c(tmp.path()), c(path)) {
            // SAFETY: two NUL-terminated paths that live across the call.
            let swapped = unsafe {
                libc::renameat2(
                    libc::AT_FDCWD,
                    from.as_ptr(),
                    libc::AT_FDCWD,
                    to.as_ptr(),
                    libc::RENAME_EXCHANGE,
                )
            } == 0;
            if swapped {
                // The temporary name now holds the old file.
                return tmp.close();
            }
            // A file system without the swap (or a file gone meanwhile):
            // a plain rename.
        }
    }
    tmp.persist(path).map(drop).map_err(|e| e.error)
}

/// Writes a film as PNG (sRGB 8-bit) or EXR (linear f32), by extension.
/// A film with NaN or infinite pixels is refused, not written: such a
/// pixel is a bug, and a file holding it would pass it on.
pub fn write_film(film: &Film, path: &Path) -> Result<(), ImageError> {
    write_film_shown(film, path, &DisplayTransform::default())
}

/// [`write_film`] with a display transform for the PNG: the image as the
/// viewer shows it. An EXR stays linear, the transform is not applied.
pub fn write_film_shown(
    film: &Film,
    path: &Path,
    display: &DisplayTransform,
) -> Result<(), ImageError> {
    let kind = FileKind::of(path)?;
    refuse_non_finite(film, path)?;
    match kind {
        FileKind::Png => {
            // Its 8-bit codes are made first, 3 bytes a pixel: an allocation
            // that failed there aborted (a merge beside its parts).
            super::memory::check_image_memory(film.width, film.height, 3).map_err(|message| {
                ImageError::Memory {
                    path: path.to_owned(),
                    message,
                }
            })?;
            write_rgb8(
                path,
                film.width,
                film.height,
                &display.encode_all(&film.pixels),
            )
        }
        FileKind::Exr => {
            use exr::prelude::{
                Encoding, Image, Layer, LayerAttributes, SpecificChannels, Vec2, WritableImage,
            };
            // Uncompressed: a render's f32 pixels hardly compress (run
            // lengths saved 0.1% of the seed room's file), and compressing
            // took longer than rendering a 1-ray frame.
            let layer = Layer::new(
                (film.width as usize, film.height as usize),
                LayerAttributes::default(),
                Encoding::UNCOMPRESSED,
                SpecificChannels::rgb(|p: Vec2<usize>| {
                    let c = film.get(p.x() as u32, p.y() as u32);
                    (c.x, c.y, c.z)
                }),
            );
            let image = Image::from_layer(layer);
            write_atomic(path, |w| {
                image.write().to_buffered(w).map_err(|e| e.to_string())
            })
        }
    }
}

/// A film with NaN or infinite pixels is not written (see [`write_film`]).
fn refuse_non_finite(film: &Film, path: &Path) -> Result<(), ImageError> {
    match film.non_finite() {
        Some((count, (x, y))) => Err(ImageError::Write {
            path: path.to_owned(),
            message: format!(
                "{count} pixels are NaN or infinite (the first at ({x}, {y})): not written"
            ),
        }),
        None => Ok(()),
    }
}

/// A render's PNG codes (8-bit sRGB, the identity display transform),
/// encoded tile by tile as the render finishes them: on the render's
/// threads and while the tile is in cache, so that the write after the
/// render only compresses them. The same codes as [`write_film`]'s.
pub struct PngCodes {
    width: u32,
    codes: Mutex<Vec<u8>>,
}

impl PngCodes {
    /// Codes for a `width` × `height` image (zero pages until encoded).
    pub fn new(width: u32, height: u32) -> PngCodes {
        PngCodes {
            width,
            codes: Mutex::new(vec![0; width as usize * height as usize * 3]),
        }
    }

    /// Encodes the pixels of `rect` (rows packed).
    pub fn put(&self, rect: TileRect, pixels: &[Vec3]) {
        let mut tile = Vec::with_capacity(pixels.len() * 3);
        encode_srgb8_each(pixels, |rgb| tile.extend_from_slice(&rgb));
        let (w, row) = (rect.w as usize * 3, self.width as usize * 3);
        let mut codes = self.codes.lock().unwrap_or_else(|e| e.into_inner());
        for (y, line) in tile.chunks_exact(w).enumerate() {
            let start = (rect.y as usize + y) * row + rect.x as usize * 3;
            codes[start..start + w].copy_from_slice(line);
        }
    }

    /// Writes the codes of `film` (whose every tile was put) as a PNG,
    /// refusing a film with non-finite pixels as [`write_film`] does.
    pub fn write(&self, film: &Film, path: &Path) -> Result<(), ImageError> {
        refuse_non_finite(film, path)?;
        let codes = self.codes.lock().unwrap_or_else(|e| e.into_inner());
        write_rgb8(path, film.width, film.height, &codes)
    }
}

/// Bytes of compressed data in each of a PNG's IDAT chunks.
const IDAT_BYTES: usize = 1 << 16;

/// Writes 8-bit sRGB RGB data as a PNG, compressed as it is written: the
/// encoder's one-call path holds the whole compressed image in memory,
/// as large as the codes again for a noisy image, which could abort a
/// render that fit the memory check. The compression and the row filters
/// are `image`'s defaults (the same pixels and nearly the same bytes).
pub fn write_rgb8(path: &Path, width: u32, height: u32, rgb: &[u8]) -> Result<(), ImageError> {
    if FileKind::of(path)? != FileKind::Png {
        return Err(ImageError::Format {
            path: path.to_owned(),
        });
    }
    assert_eq!(
        rgb.len(),
        width as usize * height as usize * 3,
        "buffer matches size"
    );
    write_atomic(path, |w| {
        let mut encoder = png::Encoder::new(w, width, height);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        encoder.set_compression(png::Compression::Fast);
        encoder.set_filter(png::Filter::Adaptive);
        let mut header = encoder.write_header().map_err(|e| e.to_string())?;
        let mut stream = header
            .stream_writer_with_size(IDAT_BYTES)
            .map_err(|e| e.to_string())?;
        stream.write_all(rgb).map_err(|e| e.to_string())?;
        stream.finish().map_err(|e| e.to_string())?;
        // The end chunk, whose write error the writer's drop would drop.
        header.finish().map_err(|e| e.to_string())
    })
}

/// The most memory an image's decoder may take: a 16384² image as RGBA
/// f32, and room for the decoder's own buffers.
const DECODE_BYTES: u64 = 16384 * 16384 * 16 + (256 << 20);

/// Reads a PNG (decoded from sRGB to linear) or EXR (linear) image. The
/// format, and with it the transfer function, is the one the bytes are in,
/// whatever the file's name says. At most [`MAX_IMAGE_BYTES`] are read.
/// An image larger than the memory the process may have is refused
/// ([`ImageError::Memory`]) before it is decoded.
pub fn read_film(path: &Path) -> Result<Film, ImageError> {
    let fail = |message: String| ImageError::Read {
        path: path.to_owned(),
        message,
    };
    let bytes = read_image_file(path)?;
    let mut reader = ImageReader::new(Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| fail(e.to_string()))?;
    // The decoder's own default stops at 512 MiB, below the images
    // penumbra writes (a 16384² EXR decodes to 4 GiB of RGBA f32).
    let side = super::scene_file::limits::MAX_SIDE;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(side);
    limits.max_image_height = Some(side);
    limits.max_alloc = Some(DECODE_BYTES);
    reader.limits(limits.clone());
    let linear = match reader.format() {
        Some(ImageFormat::OpenExr) => true,
        Some(ImageFormat::Png) => false,
        _ => return Err(fail("not a PNG or OpenEXR image".into())),
    };
    // The header only: the size is known before any pixel is allocated.
    let mut decoder = reader.into_decoder().map_err(|e| fail(e.to_string()))?;
    let (width, height) = decoder.dimensions();
    let decoded = decoder.total_bytes();
    check_memory_to_decode(path, width, height, decoded, linear)?;
    // As `ImageReader::decode` does: the image's buffer counts against the
    // decoder's allowance.
    limits
        .reserve(decoded)
        .and_then(|()| decoder.set_limits(limits))
        .map_err(|e| fail(e.to_string()))?;
    let img = image::DynamicImage::from_decoder(decoder).map_err(|e| fail(e.to_string()))?;
    let pixels = if linear {
        img.into_rgb32f()
            .pixels()
            .map(|p| Vec3::new(p[0], p[1], p[2]))
            .collect()
    } else {
        img.into_rgb8()
            .pixels()
            .map(|p| {
                Vec3::new(
                    decode_channel(p[0]),
                    decode_channel(p[1]),
                    decode_channel(p[2]),
                )
            })
            .collect()
    };
    Ok(Film {
        width,
        height,
        pixels,
    })
}

/// Refuses an image whose decode [`read_film`] could not allocate. What
/// it allocates beyond the file's bytes (measured): an EXR's pixels twice,
/// the decoder's copy and the exr crate's (`decoded` bytes each, the whole
/// display window, f32 RGB or RGBA), and at most that again while they
/// become the film's 12 bytes a pixel; a PNG's `decoded` bytes, then its
/// 8-bit RGB copy (3 bytes a pixel) beside them or beside the film's 12.
/// With room for the decoder's own buffers (a block of rows).
fn check_memory_to_decode(
    path: &Path,
    width: u32,
    height: u32,
    decoded: u64,
    linear: bool,
) -> Result<(), ImageError> {
    let pixels = width as u64 * height as u64;
    let images = if linear {
        decoded.saturating_mul(2)
    } else {
        decoded.saturating_add(3 * pixels).max(15 * pixels)
    };
    // 32 rows (the most an EXR block takes) of RGBA f32, compressed and not.
    let room = (256 << 10) + 2 * 32 * width as u64 * 16;
    super::memory::check_read_memory(width as u64, height as u64, images.saturating_add(room))
        .map_err(|message| ImageError::Memory {
            path: path.to_owned(),
            message,
        })
}

/// The first bytes of an OpenEXR file.
pub const EXR_MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];
/// The first bytes of a PNG file.
pub const PNG_MAGIC: [u8; 8] = [0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a];

/// The bytes of an image file, at most [`MAX_IMAGE_BYTES`]. A file that
/// starts as neither a PNG nor an OpenEXR file is refused from its first
/// bytes; a file the process has too little memory to hold is refused
/// ([`ImageError::Memory`]).
pub fn read_image_file(path: &Path) -> Result<Vec<u8>, ImageError> {
    read_image_file_if(
        path,
        |head| head.starts_with(&EXR_MAGIC) || head.starts_with(&PNG_MAGIC),
        "not a PNG or OpenEXR image",
    )
}

/// [`read_image_file`] for a file whose first 8 bytes `accept` takes;
/// any other is refused with `refusal` before the rest is read (a
/// device of endless bytes read 3 GB to be told it is not an image).
pub fn read_image_file_if(
    path: &Path,
    accept: impl Fn(&[u8]) -> bool,
    refusal: &str,
) -> Result<Vec<u8>, ImageError> {
    use std::io::Read;
    let fail = |message: String| ImageError::Read {
        path: path.to_owned(),
        message,
    };
    let file = std::fs::File::open(path).map_err(|e| fail(format!("cannot read: {e}")))?;
    let meta = file
        .metadata()
        .map_err(|e| fail(format!("cannot read: {e}")))?;
    if meta.is_dir() {
        return Err(fail("cannot read: is a directory".into()));
    }
    if meta.is_file() && meta.len() > MAX_IMAGE_BYTES {
        return Err(fail(format!(
            "file is {} bytes, at most {MAX_IMAGE_BYTES} are read",
            meta.len()
        )));
    }
    let mut head = Vec::with_capacity(PNG_MAGIC.len());
    (&file)
        .take(PNG_MAGIC.len() as u64)
        .read_to_end(&mut head)
        .map_err(|e| fail(format!("cannot read: {e}")))?;
    if !accept(&head) {
        return Err(fail(refusal.into()));
    }
    let size = if meta.is_file() { meta.len() } else { 0 };
    let mut bytes = head;
    super::memory::reserve_for_file(&mut bytes, size).map_err(|message| ImageError::Memory {
        path: path.to_owned(),
        message,
    })?;
    let rest = MAX_IMAGE_BYTES - bytes.len() as u64;
    (&file)
        .take(rest + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| fail(format!("cannot read: {e}")))?;
    if bytes.len() as u64 > MAX_IMAGE_BYTES {
        return Err(fail(format!(
            "more than {MAX_IMAGE_BYTES} bytes (at most {MAX_IMAGE_BYTES} are read; stopped there)"
        )));
    }
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A disk that fills up after `room` bytes.
    struct Full {
        inner: Cursor<Vec<u8>>,
        room: usize,
    }

    impl Write for Full {
        fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
            if self.inner.get_ref().len() + buf.len() > self.room {
                return Err(std::io::Error::from_raw_os_error(libc::ENOSPC));
            }
            self.inner.write(buf)
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    impl Seek for Full {
        fn seek(&mut self, pos: SeekFrom) -> std::io::Result<u64> {
            self.inner.seek(pos)
        }
    }

    #[test]
    fn a_full_disk_is_reported_as_such() {
        // What the encoder says of a full disk: not a word about the disk.
        let img = image::Rgb32FImage::from_raw(64, 64, vec![0.5; 64 * 64 * 3]).unwrap();
        let mut full = Full {
            inner: Cursor::new(Vec::new()),
            room: 1000,
        };
        let encoder = img
            .write_to(&mut full, ImageFormat::OpenExr)
            .unwrap_err()
            .to_string();
        // What the file said first, which write_atomic reports instead.
        let mut file = AtomicFile {
            file: tempfile::tempfile().unwrap(),
            first_error: None,
        };
        let r: std::io::Result<()> = Err(std::io::Error::from_raw_os_error(libc::ENOSPC));
        let _ = file.keep(r);
        let kept = file.first_error.unwrap();
        assert!(kept.contains("No space left on device"), "{kept}");
        assert!(!kept.to_lowercase().contains("decod"), "{kept}");
        eprintln!("encoder: {encoder}; reported: {kept}");
    }
}
