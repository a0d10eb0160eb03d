//! Fuzz target: any bytes → the glTF 2.0 / GLB (external buffers are not found: no folder) reader → scene faces.
//!
//! A file that is refused must be refused with an error (never a panic); a
//! file that is read must have its indices in range. Run from the
//! repository root (stable toolchain), seeded with the sample meshes:
//! `RUSTC_BOOTSTRAP=1 cargo fuzz run -s none read_gltf fuzz/corpus/read_gltf scenes/models -- -max_len=65536 -max_total_time=600`

#![no_main]

mod mesh_check;

use libfuzzer_sys::fuzz_target;
use penumbra::render::mesh::read_gltf;

fuzz_target!(|data: &[u8]| {
    mesh_check::guarded(|| mesh_check::check(read_gltf(data, None)));
});
