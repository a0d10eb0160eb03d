//! The rendering core: scene, geometry, camera, light, sampling, shading,
//! tracer, progressive tiles and film/output. It knows nothing of the UI.

pub mod analytic;
pub mod camera;
pub mod compare;
pub mod error;
pub mod film;
pub mod generate;
pub mod geometry;
pub mod light;
pub mod light_frame;
pub mod math;
pub mod occlusion;
pub mod output;
pub mod progressive;
pub mod ray_packet;
pub mod rng;
pub mod sampling;
pub mod scene;
pub mod scene_file;
pub mod scene_transform;
pub mod shading;
pub mod sobol;
pub mod stats;
pub mod tracer;

pub use error::{ImageError, SceneError};
pub use film::Film;
pub use progressive::{
    CancelToken, Cancelled, Pass, RenderOptions, RenderReport, TileRect, TileUpdate, pass_plan,
    render, render_image,
};
pub use scene::{RenderSettings, Scene};
pub use scene_file::{AreaLightModel, Sampling, SceneDesc};
pub use stats::RayStats;
