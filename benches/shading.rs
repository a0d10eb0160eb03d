//! Shading one hit point of the seed room with 64 grid shadow rays (a
//! floor point whose shadow rays must be traced, and one that skipping
//! answers), and whole pixels through the tracer (reflections included).

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use penumbra::render::HitTarget;
use penumbra::render::Loaded;
use penumbra::render::RayStats;
use penumbra::render::rng::Rng;
use penumbra::render::shading::{ShadingPoint, shade};
use penumbra::render::shadow::{ShadowBuffers, ShadowQuery};
use penumbra::render::tracer::Tracer;

/// The first hit of pixel (x, y) as the tracer shades it.
fn hit(loaded: &Loaded, x: u32, y: u32) -> Option<ShadingPoint<'_>> {
    let scene = &loaded.scene;
    let ray = scene.camera.pixel_ray(x, y);
    let Some((HitTarget::Object(object), t)) = scene.closest_hit(&ray) else {
        return None;
    };
    let surface = scene.surface(object, &ray, t);
    let inside = surface.normal.dot(ray.dir) > 0.0;
    let normal = if inside {
        -surface.normal
    } else {
        surface.normal
    };
    Some(ShadingPoint {
        point: surface.point,
        normal,
        view: -ray.dir,
        shadow: ShadowQuery {
            point: surface.point,
            normal,
            object,
            inside,
        },
        material: &loaded.shading.materials[scene.material_of(object) as usize],
        material_index: scene.material_of(object),
    })
}

fn shading(c: &mut Criterion) {
    // 64 grid rays and depth 4: the settings of the speed targets.
    let loaded = Loaded::seed_room();
    let (scene, settings, shading) = (&*loaded.scene, &loaded.settings, &loaded.shading);
    let tracer = Tracer::new(scene, settings, shading, 64);
    let (w, h) = (scene.camera.width, scene.camera.height);
    let mut buf = ShadowBuffers::with_capacity(tracer.pattern.count());

    // Floor points (object 0), found rather than hard-coded so that scene
    // edits keep the benchmark meaningful: one whose shadow rays are
    // traced (an occluder may be in the way) and one answered by skipping.
    let (mut traced, mut skipped) = (None, None);
    for y in (h / 2..h).rev().step_by(4) {
        for x in (0..w).step_by(4) {
            let Some(sp) = hit(&loaded, x, y).filter(|sp| sp.shadow.object == 0) else {
                continue;
            };
            let mut stats = RayStats::default();
            let mut rng = Rng::for_vertex(settings.seed, x, y, 1);
            shade(
                scene,
                settings,
                shading,
                &sp,
                &tracer.pattern,
                &mut rng,
                &mut buf,
                &mut stats,
            );
            if stats.shadow > 0 {
                traced.get_or_insert((x, y, sp));
            } else if stats.shadow_unoccluded > 0 {
                skipped.get_or_insert((x, y, sp));
            }
        }
    }
    let mut g = c.benchmark_group("shade_64_grid");
    for (name, found) in [("floor_traced", traced), ("floor_unoccluded", skipped)] {
        let Some((x, y, sp)) = found else {
            eprintln!("no floor point for {name}");
            continue;
        };
        let mut stats = RayStats::default();
        g.bench_function(name, |b| {
            b.iter(|| {
                let mut rng = Rng::for_vertex(settings.seed, x, y, 1);
                shade(
                    scene,
                    settings,
                    shading,
                    black_box(&sp),
                    &tracer.pattern,
                    &mut rng,
                    &mut buf,
                    &mut stats,
                )
            })
        });
    }
    g.finish();

    let mut g = c.benchmark_group("pixel_64_grid_depth_4");
    let mut scratch = tracer.scratch();
    // The mirror sphere (reflected rays) and the image centre.
    for (name, fx, fy) in [("mirror_sphere", 0.36, 0.5), ("centre", 0.5, 0.5)] {
        let (x, y) = ((fx * w as f64) as u32, (fy * h as f64) as u32);
        g.bench_function(name, |b| {
            b.iter(|| tracer.pixel(black_box(x), black_box(y), &mut scratch))
        });
    }
    g.finish();
}

// No HTML plots: criterion draws them with plotters, whose text needs a
// registered font under this crate's plotters features.
criterion_group! {
    name = benches;
    config = Criterion::default().without_plots();
    targets = shading
}
criterion_main!(benches);
