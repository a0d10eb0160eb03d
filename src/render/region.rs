//! Crop windows: a rectangle of the image rendered on its own, written as an
//! OpenEXR file that records where it sits, and the merge of such parts
//! into the whole image.
//!
//! A part is a standard crop EXR: its data window is the region, its
//! display window the whole image (what pbrt's `--cropwindow` writes, and
//! what compositors read). Two attributes of penumbra's own say which scene
//! it is a part of: a fingerprint of the scene description as rendered and
//! the version of penumbra that rendered it. Every pixel's random numbers
//! are keyed by its position in the whole image, so the merged parts equal
//! a one-shot render bit for bit, however the image was cut.

use std::io::Cursor;
use std::path::{Path, PathBuf};

use exr::meta::MetaData;
use exr::meta::attribute::{AttributeValue, Text};
use exr::prelude::{
    Encoding, Image, ImageAttributes, IntegerBounds, Layer, LayerAttributes, ReadChannels,
    ReadLayers, SpecificChannels, Vec2,
};
use glam::Vec3;

use super::error::{ImageError, cut};
use super::film::Film;
use super::memory::check_read_memory;
use super::output::{EXR_MAGIC, read_image_file_if, write_atomic};
use super::progressive::TileRect;
use super::scene_file::SceneDesc;
use super::scene_file::limits::MAX_SIDE;
use super::settings::RenderSettings;

/// The attribute holding the scene's fingerprint.
pub const SCENE_ATTRIBUTE: &str = "penumbraScene";
/// The attribute holding the version of penumbra that rendered the part.
pub const VERSION_ATTRIBUTE: &str = "penumbraVersion";

/// Most parts one merge takes (each pixel remembers which part gave it).
pub const MAX_PARTS: usize = u16::MAX as usize;

/// A rendered rectangle of an image and what it is a part of.
#[derive(Debug, Clone, PartialEq)]
pub struct Part {
    /// Where the pixels sit in the whole image.
    pub region: TileRect,
    /// The whole image's width and height.
    pub full: (u32, u32),
    /// [`fingerprint`] of the scene as rendered.
    pub scene: String,
    /// The version of penumbra that rendered it.
    pub version: String,
    /// The region's pixels (`region.w × region.h`).
    pub film: Film,
}

/// A stable fingerprint (64-bit FNV-1a, hex) of everything a render's
/// pixels depend on that the scene file says: the description (with the
/// command line's overrides applied) and the reconstruction filter.
/// A mesh file is named by its path; its contents are not hashed.
pub fn fingerprint(desc: &SceneDesc, settings: &RenderSettings) -> String {
    let text = format!("{}\n{:?}", desc.to_json(), settings.filter);
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in text.bytes() {
        h ^= b as u64;
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    format!("{h:016x}")
}

/// Parses `X,Y,W,H` (pixels, from the top-left corner). A number out of
/// range is named with its range, as other numbers on the command line
/// are: `X: -1 is not in 0..=16383`.
pub fn parse_region(s: &str) -> Result<TileRect, String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if parts.len() != 4 {
        return Err(format!(
            "{s:?}: expected X,Y,W,H (four whole numbers of pixels)"
        ));
    }
    // A corner inside the largest image; a side of at least one pixel.
    let ranges = [
        ("X", 0..=MAX_SIDE - 1),
        ("Y", 0..=MAX_SIDE - 1),
        ("W", 1..=MAX_SIDE),
        ("H", 1..=MAX_SIDE),
    ];
    let mut v = [0u32; 4];
    for ((o, p), (name, range)) in v.iter_mut().zip(&parts).zip(ranges) {
        let n: i128 = p
            .parse()
            .map_err(|_| format!("{p:?} is not a whole number of pixels (in X,Y,W,H)"))?;
        *o = u32::try_from(n)
            .ok()
            .filter(|n| range.contains(n))
            .ok_or_else(|| format!("{name}: {n} is not in {}..={}", range.start(), range.end()))?;
    }
    let [x, y, w, h] = v;
    Ok(TileRect { x, y, w, h })
}

