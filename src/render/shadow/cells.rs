//! The objects that may block a shadow ray from anywhere in a small cube of
//! space: each hit point tests only its cube's list, not every object.
//!
//! Every shadow ray from a point of the cube lies in the convex hull of the
//! cube and the light. An object left out of a cube's list is separated
//! from that hull by a margin far beyond the rounding of the f32 ray tests
//! (as the shadow packets' margin, `visibility.rs`), so none of those rays
//! could find it blocking: the same visibility bits. A plane is left out
//! only where the per-hit-point test would leave it out at every point of
//! the cube (the whole light on the point's side). The objects of the BVH
//! (meshes, many objects) are listed as one: whether any of them may block,
//! found by walking the BVH with the same test (a triangle by its vertices):
//! hit points whose cube no mesh can shadow skip the BVH altogether.
//!
//! The lists are made lazily, cube by cube, into a small direct-mapped
//! cache per thread: neighbouring pixels' hit points share a cube. A
//! thread keeps its lists from one render to the next: a render of the
//! same objects under the same light (a shading edit, a benchmark's runs)
//! finds them made.

use std::cell::RefCell;
use std::sync::Arc;

use glam::DVec3;

use crate::render::geometry::{Aabb, Primitive, Shape};
use crate::render::scene::{Object, Scene};

/// Cubes per side of the scene's finite part ([`Scene::scale`]): small
/// enough that a cube's hull with the light stays close to the pyramids of
/// its points, large enough that neighbouring hit points share one.
const CUBES_PER_SCALE: f64 = 40.0;

/// Cache slots: 2^SLOT_BITS.
const SLOT_BITS: u32 = 12;

/// The margin, as a fraction of the scene's scale.
const MARGIN: f64 = 1e-4;

/// The objects tested one by one ([`Scene::unbounded`], then
/// [`Scene::bounded`]) as bits, in this order; the lists serve up to 64 of
/// them.
pub(super) type ObjectBits = u64;

/// The objects that may block a shadow ray from a cube.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct CubeList {
    /// Those tested one by one, as bits of [`OccluderCells::objects`].
    pub(super) objects: ObjectBits,
    /// Whether any object of the BVH may (the packets and the BVH walk
    /// are left out where none can).
    pub(super) bvh: bool,
}

/// What the lists were made for: they hold only for the same objects
/// under the same light.
#[derive(Debug)]
struct Made {
    /// The scene's objects, held so that their address cannot be reused by
    /// another scene's while the lists exist.
    objects: Arc<[Object]>,
    corner: DVec3,
    edge_u: DVec3,
    edge_v: DVec3,
    /// The scene's scale, which sets the cubes' side and the margin.
    scale: f64,
}

impl Made {
    /// Field by field from the scene (a copy on the stack compared at once
    /// would stall on forwarding its stores).
    #[inline(always)]
    fn is_for(&self, scene: &Scene) -> bool {
        let light = &scene.light.shape;
        Arc::ptr_eq(&self.objects, &scene.objects)
            && self.corner == light.corner
            && self.edge_u == light.edge_u
            && self.edge_v == light.edge_v
            && self.scale == scene.scale
    }
}

#[derive(Debug, Clone, Copy)]
struct Slot {
    cube: [i32; 3],
    list: CubeList,
}

/// Per-thread occluder lists of the cubes met so far.
#[derive(Debug, Default)]
pub(crate) struct OccluderCells {
    made: Option<Made>,
    /// Object ids, in the order of the bits.
    objects: Vec<u32>,
    side: f64,
    /// 1 / `side`.
    per_side: f64,
    margin: f64,
    /// The address of the scene [`Self::check_for`] found the lists made
    /// for (0: none): until [`Self::forget_check`], while its caller holds
    /// that scene borrowed, [`Self::list_at`] does not compare it again.
    checked: usize,
    /// The last cube's list: neighbouring hit points mostly share it.
    last: Slot,
    slots: Vec<Slot>,
}

