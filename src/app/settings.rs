//! Viewer toggles that are not fields of the scene file but map onto it:
//! the term checkboxes keep the slider's strength while a term is off,
//! "reflections" keeps the chosen depth, and the resolution scale shrinks
//! the image for a faster preview; hidden objects (the object list's
//! toggles) are left out; the preview never exceeds a display's pixels
//! ([`PREVIEW_MAX_PIXELS`]). [`ViewSettings::apply`] is the only place
//! they meet the scene.

use crate::render::{SceneDesc, SceneError};

/// The most pixels the viewer renders and shows (a 4K screen's): a larger
/// scene is previewed at this many, its proportions kept, and written at
/// its own size by *Save PNG*. At the format's 16384² the image's buffers
/// (the render's film, the viewer's copy, the texture) took about 13 GB,
/// filled and uploaded on the UI thread for 39 s.
pub const PREVIEW_MAX_PIXELS: u64 = 3840 * 2160;

/// The longest side the viewer previews (a texture's size every GPU takes).
pub const PREVIEW_MAX_SIDE: u32 = 4096;

/// `width`×`height` shrunk (proportions kept) to at most
/// [`PREVIEW_MAX_PIXELS`] pixels and [`PREVIEW_MAX_SIDE`] a side.
pub fn preview_size(width: u32, height: u32) -> (u32, u32) {
    let (w, h) = (width.max(1) as f64, height.max(1) as f64);
    let by_area = (PREVIEW_MAX_PIXELS as f64 / (w * h)).sqrt();
    let by_side = PREVIEW_MAX_SIDE as f64 / w.max(h);
    let s = by_area.min(by_side);
    if s >= 1.0 {
        return (width.max(1), height.max(1));
    }
    // Rounded down, so the product stays within the limit.
    let side = |v: f64| ((v * s).floor() as u32).max(1);
    (side(w), side(h))
}

#[derive(Debug, Clone, PartialEq)]
pub struct ViewSettings {
    pub ambient: bool,
    pub diffuse: bool,
    pub specular: bool,
    /// Off: `max_depth` 1, no mirrored rays.
    pub reflections: bool,
    /// Image size relative to the scene's camera.
    pub resolution_scale: f64,
    /// The shininess override's slider value, kept while it is switched off.
    pub shininess: f64,
    /// Indices of the objects hidden in the object list (sorted).
    pub hidden: Vec<usize>,
}

impl ViewSettings {
    pub const SCALE_RANGE: std::ops::RangeInclusive<f64> = 0.1..=2.0;

    /// Settings that leave `desc` as it is.
    pub fn for_scene(desc: &SceneDesc) -> ViewSettings {
        ViewSettings {
            ambient: true,
            diffuse: true,
            specular: true,
            reflections: true,
            resolution_scale: 1.0,
            shininess: desc.render.shininess_override.unwrap_or(50.0),
            hidden: Vec::new(),
        }
    }

    /// What "Save scene" writes other than the scene as edited, since the
    /// file renders the image shown and the format has no toggles or
    /// hidden objects; `None` if nothing.
    pub fn save_note(&self) -> Option<String> {
        let mut differences = Vec::new();
        match self.hidden.len() {
            0 => {}
            1 => differences.push("the hidden object left out".to_string()),
            n => differences.push(format!("the {n} hidden objects left out")),
        }
        let off: Vec<&str> = [
            (self.ambient, "ambient"),
            (self.diffuse, "diffuse"),
            (self.specular, "specular"),
        ]
        .into_iter()
        .filter_map(|(on, term)| (!on).then_some(term))
        .collect();
        if !off.is_empty() {
            differences.push(format!("{} strength written as 0", off.join(", ")));
        }
        if !self.reflections {
            differences.push("max depth written as 1 (reflections off)".into());
        }
        (!differences.is_empty()).then(|| {
            format!(
                "The file renders the image shown: {}.",
                differences.join("; ")
            )
        })
    }

    /// The scene to render: `desc` with the toggles applied, at the
    /// resolution scale within the preview's limit (`full`: at the scene's
    /// own size, for export and "save scene").
    /// `self.apply(desc, full) == *other`, without copying the objects
    /// (the viewer asks every frame; a scene may hold 10⁶ of them).
    pub fn applied_equals(&self, desc: &SceneDesc, full: bool, other: &SceneDesc) -> bool {
        let head = |d: &SceneDesc| SceneDesc {
            format: d.format,
            camera: d.camera.clone(),
            render: d.render.clone(),
            light: d.light.clone(),
            materials: Default::default(),
            objects: Vec::new(),
            base_dir: None,
        };
        desc.objects == other.objects
            && desc.materials == other.materials
            && self.apply(&head(desc), full) == head(other)
    }

