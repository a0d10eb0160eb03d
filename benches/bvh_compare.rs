//! penumbra's own binned-SAH BVH against the `bvh` crate's SAH BVH
//! (issue 4: measure both and keep the faster), in rooms of N random
//! spheres: the build over the same bounds, and the closest hit of the same
//! 64 × 64 camera rays, with the same exact shape tests in both.

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use penumbra::render::HitTarget;
use penumbra::render::generate::spheres_in_room;
use penumbra::render::geometry::{Aabb, Bvh, Ray};
use penumbra::render::{Loaded, Scene};

type CrateBvh = bvh::bvh::Bvh<f64, 3>;
type CrateAabb = bvh::aabb::Aabb<f64, 3>;
type CrateRay = bvh::ray::Ray<f64, 3>;

const SIZES: [usize; 3] = [100, 1000, 10_000];
const SIDE: u32 = 64;

/// A bounded object as the `bvh` crate sees it: its id in the scene and its
/// bounds (the same padded ones penumbra's BVH gets).
#[derive(Clone)]
struct Item {
    object: u32,
    aabb: CrateAabb,
    node: usize,
}

impl bvh::aabb::Bounded<f64, 3> for Item {
    fn aabb(&self) -> CrateAabb {
        self.aabb
    }
}

impl bvh::bounding_hierarchy::BHShape<f64, 3> for Item {
    fn set_bh_node_index(&mut self, index: usize) {
        self.node = index;
    }

    fn bh_node_index(&self) -> usize {
        self.node
    }
}

struct Case {
    scene: Scene,
    rays: Vec<Ray>,
    /// What penumbra's `Bvh::build` takes (as `Scene::build` makes it).
    bounds: Vec<(u32, Aabb)>,
    items: Vec<Item>,
    crate_bvh: CrateBvh,
}

fn case(n: usize) -> Case {
    let mut desc = spheres_in_room(n, 1);
    desc.camera.width = SIDE;
    desc.camera.height = SIDE;
    let loaded = Loaded::new(&desc).expect("generated scenes are valid");
    let scene = std::sync::Arc::unwrap_or_clone(loaded.scene);
    assert!(
        scene.bounded.is_empty(),
        "N = {n} is above the BVH threshold"
    );
    let rays: Vec<Ray> = (0..SIDE)
        .flat_map(|y| (0..SIDE).map(move |x| (x, y)))
        .map(|(x, y)| scene.camera.pixel_ray(x, y))
        .collect();
    let bounds: Vec<(u32, Aabb)> = scene
        .objects
        .iter()
        .enumerate()
        .filter_map(|(i, o)| o.bounds.map(|b| (i as u32, b)))
        .collect();
    let mut items: Vec<Item> = bounds
        .iter()
        .map(|&(object, b)| Item {
            object,
            aabb: CrateAabb::with_bounds(b.min.to_array().into(), b.max.to_array().into()),
            node: 0,
        })
        .collect();
    let crate_bvh = CrateBvh::build(&mut items);
    Case {
        scene,
        rays,
        bounds,
        items,
        crate_bvh,
    }
}

/// The light and the unbounded objects (planes), tested one by one exactly
/// as `Scene::closest_hit` does before it goes to its BVH.
fn outside_bvh(scene: &Scene, ray: &Ray) -> Option<(HitTarget, f64)> {
    let mut best = None;
    let mut t_max = f64::INFINITY;
    if let Some(t) = scene.light.shape.intersect(ray, t_max) {
        best = Some((HitTarget::Light, t));
        t_max = t;
    }
    for &i in scene.unbounded.iter() {
        if let Some(t) = scene.objects[i as usize].shape.intersect(ray, t_max) {
            best = Some((HitTarget::Object(i), t));
            t_max = t;
        }
    }
    best
}

fn crate_ray(ray: &Ray) -> CrateRay {
    CrateRay::new(ray.origin.to_array().into(), ray.dir.to_array().into())
}