impl Default for Slot {
    fn default() -> Slot {
        EMPTY_SLOT
    }
}

/// A slot of a cube no point maps to.
const EMPTY_SLOT: Slot = Slot {
    cube: [i32::MIN; 3],
    list: CubeList {
        objects: 0,
        bvh: false,
    },
};

thread_local! {
    /// The lists the last render on this thread left.
    static KEPT: RefCell<OccluderCells> = RefCell::default();
}

impl OccluderCells {
    /// The lists the last render on this thread left (none at first).
    pub(super) fn kept() -> OccluderCells {
        KEPT.try_with(|k| std::mem::take(&mut *k.borrow_mut()))
            .unwrap_or_default()
    }

    /// Keeps these lists for the next render on this thread.
    pub(super) fn keep(mut self) {
        self.forget_check();
        // A thread that is ending keeps nothing.
        let _ = KEPT.try_with(|k| *k.borrow_mut() = self);
    }

    /// The object ids the bits stand for (valid after [`Self::list_at`]
    /// returned `Some`).
    #[inline(always)]
    pub(super) fn objects(&self) -> &[u32] {
        &self.objects
    }

    /// The objects that may block a shadow ray from `p`; `None` where the
    /// lists do not serve (more than 64 objects tested one by one, or `p`
    /// far outside the scene).
    #[inline(always)]
    pub(super) fn list_at(&mut self, scene: &Scene, p: DVec3) -> Option<CubeList> {
        if self.checked != address(scene) {
            self.make_for(scene);
        }
        if self.slots.is_empty() {
            return None;
        }
        let c = (p * self.per_side).floor();
        // Far outside the scene (or not finite): the full list.
        if !c.is_finite() || c.abs().max_element() >= 1e9 {
            return None;
        }
        let cube = [c.x as i32, c.y as i32, c.z as i32];
        if self.last.cube == cube {
            return Some(self.last.list);
        }
        let hash = (cube[0] as u32).wrapping_mul(0x9E37_79B1)
            ^ (cube[1] as u32).wrapping_mul(0x85EB_CA77)
            ^ (cube[2] as u32).wrapping_mul(0xC2B2_AE3D);
        let slot = &mut self.slots[(hash >> (32 - SLOT_BITS)) as usize];
        if slot.cube != cube {
            let lo = c * self.side;
            *slot = Slot {
                cube,
                list: cube_list(scene, &self.objects, lo, lo + self.side, self.margin),
            };
        }
        self.last = *slot;
        Some(slot.list)
    }

    /// Makes the lists `scene`'s (anew unless they are) and lets
    /// [`Self::list_at`] take that as known until [`Self::forget_check`]:
    /// for the hit points of one tile, whose scene cannot change while the
    /// caller holds it borrowed.
    pub(super) fn check_for(&mut self, scene: &Scene) {
        self.make_for(scene);
        self.checked = address(scene);
    }

    /// Ends [`Self::check_for`]: the scene is compared again.
    pub(super) fn forget_check(&mut self) {
        self.checked = 0;
    }

    /// The lists made anew unless they are `scene`'s.
    #[inline(always)]
    fn make_for(&mut self, scene: &Scene) {
        if !self.made.as_ref().is_some_and(|m| m.is_for(scene)) {
            self.start(scene);
        }
    }

    /// Forgets every list: they are made anew for `made`'s scene.
    #[cold]
    fn start(&mut self, scene: &Scene) {
        let light = &scene.light.shape;
        self.made = Some(Made {
            objects: Arc::clone(&scene.objects),
            corner: light.corner,
            edge_u: light.edge_u,
            edge_v: light.edge_v,
            scale: scene.scale,
        });
        self.objects.clear();
        self.objects
            .extend(scene.unbounded.iter().chain(scene.bounded.iter()));
        self.slots.clear();
        if self.objects.len() > ObjectBits::BITS as usize {
            return;
        }
        self.side = scene.scale / CUBES_PER_SCALE;
        self.per_side = 1.0 / self.side;
        self.last = EMPTY_SLOT;
        self.margin = MARGIN * scene.scale;
        self.slots.resize(1 << SLOT_BITS, EMPTY_SLOT);
    }
}

