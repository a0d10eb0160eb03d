//! The scene file, as written on disk (format version 1, see
//! `shared/scene-format.md`): plain serde structs that round-trip through
//! JSON, plus the parser and validator that turn any problem into a
//! [`SceneError`] naming the field's JSON path.
//!
//! These structs are also what the viewer edits: a change is made here and
//! the runtime [`crate::render::Scene`] is rebuilt from it, so there is one
//! road from a control to the renderer and "save scene" writes exactly what
//! is rendered.

use std::collections::BTreeMap;
use std::fmt::Display;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use serde_json::Value;

use super::error::SceneError;
use super::whole_number::deserialize_whole;

/// The scene files this build reads.
pub const FORMAT_VERSION: u32 = 1;

/// Limits that protect the machine from absurd input (documented in the
/// README); the format's own ranges are checked as well.
pub mod limits {
    /// Largest scene file read, in bytes.
    pub const MAX_FILE_BYTES: u64 = 64 << 20;
    /// Most objects in one scene.
    pub const MAX_OBJECTS: usize = 1_000_000;
    /// Most materials in one scene.
    pub const MAX_MATERIALS: usize = 100_000;
    /// Largest absolute coordinate or length, in world units.
    pub const MAX_COORD: f64 = 1e9;
    /// Largest colour component, term multiplier or light intensity.
    pub const MAX_COLOUR: f64 = 1e6;
    /// Largest shininess exponent.
    pub const MAX_SHININESS: f64 = 1e6;
    /// Largest image side, in pixels (the format's own limit).
    pub const MAX_SIDE: u32 = 16384;
    /// Most shadow rays asked for per hit point.
    pub const MAX_SHADOW_RAYS: u32 = 4096;
    /// Most surface hits along one camera path.
    pub const MAX_DEPTH: u32 = 16;
    /// Most camera samples per pixel.
    pub const MAX_SAMPLES_PER_PIXEL: u32 = 1024;
    /// Smallest scene size (the largest side of the box around the camera,
    /// the light and every bounded object), in world units: below it the
    /// f32 shadow rays lose their precision (a room 2e-9 across is the
    /// last that renders right).
    pub const MIN_SCENE_SIZE: f64 = 1e-6;
    /// Farthest any point of the scene may be from the origin, in scene
    /// sizes: farther, f64 hit points lose the precision the image needs.
    pub const MAX_OFFSET: f64 = 1e6;
    /// Smallest light edge, light width, rect edge, rect width and sphere
    /// radius, in scene sizes (the `analytic` model is exact down to about
    /// 1e-12; a light 1e-200 across would go dark).
    pub const MIN_FEATURE: f64 = 1e-9;
}

/// Reads at most `limit` bytes of a file, pipe or device: the limit holds
/// before anything is buffered, whatever the file reports as its size
/// (`/dev/zero`, `/dev/stdin`, a FIFO). The message says what went wrong,
/// without the file name.
pub fn read_bounded(path: &Path, limit: u64) -> Result<Vec<u8>, String> {
    let file = std::fs::File::open(path).map_err(|e| format!("cannot read: {e}"))?;
    let meta = file.metadata().map_err(|e| format!("cannot read: {e}"))?;
    if meta.is_dir() {
        return Err("cannot read: is a directory".into());
    }
    if meta.is_file() && meta.len() > limit {
        return Err(format!(
            "file is {} bytes, at most {limit} are read",
            meta.len()
        ));
    }
    let hint = if meta.is_file() { meta.len() } else { 0 };
    read_all_bounded(file, limit, hint)
}

/// Reads a scene or mesh file of at most `limit` bytes: a regular file,
/// its type checked before a byte is read (a FIFO blocks the reader until
/// something writes to it, a device may never end); standard input only
/// when named so (`-` or `/dev/stdin`), bounded like a file. The message
/// says what went wrong, without the file name.
pub fn read_regular(path: &Path, limit: u64) -> Result<Vec<u8>, String> {
    use std::io::Read;
    if path == Path::new("-") || path == Path::new("/dev/stdin") {
        return read_all_bounded(std::io::stdin().lock(), limit, 0);
    }
    let file = open_without_blocking(path).map_err(|e| format!("cannot read: {e}"))?;
    let meta = file.metadata().map_err(|e| format!("cannot read: {e}"))?;
    if !meta.is_file() {
        return Err(format!(
            "{}, not a regular file: scenes and meshes are read from regular files \
             (standard input as `-`)",
            file_type_name(&meta.file_type())
        ));
    }
    if meta.len() > limit {
        return Err(format!(
            "file is {} bytes, at most {limit} are read",
            meta.len()
        ));
    }
    read_all_bounded(file.take(limit + 1), limit, meta.len())
}

/// Opens for reading without waiting for a FIFO's writer (a regular file
/// reads as ever).
fn open_without_blocking(path: &Path) -> std::io::Result<std::fs::File> {
    let mut options = std::fs::OpenOptions::new();
    options.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        options.custom_flags(libc::O_NONBLOCK);
    }
    options.open(path)
}

/// "a FIFO (named pipe)", "a character device", ...
fn file_type_name(t: &std::fs::FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return "a FIFO";
        }
        if t.is_char_device() {
            return "a character device";
        }
        if t.is_block_device() {
            return "a block device";
        }
        if t.is_socket() {
            return "a socket";
        }
    }
    if t.is_dir() {
        "a directory"
    } else {
        "not a file"
    }
}

fn read_all_bounded(reader: impl std::io::Read, limit: u64, hint: u64) -> Result<Vec<u8>, String> {
    use std::io::Read;
    let mut bytes = Vec::new();
    super::memory::reserve_for_file(&mut bytes, hint.min(limit))?;
    reader
        .take(limit + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| format!("cannot read: {e}"))?;
    if bytes.len() as u64 > limit {
        return Err(format!(
            "more than {limit} bytes (at most {limit} are read; stopped there)"
        ));
    }
    Ok(bytes)
}

pub type Vec3Desc = [f64; 3];

/// A whole scene file.
#[derive(Debug, Clone, Serialize)]
pub struct SceneDesc {
    pub format: u32,
    pub camera: CameraDesc,
    pub render: RenderDesc,
    pub light: LightDesc,
    pub materials: BTreeMap<String, MaterialDesc>,
    pub objects: Vec<ObjectDesc>,
    /// The folder that relative `mesh.file` paths are resolved against: the
    /// scene file's, set by [`SceneDesc::load`]; `None` for scenes from
    /// text (their meshes need absolute paths). Not part of the file.
    #[serde(skip)]
    pub base_dir: Option<PathBuf>,
}

