//! Converged reference images, cached as EXR under a hash of the scene.
//!
//! The key hashes the scene JSON with the settings the sweep varies
//! replaced by the reference's own (stratified sampling, `rays` shadow rays,
//! a fixed seed) and the model set: every sweep of one scene and model
//! shares one reference, and any change to geometry, camera, size, depth,
//! materials or light makes a new one. The scene's mesh files are hashed
//! by their content too: the JSON names a mesh only by a path relative to
//! the scene, so an edited mesh, or the same scene text beside another
//! mesh, would otherwise find the old mesh's reference.

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use super::{CliError, render_once};
use crate::render::output::{read_film, write_atomic, write_film};
use crate::render::{AreaLightModel, Film, ImageError, SceneDesc};

pub use crate::render::REFERENCE_RAYS;
use crate::render::{reference_desc, reference_scene};

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

/// Hex key of a reference: FNV-1a (64 bit) of the normalised scene JSON
/// and of the content of each of its mesh files, in the scene's order.
/// (Stable across Rust versions, unlike std's `DefaultHasher`.) A scene
/// without meshes keeps the key it had before meshes were hashed.
pub fn reference_key(desc: &SceneDesc, model: AreaLightModel, rays: u32) -> String {
    let text = format!(
        "{KEY_VERSION}\n{}\n{}",
        env!("CARGO_PKG_VERSION"),
        reference_desc(desc, model, rays).to_json()
    );
    let mut h = Fnv1a::default();
    h.add(text.as_bytes());
    // With several camera samples the reference takes the image's places
    // for them (see `reference`): another seed, another reference.
    if desc.render.samples_per_pixel > 1 {
        h.add(format!("\ncamera seed {}", desc.render.seed).as_bytes());
    }
    for mesh in desc.mesh_files() {
        h.add(b"\nmesh\n");
        // A file that cannot be read hashes as its error: the render that
        // would fill the entry refuses it anyway.
        if let Err(e) = h.add_file(&mesh) {
            h.add(e.to_string().as_bytes());
        }
    }
    format!("{:016x}", h.0)
}

/// FNV-1a, 64 bit.
struct Fnv1a(u64);

impl Default for Fnv1a {
    fn default() -> Fnv1a {
        Fnv1a(0xcbf2_9ce4_8422_2325)
    }
}

impl Fnv1a {
    fn add(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 ^= b as u64;
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }

    /// The file's bytes, read in pieces (a mesh may be large); only a
    /// regular file, and only the length it had when opened (a device or a
    /// growing file would never end).
    fn add_file(&mut self, path: &Path) -> std::io::Result<()> {
        use std::io::Read as _;
        let file = std::fs::File::open(path)?;
        let meta = file.metadata()?;
        if !meta.is_file() {
            return Err(std::io::Error::other("not a regular file"));
        }
        let mut file = file.take(meta.len());
        let mut buf = vec![0u8; 1 << 16];
        loop {
            match file.read(&mut buf) {
                Ok(0) => return Ok(()),
                Ok(n) => self.add(&buf[..n]),
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
    }
}

/// The cache entry at `path` if it is whole: a `size` image of finite
/// pixels. One missing, unreadable (a damaged file) or of another size is
/// `None`, to be rendered again; one too large for the memory left is
/// refused (rendering it again would need more).
pub fn cached_film(path: &Path, size: (u32, u32)) -> Result<Option<Film>, CliError> {
    if !path.exists() {
        return Ok(None);
    }
    match read_film(path) {
        Err(e @ ImageError::Memory { .. }) => Err(CliError::input(e)),
        Ok(film) if (film.width, film.height) == size && !film.has_non_finite() => Ok(Some(film)),
        _ => Ok(None),
    }
}

/// Loads the reference of `desc` under `model` from `cache_dir`, or
/// renders and stores it (with the normalised scene beside it, to see what
/// a cache entry is). `fresh` renders even if cached. Its camera samples
/// (with several a pixel) lie where `desc`'s own renders put them,
/// scrambled by `desc`'s seed: the reference converges the light, not the
/// anti-aliasing, so a render's error is its light's.
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
    if !fresh && let Some(film) = cached_film(&path, (w, h))? {
        return Ok(Reference {
            film,
            path,
            cached: true,
            elapsed: Duration::ZERO,
        });
    }
    std::fs::create_dir_all(cache_dir).map_err(|e| {
        CliError::other(format!(
            "cannot create the cache directory {}: {e}",
            cache_dir.display()
        ))
    })?;
    let rdesc = reference_desc(desc, model, rays);
    let scene = reference_scene(&rdesc, desc).map_err(CliError::input)?;
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
