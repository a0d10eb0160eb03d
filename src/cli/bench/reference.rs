//! Converged reference images, cached as EXR under a hash of the scene.
//!
//! The key hashes the scene JSON with the settings the sweep varies
//! replaced by the reference's own (stratified sampling, `rays` shadow rays,
//! a fixed seed) and the model set: every sweep of one scene and model
//! shares one reference, and any change to geometry, camera, size, depth,
//! materials or light makes a new one.

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use super::{CliError, build, render_once};
use crate::render::output::{read_film, write_atomic, write_film};
use crate::render::{AreaLightModel, Film, ImageError, SceneDesc};

pub use crate::render::REFERENCE_RAYS;
use crate::render::reference_desc;

/// Bump when the renderer changes what a reference looks like, so that old
/// cache entries are not reused.
const KEY_VERSION: &str = "penumbra-reference-1";

/// A reference image and where it came from.
pub struct Reference {
    pub film: Film,
    pub path: PathBuf,
    /// Loaded from the cache rather than rendered.
    pub cached: bool,
    /// Render time (zero when cached).
    pub elapsed: Duration,
}

/// Hex key of a reference: FNV-1a (64 bit) of the normalised scene JSON.
/// (Stable across Rust versions, unlike std's `DefaultHasher`.)
pub fn reference_key(desc: &SceneDesc, model: AreaLightModel, rays: u32) -> String {
    let text = format!(
        "{KEY_VERSION}\n{}\n{}",
        env!("CARGO_PKG_VERSION"),
        reference_desc(desc, model, rays).to_json()
    );
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in text.bytes() {
        h ^= b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    format!("{h:016x}")
}

/// Loads the reference of `desc` under `model` from `cache_dir`, or
/// renders and stores it (with the normalised scene beside it, to see what
/// a cache entry is). `fresh` renders even if cached.
pub fn reference(
    desc: &SceneDesc,
    model: AreaLightModel,
    rays: u32,
    cache_dir: &Path,
    fresh: bool,
) -> Result<Reference, CliError> {
    let key = reference_key(desc, model, rays);
    let path = cache_dir.join(format!("ref-{}-{key}.exr", model.name()));
    let (w, h) = (desc.camera.width, desc.camera.height);
    if !fresh && path.exists() {
        // A cache entry of the wrong size (or unreadable) is rendered again;
        // one too large for the memory left is refused (rendering it again
        // would need more).
        let cached = match read_film(&path) {
            Err(e @ ImageError::Memory { .. }) => return Err(CliError::input(e)),
            read => read,
        };
        if let Ok(film) = cached
            && (film.width, film.height) == (w, h)
            && !film.has_non_finite()
        {
            return Ok(Reference {
                film,
                path,
                cached: true,
                elapsed: Duration::ZERO,
            });
        }
    }
    std::fs::create_dir_all(cache_dir).map_err(|e| {
        CliError::other(format!(
            "cannot create the cache directory {}: {e}",
            cache_dir.display()
        ))
    })?;
    let rdesc = reference_desc(desc, model, rays);
    let scene = build(&rdesc, true)?;
    let start = Instant::now();
    let film = render_once(&scene).film;
    let elapsed = start.elapsed();
    write_film(&film, &path).map_err(CliError::other)?;
    // Only informative (never read back): a failure to write it does not
    // spoil the cache. Written whole or not at all, as the EXR is, so that
    // an interrupted bench leaves no half-written entry.
    let json = rdesc.to_json();
    let _ = write_atomic(&path.with_extension("json"), |w| {
        w.write_all(json.as_bytes()).map_err(|e| e.to_string())
    });
    Ok(Reference {
        film,
        path,
        cached: false,
        elapsed,
    })
}
