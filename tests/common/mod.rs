//! Helpers shared by the integration tests.
#![allow(dead_code)]

pub mod viewer;

use std::path::Path;
use std::process::{Command, Output};

use penumbra::render::{Loaded, SceneDesc};

/// The seed room description, resized.
pub fn seed_room(width: u32, height: u32) -> SceneDesc {
    let mut desc = SceneDesc::from_json(penumbra::render::SEED_ROOM_JSON).unwrap();
    desc.camera.width = width;
    desc.camera.height = height;
    desc
}

pub fn build(desc: SceneDesc) -> Loaded {
    Loaded::new(&desc).expect("valid scene")
}

/// A scene from JSON text, panicking with the loader's message.
pub fn scene_json(text: &str) -> Loaded {
    Loaded::from_json(text).unwrap_or_else(|e| panic!("{e}"))
}

/// Runs the `penumbra` binary with `args`.
pub fn penumbra(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_penumbra"))
        .args(args)
        .output()
        .expect("runs")
}

/// Runs the `penumbra` binary with `args`, expects success and returns
/// its standard output.
pub fn penumbra_ok(args: &[&str]) -> String {
    let out = penumbra(args);
    assert!(
        out.status.success(),
        "penumbra {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// The names of the files in `dir`, sorted.
pub fn files_in(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}
