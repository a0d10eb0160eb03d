//! Viewer toggles that are not fields of the scene file but map onto it:
//! the term checkboxes keep the slider's strength while a term is off,
//! "reflections" keeps the chosen depth, and the resolution scale shrinks
//! the image for a faster preview; hidden objects (the object list's
//! toggles) are left out. [`ViewSettings::apply`] is the only place
//! they meet the scene.

use crate::render::SceneDesc;

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

    /// The scene to render: `desc` with the toggles applied, at the
    /// resolution scale (`full`: at the scene's own size, for export and
    /// "save scene").
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
            let s = self.resolution_scale;
            let side = |v: u32| ((v as f64 * s).round() as u32).clamp(1, 16384);
            d.camera.width = side(desc.camera.width);
            d.camera.height = side(desc.camera.height);
        }
        d
    }
}
