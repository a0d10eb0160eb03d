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
    /// `tests` as [`TileTargets::nearest_of_rays`] takes them: each run of
    /// planes at once (their data in `lane_planes`), other objects one by
    /// one.
    row_steps: Vec<RowStep>,
    lane_planes: Vec<LanePlane>,
}

/// A step of [`TileTargets::nearest_of_rays`].
#[derive(Debug, Clone, Copy)]
enum RowStep {
    /// The planes of `lane_planes` from the previous run's end to this
    /// index.
    Planes(usize),
    /// Any other primitive, through [`Scene::intersect`].
    Other(u32),
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

/// Camera rays whose nearest hits [`TileTargets::nearest_of_rays`] finds
/// side by side.
const RAY_LANES: usize = 8;

/// No hit yet, and the light, among a lane's hits (objects: their index).
const NO_HIT: u64 = u64::MAX;
const LIGHT_HIT: u64 = u64::MAX - 1;

impl TileTargets {
    /// [`TileTargets::nearest`] of each of `rays` (camera rays of the
    /// tile) into `out`, [`RAY_LANES`] rays at a time: each plane tested
    /// against all of them at once, its hits kept by selection instead of
    /// a branch per ray and plane, other objects ray by ray. Every ray
    /// meets the tests in the same order with the same operations, so
    /// each finds the same hit and distance.
    #[inline(always)]
    pub(crate) fn nearest_of_rays(
        &self,
        scene: &Scene,
        rays: &[Ray],
        cutaway: bool,
        out: &mut Vec<Option<(HitTarget, f64)>>,
    ) {
        out.clear();
        for chunk in rays.chunks(RAY_LANES) {
            let n = chunk.len();
            // Lanes past `n` repeat the first ray; their hits are dropped.
            let lane = |j: usize| chunk[if j < n { j } else { 0 }].dir;
            let dirs: [[f64; RAY_LANES]; 3] = [
                std::array::from_fn(|j| lane(j).x),
                std::array::from_fn(|j| lane(j).y),
                std::array::from_fn(|j| lane(j).z),
            ];
            let mut t_max = [f64::INFINITY; RAY_LANES];
            let mut best = [NO_HIT; RAY_LANES];
            if self.light {
                for (j, ray) in chunk.iter().enumerate() {
                    if let Some(t) = scene.light.shape.intersect(ray, t_max[j]) {
                        (best[j], t_max[j]) = (LIGHT_HIT, t);
                    }
                }
            }
            let mut start = 0;
            for step in &self.row_steps {
                match *step {
                    RowStep::Planes(end) => {
                        let planes = &self.lane_planes[start..end];
                        planes_nearer(planes, &dirs, cutaway, &mut t_max, &mut best);
                        start = end;
                    }
                    RowStep::Other(id) => {
                        for (j, ray) in chunk.iter().enumerate() {
                            if let Some(t) = scene.intersect(id, ray, t_max[j]) {
                                (best[j], t_max[j]) = (id as u64, t);
                            }
                        }
                    }
                }
            }
            for (j, ray) in chunk.iter().enumerate() {
                if self.bvh
                    && let Some((i, t)) = scene
                        .bvh
                        .closest(ray, t_max[j], |i, t_max| scene.intersect(i, ray, t_max))
                {
                    (best[j], t_max[j]) = (i as u64, t);
                }
                out.push(match best[j] {
                    NO_HIT => None,
                    LIGHT_HIT => Some((HitTarget::Light, t_max[j])),
                    i => Some((HitTarget::Object(i as u32), t_max[j])),
                });
            }
        }
    }
}

/// A plane as [`TileTargets::nearest_of_rays`] tests it against a lane of
/// rays: its unit normal, minus the camera's signed distance, its object.
#[derive(Debug, Clone, Copy)]
struct LanePlane {
    normal: DVec3,
    neg_distance: f64,
    id: u64,
}

/// Makes each of `planes` in turn the nearest hit of each ray of `dirs`
/// (directions, coordinate by coordinate) that meets it in front of the
/// camera nearer than its `t_max` (`best`: the rays' nearest objects), as
/// [`TileTargets::nearest`] tests a plane: the same operations, so the
/// same distances. On AVX2, four rays per instruction, the nearest hits
/// kept in registers through all the planes and by blending instead of a
/// branch per ray and plane.
#[inline(always)]
fn planes_nearer(
    planes: &[LanePlane],
    dirs: &[[f64; RAY_LANES]; 3],
    cutaway: bool,
    t_max: &mut [f64; RAY_LANES],
    best: &mut [u64; RAY_LANES],
) {
    #[cfg(target_arch = "x86_64")]
    if crate::render::math::avx2_kernels() {
        // SAFETY: the CPU supports AVX2 (`avx2_kernels` checks).
        return unsafe { planes_nearer_avx2(planes, dirs, cutaway, t_max, best) };
    }
    for plane in planes {
        let n = plane.normal;
        for j in 0..RAY_LANES {
            let denom = n.x * dirs[0][j] + n.y * dirs[1][j] + n.z * dirs[2][j];
            let t = plane.neg_distance / denom;
            // Cut away: planes seen from behind are passed through.
            if !(cutaway && denom > 0.0) && t > 0.0 && t < t_max[j] {
                (t_max[j], best[j]) = (t, plane.id);
            }
        }
    }
}

/// [`planes_nearer`] on four-lane vectors, two at once: products and sums
/// in the order of the portable loop (no fused multiply-add), the
/// comparisons ordered (false for NaN), as its `>` and `<` are.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn planes_nearer_avx2(
    planes: &[LanePlane],
    dirs: &[[f64; RAY_LANES]; 3],
    cutaway: bool,
    t_max: &mut [f64; RAY_LANES],
    best: &mut [u64; RAY_LANES],
) {
    use std::arch::x86_64::*;
    const { assert!(RAY_LANES == 8, "two vectors of four rays") };
    let zero = _mm256_setzero_pd();
    // SAFETY: every load and store is of four values at 0 or 4 of an
    // eight-value array.
    unsafe {
        let (dx0, dx1) = (_mm256_loadu_pd(&dirs[0][0]), _mm256_loadu_pd(&dirs[0][4]));
        let (dy0, dy1) = (_mm256_loadu_pd(&dirs[1][0]), _mm256_loadu_pd(&dirs[1][4]));
        let (dz0, dz1) = (_mm256_loadu_pd(&dirs[2][0]), _mm256_loadu_pd(&dirs[2][4]));
        let (mut t0, mut t1) = (_mm256_loadu_pd(&t_max[0]), _mm256_loadu_pd(&t_max[4]));
        let best_bits = best.as_mut_ptr() as *mut f64;
        let (mut b0, mut b1) = (
            _mm256_loadu_pd(best_bits),
            _mm256_loadu_pd(best_bits.add(4)),
        );
        for plane in planes {
            let nx = _mm256_set1_pd(plane.normal.x);
            let ny = _mm256_set1_pd(plane.normal.y);
            let nz = _mm256_set1_pd(plane.normal.z);
            let neg_distance = _mm256_set1_pd(plane.neg_distance);
            let id = _mm256_castsi256_pd(_mm256_set1_epi64x(plane.id as i64));
            let denom0 = _mm256_add_pd(
                _mm256_add_pd(_mm256_mul_pd(nx, dx0), _mm256_mul_pd(ny, dy0)),
                _mm256_mul_pd(nz, dz0),
            );
            let denom1 = _mm256_add_pd(
                _mm256_add_pd(_mm256_mul_pd(nx, dx1), _mm256_mul_pd(ny, dy1)),
                _mm256_mul_pd(nz, dz1),
            );
            let (d0, d1) = (
                _mm256_div_pd(neg_distance, denom0),
                _mm256_div_pd(neg_distance, denom1),
            );
            let mut nearer0 = _mm256_and_pd(
                _mm256_cmp_pd::<_CMP_GT_OQ>(d0, zero),
                _mm256_cmp_pd::<_CMP_LT_OQ>(d0, t0),
            );
            let mut nearer1 = _mm256_and_pd(
                _mm256_cmp_pd::<_CMP_GT_OQ>(d1, zero),
                _mm256_cmp_pd::<_CMP_LT_OQ>(d1, t1),
            );
            if cutaway {
                nearer0 = _mm256_andnot_pd(_mm256_cmp_pd::<_CMP_GT_OQ>(denom0, zero), nearer0);
                nearer1 = _mm256_andnot_pd(_mm256_cmp_pd::<_CMP_GT_OQ>(denom1, zero), nearer1);
            }
            t0 = _mm256_blendv_pd(t0, d0, nearer0);
            t1 = _mm256_blendv_pd(t1, d1, nearer1);
            b0 = _mm256_blendv_pd(b0, id, nearer0);
            b1 = _mm256_blendv_pd(b1, id, nearer1);
        }
        _mm256_storeu_pd(&mut t_max[0], t0);
        _mm256_storeu_pd(&mut t_max[4], t1);
        _mm256_storeu_pd(best_bits, b0);
        _mm256_storeu_pd(best_bits.add(4), b1);
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
    out.row_steps.clear();
    out.lane_planes.clear();
    for test in &out.tests {
        match *test {
            CameraTest::Plane {
                id,
                normal,
                neg_distance,
                ..
            } => {
                out.lane_planes.push(LanePlane {
                    normal,
                    neg_distance,
                    id: id as u64,
                });
                // A plane ends the run it extends, or starts one.
                if let Some(RowStep::Planes(_)) = out.row_steps.last() {
                    out.row_steps.pop();
                }
                out.row_steps.push(RowStep::Planes(out.lane_planes.len()));
            }
            CameraTest::Other(id) => out.row_steps.push(RowStep::Other(id)),
        }
    }
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

    /// The seed room, the seed room seen from outside (cut-away passes
    /// its walls), and a room of 40 spheres (found through the BVH).
    fn test_rooms() -> [Loaded; 3] {
        let mut outside = Loaded::seed_room();
        let mut camera =
            crate::render::scene_file::SceneDesc::from_json(crate::render::scene::SEED_ROOM_JSON)
                .unwrap();
        camera.camera.position = [7.0, 11.0, -20.0];
        outside.scene = std::sync::Arc::new(outside.scene.with_view(&camera));
        let spheres = Loaded::new(&crate::render::generate::spheres_in_room(40, 3)).expect("valid");
        assert!(!spheres.scene.bvh.is_empty());
        [Loaded::seed_room(), outside, spheres]
    }

    /// A tile's camera rays find, bit for bit, the hit of
    /// [`Scene::camera_hit`] (with and without cut-away): the seed room, a
    /// camera outside it (cut-away passes walls), and a room of 40
    /// spheres (found through the BVH); rays through pixel centres, and
    /// with a reach, rays as far from them as it lets samples lie.
    #[test]
    fn a_tile_s_camera_rays_meet_what_each_ray_meets() {
        let mut listed = TileTargets::default();
        for loaded in test_rooms() {
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

    /// A row of camera rays searched side by side finds, bit for bit, what
    /// each ray finds alone (with and without cut-away): rows of every
    /// length up to three lanes and more (lanes left over), in the seed
    /// room, seen from outside it, and in a room of spheres found
    /// through the BVH.
    #[test]
    fn a_row_searched_side_by_side_meets_what_each_ray_meets() {
        let mut listed = TileTargets::default();
        let (mut rays, mut found) = (Vec::new(), Vec::new());
        let bits = |h: Option<(HitTarget, f64)>| h.map(|(o, t)| (o, t.to_bits()));
        for loaded in test_rooms() {
            let scene = &loaded.scene;
            let whole = TileRect::whole(&scene.camera);
            let (mut hits, mut lit) = (0, 0);
            for (k, rect) in tiles_of(whole, 32).into_iter().enumerate() {
                camera_objects(scene, rect, 0.0, &mut listed);
                // Rows of 1 to 32 rays, from the tile's left.
                let w = 1 + k as u32 % rect.w;
                for y in (rect.y..rect.y + rect.h).step_by(3) {
                    scene.camera.row_rays(rect.x, y, w, &mut rays);
                    for cutaway in [false, true] {
                        listed.nearest_of_rays(scene, &rays, cutaway, &mut found);
                        assert_eq!(found.len(), rays.len());
                        for (x, (ray, &got)) in (rect.x..).zip(rays.iter().zip(&found)) {
                            let want = listed.nearest(scene, ray, cutaway);
                            assert_eq!(
                                bits(got),
                                bits(want),
                                "pixel ({x}, {y}), cut-away {cutaway}"
                            );
                            hits += want.is_some() as usize;
                            lit += matches!(want, Some((HitTarget::Light, _))) as usize;
                        }
                    }
                }
            }
            assert!(hits > 1000, "{hits} hits");
            if loaded.scene.bvh.is_empty() {
                assert!(lit > 0, "some rows see the light");
            }
        }
    }
}
