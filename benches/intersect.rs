//! Intersection routines: one ray against each primitive, and the closest
//! hit of camera rays in a generated room of 1000 spheres (through the BVH).

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use glam::DVec3;
use penumbra::render::Loaded;
use penumbra::render::generate::spheres_in_room;
use penumbra::render::geometry::{Cuboid, Parallelogram, Plane, Ray, Sphere};

/// Rays from the seed room's camera position towards points spread over
/// the scene, so that some hit each primitive and some miss it.
fn rays(n: usize) -> Vec<Ray> {
    let origin = DVec3::new(0.0, 4.0, -14.0);
    (0..n)
        .map(|i| {
            let a = i as f64 / n as f64;
            let target = DVec3::new(
                -4.0 + 8.0 * a,
                1.0 + 6.0 * ((i * 7) % n) as f64 / n as f64,
                0.0,
            );
            Ray::new(origin, (target - origin).normalize())
        })
        .collect()
}

fn primitives(c: &mut Criterion) {
    let rays = rays(256);
    let plane = Plane::new(DVec3::new(0.0, 0.0, 5.0), DVec3::new(0.0, 0.0, -1.0));
    let rect = Parallelogram::new(
        DVec3::new(-2.0, 1.0, 0.0),
        DVec3::new(4.0, 0.0, 0.0),
        DVec3::new(0.0, 4.0, 0.0),
    );
    let cuboid = Cuboid::new(
        DVec3::new(-1.0, 0.0, -1.0),
        DVec3::new(1.0, 5.0, 1.0),
        20.0,
        DVec3::new(-2.0, 0.0, 1.0),
    );
    let sphere = Sphere {
        centre: DVec3::new(2.0, 3.5, -1.5),
        radius: 1.0,
    };
    let mut g = c.benchmark_group("intersect");
    g.throughput(Throughput::Elements(rays.len() as u64));
    g.bench_function("plane", |b| {
        b.iter(|| {
            rays.iter()
                .filter_map(|r| plane.intersect(black_box(r), f64::INFINITY))
                .count()
        })
    });
    g.bench_function("parallelogram", |b| {
        b.iter(|| {
            rays.iter()
                .filter_map(|r| rect.intersect(black_box(r), f64::INFINITY))
                .count()
        })
    });
    g.bench_function("cuboid", |b| {
        b.iter(|| {
            rays.iter()
                .filter_map(|r| cuboid.intersect(black_box(r), f64::INFINITY))
                .count()
        })
    });
    g.bench_function("sphere", |b| {
        b.iter(|| {
            rays.iter()
                .filter_map(|r| sphere.intersect(black_box(r), f64::INFINITY))
                .count()
        })
    });
    g.finish();
}

fn bvh_closest(c: &mut Criterion) {
    let mut g = c.benchmark_group("closest_hit");
    for n in [10usize, 1000, 10_000] {
        let mut desc = spheres_in_room(n, 1);
        desc.camera.width = 32;
        desc.camera.height = 18;
        let scene = Loaded::new(&desc)
            .expect("generated scenes are valid")
            .scene;
        let rays: Vec<Ray> = (0..18)
            .flat_map(|y| (0..32).map(move |x| (x, y)))
            .map(|(x, y)| scene.camera.pixel_ray(x, y))
            .collect();
        g.throughput(Throughput::Elements(rays.len() as u64));
        g.bench_function(format!("spheres_{n}"), |b| {
            b.iter(|| {
                rays.iter()
                    .filter_map(|r| scene.closest_hit(black_box(r)))
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
    targets = primitives, bvh_closest
}
criterion_main!(benches);
