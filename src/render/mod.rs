//! The rendering core: scene, geometry, camera, light, sampling, shadow
//! rays, shading, tracer, progressive tiles, live edits and film/output. It
//! knows nothing of the UI.
//!
//! The public API is the list of `pub use` below; the modules themselves
//! are public only where the CLI's benchmarks and the tests reach inside.

pub mod analytic;
pub mod camera;
pub mod compare;
pub mod error;
pub mod film;
pub mod generate;
pub mod geometry;
pub mod light;
pub mod live;
pub mod math;
pub mod output;
pub mod progressive;
pub mod rng;
pub mod sampling;
pub mod scene;
pub mod scene_file;
pub mod scene_transform;
pub mod settings;
pub mod shading;
pub mod shading_params;
pub mod shadow;
pub mod sobol;
pub mod stats;
pub mod tracer;

pub use error::{ImageError, SceneError};
pub use film::Film;
pub use live::{EditClass, LiveError, LiveRender, LiveReport, classify};
pub use progressive::{
    CancelToken, Cancelled, Pass, RenderOptions, RenderReport, TileRect, TileUpdate, pass_plan,
    render, render_image,
};
pub use scene::{Loaded, Scene};
pub use scene_file::{AreaLightModel, Sampling, SceneDesc};
pub use settings::RenderSettings;
pub use shading_params::{LightColours, Material, ShadingParams};
pub use stats::RayStats;