/// Equal content: `base_dir` is where the file was read from, not part of
/// what it says, and is left out (`live::classify` compares it on its own).
impl PartialEq for SceneDesc {
    fn eq(&self, o: &SceneDesc) -> bool {
        let SceneDesc {
            format,
            camera,
            render,
            light,
            materials,
            objects,
            base_dir: _,
        } = self;
        (format, camera, render, light, materials, objects)
            == (
                &o.format,
                &o.camera,
                &o.render,
                &o.light,
                &o.materials,
                &o.objects,
            )
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraDesc {
    pub position: Vec3Desc,
    pub look_at: Vec3Desc,
    pub up: Vec3Desc,
    pub fov_y_deg: f64,
    #[serde(deserialize_with = "image_side")]
    pub width: u32,
    #[serde(deserialize_with = "image_side")]
    pub height: u32,
}

/// How shadow-ray points are placed on the light.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Sampling {
    /// n×n cell centres, n = ⌊√shadow_rays⌋ (the report's systematic rays).
    #[default]
    Grid,
    /// `shadow_rays` uniform random points.
    Random,
    /// The grid plus as many random points again.
    Mixed,
    /// One jittered point in each of the n×n grid cells.
    Stratified,
    /// `shadow_rays` points of an Owen-scrambled Sobol' sequence, scrambled
    /// afresh for every hit point.
    Sobol,
    /// The n×n grid shifted by a random toroidal offset per hit point
    /// (Cranley–Patterson rotation): the grid's bands become noise.
    RotatedGrid,
}

impl Sampling {
    pub const ALL: [Sampling; 6] = [
        Sampling::Grid,
        Sampling::Random,
        Sampling::Mixed,
        Sampling::Stratified,
        Sampling::Sobol,
        Sampling::RotatedGrid,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Sampling::Grid => "grid",
            Sampling::Random => "random",
            Sampling::Mixed => "mixed",
            Sampling::Stratified => "stratified",
            Sampling::Sobol => "sobol",
            Sampling::RotatedGrid => "rotated_grid",
        }
    }
}

/// How the diffuse and specular terms see the area light.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum AreaLightModel {
    /// Phong terms averaged over the shadow-ray points, each weighted by its
    /// visibility.
    #[default]
    Sampled,
    /// The report's method: one "optimal" light point for diffuse and one
    /// for specular, scaled by the fraction of unblocked shadow rays.
    NearestPoint,
    /// The diffuse term in closed form (the exact average of max(0, N·L)
    /// over the light's area, the `sampled` model's limit), shadowed by the
    /// ratio estimator over the shadow rays; specular as `sampled`.
    Analytic,
    /// No sampling: the visible part of the light computed from the
    /// occluders' shadows, the diffuse term integrated over it in closed
    /// form and the specular term by adaptive cubature (`sampled`'s limit).
    Exact,
}

impl AreaLightModel {
    pub const ALL: [AreaLightModel; 4] = [
        AreaLightModel::Sampled,
        AreaLightModel::NearestPoint,
        AreaLightModel::Analytic,
        AreaLightModel::Exact,
    ];

    pub fn name(self) -> &'static str {
        match self {
            AreaLightModel::Sampled => "sampled",
            AreaLightModel::NearestPoint => "nearest_point",
            AreaLightModel::Analytic => "analytic",
            AreaLightModel::Exact => "exact",
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TermsDesc {
    #[serde(default = "one")]
    pub ambient: f64,
    #[serde(default = "one")]
    pub diffuse: f64,
    #[serde(default = "one")]
    pub specular: f64,
}

impl Default for TermsDesc {
    fn default() -> Self {
        TermsDesc {
            ambient: 1.0,
            diffuse: 1.0,
            specular: 1.0,
        }
    }
}

fn one() -> f64 {
    1.0
}
fn default_shadow_rays() -> u32 {
    64
}
fn default_max_depth() -> u32 {
    4
}
fn default_seed() -> u64 {
    1
}
fn yes() -> bool {
    true
}
fn is_true(b: &bool) -> bool {
    *b
}

/// The `render` section: every field optional.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RenderDesc {
    #[serde(default = "default_shadow_rays", deserialize_with = "shadow_rays")]
    pub shadow_rays: u32,
    #[serde(default)]
    pub sampling: Sampling,
    #[serde(default = "default_max_depth", deserialize_with = "max_depth")]
    pub max_depth: u32,
    #[serde(default = "default_seed", deserialize_with = "seed")]
    pub seed: u64,
    #[serde(default)]
    pub area_light_model: AreaLightModel,
    #[serde(default)]
    pub terms: TermsDesc,
    #[serde(default)]
    pub background: Vec3Desc,
    /// Extension: `false` treats every shadow ray as unblocked (the
    /// viewer's "shadows" toggle). Omitted when true.
    #[serde(default = "yes", skip_serializing_if = "is_true")]
    pub shadows: bool,
    /// Extension: trace a few shadow rays per hit point first and the rest
    /// only where they disagree (faster, biased). Omitted when false.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub adaptive: bool,
    /// Extension: camera rays pass through planes seen from behind (a
    /// cut-away view into a room from outside; shadow and reflected rays
    /// still meet every plane). Omitted when false.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub cutaway: bool,
    /// Extension: one shininess for every material (the viewer's global
    /// override). Omitted when unset.
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        deserialize_with = "number_if_present"
    )]
    pub shininess_override: Option<f64>,
    /// Camera samples per pixel (anti-aliasing); 1: one ray through the
    /// pixel centre.
    #[serde(
        default = "one_sample",
        skip_serializing_if = "is_one_sample",
        deserialize_with = "samples_per_pixel"
    )]
    pub samples_per_pixel: u32,
}

/// The ranges of the format's whole-number fields.
mod whole_ranges {
    use super::limits::*;
    use crate::render::whole_number::WholeRange;

    pub const FORMAT: WholeRange = WholeRange::new(0, u32::MAX as u64, "");
    pub const SIDE: WholeRange = WholeRange::new(1, MAX_SIDE as u64, " pixels");
    pub const SHADOW_RAYS: WholeRange = WholeRange::new(1, MAX_SHADOW_RAYS as u64, "");
    pub const DEPTH: WholeRange = WholeRange::new(1, MAX_DEPTH as u64, "");
    pub const SEED: WholeRange = WholeRange::new(0, u64::MAX, "");
    pub const SAMPLES: WholeRange = WholeRange::new(1, MAX_SAMPLES_PER_PIXEL as u64, "");
}

/// A serde reader (`deserialize_with`) of a whole-number field of type
/// `$t` within `$range` (see `whole_number.rs`).
macro_rules! whole_field {
    ($name:ident: $t:ty, $range:expr) => {
        fn $name<'de, D: serde::Deserializer<'de>>(d: D) -> Result<$t, D::Error> {
            deserialize_whole(d, $range)
        }
    };
}
// Any version number is read; `validate` names the supported one.
whole_field!(format_version: u32, whole_ranges::FORMAT);
whole_field!(image_side: u32, whole_ranges::SIDE);
whole_field!(shadow_rays: u32, whole_ranges::SHADOW_RAYS);
whole_field!(max_depth: u32, whole_ranges::DEPTH);
whole_field!(seed: u64, whole_ranges::SEED);
whole_field!(samples_per_pixel: u32, whole_ranges::SAMPLES);

