//! What the mesh reader targets check of a mesh that was read: its indices
//! are in range, and it turns into scene faces without a panic.

use penumbra::render::geometry::Meshes;
use penumbra::render::mesh::{self, RawMesh};
use penumbra::render::scene_file::{MeshDesc, MeshScale, MeshShading};

/// Runs a reader. The glTF reader catches the panics of the `gltf` crate
/// on some malformed documents and refuses the file: libFuzzer's panic
/// hook would count those as crashes, so it is silenced, and only a panic
/// that escapes the reader aborts (a crash libFuzzer reports).
pub fn guarded<T>(read: impl FnOnce() -> T) -> T {
    static SILENCE: std::sync::Once = std::sync::Once::new();
    SILENCE.call_once(|| std::panic::set_hook(Box::new(|_| {})));
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(read)) {
        Ok(v) => v,
        Err(e) => {
            let what = e
                .downcast_ref::<String>()
                .map(String::as_str)
                .or_else(|| e.downcast_ref::<&str>().copied())
                .unwrap_or("(no message)");
            eprintln!("a panic escaped the reader: {what}");
            std::process::abort()
        }
    }
}

pub fn check(read: Result<RawMesh, String>) {
    let raw = match read {
        Ok(raw) => raw,
        Err(e) => {
            assert!(!e.is_empty() && e.len() < 2000, "{e}");
            return;
        }
    };
    let n = raw.positions.len() as u32;
    assert!(raw.faces.iter().flatten().all(|&i| i < n));
    if let Some(f) = &raw.face_normals {
        let m = raw.normals.len() as u32;
        assert!(f.iter().flatten().all(|&i| i < m));
        assert_eq!(f.len(), raw.faces.len());
    }
    for shading in [MeshShading::Auto, MeshShading::Smooth] {
        let desc = MeshDesc {
            file: "fuzz".into(),
            material: "white".into(),
            scale: MeshScale::Uniform(1.0),
            rotate_y_deg: 30.0,
            translate: [0.0; 3],
            shading,
        };
        let mut meshes = Meshes::default();
        let faces = raw.faces.len();
        let skipped = meshes.add(mesh::build(raw.clone(), &desc), 0).unwrap();
        assert_eq!(meshes.len() + skipped, faces);
    }
}
