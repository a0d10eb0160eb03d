//! The objects a tile's camera rays may meet, and whether they may meet
//! the light: every camera ray of a tile
//! starts at the camera and runs inside the cone spanned by the rays
//! through its corner pixels, so an object wholly outside that cone (or a
//! plane that every one of those rays runs away from) is met by none of
//! them, and the tile's camera rays leave it out. Decided once per tile, by
//! margins far wider than the rays' rounding; the objects kept are tested
//! as before, in the same order, so every hit is the same.
//!
//! Every camera ray of a tile starts at the camera, so what a plane's test
//! takes from the ray's origin (its distance from the plane) is the same
//! for all of them: it is taken once per tile, with the same operations,
//! so the same values.

use glam::DVec3;

use super::geometry::{Aabb, Primitive, Ray, Shape};
use super::progressive::TileRect;
use super::scene::{HitTarget, Scene};

/// What the camera rays of one tile may meet.
#[derive(Debug, Default)]
pub(crate) struct TileTargets {
    /// The unbounded and bounded objects, in the order the closest-hit
    /// loop takes them; the BVH's objects are not listed (they are found
    /// through the BVH as before).
    pub objects: Vec<u32>,
    /// Whether the light may be met (most tiles see no light: their rays
    /// skip its test).
    pub light: bool,
    /// The tests of `objects`, in their order.
    tests: Vec<CameraTest>,
    /// The first [`PLANE_LANES`] planes' tests, lane by lane: a ray's
    /// divisions for them are done side by side before the tests run.
    planes: PlaneLanes,
    /// Whether the scene's BVH holds objects (else its walk is skipped).
    bvh: bool,
}

/// Planes whose distances along a camera ray are computed at once.
const PLANE_LANES: usize = 8;

/// Planes' unit normals and minus the camera's signed distances, lane by
/// lane (lanes past `count` hold zeros and are not read).
#[derive(Debug, Default)]
struct PlaneLanes {
    count: usize,
    normal: [[f64; PLANE_LANES]; 3],
    neg_distance: [f64; PLANE_LANES],
}

impl PlaneLanes {
    /// Each plane's normal · direction and distance along `dir`, as a
    /// plane's test computes them one by one (the same operations lane by
    /// lane, so the same values): the divisions, the slowest part of a
    /// camera ray, side by side instead of each waiting for the one before.
    #[inline(always)]
    fn along(&self, dir: DVec3) -> ([f64; PLANE_LANES], [f64; PLANE_LANES]) {
        let [nx, ny, nz] = &self.normal;
        let mut denom = [0.0; PLANE_LANES];
        let mut t = [0.0; PLANE_LANES];
        // Four lanes at a time, and no more than the planes need.
        for k in (0..self.count).step_by(4) {
            for j in k..k + 4 {
                denom[j] = nx[j] * dir.x + ny[j] * dir.y + nz[j] * dir.z;
                t[j] = self.neg_distance[j] / denom[j];
            }
        }
        (denom, t)
    }
}

/// How a tile's camera rays test one object.
#[derive(Debug, Clone, Copy)]
enum CameraTest {
    /// A plane: its unit normal, and minus the camera's signed distance
    /// from it (what `Plane::intersect` divides by the normal's cosine).
    Plane {
        id: u32,
        normal: DVec3,
        neg_distance: f64,
        /// Its lane of [`PlaneLanes`], if it has one.
        lane: Option<u8>,
    },
    /// Any other primitive, through [`Scene::intersect`].
    Other(u32),
}

impl TileTargets {
    /// What a camera ray of the tile (from the camera, through a pixel
    /// centre of the tile) meets first: [`Scene::camera_hit_among`] of the
    /// tile's light and objects, the same operations, so the same hit and
    /// distance.
    #[inline(always)]
    pub(crate) fn nearest(
        &self,
        scene: &Scene,
        ray: &Ray,
        cutaway: bool,
    ) -> Option<(HitTarget, f64)> {
        debug_assert_eq!(ray.origin, scene.camera.origin);
        let mut best: Option<(HitTarget, f64)> = None;
        let mut t_max = f64::INFINITY;
        if self.light
            && let Some(t) = scene.light.shape.intersect(ray, t_max)
        {
            best = Some((HitTarget::Light, t));
            t_max = t;
        }
        let (denoms, ts) = self.planes.along(ray.dir);
        for test in &self.tests {
            match *test {
                CameraTest::Plane {
                    id,
                    normal,
                    neg_distance,
                    lane,
                } => {
                    let (denom, t) = match lane {
                        Some(k) => (denoms[k as usize], ts[k as usize]),
                        None => {
                            let denom = normal.dot(ray.dir);
                            (denom, neg_distance / denom)
                        }
                    };
                    // Cut away: planes seen from behind are passed through.
                    if cutaway && denom > 0.0 {
                        continue;
                    }
                    if t > 0.0 && t < t_max {
                        best = Some((HitTarget::Object(id), t));
                        t_max = t;
                    }
                }
                CameraTest::Other(id) => {
                    if let Some(t) = scene.intersect(id, ray, t_max) {
                        best = Some((HitTarget::Object(id), t));
                        t_max = t;
                    }
                }
            }
        }
        if self.bvh
            && let Some((i, t)) = scene
                .bvh
                .closest(ray, t_max, |i, t_max| scene.intersect(i, ray, t_max))
        {
            best = Some((HitTarget::Object(i), t));
        }
        best
    }
}

