//! What an edit of a scene description invalidates: the one place that
//! knows, for every field of the format, how much of a render survives a
//! change of it.

use crate::render::scene_file::{
    CameraDesc, LightDesc, MaterialDesc, RenderDesc, SceneDesc, TermsDesc,
};

/// How much of the last render an edit leaves valid, from least to most
/// work. A list of edits costs the largest class among them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum EditClass {
    /// Nothing the image depends on changed.
    Nothing,
    /// Term toggles and strengths, the background, the light's colours and
    /// intensity, material colours: the image is linear in them, so the
    /// recorded light factors are combined again. No rays.
    Recombine,
    /// Shininess (of a material or the override) and reflectivity: the
    /// recorded visibility gives the specular factors again, and only the
    /// paths a reflectivity edit lengthens are traced.
    Reshade,
    /// The light's position or size (with any of the edits above): the
    /// camera paths stand, so each hit's light is traced again over the
    /// recorded paths, intersecting only the rays the new light may cut
    /// (`relight.rs`).
    Relight,
    /// The camera, shadow rays, sampling, model, depth, seed, shadows,
    /// adaptive, cut-away, samples per pixel: the objects and their BVH
    /// stand, every pixel is traced.
    Retrace,
    /// Objects, the set of materials: the scene is built again and every
    /// pixel traced.
    Rebuild,
}

impl EditClass {
    pub const ALL: [EditClass; 6] = [
        EditClass::Nothing,
        EditClass::Recombine,
        EditClass::Reshade,
        EditClass::Relight,
        EditClass::Retrace,
        EditClass::Rebuild,
    ];

    pub fn name(self) -> &'static str {
        match self {
            EditClass::Nothing => "nothing",
            EditClass::Recombine => "recombine",
            EditClass::Reshade => "reshade",
            EditClass::Relight => "relight",
            EditClass::Retrace => "retrace",
            EditClass::Rebuild => "rebuild",
        }
    }
}

/// The class of the edit that turns `old` into `new`. Every field is named
/// (the destructuring below fails to compile when the format grows), so a
/// new field cannot be forgotten.
pub fn classify(old: &SceneDesc, new: &SceneDesc) -> EditClass {
    let SceneDesc {
        format,
        camera,
        render,
        light,
        materials,
        objects,
        base_dir,
    } = new;
    let CameraDesc {
        position,
        look_at,
        up,
        fov_y_deg,
        width,
        height,
    } = camera;
    let c = &old.camera;
    let camera_same = (position, look_at, up, fov_y_deg, width, height)
        == (
            &c.position,
            &c.look_at,
            &c.up,
            &c.fov_y_deg,
            &c.width,
            &c.height,
        );
    let LightDesc {
        corner,
        edge_u,
        edge_v,
        ambient: light_ambient,
        diffuse: light_diffuse,
        specular: light_specular,
    } = light;
    let l = &old.light;
    let objects_same = *format == old.format
        && materials.keys().eq(old.materials.keys())
        && *objects == old.objects
        && *base_dir == old.base_dir;
    if !objects_same {
        return EditClass::Rebuild;
    }
    if !camera_same {
        return EditClass::Retrace;
    }
    let light_moved = (corner, edge_u, edge_v) != (&l.corner, &l.edge_u, &l.edge_v);

    let RenderDesc {
        shadow_rays,
        sampling,
        max_depth,
        seed,
        area_light_model,
        terms,
        background,
        shadows,
        adaptive,
        cutaway,
        shininess_override,
        samples_per_pixel,
    } = render;
    let r = &old.render;
    if (
        shadow_rays,
        sampling,
        max_depth,
        seed,
        area_light_model,
        shadows,
        adaptive,
        cutaway,
    ) != (
        &r.shadow_rays,
        &r.sampling,
        &r.max_depth,
        &r.seed,
        &r.area_light_model,
        &r.shadows,
        &r.adaptive,
        &r.cutaway,
    ) || *samples_per_pixel != r.samples_per_pixel
    {
        return EditClass::Retrace;
    }

    let mut class = if light_moved {
        EditClass::Relight
    } else {
        EditClass::Nothing
    };
    if *shininess_override != r.shininess_override {
        class = class.max(EditClass::Reshade);
    }
    for (m, o) in materials.values().zip(old.materials.values()) {
        let MaterialDesc {
            ambient,
            diffuse,
            specular,
            shininess,
            reflectivity,
        } = m;
        if (shininess, reflectivity) != (&o.shininess, &o.reflectivity) {
            class = class.max(EditClass::Reshade);
        }
        if (ambient, diffuse, specular) != (&o.ambient, &o.diffuse, &o.specular) {
            class = class.max(EditClass::Recombine);
        }
    }
    let TermsDesc {
        ambient,
        diffuse,
        specular,
    } = terms;
    if (ambient, diffuse, specular) != (&r.terms.ambient, &r.terms.diffuse, &r.terms.specular)
        || *background != r.background
        || (light_ambient, light_diffuse, light_specular) != (&l.ambient, &l.diffuse, &l.specular)
    {
        class = class.max(EditClass::Recombine);
    }
    class
}