/// An optional number: absent is `None` (the field's default), `null` is
/// refused as what it is not (the format says "a number or absent").
fn number_if_present<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Option<f64>, D::Error> {
    struct Number;
    impl serde::de::Visitor<'_> for Number {
        type Value = f64;
        fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
            f.write_str("a number, or the field left out")
        }
        fn visit_f64<E>(self, v: f64) -> Result<f64, E> {
            Ok(v)
        }
        fn visit_u64<E>(self, v: u64) -> Result<f64, E> {
            Ok(v as f64)
        }
        fn visit_i64<E>(self, v: i64) -> Result<f64, E> {
            Ok(v as f64)
        }
    }
    d.deserialize_any(Number).map(Some)
}

fn one_sample() -> u32 {
    1
}
fn is_one_sample(n: &u32) -> bool {
    *n == 1
}

impl Default for RenderDesc {
    fn default() -> Self {
        RenderDesc {
            shadow_rays: default_shadow_rays(),
            sampling: Sampling::default(),
            max_depth: default_max_depth(),
            seed: default_seed(),
            area_light_model: AreaLightModel::default(),
            terms: TermsDesc::default(),
            background: [0.0; 3],
            shadows: true,
            adaptive: false,
            cutaway: false,
            shininess_override: None,
            samples_per_pixel: 1,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LightDesc {
    pub corner: Vec3Desc,
    pub edge_u: Vec3Desc,
    pub edge_v: Vec3Desc,
    pub ambient: Vec3Desc,
    pub diffuse: Vec3Desc,
    pub specular: Vec3Desc,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialDesc {
    pub ambient: Vec3Desc,
    pub diffuse: Vec3Desc,
    pub specular: Vec3Desc,
    pub shininess: f64,
    pub reflectivity: f64,
}

/// One object of the `objects` list; `type` selects the variant.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum ObjectDesc {
    Plane(PlaneDesc),
    Rect(RectDesc),
    Box(BoxDesc),
    Sphere(SphereDesc),
    Triangle(TriangleDesc),
    Mesh(MeshDesc),
}

impl ObjectDesc {
    pub fn material(&self) -> &str {
        match self {
            ObjectDesc::Plane(o) => &o.material,
            ObjectDesc::Rect(o) => &o.material,
            ObjectDesc::Box(o) => &o.material,
            ObjectDesc::Sphere(o) => &o.material,
            ObjectDesc::Triangle(o) => &o.material,
            ObjectDesc::Mesh(o) => &o.material,
        }
    }

    pub fn kind(&self) -> &'static str {
        match self {
            ObjectDesc::Plane(_) => "plane",
            ObjectDesc::Rect(_) => "rect",
            ObjectDesc::Box(_) => "box",
            ObjectDesc::Sphere(_) => "sphere",
            ObjectDesc::Triangle(_) => "triangle",
            ObjectDesc::Mesh(_) => "mesh",
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlaneDesc {
    pub point: Vec3Desc,
    pub normal: Vec3Desc,
    pub material: String,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RectDesc {
    pub corner: Vec3Desc,
    pub edge_u: Vec3Desc,
    pub edge_v: Vec3Desc,
    pub material: String,
}

fn is_zero(x: &f64) -> bool {
    *x == 0.0
}
fn is_origin(v: &Vec3Desc) -> bool {
    *v == [0.0; 3]
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoxDesc {
    pub min: Vec3Desc,
    pub max: Vec3Desc,
    #[serde(default, skip_serializing_if = "is_zero")]
    pub rotate_y_deg: f64,
    #[serde(default, skip_serializing_if = "is_origin")]
    pub translate: Vec3Desc,
    pub material: String,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SphereDesc {
    pub center: Vec3Desc,
    pub radius: f64,
    pub material: String,
}

/// Extension: one flat, two-sided triangle.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TriangleDesc {
    pub vertices: [Vec3Desc; 3],
    pub material: String,
}

/// Extension: a triangle mesh from a file (`.obj`, `.ply`), transformed
/// by `translate + R_y(rotate_y_deg) · (scale ∘ v)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshDesc {
    /// Relative to the scene file's folder, or absolute.
    pub file: String,
    pub material: String,
    #[serde(default, skip_serializing_if = "MeshScale::is_one")]
    pub scale: MeshScale,
    #[serde(default, skip_serializing_if = "is_zero")]
    pub rotate_y_deg: f64,
    #[serde(default, skip_serializing_if = "is_origin")]
    pub translate: Vec3Desc,
    #[serde(default, skip_serializing_if = "MeshShading::is_auto")]
    pub shading: MeshShading,
}

/// A mesh's scale: one factor or one per axis.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(untagged, expecting = "a number or an array of three numbers")]
pub enum MeshScale {
    Uniform(f64),
    PerAxis(Vec3Desc),
}

impl Default for MeshScale {
    fn default() -> Self {
        MeshScale::Uniform(1.0)
    }
}

impl MeshScale {
    fn is_one(&self) -> bool {
        *self == MeshScale::Uniform(1.0)
    }

    pub fn per_axis(self) -> Vec3Desc {
        match self {
            MeshScale::Uniform(s) => [s; 3],
            MeshScale::PerAxis(v) => v,
        }
    }
}

/// How a mesh is shaded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum MeshShading {
    /// The file's vertex normals on the faces that have them, the other
    /// faces flat.
    #[default]
    Auto,
    /// Face normals.
    Flat,
    /// Area-weighted vertex normals.
    Smooth,
}

impl MeshShading {
    fn is_auto(&self) -> bool {
        *self == MeshShading::Auto
    }
}

/// The top level as parsed; objects stay JSON values until their `type`
/// is known, so that errors inside them keep their full path.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScene {
    #[serde(deserialize_with = "format_version")]
    format: u32,
    camera: CameraDesc,
    #[serde(default)]
    render: RenderDesc,
    light: LightDesc,
    materials: BTreeMap<String, MaterialDesc>,
    objects: Vec<Value>,
}

fn path_error<E: std::fmt::Display>(
    prefix: &str,
    err: serde_path_to_error::Error<E>,
) -> SceneError {
    let mut inner = err.path().to_string();
    let mut message = err.inner().to_string();
    // A trailing comma leaves serde at a key it has not read: the path of
    // the object that holds it, not "render.?".
    if let Some(object) = inner.strip_suffix(".?") {
        inner = object.to_string();
    } else if inner == "?" {
        inner = ".".to_string();
    }
    // An array longer than the fixed one it fills: serde_json says
    // "trailing characters" (or, for an array of arrays, "expected fewer
    // elements in array"). Every fixed array of the format has 3 elements.
    if inner != "." {
        if let Some(rest) = message.strip_prefix("trailing characters") {
            message = format!("too many elements, expected an array of 3{rest}");
        } else if message.contains("expected fewer elements in array") {
            message = message.replace("expected fewer elements in array", "expected an array of 3");
        }
    }
    // A missing field is found at its object's end, which points nowhere
    // useful (the end of the file, for a top-level field).
    if message.starts_with("missing field")
        && let Some(at) = message.find(" at line ")
    {
        message.truncate(at);
    }
    // serde names a duplicate field in the message, at its object's path:
    // the path of the field itself is the more useful one.
    if let Some(field) = message
        .strip_prefix("duplicate field `")
        .and_then(|rest| rest.split('`').next())
    {
        inner = if inner == "." {
            field.to_string()
        } else {
            format!("{inner}.{field}")
        };
    }
    let path = match (prefix.is_empty(), inner == ".") {
        (_, true) => prefix.to_string(),
        (true, false) => inner,
        (false, false) if inner.starts_with('[') => format!("{prefix}{inner}"),
        (false, false) => format!("{prefix}.{inner}"),
    };
    SceneError::new(path, message)
}

/// Refuses an array where the format has an object (a section, a material).
fn require_objects(tree: &Value) -> Result<(), SceneError> {
    let object = |path: &str, v: Option<&Value>| match v {
        Some(v) if !v.is_object() => Err(SceneError::new(
            path,
            format!("invalid type: {}, expected an object", kind_of(v)),
        )),
        _ => Ok(()),
    };
    object("", Some(tree))?;
    for section in ["camera", "render", "light", "materials"] {
        object(section, tree.get(section))?;
    }
    object(
        "render.terms",
        tree.get("render").and_then(|r| r.get("terms")),
    )?;
    if let Some(Value::Object(materials)) = tree.get("materials") {
        for (name, m) in materials {
            object(&format!("materials.{name}"), Some(m))?;
        }
    }
    let render = tree.get("render");
    require_name::<Sampling>("render.sampling", render.and_then(|r| r.get("sampling")))?;
    require_name::<AreaLightModel>(
        "render.area_light_model",
        render.and_then(|r| r.get("area_light_model")),
    )?;
    Ok(())
}

/// Refuses a value of a named choice (`"grid"`, `"exact"`, ...) that is
/// not a string, listing the names: serde's own message for a number or a
/// null there ("expected value at line …") reads as a syntax error.
fn require_name<T: serde::de::DeserializeOwned>(
    path: &str,
    v: Option<&Value>,
) -> Result<(), SceneError> {
    match v {
        Some(v) if !v.is_string() => {
            // serde's message for an unknown name lists the known ones.
            let names = serde_json::from_value::<T>(Value::String(String::new()))
                .err()
                .map(|e| e.to_string())
                .and_then(|m| m.split_once("expected ").map(|(_, n)| n.to_string()))
                .unwrap_or_else(|| "a name".into());
            Err(SceneError::new(
                path,
                format!("invalid type: {}, expected {names}", kind_of(v)),
            ))
        }
        _ => Ok(()),
    }
}

fn kind_of(v: &Value) -> &'static str {
    match v {
        Value::Null => "null",
        Value::Bool(_) => "boolean",
        Value::Number(_) => "number",
        Value::String(_) => "string",
        Value::Array(_) => "array",
        Value::Object(_) => "object",
    }
}

fn parse_object(index: usize, value: Value) -> Result<ObjectDesc, SceneError> {
    let path = format!("objects[{index}]");
    let Value::Object(mut map) = value else {
        return Err(SceneError::new(
            path,
            "expected an object with a \"type\" field",
        ));
    };
    let kind = match map.remove("type") {
        Some(Value::String(s)) => s,
        Some(_) => return Err(SceneError::new(format!("{path}.type"), "expected a string")),
        None => {
            return Err(SceneError::new(
                path,
                "missing field `type` (one of plane, rect, box, sphere, triangle, mesh)",
            ));
        }
    };
    if kind == "mesh" {
        require_name::<MeshShading>(&format!("{path}.shading"), map.get("shading"))?;
    }
    let body = Value::Object(map);
    fn variant<T: serde::de::DeserializeOwned>(path: &str, body: Value) -> Result<T, SceneError> {
        serde_path_to_error::deserialize(body).map_err(|e| path_error(path, e))
    }
    Ok(match kind.as_str() {
        "plane" => ObjectDesc::Plane(variant(&path, body)?),
        "rect" => ObjectDesc::Rect(variant(&path, body)?),
        "box" => ObjectDesc::Box(variant(&path, body)?),
        "sphere" => ObjectDesc::Sphere(variant(&path, body)?),
        "triangle" => ObjectDesc::Triangle(variant(&path, body)?),
        "mesh" => ObjectDesc::Mesh(variant(&path, body)?),
        other => {
            return Err(SceneError::new(
                format!("{path}.type"),
                format!(
                    "unknown object type {other:?}, expected one of plane, rect, box, sphere, triangle, mesh"
                ),
            ));
        }
    })
}

impl SceneDesc {
    /// Parses and validates a scene from JSON text.
    pub fn from_json(text: &str) -> Result<SceneDesc, SceneError> {
        // A UTF-8 byte order mark (some editors write one) is skipped.
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        let mut de = serde_json::Deserializer::from_str(text);
        let typed: Result<RawScene, _> =
            serde_path_to_error::deserialize(&mut de).map_err(|e| path_error("", e));
        // serde's derive also reads a struct from an array of its fields in
        // order ("terms": [1, 0, 0]); the format has objects only. Checked
        // first, as the more basic mistake, whenever the JSON is well formed.
        if let Ok(tree) = serde_json::from_str::<Value>(text) {
            require_objects(&tree)?;
        }
        let raw = typed?;
        de.end().map_err(|e| SceneError::new("", e.to_string()))?;
        // serde keeps the last of two equal keys in a map (materials, the
        // objects' fields) without a word: refused instead.
        duplicates::check(text)?;
        if raw.objects.len() > limits::MAX_OBJECTS {
            return Err(SceneError::new(
                "objects",
                format!(
                    "{} objects, at most {} are allowed",
                    raw.objects.len(),
                    limits::MAX_OBJECTS
                ),
            ));
        }
        let objects = raw
            .objects
            .into_iter()
            .enumerate()
            .map(|(i, v)| parse_object(i, v))
            .collect::<Result<Vec<_>, _>>()?;
        let desc = SceneDesc {
            format: raw.format,
            camera: raw.camera,
            render: raw.render,
            light: raw.light,
            materials: raw.materials,
            objects,
            base_dir: None,
        };
        desc.validate()?;
        Ok(desc)
    }

    /// Reads, parses and validates a scene file; errors name the file.
    pub fn load(path: &Path) -> Result<SceneDesc, SceneError> {
        let fail = |msg: String| SceneError::new("", msg).in_file(path);
        let bytes = read_regular(path, limits::MAX_FILE_BYTES).map_err(fail)?;
        let text = String::from_utf8(bytes).map_err(|_| fail("not UTF-8 text".into()))?;
        let mut desc = SceneDesc::from_json(&text).map_err(|e| e.in_file(path))?;
        desc.base_dir = Some(match path.parent() {
            Some(dir) if !dir.as_os_str().is_empty() => dir.to_path_buf(),
            _ => PathBuf::from("."),
        });
        Ok(desc)
    }

    /// The files of the mesh objects, resolved as the loader resolves them
    /// (one it cannot resolve is left out: the load refuses it). Commands
    /// count them as inputs that no output may overwrite.
    pub fn mesh_files(&self) -> Vec<PathBuf> {
        self.objects
            .iter()
            .filter_map(|o| match o {
                ObjectDesc::Mesh(m) => super::mesh::resolve(&m.file, self.base_dir.as_deref()).ok(),
                _ => None,
            })
            .collect()
    }

    /// Pretty JSON that [`SceneDesc::from_json`] reads back to an equal scene.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("scene descriptions always serialize")
    }

    /// Checks every range and cross-reference of the format.
    pub fn validate(&self) -> Result<(), SceneError> {
        use limits::*;
        if self.format != FORMAT_VERSION {
            return Err(SceneError::new(
                "format",
                format!(
                    "unsupported format {}, expected {FORMAT_VERSION}",
                    self.format
                ),
            ));
        }
        let c = &self.camera;
        point("camera.position", c.position)?;
        point("camera.look_at", c.look_at)?;
        direction("camera.up", c.up)?;
        if !(c.fov_y_deg > 0.0 && c.fov_y_deg < 180.0) {
            return Err(SceneError::new(
                "camera.fov_y_deg",
                format!(
                    "{} is out of range, expected degrees in (0, 180)",
                    num(c.fov_y_deg)
                ),
            ));
        }
        for (name, v) in [("width", c.width), ("height", c.height)] {
            if !(1..=MAX_SIDE).contains(&v) {
                return Err(SceneError::new(
                    format!("camera.{name}"),
                    whole_ranges::SIDE.out_of_range(v),
                ));
            }
        }
        let view = sub(c.look_at, c.position);
        if norm(view) <= 1e-12 * (norm(c.position) + norm(c.look_at)).max(f64::MIN_POSITIVE) {
            return Err(SceneError::new(
                "camera.look_at",
                "equals camera.position: the view direction is undefined",
            ));
        }
        if sin_angle(view, c.up) < 1e-9 {
            return Err(SceneError::new(
                "camera.up",
                "is parallel to the view direction (look_at - position): the image's orientation is undefined",
            ));
        }

        let r = &self.render;
        if !(1..=limits::MAX_SHADOW_RAYS).contains(&r.shadow_rays) {
            return Err(SceneError::new(
                "render.shadow_rays",
                whole_ranges::SHADOW_RAYS.out_of_range(r.shadow_rays),
            ));
        }
        if !(1..=limits::MAX_DEPTH).contains(&r.max_depth) {
            return Err(SceneError::new(
                "render.max_depth",
                whole_ranges::DEPTH.out_of_range(r.max_depth),
            ));
        }
        for (name, v) in [
            ("ambient", r.terms.ambient),
            ("diffuse", r.terms.diffuse),
            ("specular", r.terms.specular),
        ] {
            scalar(format_args!("render.terms.{name}"), v, 0.0, MAX_COLOUR)?;
        }
        colour("render.background", r.background)?;
        if let Some(s) = r.shininess_override {
            positive("render.shininess_override", s, MAX_SHININESS)?;
        }
        if !(1..=limits::MAX_SAMPLES_PER_PIXEL).contains(&r.samples_per_pixel) {
            return Err(SceneError::new(
                "render.samples_per_pixel",
                whole_ranges::SAMPLES.out_of_range(r.samples_per_pixel),
            ));
        }
        let l = &self.light;
        point("light.corner", l.corner)?;
        parallelogram("light", l.edge_u, l.edge_v)?;
        colour("light.ambient", l.ambient)?;
        colour("light.diffuse", l.diffuse)?;
        colour("light.specular", l.specular)?;

        if self.materials.len() > MAX_MATERIALS {
            return Err(SceneError::new(
                "materials",
                format!(
                    "{} materials, at most {MAX_MATERIALS} are allowed",
                    self.materials.len()
                ),
            ));
        }
        for (name, m) in &self.materials {
            let p = format!("materials.{name}");
            colour(format_args!("{p}.ambient"), m.ambient)?;
            colour(format_args!("{p}.diffuse"), m.diffuse)?;
            colour(format_args!("{p}.specular"), m.specular)?;
            positive(format_args!("{p}.shininess"), m.shininess, MAX_SHININESS)?;
            scalar(format_args!("{p}.reflectivity"), m.reflectivity, 0.0, 1.0)?;
        }

        if self.objects.len() > MAX_OBJECTS {
            return Err(SceneError::new(
                "objects",
                format!(
                    "{} objects, at most {MAX_OBJECTS} are allowed",
                    self.objects.len()
                ),
            ));
        }
        for (i, o) in self.objects.iter().enumerate() {
            let p = ObjectPath(i);
            if !self.materials.contains_key(o.material()) {
                let known: Vec<&str> = self.materials.keys().map(String::as_str).take(20).collect();
                return Err(SceneError::new(
                    format!("{p}.material"),
                    format!(
                        "unknown material {:?}, expected one of: {}",
                        o.material(),
                        known.join(", ")
                    ),
                ));
            }
            match o {
                ObjectDesc::Plane(pl) => {
                    point(format_args!("{p}.point"), pl.point)?;
                    direction(format_args!("{p}.normal"), pl.normal)?;
                }
                ObjectDesc::Rect(rc) => {
                    point(format_args!("{p}.corner"), rc.corner)?;
                    parallelogram(&p, rc.edge_u, rc.edge_v)?;
                }
                ObjectDesc::Box(b) => {
                    point(format_args!("{p}.min"), b.min)?;
                    point(format_args!("{p}.max"), b.max)?;
                    for axis in 0..3 {
                        if b.min[axis] > b.max[axis] {
                            return Err(SceneError::new(
                                format!("{p}.min[{axis}]"),
                                format!(
                                    "min {} is greater than max {}: expected min <= max on every axis",
                                    num(b.min[axis]),
                                    num(b.max[axis])
                                ),
                            ));
                        }
                    }
                    scalar(format_args!("{p}.rotate_y_deg"), b.rotate_y_deg, -1e6, 1e6)?;
                    point(format_args!("{p}.translate"), b.translate)?;
                }
                ObjectDesc::Sphere(s) => {
                    point(format_args!("{p}.center"), s.center)?;
                    positive(format_args!("{p}.radius"), s.radius, MAX_COORD)?;
                }
                ObjectDesc::Triangle(t) => {
                    for (k, v) in t.vertices.iter().enumerate() {
                        point(format_args!("{p}.vertices[{k}]"), *v)?;
                    }
                }
                ObjectDesc::Mesh(m) => {
                    if m.file.trim().is_empty() {
                        return Err(SceneError::new(
                            format!("{p}.file"),
                            "is empty, expected the path of a .obj, .ply, .gltf or .glb file",
                        ));
                    }
                    match m.scale {
                        MeshScale::Uniform(s) => positive(format_args!("{p}.scale"), s, MAX_COORD)?,
                        MeshScale::PerAxis(v) => {
                            for (k, s) in v.iter().enumerate() {
                                positive(format_args!("{p}.scale[{k}]"), *s, MAX_COORD)?;
                            }
                        }
                    }
                    scalar(format_args!("{p}.rotate_y_deg"), m.rotate_y_deg, -1e6, 1e6)?;
                    point(format_args!("{p}.translate"), m.translate)?;
                }
            }
        }
        self.check_numeric_range()
    }

    /// The scene's size: the largest side of the axis-aligned box around
    /// the camera, the light and every bounded object (planes left out),
    /// and the largest absolute coordinate of those and of the planes'
    /// points. Assumes the fields themselves are valid.
    pub fn size_and_offset(&self) -> (f64, f64) {
        let (lo, hi) = self.bounds(None);
        let mut offset = 0.0f64;
        for o in &self.objects {
            match o {
                ObjectDesc::Plane(pl) => offset = offset.max(max_abs(pl.point)),
                // Its vertices are only known once the file is read; the
                // mesh's own checks bound them (`mesh.rs`).
                ObjectDesc::Mesh(m) => offset = offset.max(max_abs(m.translate)),
                _ => {}
            }
        }
        let offset = (0..3).fold(offset, |m, i| m.max(lo[i].abs()).max(hi[i].abs()));
        (side(lo, hi), offset)
    }

    /// The box around the camera, the light and every bounded object,
    /// leaving `left_out` out.
    fn bounds(&self, left_out: Option<SizePart>) -> (Vec3Desc, Vec3Desc) {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        self.for_each_extent(|part, a, b| {
            if Some(part) != left_out {
                for i in 0..3 {
                    lo[i] = lo[i].min(a[i]);
                    hi[i] = hi[i].max(b[i]);
                }
            }
        });
        (lo, hi)
    }

    /// Calls `f` with the box around each part that sets the scene's size:
    /// the camera's position, the light and every bounded object.
    fn for_each_extent(&self, mut f: impl FnMut(SizePart, Vec3Desc, Vec3Desc)) {
        let (lo, hi) = box_around(&[self.camera.position]);
        f(SizePart::Camera, lo, hi);
        let l = &self.light;
        let (lo, hi) = box_around(&corners(l.corner, l.edge_u, l.edge_v));
        f(SizePart::Light, lo, hi);
        for (i, o) in self.objects.iter().enumerate() {
            let extent = match o {
                ObjectDesc::Plane(_) | ObjectDesc::Mesh(_) => continue,
                ObjectDesc::Rect(r) => box_around(&corners(r.corner, r.edge_u, r.edge_v)),
                ObjectDesc::Box(b) => {
                    // The exact bounds of the box rotated about its centre.
                    let (sin, cos) = b.rotate_y_deg.to_radians().sin_cos();
                    let h = [
                        (b.max[0] - b.min[0]) * 0.5,
                        (b.max[1] - b.min[1]) * 0.5,
                        (b.max[2] - b.min[2]) * 0.5,
                    ];
                    let centre = [
                        (b.min[0] + b.max[0]) * 0.5 + b.translate[0],
                        (b.min[1] + b.max[1]) * 0.5 + b.translate[1],
                        (b.min[2] + b.max[2]) * 0.5 + b.translate[2],
                    ];
                    let r = [
                        cos.abs() * h[0] + sin.abs() * h[2],
                        h[1],
                        sin.abs() * h[0] + cos.abs() * h[2],
                    ];
                    (sub(centre, r), add(centre, r))
                }
                ObjectDesc::Sphere(s) => {
                    let r = [s.radius; 3];
                    (sub(s.center, r), add(s.center, r))
                }
                ObjectDesc::Triangle(t) => box_around(&t.vertices),
            };
            f(SizePart::Object(i), extent.0, extent.1);
        }
    }

    /// The one part other than `other_than` without which the scene would
    /// be smallest, and its size then, where leaving a part out shrinks
    /// it: what makes the scene as large as it is, for the message of a
    /// feature below the floor that size sets. Only parts that reach a
    /// side of the box can shrink it; a handful are tried.
    fn what_sets_the_size(&self, other_than: SizePart) -> Option<(SizePart, f64)> {
        let (lo, hi) = self.bounds(None);
        let size = side(lo, hi);
        let mut reaching: Vec<SizePart> = Vec::new();
        self.for_each_extent(|part, a, b| {
            if part != other_than
                && reaching.len() < 12
                && (0..3).any(|i| a[i] == lo[i] || b[i] == hi[i])
            {
                reaching.push(part);
            }
        });
        reaching
            .into_iter()
            .map(|part| {
                let (lo, hi) = self.bounds(Some(part));
                (part, side(lo, hi))
            })
            .filter(|&(_, without)| without < size)
            .min_by(|a, b| a.1.total_cmp(&b.1))
    }

    /// A part of the scene by its place in the file, as a message names it
    /// (`objects[9], a sphere of radius 1e9`).
    fn describe(&self, part: SizePart) -> String {
        match part {
            SizePart::Camera => "camera.position".into(),
            SizePart::Light => "the light".into(),
            SizePart::Object(i) => match &self.objects[i] {
                ObjectDesc::Sphere(s) => {
                    format!("objects[{i}], a sphere of radius {}", sig(s.radius))
                }
                ObjectDesc::Rect(_) => format!("objects[{i}], a rect"),
                ObjectDesc::Box(_) => format!("objects[{i}], a box"),
                ObjectDesc::Triangle(_) => format!("objects[{i}], a triangle"),
                ObjectDesc::Plane(_) | ObjectDesc::Mesh(_) => format!("objects[{i}]"),
            },
        }
    }

    /// The numeric range the renderer supports (`limits::MIN_SCENE_SIZE`,
    /// `MAX_OFFSET`, `MIN_FEATURE`): inside it images match the same scene
    /// at scale 1 at the origin; outside it the scene is refused.
    fn check_numeric_range(&self) -> Result<(), SceneError> {
        use limits::*;
        let (size, offset) = self.size_and_offset();
        if size < MIN_SCENE_SIZE {
            return Err(SceneError::new(
                "",
                format!(
                    "the scene is {} across (the box around camera.position, the light and the bounded objects), \
                     at least {MIN_SCENE_SIZE:e} is supported: scale it up",
                    sig(size)
                ),
            ));
        }
        if offset > MAX_OFFSET * size {
            let (path, v) = self.farthest_coordinate();
            return Err(SceneError::new(
                path,
                format!(
                    "{} is {} scene sizes from the origin (the scene is {} across), \
                     at most {MAX_OFFSET:e} are supported: move the scene towards the origin",
                    sig(v),
                    sig((v.abs() / size).round()),
                    sig(size)
                ),
            ));
        }
        let least = MIN_FEATURE * size;
        let small = |part: SizePart,
                     path: std::fmt::Arguments<'_>,
                     what: &str,
                     v: f64|
         -> Result<(), SceneError> {
            if v >= least {
                return Ok(());
            }
            let mut message = format!(
                "{what} {} is below the smallest supported size, {MIN_FEATURE:e} of the scene's size {} = {}",
                sig(v),
                sig(size),
                sig(least)
            );
            // A feature of an ordinary size may be below the floor only
            // because another part makes the scene huge: that one is named.
            if let Some((large, without)) = self.what_sets_the_size(part)
                && v >= MIN_FEATURE * without
            {
                message += &format!(
                    "; the scene is that large because of {} ({} across without it): \
                     make that smaller or this larger",
                    self.describe(large),
                    sig(without)
                );
            }
            Err(SceneError::new(path.to_string(), message))
        };
        let flat = |part: SizePart,
                    path: &dyn Display,
                    u: Vec3Desc,
                    v: Vec3Desc|
         -> Result<(), SceneError> {
            let (nu, nv) = (norm(u), norm(v));
            small(part, format_args!("{path}.edge_u"), "length", nu)?;
            small(part, format_args!("{path}.edge_v"), "length", nv)?;
            // Width across the longer edge: area / longer edge.
            let width = nu.min(nv) * sin_angle(u, v);
            small(
                part,
                format_args!("{path}.edge_v"),
                "width (area / longer edge)",
                width,
            )
        };
        flat(
            SizePart::Light,
            &"light",
            self.light.edge_u,
            self.light.edge_v,
        )?;
        for (i, o) in self.objects.iter().enumerate() {
            let part = SizePart::Object(i);
            match o {
                ObjectDesc::Rect(r) => flat(part, &ObjectPath(i), r.edge_u, r.edge_v)?,
                ObjectDesc::Sphere(s) => small(
                    part,
                    format_args!("objects[{i}].radius"),
                    "radius",
                    s.radius,
                )?,
                ObjectDesc::Plane(_)
                | ObjectDesc::Box(_)
                | ObjectDesc::Triangle(_)
                | ObjectDesc::Mesh(_) => {}
            }
        }
        Ok(())
    }

    /// The path and value of the coordinate farthest from the origin, for
    /// the message of a scene too far from it.
    fn farthest_coordinate(&self) -> (String, f64) {
        let mut best = (String::new(), 0.0f64);
        let mut consider = |path: String, v: Vec3Desc| {
            for (i, x) in v.iter().enumerate() {
                if x.abs() > best.1.abs() {
                    best = (format!("{path}[{i}]"), *x);
                }
            }
        };
        consider("camera.position".into(), self.camera.position);
        consider("light.corner".into(), self.light.corner);
        for (i, o) in self.objects.iter().enumerate() {
            let p = format!("objects[{i}]");
            match o {
                ObjectDesc::Plane(pl) => consider(format!("{p}.point"), pl.point),
                ObjectDesc::Rect(r) => consider(format!("{p}.corner"), r.corner),
                ObjectDesc::Box(b) => {
                    consider(format!("{p}.min"), b.min);
                    consider(format!("{p}.max"), b.max);
                    consider(format!("{p}.translate"), b.translate);
                }
                ObjectDesc::Sphere(s) => consider(format!("{p}.center"), s.center),
                ObjectDesc::Triangle(t) => {
                    for (k, v) in t.vertices.iter().enumerate() {
                        consider(format!("{p}.vertices[{k}]"), *v);
                    }
                }
                ObjectDesc::Mesh(m) => consider(format!("{p}.translate"), m.translate),
            }
        }
        best
    }
}

/// A part of the scene that sets its size (see
/// [`SceneDesc::size_and_offset`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum SizePart {
    Camera,
    Light,
    Object(usize),
}

/// The smallest box around `points`.
fn box_around(points: &[Vec3Desc]) -> (Vec3Desc, Vec3Desc) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in points {
        for i in 0..3 {
            lo[i] = lo[i].min(p[i]);
            hi[i] = hi[i].max(p[i]);
        }
    }
    (lo, hi)
}