/// Where `scene` lies in memory: what [`OccluderCells::check_for`] keeps.
fn address(scene: &Scene) -> usize {
    std::ptr::from_ref(scene) as usize
}

/// The objects that may block a shadow ray from a point of the box
/// `lo..hi`: those tested one by one (`objects`) as bits, and whether any
/// of the BVH's may.
fn cube_list(scene: &Scene, objects: &[u32], lo: DVec3, hi: DVec3, margin: f64) -> CubeList {
    let hull = Hull::new(scene, lo, hi, margin);
    let mut bits = 0;
    for (k, &i) in objects.iter().enumerate() {
        if hull.may_meet(scene, i) {
            bits |= 1 << k;
        }
    }
    // The first BVH object the hull may meet settles it.
    let mut bvh = false;
    scene.bvh.visit_near_first(
        (lo + hi) * 0.5,
        |b| hull.may_meet_box(b),
        |i| {
            bvh = hull.may_meet(scene, i);
            !bvh
        },
    );
    CubeList { objects: bits, bvh }
}

/// The convex hull of a box of points (grown by the margin) and the light,
/// by its reach along directions that may separate an object from it.
struct Hull {
    /// The box's corners, then the light's.
    points: [DVec3; 12],
    axes: [DVec3; 12],
    /// The hull's extent along each axis.
    reach: [f64; 12],
    margin: f64,
}

impl Hull {
    fn new(scene: &Scene, lo: DVec3, hi: DVec3, margin: f64) -> Hull {
        // The cube grown by the margin: a point rounds into its cube's index
        // from as far as a few ulps outside it.
        let (lo, hi) = (lo - margin, hi + margin);
        let light = &scene.light.shape;
        let corners = light.corners();
        let mut points = [DVec3::ZERO; 12];
        for (k, h) in points.iter_mut().enumerate().take(8) {
            *h = DVec3::new(
                if k & 1 == 0 { lo.x } else { hi.x },
                if k & 2 == 0 { lo.y } else { hi.y },
                if k & 4 == 0 { lo.z } else { hi.z },
            );
        }
        points[8..].copy_from_slice(&corners);
        // Directions that may separate an object from the hull: the axes,
        // the light's normal, the way from the light to the cube, and the
        // sides of the pyramid from the cube's centre to the light.
        let centre = (lo + hi) * 0.5;
        let light_centre = light.centre();
        let mut axes = [
            DVec3::X,
            DVec3::NEG_X,
            DVec3::Y,
            DVec3::NEG_Y,
            DVec3::Z,
            DVec3::NEG_Z,
            -light.normal,
            (centre - light_centre).normalize_or_zero(),
            DVec3::ZERO,
            DVec3::ZERO,
            DVec3::ZERO,
            DVec3::ZERO,
        ];
        for i in 0..4 {
            let n = (corners[i] - centre)
                .cross(corners[(i + 1) % 4] - centre)
                .normalize_or_zero();
            axes[8 + i] = if n.dot(light_centre - centre) > 0.0 {
                -n
            } else {
                n
            };
        }
        let reach = axes.map(|n| Self::extent(&points, n));
        Hull {
            points,
            axes,
            reach,
            margin,
        }
    }

    /// The largest `n · x` over `points`.
    fn extent(points: &[DVec3], n: DVec3) -> f64 {
        points.iter().map(|h| n.dot(*h)).fold(f64::MIN, f64::max)
    }

    /// Whether no axis separates the box `b` from the hull by the margin.
    fn may_meet_box(&self, b: &Aabb) -> bool {
        self.axes.iter().zip(&self.reach).all(|(n, r)| {
            // The box's corner furthest along −n.
            let x = DVec3::select(n.cmpge(DVec3::ZERO), b.min, b.max);
            n.dot(x) <= r + self.margin
        })
    }

