//! The rendering core: scene, geometry, camera, light, sampling, shadow
//! rays, shading, tracer, progressive tiles, live edits and film/output. It
//! knows nothing of the UI.
//!
//! The API is the list of `pub use` below plus the public modules of the
//! format (`scene_file`), the primitives (`geometry`), generated scenes and
//! image files; hidden modules are internals that benchmarks and white-box
//! tests reach into.

// The format, the primitives and the image files: public modules.
pub mod compare;
pub mod display;
pub mod film;
pub mod generate;
pub mod generate_mesh;
pub mod geometry;
pub mod memory;
pub mod mesh;
mod mesh_gltf;
mod mesh_obj;
mod mesh_ply;
pub mod output;
pub mod region;
pub mod scene_file;
mod whole_number;

// Internals that the benchmarks and white-box tests reach into; not part of
// the API.
#[doc(hidden)]
pub mod exact;
#[doc(hidden)]
pub mod math;
#[doc(hidden)]
pub mod rng;
#[doc(hidden)]
pub mod sampling;
#[doc(hidden)]
pub mod shading;
#[doc(hidden)]
pub mod shadow;
#[doc(hidden)]
pub mod tracer;

// Internals, re-exported below where they are part of the API.
pub(crate) mod analytic;
pub(crate) mod camera;
pub(crate) mod error;
pub(crate) mod light;
pub(crate) mod live;
pub(crate) mod pixel_filter;
pub(crate) mod progressive;
pub(crate) mod reference;
pub(crate) mod sampled_lanes;
pub(crate) mod scene;
pub(crate) mod scene_transform;
pub(crate) mod settings;
pub(crate) mod shading_params;
pub(crate) mod sobol;
pub(crate) mod stats;
pub(crate) mod tile_frustum;

pub use display::{DisplayTransform, ToneCurve};
pub use error::{ImageError, SceneError};
pub use film::Film;
pub use live::{EditClass, LiveError, LiveRender, LiveReport, classify};
pub use pixel_filter::FilterKind;
pub use progressive::{
    CancelToken, Cancelled, Pass, RenderOptions, RenderReport, TileRect, TileUpdate, on_threads,
    pass_plan, render, render_image, render_region,
};
pub use reference::{
    REFERENCE_RAYS, REFERENCE_SAMPLING, REFERENCE_SEED, reference_desc, reference_scene,
};
pub use scene::{HitTarget, Loaded, PACKET_THRESHOLD, SEED_ROOM_JSON, Scene};
pub use scene_file::{AreaLightModel, Sampling, SceneDesc};
pub use settings::RenderSettings;
pub use shading_params::{LightColours, Material, ShadingParams};
pub use stats::{RayStats, SAVINGS, Saving};
