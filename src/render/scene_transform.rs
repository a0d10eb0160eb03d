//! Whole-scene similarity transforms (uniform scale, translation) of a
//! scene description: the image must not change, which the stress tests
//! check at scales from 1e-3 to 1e5 and far from the origin.

use super::scene_file::{MeshScale, ObjectDesc, SceneDesc, Vec3Desc};

fn map(v: Vec3Desc, f: impl Fn(f64) -> f64) -> Vec3Desc {
    [f(v[0]), f(v[1]), f(v[2])]
}

impl SceneDesc {
    /// Every position and length multiplied by `factor` (> 0).
    pub fn scaled(mut self, factor: f64) -> SceneDesc {
        let s = |v: Vec3Desc| map(v, |x| x * factor);
        self.camera.position = s(self.camera.position);
        self.camera.look_at = s(self.camera.look_at);
        self.light.corner = s(self.light.corner);
        self.light.edge_u = s(self.light.edge_u);
        self.light.edge_v = s(self.light.edge_v);
        for o in &mut self.objects {
            match o {
                ObjectDesc::Plane(p) => p.point = s(p.point),
                ObjectDesc::Rect(r) => {
                    r.corner = s(r.corner);
                    r.edge_u = s(r.edge_u);
                    r.edge_v = s(r.edge_v);
                }
                ObjectDesc::Box(b) => {
                    b.min = s(b.min);
                    b.max = s(b.max);
                    b.translate = s(b.translate);
                }
                ObjectDesc::Sphere(sp) => {
                    sp.center = s(sp.center);
                    sp.radius *= factor;
                }
                ObjectDesc::Triangle(t) => t.vertices = t.vertices.map(s),
                // The scale applies first, about the model's origin: scaling
                // the world scales both.
                ObjectDesc::Mesh(m) => {
                    m.scale = match m.scale {
                        MeshScale::Uniform(k) => MeshScale::Uniform(k * factor),
                        MeshScale::PerAxis(v) => MeshScale::PerAxis(s(v)),
                    };
                    m.translate = s(m.translate);
                }
            }
        }
        self
    }

    /// Every position moved by `offset`.
    pub fn translated(mut self, offset: Vec3Desc) -> SceneDesc {
        let t = |v: Vec3Desc| [v[0] + offset[0], v[1] + offset[1], v[2] + offset[2]];
        self.camera.position = t(self.camera.position);
        self.camera.look_at = t(self.camera.look_at);
        self.light.corner = t(self.light.corner);
        for o in &mut self.objects {
            match o {
                ObjectDesc::Plane(p) => p.point = t(p.point),
                ObjectDesc::Rect(r) => r.corner = t(r.corner),
                // The box rotates about its own centre, so moving it is
                // moving its translation.
                ObjectDesc::Box(b) => b.translate = t(b.translate),
                ObjectDesc::Sphere(sp) => sp.center = t(sp.center),
                ObjectDesc::Triangle(tr) => tr.vertices = tr.vertices.map(t),
                ObjectDesc::Mesh(m) => m.translate = t(m.translate),
            }
        }
        self
    }
}
