//! The egui viewer (only UI; rendering lives in `crate::render`).

use crate::cli::ViewArgs;

pub fn run(_args: &ViewArgs) -> Result<(), String> {
    Err("the viewer is not built yet; use `penumbra render`".into())
}