/// Whether `region` lies within a `width × height` image.
pub fn check_region(region: TileRect, width: u32, height: u32) -> Result<(), String> {
    let TileRect { x, y, w, h } = region;
    if x as u64 + w as u64 > width as u64 || y as u64 + h as u64 > height as u64 {
        return Err(format!(
            "the region {x},{y},{w},{h} reaches past the {width}×{height} image"
        ));
    }
    Ok(())
}

/// Writes a part as a crop EXR (atomically; NaN or infinite pixels are
/// refused, as for any image).
pub fn write_part(part: &Part, path: &Path) -> Result<(), ImageError> {
    let fail = |message: String| ImageError::Write {
        path: path.to_owned(),
        message,
    };
    if !path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("exr"))
    {
        return Err(fail(
            "a region is written as OpenEXR (.exr): only it records where the region sits".into(),
        ));
    }
    if let Some((count, (x, y))) = part.film.non_finite() {
        return Err(fail(format!(
            "{count} pixels are NaN or infinite (the first at ({x}, {y})): not written"
        )));
    }
    let r = part.region;
    let mut attributes = LayerAttributes {
        layer_position: Vec2(r.x as i32, r.y as i32),
        ..LayerAttributes::default()
    };
    attributes.software_name = Some(Text::from("penumbra"));
    // One attribute of our own in each of the crate's maps (hash maps,
    // written in an order that changes from run to run): the same render
    // writes the same bytes. `read_part` looks in both.
    attributes.other.insert(
        Text::from(VERSION_ATTRIBUTE),
        AttributeValue::Text(Text::from(part.version.as_str())),
    );
    let film = &part.film;
    let layer = Layer::new(
        (r.w as usize, r.h as usize),
        attributes,
        Encoding::FAST_LOSSLESS,
        SpecificChannels::rgb(|p: Vec2<usize>| {
            let c = film.get(p.x() as u32, p.y() as u32);
            (c.x, c.y, c.z)
        }),
    );
    let display = IntegerBounds::from_dimensions((part.full.0 as usize, part.full.1 as usize));
    let mut image_attributes = ImageAttributes::new(display);
    image_attributes.other.insert(
        Text::from(SCENE_ATTRIBUTE),
        AttributeValue::Text(Text::from(part.scene.as_str())),
    );
    let image = Image::new(image_attributes, layer);
    write_atomic(path, |w| {
        use exr::prelude::WritableImage;
        image.write().to_buffered(w).map_err(|e| e.to_string())
    })
}

/// Reads a part written by [`write_part`]; any other image is refused with
/// what it lacks.
pub fn read_part(path: &Path) -> Result<Part, ImageError> {
    read_part_or_other(path).map_err(|e| e.error)
}

/// [`read_part`] for a reader that takes other images too (`compare`):
/// `None` for an image that is no part (it lacks the fingerprint, or is
/// no single-layer OpenEXR file), an error for a file that says it is a
/// part but is broken (an empty window, say) or too large to read.
pub fn read_if_part(path: &Path) -> Result<Option<Part>, ImageError> {
    match read_part_or_other(path) {
        Ok(part) => Ok(Some(part)),
        Err(e) if e.a_part || matches!(e.error, ImageError::Memory { .. }) => Err(e.error),
        Err(_) => Ok(None),
    }
}

/// Why a file was not read as a part, and whether it says it is one.
struct NotRead {
    error: ImageError,
    a_part: bool,
}

