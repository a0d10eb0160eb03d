//! The shading parameters: material reflectances, shininess and
//! reflectivity, and the light's colours. Editing them moves no ray (see
//! `live/`), so they travel beside the scene, not inside it.

use glam::{DVec3, Vec3};

use super::scene_file::SceneDesc;

/// Phong material with f32 reflectances (the shading runs in f32).
#[derive(Debug, Clone, PartialEq)]
pub struct Material {
    pub ambient: Vec3,
    pub diffuse: Vec3,
    pub specular: Vec3,
    pub shininess: f32,
    pub reflectivity: f32,
}

/// The light's ambient, diffuse and specular colours (the diffuse one is
/// also what a camera ray sees of the light).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LightColours {
    pub ambient: Vec3,
    pub diffuse: Vec3,
    pub specular: Vec3,
}

/// Everything the Phong sums read besides the geometry.
#[derive(Debug, Clone, PartialEq)]
pub struct ShadingParams {
    /// In the order of the scene's material names (sorted by name).
    pub materials: Vec<Material>,
    pub light: LightColours,
}

impl ShadingParams {
    /// The description's materials (with the shininess override applied)
    /// and light colours.
    pub fn from_desc(desc: &SceneDesc) -> ShadingParams {
        let override_shininess = desc.render.shininess_override;
        let v = |c: [f64; 3]| DVec3::from(c).as_vec3();
        ShadingParams {
            materials: desc
                .materials
                .values()
                .map(|m| Material {
                    ambient: v(m.ambient),
                    diffuse: v(m.diffuse),
                    specular: v(m.specular),
                    shininess: override_shininess.unwrap_or(m.shininess) as f32,
                    reflectivity: m.reflectivity as f32,
                })
                .collect(),
            light: LightColours {
                ambient: v(desc.light.ambient),
                diffuse: v(desc.light.diffuse),
                specular: v(desc.light.specular),
            },
        }
    }
}
