//! The scene's objects as a list: a visibility toggle and the material of
//! each, and "Add mesh…" (an OBJ, PLY, glTF or GLB file, placed on the
//! floor and scaled to fit the room, in the material chosen beside it).
//! Hidden objects are a view setting ([`ViewSettings::hidden`]): they are
//! left out of the render and of what is saved, and undo restores them.

use std::path::Path;

use egui::Ui;
use glam::DVec3;

use super::settings::ViewSettings;
use crate::render::SceneDesc;
use crate::render::mesh;
use crate::render::scene_file::{MeshDesc, MeshScale, MeshShading, ObjectDesc};

/// File endings of the mesh formats.
pub const MESH_EXTENSIONS: [&str; 4] = ["obj", "ply", "gltf", "glb"];

/// Whether a path names a mesh file (by its ending).
pub fn is_mesh_file(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| MESH_EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()))
}

/// What the list keeps between frames.
#[derive(Debug, Clone, Default)]
pub struct ObjectListState {
    /// Material of the next mesh added (a name of the scene's materials).
    pub material: String,
}

/// What the user asked for in the list this frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ListAction {
    /// Open the file dialog to add a mesh.
    AddMesh,
}

/// The list's frame: true in `.0` if the scene or the view changed.
pub fn object_list_ui(
    ui: &mut Ui,
    state: &mut ObjectListState,
    desc: &mut SceneDesc,
    view: &mut ViewSettings,
) -> (bool, Option<ListAction>) {
    let mut changed = false;
    let mut action = None;
    let materials: Vec<String> = desc.materials.keys().cloned().collect();
    if !materials.contains(&state.material) {
        state.material = default_material(desc);
    }
    egui::CollapsingHeader::new("Objects")
        .default_open(false)
        .show(ui, |ui| {
            for (i, o) in desc.objects.iter_mut().enumerate() {
                ui.horizontal(|ui| {
                    let mut visible = !view.hidden.contains(&i);
                    if ui
                        .checkbox(&mut visible, object_label(i, o))
                        .on_hover_text("Show or hide this object")
                        .changed()
                    {
                        if visible {
                            view.hidden.retain(|&h| h != i);
                        } else {
                            view.hidden.push(i);
                            view.hidden.sort_unstable();
                        }
                        changed = true;
                    }
                    let current = o.material().to_string();
                    let mut chosen = current.clone();
                    egui::ComboBox::from_id_salt(("object material", i))
                        .selected_text(&chosen)
                        .show_ui(ui, |ui| {
                            for m in &materials {
                                ui.selectable_value(&mut chosen, m.clone(), m);
                            }
                        });
                    if chosen != current {
                        set_material(o, chosen);
                        changed = true;
                    }
                });
            }
            ui.horizontal(|ui| {
                if ui
                    .button("Add mesh…")
                    .on_hover_text("An OBJ, PLY, glTF or GLB file, placed on the floor (or drop one on the window)")
                    .clicked()
                {
                    action = Some(ListAction::AddMesh);
                }
                egui::ComboBox::from_id_salt("new mesh material")
                    .selected_text(&state.material)
                    .show_ui(ui, |ui| {
                        for m in &materials {
                            ui.selectable_value(&mut state.material, m.clone(), m);
                        }
                    });
            });
        });
    (changed, action)
}

/// "white" if the scene has it, else its first material.
fn default_material(desc: &SceneDesc) -> String {
    if desc.materials.contains_key("white") {
        "white".into()
    } else {
        desc.materials.keys().next().cloned().unwrap_or_default()
    }
}

fn object_label(i: usize, o: &ObjectDesc) -> String {
    match o {
        ObjectDesc::Plane(_) => format!("{i}: plane"),
        ObjectDesc::Rect(_) => format!("{i}: rect"),
        ObjectDesc::Box(_) => format!("{i}: box"),
        ObjectDesc::Sphere(_) => format!("{i}: sphere"),
        ObjectDesc::Triangle(_) => format!("{i}: triangle"),
        ObjectDesc::Mesh(m) => {
            let name = Path::new(&m.file)
                .file_name()
                .map_or(m.file.clone(), |n| n.to_string_lossy().into_owned());
            format!("{i}: mesh {name}")
        }
    }
}

fn set_material(o: &mut ObjectDesc, m: String) {
    match o {
        ObjectDesc::Plane(p) => p.material = m,
        ObjectDesc::Rect(r) => r.material = m,
        ObjectDesc::Box(b) => b.material = m,
        ObjectDesc::Sphere(s) => s.material = m,
        ObjectDesc::Triangle(t) => t.material = m,
        ObjectDesc::Mesh(x) => x.material = m,
    }
}

/// The room the mesh goes into: the box between the scene's axis-aligned
/// planes (floor, ceiling, walls), with the seed room's sides where a
/// plane is missing.
fn room(desc: &SceneDesc) -> (DVec3, DVec3) {
    let (mut lo, mut hi) = (DVec3::new(-5.0, 0.0, -5.0), DVec3::new(5.0, 8.0, 5.0));
    for o in &desc.objects {
        let ObjectDesc::Plane(p) = o else { continue };
        let n = DVec3::from(p.normal);
        let at = DVec3::from(p.point);
        for k in 0..3 {
            let along = n[k] / n.length();
            if along > 0.999 {
                lo[k] = at[k];
            } else if along < -0.999 {
                hi[k] = at[k];
            }
        }
    }
    if (0..3).any(|k| hi[k] <= lo[k]) {
        return (DVec3::new(-5.0, 0.0, -5.0), DVec3::new(5.0, 8.0, 5.0));
    }
    (lo, hi)
}

/// Reads a mesh file and returns it as a `mesh` object standing on the
/// floor in the middle of the room, its largest side 40 % of the room's
/// smallest, in `material`; or the reader's error naming the file.
pub fn mesh_object(desc: &SceneDesc, path: &Path, material: &str) -> Result<ObjectDesc, String> {
    let file = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    let mut m = MeshDesc {
        file: file.to_string_lossy().into_owned(),
        material: material.into(),
        scale: MeshScale::Uniform(1.0),
        rotate_y_deg: 0.0,
        translate: [0.0; 3],
        shading: MeshShading::Auto,
    };
    let part = mesh::load(&m, None, mesh::limits::MAX_TRIANGLES)?;
    let (lo, hi) = part
        .positions
        .iter()
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(a, b), &p| {
            (a.min(p), b.max(p))
        });
    let size = (hi - lo).max_element();
    if part.faces.is_empty() || !(size > 0.0 && size.is_finite()) {
        return Err(format!("{}: no triangles to show", path.display()));
    }
    let (room_lo, room_hi) = room(desc);
    let scale = 0.4 * (room_hi - room_lo).min_element() / size;
    let centre = (room_lo + room_hi) * 0.5;
    let mid = (lo + hi) * 0.5;
    m.scale = MeshScale::Uniform(scale);
    // A hair above the floor, so that the mesh's base does not fight it.
    let lift = 1e-4 * (room_hi - room_lo).max_element();
    m.translate = [
        centre.x - scale * mid.x,
        room_lo.y + lift - scale * lo.y,
        centre.z - scale * mid.z,
    ];
    Ok(ObjectDesc::Mesh(m))
}

/// The material an added mesh gets: the list's choice, if the scene has it.
pub fn mesh_material(state: &ObjectListState, desc: &SceneDesc) -> String {
    if desc.materials.contains_key(&state.material) {
        state.material.clone()
    } else {
        default_material(desc)
    }
}
