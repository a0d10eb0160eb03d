//! Fuzz target: any bytes → the PLY (ASCII and binary) reader → scene faces.
//!
//! A file that is refused must be refused with an error (never a panic); a
//! file that is read must have its indices in range. Run from the
//! repository root (stable toolchain), seeded with the sample meshes:
//! `RUSTC_BOOTSTRAP=1 cargo fuzz run -s none read_ply fuzz/corpus/read_ply scenes/models -- -max_len=65536 -max_total_time=600`

#![no_main]

mod mesh_check;

use libfuzzer_sys::fuzz_target;
use penumbra::render::mesh::read_ply;

fuzz_target!(|data: &[u8]| {
    mesh_check::guarded(|| mesh_check::check(read_ply(data)));
});