/// The largest side of the box `lo`..`hi` (0 for an empty one).
fn side(lo: Vec3Desc, hi: Vec3Desc) -> f64 {
    (0..3).map(|i| hi[i] - lo[i]).fold(0.0, f64::max)
}

fn add(a: Vec3Desc, b: Vec3Desc) -> Vec3Desc {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn corners(c: Vec3Desc, u: Vec3Desc, v: Vec3Desc) -> [Vec3Desc; 4] {
    [c, add(c, u), add(add(c, u), v), add(c, v)]
}

fn max_abs(v: Vec3Desc) -> f64 {
    v.iter().fold(0.0f64, |m, x| m.max(x.abs()))
}

/// Duplicate keys: a walk over the whole document that refuses the second
/// of two equal keys in any object, naming its path.
mod duplicates {
    use std::cell::RefCell;
    use std::collections::HashSet;
    use std::fmt;

    use serde::de::{DeserializeSeed, Deserializer, Error, MapAccess, SeqAccess, Visitor};

    use super::SceneError;

    enum Segment {
        Key(String),
        Index(usize),
    }

    #[derive(Default)]
    struct State {
        path: Vec<Segment>,
        found: Option<SceneError>,
    }

    impl State {
        fn path_with(&self, last: &str) -> String {
            let mut out = String::new();
            for s in self
                .path
                .iter()
                .chain(std::iter::once(&Segment::Key(last.into())))
            {
                match s {
                    Segment::Key(k) if out.is_empty() => out.push_str(k),
                    Segment::Key(k) => {
                        out.push('.');
                        out.push_str(k);
                    }
                    Segment::Index(i) => out.push_str(&format!("[{i}]")),
                }
            }
            out
        }
    }

    struct Walk<'a>(&'a RefCell<State>);

    impl<'de> DeserializeSeed<'de> for Walk<'_> {
        type Value = ();
        fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
            d.deserialize_any(self)
        }
    }

    impl<'de> Visitor<'de> for Walk<'_> {
        type Value = ();
        fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
            f.write_str("any JSON value")
        }
        fn visit_bool<E>(self, _: bool) -> Result<(), E> {
            Ok(())
        }
        fn visit_i64<E>(self, _: i64) -> Result<(), E> {
            Ok(())
        }
        fn visit_u64<E>(self, _: u64) -> Result<(), E> {
            Ok(())
        }
        fn visit_f64<E>(self, _: f64) -> Result<(), E> {
            Ok(())
        }
        fn visit_str<E>(self, _: &str) -> Result<(), E> {
            Ok(())
        }
        fn visit_unit<E>(self) -> Result<(), E> {
            Ok(())
        }
        fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<(), A::Error> {
            let mut i = 0;
            loop {
                self.0.borrow_mut().path.push(Segment::Index(i));
                let more = seq.next_element_seed(Walk(self.0))?.is_some();
                self.0.borrow_mut().path.pop();
                if !more {
                    return Ok(());
                }
                i += 1;
            }
        }
        fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<(), A::Error> {
            let mut seen = HashSet::new();
            while let Some(key) = map.next_key::<String>()? {
                if seen.contains(&key) {
                    let mut state = self.0.borrow_mut();
                    let path = state.path_with(&key);
                    let what = if state.path.len() == 1
                        && matches!(&state.path[0], Segment::Key(k) if k == "materials")
                    {
                        "duplicate material name"
                    } else {
                        "duplicate key"
                    };
                    state.found = Some(SceneError::new(
                        path,
                        format!("{what} {key:?}: each may appear only once in its object"),
                    ));
                    return Err(A::Error::custom("duplicate key"));
                }
                self.0.borrow_mut().path.push(Segment::Key(key.clone()));
                map.next_value_seed(Walk(self.0))?;
                self.0.borrow_mut().path.pop();
                seen.insert(key);
            }
            Ok(())
        }
    }

    /// Refuses a document with two equal keys in one object. Other errors
    /// are left to the typed parse, which has run before.
    pub fn check(text: &str) -> Result<(), SceneError> {
        let state = RefCell::new(State::default());
        let mut de = serde_json::Deserializer::from_str(text);
        let result = Walk(&state).deserialize(&mut de);
        match (result, state.into_inner().found) {
            (_, Some(e)) => Err(e),
            _ => Ok(()),
        }
    }
}