    /// Whether the triangle `v` may meet the hull: no axis, nor the
    /// triangle's normal either way, separates them by the margin.
    fn may_meet_triangle(&self, v: [DVec3; 3]) -> bool {
        let normal = (v[1] - v[0]).cross(v[2] - v[0]).normalize_or_zero();
        let apart = |n: DVec3, r: f64| v.iter().all(|x| n.dot(*x) > r + self.margin);
        !self
            .axes
            .iter()
            .zip(&self.reach)
            .any(|(n, r)| apart(*n, *r))
            && !apart(normal, Self::extent(&self.points, normal))
            && !apart(-normal, Self::extent(&self.points, -normal))
    }

    /// Whether object `i` may block a shadow ray from a point of the box.
    fn may_meet(&self, scene: &Scene, i: u32) -> bool {
        match (scene.primitive(i), scene.bounds_of(i)) {
            (Primitive::Shape(Shape::Plane(pl)), _) => {
                let d = self.points[..8].iter().map(|h| pl.signed_distance(*h));
                let range = (
                    d.clone().fold(f64::MAX, f64::min),
                    d.fold(f64::MIN, f64::max),
                );
                plane_may_block(range, &scene.light_sides_of(i))
            }
            (Primitive::Shape(Shape::Sphere(s)), _) => self
                .axes
                .iter()
                .zip(&self.reach)
                .all(|(n, r)| n.dot(s.centre) - s.radius <= r + self.margin),
            (Primitive::Shape(Shape::Triangle(t)), _) => self.may_meet_triangle(t.vertices()),
            (Primitive::Face { meshes, face }, _) => self.may_meet_triangle(meshes.vertices(face)),
            (_, Some(b)) => self.may_meet_box(&b),
            (_, None) => true,
        }
    }
}

/// Whether a plane may block a shadow ray from some point whose signed
/// distance from it lies in `range` (conservative in its rounding): the
/// per-point test leaves it out where every `c * distance > 0`, `c` the
/// light corners' distances `sides`. A bound of the range nearest zero
/// with that product positive gives every distance of the range its sign,
/// and the product only grows with the distance's size.
fn plane_may_block((near, far): (f64, f64), sides: &[f64; 4]) -> bool {
    let all_positive = |d: f64| sides.iter().all(|&c| c * d > 0.0);
    !(near > 0.0 && all_positive(near) || far < 0.0 && all_positive(far))
}

#[cfg(test)]
mod tests {
    use glam::DVec2;

    use super::*;
    use crate::render::generate::spheres_in_room;
    use crate::render::geometry::Ray;
    use crate::render::rng::Rng;
    use crate::render::scene::Loaded;
    use crate::render::scene_file::{ObjectDesc, RectDesc, TriangleDesc};

