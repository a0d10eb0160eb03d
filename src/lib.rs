//! penumbra: an interactive previewer for a Phong ray tracer with a
//! rectangular area light.
//!
//! - [`render`]: the rendering core (no UI dependencies).
//! - [`app`]: the egui viewer.
//! - [`cli`]: the command-line front end.

pub mod app;
pub mod cli;
pub mod render;