fn read_part_or_other(path: &Path) -> Result<Part, NotRead> {
    let not_a_part = |error: ImageError| NotRead {
        error,
        a_part: false,
    };
    // Past the fingerprint the file says it is a part: what fails is a
    // broken part.
    let fail = |message: String| NotRead {
        error: ImageError::Read {
            path: path.to_owned(),
            message,
        },
        a_part: true,
    };
    let bytes = read_image_file_if(
        path,
        |head| head.starts_with(&EXR_MAGIC),
        "not an OpenEXR file (a region part is one)",
    )
    .map_err(not_a_part)?;
    let other = |message: String| {
        not_a_part(ImageError::Read {
            path: path.to_owned(),
            message,
        })
    };
    // The header first: its sizes are checked before any pixel is
    // allocated.
    let meta = MetaData::read_from_buffered(Cursor::new(&bytes), false)
        .map_err(|e| other(format!("not a readable OpenEXR file: {e}")))?;
    let [header] = meta.headers.as_slice() else {
        return Err(other(format!(
            "{} layers; a region part has one",
            meta.headers.len()
        )));
    };
    // Written as image attributes; a reader may file them with the layer.
    let text = |name: &str| {
        let key = Text::from(name);
        let value = header.shared_attributes.other.get(&key);
        match value.or_else(|| header.own_attributes.other.get(&key)) {
            Some(AttributeValue::Text(t)) => Some(t.to_string()),
            _ => None,
        }
    };
    let (Some(scene), Some(version)) = (text(SCENE_ATTRIBUTE), text(VERSION_ATTRIBUTE)) else {
        return Err(other(
            "not a region part: it lacks the scene fingerprint that `penumbra render --region` records"
                .into(),
        ));
    };
    // The crate swaps a window's ends when they are reversed (x 0..-1
    // reads as 2 pixels at -1): an empty window is found in the bytes.
    for name in ["displayWindow", "dataWindow"] {
        if let Some([x0, y0, x1, y1]) = raw_box(&bytes, name)
            && (x1 < x0 || y1 < y0)
        {
            let what = if name == "dataWindow" {
                "data"
            } else {
                "display"
            };
            let ends: Vec<String> = [("x", x0, x1), ("y", y0, y1)]
                .iter()
                .filter(|(_, lo, hi)| hi < lo)
                .map(|(axis, lo, hi)| format!("{axis} {lo}..{hi}"))
                .collect();
            return Err(fail(format!(
                "its {what} window is empty ({})",
                ends.join(", ")
            )));
        }
    }
    let display = header.shared_attributes.display_window;
    let data = header.data_window();
    let side = MAX_SIDE as usize;
    if display.position != Vec2(0, 0) || display.size.0 > side || display.size.1 > side {
        return Err(fail(format!(
            "display window at ({}, {}) of {}×{}: a part's whole image starts at (0, 0) and is at most {side} pixels a side",
            display.position.0, display.position.1, display.size.0, display.size.1
        )));
    }
    let inside = data.position.0 >= 0
        && data.position.1 >= 0
        && data.size.0 > 0
        && data.size.1 > 0
        && data.position.0 as usize + data.size.0 <= display.size.0
        && data.position.1 as usize + data.size.1 <= display.size.1;
    if !inside {
        return Err(fail(format!(
            "data window at ({}, {}) of {}×{} is not inside the {}×{} image",
            data.position.0,
            data.position.1,
            data.size.0,
            data.size.1,
            display.size.0,
            display.size.1
        )));
    }
    // The film (12 bytes a pixel) and a block of the file, compressed and
    // not (as measured: nothing else of the size of the image).
    let film_bytes = (data.size.0 as u64 * data.size.1 as u64).saturating_mul(12);
    let block_bytes = 2 * header.max_block_byte_size() as u64 + (256 << 10);
    check_read_memory(
        data.size.0 as u64,
        data.size.1 as u64,
        film_bytes.saturating_add(block_bytes),
    )
    .map_err(|message| NotRead {
        error: ImageError::Memory {
            path: path.to_owned(),
            message,
        },
        a_part: true,
    })?;
    let image = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .rgb_channels(
            |size, _| Film::new(size.0 as u32, size.1 as u32),
            |film: &mut Film, p: Vec2<usize>, (r, g, b): (f32, f32, f32)| {
                let i = p.y() * film.width as usize + p.x();
                film.pixels[i] = Vec3::new(r, g, b);
            },
        )
        .first_valid_layer()
        .all_attributes()
        .from_buffered(Cursor::new(&bytes))
        .map_err(|e| fail(format!("reading its pixels: {e}")))?;
    let film = image.layer_data.channel_data.pixels;
    Ok(Part {
        region: TileRect {
            x: data.position.0 as u32,
            y: data.position.1 as u32,
            w: film.width,
            h: film.height,
        },
        full: (display.size.0 as u32, display.size.1 as u32),
        scene,
        version,
        film,
    })
}

