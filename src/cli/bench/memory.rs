//! The bench's memory check, made before any render: as `render` does, a
//! size whose images cannot be allocated is refused (exit 2) rather than
//! aborting the process half-way through a run when an allocation fails.

use super::{BenchArgs, BenchScene, CliError};
use crate::render::memory::check_render_memory;

/// Bytes a pixel of the largest size each mode holds at once, generously
/// rounded up: every live film (12 bytes a pixel each), the encoder's
/// buffer of a written EXR (12) and the mode's own per-pixel data.
fn bytes_per_pixel(args: &BenchArgs) -> usize {
    if args.exact {
        // The f64 sum of the reference renders (24), the mean, the exact,
        // grid and one-render films, the EXR buffer and the error image.
        96
    } else if args.edits {
        // The viewer's recorded paths and preview (as the viewer's own
        // check) and the one-shot render beside them.
        128
    } else if args.spp_split || args.slopes {
        // A reference, the render compared with it, the reference's EXR
        // buffer (or the penumbra mask).
        48
    } else if args.meshes.is_some() || args.scaling {
        // The renders' films, one at a time (two with shadows off).
        24
    } else if args.target {
        // The skip-on and skip-off films at 1920×1080, compared.
        48
    } else {
        // The reference, the exact reference, the image, the no-skip
        // image and the reference's EXR buffer.
        64
    }
}

/// Refuses (exit 2) a bench whose largest render of `scene` does not fit
/// in the memory the process may take, with room for the worker threads
/// of the current pool.
pub fn check(args: &BenchArgs, scene: &BenchScene) -> Result<(), CliError> {
    let c = &scene.desc.camera;
    check_render_memory(
        c.width,
        c.height,
        bytes_per_pixel(args),
        rayon::current_num_threads(),
    )
    .map_err(|why| CliError::input(format!("{}: {why}", scene.name)))
}