/// Closest hit through the crate's nearest-first iterator (leaves in the
/// order of their boxes' entry distance), stopping at the first box that
/// starts beyond the best hit. Camera rays have unit directions, so the
/// crate's distances (it normalises) and penumbra's are the same t.
fn crate_nearest(c: &Case, ray: &Ray) -> Option<(HitTarget, f64)> {
    let mut best = outside_bvh(&c.scene, ray);
    let mut t_max = best.map_or(f64::INFINITY, |b| b.1);
    let r = crate_ray(ray);
    for item in c.crate_bvh.nearest_traverse_iterator(&r, &c.items) {
        match r.intersection_slice_for_aabb(&item.aabb) {
            Some((entry, _)) if entry > t_max => break,
            _ => {}
        }
        let object = &c.scene.objects[item.object as usize];
        if let Some(t) = object.shape.intersect(ray, t_max) {
            best = Some((HitTarget::Object(item.object), t));
            t_max = t;
        }
    }
    best
}

/// Closest hit through the crate's plain traversal: every object whose box
/// the ray crosses, in tree order, each tested below the best hit so far.
fn crate_all(c: &Case, ray: &Ray) -> Option<(HitTarget, f64)> {
    let mut best = outside_bvh(&c.scene, ray);
    let mut t_max = best.map_or(f64::INFINITY, |b| b.1);
    let r = crate_ray(ray);
    for item in c.crate_bvh.traverse_iterator(&r, &c.items) {
        let object = &c.scene.objects[item.object as usize];
        if let Some(t) = object.shape.intersect(ray, t_max) {
            best = Some((HitTarget::Object(item.object), t));
            t_max = t;
        }
    }
    best
}

/// Once per scene, outside the timed loops: both ways find the same closest
/// object at the same distance for every ray.
fn check(n: usize, c: &Case) {
    let mut hits = 0;
    for (k, ray) in c.rays.iter().enumerate() {
        assert!((ray.dir.length() - 1.0).abs() < 1e-12);
        let own = c.scene.closest_hit(ray);
        assert_eq!(own, crate_nearest(c, ray), "ray {k}, nearest-first");
        assert_eq!(own, crate_all(c, ray), "ray {k}, plain traversal");
        hits += usize::from(matches!(own, Some((HitTarget::Object(i), _))
            if c.scene.objects[i as usize].bounds.is_some()));
    }
    eprintln!(
        "N = {n}: {} bounded objects, {hits} of {} rays end on one; same closest hits",
        c.bounds.len(),
        c.rays.len()
    );
}

fn compare(cr: &mut Criterion) {
    let cases: Vec<(usize, Case)> = SIZES.iter().map(|&n| (n, case(n))).collect();
    for (n, c) in &cases {
        check(*n, c);
    }

    let mut g = cr.benchmark_group("bvh_build");
    for (n, c) in &cases {
        g.throughput(Throughput::Elements(c.bounds.len() as u64));
        g.bench_with_input(BenchmarkId::new("penumbra", n), c, |b, c| {
            b.iter(|| Bvh::build(black_box(&c.bounds)))
        });
        let mut items = c.items.clone();
        g.bench_with_input(BenchmarkId::new("bvh_crate", n), c, |b, _| {
            b.iter(|| CrateBvh::build(black_box(&mut items)))
        });
    }
    g.finish();

    let mut g = cr.benchmark_group("bvh_closest_hit");
    for (n, c) in &cases {
        g.throughput(Throughput::Elements(c.rays.len() as u64));
        g.bench_with_input(BenchmarkId::new("penumbra", n), c, |b, c| {
            b.iter(|| {
                c.rays
                    .iter()
                    .filter_map(|r| c.scene.closest_hit(black_box(r)))
                    .count()
            })
        });
        g.bench_with_input(BenchmarkId::new("bvh_crate_nearest", n), c, |b, c| {
            b.iter(|| {
                c.rays
                    .iter()
                    .filter_map(|r| crate_nearest(c, black_box(r)))
                    .count()
            })
        });
        g.bench_with_input(BenchmarkId::new("bvh_crate_all", n), c, |b, c| {
            b.iter(|| {
                c.rays
                    .iter()
                    .filter_map(|r| crate_all(c, black_box(r)))
                    .count()
            })
        });
    }
    g.finish();
}

// No HTML plots: criterion draws them with plotters, whose text needs a
// registered font under this crate's plotters features.
criterion_group! {
    name = benches;
    config = Criterion::default().without_plots();
    targets = compare
}
criterion_main!(benches);