/// The `box2i` attribute `name` of an OpenEXR file's first header as
/// written (x min, y min, x max, y max, inclusive); `None` if it is not
/// there or the header ends early.
fn raw_box(bytes: &[u8], name: &str) -> Option<[i32; 4]> {
    // After the magic number and the version field: name, type, size,
    // value, until an empty name.
    let mut at = 8;
    let text = |at: &mut usize| {
        let len = bytes.get(*at..)?.iter().position(|&b| b == 0)?;
        let t = &bytes[*at..*at + len];
        *at += len + 1;
        Some(t)
    };
    loop {
        let key = text(&mut at)?;
        if key.is_empty() {
            return None;
        }
        let kind = text(&mut at)?;
        let size = i32::from_le_bytes(bytes.get(at..at + 4)?.try_into().ok()?);
        at += 4;
        let value = bytes.get(at..at.checked_add(usize::try_from(size).ok()?)?)?;
        at += value.len();
        if key == name.as_bytes() && kind == b"box2i" && value.len() == 16 {
            let v = |i: usize| i32::from_le_bytes(value[4 * i..4 * i + 4].try_into().unwrap());
            return Some([v(0), v(1), v(2), v(3)]);
        }
    }
}

/// Why parts do not make one image; every message names the files.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct MergeError(pub String);

/// Stitches parts into the whole image. Refused: no parts, parts of
/// another scene, size or version, pixels covered by no part (a gap), and
/// overlapping parts that disagree on a pixel (bit for bit).
pub fn merge(parts: &[(PathBuf, Part)]) -> Result<Film, MergeError> {
    let err = |m: String| Err(MergeError(m));
    let Some((first_path, first)) = parts.first() else {
        return err("no parts to merge".into());
    };
    if parts.len() > MAX_PARTS {
        return err(format!(
            "{} parts: at most {MAX_PARTS} are merged at once",
            parts.len()
        ));
    }
    for (path, p) in &parts[1..] {
        let (a, b) = (first_path.display(), path.display());
        // The size first: the fingerprint covers it, and a size is the
        // clearer reason. The version next: another version may write
        // another fingerprint for the same scene.
        if p.full != first.full {
            return err(format!(
                "{b} is a part of a {}×{} image, {a} of a {}×{} one",
                p.full.0, p.full.1, first.full.0, first.full.1
            ));
        }
        if p.version != first.version {
            return err(format!(
                "{b} was rendered by penumbra {}, {a} by {}: their pixels may differ",
                quoted(&p.version),
                quoted(&first.version)
            ));
        }
        if p.scene != first.scene {
            return err(format!(
                "{b} is a part of another scene than {a} (scene fingerprint {} against {})",
                quoted(&p.scene),
                quoted(&first.scene)
            ));
        }
    }
    let (width, height) = first.full;
    // A gap is found from the parts' rectangles before the whole image's
    // memory is taken (a 1×1 part of a 16384² image took 3 GB and 12 s to
    // be told it is not the whole).
    if let Some((gaps, (x, y))) = gaps_of(parts, width, height) {
        return err(format!(
            "a gap: {gaps} pixels of the {width}×{height} image are in no part, the first at ({x}, {y})"
        ));
    }
    let pixels = width as usize * height as usize;
    let mut film = Film {
        width,
        height,
        pixels: Vec::new(),
    };
    // Which part (index + 1) gave each pixel; 0: none yet.
    let mut owner: Vec<u16> = Vec::new();
    let reserved = super::memory::probing(|| {
        film.pixels.try_reserve_exact(pixels).is_ok() && owner.try_reserve_exact(pixels).is_ok()
    });
    if !reserved {
        return err(format!(
            "the merged {width}×{height} image needs about {} beyond its parts, more than this process can have",
            super::memory::amount(pixels.saturating_mul(14))
        ));
    }
    film.pixels.resize(pixels, Vec3::ZERO);
    owner.resize(pixels, 0);
    for (index, (path, part)) in parts.iter().enumerate() {
        let r = part.region;
        for y in 0..r.h {
            for x in 0..r.w {
                let (gx, gy) = (r.x + x, r.y + y);
                let i = gy as usize * width as usize + gx as usize;
                let value = part.film.get(x, y);
                match owner[i] {
                    0 => {
                        film.pixels[i] = value;
                        owner[i] = index as u16 + 1;
                    }
                    o if !same_bits(film.pixels[i], value) => {
                        let other = &parts[o as usize - 1].0;
                        return err(format!(
                            "{} and {} overlap and disagree at pixel ({gx}, {gy}): {} against {}",
                            other.display(),
                            path.display(),
                            film.pixels[i],
                            value
                        ));
                    }
                    _ => {}
                }
            }
        }
    }
    let gaps = owner.iter().filter(|&&o| o == 0).count();
    if let Some(first_gap) = owner.iter().position(|&o| o == 0) {
        let (x, y) = (first_gap % width as usize, first_gap / width as usize);
        return err(format!(
            "a gap: {gaps} pixels of the {width}×{height} image are in no part, the first at ({x}, {y})"
        ));
    }
    Ok(film)
}

