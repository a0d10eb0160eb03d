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

/// Runs the `penumbra` binary with `args` under an address-space limit
/// of `kib` KiB (`ulimit -v`): how a machine short of memory looks to it.
/// The arguments go to the shell as its own positional parameters, so
/// paths need no quoting.
pub fn penumbra_within_memory(kib: u64, args: &[&str]) -> Output {
    Command::new("sh")
        .arg("-c")
        .arg(format!("ulimit -v {kib} && exec \"$0\" \"$@\""))
        .arg(env!("CARGO_BIN_EXE_penumbra"))
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

/// The standard error of a run that must refuse its input (exit 2, the
/// code of every input error); `what` names the case in the failure.
pub fn refused(out: &Output, what: impl std::fmt::Display) -> String {
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "{what}: {err}");
    err
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

/// The 8 corners ±h and the 12 triangles of a box as OBJ text.
pub fn box_obj(h: [f64; 3]) -> String {
    use std::fmt::Write;
    let mut s = String::from("# a box\n");
    for i in 0..8 {
        let c = |bit: usize, k: usize| if i & bit == 0 { -h[k] } else { h[k] };
        writeln!(s, "v {} {} {}", c(1, 0), c(2, 1), c(4, 2)).unwrap();
    }
    // Faces as quads of corner indices (1-based), split in two.
    let quads = [
        [1, 3, 7, 5],
        [2, 6, 8, 4],
        [1, 5, 6, 2],
        [3, 4, 8, 7],
        [1, 2, 4, 3],
        [5, 7, 8, 6],
    ];
    for q in quads {
        writeln!(s, "f {} {} {}", q[0], q[1], q[2]).unwrap();
        writeln!(s, "f {} {} {}", q[0], q[2], q[3]).unwrap();
    }
    s
}

/// A fresh folder for one test's files, removed when the test ends. Its
/// name is unique even when a process id comes round again (pids wrap at
/// 32768 here): a folder named by the pid alone could hold an earlier
/// run's files, and an assertion that a file was not written would fail.
pub struct Scratch(tempfile::TempDir);

impl Scratch {
    pub fn new(name: &str) -> Scratch {
        let dir = tempfile::Builder::new()
            .prefix(&format!("penumbra-{name}-"))
            .tempdir()
            .expect("a scratch folder");
        Scratch(dir)
    }
}

impl std::ops::Deref for Scratch {
    type Target = Path;
    fn deref(&self) -> &Path {
        self.0.path()
    }
}