    pub fn apply(&self, desc: &SceneDesc, full: bool) -> SceneDesc {
        let mut d = desc.clone();
        let t = &mut d.render.terms;
        if !self.ambient {
            t.ambient = 0.0;
        }
        if !self.diffuse {
            t.diffuse = 0.0;
        }
        if !self.specular {
            t.specular = 0.0;
        }
        if !self.reflections {
            d.render.max_depth = 1;
        }
        if !self.hidden.is_empty() {
            let mut i = 0;
            d.objects.retain(|_| {
                i += 1;
                !self.hidden.contains(&(i - 1))
            });
        }
        if !full {
            (d.camera.width, d.camera.height) =
                self.apply_size(desc.camera.width, desc.camera.height);
        }
        d
    }

    /// The preview's size for a scene of `width`×`height`: at the
    /// resolution scale, within the preview's limit.
    pub fn apply_size(&self, width: u32, height: u32) -> (u32, u32) {
        let s = self.resolution_scale;
        let side = |v: u32| ((v as f64 * s).round() as u32).clamp(1, 16384);
        preview_size(side(width), side(height))
    }
}

/// `error` of the scene shown (hidden objects left out), with the objects
/// it names (`objects[2]`, counted among the objects shown: its path, and
/// the object a size limit blames) named by their place in the scene as
/// edited, which also holds the `hidden` ones: the place the object list
/// and the scene file give them.
pub fn numbered_as_edited(mut error: SceneError, hidden: &[usize]) -> SceneError {
    if hidden.is_empty() {
        return error;
    }
    if let Some(path) = renumbered_after(&error.path, "", hidden) {
        error.path = path;
    }
    // Scene-size limits name the object that makes the scene that large.
    if let Some(message) = renumbered_after(&error.message, "because of ", hidden) {
        error.message = message;
    }
    error
}

/// `text` with the object index of the first `{before}objects[i]` in it
/// counted in the scene with the `hidden` objects; `None` if there is
/// none.
fn renumbered_after(text: &str, before: &str, hidden: &[usize]) -> Option<String> {
    let marker = format!("{before}objects[");
    let at = text.find(&marker)? + marker.len();
    let (index, tail) = text[at..].split_once(']')?;
    let shown = index.parse::<usize>().ok()?;
    // `hidden` is sorted: each hidden index at or before the object moves it on.
    let mut index = shown;
    for &h in hidden {
        if h <= index {
            index += 1;
        }
    }
    Some(format!("{}{index}]{tail}", &text[..at]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_error_names_objects_by_their_place_among_the_hidden_ones() {
        let error = SceneError::new(
            "objects[1].radius",
            "x is small; the scene is that large because of objects[2], a sphere",
        );
        let e = numbered_as_edited(error.clone(), &[0, 2, 5]);
        assert_eq!(e.path, "objects[3].radius");
        assert_eq!(
            e.message,
            "x is small; the scene is that large because of objects[4], a sphere"
        );
        assert_eq!(numbered_as_edited(error.clone(), &[]), error);
        let whole = SceneError::new("light.edge_u", "too small");
        assert_eq!(numbered_as_edited(whole.clone(), &[0]), whole);
    }

    #[test]
    fn a_preview_larger_than_a_display_is_shrunk_with_its_proportions() {
        assert_eq!(preview_size(960, 540), (960, 540));
        assert_eq!(preview_size(3840, 2160), (3840, 2160));
        assert_eq!(preview_size(7680, 4320), (3840, 2160));
        let (w, h) = preview_size(16384, 16384);
        assert_eq!(w, h);
        assert!(w as u64 * h as u64 <= PREVIEW_MAX_PIXELS && w > 2800, "{w}");
        // A thin strip: its long side, not its area, is the limit.
        assert_eq!(preview_size(16384, 16), (4096, 4));
        assert_eq!(preview_size(16384, 1), (4096, 1));
    }

    #[test]
    fn the_scale_applies_before_the_limit_and_never_to_the_full_size() {
        let mut desc = SceneDesc::from_json(crate::render::SEED_ROOM_JSON).unwrap();
        desc.camera.width = 16384;
        desc.camera.height = 8192;
        let mut view = ViewSettings::for_scene(&desc);
        let preview = view.apply(&desc, false).camera;
        assert_eq!((preview.width, preview.height), preview_size(16384, 8192));
        view.resolution_scale = 0.1;
        let small = view.apply(&desc, false).camera;
        assert_eq!((small.width, small.height), (1638, 819));
        let full = view.apply(&desc, true).camera;
        assert_eq!((full.width, full.height), (16384, 8192));
    }
}