fn sub(a: Vec3Desc, b: Vec3Desc) -> Vec3Desc {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn cross(a: Vec3Desc, b: Vec3Desc) -> Vec3Desc {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn norm(a: Vec3Desc) -> f64 {
    // hypot-style: no overflow or underflow for any finite input.
    let m = a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if m == 0.0 {
        return 0.0;
    }
    let s = [a[0] / m, a[1] / m, a[2] / m];
    m * (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt()
}
/// Sine of the angle between two non-zero vectors (scale-free).
fn sin_angle(a: Vec3Desc, b: Vec3Desc) -> f64 {
    let (na, nb) = (norm(a), norm(b));
    if na == 0.0 || nb == 0.0 {
        return 0.0;
    }
    let a = [a[0] / na, a[1] / na, a[2] / na];
    let b = [b[0] / nb, b[1] / nb, b[2] / nb];
    norm(cross(a, b))
}

/// A number for a message: as written when of ordinary size, in exponent
/// form when huge or tiny (1e308 would otherwise print as 309 digits).
pub(super) fn num(v: f64) -> String {
    if v == 0.0 || !v.is_finite() || (1e-4..=1e9).contains(&v.abs()) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

/// `objects[i]`, the path of an object, written only when printed.
struct ObjectPath(usize);

impl Display for ObjectPath {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "objects[{}]", self.0)
    }
}

/// A measured number for a message: four significant digits.
fn sig(v: f64) -> String {
    format!("{v:.3e}")
}

// The checks take their field's path as anything that prints it, so that
// an object's paths are written only for a message: as strings they were
// most of `validate`'s time (0.17 s for 750 000 spheres, now 0.035 s), and
// the viewer validates the scene on every edit.

fn scalar(path: impl Display, v: f64, lo: f64, hi: f64) -> Result<(), SceneError> {
    if v.is_finite() && v >= lo && v <= hi {
        Ok(())
    } else {
        Err(SceneError::new(
            path.to_string(),
            format!(
                "{} is out of range, expected a number in [{lo}, {hi}]",
                num(v)
            ),
        ))
    }
}

fn positive(path: impl Display, v: f64, hi: f64) -> Result<(), SceneError> {
    if v.is_finite() && v > 0.0 && v <= hi {
        Ok(())
    } else {
        Err(SceneError::new(
            path.to_string(),
            format!(
                "{} is out of range, expected a number > 0 and <= {hi}",
                num(v)
            ),
        ))
    }
}

fn point(path: impl Display, v: Vec3Desc) -> Result<(), SceneError> {
    for (i, x) in v.iter().enumerate() {
        if !(x.is_finite() && x.abs() <= limits::MAX_COORD) {
            return Err(SceneError::new(
                format!("{path}[{i}]"),
                format!(
                    "{} is out of range, expected a coordinate within ±{:e}",
                    num(*x),
                    limits::MAX_COORD
                ),
            ));
        }
    }
    Ok(())
}

fn direction(path: impl Display, v: Vec3Desc) -> Result<(), SceneError> {
    point(&path, v)?;
    if norm(v) == 0.0 {
        return Err(SceneError::new(
            path.to_string(),
            "is the zero vector, expected a non-zero direction",
        ));
    }
    Ok(())
}

fn colour(path: impl Display, v: Vec3Desc) -> Result<(), SceneError> {
    for (i, x) in v.iter().enumerate() {
        scalar(format_args!("{path}[{i}]"), *x, 0.0, limits::MAX_COLOUR)?;
    }
    Ok(())
}

/// A parallelogram (light or rect): edges non-zero and not parallel.
fn parallelogram(path: impl Display, u: Vec3Desc, v: Vec3Desc) -> Result<(), SceneError> {
    point(format_args!("{path}.edge_u"), u)?;
    point(format_args!("{path}.edge_v"), v)?;
    let pu = || format!("{path}.edge_u");
    let pv = || format!("{path}.edge_v");
    if norm(u) == 0.0 {
        return Err(SceneError::new(
            pu(),
            "is the zero vector: the area is zero",
        ));
    }
    if norm(v) == 0.0 {
        return Err(SceneError::new(
            pv(),
            "is the zero vector: the area is zero",
        ));
    }
    if sin_angle(u, v) < 1e-9 {
        return Err(SceneError::new(
            pv(),
            "is parallel to edge_u: the area is zero, expected two independent edges",
        ));
    }
    Ok(())
}