    /// At random points of the room, no object left out of the point's
    /// list meets a segment to any of 256 light points (f64 intersection,
    /// planes included), and the lists do leave objects out: the seed room,
    /// spheres with a tilted rect under a tilted light, and spheres and
    /// triangles in a BVH (left out as a whole where none may block).
    #[test]
    fn a_cube_leaves_out_only_objects_that_block_no_shadow_ray() {
        let mut tilted = spheres_in_room(6, 5);
        tilted.light.corner = [-1.5, 7.0, -1.0];
        tilted.light.edge_u = [2.5, 0.6, 0.3];
        tilted.light.edge_v = [0.8, 0.2, 2.0];
        tilted.objects.push(ObjectDesc::Rect(RectDesc {
            corner: [0.5, 3.0, 0.5],
            edge_u: [1.0, 0.4, -0.2],
            edge_v: [0.1, 0.2, 1.3],
            material: "green".into(),
        }));
        let mut in_bvh = spheres_in_room(6, 9);
        for k in 0..12 {
            let (x, z) = (k as f64 * 0.7 - 4.0, (k % 5) as f64 - 2.0);
            in_bvh.objects.push(ObjectDesc::Triangle(TriangleDesc {
                vertices: [
                    [x, 2.0, z],
                    [x + 0.6, 2.5, z + 0.3],
                    [x + 0.2, 3.0, z - 0.5],
                ],
                material: "green".into(),
            }));
        }
        let in_bvh = Loaded::new(&in_bvh).unwrap().scene;
        assert!(!in_bvh.bvh.is_empty());
        let mut bvh_left_out = 0;
        for scene in [
            Loaded::seed_room().scene,
            Loaded::new(&tilted).unwrap().scene,
            in_bvh,
        ] {
            let light = &scene.light.shape;
            let mut cells = OccluderCells::default();
            let mut rng = Rng::new(7);
            let mut u =
                |lo: f64, hi: f64| lo + (hi - lo) * (rng.next_u64() >> 11) as f64 / 2f64.powi(53);
            let mut left_out = 0;
            for _ in 0..4000 {
                let p = DVec3::new(u(-5.0, 5.0), u(0.0, 8.0), u(-5.0, 5.0));
                let list = cells.list_at(&scene, p).expect("a small scene has lists");
                let mut left_out_here: Vec<u32> = Vec::new();
                if !list.bvh && !scene.bvh.is_empty() {
                    bvh_left_out += 1;
                    scene.bvh.visit_near_first(
                        p,
                        |_| true,
                        |i| {
                            left_out_here.push(i);
                            true
                        },
                    );
                }
                for (k, &i) in cells.objects().iter().enumerate() {
                    if list.objects >> k & 1 == 0 {
                        left_out_here.push(i);
                    }
                }
                for i in left_out_here {
                    left_out += 1;
                    for j in 0..256 {
                        let y =
                            light.point(DVec2::new((j % 16) as f64 / 15.0, (j / 16) as f64 / 15.0));
                        let ray = Ray::new(p, y - p);
                        assert!(
                            scene.intersect(i, &ray, 1.0).is_none(),
                            "object {i} left out at {p} meets the ray to {y}"
                        );
                    }
                }
            }
            assert!(left_out > 4000, "{left_out} objects left out");
        }
        assert!(
            bvh_left_out > 400,
            "the BVH left out at {bvh_left_out} points"
        );
    }

    /// A thread's shadow buffers leave their lists to the next ones made
    /// on it: the same objects under the same light find their cubes
    /// listed; under a moved light the lists are made anew, as a fresh
    /// thread's would be.
    #[test]
    fn a_thread_keeps_its_lists_for_its_next_render() {
        use crate::render::shadow::ShadowBuffers;
        let scene = Loaded::seed_room().scene;
        let p = DVec3::new(1.5, 0.0, -3.0);
        let mut buf = ShadowBuffers::with_capacity(4);
        let list = buf.cells.list_at(&scene, p).expect("lists");
        drop(buf);
        let mut kept = ShadowBuffers::with_capacity(4);
        assert!(kept.cells.made.as_ref().is_some_and(|m| m.is_for(&scene)));
        assert_eq!(kept.cells.last.list, list);
        let c = (p * kept.cells.per_side).floor();
        assert_eq!(kept.cells.last.cube, [c.x as i32, c.y as i32, c.z as i32]);

        let mut desc =
            crate::render::scene_file::SceneDesc::from_json(crate::render::scene::SEED_ROOM_JSON)
                .unwrap();
        desc.light.corner = [-4.0, 7.5, 3.0];
        let moved = scene.with_view(&desc);
        let mut fresh = OccluderCells::default();
        let want = fresh.list_at(&moved, p);
        assert_ne!(want, Some(list), "the light's move changes the list");
        assert_eq!(kept.cells.list_at(&moved, p), want);
        assert!(kept.cells.made.as_ref().is_some_and(|m| m.is_for(&moved)));
    }
}