/// Writes into `out` what a camera ray through a point of a pixel of
/// `rect` within `reach` pixels of its centre along either axis (0: the
/// centres; a filter's reach for the samples it places) may meet.
pub(crate) fn camera_objects(scene: &Scene, rect: TileRect, reach: f64, out: &mut TileTargets) {
    let out_objects = &mut out.objects;
    out_objects.clear();
    let camera = &scene.camera;
    let origin = camera.origin;
    // The rays through the corners of the square `reach` around the
    // corner pixels' centres (an empty rectangle, which no caller passes,
    // counts as its corner): every ray of the tile is a positive
    // combination of them.
    let centre_of = |p: u32| p as f64 + 0.5;
    let (x0, y0) = (centre_of(rect.x) - reach, centre_of(rect.y) - reach);
    let (x1, y1) = (
        centre_of(rect.x + rect.w.saturating_sub(1)) + reach,
        centre_of(rect.y + rect.h.saturating_sub(1)) + reach,
    );
    let dirs = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)].map(|(x, y)| camera.ray(x, y).dir);
    let centre = dirs.iter().sum::<DVec3>();
    // The cone's sides, normals pointing in (zero for a tile one pixel
    // wide or high: such a side culls nothing).
    let sides = [0, 1, 2, 3].map(|k| {
        let n = dirs[k].cross(dirs[(k + 1) % 4]).normalize_or_zero();
        if n.dot(centre) < 0.0 { -n } else { n }
    });
    // Far beyond the rounding of the rays' directions (~1e-16) over the
    // scene's extent.
    let margin = 1e-6 * scene.scale;
    const SLOPE: f64 = 1e-9;
    // The box corner furthest along a side's inner normal lies outside it.
    let outside = |b: &Aabb| {
        sides.iter().any(|&n| {
            let x = DVec3::select(n.cmpge(DVec3::ZERO), b.max, b.min);
            n.dot(x - origin) < -margin
        })
    };
    out.light = !outside(&Aabb::from_points(&scene.light.shape.corners()));
    for &i in scene.unbounded.iter().chain(scene.bounded.iter()) {
        let missed = match (scene.primitive(i), scene.bounds_of(i)) {
            // t = −distance / (normal · direction) > 0 for none of the
            // rays: every direction leaves the plane's side the camera
            // is on (the dot products over the tile lie between the
            // corners').
            (Primitive::Shape(Shape::Plane(pl)), _) => {
                let side = pl.signed_distance(origin);
                let along = dirs.map(|d| pl.normal.dot(d));
                (side >= 0.0 && along.iter().all(|&a| a > SLOPE))
                    || (side <= 0.0 && along.iter().all(|&a| a < -SLOPE))
            }
            (_, Some(b)) => outside(&b),
            (_, None) => false,
        };
        if !missed {
            out_objects.push(i);
        }
    }
    out.tests.clear();
    let planes = &mut out.planes;
    *planes = PlaneLanes::default();
    out.tests
        .extend(out.objects.iter().map(|&i| match scene.primitive(i) {
            Primitive::Shape(Shape::Plane(pl)) => {
                let neg_distance = -pl.signed_distance(origin);
                let lane = (planes.count < PLANE_LANES).then(|| {
                    let k = planes.count;
                    planes.count += 1;
                    for (axis, n) in planes.normal.iter_mut().zip(pl.normal.to_array()) {
                        axis[k] = n;
                    }
                    planes.neg_distance[k] = neg_distance;
                    k as u8
                });
                CameraTest::Plane {
                    id: i,
                    normal: pl.normal,
                    neg_distance,
                    lane,
                }
            }
            _ => CameraTest::Other(i),
        }));
    out.bvh = !scene.bvh.is_empty();
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::progressive::tiles_of;
    use crate::render::scene::{HitTarget, Loaded};

    /// Every object a camera ray of a tile meets is listed for the tile,
    /// and objects no ray of it meets are left out: the floor above the
    /// horizon, the wall at x = 5 on the image's right (the camera looks
    /// along +z, its right is −x), the boxes and the sphere away from where
    /// they are seen.
    #[test]
    fn a_tile_lists_what_its_rays_meet_and_leaves_out_the_rest() {
        let loaded = Loaded::seed_room();
        let scene = &loaded.scene;
        let whole = TileRect::whole(&scene.camera);
        let mut listed = TileTargets::default();
        let mut lit_tiles = 0;
        let (mut kept, mut all) = (0, 0);
        for rect in tiles_of(whole, 32) {
            camera_objects(scene, rect, 0.0, &mut listed);
            lit_tiles += listed.light as usize;
            kept += listed.objects.len();
            all += scene.unbounded.len() + scene.bounded.len();
            for y in (rect.y..rect.y + rect.h).step_by(3) {
                for x in (rect.x..rect.x + rect.w).step_by(3) {
                    let ray = scene.camera.pixel_ray(x, y);
                    match scene.camera_hit(&ray, false) {
                        Some((HitTarget::Object(i), _)) => assert!(
                            listed.objects.contains(&i),
                            "tile {rect:?}: pixel ({x}, {y}) meets {i}"
                        ),
                        Some((HitTarget::Light, _)) => assert!(
                            listed.light,
                            "tile {rect:?}: pixel ({x}, {y}) meets the light"
                        ),
                        None => {}
                    }
                    let among = scene.camera_hit_among(
                        &ray,
                        false,
                        listed.light,
                        listed.objects.iter().copied(),
                    );
                    assert_eq!(among, scene.camera_hit(&ray, false));
                }
            }
        }
        assert!(kept * 2 < all, "{kept} of {all} objects kept");
        // The light, at the top of the image's middle, is seen by few tiles.
        assert!(
            (1..40).contains(&lit_tiles),
            "{lit_tiles} tiles see the light"
        );
        // Top right: rays above the horizon, towards −x.
        let top_right = TileRect {
            x: 928,
            y: 0,
            w: 32,
            h: 32,
        };
        camera_objects(scene, top_right, 0.0, &mut listed);
        assert!(!listed.objects.contains(&0), "the floor: {listed:?}");
        assert!(
            !listed.objects.contains(&2),
            "the wall at x = 5: {listed:?}"
        );
        assert_eq!(
            listed.objects,
            [1, 3, 4],
            "ceiling, walls at x = −5 and z = 5"
        );
        assert!(!listed.light);
    }

    /// A tile's camera rays find, bit for bit, the hit of
    /// [`Scene::camera_hit`] (with and without cut-away): the seed room, a
    /// camera outside it (cut-away passes walls), and a room of 40
    /// spheres (found through the BVH); rays through pixel centres, and
    /// with a reach, rays as far from them as it lets samples lie.
    #[test]
    fn a_tile_s_camera_rays_meet_what_each_ray_meets() {
        let mut outside = Loaded::seed_room();
        let mut camera =
            crate::render::scene_file::SceneDesc::from_json(crate::render::scene::SEED_ROOM_JSON)
                .unwrap();
        camera.camera.position = [7.0, 11.0, -20.0];
        outside.scene = std::sync::Arc::new(outside.scene.with_view(&camera));
        let spheres = Loaded::new(&crate::render::generate::spheres_in_room(40, 3)).expect("valid");
        assert!(!spheres.scene.bvh.is_empty());
        let mut listed = TileTargets::default();
        for loaded in [Loaded::seed_room(), outside, spheres] {
            let scene = &loaded.scene;
            let whole = TileRect::whole(&scene.camera);
            let mut hits = 0;
            for (rect, reach) in tiles_of(whole, 32)
                .into_iter()
                .zip([0.0, 0.75, 2.5].repeat(1000))
            {
                camera_objects(scene, rect, reach, &mut listed);
                for y in (rect.y..rect.y + rect.h).step_by(5) {
                    for x in (rect.x..rect.x + rect.w).step_by(5) {
                        // The centre, and with a reach the corners of its
                        // square (a filter's samples lie within).
                        let (cx, cy) = (x as f64 + 0.5, y as f64 + 0.5);
                        let rays = [
                            (0.0, 0.0),
                            (-reach, -reach),
                            (reach, reach),
                            (-reach, reach),
                        ]
                        .map(|(dx, dy)| scene.camera.ray(cx + dx, cy + dy));
                        for (ray, cutaway) in rays.iter().flat_map(|r| [(r, false), (r, true)]) {
                            let want = scene.camera_hit(ray, cutaway);
                            let got = listed.nearest(scene, ray, cutaway);
                            let bits =
                                |h: Option<(HitTarget, f64)>| h.map(|(o, t)| (o, t.to_bits()));
                            assert_eq!(
                                bits(got),
                                bits(want),
                                "pixel ({x}, {y}), cut-away {cutaway}"
                            );
                            hits += want.is_some() as usize;
                        }
                    }
                }
            }
            assert!(hits > 1000, "{hits} hits");
        }
    }
}