/// The pixels of the `width`×`height` image in no part's rectangle, and
/// the first of them row by row, or `None` if the parts cover it (or are
/// too many to check this way: the merge's own pass finds a gap then).
fn gaps_of(parts: &[(PathBuf, Part)], width: u32, height: u32) -> Option<(u64, (u32, u32))> {
    if parts.len() as u64 * height as u64 > 50_000_000 {
        return None;
    }
    let mut spans: Vec<(u32, u32)> = Vec::with_capacity(parts.len());
    let (mut gaps, mut first) = (0u64, None);
    for y in 0..height {
        spans.clear();
        spans.extend(
            parts
                .iter()
                .map(|(_, p)| p.region)
                .filter(|r| (r.y..r.y + r.h).contains(&y))
                .map(|r| (r.x, r.x + r.w)),
        );
        spans.sort_unstable();
        // Walk the spans left to right; `x` is the first pixel not yet
        // covered.
        let mut x = 0;
        for &(start, end) in spans.iter().chain([(width, width)].iter()) {
            if start > x {
                gaps += (start.min(width) - x) as u64;
                first.get_or_insert((x, y));
            }
            x = x.max(end);
            if x >= width {
                break;
            }
        }
    }
    first.map(|f| (gaps, f))
}

/// An attribute's text as a message quotes it: on one line, cut to
/// [`MAX_QUOTED`](super::error::MAX_QUOTED) characters (a crafted file may
/// hold anything there).
fn quoted(text: &str) -> String {
    cut(&text.escape_debug().to_string())
}

fn same_bits(a: Vec3, b: Vec3) -> bool {
    a.to_array()
        .iter()
        .zip(b.to_array())
        .all(|(p, q)| p.to_bits() == q.to_bits())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regions_parse_and_are_checked_against_the_image() {
        let r = parse_region("10, 20,30,40").unwrap();
        assert_eq!((r.x, r.y, r.w, r.h), (10, 20, 30, 40));
        assert!(parse_region("1,2,3").unwrap_err().contains("X,Y,W,H"));
        assert_eq!(
            parse_region("1,2,0,4").unwrap_err(),
            "W: 0 is not in 1..=16384"
        );
        assert_eq!(
            parse_region("-1,2,3,4").unwrap_err(),
            "X: -1 is not in 0..=16383"
        );
        assert!(parse_region("1,x,3,4").unwrap_err().contains("\"x\""));
        assert!(check_region(r, 40, 60).is_ok());
        assert!(
            check_region(r, 39, 60)
                .unwrap_err()
                .contains("reaches past")
        );
        let huge = TileRect {
            x: u32::MAX,
            y: 0,
            w: u32::MAX,
            h: 1,
        };
        assert!(check_region(huge, 100, 100).is_err());
    }
}
